/* Readings and trends: a task's readings (task_control query_results), alarms first, with their
   annotated pictures; a click on a meter draws its last 90 days against its normal band. */
import { alarmWords, readingAlarm, readingText, sortReadings, statusTask, trendSeries } from './decode.js';
import { fetchPicture } from './files.js';
import { control } from './link.js';
import * as store from './state.js';
import { $, coalesced } from './ui.js';

const MAX_RESULT_ROWS = 200;
const MAX_RESULT_PICTURES = 30;
const TREND_DAYS = 90;
const TREND_COLOURS = { read: '#2e7d32', uncertain: '#e65100', corrected: '#1565c0', alarm: '#c62828',
  check: '#e65100', trend: '#6a1b9a' };
// ``follow``: the readings follow the running (or last) task until the operator types a task id.
const results = { follow: true, key: '' };

/** The running (or last) task's readings unless the operator typed another task id; asked again when
    its progress or state changed. */
function followTask(status) {
  const { task, key } = statusTask(status);
  if (task && results.follow) $('results-task').value = task;
  if (task && results.follow && key !== results.key) {
    results.key = key;
    queryResults();
  }
}

/** Ask again when the readings shown are ``task``'s (a review changed one of them). */
function refreshTask(task) {
  if ($('results-task').value.trim() === task) queryResults();
}

// one more query when this one is back, not one per status
const queryResults = coalesced(() => {
  const task = $('results-task').value.trim();
  return control('task_control', 'query_results', task ? { task_id: task, limit: 5000 } : { limit: 500 }, true)
    .then((text) => renderResults(JSON.parse(text)))
    .catch((err) => { $('results-count').textContent = 'query refused: ' + err.message; });
});

/** Alarms first, then failures, then the rest; newest first within each (bounded to MAX_RESULT_ROWS). */
function renderResults(rows) {
  const shown = sortReadings(rows).slice(0, MAX_RESULT_ROWS);
  const alarms = rows.filter((r) => readingAlarm(r) === 'alarm').length;
  $('results-count').textContent = rows.length + ' reading(s), ' + alarms + ' alarm(s)'
    + (shown.length < rows.length ? ', first ' + shown.length + ' shown' : '');
  const body = $('results').tBodies[0];
  const fresh = document.createElement('tbody');
  shown.forEach((r, i) => {
    const tr = fresh.insertRow();
    const state = readingAlarm(r);
    tr.className = ['alarm', 'check', 'warning'].includes(state) ? state : r.status === 'failed' ? 'failed' : '';
    const alarm = tr.insertCell();   // a thermal defect names its grade; the rule and temperatures on hover
    alarm.textContent = alarmWords(state) + (r.grade ? ' (' + r.grade + ' defect)' : '');
    if (r.reason) alarm.title = r.reason;
    const target = tr.insertCell();
    target.textContent = r.target_name || r.kind + ' ' + r.target;
    if (r.target_name) {
      target.className = 'trend-link';
      target.title = 'show this meter\'s trend';
      target.addEventListener('click', () => showTrend(r.target_name, r.unit));
    }
    tr.insertCell().textContent = readingText(r);
    tr.insertCell().textContent = r.stop_name || String(r.stop + 1);
    tr.insertCell().textContent = new Date(r.time * 1000).toLocaleString();
    const cell = tr.insertCell();
    if (r.picture && i < MAX_RESULT_PICTURES) {
      const img = document.createElement('img');
      img.alt = r.picture;
      cell.appendChild(img);
      fetchPicture(r.picture).then((url) => { img.src = url; })
        .catch((err) => { cell.textContent = 'picture: ' + err.message; });
    } else if (r.picture) {
      cell.textContent = r.picture.split('/').pop();
    }
  });
  body.parentNode.replaceChild(fresh, body);
}

function showTrend(target, unit) {
  $('trend-meter').textContent = target + ' (loading…)';
  const since = Date.now() / 1000 - TREND_DAYS * 86400;
  control('task_control', 'query_results', { target, from: since, limit: 5000 }, true)
    .then((text) => drawTrend($('trend'), target, unit, JSON.parse(text)))
    .catch((err) => { $('trend-meter').textContent = target + ': query refused: ' + err.message; });
}

function drawTrend(canvas, target, unit, rows) {
  const series = trendSeries(rows);
  const ctx = canvas.getContext('2d');
  const w = canvas.width;
  const h = canvas.height;
  const pad = 36;
  ctx.fillStyle = '#fff';
  ctx.fillRect(0, 0, w, h);
  const times = series.points.map((p) => p.t);
  const t0 = Math.min.apply(null, times.length ? times : [0]);
  const t1 = Math.max.apply(null, times.length ? times : [1]);
  const x = (t) => pad + (t1 > t0 ? (t - t0) / (t1 - t0) : 0.5) * (w - 2 * pad);
  const [lo, hi] = series.range;
  const y = (v) => h - pad - (v - lo) / (hi - lo) * (h - 2 * pad);
  if (series.band) {   // the normal band, shaded
    ctx.fillStyle = 'rgba(46, 125, 50, 0.12)';
    ctx.fillRect(pad, y(series.band[1]), w - 2 * pad, y(series.band[0]) - y(series.band[1]));
  }
  ctx.strokeStyle = '#999';
  ctx.strokeRect(pad, pad, w - 2 * pad, h - 2 * pad);
  ctx.fillStyle = '#333';
  ctx.font = '11px sans-serif';
  ctx.fillText(hi.toPrecision(4) + (unit ? ' ' + unit : ''), 2, pad);
  ctx.fillText(lo.toPrecision(4), 2, h - pad);
  if (times.length) {
    ctx.fillText(new Date(t0 * 1000).toLocaleDateString(), pad, h - 8);
    ctx.fillText(new Date(t1 * 1000).toLocaleDateString(), w - pad - 70, h - 8);
  }
  ctx.strokeStyle = '#777';
  ctx.beginPath();
  series.points.forEach((p, i) => (i ? ctx.lineTo(x(p.t), y(p.v)) : ctx.moveTo(x(p.t), y(p.v))));
  ctx.stroke();
  series.points.forEach((p) => {
    ctx.fillStyle = TREND_COLOURS[p.kind] || '#333';
    ctx.beginPath();
    ctx.arc(x(p.t), y(p.v), 3.5, 0, 2 * Math.PI);
    ctx.fill();
    if (p.kind === 'trend') {
      ctx.strokeStyle = TREND_COLOURS.trend;
      ctx.beginPath();
      ctx.arc(x(p.t), y(p.v), 7, 0, 2 * Math.PI);
      ctx.stroke();
    }
  });
  canvas.dataset.points = String(series.points.length);
  $('trend-meter').textContent = target + ': ' + series.points.length + ' reading(s) in ' + TREND_DAYS + ' days';
}

export function init() {
  $('results-refresh').addEventListener('click', queryResults);
  $('results-task').addEventListener('input', () => { results.follow = $('results-task').value.trim() === ''; });
  store.on('task', followTask);
  store.on('readings-changed', refreshTask);
}

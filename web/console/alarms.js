/* Open alarms: readings of any patrol whose alarm is ``alarm``, ``check`` or ``warning`` and nobody acknowledged
   (task_control alarms), newest first, each acknowledged by a named operator with an optional note
   (task_control acknowledge). task_status ``open_alarms`` drives the header's banner; a count that
   grows sounds a short tone (Web Audio: nothing to download) and lists the alarms again. */
import { t, timeText } from './i18n.js';
import { alarmWords, readingText } from './decode.js';
import { fetchPicture } from './files.js';
import { control } from './link.js';
import * as store from './state.js';
import { $, coalesced } from './ui.js';

const ALARM_LIMIT = 50;
const alarms = { count: null, audio: null };

function alarmMessage(text, failed) {
  $('alarm-result').textContent = text;
  $('alarm-result').className = failed ? 'error' : '';
}

/** A two-note tone: the browser may refuse sound until the operator clicked the page once. */
function chime() {
  try {
    alarms.audio = alarms.audio || new AudioContext();
    const ctx = alarms.audio;
    [880, 660].forEach((hz, i) => {
      const osc = ctx.createOscillator();
      const gain = ctx.createGain();
      osc.frequency.value = hz;
      gain.gain.setValueAtTime(0.2, ctx.currentTime + i * 0.25);
      gain.gain.exponentialRampToValueAtTime(0.001, ctx.currentTime + i * 0.25 + 0.22);
      osc.connect(gain).connect(ctx.destination);
      osc.start(ctx.currentTime + i * 0.25);
      osc.stop(ctx.currentTime + i * 0.25 + 0.23);
    });
    window.consoleAlarms.chimes += 1;
  } catch (err) {
    alarmMessage(t('no sound') + ': ' + err.message, false);
  }
}

function onTaskStatus(status) {
  const count = status.open_alarms;
  if (typeof count !== 'number' || count === alarms.count) return;
  const grew = alarms.count !== null && count > alarms.count;
  alarms.count = count;
  window.consoleAlarms.count = count;
  const banner = $('alarm-banner');
  banner.hidden = count === 0;
  banner.textContent = t(count === 1 ? '{n} open alarm' : '{n} open alarms', { n: count });
  $('alarm-count').textContent = count ? '(' + count + ')' : '';
  if (grew) chime();
  queryAlarms();
}

const queryAlarms = coalesced(() => control('task_control', 'alarms', { limit: ALARM_LIMIT }, true)
  .then((text) => renderAlarms(JSON.parse(text)))
  .catch((err) => alarmMessage(t('alarm list refused') + ': ' + err.message, true)));

/** One row per open alarm: what, where, when, the value and its reason; acknowledge. */
function renderAlarms(rows) {
  const body = $('alarm-list').tBodies[0];
  const fresh = document.createElement('tbody');
  for (const r of rows) {
    const tr = fresh.insertRow();
    tr.className = r.alarm;
    tr.dataset.id = r.id;
    tr.insertCell().textContent = alarmWords(r.alarm) + (r.grade ? ' (' + t('{grade} defect', { grade: t(r.grade) }) + ')' : '');
    const target = tr.insertCell();   // a click puts the meter on the trend chart
    target.textContent = r.target_name || r.kind + ' ' + r.target;
    if (r.target_name) {
      target.className = 'trend-link';
      target.title = t('add this meter to the trend chart');
      target.addEventListener('click', () => store.emit('trend-meter', { target: r.target_name, unit: r.unit }));
    }
    tr.insertCell().textContent = readingText(r) + (r.reason && r.status !== 'uncertain' ? ' · ' + r.reason : '');
    tr.insertCell().textContent = r.task_id + ' · ' + (r.stop_name || t('stop {i}', { i: r.stop + 1 }));
    tr.insertCell().textContent = timeText(r.time);
    const cell = tr.insertCell();
    if (r.picture) {   // the annotated picture, in a tab of its own
      const view = document.createElement('button');
      view.type = 'button';
      view.className = 'alarm-picture';
      view.textContent = t('picture');
      view.addEventListener('click', () => showPicture(r.picture));
      cell.appendChild(view);
    }
    const button = document.createElement('button');
    button.type = 'button';
    button.className = 'alarm-ack';
    button.textContent = t('acknowledge');
    button.addEventListener('click', () => acknowledge(r, button));
    cell.appendChild(button);
  }
  if (!rows.length) fresh.insertRow().insertCell().textContent = t('No open alarm.');
  body.parentNode.replaceChild(fresh, body);
}

function showPicture(picture) {
  const tab = window.open('', '_blank');   // opened now, in the click, or the browser blocks it
  fetchPicture(picture).then((url) => {
    if (tab) tab.document.body.innerHTML = '<img alt="" style="max-width:100%">';
    if (tab) tab.document.querySelector('img').src = url;
  }).catch((err) => alarmMessage(t('picture') + ': ' + err.message, true));
}

function acknowledge(row, button) {
  const by = $('alarm-by').value.trim();
  if (!by) {
    alarmMessage(t('type your name in "operator" first'), true);
    $('alarm-by').focus();
    return;
  }
  const note = $('alarm-note').value.trim();
  button.disabled = true;
  control('task_control', 'acknowledge', note ? { id: row.id, by, note } : { id: row.id, by })
    .then((text) => {
      const done = JSON.parse(text);
      alarmMessage(t('alarm of {target} acknowledged by {name}', { target: done.target_name, name: done.ack_by }));
      $('alarm-note').value = '';
      queryAlarms();
      store.emit('readings-changed', row.task_id);
    })
    .catch((err) => {
      alarmMessage(t('acknowledge refused') + ': ' + err.message, true);
      button.disabled = false;
    });
}

export function init() {
  window.consoleAlarms = { chimes: 0, count: null, ids: () => Array.from(document.querySelectorAll('#alarm-list tr[data-id]'),
    (e) => Number(e.dataset.id)) };
  $('alarm-refresh').addEventListener('click', queryAlarms);
  $('alarm-banner').addEventListener('click', () => $('alarm-panel').scrollIntoView());
  store.on('task', onTaskStatus);
}

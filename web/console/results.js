/* Readings: a task's readings (task_control query_results), alarms first, with their annotated
   pictures; a click on a meter adds it to the trend chart (news 'trend-meter' to trends.js). */
import { t, timeText } from './i18n.js';
import { alarmWords, readingAlarm, readingText, sortReadings, statusTask } from './decode.js';
import { fetchPicture } from './files.js';
import { control } from './link.js';
import * as store from './state.js';
import { $, coalesced, emptyRow } from './ui.js';

const MAX_RESULT_ROWS = 200;
const MAX_RESULT_PICTURES = 30;
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
    .catch((err) => { $('results-count').textContent = t('query refused') + ': ' + err.message; });
});

/** Alarms first, then failures, then the rest; newest first within each (bounded to MAX_RESULT_ROWS). */
function renderResults(rows) {
  const shown = sortReadings(rows).slice(0, MAX_RESULT_ROWS);
  const alarms = rows.filter((r) => readingAlarm(r) === 'alarm').length;
  $('results-count').textContent = t('{n} reading(s), {alarms} alarm(s)', { n: rows.length, alarms })
    + (shown.length < rows.length ? ', ' + t('first {n} shown', { n: shown.length }) : '');
  const body = $('results').tBodies[0];
  const fresh = document.createElement('tbody');
  shown.forEach((r, i) => {
    const tr = fresh.insertRow();
    const state = readingAlarm(r);
    tr.className = ['alarm', 'check', 'warning'].includes(state) ? state : r.status === 'failed' ? 'failed' : '';
    const alarm = tr.insertCell();   // a thermal defect names its grade; the rule and temperatures on hover
    alarm.textContent = alarmWords(state) + (r.grade ? ' (' + t('{grade} defect', { grade: t(r.grade) }) + ')' : '');
    if (r.reason) alarm.title = r.reason;
    const target = tr.insertCell();
    target.textContent = r.target_name || r.kind + ' ' + r.target;
    if (r.target_name) {
      target.className = 'trend-link';
      target.title = t('add this meter to the trend chart');
      target.addEventListener('click', () => store.emit('trend-meter', { target: r.target_name, unit: r.unit }));
    }
    tr.insertCell().textContent = readingText(r);
    tr.insertCell().textContent = r.stop_name || String(r.stop + 1);
    tr.insertCell().textContent = timeText(r.time);
    const cell = tr.insertCell();
    if (r.picture && i < MAX_RESULT_PICTURES) {
      const img = document.createElement('img');
      img.alt = r.picture;
      cell.appendChild(img);
      fetchPicture(r.picture).then((url) => { img.src = url; })
        .catch((err) => { cell.textContent = t('picture') + ': ' + err.message; });
    } else if (r.picture) {
      cell.textContent = r.picture.split('/').pop();
    }
  });
  if (!rows.length) emptyRow(fresh, 6, t('No readings of this task yet.'));
  body.parentNode.replaceChild(fresh, body);
}

export function init() {
  $('results-refresh').addEventListener('click', queryResults);
  $('results-task').addEventListener('input', () => { results.follow = $('results-task').value.trim() === ''; });
  store.on('task', followTask);
  store.on('readings-changed', refreshTask);
}

/* Routines and schedules: the routines saved with the planner (task_control routine_list /
   routine_delete, "load" puts one back into the planner) and the schedules that run them by
   themselves (schedule_set / schedule_list / schedule_delete): when, next run, last run, missed runs. */
import { t } from './i18n.js';
import { control, subscribe } from './link.js';
import * as store from './state.js';
import { scheduleRequest, scheduleText, WEEKDAYS, whenText } from './planning.js';
import { $, coalesced, emptyRow } from './ui.js';

const schedules = { key: null };

function message(text, failed) {
  $('schedule-result').textContent = text;
  $('schedule-result').className = failed ? 'error' : '';
}

/** routine_list and schedule_list again (one query in flight, one more queued at most). */
export const refreshRoutines = coalesced(() => Promise.all([control('task_control', 'routine_list', '', true),
  control('task_control', 'schedule_list', '', true)])
  .then(([routines, rows]) => {
    renderRoutines(JSON.parse(routines));
    renderSchedules(JSON.parse(rows));
  })
  .catch((err) => message(t('routines and schedules refused') + ': ' + err.message, true)));

function button(text, onClick) {
  const b = document.createElement('button');
  b.type = 'button';
  b.textContent = t(text);
  b.addEventListener('click', onClick);
  return b;
}

function act(cmd, data, done) {
  control('task_control', cmd, data).then(() => {
    message(done);
    refreshRoutines();
  }).catch((err) => message(t('{cmd} refused', { cmd }) + ': ' + err.message, true));
}

/** An empty table's one row saying so, as a hint. */
function empty(body, columns, text) {
  emptyRow(body, columns, text).className = 'hint';
}

function renderRoutines(routines) {
  const now = Date.now() / 1000;
  const body = document.createElement('tbody');
  for (const routine of routines) {
    const tr = body.insertRow();
    tr.dataset.routine = routine.name;
    tr.insertCell().textContent = routine.name;
    tr.insertCell().textContent = String(routine.task.stops.length);
    tr.insertCell().textContent = whenText(routine.saved, now);
    tr.insertCell().append(button('load', () => store.emit('load-routine', routine)),
      button('delete', () => act('routine_delete', routine.name, t('routine {name} deleted', { name: routine.name }))));
  }
  if (!routines.length) empty(body, 4, t('No saved routine yet: plan a patrol and save it as a routine.'));
  const table = $('routines');
  table.replaceChild(body, table.tBodies[0]);
  const select = $('schedule-routine');
  const chosen = select.value;
  select.textContent = '';
  routines.forEach((r) => select.add(new Option(r.name, r.name)));
  if (routines.some((r) => r.name === chosen)) select.value = chosen;
}

function renderSchedules(rows) {
  const now = Date.now() / 1000;
  const body = document.createElement('tbody');
  for (const row of rows) {
    const text = scheduleText(row, now);
    const tr = body.insertRow();
    tr.dataset.schedule = row.name;
    for (const value of [text.name, text.routine, text.when, text.enabled, text.next, text.last]) {
      tr.insertCell().textContent = value;
    }
    const missed = tr.insertCell();
    missed.className = text.missedCount ? 'missed' : '';
    missed.textContent = text.missedCount ? text.missed.join('; ') : t('none');
    const toggled = Object.assign({}, row, { enabled: !row.enabled });
    ['next_run', 'last_run', 'missed'].forEach((key) => delete toggled[key]);
    tr.insertCell().append(
      button(row.enabled ? 'disable' : 'enable', () => act('schedule_set', toggled,
        t(row.enabled ? 'schedule {name} disabled' : 'schedule {name} enabled', { name: row.name }))),
      button('delete', () => act('schedule_delete', row.name, t('schedule {name} deleted', { name: row.name }))));
  }
  if (!rows.length) empty(body, 8, t('No schedule yet: a saved routine runs on the days and at the time you set.'));
  const table = $('schedules');
  table.replaceChild(body, table.tBodies[0]);
}

function saveSchedule(event) {
  event.preventDefault();
  let data;
  try {
    data = scheduleRequest({ name: $('schedule-name').value.trim(), routine: $('schedule-routine').value,
      time: $('schedule-time').value, repeat: document.querySelector('input[name=schedule-repeat]:checked').value,
      weekdays: Array.from(document.querySelectorAll('#schedule-days input:checked'), (e) => e.value),
      date: $('schedule-date').value, enabled: $('schedule-enabled').checked });
  } catch (err) {
    message(err.message, true);
    return;
  }
  message(t('saving…'));
  control('task_control', 'schedule_set', data).then((text) => {
    const row = JSON.parse(text);
    message(t('schedule {name} saved, next run {when}', { name: row.name, when: whenText(row.next_run, Date.now() / 1000) }));
    refreshRoutines();
  }).catch((err) => message(t('schedule refused') + ': ' + err.message, true));
}

/** task_status: a run started or ended, a run missed or the next one changed: list again. */
function onTaskStatus(msg) {
  let s;
  try {
    s = JSON.parse(msg.data);
  } catch (err) {
    return;   // the patrol panel logs it
  }
  const key = JSON.stringify([s.task_id, s.state, s.last_ended && s.last_ended.task_id, s.missed_runs,
    s.next_scheduled]);
  if (key === schedules.key) return;
  schedules.key = key;
  refreshRoutines();
}

export function init() {
  window.consoleSchedules = { rows: () => Array.from(document.querySelectorAll('#schedules tbody tr[data-schedule]'),
    (tr) => Array.from(tr.cells, (c) => c.textContent)) };
  const days = $('schedule-days');
  for (const day of WEEKDAYS) {
    const label = document.createElement('label');
    const box = document.createElement('input');
    box.type = 'checkbox';
    box.value = day;
    box.checked = !['sat', 'sun'].includes(day);
    label.append(box, ' ' + t(day));   // the value stays the interface's (mon, tue, ...)
    days.appendChild(label);
  }
  $('schedule-form').addEventListener('submit', saveSchedule);
  $('schedule-refresh').addEventListener('click', refreshRoutines);
  store.on('routines-changed', refreshRoutines);
  subscribe('task_status', 'inspection_robot/GeneralTopic', { queue_length: 1 }, onTaskStatus);
}

/* The patrol panel: a task submitted to task_manager (task_control submit), pause / resume / cancel /
   return home, and the latched task_status in words with a progress bar. */
import { t } from './i18n.js';
import { control, subscribe } from './link.js';
import { taskId } from './planning.js';
import * as store from './state.js';
import { $, log } from './ui.js';

const patrol = { status: null, frame: 0 };

function exampleTask() {
  return JSON.stringify({ id: taskId(new Date()), priority: 'routine', retries: 1, stops: [
    { name: 'cabinet_1', pose: { x: 20.0, y: 21.4, yaw: 1.5708 }, precision: 0,
      presets: [{ preset: 'cabinet_1', alarms: {}, foreign: false }] }] }, null, 2);
}

/** A task_control command with its outcome on the panel; resolves true when the robot took it. */
function patrolCommand(cmd, data) {
  $('patrol-result').textContent = t(cmd) + '…';
  $('patrol-result').className = '';
  return control('task_control', cmd, data).then(() => {
    $('patrol-result').textContent = t(cmd) + ': ' + t('done');
    return true;
  }).catch((err) => {
    $('patrol-result').textContent = t('{cmd} refused', { cmd: t(cmd) }) + ': ' + err.message;
    $('patrol-result').className = 'error';
    return false;
  });
}

function onTaskStatus(msg) {
  try {
    patrol.status = JSON.parse(msg.data);
  } catch (err) {
    log('task_status ' + t('unreadable') + ': ' + err, true);
    return;
  }
  store.set('task', patrol.status);   // the readings, the review queue and the alarms follow it
  if (!patrol.frame) patrol.frame = requestAnimationFrame(renderPatrol);
}

function renderPatrol() {
  patrol.frame = 0;
  const s = patrol.status;
  const parts = [t(s.state) + (s.task_id ? ': ' + s.task_id + (s.priority ? ' (' + t(s.priority) + ')' : '') : '')];
  if (s.task_id && s.stops) {
    parts.push(t('stop {i} of {n}', { i: s.stop, n: s.stops }) + (s.stop_name ? ' (' + s.stop_name + ')' : ''),
      t('preset {i} of {n}', { i: s.preset, n: s.presets }), t('{done}/{total} presets done', s),
      t('ETA {s} s', { s: Math.round(s.eta_s || 0) }));
  }
  if (s.holds && s.holds.length) parts.push(t('held') + ': ' + s.holds.map((h) => t(h)).join(', '));
  if (s.suspended) parts.push(t('suspended') + ': ' + s.suspended);
  if (s.reason) parts.push(s.reason);
  if (s.last_ended) parts.push(t('last ended') + ': ' + s.last_ended.task_id + ' ' + t(s.last_ended.state)
    + (s.last_ended.reason ? ' (' + s.last_ended.reason + ')' : ''));
  $('patrol-state').textContent = parts.join(' · ');
  $('patrol-state').className = s.holds && s.holds.length ? 'error' : '';
  $('patrol-progress').max = Math.max(1, s.total || 0);
  $('patrol-progress').value = s.done || 0;
}

export function init() {
  window.consolePatrol = { status: () => patrol.status };
  $('patrol-task').value = exampleTask();
  $('patrol-form').addEventListener('submit', (event) => {
    event.preventDefault();
    patrolCommand('submit', $('patrol-task').value).then((ok) => {
      if (ok) $('patrol-task').value = exampleTask();   // ids are never reused
    });
  });
  $('patrol-pause').addEventListener('click', () => patrolCommand('pause', ''));
  $('patrol-resume').addEventListener('click', () => patrolCommand('resume', ''));
  $('patrol-cancel').addEventListener('click', () => patrolCommand('cancel', ''));
  $('patrol-home').addEventListener('click', () => patrolCommand('return_home', ''));
  store.on('submit-task', (request) => patrolCommand(request.cmd, request.data));   // the planner's
  subscribe('task_status', 'inspection_robot/GeneralTopic', { queue_length: 1 }, onTaskStatus);
}

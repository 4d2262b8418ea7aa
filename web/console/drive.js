/* Driving: the heartbeat (the page acting as the backend), e-stop, taking and releasing control, and
   hold-to-move teleop (buttons and keys) that sends one explicit stop when the last key goes. */
import { t } from './i18n.js';
import { MODES } from './decode.js';
import { command, onClose, publish, session } from './link.js';
import * as store from './state.js';
import { $, holdButton, log, typing } from './ui.js';

const DRIVE_PERIOD_MS = 100;        // move_cmd repeat while a drive key is held (robot cmd_timeout 0.5 s)
const HEARTBEAT_PERIOD_MS = 1000;   // server_status while the page acts as the backend
const YAW_RATE = 0.5;               // rad/s when turning
const ACQUIRE_WAIT_MS = 10000;      // for robot_status to show the backend online before `acquire server`
const KEYS = { ArrowUp: 'forward', KeyW: 'forward', ArrowDown: 'backward', KeyS: 'backward', ArrowLeft: 'left',
  KeyA: 'left', ArrowRight: 'right', KeyD: 'right', Space: 'stop' };

const held = new Set();
let driveTimer = null;
let wheelControl = 0;

function heartbeat() {
  if (store.get('connected') && $('heartbeat').checked) {
    publish('server_status', 'inspection_robot/GeneralTopic', { data: 'console', trans_id: session() });
  }
}

function driveCommand() {
  const speed = Number($('speed').value);
  let vx = 0;
  let yaw = 0;
  if (held.has('forward')) vx += speed;
  if (held.has('backward')) vx -= speed;
  if (held.has('left')) yaw += YAW_RATE;
  if (held.has('right')) yaw -= YAW_RATE;
  // Turning alone spins in place (steer mode); with a forward/backward key it steers while driving.
  wheelControl = vx === 0 && yaw !== 0 ? 1 : 0;
  return { vx, yaw };
}

function publishMove(vx, yaw) {
  publish('move_cmd', 'inspection_robot/MoveCmd',
    { velocity_x: Math.round(vx * 1000), velocity_yaw: Math.round(yaw * 1000), wheel_control: wheelControl });
}

function sendDrive() {
  const { vx, yaw } = driveCommand();
  publishMove(vx, yaw);
}

function startDriving(direction) {
  if (direction === 'stop') {
    stopDriving();
    return;
  }
  held.add(direction);
  markHeld();
  sendDrive();
  if (!driveTimer) driveTimer = setInterval(sendDrive, DRIVE_PERIOD_MS);
}

function releaseDriving(direction) {
  if (!held.delete(direction)) return;
  markHeld();
  if (held.size) {
    sendDrive();
  } else {
    stopDriving();
  }
}

/** One explicit zero move_cmd, then silence (the robot's watchdog covers a lost stop). */
export function stopDriving() {
  const wasDriving = driveTimer !== null || held.size > 0;
  held.clear();
  markHeld();
  if (driveTimer) clearInterval(driveTimer);
  driveTimer = null;
  if (wasDriving && store.get('connected')) publishMove(0, 0);
}

function markHeld() {
  document.querySelectorAll('[data-drive]').forEach((b) => b.classList.toggle('held', held.has(b.dataset.drive)));
}

function acquire() {
  // robot_control refuses `acquire server` while the backend is offline: heartbeat first, then ask.
  $('heartbeat').checked = true;
  heartbeat();
  const started = Date.now();
  // the robot has this connection's own heartbeat when robot_status names its session (an older
  // connection's heartbeat could still expire after the grant and take the robot offline)
  const ours = () => {
    const status = store.get('status');
    return status && !status.offline_warn && status.trans_id === session();
  };
  const tryAcquire = () => {
    if (!ours() && Date.now() - started < ACQUIRE_WAIT_MS) {
      setTimeout(tryAcquire, 200);
      return;
    }
    publish('mode_cmd', 'inspection_robot/GeneralCmd', { cmd: 'acquire', data: 'server', trans_id: session() });
    setTimeout(() => {
      const status = store.get('status');
      if (!status || status.mode !== 1) {
        log(t('acquire: control not granted yet (mode {mode})', { mode: status ? t(MODES[status.mode]) : '?' }), true);
      }
    }, 1500);
  };
  tryAcquire();
}

export function init() {
  setInterval(heartbeat, HEARTBEAT_PERIOD_MS);
  $('heartbeat').addEventListener('change', heartbeat);
  $('estop').addEventListener('click', () => {
    stopDriving();
    command('control_cmd', 'enable_stop');
  });
  $('estop-release').addEventListener('click', () => command('control_cmd', 'disable_stop'));
  $('acquire').addEventListener('click', acquire);
  $('release').addEventListener('click', () => {
    stopDriving();
    command('mode_cmd', 'release', 'server');
  });
  $('speed').addEventListener('input', () => { $('speed-out').textContent = $('speed').value; });
  window.addEventListener('keydown', (event) => {
    const direction = KEYS[event.code];
    if (!direction || typing(event)) return;
    event.preventDefault();
    if (!event.repeat) startDriving(direction);
  });
  window.addEventListener('keyup', (event) => {
    const direction = KEYS[event.code];
    if (direction && !typing(event)) releaseDriving(direction);
  });
  // Losing focus loses the key-up: stop rather than drive on.
  window.addEventListener('blur', stopDriving);
  document.addEventListener('visibilitychange', () => { if (document.hidden) stopDriving(); });
  document.querySelectorAll('[data-drive]').forEach((b) => {
    holdButton(b, () => startDriving(b.dataset.drive), () => releaseDriving(b.dataset.drive));
  });
  onClose(stopDriving);
}

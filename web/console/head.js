/* The head and camera: held pan/tilt and lens buttons (stop on release), angles, light and wiper, and
   the head's angle from terrace_state. */
import { t } from './i18n.js';
import { command, onClose, subscribe } from './link.js';
import * as store from './state.js';
import { $, holdButton } from './ui.js';

let headMoving = false;
let lensMoving = false;

function stopHead() {
  if (headMoving && store.get('connected')) command('terrace_cmd', 'terrace_stop');
  if (lensMoving && store.get('connected')) command('camera_cmd', 'camera_stop');
  headMoving = lensMoving = false;
}

function onHead(msg) {
  const deg = (rad) => (rad * 180 / Math.PI).toFixed(2);
  $('head-angle').textContent = t('now pan {pan}°, tilt {tilt}°', { pan: deg(msg.position[0]), tilt: deg(msg.position[1]) });
}

export function init() {
  document.querySelectorAll('[data-head]').forEach((b) => {
    const cmd = b.dataset.head;
    if (cmd === 'terrace_stop') {
      b.addEventListener('click', () => { headMoving = true; stopHead(); });
      return;
    }
    holdButton(b, () => { headMoving = true; command('terrace_cmd', cmd, 'mid_speed'); }, stopHead);
  });
  document.querySelectorAll('[data-lens]').forEach((b) => {
    holdButton(b, () => { lensMoving = true; command('camera_cmd', b.dataset.lens, '0'); }, stopHead);
  });
  document.querySelectorAll('[data-aux]').forEach((b) => {
    b.addEventListener('click', () => command('terrace_cmd', b.dataset.aux));
  });
  $('angle-form').addEventListener('submit', (event) => {
    event.preventDefault();
    const centi = (input) => Math.round(Number(input.value) * 100);
    command('terrace_cmd', 'set_angle', centi($('pan')) + ',' + centi($('tilt')));
  });
  subscribe('terrace_state', 'sensor_msgs/JointState', { throttle_rate: 200, queue_length: 1 }, onHead);
  onClose(stopHead);
}

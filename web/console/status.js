/* The status panel: robot_status in words (decode.js), the mode pill and the alarm line. */
import { decodeStatus, MODES } from './decode.js';
import { t } from './i18n.js';
import { subscribe } from './link.js';
import * as store from './state.js';
import { $ } from './ui.js';

const rows = {};   // one table row per (name, index), kept across updates: a 10 Hz refresh must not grow the DOM
let frame = 0;

function onStatus(msg) {
  store.set('status', msg);   // the map redraws the robot on it
  if (!frame) frame = requestAnimationFrame(render);
}

/** At most once per animation frame, whatever the rate: the newest status only. */
function render() {
  frame = 0;
  const msg = store.get('status');
  window.consoleStats.status += 1;
  const decoded = decodeStatus(msg);
  $('mode').textContent = t('mode') + ': ' + t(MODES[msg.mode] || '?');
  const alarms = $('alarms');
  alarms.textContent = decoded.alarms.length ? decoded.alarms.join(' · ') : t('no alarm');
  alarms.className = 'alarms' + (decoded.alarms.length ? ' active' : '');
  const body = $('status').tBodies[0];
  const seen = {};
  decoded.rows.forEach((row) => {
    const key = row.name + '#' + (seen[row.name] = (seen[row.name] || 0) + 1);
    let tr = rows[key];
    if (!tr) {
      tr = rows[key] = body.insertRow();
      tr.insertCell().textContent = row.label;
      tr.insertCell();
    }
    tr.cells[1].textContent = row.text;
    tr.className = row.alarm ? 'alarm' : '';
    tr.hidden = false;
  });
  Object.keys(rows).forEach((key) => {
    const [name, n] = key.split('#');
    if (Number(n) > (seen[name] || 0)) rows[key].hidden = true;
  });
}

export function init() {
  window.consoleStats = { status: 0 };   // statuses rendered, for the benchmark
  subscribe('robot_status', 'inspection_robot/RobotStatus', { throttle_rate: 0, queue_length: 1 }, onStatus);
}

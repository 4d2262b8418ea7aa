/* robot_status decoded into words: the spec's bit tables (docs/interface.md, "Heartbeat and status",
   "Motion and safety"), and the calibration editor's and the history's arithmetic, kept apart from the
   page so node's test runner checks them without a browser. Words go through the catalogue (i18n.js). */
import { t, unitText } from './i18n.js';

export const MODES = ['task', 'backend remote control', 'joystick'];

// [bit, words, is an alarm when set]
export const BITS = {
  wheel_status: [[0, 'straight mode', false], [1, 'steer mode', false], [2, 'switching direction', false],
    [3, 'stepper fault clear', false], [4, 'servo fault clear', false], [5, 'obstacle detection OFF', true],
    [6, 'anti-collision OFF', true], [7, 'anti-fall OFF', true]],
  light_status: [[0, 'charge relay on', false], [1, 'lamp red', false], [2, 'lamp green', false],
    [3, 'lamp blue', false], [4, 'soft e-stop engaged', true], [5, 'hard e-stop pressed', true],
    [6, 'bumper strip pressed', true]],
  stop_status: [[0, 'front collision alarm', true], [5, 'obstacle alarm', true], [6, 'left fall alarm', true],
    [7, 'right fall alarm', true]],
  circuit_status: [[0, 'stepper board comm alarm', true], [1, 'joystick comm lost', true],
    [2, 'joystick line fault', true], [3, 'sensor board line fault', true], [4, 'collision line fault', true],
    [5, 'left TOF line fault', true], [6, 'right TOF line fault', true], [7, 'battery critically low', true]],
  battery_status: [[0, 'under-voltage', true], [1, 'over-voltage', true], [2, 'low temperature', true],
    [3, 'high temperature', true], [4, 'charging', false], [5, 'discharging', false],
    [7, 'battery line fault', true]],
  nav_status: [[0, 'off-track', true], [1, 'localization lost', true], [2, '3D obstacle', true]],
  sensor_status: [[0, 'visible camera alarm', true], [1, 'thermal imager alarm', true]],
};

// robot_status fields in the operator's words
const FIELD_WORDS = { mode: 'mode', 'backend link': 'backend link', pose: 'pose', speed: 'speed', battery: 'battery',
  battery_status: 'battery state', wheel_status: 'wheels', light_status: 'lights and e-stops',
  stop_status: 'stop sensors', circuit_status: 'circuits', nav_status: 'navigation', sensor_status: 'sensors',
  motors: 'motors', temperatures: 'temperatures' };

const MOTORS = ['LF servo', 'RF servo', 'RR servo', 'LR servo', 'LF stepper', 'RF stepper', 'RR stepper',
  'LR stepper'];
const TEMPERATURES = ['battery', 'servo LF', 'servo RF', 'servo RR', 'servo LR', 'stepper LF', 'stepper RF',
  'stepper RR', 'stepper LR', 'IPC', 'motion control card', 'pod inside', 'pod outside'];

/** The set bits of ``value`` in ``field`` as [{words, alarm}]. */
export function bits(field, value) {
  return BITS[field].filter(([bit]) => (value >> bit) & 1).map(([, words, alarm]) => ({ words, alarm }));
}

/** A uint8[] field as numbers: rosbridge's JSON carries uint8[] as base64, CBOR as bytes. */
export function byteArray(value) {
  if (typeof value !== 'string') return Array.from(value || []);
  const text = typeof atob === 'function' ? atob(value) : Buffer.from(value, 'base64').toString('binary');
  return Array.from(text, (c) => c.charCodeAt(0));
}

/** ``work(item)`` (may return a promise) run one at a time, newest first: what arrives while one runs
    replaces whatever was waiting, so a slow JPEG decoder draws the latest video frame instead of
    working through stale ones. The returned function takes items; its ``skipped`` counts the replaced. */
export function newestOnly(work) {
  let busy = false;
  let waiting = null;
  const push = (item) => {
    if (busy) {
      if (waiting !== null) push.skipped += 1;
      waiting = item;
      return;
    }
    busy = true;
    Promise.resolve().then(() => work(item)).catch(() => {}).then(() => {
      busy = false;
      if (waiting !== null) {
        const next = waiting;
        waiting = null;
        push(next);
      }
    });
  };
  push.skipped = 0;
  return push;
}

/** Motor faults as words: servo b0 disconnected / b4 fault, stepper b0 error (motor_status). */
function motorFaults(motorStatus) {
  const faults = [];
  byteArray(motorStatus).forEach((value, i) => {
    const servo = i < 4;
    if (value & 1) faults.push(t(servo ? '{motor} disconnected' : '{motor} error', { motor: t(MOTORS[i]) }));
    if (servo && (value >> 4) & 1) faults.push(t('{motor} fault', { motor: t(MOTORS[i]) }));
  });
  return faults;
}

/** Everything the status panel shows, in words: {mode, offline, rows: [{name (the field), label (its
    words), text, alarm}], alarms}. */
export function decodeStatus(msg) {
  const rows = [];
  const alarms = [];
  const add = (name, text, alarm) => {
    const label = t(FIELD_WORDS[name] || name);
    rows.push({ name, label, text, alarm: !!alarm });
    if (alarm) alarms.push(label + ': ' + text);
  };
  add('mode', MODES[msg.mode] !== undefined ? t(MODES[msg.mode]) : t('unknown ({mode})', { mode: msg.mode }), false);
  add('backend link', msg.offline_warn ? t('OFFLINE (no server heartbeat)') : t('online'), msg.offline_warn);
  const pos = msg.position || [];
  add('pose', pos.length >= 2
    ? 'x ' + pos[0].toFixed(2) + ' m, y ' + pos[1].toFixed(2) + ' m, ' + t('yaw') + ' '
      + (msg.orientation * 180 / Math.PI).toFixed(1) + '°'
    : t('unknown'), false);
  add('speed', (msg.velocity_x).toFixed(2) + ' m/s, ' + (msg.velocity_yaw).toFixed(2) + ' rad/s', false);
  add('battery', msg.battery_quantity + ' %, ' + (msg.battery_voltage / 10).toFixed(1) + ' V, '
    + (msg.battery_current / 10).toFixed(1) + ' A', msg.battery_quantity <= 10);
  for (const field of ['battery_status', 'wheel_status', 'light_status', 'stop_status', 'circuit_status',
    'nav_status', 'sensor_status']) {
    const set = bits(field, msg[field] || 0);
    if (!set.length) {
      add(field, t('none'), false);
    }
    for (const bit of set) add(field, t(bit.words), bit.alarm);
  }
  const motors = motorFaults(msg.motor_status);
  add('motors', motors.length ? motors.join(', ') : t('ok'), motors.length > 0);
  const temps = (msg.temperature || []).map((tenths, i) => (tenths === -1000 ? null : t(TEMPERATURES[i]) + ' '
    + (tenths / 10).toFixed(1) + ' °C')).filter((text) => text);
  add('temperatures', temps.length ? temps.join(', ') : t('not sampled'), false);
  return { mode: msg.mode, offline: !!msg.offline_warn, rows, alarms };
}

/** The needle angle of picture point ``p`` about the centre of ``box`` [x0, y0, x1, y1] (px, y down):
    degrees clockwise from 12 o'clock, as calibration_control's set_zero / set_full_scale take it. */
export function needleAngle(box, p) {
  const [x0, y0, x1, y1] = box;
  return Math.atan2(p[0] - (x0 + x1) / 2, (y0 + y1) / 2 - p[1]) * 180 / Math.PI;
}

/** An axis-aligned box [x0, y0, x1, y1] as calibration's 8 numbers TL, TR, BR, BL (0.1 px). */
export function boxQuad(box) {
  const [x0, y0, x1, y1] = box;
  return [x0, y0, x1, y0, x1, y1, x0, y1].map((v) => Math.round(v * 10) / 10);
}

/** The task a task_status is about (the running one, else the last ended; '' for none) and a key that
    changes when its progress or state does: what the readings and the review queue follow. */
export function statusTask(status) {
  const task = status.task_id || (status.last_ended && status.last_ended.task_id) || '';
  return { task, key: task + '|' + status.done + '|' + status.state };
}

// task_manager's alarm states, most urgent first (src/inspection_robot/task/states.py ALARM_ORDER)
const ALARM_ORDER = { alarm: 0, check: 1, warning: 2, failed: 3, trend: 4, normal: 5, none: 6 };
// an alarm state in the operator's words where its code does not say it
const ALARM_WORDS = { none: 'no limits', check: 'check (uncertain, outside its band)', alarm: 'alarm',
  warning: 'warning', failed: 'failed', trend: 'trend', normal: 'normal' };

/** An alarm state in words: "none" is "no limits" (a reading without limits is never "normal"). */
export function alarmWords(state) {
  return t(ALARM_WORDS[state] || state);
}
/** A reading's alarm as the report states it: the reviewed value's once an operator reviewed it. */
export function readingAlarm(row) {
  return row.review_time !== null && row.review_time !== undefined && row.review_alarm ? row.review_alarm : row.alarm;
}

const alarmRank = (row) => (readingAlarm(row) in ALARM_ORDER ? ALARM_ORDER[readingAlarm(row)] : ALARM_ORDER.none);

/** query_results rows, alarms and checks first, then failures, then the rest; newest first within each. */
export function sortReadings(rows) {
  return rows.slice().sort((a, b) => alarmRank(a) - alarmRank(b) || b.time - a.time);
}

/** A reading's limits in words: "[0, 1]", with its alarm band "[0, 1] (alarm outside [-1, 2])", or
    "no limits". */
export function limitsText(row) {
  if (row.low === null || row.low === undefined) return t('no limits');
  const alarm = row.alarm_low !== null && row.alarm_low !== undefined
    ? ' ' + t('(alarm outside [{low}, {high}])', { low: row.alarm_low, high: row.alarm_high }) : '';
  return '[' + row.low + ', ' + row.high + ']' + alarm;
}

/** A reading's value in words: "0.788 MPa [0, 1]", "failed: <reason>", an uncertain one
    "0.97 MPa [0.2, 0.8] uncertain: <reason>" and a reviewed one "... reviewed by li: 0.62 MPa". */
export function readingText(row) {
  if (row.status === 'failed' || row.value === null) return t('failed') + ': ' + row.reason;
  const band = ' ' + limitsText(row);
  // the robot's text (rounded to the meter's resolution, with unit) when the row carries it
  const number = (value) => Number(value.toPrecision(4)) + (row.unit ? ' ' + unitText(row.unit) : '');
  let text = (row.display ? displayText(row.display, row) : number(row.value)) + band;
  if (row.status === 'uncertain') text += ' ' + t('uncertain') + ': ' + row.reason;
  if (row.review_time !== null && row.review_time !== undefined) {
    text += ' · ' + t('reviewed by {name}', { name: row.review_by }) + ': ' + (row.review_value === row.value
      ? t('confirmed') : (row.review_display ? displayText(row.review_display, row) : number(row.review_value)));
  }
  return text;
}

/** The robot's ``display`` text (task.display: English words, ``C`` for degrees) for the operator: lamp
    and switch states and object counts in the page's language, °C. */
export function displayText(display, row) {
  if (row.kind === 'lamp' || row.kind === 'switch') return t(display);
  const objects = /^(\d+) objects?$/.exec(display);
  if (row.kind === 'foreign' && objects) return t('{n} object(s)', { n: objects[1] });
  return row.unit === 'C' ? display.replace(/ C$/, ' °C') : display;
}

/* One calibration self-check entry (calibration_control apply/upload) in words. */
export function selfCheckText(check) {
  if (check.read === null) return t('the robot cannot read it') + ': ' + check.reason;
  let text = t('the robot reads {value} ({confidence} %)', { value: Number(check.read.toPrecision(4)),
    confidence: Math.round(check.confidence) });
  if (check.expected !== null) {
    text += ', ' + t('you {value}: {apart} % of full scale apart', { value: check.expected, apart: check.apart_fs_pct });
  }
  text += check.reason ? ' (' + check.reason + ')' : '';
  if (check.needle_model) {   // learned at calibration (docs/interface.md, read_scale: "This meter's needle")
    text += '; ' + (check.needle_model.startsWith('learned') ? t('needle model learned') : t('no needle model'));
  }
  return text;
}


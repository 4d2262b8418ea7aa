/* A meter's limits as the calibration keeps them (calibration_control: ``normal`` [low, high] and the
   ``alarm_band`` around it; between the two a reading is a warning) and as the limits editor shows
   them: four number fields for a value, the expected state for a lamp or a switch. No DOM: the limits
   panel (limits.js) draws, this checks, and node tests it. The robot checks again (one schema,
   inspection/calibration_schema.py); these checks only answer before a round trip. */
import { t } from './i18n.js';

// read_scale's state codes (docs/interface.md, read_scale_ack ``scale``): lamps 0 off, 1.. their colour
export const LAMP_COLOURS = ['red', 'green', 'yellow', 'blue', 'white'];
export const SWITCH_STATES = [['closed', 1], ['open', 0]];

/** Whether ``kind``'s readings are state codes (an expected state) rather than values (bands). */
export function statesKind(kind) {
  return kind === 'lamp' || kind === 'switch';
}

/** The expected states a target may be given: [[words, code]]. */
export function stateChoices(target) {
  if (target.kind === 'switch') return SWITCH_STATES.map(([words, code]) => [t(words), code]);
  const code = LAMP_COLOURS.indexOf(target.colour) + 1;
  return [[t('off'), 0]].concat(code > 0 ? [[t('on ({colour})', { colour: t(target.colour) }), code]] : []);
}

/** The editor's fields of a calibrated target: {low, high, alarmLow, alarmHigh} as text ('' when
    unset), or {state} (the expected code as text) for a lamp or a switch. */
export function limitFields(target) {
  const normal = target.normal || null;
  if (statesKind(target.kind)) return { state: normal && normal[0] === normal[1] ? String(normal[0]) : '' };
  const alarm = target.alarm_band || null;
  const text = (band, i) => (band ? String(band[i]) : '');
  return { low: text(normal, 0), high: text(normal, 1), alarmLow: text(alarm, 0), alarmHigh: text(alarm, 1) };
}

function number(text, what) {
  const value = Number(text);
  if (text.trim() === '' || !Number.isFinite(value)) {
    throw new Error(t('{what} must be a number, got "{text}"', { what: t(what), text }));
  }
  return value;
}

function band(lowText, highText, what) {
  if (lowText.trim() === '' && highText.trim() === '') return null;
  if (lowText.trim() === '' || highText.trim() === '') {
    throw new Error(t('{what} needs both its low and its high', { what: t(what) }));
  }
  const low = number(lowText, what + ' low');
  const high = number(highText, what + ' high');
  if (low > high) throw new Error(t('{what}: low {low} is above high {high}', { what: t(what), low, high }));
  return [low, high];
}

/** The calibration keys of the editor's ``fields`` for ``target``: {normal, alarm_band} (null: no such
    band); an Error naming the field for text that is not a number, a band with one end, low above
    high, an alarm band without a normal band or not around it. */
export function limitKeys(target, fields) {
  if (statesKind(target.kind)) {
    if (fields.state === '') return { normal: null, alarm_band: null };
    const code = number(fields.state, 'expected state');
    return { normal: [code, code], alarm_band: null };
  }
  const normal = band(fields.low, fields.high, 'normal band');
  const alarm = band(fields.alarmLow, fields.alarmHigh, 'alarm band');
  if (alarm && !normal) throw new Error(t('an alarm band needs a normal band inside it'));
  if (alarm && (alarm[0] > normal[0] || alarm[1] < normal[1])) {
    throw new Error(t('alarm band [{alarm}] must contain the normal band [{normal}]',
      { alarm: alarm.join(', '), normal: normal.join(', ') }));
  }
  return { normal, alarm_band: alarm };
}

/** ``target`` (as calibration_control get answers it) with ``keys`` applied: a null key removed. */
export function withLimits(target, keys) {
  const out = Object.assign({}, target);
  for (const key of ['normal', 'alarm_band']) {
    if (keys[key]) out[key] = keys[key];
    else delete out[key];
  }
  return out;
}

/* The patrol planner's arithmetic, kept apart from the page so node's test runner checks it: the
   preset catalog (which preset reads which meters, at which stop pose), picked presets grouped into
   stops, the task JSON task_manager takes (submit, plan, routine_save), the planned route in words,
   and schedules (a form's fields checked, their runs in words). No DOM, no link. */
import { t } from './i18n.js';

export const STOP_MERGE_M = 0.25;      // presets recorded this close together share a stop
export const MAX_PRESETS_PER_STOP = 20;   // task_manager's limit per stop
export const WEEKDAYS = ['mon', 'tue', 'wed', 'thu', 'fri', 'sat', 'sun'];
const NAME_PATTERN = /^[A-Za-z0-9_-]{1,50}$/;   // a routine name (its runs' ids add _YYYYMMDD_HHMM)
const SCHEDULE_PATTERN = /^[A-Za-z0-9_-]{1,64}$/;
const TIME_PATTERN = /^([01][0-9]|2[0-3]):[0-5][0-9]$/;
const DATE_PATTERN = /^[0-9]{4}-[0-9]{2}-[0-9]{2}$/;
const DAY_NAMES = ['Sun', 'Mon', 'Tue', 'Wed', 'Thu', 'Fri', 'Sat'];   // Date.getDay() order

/** A new task id, ``patrol_<YYYYMMDD_HHMMSS>`` (UTC): ids are never reused, so one per submission. */
export function taskId(date) {
  return 'patrol_' + date.toISOString().replace(/[-:]/g, '').replace('T', '_').slice(0, 15);
}

/** One catalog entry from calibration_control get's answer of a preset's newest recording:
    {id, directory, pose {x, y, yaw} or null, meters (target names), calibrated}. */
export function catalogEntry(id, answer) {
  const pose = answer.info && answer.info.pose;
  return { id, directory: answer.preset,
    pose: Array.isArray(pose) && pose.length === 3 ? { x: pose[0], y: pose[1], yaw: pose[2] } : null,
    meters: answer.targets.map((t) => t.name).filter((name) => name),
    calibrated: !!answer.calibrated };
}

/** The entries whose preset id or a meter name contains every word of ``query`` (any case), by id. */
export function searchCatalog(catalog, query) {
  const words = query.toLowerCase().split(/\s+/).filter((w) => w);
  return catalog.filter((e) => {
    const text = (e.id + ' ' + e.meters.join(' ')).toLowerCase();
    return words.every((w) => text.includes(w));
  }).sort((a, b) => (a.id < b.id ? -1 : a.id > b.id ? 1 : 0));
}

const apart = (a, b) => Math.hypot(a.x - b.x, a.y - b.y);

/** The entries of the stop nearest to ``world`` [x, y] within ``tolerance`` m: every calibrated preset
    recorded at that stop's pose (within STOP_MERGE_M of the nearest one). */
export function entriesAt(catalog, world, tolerance) {
  const here = { x: world[0], y: world[1] };
  let nearest = null;
  for (const e of catalog) {
    if (!e.pose || !e.calibrated) continue;
    const d = apart(e.pose, here);
    if (d <= tolerance && (!nearest || d < apart(nearest.pose, here))) nearest = e;
  }
  if (!nearest) return [];
  return catalog.filter((e) => e.pose && e.calibrated && apart(e.pose, nearest.pose) <= STOP_MERGE_M);
}

/** ``stops`` with the presets of ``entries`` added: a preset joins the stop (of the same pose, within
    STOP_MERGE_M, not full) or starts one named after it; one already planned is not added twice.
    Returns {stops (a new list), added, skipped: [reasons]}. Stops: [{name, pose, presets: [directory]}]. */
export function addPresets(stops, entries) {
  const out = stops.map((s) => Object.assign({}, s, { presets: s.presets.slice() }));
  const planned = new Set(out.flatMap((s) => s.presets));
  const skipped = [];
  let added = 0;
  for (const e of entries) {
    if (!e.calibrated) {
      skipped.push(e.id + ': not calibrated');
    } else if (!e.pose) {
      skipped.push(e.id + ': its preset.ini has no pose');
    } else if (planned.has(e.directory)) {
      skipped.push(e.id + ': already planned');
    } else {
      let stop = out.find((s) => apart(s.pose, e.pose) <= STOP_MERGE_M && s.presets.length < MAX_PRESETS_PER_STOP);
      if (!stop) {
        stop = { name: uniqueName(out, e.id), pose: Object.assign({}, e.pose), presets: [] };
        out.push(stop);
      }
      stop.presets.push(e.directory);
      planned.add(e.directory);
      added += 1;
    }
  }
  return { stops: out, added, skipped };
}

function uniqueName(stops, base) {
  const names = new Set(stops.map((s) => s.name));
  let name = base.slice(0, 60);
  for (let i = 2; names.has(name); i++) name = base.slice(0, 60) + '_' + i;
  return name;
}

/** ``stops`` without preset ``directory`` (a stop left empty goes too). */
export function removePreset(stops, directory) {
  return stops.map((s) => Object.assign({}, s, { presets: s.presets.filter((p) => p !== directory) }))
    .filter((s) => s.presets.length);
}

/** The task JSON for submit / plan / routine_save. ``options``: {id (omitted for a routine), order
    (shortest|given), retries}. Throws an Error saying what is missing. */
export function buildTask(stops, options) {
  if (!stops.length) throw new Error(t('pick at least one preset or stop first'));
  const task = {};
  if (options.id) task.id = options.id;
  task.priority = 'routine';
  task.order = options.order || 'shortest';
  if (options.retries !== undefined && options.retries !== '') {
    const retries = Number(options.retries);
    if (!Number.isInteger(retries) || retries < 0 || retries > 10) throw new Error(t('retries must be 0 to 10'));
    task.retries = retries;
  }
  task.stops = stops.map((s) => ({ name: s.name, pose: { x: s.pose.x, y: s.pose.y, yaw: s.pose.yaw }, precision: 0,
    presets: s.presets.slice() }));
  return task;
}

/** A task's stops (as submit, plan and routine_list give them) as planner stops. */
export function stopsOfTask(task) {
  return task.stops.map((s, i) => ({ name: s.name || 'stop_' + (i + 1), pose: Object.assign({}, s.pose),
    presets: s.presets.map((p) => (typeof p === 'string' ? p : p.preset)) }));
}

/** task_control plan's answer in words: "123.4 m planned, 3 stops (shortest): a → b → c". */
export function routeText(answer) {
  const length = answer.planned_length_m === null || answer.planned_length_m === undefined ? t('unknown length')
    : t('{m} m planned', { m: answer.planned_length_m.toFixed(1) });
  return length + ', ' + t(answer.stops.length === 1 ? '{n} stop' : '{n} stops', { n: answer.stops.length })
    + ' (' + t(answer.order) + '): ' + answer.stops.map((s) => s.name).join(' → ');
}

const two = (n) => String(n).padStart(2, '0');

/** Unix time ``at`` in the page's local time, "Sat 2026-11-28 08:00", with how far from ``now`` (unix s):
    "(in 2 h 5 min)", "(3 d ago)"; "none" for null. */
export function whenText(at, now) {
  if (at === null || at === undefined) return t('none');
  const d = new Date(at * 1000);
  const text = t(DAY_NAMES[d.getDay()]) + ' ' + d.getFullYear() + '-' + two(d.getMonth() + 1) + '-' + two(d.getDate())
    + ' ' + two(d.getHours()) + ':' + two(d.getMinutes());
  return now === undefined ? text : text + ' (' + relative(at - now) + ')';
}

function relative(seconds) {
  const s = Math.abs(seconds);
  const minutes = Math.round(s / 60);
  let span;
  if (s < 60) span = Math.round(s) + ' s';
  else if (minutes < 60) span = minutes + ' min';
  else if (s < 2 * 86400) span = Math.floor(minutes / 60) + ' h ' + (minutes % 60) + ' min';
  else span = Math.round(s / 86400) + ' d';
  return t(seconds >= 0 ? 'in {span}' : '{span} ago', { span });
}

/** schedule_set's JSON from the form's fields {name, routine, time, repeat ('weekdays'|'date'),
    weekdays: [..], date, enabled}; throws an Error with the field's fault. */
export function scheduleRequest(fields) {
  if (!SCHEDULE_PATTERN.test(fields.name || '')) throw new Error(t('schedule name: 1-64 letters, digits, _ or -'));
  if (!fields.routine) throw new Error(t('choose a saved routine'));
  if (!TIME_PATTERN.test(fields.time || '')) throw new Error(t('time must be HH:MM (robot local time)'));
  const out = { name: fields.name, routine: fields.routine, time: fields.time };
  if (fields.repeat === 'date') {
    if (!DATE_PATTERN.test(fields.date || '')) throw new Error(t('date must be YYYY-MM-DD'));
    out.date = fields.date;
  } else {
    const days = WEEKDAYS.filter((d) => (fields.weekdays || []).includes(d));
    if (!days.length) throw new Error(t('tick at least one weekday'));
    out.weekdays = days;
  }
  out.enabled = !!fields.enabled;
  return out;
}

/** A routine name as routine_save takes it, or an Error. */
export function routineName(name) {
  if (!NAME_PATTERN.test(name)) throw new Error(t('routine name: 1-50 letters, digits, _ or -'));
  return name;
}

/** One schedule_list row in words: {name, routine, when, enabled, next, last, missed, missedCount}. */
export function scheduleText(row, now) {
  const when = row.time + ' ' + (row.date ? t('on {date}', { date: row.date })
    : row.weekdays.length === 7 ? t('daily') : row.weekdays.map((d) => t(d)).join(' '));
  const last = row.last_run ? whenText(row.last_run.at, now) + ': ' + row.last_run.task_id
    + (row.last_run.state ? ' ' + t(row.last_run.state) : '') : t('never');
  const missed = (row.missed || []).map((m) => whenText(m.at) + ': ' + m.reason);
  return { name: row.name, routine: row.routine, when, enabled: t(row.enabled ? 'yes' : 'no'),
    next: row.enabled ? whenText(row.next_run, now) : t('disabled'), last, missed, missedCount: missed.length };
}

/* The trend chart's data, without DOM or chart library (node tests it): the readings of several meters
   (query_results rows) as one table on a shared time axis, as uPlot takes it, each meter with its
   value, the limits each reading was judged by (so a band drawn is the band of its time) and the state
   of each point; and the same readings as CSV. */
import { readingAlarm } from './decode.js';

export const TREND_RANGES = { '7 days': 7, '30 days': 30, '90 days': 90, '1 year': 365 };
export const MAX_TREND_METERS = 6;
// a point's colour by its state, as the report's (src/inspection_robot/task/report.py STATE_COLOURS)
export const POINT_COLOURS = { normal: '#2e7d32', none: '#1565c0', warning: '#b8860b', alarm: '#c62828',
  check: '#ef6c00', trend: '#f9a825', uncertain: '#6a1b9a', corrected: '#00838f' };

const given = (v) => v !== null && v !== undefined;

/** The state a point is drawn with: an operator's correction, an uncertain value nobody reviewed, else
    its alarm as the report states it. */
export function pointState(row) {
  if (given(row.review_time) && given(row.review_value) && row.review_value !== row.value) return 'corrected';
  if (row.status === 'uncertain' && !given(row.review_time) && row.alarm !== 'check') return 'uncertain';
  return readingAlarm(row);
}

/** ``meters`` [{target, unit, rows}] as one table: ``x`` the union of reading times (unix s, ascending),
    and per meter ``values``, ``low``, ``high``, ``alarmLow``, ``alarmHigh`` and ``states`` aligned to
    ``x`` (null where the meter has no reading, or no such limit, at that time). Failed readings have no
    value and are left out; a reviewed reading shows the operator's value. */
export function trendTable(meters) {
  const usable = meters.map((m) => ({ target: m.target, unit: m.unit,
    rows: m.rows.filter((r) => given(r.value) || given(r.review_value)).sort((a, b) => a.time - b.time) }));
  const x = Array.from(new Set([].concat(...usable.map((m) => m.rows.map((r) => r.time))))).sort((a, b) => a - b);
  const at = new Map(x.map((t, i) => [t, i]));
  const series = usable.map((m) => {
    const column = () => x.map(() => null);
    const s = { target: m.target, unit: m.unit, values: column(), low: column(), high: column(), alarmLow: column(),
      alarmHigh: column(), states: column(), points: m.rows.length };
    for (const r of m.rows) {
      const i = at.get(r.time);
      s.values[i] = given(r.review_value) && given(r.review_time) ? r.review_value : r.value;
      s.states[i] = pointState(r);
      if (given(r.low)) [s.low[i], s.high[i]] = [r.low, r.high];
      if (given(r.alarm_low)) [s.alarmLow[i], s.alarmHigh[i]] = [r.alarm_low, r.alarm_high];
    }
    return s;
  });
  return { x, series };
}

function csvField(value) {
  const text = given(value) ? String(value) : '';
  return /[",\n\r]/.test(text) ? '"' + text.replace(/"/g, '""') + '"' : text;
}

/** The readings of ``meters`` as CSV text: one line per reading, oldest first, with its time in UTC
    (ISO 8601) and in unix seconds, and the limits it was judged by. */
export function trendCsv(meters) {
  const columns = ['time_utc', 'time', 'target', 'value', 'unit', 'status', 'alarm', 'low', 'high', 'alarm_low',
    'alarm_high', 'review_value', 'review_by', 'task_id', 'stop_name'];
  const rows = [].concat(...meters.map((m) => m.rows)).sort((a, b) => a.time - b.time || (a.id || 0) - (b.id || 0));
  const lines = rows.map((r) => [new Date(r.time * 1000).toISOString(), r.time, r.target_name, r.value, r.unit,
    r.status, readingAlarm(r), r.low, r.high, r.alarm_low, r.alarm_high, r.review_value, r.review_by, r.task_id,
    r.stop_name].map(csvField).join(','));
  return [columns.join(',')].concat(lines).join('\n') + '\n';
}

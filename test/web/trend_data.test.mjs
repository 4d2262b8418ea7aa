// node --test: the trend chart's data (trend_data.js): several meters on one time axis, each reading with
// the limits of its own time and its own state; CSV export.
import assert from 'node:assert';
import test from 'node:test';

import { pointState, trendCsv, trendTable } from '../../web/console/trend_data.js';

const row = (target, time, value, extra) => Object.assign({ id: time, target_name: target, time, value, unit: 'C',
  status: 'read', alarm: 'normal', low: 0, high: 85, alarm_low: null, alarm_high: null, review_value: null,
  review_time: null, task_id: 't' + time, stop_name: 's' }, extra);

test('two meters on one time axis, each point with the limits it was judged by', () => {
  const oil = [row('oil', 30, 118, { alarm: 'none', low: null, high: null }), row('oil', 10, 50),
    row('oil', 20, 90, { alarm: 'warning', alarm_low: -10, alarm_high: 95 })];
  const amps = [row('amps', 20, 300, { unit: 'A', low: 0, high: 500 }), row('amps', 25, null, { status: 'failed' })];
  const t = trendTable([{ target: 'oil', unit: 'C', rows: oil }, { target: 'amps', unit: 'A', rows: amps }]);
  assert.deepStrictEqual(t.x, [10, 20, 30]);   // the failed reading has no point
  const [o, a] = t.series;
  assert.deepStrictEqual(o.values, [50, 90, 118]);
  assert.deepStrictEqual([o.low, o.high], [[0, 0, null], [85, 85, null]]);   // no band on the patrol without limits
  assert.deepStrictEqual([o.alarmLow, o.alarmHigh], [[null, -10, null], [null, 95, null]]);
  assert.deepStrictEqual(o.states, ['normal', 'warning', 'none']);   // 118 without limits is not drawn "normal"
  assert.deepStrictEqual(a.values, [null, 300, null]);
  assert.deepStrictEqual([o.points, a.points], [3, 1]);
  assert.deepStrictEqual(trendTable([]), { x: [], series: [] });
});

test('a point\'s state: corrected, uncertain, else its stated alarm', () => {
  assert.strictEqual(pointState(row('oil', 1, 90, { status: 'uncertain', review_time: 5, review_value: 55,
    review_alarm: 'normal' })), 'corrected');
  assert.strictEqual(pointState(row('oil', 1, 50, { status: 'uncertain' })), 'uncertain');
  assert.strictEqual(pointState(row('oil', 1, 99, { status: 'uncertain', alarm: 'check' })), 'check');
  assert.strictEqual(pointState(row('oil', 1, 50, { status: 'uncertain', review_time: 5, review_value: 50,
    review_alarm: 'normal' })), 'normal');   // confirmed
  const t = trendTable([{ target: 'oil', unit: 'C', rows: [row('oil', 1, 90, { status: 'uncertain', review_time: 5,
    review_value: 55, review_alarm: 'normal' })] }]);
  assert.deepStrictEqual(t.series[0].values, [55]);   // the operator's value
});

test('CSV: one line per reading, oldest first, quoted where needed, UTC time', () => {
  const csv = trendCsv([{ target: 'oil', rows: [row('oil', 86400, 50, { stop_name: 'bay "3", north' }),
    row('oil', 0, 40)] }, { target: 'amps', rows: [row('amps', 3600, 300, { unit: 'A' })] }]);
  const lines = csv.trim().split('\n');
  assert.strictEqual(lines[0], 'time_utc,time,target,value,unit,status,alarm,low,high,alarm_low,alarm_high,'
    + 'review_value,review_by,task_id,stop_name');
  assert.deepStrictEqual(lines.slice(1).map((l) => l.split(',').slice(0, 4).join(',')), [
    '1970-01-01T00:00:00.000Z,0,oil,40', '1970-01-01T01:00:00.000Z,3600,amps,300', '1970-01-02T00:00:00.000Z,86400,oil,50']);
  assert.ok(lines[3].endsWith(',t86400,"bay ""3"", north"'), lines[3]);
});

// node --test: the patrol planner's arithmetic (web/console/planning.js): the preset catalog, picked
// presets grouped into stops, the task JSON, the route and schedules in words.
import assert from 'node:assert';
import test from 'node:test';

import { addPresets, buildTask, catalogEntry, entriesAt, removePreset, routeText, routineName, scheduleRequest,
  scheduleText, searchCatalog, stopsOfTask, taskId, whenText } from '../../web/console/planning.js';

// calibration_control get's answers, as the robot gives them
const get = (id, pose, names, calibrated = true) => catalogEntry(id, { preset: 'presets/' + id + '/20261127_080000',
  calibrated, targets: names.map((name) => ({ name, kind: 'pointer' })), info: { pose } });
const catalog = [
  get('cabinet_1', [20, 21.4, 1.5708], ['cabinet_1/ammeter', 'cabinet_1/lamp_run']),
  get('cabinet_1_thermal', [20.1, 21.45, 1.5708], ['cabinet_1/hot_spot']),
  get('transformer_1', [5, 8, 0], ['transformer_1/oil_temp']),
  get('new_gauge', [9, 9, 0], [], false),
];

test('a catalog entry: directory, stop pose and meter names from calibration_control get', () => {
  assert.deepStrictEqual(catalog[0], { id: 'cabinet_1', directory: 'presets/cabinet_1/20261127_080000',
    pose: { x: 20, y: 21.4, yaw: 1.5708 }, meters: ['cabinet_1/ammeter', 'cabinet_1/lamp_run'], calibrated: true });
  assert.strictEqual(catalogEntry('x', { preset: 'presets/x/1', calibrated: false, targets: [], info: {} }).pose, null);
});

test('search: every word in the preset id or a meter name, any case, sorted by id', () => {
  assert.deepStrictEqual(searchCatalog(catalog, 'OIL').map((e) => e.id), ['transformer_1']);
  assert.deepStrictEqual(searchCatalog(catalog, 'cabinet hot').map((e) => e.id), ['cabinet_1_thermal']);
  assert.deepStrictEqual(searchCatalog(catalog, ' ').map((e) => e.id),
    ['cabinet_1', 'cabinet_1_thermal', 'new_gauge', 'transformer_1']);
});

test('picked presets grouped into stops: same pose one stop, in pick order; no duplicates; reasons', () => {
  const first = addPresets([], [catalog[2], catalog[0]]);
  assert.deepStrictEqual(first.stops.map((s) => [s.name, s.presets.length]), [['transformer_1', 1], ['cabinet_1', 1]]);
  const second = addPresets(first.stops, [catalog[1], catalog[0], catalog[3]]);
  assert.strictEqual(second.added, 1);
  assert.deepStrictEqual(second.stops[1].presets, ['presets/cabinet_1/20261127_080000',
    'presets/cabinet_1_thermal/20261127_080000']);
  assert.deepStrictEqual(second.skipped, ['cabinet_1: already planned', 'new_gauge: not calibrated']);
  assert.strictEqual(first.stops[1].presets.length, 1);   // the earlier list is not changed
  const fewer = removePreset(second.stops, 'presets/transformer_1/20261127_080000');
  assert.deepStrictEqual(fewer.map((s) => s.name), ['cabinet_1']);   // an emptied stop goes
});

test('a stop full at 20 presets: the 21st starts another stop at the same pose, with its own name', () => {
  const many = Array.from({ length: 21 }, (_, i) => get('p' + i, [1, 1, 0], ['m' + i]));
  const { stops } = addPresets([], many);
  assert.deepStrictEqual(stops.map((s) => [s.name, s.presets.length]), [['p0', 20], ['p20', 1]]);
  const again = addPresets(addPresets([], [get('a', [0, 0, 0], [])]).stops, [get('a', [5, 5, 0], [])]);
  assert.deepStrictEqual(again.stops.map((s) => s.name), ['a']);   // same directory: already planned
});

test('a click on the map picks every preset of the nearest stop within the tolerance', () => {
  assert.deepStrictEqual(entriesAt(catalog, [20.3, 21.2], 0.5).map((e) => e.id), ['cabinet_1', 'cabinet_1_thermal']);
  assert.deepStrictEqual(entriesAt(catalog, [5.2, 8], 0.5).map((e) => e.id), ['transformer_1']);
  assert.deepStrictEqual(entriesAt(catalog, [9, 9], 0.5), []);   // not calibrated
  assert.deepStrictEqual(entriesAt(catalog, [12, 12], 0.5), []);
});

test('the task JSON: submit with an id, a routine without; bad retries and no stops refused', () => {
  const { stops } = addPresets([], [catalog[0], catalog[1]]);
  assert.deepStrictEqual(buildTask(stops, { id: 'patrol_1', order: 'shortest', retries: '1' }), {
    id: 'patrol_1', priority: 'routine', order: 'shortest', retries: 1, stops: [{ name: 'cabinet_1',
      pose: { x: 20, y: 21.4, yaw: 1.5708 }, precision: 0,
      presets: ['presets/cabinet_1/20261127_080000', 'presets/cabinet_1_thermal/20261127_080000'] }] });
  assert.strictEqual('id' in buildTask(stops, { order: 'given' }), false);
  assert.throws(() => buildTask([], {}), /pick at least one/);
  assert.throws(() => buildTask(stops, { retries: '11' }), /retries must be 0 to 10/);
  const task = buildTask(stops, { order: 'given' });
  assert.deepStrictEqual(stopsOfTask(task), stops);
  assert.deepStrictEqual(stopsOfTask({ stops: [{ pose: { x: 1, y: 2, yaw: 0 }, presets: [{ preset: 'p' }, 'q'] }] }),
    [{ name: 'stop_1', pose: { x: 1, y: 2, yaw: 0 }, presets: ['p', 'q'] }]);
  assert.strictEqual(taskId(new Date(Date.UTC(2026, 10, 27, 8, 5, 9))), 'patrol_20261127_080509');
});

test('the planned route in words', () => {
  assert.strictEqual(routeText({ order: 'shortest', planned_length_m: 123.456, path: [],
    stops: [{ name: 'a' }, { name: 'b' }] }), '123.5 m planned, 2 stops (shortest): a → b');
  assert.strictEqual(routeText({ order: 'given', planned_length_m: null, stops: [{ name: 'a' }] }),
    'unknown length, 1 stop (given): a');
});

test('times in the page\'s local time with how far away', () => {
  const at = new Date(2026, 10, 28, 8, 0).getTime() / 1000;   // a Saturday
  assert.strictEqual(whenText(at), 'Sat 2026-11-28 08:00');
  assert.strictEqual(whenText(at, at - 2 * 3600 - 5 * 60), 'Sat 2026-11-28 08:00 (in 2 h 5 min)');
  assert.strictEqual(whenText(at, at + 3 * 86400), 'Sat 2026-11-28 08:00 (3 d ago)');
  assert.strictEqual(whenText(at, at - 30), 'Sat 2026-11-28 08:00 (in 30 s)');
  assert.strictEqual(whenText(null, at), 'none');
});

test('a schedule from the form: weekdays in week order or one date; each fault named', () => {
  const form = { name: 'morning', routine: 'yard', time: '08:00', repeat: 'weekdays', weekdays: ['fri', 'mon'],
    date: '', enabled: true };
  assert.deepStrictEqual(scheduleRequest(form), { name: 'morning', routine: 'yard', time: '08:00',
    weekdays: ['mon', 'fri'], enabled: true });
  assert.deepStrictEqual(scheduleRequest(Object.assign({}, form, { repeat: 'date', date: '2026-12-01', enabled: false })),
    { name: 'morning', routine: 'yard', time: '08:00', date: '2026-12-01', enabled: false });
  assert.throws(() => scheduleRequest(Object.assign({}, form, { time: '8:00' })), /HH:MM/);
  assert.throws(() => scheduleRequest(Object.assign({}, form, { time: '24:00' })), /HH:MM/);
  assert.throws(() => scheduleRequest(Object.assign({}, form, { weekdays: [] })), /weekday/);
  assert.throws(() => scheduleRequest(Object.assign({}, form, { repeat: 'date', date: '1.12.2026' })), /YYYY-MM-DD/);
  assert.throws(() => scheduleRequest(Object.assign({}, form, { name: 'a b' })), /schedule name/);
  assert.throws(() => scheduleRequest(Object.assign({}, form, { routine: '' })), /routine/);
  assert.strictEqual(routineName('yard_morning'), 'yard_morning');
  assert.throws(() => routineName('x'.repeat(51)), /1-50/);
});

test('a schedule_list row in words: next run, last run, missed runs', () => {
  const now = new Date(2026, 10, 27, 20, 0).getTime() / 1000;
  const next = new Date(2026, 10, 28, 8, 0).getTime() / 1000;
  const row = { name: 'morning', routine: 'yard', time: '08:00', weekdays: ['mon', 'tue', 'wed', 'thu', 'fri', 'sat',
    'sun'], enabled: true, next_run: next, last_run: { at: now - 12 * 3600, task_id: 'yard_20261127_0800',
    state: 'done' }, missed: [{ at: now - 36 * 3600, reason: 'task_manager was not running' }] };
  const text = scheduleText(row, now);
  assert.strictEqual(text.when, '08:00 daily');
  assert.strictEqual(text.next, 'Sat 2026-11-28 08:00 (in 12 h 0 min)');
  assert.strictEqual(text.last, 'Fri 2026-11-27 08:00 (12 h 0 min ago): yard_20261127_0800 done');
  assert.deepStrictEqual(text.missed, ['Thu 2026-11-26 08:00: task_manager was not running']);
  const off = scheduleText(Object.assign({}, row, { enabled: false, next_run: null, last_run: null, missed: [],
    weekdays: undefined, date: '2026-12-01' }), now);
  assert.deepStrictEqual([off.when, off.next, off.last, off.missedCount], ['08:00 on 2026-12-01', 'disabled', 'never', 0]);
});

// node --test: the limits editor's checks (bands.js) and the console's store (state.js).
import assert from 'node:assert';
import test from 'node:test';

import { limitFields, limitKeys, stateChoices, withLimits } from '../../web/console/bands.js';
import * as store from '../../web/console/state.js';

const gauge = { kind: 'pointer', name: 'oil', unit: 'C', normal: [0, 85], alarm_band: [-10, 95], box: [] };
const fields = (low, high, alarmLow, alarmHigh) => ({ low, high, alarmLow, alarmHigh });

test('a meter\'s bands become its calibration keys, and back', () => {
  assert.deepStrictEqual(limitFields(gauge), fields('0', '85', '-10', '95'));
  assert.deepStrictEqual(limitKeys(gauge, fields('0', '85', '-10', '95')), { normal: [0, 85], alarm_band: [-10, 95] });
  assert.deepStrictEqual(limitKeys(gauge, fields(' 1.5', '2e1', '', '')), { normal: [1.5, 20], alarm_band: null });
  assert.deepStrictEqual(limitKeys(gauge, fields('', '', '', '')), { normal: null, alarm_band: null });
  assert.deepStrictEqual(limitKeys(gauge, fields('0', '85', '0', '85')), { normal: [0, 85], alarm_band: [0, 85] });
  const cleared = withLimits(gauge, { normal: null, alarm_band: null });
  assert.ok(!('normal' in cleared) && !('alarm_band' in cleared) && cleared.name === 'oil');
  assert.deepStrictEqual(withLimits(gauge, { normal: [1, 2], alarm_band: null }).normal, [1, 2]);
  assert.deepStrictEqual(gauge.normal, [0, 85]);   // the target as get answered it is left alone
});

test('bad limits are refused with the field named', () => {
  const refused = (f, text) => assert.throws(() => limitKeys(gauge, f), (err) => err.message === text);
  refused(fields('NaN', '85', '', ''), 'normal band low must be a number, got "NaN"');
  refused(fields('0', 'Infinity', '', ''), 'normal band high must be a number, got "Infinity"');
  refused(fields('0', '', '', ''), 'normal band needs both its low and its high');
  refused(fields('90', '85', '', ''), 'normal band: low 90 is above high 85');
  refused(fields('', '', '-10', '95'), 'an alarm band needs a normal band inside it');
  refused(fields('0', '85', '5', '95'), 'alarm band [5, 95] must contain the normal band [0, 85]');
  refused(fields('0', '85', '-10', 'x'), 'alarm band high must be a number, got "x"');
});

test('lamps and switches take the state they should be in', () => {
  const lamp = { kind: 'lamp', colour: 'green', normal: [2, 2] };
  assert.deepStrictEqual(stateChoices(lamp), [['off', 0], ['on (green)', 2]]);
  assert.deepStrictEqual(limitFields(lamp), { state: '2' });
  assert.deepStrictEqual(limitKeys(lamp, { state: '0' }), { normal: [0, 0], alarm_band: null });
  assert.deepStrictEqual(limitKeys({ kind: 'switch' }, { state: '' }), { normal: null, alarm_band: null });
  assert.deepStrictEqual(stateChoices({ kind: 'switch' }), [['closed', 1], ['open', 0]]);
});

test('the store: values and news reach their listeners; a misspelt key throws', () => {
  const seen = [];
  const off = store.on('task', (v) => seen.push(v));
  store.on('task', () => { throw new Error('a broken listener'); });   // logged, the others still hear
  const quiet = console.error;
  console.error = () => {};
  try {
    store.set('task', { state: 'idle' });
    store.emit('readings-changed', 't1');
    assert.deepStrictEqual(store.get('task'), { state: 'idle' });
    assert.deepStrictEqual(seen, [{ state: 'idle' }]);
    off();
    store.set('task', { state: 'running' });
    assert.strictEqual(seen.length, 1);
  } finally {
    console.error = quiet;
  }
  assert.throws(() => store.set('taks', 1), /unknown store key taks/);
  assert.throws(() => store.on('statuss', () => {}), /unknown store key statuss/);
  assert.strictEqual(store.get('readings-changed'), null);   // news keep no value
});

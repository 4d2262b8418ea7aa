// node --test: robot_status decoded into words, the calibration editor's and the history's arithmetic
// (web/console/decode.js) without a browser.
import assert from 'node:assert';
import test from 'node:test';

import { bits, boxQuad, byteArray, decodeStatus, needleAngle, newestOnly, readingAlarm, readingText, selfCheckText,
  sortReadings } from '../../web/console/decode.js';

const quiet = {
  offline_warn: 0, mode: 0, velocity_x: 0, velocity_yaw: 0, position: [1.5, -2.25], orientation: Math.PI / 2,
  nav_status: 0, sensor_status: 0, wheel_status: 1, light_status: 4, stop_status: 0, circuit_status: 0,
  battery_voltage: 532, battery_current: -15, battery_quantity: 90, battery_status: 32,
  motor_status: Buffer.alloc(8).toString('base64'), temperature: [251].concat(Array(12).fill(-1000)),
};

test('a quiet robot: words for every field, no alarm', () => {
  const d = decodeStatus(quiet);
  assert.deepStrictEqual(d.alarms, []);
  const text = Object.fromEntries(d.rows.map((r) => [r.name, r.text]));
  assert.strictEqual(text.mode, 'task');
  assert.strictEqual(text.pose, 'x 1.50 m, y -2.25 m, yaw 90.0°');
  assert.strictEqual(text.battery, '90 %, 53.2 V, -1.5 A');
  assert.strictEqual(text.battery_status, 'discharging');
  assert.strictEqual(text.light_status, 'lamp green');
  assert.strictEqual(text.temperatures, 'battery 25.1 °C');
});

test('alarms: offline, e-stops, falls, faults, low battery, motors (uint8[] as base64 or bytes)', () => {
  const d = decodeStatus(Object.assign({}, quiet, {
    offline_warn: 1, mode: 1, light_status: (1 << 4) | (1 << 5), stop_status: 1 << 6, circuit_status: 1 << 7,
    battery_quantity: 8, battery_status: 1, nav_status: 4, sensor_status: 2,
    motor_status: Buffer.from([1, 0, 0, 16, 1, 0, 0, 0]).toString('base64'),
  }));
  for (const words of ['OFFLINE', 'soft e-stop engaged', 'hard e-stop pressed', 'left fall alarm',
    'battery critically low', 'under-voltage', '3D obstacle', 'thermal imager alarm', 'LF servo disconnected',
    'LR servo fault', 'LF stepper error', '8 %']) {
    assert.ok(d.alarms.some((a) => a.includes(words)), words + ' in ' + d.alarms.join(' | '));
  }
  assert.strictEqual(d.rows[0].text, 'backend remote control');
  assert.deepStrictEqual(byteArray(new Uint8Array([3, 4])), [3, 4]);
});

test('every bit of the spec tables has words', () => {
  assert.deepStrictEqual(bits('wheel_status', 0xff).length, 8);
  assert.deepStrictEqual(bits('circuit_status', 0xff).length, 8);
  assert.deepStrictEqual(bits('battery_status', 0xff).map((b) => b.words).includes('charging'), true);
});

test('needle angles: clockwise from 12 o\'clock about the box centre, picture y down', () => {
  const box = [100, 50, 300, 250];   // centre (200, 150)
  assert.strictEqual(needleAngle(box, [200, 50]), 0);
  assert.strictEqual(needleAngle(box, [300, 150]), 90);
  assert.strictEqual(needleAngle(box, [100, 150]), -90);
  assert.ok(Math.abs(needleAngle(box, [100, 250]) + 135) < 1e-9);   // 7:30, a gauge's usual zero
  assert.ok(Math.abs(needleAngle(box, [300, 250]) - 135) < 1e-9);
});

test('a drawn box as calibration\'s TL, TR, BR, BL quad', () => {
  assert.deepStrictEqual(boxQuad([10.04, 20.26, 30, 40]), [10, 20.3, 30, 20.3, 30, 40, 10, 40]);
});

test('readings: alarms first, then failures, newest first within each', () => {
  const rows = [{ id: 1, alarm: 'normal', time: 5 }, { id: 2, alarm: 'alarm', time: 1 }, { id: 3, alarm: 'failed', time: 9 },
    { id: 4, alarm: 'alarm', time: 3 }, { id: 5, alarm: 'none', time: 7 }, { id: 6, alarm: 'check', time: 8 }];
  assert.deepStrictEqual(sortReadings(rows).map((r) => r.id), [4, 2, 6, 3, 1, 5]);
  assert.deepStrictEqual(rows.map((r) => r.id), [1, 2, 3, 4, 5, 6]);   // not sorted in place
});

test('a reviewed reading states and sorts by its reviewed alarm, as the report does', () => {
  const corrected = { id: 1, alarm: 'check', review_time: 10, review_alarm: 'normal', time: 9 };
  const open = { id: 2, alarm: 'check', review_time: null, review_alarm: '', time: 1 };
  assert.strictEqual(readingAlarm(corrected), 'normal');
  assert.strictEqual(readingAlarm(open), 'check');
  assert.strictEqual(readingAlarm({ alarm: 'alarm' }), 'alarm');   // rows of an older robot: no review columns
  assert.deepStrictEqual(sortReadings([corrected, open]).map((r) => r.id), [2, 1]);
});

test('a reading in words', () => {
  assert.strictEqual(readingText({ status: 'read', value: 0.78845570687, unit: 'MPa', low: 0, high: 1.6 }),
    '0.7885 MPa [0, 1.6]');
  assert.strictEqual(readingText({ status: 'read', value: 2, unit: '', low: null, high: null }), '2 no limits');
  assert.strictEqual(readingText({ status: 'failed', value: null, reason: 'find_scale failed' }),
    'failed: find_scale failed');
  const doubted = { status: 'uncertain', value: 0.97, unit: 'MPa', low: 0.2, high: 0.8, reason: 'glare', review_time: null };
  assert.strictEqual(readingText(doubted), '0.97 MPa [0.2, 0.8] uncertain: glare');
  assert.strictEqual(readingText(Object.assign({}, doubted, { review_time: 5, review_by: 'li', review_value: 0.62 })),
    '0.97 MPa [0.2, 0.8] uncertain: glare · reviewed by li: 0.62 MPa');
  assert.strictEqual(readingText(Object.assign({}, doubted, { review_time: 5, review_by: 'li', review_value: 0.97 })),
    '0.97 MPa [0.2, 0.8] uncertain: glare · reviewed by li: confirmed');
});

test('a reading in the robot\'s words: rounded to its meter\'s resolution', () => {
  const row = { status: 'read', value: 0.80273, unit: 'MPa', low: 0, high: 1.6, display: '0.80 MPa' };
  assert.strictEqual(readingText(row), '0.80 MPa [0, 1.6]');
  const reviewed = Object.assign({}, row, { status: 'uncertain', reason: 'glare', review_time: 5, review_by: 'li',
    review_value: 0.6213, review_display: '0.62 MPa' });
  assert.strictEqual(readingText(reviewed), '0.80 MPa [0, 1.6] uncertain: glare · reviewed by li: 0.62 MPa');
});

test('a calibration self-check in words', () => {
  assert.strictEqual(selfCheckText({ read: 0.600928, confidence: 90.6, expected: 0.6, apart_fs_pct: 0.09, reason: '' }),
    'the robot reads 0.6009 (91 %), you 0.6: 0.09 % of full scale apart');
  assert.strictEqual(selfCheckText({ read: 3.5, confidence: 40, expected: null, apart_fs_pct: null, reason: 'two pointers' }),
    'the robot reads 3.5 (40 %) (two pointers)');
  assert.strictEqual(selfCheckText({ read: null, confidence: null, expected: 1, apart_fs_pct: null, reason: 'no needle' }),
    'the robot cannot read it: no needle');
  assert.strictEqual(selfCheckText({ read: 0.6, confidence: 95, expected: 0.6, apart_fs_pct: 0, reason: '',
    needle_model: 'learned from the value given' }), 'the robot reads 0.6 (95 %), you 0.6: 0 % of full scale apart; '
    + 'needle model learned');
  assert.strictEqual(selfCheckText({ read: 0.6, confidence: 95, expected: null, apart_fs_pct: null, reason: '',
    needle_model: 'generic: the calibration has no needle model' }), 'the robot reads 0.6 (95 %); no needle model');
});

test('newestOnly: one decode at a time; frames arriving meanwhile leave only the newest waiting', async () => {
  const started = [];
  const finish = [];
  const push = newestOnly((frame) => {
    started.push(frame);
    return new Promise((resolve, reject) => finish.push([resolve, reject]));
  });
  push(1);
  for (let frame = 2; frame <= 5; frame++) push(frame);   // the browser still decodes frame 1
  await new Promise((resolve) => setTimeout(resolve, 0));
  assert.deepStrictEqual(started, [1]);
  finish.shift()[0]();
  await new Promise((resolve) => setTimeout(resolve, 0));
  assert.deepStrictEqual(started, [1, 5]);   // the newest next, the stale ones skipped and counted
  assert.strictEqual(push.skipped, 3);
  finish.shift()[1](new Error('corrupt JPEG'));
  await new Promise((resolve) => setTimeout(resolve, 0));
  push(6);   // idle again: decoded at once; a failing decode does not stop the next one
  await new Promise((resolve) => setTimeout(resolve, 0));
  assert.deepStrictEqual(started, [1, 5, 6]);
});

// node --test: every console module loads without a browser (imports resolve, nothing runs at import
// time) and every panel wires itself through init(); main.js lists each panel once.
import assert from 'node:assert';
import { readdirSync, readFileSync } from 'node:fs';
import test from 'node:test';

const DIR = new URL('../../web/console/', import.meta.url);
const PANELS = ['status', 'drive', 'head', 'images', 'map', 'planner', 'schedules', 'calibration', 'limits', 'patrol',
  'results', 'trends', 'review', 'alarms'];

test('every module but main imports in node; panels export init', async () => {
  const modules = readdirSync(DIR).filter((name) => name.endsWith('.js') && name !== 'main.js');
  assert.ok(modules.length >= PANELS.length + 4, modules.join(' '));
  for (const name of modules) {
    const module = await import(new URL(name, DIR));
    if (PANELS.includes(name.replace('.js', ''))) assert.strictEqual(typeof module.init, 'function', name);
  }
});

test('main.js starts every panel, then the link', () => {
  const main = readFileSync(new URL('main.js', DIR), 'utf8');
  const started = main.match(/for \(const panel of \[([^\]]*)\]\)/)[1].split(',').map((s) => s.trim());
  assert.deepStrictEqual(started.slice().sort(), PANELS.slice().sort());
  for (const panel of PANELS) assert.ok(main.includes("from './" + panel + ".js'"), panel);
});

test('coalesced: one run in flight, one more after it however often it was asked meanwhile', async () => {
  const { coalesced } = await import(new URL('ui.js', DIR));
  let runs = 0;
  let finish;
  const go = coalesced(() => { runs += 1; return new Promise((resolve) => { finish = resolve; }); });
  go(); go(); go(); go();
  assert.strictEqual(runs, 1);
  finish();
  await new Promise((resolve) => setTimeout(resolve, 0));
  assert.strictEqual(runs, 2);   // the three asks while it ran made one more run
  finish();
  await new Promise((resolve) => setTimeout(resolve, 0));
  assert.strictEqual(runs, 2);
  go();
  assert.strictEqual(runs, 3);
});

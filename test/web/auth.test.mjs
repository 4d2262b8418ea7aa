// node --test: the console's SHA-512 and auth fields (web/console/auth.js) against node's crypto.
import assert from 'node:assert';
import crypto from 'node:crypto';
import test from 'node:test';

import { authFields, sha512Hex } from '../../web/console/auth.js';

const reference = (text) => crypto.createHash('sha512').update(text, 'utf8').digest('hex');

test('sha512 matches node crypto on every padding boundary and on UTF-8', () => {
  for (let n = 0; n <= 260; n++) assert.strictEqual(sha512Hex('x'.repeat(n)), reference('x'.repeat(n)), 'length ' + n);
  for (const text of ['abc', 'Zählerstand 10,5 kV', '巡检机器人', '\u{1F916}']) {
    assert.strictEqual(sha512Hex(text), reference(text));
  }
});

test('auth fields: the MAC of the nonce, the robot time and the end', () => {
  const fields = authFields('s3cret', { nonce: 'ab12', t: 1000 }, 'console', 'robot', 3600);
  assert.deepStrictEqual(Object.keys(fields), ['mac', 'client', 'dest', 'rand', 't', 'level', 'end']);
  assert.strictEqual(fields.rand, 'ab12');
  assert.strictEqual(fields.end, 4600);
  assert.strictEqual(fields.mac, reference('s3cretconsolerobotab121000operator4600'));
});

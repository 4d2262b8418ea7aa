/* The console's side of the bridge's challenge authentication (docs/interface.md, "Backend link"):
   the page never sends the token itself, only rosauth's MAC over a nonce the robot issued to this
   connection. SHA-512 is computed here because crypto.subtle exists only on https:// or localhost
   pages, and an operator may open the console as http://<robot address>/ on the station network. */

const MASK = (1n << 64n) - 1n;

function integerRoot(n, k) {   // floor(n ** (1/k)) for a BigInt n, by Newton's method
  let x = 1n << BigInt(Math.ceil(n.toString(2).length / k) + 1);
  for (;;) {
    const next = ((BigInt(k) - 1n) * x + n / x ** BigInt(k - 1)) / BigInt(k);
    if (next >= x) return x;
    x = next;
  }
}

function primes(count) {
  const found = [];
  for (let n = 2; found.length < count; n++) {
    if (found.every((p) => n % p !== 0)) found.push(n);
  }
  return found;
}

// FIPS 180-4 5.3.5 and 4.2.3: the first 64 fraction bits of square roots (initial hash) and cube
// roots (round constants) of the first primes, derived rather than typed in.
const PRIMES = primes(80);
const H0 = PRIMES.slice(0, 8).map((p) => integerRoot(BigInt(p) << 128n, 2) & MASK);
const K = PRIMES.map((p) => integerRoot(BigInt(p) << 192n, 3) & MASK);

const rotr = (x, n) => ((x >> n) | (x << (64n - n))) & MASK;

export function sha512Hex(text) {
  const bytes = Array.from(new TextEncoder().encode(text));
  const bitLength = BigInt(bytes.length) * 8n;
  bytes.push(0x80);
  while (bytes.length % 128 !== 112) bytes.push(0);
  for (let i = 15; i >= 0; i--) bytes.push(Number((bitLength >> BigInt(8 * i)) & 0xffn));
  const h = H0.slice();
  const w = new Array(80);
  for (let block = 0; block < bytes.length; block += 128) {
    for (let t = 0; t < 16; t++) {
      let word = 0n;
      for (let b = 0; b < 8; b++) word = (word << 8n) | BigInt(bytes[block + 8 * t + b]);
      w[t] = word;
    }
    for (let t = 16; t < 80; t++) {
      const s0 = rotr(w[t - 15], 1n) ^ rotr(w[t - 15], 8n) ^ (w[t - 15] >> 7n);
      const s1 = rotr(w[t - 2], 19n) ^ rotr(w[t - 2], 61n) ^ (w[t - 2] >> 6n);
      w[t] = (w[t - 16] + s0 + w[t - 7] + s1) & MASK;
    }
    let [a, b, c, d, e, f, g, hh] = h;
    for (let t = 0; t < 80; t++) {
      const t1 = (hh + (rotr(e, 14n) ^ rotr(e, 18n) ^ rotr(e, 41n)) + ((e & f) ^ (~e & MASK & g)) + K[t] + w[t])
        & MASK;
      const t2 = ((rotr(a, 28n) ^ rotr(a, 34n) ^ rotr(a, 39n)) + ((a & b) ^ (a & c) ^ (b & c))) & MASK;
      [hh, g, f, e, d, c, b, a] = [g, f, e, (d + t1) & MASK, c, b, a, (t1 + t2) & MASK];
    }
    [a, b, c, d, e, f, g, hh].forEach((v, i) => { h[i] = (h[i] + v) & MASK; });
  }
  return h.map((v) => v.toString(16).padStart(16, '0')).join('');
}

/* The auth op's fields answering a challenge {nonce, t}: rosauth's MAC, the SHA-512 of
   token + client + dest + rand + t + level + end, with rand = the nonce and t = the robot's time. */
export function authFields(token, challenge, client, dest, lifetimeS) {
  const t = challenge.t;
  const end = t + lifetimeS;
  const level = 'operator';
  const mac = sha512Hex(token + client + dest + challenge.nonce + t + level + end);
  return { mac, client, dest, rand: challenge.nonce, t, level, end };
}


// The stillness indicator uses the calibration's definition: population standard
// deviation, a missing sample is not still, the limit itself still counts as still.
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { test } from "node:test";
import { populationStd, Stillness } from "/static/stillness.js";
import { DEG } from "/static/tickdata.js";

test("alternating +a, -a has population standard deviation a (sample sd would be larger)", () => {
  for (const n of [2, 4, 10, 100]) {
    const xs = Array.from({ length: n }, (_, i) => (i % 2 ? -0.25 : 0.25));
    assert.equal(populationStd(xs), 0.25);
  }
});

test("a constant window has zero deviation; empty, null or NaN has none", () => {
  assert.equal(populationStd([0.3, 0.3, 0.3]), 0);
  assert.ok(Number.isNaN(populationStd([])));
  assert.ok(Number.isNaN(populationStd([0.1, null, 0.2])));
  assert.ok(Number.isNaN(populationStd([0.1, NaN, 0.2])));
});

test("numpy's std (ddof = 0) agrees on random windows", () => {
  const cases = JSON.parse(readFileSync(process.env.EXOSTUDY_STD_CASES, "utf8"));
  assert.ok(cases.length >= 20);
  for (const { values, std } of cases) {
    const got = populationStd(values);
    assert.ok(Math.abs(got - std) <= 1e-12 * Math.max(1, std), `${got} != ${std}`);
  }
});

function windowOf(left, right) {
  const s = new Stillness({ seconds: 1.0, limitDeg: 0.5 * DEG, minSamples: 20 });
  const t = left.map((_, i) => i * 0.01);
  s.push({ t, q_left: left, q_right: right });
  return s;
}

test("a deviation equal to the limit is still; above it is moving", () => {
  const n = 40;
  const at = Array.from({ length: n }, (_, i) => (i % 2 ? -0.5 : 0.5));
  const flat = new Array(n).fill(0.1);
  assert.equal(windowOf(at, flat).state().still, true);
  const above = at.map((x) => x * 1.001);
  assert.equal(windowOf(above, flat).state().still, false);
  assert.equal(windowOf(flat, above).state().still, false);
});

test("a missing sample in the window makes it not still", () => {
  const flat = new Array(40).fill(0.1);
  const gap = flat.slice();
  gap[7] = null;
  assert.equal(windowOf(flat, flat).state().still, true);
  assert.equal(windowOf(gap, flat).state().still, false);
});

test("too few samples give no verdict; the window keeps only the last second", () => {
  assert.equal(windowOf(new Array(19).fill(0), new Array(19).fill(0)).state(), null);
  // Times in 1/64 s steps, exact in binary: the last second is 65 samples, both ends in.
  const s = new Stillness({ seconds: 1.0 });
  const t = Array.from({ length: 300 }, (_, i) => i / 64);
  s.push({ t, q_left: t.map(() => 0), q_right: t.map(() => 0) });
  assert.equal(s.t.length, 65);
  assert.equal(s.t[0], t[235]);
});

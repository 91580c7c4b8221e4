// What the plots draw: columns per plot, display units, the leading model's progress.
import assert from "node:assert/strict";
import { test } from "node:test";
import { addProgress, DEG, degrees, displayValue, lastTick, PLOT_COLUMNS } from "/static/tickdata.js";
import { VOCABULARY } from "/static/names.js";
import { Ring } from "/static/livestream.js";

test("every plotted tick column is streamed to the browser", () => {
  const streamed = new Set(VOCABULARY.stream_fields);
  for (const [plot, cols] of Object.entries(PLOT_COLUMNS)) {
    for (const c of cols) {
      if (c.startsWith("progress_")) continue;  // made by addProgress from s_curr_*
      assert.ok(streamed.has(c), `${plot}: ${c} is not streamed`);
    }
  }
  for (const m of VOCABULARY.models) assert.ok(streamed.has(`s_curr_${m.name}`));
});

test("progress: the most probable model's s_curr, nothing where 'other' leads", () => {
  const cols = addProgress({
    t: [0, 1, 2, 3],
    post_squat: [0.7, 0.1, null, 0.2],
    post_stoop_left: [0.2, 0.8, null, 0.1],
    post_stoop_right: [0.1, 0.05, null, 0.1],
    post_other: [0.0, 0.05, null, 0.6],
    s_curr_squat: [0.3, 0.9, null, 0.5],
    s_curr_stoop_left: [0.1, 0.4, null, 0.2],
    s_curr_stoop_right: [0.2, 0.2, null, 0.1],
  });
  assert.deepEqual(cols.progress_squat, [0.3, null, null, null]);
  assert.deepEqual(cols.progress_stoop_left, [null, 0.4, null, null]);
  assert.deepEqual(cols.progress_stoop_right, [null, null, null, null]);
});

test("display units: degrees for angles, lock steps at two heights, gaps stay gaps", () => {
  assert.equal(displayValue("q_left", Math.PI), 180);
  assert.equal(displayValue("omega_left", 2.5), 2.5);
  assert.deepEqual([displayValue("lock_left", true), displayValue("lock_left", false)], [1, 0]);
  assert.deepEqual([displayValue("lock_right", true), displayValue("lock_right", false)], [1.2, 0.2]);
  assert.equal(displayValue("q_right", null), null);
  assert.deepEqual(degrees([Math.PI / 2, null]), [90, null]);
  assert.equal(DEG * Math.PI, 180);
});

test("lastTick takes the newest value of every column", () => {
  assert.deepEqual(lastTick({ t: [1, 2], action: [1, 4] }), { t: 2, action: 4 });
  assert.equal(lastTick({ t: [] }), null);
});

test("the ring keeps the newest `capacity` samples of each column", () => {
  const ring = new Ring(["t", "q_left"], 3);
  ring.push({ t: [0, 1], q_left: [0, Math.PI] }, displayValue);
  ring.push({ t: [2, 3] });
  assert.deepEqual(ring.cols.t, [1, 2, 3]);
  assert.deepEqual(ring.cols.q_left, [180, null, null]);
  ring.resize(2);
  assert.equal(ring.length, 2);
});

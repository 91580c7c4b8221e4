// Is the wearer standing still? The standard deviation of each hip angle over the last
// second, from the live stream, against the calibration's limit. The same definition as
// the calibration the server runs (controller/intent/calibration.py): the population standard
// deviation (divide by n), a missing sample makes the window not still, and a deviation
// equal to the limit still counts as still.

import { DEG } from "/static/tickdata.js";

// Population standard deviation (two-pass, as numpy's `std` with ddof = 0); NaN for an
// empty list or one holding a missing (null) or non-finite value.
export function populationStd(values) {
  const n = values.length;
  if (!n || values.some((x) => x == null || !Number.isFinite(x))) return NaN;
  const mean = values.reduce((a, b) => a + b, 0) / n;
  return Math.sqrt(values.reduce((a, b) => a + (b - mean) ** 2, 0) / n);
}

export class Stillness {
  constructor({ seconds = 1.0, limitDeg = 1.0, minSamples = 20 } = {}) {
    this.seconds = seconds;
    this.limitDeg = limitDeg;
    this.minSamples = minSamples;
    this.t = [];
    this.left = [];
    this.right = [];
  }

  push(columns) {
    const n = columns.t.length;
    for (let i = 0; i < n; i++) {
      this.t.push(columns.t[i]);
      this.left.push(columns.q_left[i]);
      this.right.push(columns.q_right[i]);
    }
    const from = this.t[this.t.length - 1] - this.seconds;
    let k = 0;
    while (k < this.t.length && this.t[k] < from) k++;
    if (k) { this.t.splice(0, k); this.left.splice(0, k); this.right.splice(0, k); }
  }

  // {stdLeftDeg, stdRightDeg, still} or null while there is too little data.
  state() {
    if (this.t.length < this.minSamples) return null;
    const l = populationStd(this.left) * DEG;
    const r = populationStd(this.right) * DEG;
    return { stdLeftDeg: l, stdRightDeg: r, still: l <= this.limitDeg && r <= this.limitDeg };
  }
}

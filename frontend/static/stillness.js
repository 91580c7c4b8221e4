// Is the wearer standing still? The standard deviation of each hip angle over the last
// second, from the live stream, against the calibration's limit.

export class Stillness {
  constructor({ seconds = 1.0, limitDeg = 1.0 } = {}) {
    this.seconds = seconds;
    this.limitDeg = limitDeg;
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
    if (this.t.length < 20) return null;
    const sd = (xs) => {
      const v = xs.filter((x) => x != null);
      if (v.length < 10) return NaN;
      const m = v.reduce((a, b) => a + b, 0) / v.length;
      return Math.sqrt(v.reduce((a, b) => a + (b - m) ** 2, 0) / (v.length - 1)) * 180 / Math.PI;
    };
    const l = sd(this.left);
    const r = sd(this.right);
    return { stdLeftDeg: l, stdRightDeg: r, still: l < this.limitDeg && r < this.limitDeg };
  }
}

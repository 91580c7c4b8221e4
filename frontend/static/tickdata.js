// Ticks as the plots draw them: which columns each plot needs, display units, and the
// progress of the leading model. Pure functions of column objects (`{name: [values]}`).
import { CATEGORY_NAMES, MODEL_NAMES, modelColumns, tickColumn } from "/static/names.js";

export const DEG = 180 / Math.PI;

const sides = (prefix) => [tickColumn(`${prefix}_left`), tickColumn(`${prefix}_right`)];
const LOCKS = sides("lock");

// Which columns each plot needs, in series order after t.
export const PLOT_COLUMNS = {
  angles: sides("q"),
  velocities: [...sides("omega"), tickColumn("trigger")],
  posteriors: [...modelColumns("post_", CATEGORY_NAMES).map(tickColumn), ...LOCKS],
  torques: sides("torque"),
  progress: modelColumns("progress_"),
};
const ANGLES = new Set(PLOT_COLUMNS.angles);

// The progress estimate of the most probable model (its s_curr), one column per model so
// the colour says which model leads; null where "other" leads or nothing was estimated.
// Adds `progress_<model>` columns to a columns object (live message or stored trial).
export function addProgress(columns) {
  const n = columns.t.length;
  const post = MODEL_NAMES.map((m) => columns[`post_${m}`] || []);
  const other = columns.post_other || [];
  const curr = MODEL_NAMES.map((m) => columns[`s_curr_${m}`] || []);
  const out = MODEL_NAMES.map(() => new Array(n).fill(null));
  for (let i = 0; i < n; i++) {
    let best = -1;
    let bestP = other[i] ?? -Infinity;
    for (let k = 0; k < MODEL_NAMES.length; k++) {
      const p = post[k][i];
      if (p != null && p > bestP) { best = k; bestP = p; }
    }
    if (best >= 0 && curr[best][i] != null) out[best][i] = curr[best][i];
  }
  MODEL_NAMES.forEach((m, k) => { columns[`progress_${m}`] = out[k]; });
  return columns;
}

// Ticks as they arrive (SI units, booleans) to what the plots draw: angles in degrees,
// the two lock commands as steps at different heights so both stay visible.
export function displayValue(name, v) {
  if (v == null) return null;
  if (ANGLES.has(name)) return v * DEG;
  if (name === LOCKS[0]) return v ? 1 : 0;
  if (name === LOCKS[1]) return v ? 1.2 : 0.2;
  if (name === "trigger") return v ? 1 : 0;
  return v;
}

// The last tick in a columns message, as a plain object.
export function lastTick(columns) {
  const n = columns.t.length;
  if (!n) return null;
  const out = {};
  for (const [k, v] of Object.entries(columns)) out[k] = v[n - 1];
  return out;
}

// Radians to degrees, keeping nulls (gaps) as gaps.
export const degrees = (values) => values.map((v) => (v == null ? null : v * DEG));

// The time plots shared by the live page, replay and the session page: hip angles,
// velocities with the trigger threshold, posteriors with lock commands, the progress of
// the most probable model, torques.
// All plots share one cursor (uPlot cursor.sync), so a time reads across them.
import uPlot from "/vendor/uplot/uPlot.esm.js";

export const DEG = 180 / Math.PI;
export const LEFT = "#1f6feb";
export const RIGHT = "#d9480f";
const SYNC_KEY = "exostudy-time";
const stepped = uPlot.paths.stepped({ align: 1 });

export function sizeOf(el, height = 220) {
  return { width: Math.max(300, el.clientWidth - 4), height };
}

function thresholdLine(getValue) {
  return (u) => {
    const v = getValue();
    if (v == null || u.scales.y.min == null) return;
    const { ctx } = u;
    ctx.save();
    ctx.setLineDash([8, 5]);
    ctx.lineWidth = 2;
    ctx.strokeStyle = "#6b7685";
    for (const y of [v]) {
      const py = u.valToPos(y, "y", true);
      ctx.beginPath();
      ctx.moveTo(u.bbox.left, py);
      ctx.lineTo(u.bbox.left + u.bbox.width, py);
      ctx.stroke();
    }
    ctx.fillStyle = "#6b7685";
    ctx.font = `${12 * devicePixelRatio}px system-ui`;
    ctx.textAlign = "right";
    ctx.fillText(`trigger threshold ${v} rad/s`, u.bbox.left + u.bbox.width - 6, u.valToPos(v, "y", true) - 6);
    ctx.restore();
  };
}

const xAxis = { label: "device time (s)" };
const base = (el, height, onDraw) => ({
  ...sizeOf(el, height),
  scales: { x: { time: false } },
  cursor: { sync: { key: SYNC_KEY, setSeries: false }, drag: { x: false, y: false } },
  hooks: { draw: [onDraw] },
  legend: { live: true },
});

// Which tick columns each plot needs, in series order after t.
export const PLOT_COLUMNS = {
  angles: ["q_left", "q_right"],
  velocities: ["omega_left", "omega_right", "trigger"],
  posteriors: ["post_squat", "post_stoop_left", "post_stoop_right", "post_other",
    "lock_left", "lock_right"],
  torques: ["torque_left", "torque_right"],
  progress: ["progress_squat", "progress_stoop_left", "progress_stoop_right"],
};

const MODELS = ["squat", "stoop_left", "stoop_right"];

// The progress estimate of the most probable model (its s_curr), one column per model so
// the colour says which model leads; null where "other" leads or nothing was estimated.
// Adds `progress_<model>` columns to a columns object (live message or stored trial).
export function addProgress(columns) {
  const n = columns.t.length;
  const post = MODELS.map((m) => columns[`post_${m}`] || []);
  const other = columns.post_other || [];
  const curr = MODELS.map((m) => columns[`s_curr_${m}`] || []);
  const out = MODELS.map(() => new Array(n).fill(null));
  for (let i = 0; i < n; i++) {
    let best = -1;
    let bestP = other[i] ?? -Infinity;
    for (let k = 0; k < MODELS.length; k++) {
      const p = post[k][i];
      if (p != null && p > bestP) { best = k; bestP = p; }
    }
    if (best >= 0 && curr[best][i] != null) out[best][i] = curr[best][i];
  }
  MODELS.forEach((m, k) => { columns[`progress_${m}`] = out[k]; });
  return columns;
}

// Ticks as they arrive (SI units, booleans) to what the plots draw.
export function displayValue(name, v) {
  if (v == null) return null;
  if (name === "q_left" || name === "q_right") return v * DEG;
  if (name === "lock_left") return v ? 1 : 0;
  if (name === "lock_right") return v ? 1.2 : 0.2;
  if (name === "trigger") return v ? 1 : 0;
  return v;
}

// Event markers (backend/schemas/lab.py MarkerOut): a dashed line and the label at the
// marker's tick time. Calls `onShown(labels)` with the labels drawn in view.
function markerLines(getMarkers, onShown) {
  return (u) => {
    const x0 = u.scales.x.min;
    const x1 = u.scales.x.max;
    const markers = getMarkers();
    if (x0 == null || !markers.length) return;
    const { ctx } = u;
    const shown = [];
    ctx.save();
    ctx.setLineDash([4, 4]);
    ctx.lineWidth = 2;
    ctx.strokeStyle = "#9c36b5";
    ctx.fillStyle = "#9c36b5";
    ctx.font = `${11 * devicePixelRatio}px system-ui`;
    for (const m of markers) {
      if (m.t == null || m.t < x0 || m.t > x1) continue;
      const px = u.valToPos(m.t, "x", true);
      ctx.beginPath();
      ctx.moveTo(px, u.bbox.top);
      ctx.lineTo(px, u.bbox.top + u.bbox.height);
      ctx.stroke();
      ctx.fillText(m.label, px + 4, u.bbox.top + 12 * devicePixelRatio);
      shown.push(m.label);
    }
    ctx.restore();
    onShown(shown);
  };
}

export function createTimePlots(containers, { threshold = 1.0, height = 220, onDraw = () => {},
  onMarkersShown = () => {} } = {}) {
  const plots = {};
  const state = { threshold };
  const c = containers;
  if (c.angles) {
    plots.angles = new uPlot({
      ...base(c.angles, height, onDraw),
      axes: [xAxis, { label: "hip flexion (deg)" }],
      series: [{}, { label: "left hip", stroke: LEFT, width: 2 },
        { label: "right hip", stroke: RIGHT, width: 2 }],
    }, [[], [], []], c.angles);
  }
  if (c.velocities) {
    plots.velocities = new uPlot({
      ...base(c.velocities, height, onDraw),
      hooks: { draw: [onDraw, thresholdLine(() => state.threshold)] },
      scales: {
        x: { time: false },
        y: { range: (u, min, max) => [Math.min(min ?? -1, -1), Math.max(max ?? 1, state.threshold * 1.5)] },
        trig: { range: [-0.1, 8] },
      },
      axes: [xAxis, { label: "hip velocity (rad/s)" }],
      series: [{}, { label: "left", stroke: LEFT, width: 2 },
        { label: "right", stroke: RIGHT, width: 2 },
        { label: "trigger", stroke: "#2b8a3e", fill: "rgba(43,138,62,0.15)", width: 2, scale: "trig", paths: stepped }],
    }, [[], [], [], []], c.velocities);
  }
  if (c.posteriors) {
    plots.posteriors = new uPlot({
      ...base(c.posteriors, height, onDraw),
      scales: { x: { time: false }, p: { range: [0, 1.05] }, lock: { range: [-0.1, 3] } },
      axes: [xAxis, { scale: "p", label: "P(model | obs)" }],
      series: [{},
        { label: "squat", stroke: "#2b8a3e", scale: "p", width: 2, spanGaps: true },
        { label: "stoop left", stroke: LEFT, scale: "p", width: 2, spanGaps: true, dash: [6, 3] },
        { label: "stoop right", stroke: RIGHT, scale: "p", width: 2, spanGaps: true, dash: [6, 3] },
        { label: "other", stroke: "#868e96", scale: "p", width: 2, spanGaps: true },
        { label: "lock left", stroke: LEFT, scale: "lock", width: 3, paths: stepped },
        { label: "lock right", stroke: RIGHT, scale: "lock", width: 3, paths: stepped }],
    }, [[], [], [], [], [], [], []], c.posteriors);
  }
  if (c.progress) {
    plots.progress = new uPlot({
      ...base(c.progress, height, onDraw),
      scales: { x: { time: false }, y: { range: [0, 1.05] } },
      axes: [xAxis, { label: "progress s (0-1)" }],
      series: [{},
        { label: "squat", stroke: "#2b8a3e", width: 2 },
        { label: "stoop left", stroke: LEFT, width: 2, dash: [6, 3] },
        { label: "stoop right", stroke: RIGHT, width: 2, dash: [6, 3] }],
    }, [[], [], [], []], c.progress);
  }
  if (c.torques) {
    plots.torques = new uPlot({
      ...base(c.torques, height, onDraw),
      axes: [xAxis, { label: "torque (Nm)" }],
      series: [{}, { label: "left", stroke: LEFT, width: 2, spanGaps: true },
        { label: "right", stroke: RIGHT, width: 2, spanGaps: true }],
    }, [[], [], []], c.torques);
  }

  state.markers = [];
  const drawMarkers = markerLines(() => state.markers, onMarkersShown);
  for (const plot of Object.values(plots)) (plot.hooks.draw ||= []).push(drawMarkers);

  return {
    plots,
    // Markers to draw (`{t, label}` on the device time axis); redraws at once.
    setMarkers(list) {
      state.markers = list;
      for (const plot of Object.values(plots)) plot.redraw(false, false);
    },
    addMarker(m) { this.setMarkers([...state.markers, m].slice(-200)); },
    // `cols`: display-unit arrays by column name, `t` included. With `only` (a set of
    // plot names), the other plots keep their last picture: a plot scrolled out of view
    // costs nothing until it comes back (the caller redraws it then).
    setData(cols, only = null) {
      for (const [name, plot] of Object.entries(plots)) {
        if (only && !only.has(name)) continue;
        plot.setData([cols.t, ...PLOT_COLUMNS[name].map((n) => cols[n])]);
      }
    },
    // Calls `onChange(visibleNames)` whenever a plot enters or leaves the viewport.
    watchVisibility(onChange) {
      const visible = new Set(Object.keys(plots));
      const byEl = new Map(Object.keys(plots).map((n) => [c[n], n]));
      const io = new IntersectionObserver((entries) => {
        for (const e of entries) {
          const name = byEl.get(e.target);
          if (e.isIntersecting) visible.add(name); else visible.delete(name);
        }
        onChange(visible);
      });
      for (const el of byEl.keys()) io.observe(el);
      return visible;
    },
    setThreshold(v) { state.threshold = v; },
    resize() {
      for (const [name, plot] of Object.entries(plots)) plot.setSize(sizeOf(c[name], height));
    },
  };
}

// The time plots shared by the live page, replay and the session page: hip angles,
// velocities with the trigger threshold, posteriors with lock commands, the progress of
// the most probable model, torques.
// All plots share one cursor (uPlot cursor.sync), so a time reads across them.
import { makePlot, uPlot } from "/static/plot.js";
import { CATEGORY_NAMES, MODEL_NAMES, modelLabel } from "/static/names.js";
import { categoryColour, LEFT, MARKER, NEUTRAL, RIGHT, TRIGGER } from "/static/palette.js";
import { PLOT_COLUMNS } from "/static/tickdata.js";

const SYNC_KEY = "exostudy-time";
const stepped = uPlot.paths.stepped({ align: 1 });

function thresholdLine(getValue) {
  return (u) => {
    const v = getValue();
    if (v == null || u.scales.y.min == null) return;
    const { ctx } = u;
    const py = u.valToPos(v, "y", true);
    ctx.save();
    ctx.setLineDash([8, 5]);
    ctx.lineWidth = 2;
    ctx.strokeStyle = NEUTRAL;
    ctx.beginPath();
    ctx.moveTo(u.bbox.left, py);
    ctx.lineTo(u.bbox.left + u.bbox.width, py);
    ctx.stroke();
    ctx.fillStyle = NEUTRAL;
    ctx.font = `${12 * devicePixelRatio}px system-ui`;
    ctx.textAlign = "right";
    ctx.fillText(`trigger threshold ${v} rad/s`, u.bbox.left + u.bbox.width - 6, py - 6);
    ctx.restore();
  };
}

const xAxis = { label: "device time (s)" };
const CURSOR = { drag: { x: false, y: false } };
// One series per motion category: its colour, dashed for the one-sided (stoop) models.
const categorySeries = (names, extra) => names.map((m) => ({
  label: modelLabel(m), stroke: categoryColour(m), width: 2,
  dash: /_(left|right)$/.test(m) ? [6, 3] : undefined, ...extra,
}));

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
    ctx.strokeStyle = MARKER;
    ctx.fillStyle = MARKER;
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
  const make = (name, opts, draw = [onDraw]) => {
    if (c[name]) plots[name] = makePlot(c[name], { cursor: CURSOR, legend: { live: true }, hooks: { draw }, ...opts },
      { height, sync: SYNC_KEY });
  };
  make("angles", {
    axes: [xAxis, { label: "hip flexion (deg)" }],
    series: [{}, { label: "left hip", stroke: LEFT, width: 2 }, { label: "right hip", stroke: RIGHT, width: 2 }],
  });
  make("velocities", {
    scales: {
      y: { range: (u, min, max) => [Math.min(min ?? -1, -1), Math.max(max ?? 1, state.threshold * 1.5)] },
      trig: { range: [-0.1, 8] },
    },
    axes: [xAxis, { label: "hip velocity (rad/s)" }],
    series: [{}, { label: "left", stroke: LEFT, width: 2 },
      { label: "right", stroke: RIGHT, width: 2 },
      { label: "trigger", stroke: TRIGGER, fill: categoryColour("squat", 0.15), width: 2, scale: "trig", paths: stepped }],
  }, [onDraw, thresholdLine(() => state.threshold)]);
  make("posteriors", {
    scales: { p: { range: [0, 1.05] }, lock: { range: [-0.1, 3] } },
    axes: [xAxis, { scale: "p", label: "P(model | obs)" }],
    series: [{}, ...categorySeries(CATEGORY_NAMES, { scale: "p", spanGaps: true }),
      { label: "lock left", stroke: LEFT, scale: "lock", width: 3, paths: stepped },
      { label: "lock right", stroke: RIGHT, scale: "lock", width: 3, paths: stepped }],
  });
  make("progress", {
    scales: { y: { range: [0, 1.05] } },
    axes: [xAxis, { label: "progress s (0-1)" }],
    series: [{}, ...categorySeries(MODEL_NAMES, {})],
  });
  make("torques", {
    axes: [xAxis, { label: "torque (Nm)" }],
    series: [{}, { label: "left", stroke: LEFT, width: 2, spanGaps: true },
      { label: "right", stroke: RIGHT, width: 2, spanGaps: true }],
  });

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
  };
}

// The one way the console makes a uPlot: sized to its container, resized with the
// window, x as plain numbers (device seconds or progress), an optional shared cursor.
import uPlot from "/vendor/uplot/uPlot.esm.js";

export { uPlot };

// The plot size for a container: its width (at least 300 px) and a fixed height.
export function sizeOf(el, height = 220) {
  return { width: Math.max(300, el.clientWidth - 4), height };
}

// `opts`: uPlot options (series, axes, scales, hooks, cursor...) without the size;
// `sync`: a cursor key shared by plots read together. Empty data of the series' width.
export function makePlot(el, opts, { height = 220, sync = null } = {}) {
  const cursor = { ...(opts.cursor || {}) };
  if (sync) cursor.sync = { key: sync, setSeries: false, ...(cursor.sync || {}) };
  const plot = new uPlot({
    ...sizeOf(el, height),
    ...opts,
    scales: { x: { time: false }, ...(opts.scales || {}) },
    cursor,
  }, opts.series.map(() => []), el);
  window.addEventListener("resize", () => plot.setSize(sizeOf(el, height)));
  return plot;
}

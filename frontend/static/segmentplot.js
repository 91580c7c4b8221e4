// A recording's hip angles with its lift segments drawn as bands. The experimenter drags
// a band's start or end edge; the edge snaps to the nearest sample when let go.
import { makePlot } from "/static/plot.js";
import { modelLabel } from "/static/names.js";
import { categoryColour, LEFT, RIGHT } from "/static/palette.js";
import { degrees } from "/static/tickdata.js";

const GRAB_PX = 9;

export function createSegmentPlot(el, { onEdgeMoved, height = 300 }) {
  let t = [];
  let segments = [];
  let drag = null;
  let hover = null;

  function drawSegments(u) {
    const { ctx } = u;
    const top = u.bbox.top;
    const hgt = u.bbox.height;
    ctx.save();
    for (const s of segments) {
      if (t[s.start] == null || t[s.end] == null) continue;
      const x0 = u.valToPos(t[s.start], "x", true);
      const x1 = u.valToPos(t[s.end], "x", true);
      ctx.fillStyle = categoryColour(s.label, s.excluded ? 0.06 : 0.16);
      ctx.fillRect(x0, top, x1 - x0, hgt);
      for (const [which, x] of [["start", x0], ["end", x1]]) {
        const active = (drag && drag.seg === s && drag.which === which) ||
          (hover && hover.seg === s && hover.which === which);
        ctx.fillStyle = categoryColour(s.label);
        ctx.fillRect(x - (active ? 3 : 1.5) * devicePixelRatio, top, (active ? 6 : 3) * devicePixelRatio, hgt);
        // A grip in the middle of the edge, to show it can be dragged.
        ctx.fillRect(x - 6 * devicePixelRatio, top + hgt / 2 - 14 * devicePixelRatio,
          12 * devicePixelRatio, 28 * devicePixelRatio);
      }
      ctx.fillStyle = categoryColour(s.label);
      ctx.font = `${600} ${12 * devicePixelRatio}px system-ui`;
      ctx.fillText(`${modelLabel(s.label)}${s.source === "edited" ? " ✎" : ""}`,
        x0 + 4 * devicePixelRatio, top + 14 * devicePixelRatio);
    }
    ctx.restore();
  }

  const plot = makePlot(el, {
    cursor: { drag: { x: false, y: false }, points: { show: false } },
    axes: [{ label: "device time (s)" }, { label: "hip flexion (deg)" }],
    series: [{}, { label: "left hip", stroke: LEFT, width: 2 }, { label: "right hip", stroke: RIGHT, width: 2 }],
    hooks: { draw: [drawSegments] },
  }, { height });
  const over = plot.over;

  function nearestIndex(time) {
    let lo = 0;
    let hi = t.length - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (t[mid] < time) lo = mid; else hi = mid;
    }
    return Math.abs(t[lo] - time) <= Math.abs(t[hi] - time) ? lo : hi;
  }

  function edgeAt(px) {
    let best = null;
    for (const s of segments) {
      for (const which of ["start", "end"]) {
        const x = plot.valToPos(t[s[which]], "x");
        const d = Math.abs(x - px);
        if (d <= GRAB_PX && (!best || d < best.d)) best = { seg: s, which, d };
      }
    }
    return best;
  }

  const localX = (ev) => ev.clientX - over.getBoundingClientRect().left;

  over.addEventListener("mousedown", (ev) => {
    const hit = edgeAt(localX(ev));
    if (!hit) return;
    ev.preventDefault();
    ev.stopPropagation();
    drag = { seg: hit.seg, which: hit.which, original: hit.seg[hit.which] };
  });
  over.addEventListener("mousemove", (ev) => {
    if (drag) return;
    const hit = edgeAt(localX(ev));
    over.style.cursor = hit ? "ew-resize" : "";
    const changed = (hit && (!hover || hover.seg !== hit.seg || hover.which !== hit.which)) || (!hit && hover);
    hover = hit;
    if (changed) plot.redraw(false, false);
  });
  window.addEventListener("mousemove", (ev) => {
    if (!drag) return;
    const time = plot.posToVal(localX(ev), "x");
    let i = nearestIndex(time);
    const s = drag.seg;
    // An edge cannot cross the peak: the segment stays start < peak < end.
    if (drag.which === "start") i = Math.min(i, s.peak - 1);
    else i = Math.max(i, s.peak + 1);
    s[drag.which] = Math.max(0, Math.min(t.length - 1, i));
    plot.redraw(false, false);
  });
  window.addEventListener("mouseup", () => {
    if (!drag) return;
    const d = drag;
    drag = null;
    if (d.seg[d.which] !== d.original) onEdgeMoved(d.seg, d.which, d.seg[d.which], d.original);
    plot.redraw(false, false);
  });

  return {
    plot,
    setRecording(angles) {
      t = angles.t;
      plot.setData([t, degrees(angles.q_left), degrees(angles.q_right)]);
    },
    setSegments(list) { segments = list; plot.redraw(false, false); },
    // Where an edge is on screen (page coordinates), for tests and keyboard-free checks.
    edgeClientPoint(segId, which) {
      const s = segments.find((x) => x.id === segId);
      if (!s) return null;
      const r = over.getBoundingClientRect();
      return { x: r.left + plot.valToPos(t[s[which]], "x"), y: r.top + r.height / 2 };
    },
  };
}

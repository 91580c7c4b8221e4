// The trial panel's EMG: the stored recording's envelope over the trial (the study's
// zero-phase chain, decimated by the server: backend/emg/trial_envelope.py), one line per
// channel on one plot with the trial's lifts as bands, and per lift the peak envelope of
// each channel, computed by the server from the full-rate envelope. Lifts are numbered
// from 1 on the page (the server's `index` counts from 0).
import { ApiError } from "/static/api.js";
import * as api from "/static/api_client.js";
import { h } from "/static/dom.js";
import { makePlot } from "/static/plot.js";
import { categoryColour, LEFT, RIGHT } from "/static/palette.js";

const UV = 1e6;
// One dash pattern per muscle, the colour by side (left blue, right orange).
const DASHES = [undefined, [8, 4], [2, 3], [10, 3, 2, 3], [4, 4], [1, 2]];
// What the browser tests read.
const state = (window.exostudyEmgPanel = { trialId: null, loaded: false, error: null, doc: null });

let plot = null;
let lifts = [];

function liftBands(u) {
  const { ctx } = u;
  ctx.save();
  for (const l of lifts) {
    const x0 = u.valToPos(l.start_s, "x", true);
    const x1 = u.valToPos(l.end_s, "x", true);
    ctx.fillStyle = categoryColour(l.kind, 0.14);
    ctx.fillRect(x0, u.bbox.top, x1 - x0, u.bbox.height);
    ctx.fillStyle = categoryColour(l.kind);
    ctx.font = `${11 * devicePixelRatio}px system-ui`;
    ctx.fillText(`lift ${l.index + 1}`, x0 + 3 * devicePixelRatio, u.bbox.top + 12 * devicePixelRatio);
  }
  ctx.restore();
}

function draw(el, doc) {
  if (plot) { plot.destroy(); plot = null; }
  el.replaceChildren();
  const muscles = [...new Set(doc.channels.map((c) => c.muscle))];
  lifts = doc.lifts;
  plot = makePlot(el, {
    cursor: { drag: { x: false, y: false } },
    legend: { live: true },
    axes: [{ label: "time from the trial's start (s)" }, { label: "envelope (µV)" }],
    series: [{}, ...doc.channels.map((c) => ({
      label: c.label + (c.flags.length ? ` (${c.flags.join(", ")})` : ""),
      stroke: c.side === "left" ? LEFT : RIGHT, width: 1.5,
      dash: DASHES[muscles.indexOf(c.muscle) % DASHES.length],
    }))],
    hooks: { draw: [liftBands] },
  }, { height: 260 });
  plot.setData([doc.t, ...doc.channels.map((c) => c.values.map((v) => v * UV))]);
}

function liftTable(table, doc) {
  table.querySelector("thead tr").replaceChildren(h("th", {}, "lift"), h("th", {}, "kind"),
    h("th", {}, "start (s)"), h("th", {}, "end (s)"),
    ...doc.channels.map((c) => h("th", {}, `${c.label} peak (µV)`)));
  table.querySelector("tbody").replaceChildren(...doc.lifts.map((l) => h("tr", { "data-lift": l.index },
    h("td", {}, String(l.index + 1)), h("td", {}, l.kind), h("td", {}, l.start_s.toFixed(2)),
    h("td", {}, l.end_s.toFixed(2)),
    ...l.peak.map((p, k) => h("td", { class: "mono", "data-channel": doc.channels[k].label,
      "data-peak": String(p * UV) }, (p * UV).toFixed(1))))));
  table.hidden = doc.lifts.length === 0;
}

// Load and show trial `trialId`'s EMG; a trial without EMG says why (the server's 409).
export async function showTrialEmg(trialId) {
  const msg = document.getElementById("emg-panel-msg");
  const el = document.getElementById("emg-plot");
  const table = document.getElementById("emg-lifts");
  const root = document.getElementById("emg-panel");
  Object.assign(state, { trialId, loaded: false, error: null, doc: null });
  root.dataset.state = "loading";
  msg.className = "msg small";
  msg.textContent = "processing the trial's EMG…";
  table.hidden = true;
  let doc;
  try {
    doc = await api.emg.trialEmgEnvelope(trialId);
  } catch (err) {
    if (state.trialId !== trialId) return;
    if (plot) { plot.destroy(); plot = null; }
    el.replaceChildren();
    root.dataset.state = err instanceof ApiError && err.status === 409 ? "none" : "error";
    msg.textContent = err.message;
    state.error = err.message;
    return;
  }
  if (state.trialId !== trialId) return;  // another trial was opened meanwhile
  draw(el, doc);
  liftTable(table, doc);
  root.dataset.state = "loaded";
  msg.textContent = `${doc.source.toUpperCase()} recording ${doc.recording_id}: envelope ` +
    `(${doc.processing.highpass_hz}-${doc.processing.lowpass_hz} Hz band-pass, ` +
    `${doc.processing.envelope_hz} Hz low-pass, zero phase), not normalised, shown at ` +
    `${doc.fs.toFixed(0)} Hz · ${doc.lifts.length} lifts (${doc.lift_source})`;
  Object.assign(state, { loaded: true, doc });
}

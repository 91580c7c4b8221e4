// One wearer's long use: start and stop the controller in a long-use session, mark
// events, and the learning curves over sessions (values with their 95 % intervals, the
// least-squares trend per session), all from the wearer's progress document (api.wearers).
import * as api from "/static/api_client.js";
import { $, act, fmtDate, h, showFatal } from "/static/dom.js";
import { createMarkerBar } from "/static/markers.js";
import { controllerLabel } from "/static/names.js";

const participantId = Number(location.pathname.split("/").at(-2));
const SVG = "http://www.w3.org/2000/svg";

// How each metric reads: its name, the scale of its values, digits, unit, and the unit
// of its trend (rates change in percentage points per session).
const METRICS = {
  lifts_per_hour: { label: "Lifts per hour", scale: 1, digits: 1, unit: "", trend: " /h per session" },
  recognition_rate: { label: "Recognition rate", scale: 100, digits: 0, unit: " %", trend: " pp per session" },
  lock_rate: { label: "Correct lock rate", scale: 100, digits: 0, unit: " %", trend: " pp per session" },
  time_to_lock_s: { label: "Time to lock", scale: 1, digits: 2, unit: " s", trend: " s per session" },
  fp_per_hour_walking: { label: "False positives per hour of walking", scale: 1, digits: 1, unit: "", trend: " /h per session" },
  fp_per_hour_stairs: { label: "False positives per hour of stairs", scale: 1, digits: 1, unit: "", trend: " /h per session" },
};

// What the browser tests read: the loaded document and how often it loaded.
const state = (window.exostudyWearer = { loaded: 0, doc: null, running: null });

let participant = null;
// The long-use session the page works in: `?session=ID`, else the newest. The marker
// bar (with its hotkeys) belongs to one session, so choosing another reloads the page.
const chosenSession = Number(new URLSearchParams(location.search).get("session")) || null;

// `x` with `d` decimals, never "-0.00": a value that rounds to zero reads as zero.
function fixed(x, d) {
  const text = x.toFixed(d);
  return Number(text) === 0 ? (0).toFixed(d) : text;
}

// A metric's value as the page shows it ("40 %", "1081.1", "0.30 s"); "–" for none.
export function formatValue(metric, v) {
  if (v == null) return "–";
  const m = METRICS[metric];
  return `${fixed(v * m.scale, m.digits)}${m.unit}`;
}

// A trend's slope with its sign and unit ("+20.0 pp per session").
export function formatSlope(metric, v) {
  if (v == null) return "–";
  const m = METRICS[metric];
  const text = fixed(v * m.scale, m.digits + 1);
  return `${text.startsWith("-") ? "" : "+"}${text}${m.trend}`;
}

function interval(metric, lo, hi, scaleOnly = false) {
  if (lo == null || hi == null) return "";
  const m = METRICS[metric];
  const d = scaleOnly ? m.digits + 1 : m.digits;
  return `[${fixed(lo * m.scale, d)}, ${fixed(hi * m.scale, d)}]`;
}

// ------------------------------------------------------------------------ long use

async function loadSessions() {
  const all = await api.sessions.list(participantId);
  const long = all.filter((s) => s.kind === "long_use");
  const sel = $("#use-session");
  sel.replaceChildren(...long.map((s, i) => h("option", { value: s.id },
    `${i + 1}: ${fmtDate(s.started_at)} (session ${s.id})`)));
  const current = long.find((s) => s.id === chosenSession) ?? long.at(-1);
  if (current) {
    sel.value = String(current.id);
    await createMarkerBar($("#marker-bar"), current.id);
  }
  $("#use-form").hidden = long.length === 0;
  await showRunning();
}

async function showRunning() {
  const sid = Number($("#use-session").value);
  state.running = null;
  if (sid) {
    const trials = await api.trials.list(sid);
    state.running = trials.find((t) => t.status === "running") ?? null;
  }
  const r = state.running;
  $("#use-status").textContent = r
    ? `Trial ${r.id} runs the ${controllerLabel(r.controller)} since ${fmtDate(r.started_at)}.`
    : (sid ? "The controller is not running in this session." : "No long-use session yet.");
  $("#use-status").dataset.running = r ? String(r.id) : "";
  $("#use-stop").disabled = !r;
  $("#use-start").disabled = Boolean(r) || !sid;
}

async function loadSets(controllers) {
  $("#use-controller").replaceChildren(...controllers.map((c) =>
    h("option", { value: c }, controllerLabel(c))));
  const [models, utilities] = await Promise.all([
    api.models.listModelSets(participant.study_id),
    api.models.listUtilitySets(participant.study_id)]);
  const ready = (list) => list.filter((s) => s.status === "ready");
  $("#use-model-set").replaceChildren(h("option", { value: "" }, "–"),
    ...ready(models).map((s) => h("option", { value: s.id }, `${s.name} (${s.id})`)));
  $("#use-utility-set").replaceChildren(h("option", { value: "" }, "–"),
    ...ready(utilities).map((s) => h("option", { value: s.id },
      `${s.name}, ${s.precompression_pct} % (${s.id})`)));
}

$("#use-new-session").addEventListener("click", () => act($("#use-new-session"), $("#use-msg"), async () => {
  const s = await api.sessions.create(participantId, {
    kind: "long_use", precompression_pct: Number($("#use-pct").value) });
  location.assign(`?session=${s.id}`);
  return `long-use session ${s.id} created`;
}));

$("#use-session").addEventListener("change", () => location.assign(`?session=${$("#use-session").value}`));

$("#use-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#use-start"), $("#use-msg"), async () => {
    const body = { controller: $("#use-controller").value };
    for (const k of ["model_set_id", "utility_set_id"]) {
      const v = ev.target.elements[k].value;
      if (v) body[k] = Number(v);
    }
    const t = await api.wearers.startLongUse(Number($("#use-session").value), body);
    return `trial ${t.id} started`;
  }, () => showRunning().catch(showFatal));
});

$("#use-stop").addEventListener("click", () => act($("#use-stop"), $("#use-msg"), async () => {
  const t = await api.trials.stop(state.running.id, { outcome: "completed" });
  await loadProgress();
  return `trial ${t.id} stopped: ${t.tick_count} ticks stored`;
}, () => showRunning().catch(showFatal)));

// ------------------------------------------------------------------------ progress

function curveChart(curve) {
  const pts = curve.points.filter((p) => p.value != null);
  const W = 420, H = 180, L = 48, R = 10, T = 10, B = 28;
  const svg = document.createElementNS(SVG, "svg");
  svg.setAttribute("viewBox", `0 0 ${W} ${H}`);
  svg.setAttribute("role", "img");
  svg.setAttribute("aria-label", `${METRICS[curve.metric].label} over sessions`);
  svg.classList.add("curve");
  const el = (tag, attrs, text) => {
    const n = document.createElementNS(SVG, tag);
    for (const [k, v] of Object.entries(attrs)) n.setAttribute(k, v);
    if (text != null) n.textContent = text;
    svg.append(n);
    return n;
  };
  const n = Math.max(curve.points.length, 1);
  const ys = pts.flatMap((p) => [p.value, p.low ?? p.value, p.high ?? p.value]);
  const lo = Math.min(0, ...ys);
  let hi = Math.max(...ys, lo);
  if (hi === lo) hi = lo + 1;
  const x = (s) => L + (n === 1 ? 0.5 : (s - 1) / (n - 1)) * (W - L - R);
  const y = (v) => T + (1 - (v - lo) / (hi - lo)) * (H - T - B);
  el("line", { x1: L, y1: y(lo), x2: W - R, y2: y(lo), stroke: "#99a" });
  el("line", { x1: L, y1: T, x2: L, y2: H - B, stroke: "#99a" });
  const m = METRICS[curve.metric];
  for (const v of [lo, hi]) {
    el("text", { x: L - 4, y: y(v) + 4, "text-anchor": "end", "font-size": 10 },
      (v * m.scale).toFixed(m.digits));
  }
  curve.points.forEach((p) => el("text", { x: x(p.session), y: H - 10, "text-anchor": "middle",
    "font-size": 10 }, String(p.session)));
  const t = curve.trend;
  if (t.slope != null && curve.points.length > 1) {
    el("line", { x1: x(1), y1: y(t.intercept + t.slope), x2: x(n), y2: y(t.intercept + t.slope * n),
      stroke: "#c05", "stroke-dasharray": "5 3", class: "trend" });
  }
  for (const p of pts) {
    if (p.low != null && p.high != null) {
      el("line", { x1: x(p.session), y1: y(p.low), x2: x(p.session), y2: y(p.high), stroke: "#246" });
    }
    el("circle", { cx: x(p.session), cy: y(p.value), r: 4, fill: "#246", class: "point" });
  }
  return svg;
}

function render(doc) {
  const sessions = doc.sessions;
  $("#progress-empty").hidden = sessions.length > 0;
  $("#progress-notes").replaceChildren(...doc.notes.map((n) => h("li", { class: "muted" }, n)));
  $("#progress-table thead").replaceChildren(h("tr", {}, h("th", {}, "metric"),
    ...sessions.map((s) => h("th", { title: fmtDate(s.started_at) }, `session ${s.number}`)),
    h("th", {}, "trend per session [95 %]")));
  $("#progress-table tbody").replaceChildren(...doc.curves.map((c) => h("tr", { "data-metric": c.metric },
    h("th", {}, METRICS[c.metric].label),
    ...c.points.map((p) => h("td", { "data-metric": c.metric, "data-session": p.session },
      h("span", { class: "value" }, formatValue(c.metric, p.value)), " ",
      h("span", { class: "muted small ci" }, interval(c.metric, p.low, p.high)))),
    h("td", { class: "trend", "data-metric": c.metric },
      h("span", { class: "value" }, formatSlope(c.metric, c.trend.slope)), " ",
      h("span", { class: "muted small ci" }, interval(c.metric, c.trend.low, c.trend.high, true))))));
  $("#curves").replaceChildren(...doc.curves.map((c) => h("figure", { "data-curve": c.metric },
    h("figcaption", { class: "small" }, METRICS[c.metric].label), curveChart(c))));
  $("#progress-sessions tbody").replaceChildren(...sessions.map((s) => h("tr", { "data-session": s.session_id },
    h("td", {}, s.number), h("td", {}, fmtDate(s.started_at)),
    h("td", {}, s.controllers.map(controllerLabel).join(", ")), h("td", {}, s.truth.join(", ")),
    h("td", {}, s.hours.toFixed(3)), h("td", {}, s.lifts), h("td", {}, s.confirmed_lifts),
    h("td", {}, s.unconfirmed_lifts), h("td", {}, s.walking_hours.toFixed(3)),
    h("td", {}, s.stairs_hours.toFixed(3)))));
}

async function loadProgress() {
  const c = $("#progress-controller").value;
  const doc = await api.wearers.getProgress(participantId, c ? { controller: c } : undefined);
  state.doc = doc;
  render(doc);
  state.loaded += 1;
  return doc;
}

$("#progress-controller").addEventListener("change", () =>
  act($("#progress-refresh"), $("#progress-msg"), async () => { await loadProgress(); return "updated"; }));
$("#progress-refresh").addEventListener("click", () =>
  act($("#progress-refresh"), $("#progress-msg"), async () => { await loadProgress(); return "updated"; }));

async function init() {
  participant = await api.participants.get(participantId);
  $("#wearer-code").textContent = participant.code;
  document.title = `ExoStudy · ${participant.code}: long use`;
  const study = await api.studies.get(participant.study_id);
  $("#study-link").textContent = study.name;
  $("#study-link").href = `/console/studies/${study.id}`;
  const doc = await loadProgress();
  $("#progress-controller").replaceChildren(h("option", { value: "" }, "all"),
    ...doc.long_use_controllers.map((c) => h("option", { value: c }, controllerLabel(c))));
  await loadSets(doc.long_use_controllers);
  await loadSessions();
}

init().catch(showFatal);

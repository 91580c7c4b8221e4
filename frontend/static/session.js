// A session, step by step: data collection (record, check the lifts, fit models) or
// evaluation (plan, calibrate, run the trials); utilities for the session's
// precompression in both. The live stream feeds a small angle plot, the state strip and
// the stillness indicator.
import * as api from "/static/api_client.js";
import { $, act, h, showFatal } from "/static/dom.js";
import { waitForJob, progressView } from "/static/jobs.js";
import { connectLive, Ring } from "/static/livestream.js";
import { createTimePlots } from "/static/timeplots.js";
import { displayValue, lastTick } from "/static/tickdata.js";
import { createStateStrip } from "/static/statestrip.js";
import { createSegmentPlot } from "/static/segmentplot.js";
import { drawEmpty, drawModelSet } from "/static/modelplot.js";
import { createUtilityPlots } from "/static/utilityplot.js";
import { Stillness } from "/static/stillness.js";
import { createMarkerBar, createStreamPicker, markDrawn, noteMarker } from "/static/markers.js";
import { controllerLabel, MODEL_NAMES, modelLabel, SCRIPTS, SEGMENT_LABELS } from "/static/names.js";
import { categoryColour } from "/static/palette.js";
import { conditionNote, personalPlanFields } from "/static/personal_plan.js";

const sessionId = Number(location.pathname.split("/").pop());

// What the browser tests read.
const page = (window.exostudySession = {
  samples: 0, recordingId: null, segments: [], shownRecording: null, modelSetDrawn: null,
  utilityCurvesFor: null, stillness: null, calibration: null,
});

let session = null;
let participant = null;
let studyId = null;

// ------------------------------------------------------------ live stream
const ring = new Ring(["t", "q_left", "q_right"], 1000);
const livePlots = createTimePlots({ angles: $("#live-angles") },
  { height: 180, onMarkersShown: markDrawn });
const strip = createStateStrip($("#strip"));
page.strip = strip.counts;
const stillness = new Stillness();
let latest = null;
let frameQueued = false;
let lastDraw = -Infinity;

// A frame is asked for only when ticks arrived (no idle animation loop), and drawn at
// most every 40 ms: the small plot and the indicator need no more.
function requestDraw() {
  if (frameQueued) return;
  frameQueued = true;
  const wait = lastDraw + 40 - performance.now();
  if (wait > 0) setTimeout(() => requestAnimationFrame(frame), wait);
  else requestAnimationFrame(frame);
}

function frame(ts) {
  frameQueued = false;
  lastDraw = ts;
  livePlots.setData(ring.cols);
  strip.update(latest);
  showStillness();
}

connectLive({
  onTicks(msg) {
    ring.push(msg.columns, displayValue);
    stillness.push(msg.columns);
    strip.observe(msg.columns);
    latest = lastTick(msg.columns);
    page.samples += msg.columns.t.length;
    requestDraw();
  },
  onMarker(m) { if (m.session_id === sessionId) { noteMarker(m); livePlots.addMarker(m); } },
  onStatus(hlth) {
    page.health = hlth;
    $("#worker-line").textContent = hlth.worker.alive
      ? `· controller ${hlth.worker.controller ?? "none"}` : "· worker stopped";
    $("#sim-form").hidden = hlth.device.kind !== "sim";
    $("#sim-follow-row").hidden = hlth.device.kind !== "sim";
  },
  onState(state) {
    const c = $("#conn");
    c.dataset.state = state;
    c.className = "pill " + (state === "live" ? "pill-ok" : "pill-bad");
    $("#conn-text").textContent = state === "live" ? "live" : "disconnected, retrying";
  },
});

function showStillness() {
  const el = $("#stillness");
  const s = stillness.state();
  page.stillness = s;
  if (!s) return;
  el.dataset.still = String(s.still);
  el.textContent = `${s.still ? "✓ still" : "moving"} · std left ${s.stdLeftDeg.toFixed(2)}°, right ${s.stdRightDeg.toFixed(2)}°`;
}

// ------------------------------------------------------------ session header
async function loadSession() {
  session = await api.sessions.get(sessionId);
  participant = await api.participants.get(session.participant_id);
  studyId = participant.study_id;
  const study = await api.studies.get(studyId);
  const kind = session.kind === "evaluation" ? "Evaluation" : "Data collection";
  document.title = `ExoStudy · ${participant.code} · ${kind}`;
  $("#session-title").textContent = `${kind} · participant ${participant.code}`;
  $("#crumb-study").textContent = study.name;
  $("#crumb-study").href = `/console/studies/${studyId}`;
  $("#crumb-participant").textContent = `${participant.code} · session ${session.id}`;
  $("#pct").value = session.precompression_pct;
  $("#util-pct").textContent = session.precompression_pct;
  $("#util-num").textContent = session.kind === "evaluation" ? "1" : "4";
  for (const sec of document.querySelectorAll("[data-kind]")) sec.hidden = sec.dataset.kind !== session.kind;
  if (session.kind === "evaluation") $("main").insertBefore($("#utility-step"), $("#plan-step"));
  $("#fit-name").value = `${participant.code} demonstrations`;
}

$("#pct-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#pct-save"), $("#pct-msg"), async () => {
    session = await api.sessions.update(sessionId, { precompression_pct: Number($("#pct").value) });
    $("#util-pct").textContent = session.precompression_pct;
    showUtilities(true);
    return `saved ${session.precompression_pct} %`;
  });
});

$("#sim-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#sim-apply"), $("#sim-msg"), async () => {
    $("#rec-start").disabled = true;
    try {
      await applySimulation($("#sim-script").value);
    } finally {
      syncRecordButtons();
    }
    return `wearer now does ${$("#sim-script").value}`;
  });
});

let simScript = null;
async function applySimulation(script) {
  const before = latest ? latest.t : Infinity;
  await api.worker.setSimulation({ script, seed: Number($("#sim-seed").value) });
  // The simulator restarts with its clock at zero: wait until the stream shows the new
  // one running, so that a recording or trial started next holds only its samples.
  await waitUntil(() => latest && latest.t < before && latest.t > 0.5, 10000);
  simScript = script;
  $("#sim-script").value = script;
}

function waitUntil(cond, timeoutMs) {
  const until = performance.now() + timeoutMs;
  return new Promise((resolve, reject) => {
    const check = () => {
      if (cond()) resolve();
      else if (performance.now() > until) reject(new Error("the simulator did not restart in time"));
      else setTimeout(check, 50);
    };
    check();
  });
}

// ------------------------------------------------------------ recordings
let recordings = [];
const segmentsByRecording = new Map();
const excluded = new Set();

const segPlot = createSegmentPlot($("#seg-plot"), {
  async onEdgeMoved(seg, which, index, original) {
    try {
      const updated = await api.recordings.editSegment(seg.id, { [which]: index });
      Object.assign(seg, updated);
      $("#seg-msg").className = "msg msg-ok";
      $("#seg-msg").textContent = `lift ${seg.id}: ${which} moved to ${segTime(index)} s`;
    } catch (err) {
      seg[which] = original;
      $("#seg-msg").className = "msg msg-bad";
      $("#seg-msg").textContent = err.message;
    }
    showSegments();
  },
});
page.edgeClientPoint = (id, which) => segPlot.edgeClientPoint(id, which);

// The simulated wearer's scripts and the model legend, from the vocabulary.
$("#sim-script").replaceChildren(...SCRIPTS.map((name) => h("option", { value: name }, name)));
$("#model-legend").prepend(...MODEL_NAMES.map((m) => h("span", {},
  h("span", { class: "swatch", style: `background: ${categoryColour(m)}` }), modelLabel(m))));

$("#seg-legend").replaceChildren(...SEGMENT_LABELS.map((l) => h("span", {},
  h("span", { class: "swatch", style: `background: ${categoryColour(l)}` }), modelLabel(l))));

let shownAngles = null;
const segTime = (i) => (shownAngles && shownAngles.t[i] != null ? (shownAngles.t[i] - shownAngles.t[0]).toFixed(2) : "–");

async function loadRecordings() {
  recordings = await api.recordings.list(sessionId);
  for (const r of recordings) {
    if (r.status === "stopped" && !segmentsByRecording.has(r.id)) {
      segmentsByRecording.set(r.id, await api.recordings.listSegments(r.id));
    }
  }
  const active = recordings.find((r) => r.status === "recording");
  setRecordingState(active);
  $("#recordings tbody").replaceChildren(...recordings.map((r) => h("tr",
    { "data-recording": r.id, class: page.shownRecording === r.id ? "selected" : null },
    h("td", {}, r.id), h("td", {}, r.label || "–"),
    h("td", {}, h("span", { class: "badge", "data-status": r.status }, r.status)),
    h("td", {}, r.status === "stopped" ? String((segmentsByRecording.get(r.id) || []).length) : "–"),
    h("td", {}, r.status === "stopped"
      ? h("button", { type: "button", onclick: () => showRecording(r.id) }, "Show") : ""))));
  updateFitCounts();
}

function syncRecordButtons() {
  setRecordingState(recordings.find((r) => r.status === "recording"));
}

function setRecordingState(active) {
  page.recordingId = active ? active.id : null;
  $("#rec-start").disabled = Boolean(active);
  $("#rec-stop").disabled = !active;
  const st = $("#rec-state");
  st.dataset.recording = String(Boolean(active));
  st.textContent = active ? `recording #${active.id}…` : "not recording";
}

$("#rec-start").addEventListener("click", (ev) => act(ev.target, $("#rec-msg"), async () => {
  const r = await api.recordings.start(sessionId, { label: $("#rec-label").value });
  await loadRecordings();
  return `recording #${r.id} started: the worker runs without locks`;
}, syncRecordButtons));

$("#rec-stop").addEventListener("click", (ev) => act(ev.target, $("#rec-msg"), async () => {
  const r = await api.recordings.stop(page.recordingId);
  await loadRecordings();
  await showRecording(r.id);
  await findLifts(false);
  return `recording #${r.id} stopped and segmented`;
}, syncRecordButtons));

async function showRecording(id) {
  shownAngles = await api.recordings.recordingAngles(id);
  page.shownRecording = id;
  $("#seg-title").textContent = `· recording #${id}`;
  segPlot.setRecording(shownAngles);
  showSegments();
  document.querySelectorAll("#recordings tbody tr").forEach((tr) =>
    tr.classList.toggle("selected", Number(tr.dataset.recording) === id));
}

async function findLifts(replace) {
  const id = page.shownRecording;
  const found = await api.recordings.autoSegment(id, replace ? { replace: true } : {});
  segmentsByRecording.set(id, found);
  showSegments();
  await loadRecordings();
  return found.length;
}

$("#seg-run").addEventListener("click", (ev) => act(ev.target, $("#seg-msg"), async () => {
  if (page.shownRecording == null) throw new Error("record or show a recording first");
  const edited = (segmentsByRecording.get(page.shownRecording) || []).some((s) => s.source === "edited");
  if (edited && !confirm("Some lifts were edited by hand. Discard the edits?")) return "kept the edits";
  return `found ${await findLifts(edited)} lifts`;
}));

function showSegments() {
  const list = segmentsByRecording.get(page.shownRecording) || [];
  for (const s of list) s.excluded = excluded.has(s.id);
  page.segments = list.map((s) => ({ id: s.id, start: s.start, end: s.end, label: s.label, source: s.source }));
  segPlot.setSegments(list);
  $("#segments tbody").replaceChildren(...list.map((s, i) => h("tr", { "data-segment": s.id, "data-source": s.source },
    h("td", {}, h("input", { type: "checkbox", class: "use", checked: !excluded.has(s.id), "aria-label": `use lift ${i + 1}`,
      onchange: (ev) => { if (ev.target.checked) excluded.delete(s.id); else excluded.add(s.id); showSegments(); } })),
    h("td", {}, i + 1), h("td", {}, segTime(s.start)), h("td", {}, segTime(s.end)),
    h("td", {}, h("select", { class: "label", "aria-label": `label of lift ${i + 1}`,
      onchange: (ev) => relabel(s, ev.target.value) },
    ...SEGMENT_LABELS.map((l) => h("option", { value: l, selected: l === s.label ? "selected" : null }, modelLabel(l))))),
    h("td", {}, h("span", { class: "badge" }, s.source)),
    h("td", {}, h("button", { type: "button", class: "danger", onclick: () => removeSegment(s) }, "Delete")))));
  updateFitCounts();
}

async function relabel(seg, label) {
  try {
    Object.assign(seg, await api.recordings.editSegment(seg.id, { label }));
    $("#seg-msg").className = "msg msg-ok";
    $("#seg-msg").textContent = `lift ${seg.id} is now ${modelLabel(label)}`;
  } catch (err) {
    $("#seg-msg").className = "msg msg-bad";
    $("#seg-msg").textContent = err.message;
  }
  showSegments();
}

async function removeSegment(seg) {
  await api.recordings.deleteSegment(seg.id);
  const list = segmentsByRecording.get(seg.recording_id) || [];
  segmentsByRecording.set(seg.recording_id, list.filter((s) => s.id !== seg.id));
  showSegments();
  loadRecordings();
}

// ------------------------------------------------------------ models
function chosenSegments() {
  return [...segmentsByRecording.values()].flat()
    .filter((s) => MODEL_NAMES.includes(s.label) && !excluded.has(s.id));
}

function updateFitCounts() {
  const chosen = chosenSegments();
  const counts = MODEL_NAMES.map((m) => [m, chosen.filter((s) => s.label === m).length]);
  const short = counts.filter(([, c]) => c < 2);
  $("#fit-counts").innerHTML = "";
  $("#fit-counts").append(`${chosen.length} lifts chosen: ` + counts.map(([m, c]) => `${modelLabel(m)} ${c}`).join(", "),
    short.length ? h("span", { class: "warn-text" }, ` · need at least 2 of each`) : "");
  $("#fit-run").disabled = short.length > 0;
}

$("#fit-run").addEventListener("click", (ev) => act(ev.target, $("#fit-msg"), async () => {
  const ms = await api.models.fit(studyId,
    { name: $("#fit-name").value || "models", segment_ids: chosenSegments().map((s) => s.id) });
  await waitForJob(ms.job_id, progressView($("#fit-progress"), $("#fit-caption")));
  await loadModelSets(ms.id);
  return `model set “${ms.name}” fitted`;
}, updateFitCounts));

async function loadModelSets(select) {
  const sets = await api.models.listModelSets(studyId);
  // Personal sets are chosen per participant in the plan's conditions, not here.
  const ready = sets.filter((s) => s.status === "ready" && s.kind !== "personal");
  for (const sel of [$("#ms-select"), $("#plan-ms")]) {
    const keep = select ?? sel.value;
    sel.replaceChildren(...(sel.id === "plan-ms" ? [h("option", { value: "" }, "none")] : []),
      ...ready.map((s) => h("option", { value: s.id }, `#${s.id} ${s.name}`)));
    if (keep && ready.some((s) => String(s.id) === String(keep))) sel.value = String(keep);
    else if (ready.length) sel.value = String(ready[ready.length - 1].id);
  }
  if (session.kind !== "data_collection") return;
  if (ready.length) await showModelSet(Number($("#ms-select").value));
  else drawEmpty($("#model-plot"), "no model set yet: fit one above");
}

async function showModelSet(id) {
  const doc = await api.models.modelSetDocument(id);
  drawModelSet($("#model-plot"), doc);
  page.modelSetDrawn = id;
  const counts = doc.fit_params?.counts ?? {};
  $("#ms-info").replaceChildren(h("h3", { class: "small" }, `Model set ${doc.version}`),
    h("table", { class: "list" }, h("thead", {}, h("tr", {}, h("th", {}, "motion"), h("th", {}, "demonstrations"),
      h("th", {}, "latent dim"), h("th", {}, "explained variance"))),
    h("tbody", {}, ...Object.entries(doc.models).map(([name, m]) => h("tr", {}, h("td", {}, modelLabel(name)),
      h("td", {}, m.n_demonstrations ?? counts[name] ?? "–"), h("td", {}, m.q),
      h("td", {}, m.explained_variance != null ? `${(m.explained_variance * 100).toFixed(1)} %` : "–"))))));
}
$("#ms-select").addEventListener("change", (ev) => showModelSet(Number(ev.target.value)));

// ------------------------------------------------------------ utilities
const utilPlots = createUtilityPlots($("#util-plots"));
let utilRun = 0;

async function showUtilities(computeIfMissing) {
  const run = ++utilRun;
  const pct = session.precompression_pct;
  const sets = await api.models.listUtilitySets(studyId);
  let match = sets.filter((s) => s.status === "ready" && Math.abs(s.precompression_pct - pct) < 1e-9).pop();
  fillUtilitySelect(sets);
  if (!match && computeIfMissing) {
    $("#util-msg").className = "msg";
    $("#util-msg").textContent = `computing utilities for ${pct} %…`;
    const us = await api.models.computeUtilitySet(studyId, { name: `simulated ${pct} %`, precompression_pct: pct });
    await waitForJob(us.job_id, (job) => { $("#util-progress").value = job.progress; });
    if (run !== utilRun) return;
    match = us;
    fillUtilitySelect(await api.models.listUtilitySets(studyId));
    $("#util-msg").className = "msg msg-ok";
    $("#util-msg").textContent = `computed utilities for ${pct} %`;
  }
  if (!match) {
    $("#util-which").textContent = `no utilities for ${pct} % yet`;
    return;
  }
  const curves = await api.models.utilityCurves(match.id);
  if (run !== utilRun) return;
  $("#util-progress").value = 1;
  utilPlots.setCurves(curves);
  page.utilityCurvesFor = pct;
  $("#util-which").textContent = `utility set #${match.id} “${match.name}”`;
  if ($("#plan-us")) $("#plan-us").value = String(match.id);
}

function fillUtilitySelect(sets) {
  const sel = $("#plan-us");
  const keep = sel.value;
  sel.replaceChildren(h("option", { value: "" }, "none"), ...sets.filter((s) => s.status === "ready").map((s) =>
    h("option", { value: s.id }, `#${s.id} ${s.name} (${s.precompression_pct} %)`)));
  if (keep) sel.value = keep;
}

$("#util-run").addEventListener("click", (ev) => act(ev.target, $("#util-msg"), async () => {
  await showUtilities(true);
  return `utilities for ${session.precompression_pct} % shown`;
}));

// ------------------------------------------------------------ evaluation
async function loadTrials() {
  const [trials, labels] = await Promise.all([api.trials.list(sessionId),
    api.participants.listConditions(participant.id)]);
  const blind = Object.fromEntries(labels.map((c) => [c.controller, c.label]));
  $("#plan-run").disabled = trials.length > 0;
  if (trials.length) $("#plan-msg").textContent = "planned: the order below is fixed for this session";
  const running = trials.some((t) => t.status === "running");
  $("#trials tbody").replaceChildren(...trials.map((t) => h("tr", { "data-trial": t.id, "data-controller": t.controller, "data-status": t.status },
    h("td", {}, t.planned_order + 1), h("td", {}, h("strong", {}, controllerLabel(t.controller)),
      conditionNote(t)),
    h("td", {}, blind[t.controller] ? `setting ${blind[t.controller]}` : "–"), h("td", {}, t.task),
    h("td", {}, h("span", { class: "badge", "data-status": t.status }, t.status)),
    h("td", {}, ...trialButtons(t, running)))));
  page.trials = trials.map((t) => ({ id: t.id, controller: t.controller, status: t.status }));
}

function trialButtons(t, running) {
  if (t.status === "planned") {
    return [h("button", { type: "button", class: "primary start", disabled: running,
      onclick: (ev) => trialAction(ev.target, () => api.trials.start(t.id, {}), `${controllerLabel(t.controller)} · ${t.task} running`,
        () => followTask(t.task)) }, "▶ Start")];
  }
  if (t.status === "running") {
    return [h("button", { type: "button", class: "big complete",
      onclick: (ev) => trialAction(ev.target, () => api.trials.stop(t.id, { outcome: "completed" }), "trial completed") }, "■ Stop: completed"), " ",
    h("button", { type: "button", class: "danger abort",
      onclick: (ev) => trialAction(ev.target, () => api.trials.stop(t.id, { outcome: "aborted", reason: "aborted by the experimenter" }), "trial aborted") }, "Abort")];
  }
  return [h("a", { href: `/live?trial=${t.id}`, class: "replay" }, "Replay ›")];
}

// With the simulated wearer, a trial's task is what the wearer then does.
async function followTask(task) {
  const known = [...$("#sim-script").options].map((o) => o.value);
  if ($("#sim-follow-row").hidden || !$("#sim-follow").checked || !known.includes(task)) return;
  if (task !== simScript) await applySimulation(task);
}

function trialAction(button, request, text, before = null) {
  return act(button, $("#trial-msg"), async () => {
    if (before) await before();
    await request();
    await loadTrials();
    return text;
  });
}

$("#plan-run").addEventListener("click", (ev) => act(ev.target, $("#plan-msg"), async () => {
  const tasks = [...document.querySelectorAll("input[name=task]:checked")].map((x) => x.value);
  const body = { tasks, include_eumc: $("#plan-eumc").checked };
  // Baselines (springs free, no exoskeleton) for the lift tasks; the server says which.
  if ($("#plan-baselines").checked) body.include_baselines = true;
  if ($("#plan-ms").value) body.model_set_id = Number($("#plan-ms").value);
  if ($("#plan-us").value) body.utility_set_id = Number($("#plan-us").value);
  Object.assign(body, personalPlanFields());  // conditions, personal and prior sets, block
  const trials = await api.trials.plan(sessionId, body);
  $("#plan-msg").dataset.order = trials.map((t) => t.controller).join(",");
  await loadTrials();
  // The plan made the blinded condition labels: the questionnaire step offers them now.
  document.dispatchEvent(new CustomEvent("exostudy:planned", { detail: { trials } }));
  const order = [...new Set(trials.map((t) => controllerLabel(t.controller) + conditionNote(t)))].join(" → ");
  return `planned ${trials.length} trials: ${order}`;
}, () => { $("#plan-run").disabled = (page.trials || []).length > 0; }));

// Calibration: the worker averages the next seconds of raw angles and refuses them if
// the wearer moved (422). With "retry", wait for the stillness indicator and try again
// until it succeeds, the experimenter stops it, or 30 s have passed.
const CALIB_PATIENCE_MS = 30000;
let calibCancelled = false;
$("#calib-cancel").addEventListener("click", () => { calibCancelled = true; });

function untilStill(deadline) {
  return new Promise((resolve) => {
    const check = () => {
      if (calibCancelled || performance.now() > deadline || stillness.state()?.still) resolve();
      else setTimeout(check, 50);
    };
    check();
  });
}

$("#calib-run").addEventListener("click", (ev) => act(ev.target, $("#calib-msg"), async () => {
  const seconds = Number($("#calib-seconds").value);
  const retry = $("#calib-retry").checked;
  const deadline = performance.now() + CALIB_PATIENCE_MS;
  calibCancelled = false;
  $("#calib-cancel").hidden = !retry;
  page.calibration = { attempts: 0, ok: false };
  try {
    for (;;) {
      if (retry) await untilStill(deadline);
      if (calibCancelled) throw new Error(`calibration stopped after ${page.calibration.attempts} attempts`);
      page.calibration.attempts += 1;
      $("#calib-msg").textContent = `calibrating (attempt ${page.calibration.attempts}): stand still for ${seconds} s…`;
      try {
        const r = await api.worker.calibrate({ seconds });
        page.calibration = { ...r, attempts: page.calibration.attempts };
        return `calibrated: offsets ${r.offset_left_deg.toFixed(1)}°, ${r.offset_right_deg.toFixed(1)}° ` +
          `(std ${r.std_left_deg?.toFixed(2)}°, ${r.std_right_deg?.toFixed(2)}°)` +
          (page.calibration.attempts > 1 ? ` after ${page.calibration.attempts} attempts` : "");
      } catch (err) {
        // 422: the wearer moved; anything else (no worker) will not get better by waiting.
        if (!retry || err.status !== 422 || performance.now() > deadline) throw err;
      }
    }
  } finally {
    $("#calib-cancel").hidden = true;
  }
}));

// ------------------------------------------------------------ start
async function start() {
  await loadSession();
  await createMarkerBar($("#marker-bar"), sessionId);
  createStreamPicker($("#lsl-streams"), sessionId);
  if (session.kind === "data_collection") {
    await loadRecordings();
    const stopped = recordings.filter((r) => r.status === "stopped");
    if (stopped.length) await showRecording(stopped[stopped.length - 1].id);
    await loadModelSets();
  } else {
    await loadModelSets();
    await loadTrials();
  }
  await showUtilities(false);
  page.ready = true;
}
start().catch(showFatal);

// The session page's MVC step: plan maximum voluntary contractions per muscle (side,
// repetitions, contraction and rest times), then run each repetition from the console:
// a countdown, an `mvc_start` marker, the contraction timed on screen, an `mvc_stop`
// marker when the time is up (or the experimenter stops early), then the rest timed.
// The markers and the repetitions done are stored by the server (backend/emg/mvc.py);
// this page only times them.
import * as api from "/static/api_client.js";
import { $, act, h } from "/static/dom.js";

const sessionId = Number(location.pathname.split("/").pop());
const COUNTDOWN_S = 3;
const TICK_MS = 100;
// What the browser tests read.
const state = (window.exostudyMvc = { ready: false, steps: [], phase: "idle", events: [], montage: null });
let plan = [];
let running = null;  // { step, rep, phase, until, timer }

const MUSCLE_LABELS = {
  erector_spinae_lumbar: "erector spinae (lumbar)", erector_spinae_thoracic: "erector spinae (thoracic)",
  gluteus_maximus: "gluteus maximus", biceps_femoris: "biceps femoris",
  rectus_abdominis: "rectus abdominis", rectus_femoris: "rectus femoris",
};
const muscleLabel = (m) => MUSCLE_LABELS[m] ?? m.replaceAll("_", " ");

function setTimer(phase, text) {
  const el = $("#mvc-timer");
  el.dataset.phase = phase;
  el.textContent = text;
  state.phase = phase;
}

function done(step) {
  return step.repetitions_done.filter((r) => r.stop_marker_id != null).length;
}

function render() {
  const busy = running !== null;
  $("#mvc-steps tbody").replaceChildren(...state.steps.map((s, i) => {
    const n = done(s);
    const finished = n >= s.repetitions;
    return h("tr", { "data-step": s.id, "data-muscle": s.muscle, "data-side": s.side },
      h("td", {}, String(i + 1)), h("td", {}, muscleLabel(s.muscle)), h("td", {}, s.side),
      h("td", { class: "mvc-done" }, `${n} of ${s.repetitions} done`),
      h("td", {}, `${s.contraction_s} s`), h("td", {}, `${s.rest_s} s`),
      h("td", {}, h("button", {
        type: "button", class: "mvc-start primary", disabled: busy || finished,
        onclick: () => runRepetition(s),
      }, finished ? "done" : `Start repetition ${n + 1}`)));
  }));
  $("#mvc-stop").hidden = !(running && running.phase === "contract");
  $("#mvc-skip-rest").hidden = !(running && running.phase === "rest");
  $("#mvc-plan-save").disabled = busy || state.steps.some((s) => s.repetitions_done.length);
}

async function load() {
  state.steps = await api.emg.listMvcSteps(sessionId);
  render();
}

async function post(step, event) {
  const out = await api.emg.mvcEvent(sessionId, step.id, { event });
  state.events.push({ step: step.id, event });
  state.steps = state.steps.map((s) => (s.id === out.id ? out : s));
  return out;
}

// Counts down to `until` (performance.now() ms), showing `label(secondsLeft)`; resolves
// when the time is up or `running.cut` is set.
function countdown(phase, seconds, label) {
  return new Promise((resolve) => {
    const until = performance.now() + seconds * 1000;
    running.phase = phase;
    running.cut = false;
    render();
    const tick = () => {
      const left = Math.max(0, (until - performance.now()) / 1000);
      setTimer(phase, label(left));
      if (left <= 0 || running.cut) { clearInterval(running.timer); resolve(); }
    };
    running.timer = setInterval(tick, TICK_MS);
    tick();
  });
}

async function runRepetition(step) {
  if (running) return;
  const rep = done(step) + 1;
  const what = `${muscleLabel(step.muscle)}, ${step.side}, repetition ${rep} of ${step.repetitions}`;
  running = { step, rep };
  const msg = $("#mvc-msg");
  msg.className = "msg";
  try {
    await countdown("ready", COUNTDOWN_S, (s) => `${what}: get ready… ${Math.ceil(s)}`);
    step = await post(step, "start");
    await countdown("contract", step.contraction_s, (s) => `CONTRACT: push as hard as you can · ${s.toFixed(1)} s`);
    step = await post(step, "stop");
    msg.textContent = `${what}: stored (markers mvc_start and mvc_stop)`;
    msg.classList.add("msg-ok");
    if (done(step) < step.repetitions && step.rest_s > 0) {
      await countdown("rest", step.rest_s, (s) => `rest · ${Math.ceil(s)} s before the next repetition`);
    }
    setTimer("idle", done(step) >= step.repetitions ? `${muscleLabel(step.muscle)}: all repetitions done` : "ready for the next repetition");
  } catch (err) {
    msg.textContent = `${what}: ${err.message}`;
    msg.classList.add("msg-bad");
    setTimer("idle", "stopped");
    await load().catch(() => {});
  } finally {
    if (running && running.timer) clearInterval(running.timer);
    running = null;
    render();
  }
}

function renderPlan() {
  $("#mvc-plan-list").replaceChildren(...plan.map((p, i) => h("li", {},
    `${muscleLabel(p.muscle)} (${p.side}) × ${p.repetitions}, ${p.contraction_s} s, rest ${p.rest_s} s `,
    h("button", { type: "button", class: "link", onclick: () => { plan.splice(i, 1); renderPlan(); } }, "remove"))));
  $("#mvc-plan-save").hidden = plan.length === 0;
}

async function init() {
  const session = await api.sessions.get(sessionId);
  const participant = await api.participants.get(session.participant_id);
  // Every version (an empty list, not a 404, for a study without EMG); the newest counts.
  const versions = await api.emg.listMontages(participant.study_id);
  const montage = versions.length ? versions[versions.length - 1] : null;
  state.montage = montage;
  await load();
  const section = $("#mvc-step");
  if (!montage && !state.steps.length) return;  // no EMG in this study
  section.hidden = false;
  const muscles = montage ? [...new Set(montage.channels.map((c) => c.muscle))] : [];
  $("#mvc-muscle").replaceChildren(...muscles.map((m) => h("option", { value: m }, muscleLabel(m))));
  $("#mvc-plan").hidden = muscles.length === 0;
  $("#mvc-plan").addEventListener("submit", (ev) => {
    ev.preventDefault();
    const f = new FormData(ev.target);
    plan.push({ muscle: f.get("muscle"), side: f.get("side"), repetitions: Number(f.get("repetitions")),
      contraction_s: Number(f.get("contraction_s")), rest_s: Number(f.get("rest_s")) });
    renderPlan();
  });
  $("#mvc-plan-save").addEventListener("click", (ev) => act(ev.target, $("#mvc-msg"), async () => {
    state.steps = await api.emg.planMvc(sessionId, { steps: plan });
    plan = [];
    renderPlan();
    render();
    return `planned ${state.steps.length} MVC steps`;
  }));
  $("#mvc-stop").addEventListener("click", () => { if (running) running.cut = true; });
  $("#mvc-skip-rest").addEventListener("click", () => { if (running) running.cut = true; });
  renderPlan();
  state.ready = true;
}

init().catch((err) => {
  $("#mvc-step").hidden = false;
  $("#mvc-msg").textContent = `MVC steps unavailable: ${err.message}`;
});

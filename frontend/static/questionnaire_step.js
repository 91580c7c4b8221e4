// The session page's questionnaire step: make a participant link for the chosen forms
// and conditions, and show the scored answers (unblinded) as they arrive.
import * as api from "/static/api_client.js";
import { $, act, fmtDate, h } from "/static/dom.js";
import { controllerLabel } from "/static/names.js";

const sessionId = Number(location.pathname.split("/").pop());
const POLL_MS = 3000;
// What the browser tests read.
const state = (window.exostudyForms = { responses: [], preferences: [], polls: 0 });
let participantId = null;
let instruments = [];
let conditions = [];

function renderChoices() {
  $("#link-choices thead tr").replaceChildren(h("th", {}, "condition"),
    ...instruments.map((i) => h("th", {}, i.title || i.key)));
  $("#link-choices tbody").replaceChildren(...conditions.map((c) => h("tr", { "data-condition": c.label },
    // The controller is shown to the study's owners only (null for other roles).
    h("td", {}, h("strong", {}, c.label), c.controller ? h("span", { class: "muted small" }, ` (${controllerLabel(c.controller)})`) : ""),
    ...instruments.map((i) => h("td", {}, h("input", {
      type: "checkbox", name: "form", value: `${i.key}|${i.version}|${c.label}`, checked: true,
      "aria-label": `${i.key} for condition ${c.label}` }))))));
  $("#link-create").disabled = conditions.length === 0;
  if (!conditions.length) {
    $("#link-msg").textContent = "plan the trials first: the conditions and their blinded labels come from the plan";
  }
}

async function refreshAnswers() {
  if (participantId == null) return;
  const [responses, preferences] = await Promise.all([
    api.questionnaires.listResponses(participantId),
    api.preferences.list(participantId)]);
  state.polls += 1;
  if (responses.length === state.responses.length && preferences.length === state.preferences.length) return;
  state.responses = responses;
  state.preferences = preferences;
  $("#responses tbody").replaceChildren(...responses.map((r) => h("tr", { "data-response": r.id, "data-instrument": r.instrument_key },
    h("td", {}, `${r.instrument_key.toUpperCase()} ${r.instrument_version}`), h("td", {}, r.condition_label ?? "–"),
    h("td", {}, controllerLabel(r.controller) ?? "–"),
    h("td", { class: "score" }, h("strong", {}, Number(r.score).toFixed(1))), h("td", {}, fmtDate(r.submitted_at)))));
  const last = preferences.at(-1);
  $("#preference-out").textContent = last
    ? `Preferred: ${last.choice === "none" ? "no preference" : `${last.choice} (${controllerLabel(last.controller)})`}`
    : "";
}

async function load() {
  const session = await api.sessions.get(sessionId);
  if (session.kind !== "evaluation") return;
  participantId = session.participant_id;
  [instruments, conditions] = await Promise.all([
    api.questionnaires.listParticipantInstruments(participantId),
    api.participants.listConditions(participantId)]);
  // The newest version of each instrument the study may use; the link names it.
  const newest = new Map();
  for (const i of instruments) newest.set(i.key, i);
  instruments = [...newest.values()];
  renderChoices();
  await refreshAnswers();
  setInterval(() => {
    if (document.visibilityState === "visible") refreshAnswers().catch(() => {});
  }, POLL_MS);
}

// A plan made on this page adds the conditions: pick them up.
document.addEventListener("exostudy:planned", async () => {
  if (participantId == null) return;
  conditions = await api.participants.listConditions(participantId);
  $("#link-msg").textContent = "";
  renderChoices();
});

$("#link-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#link-create"), $("#link-msg"), async () => {
    const forms = [...ev.target.querySelectorAll("input[name=form]:checked")].map((x) => {
      const [key, version, label] = x.value.split("|");
      return { instrument_key: key, instrument_version: version, condition_label: label };
    });
    const link = await api.questionnaires.createLink(participantId,
      { forms, preference: $("#link-preference").checked });
    $("#link-url").href = link.url;
    $("#link-url").textContent = link.url;
    $("#link-out").hidden = false;
    return `link for ${forms.length} form${forms.length === 1 ? "" : "s"}${link.preference_due ? " and the preference" : ""}; it works once`;
  });
});

load().catch((err) => { $("#link-msg").textContent = `questionnaires: ${err.message}`; });

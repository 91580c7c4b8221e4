// A study: its participants (create, edit, consent date) and their sessions.
import * as api from "/static/api_client.js";
import { $, act, fmtDate, formData, h, showFatal } from "/static/dom.js";
import { createLabelEditor } from "/static/markers.js";
import { controllerLabel } from "/static/names.js";

const studyId = Number(location.pathname.split("/").pop());
let participants = [];
let selected = null;

const KIND = { data_collection: "data collection", evaluation: "evaluation", long_use: "long use" };

async function loadStudy() {
  const s = await api.studies.get(studyId);
  document.title = `ExoStudy · ${s.name}`;
  $("#study-title").textContent = s.name;
  $("#study-description").textContent = s.description;
  $("#export").href = api.trials.exportStudy.url(studyId);
  $("#export-bids").href = api.lab.exportBids.url(studyId);
  $("#results-link").href = `/console/studies/${studyId}/results`;
  $("#model-sets-link").href = `/console/studies/${studyId}/model-sets`;
}

async function loadParticipants() {
  participants = await api.participants.list(studyId);
  $("#participants tbody").replaceChildren(...participants.map((p) => h("tr",
    { "data-participant": p.code, class: selected && selected.id === p.id ? "selected" : null },
    h("td", {}, h("strong", {}, p.code)), h("td", {}, p.age ?? "–"), h("td", {}, p.sex ?? "–"),
    h("td", {}, p.height_m != null ? `${p.height_m} m` : "–"),
    h("td", {}, p.mass_kg != null ? `${p.mass_kg} kg` : "–"),
    h("td", { class: "consent" }, p.consent_date ?? h("span", { class: "warn-text" }, "missing")),
    h("td", {}, h("button", { type: "button", class: "open", onclick: () => select(p.id) }, "Open")))));
  $("#participants-empty").hidden = participants.length > 0;
}

async function select(id) {
  selected = participants.find((p) => p.id === id);
  $("#participant-panel").hidden = false;
  $("#panel-code").textContent = selected.code;
  $("#progress-link").href = `/console/participants/${selected.id}/progress`;
  const form = $("#edit-form");
  for (const k of ["code", "age", "sex", "height_m", "mass_kg", "consent_date"]) {
    form.elements[k].value = selected[k] ?? "";
  }
  await loadParticipants();
  await Promise.all([loadSessions(), loadAnswers()]);
  $("#participant-panel").scrollIntoView({ behavior: "smooth", block: "start" });
}

async function loadSessions() {
  const sessions = await api.sessions.list(selected.id);
  $("#sessions tbody").replaceChildren(...sessions.map((s) => h("tr", { "data-session": s.id },
    h("td", {}, KIND[s.kind] ?? s.kind), h("td", {}, `${s.precompression_pct} %`),
    h("td", {}, fmtDate(s.started_at)),
    h("td", {}, h("a", { href: s.kind === "long_use"
      ? `/console/participants/${selected.id}/progress?session=${s.id}`
      : `/console/sessions/${s.id}`, class: "session-link" }, "Open session ›")))));
}

// The participant's scored questionnaires and stated preference, unblinded.
async function loadAnswers() {
  const [responses, preferences] = await Promise.all([
    api.questionnaires.listResponses(selected.id),
    api.preferences.list(selected.id)]);
  $("#participant-responses tbody").replaceChildren(...responses.map((r) => h("tr",
    { "data-response": r.id, "data-instrument": r.instrument_key },
    h("td", {}, `${r.instrument_key.toUpperCase()} ${r.instrument_version}`),
    h("td", {}, r.condition_label ?? "–"),
    h("td", {}, controllerLabel(r.controller) ?? "–"),
    h("td", { class: "score" }, h("strong", {}, Number(r.score).toFixed(1))),
    h("td", {}, fmtDate(r.submitted_at)))));
  $("#participant-responses-empty").hidden = responses.length > 0;
  const last = preferences.at(-1);
  $("#participant-preference").textContent = !last ? ""
    : `Preferred: ${last.choice === "none" ? "no preference"
      : `${last.choice} (${controllerLabel(last.controller)})`}`;
}

$("#participant-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#participant-create"), $("#participant-msg"), async () => {
    const p = await api.participants.create(studyId, formData(ev.target));
    ev.target.reset();
    await loadParticipants();
    await select(p.id);
    return `added ${p.code}`;
  });
});

$("#edit-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#edit-save"), $("#edit-msg"), async () => {
    const body = formData(ev.target);
    // An emptied field clears it (null), rather than being left as it was.
    for (const k of ["age", "sex", "height_m", "mass_kg", "consent_date"]) {
      if (!(k in body)) body[k] = null;
    }
    const p = await api.participants.update(selected.id, body);
    await loadParticipants();
    selected = p;
    $("#panel-code").textContent = p.code;
    return `saved ${p.code}`;
  });
});

$("#session-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#session-create"), $("#session-msg"), async () => {
    const s = await api.sessions.create(selected.id, formData(ev.target));
    await loadSessions();
    return `created ${KIND[s.kind]} session`;
  });
});

Promise.all([loadStudy(), loadParticipants(),
  createLabelEditor($("#marker-labels"), studyId)]).catch(showFatal);

// A study's model sets (population and personal, with a personal set's provenance) and
// its participants' prior sets (values the controller uses beside the learned estimate).
import * as api from "/static/api_client.js";
import { $, fmtDate, h, showFatal } from "/static/dom.js";

const studyId = Number(location.pathname.split("/").slice(-2)[0]);

const fmt = (xs) => (xs || []).map((x) => Number(x).toFixed(3)).join(", ");

function demonstrations(m) {
  const counts = m.params?.counts;
  if (!counts) return "–";
  return Object.entries(counts).map(([k, v]) => `${k} ${v}`).join(", ");
}

async function load() {
  const [study, participants, population, personal, priors] = await Promise.all([
    api.studies.get(studyId), api.participants.list(studyId), api.models.listModelSets(studyId),
    api.personalisation.listStudyPersonalModelSets(studyId),
    api.personalisation.listStudyPriorSets(studyId)]);
  document.title = `ExoStudy · ${study.name} · model sets`;
  $("#crumb-study").textContent = study.name;
  $("#crumb-study").href = `/console/studies/${studyId}`;
  const code = Object.fromEntries(participants.map((p) => [p.id, p.code]));
  const byId = new Map([...population, ...personal].map((m) => [m.id, m]));
  const rows = [...byId.values()].sort((a, b) => a.id - b.id);
  $("#model-sets tbody").replaceChildren(...rows.map((m) => h("tr",
    { "data-model-set": m.id, "data-kind": m.kind },
    h("td", {}, String(m.id)), h("td", {}, m.name), h("td", {}, m.kind), h("td", {}, m.method),
    h("td", {}, m.participant_id ? code[m.participant_id] ?? String(m.participant_id) : "–"),
    h("td", {}, m.base_model_set_id ? `#${m.base_model_set_id} ${byId.get(m.base_model_set_id)?.name ?? ""}` : "–"),
    h("td", { class: "small" }, demonstrations(m)),
    h("td", {}, m.status + (m.error ? ` (${m.error})` : "")), h("td", {}, fmtDate(m.created_at)))));
  $("#model-sets-empty").hidden = rows.length > 0;
  $("#prior-sets tbody").replaceChildren(...priors.map((p) => h("tr", { "data-prior-set": p.id },
    h("td", {}, String(p.id)), h("td", {}, code[p.participant_id] ?? String(p.participant_id)),
    h("td", {}, String(p.version)), h("td", {}, p.name), h("td", {}, p.method),
    h("td", { class: "values" }, fmt(p.document?.values)), h("td", {}, fmt(p.document?.estimate)),
    h("td", {}, String((p.document?.sources || []).length)),
    h("td", {}, p.utility_set_id ? `#${p.utility_set_id}` : "–"), h("td", {}, fmtDate(p.created_at)))));
  $("#prior-sets-empty").hidden = priors.length > 0;
}

load().catch(showFatal);

// The plan form's personalisation part: which conditions every controller with motion
// models runs in (population or personal models, equal or learned priors), the
// participant's personal model set and prior set for them, and a demonstration block
// first in the plan. `personalPlanFields()` gives what session.js adds to the plan body;
// the server refuses (422, shown under the form) a condition it cannot run.
import * as api from "/static/api_client.js";
import { $, h } from "/static/dom.js";

const sessionId = Number(location.pathname.split("/").pop());

export function personalPlanFields() {
  const conditions = [...document.querySelectorAll("input[name=plan-condition]:checked")]
    .map((x) => x.value);
  const body = { conditions: conditions.length ? conditions : ["population"] };
  if ($("#plan-personal-set").value) body.personal_model_set_id = Number($("#plan-personal-set").value);
  if ($("#plan-prior-set").value) body.prior_set_id = Number($("#plan-prior-set").value);
  if ($("#plan-demos").checked) {
    const n = (id) => Number($(id).value);
    body.demonstrations = { squat: n("#demo-squat"), stoop_left: n("#demo-stoop-left"),
                            stoop_right: n("#demo-stoop-right") };
  }
  return body;
}

// What a trial's condition adds to its controller's name ("" for the population models
// with equal priors): " · personal models", " · learned priors", " · demonstrations".
export function conditionNote(t) {
  if (t.demonstrations) return " · demonstration block";
  const parts = [];
  if (t.models === "personal") parts.push("personal models");
  if (t.prior_set_id) parts.push("learned priors");
  return parts.length ? ` · ${parts.join(", ")}` : "";
}

async function fill() {
  if (!$("#plan-personal-set")) return;
  const session = await api.sessions.get(sessionId);
  const pid = session.participant_id;
  const [personal, priors] = await Promise.all([
    api.personalisation.listPersonalModelSets(pid), api.personalisation.listPriorSets(pid)]);
  $("#plan-personal-set").replaceChildren(
    h("option", { value: "" }, "newest when the trial starts"),
    ...personal.filter((m) => m.status === "ready").map((m) => h("option", { value: String(m.id) },
      `#${m.id} ${m.name} (${m.method})`)));
  $("#plan-prior-set").replaceChildren(
    h("option", { value: "" }, "none"),
    ...priors.filter((p) => p.status === "ready").map((p) => h("option", { value: String(p.id) },
      `v${p.version} ${p.name}: ${(p.document?.values || []).map((x) => x.toFixed(2)).join("/")}`)));
}

fill().catch(() => { /* the plan form works without them; the server names what is missing */ });

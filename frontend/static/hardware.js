// Hardware bring-up: the steps in order, each run through its api.hardware operation, its
// verdict shown in its row; the profile they build, stored with api.hardware.finish.
import * as api from "/static/api_client.js";
import { $, act, fmtDate, h, showFatal } from "/static/dom.js";

// Each step: its stored name, what it asks of the experimenter, its request.
const STEPS = [
  { name: "zero", label: "a. Encoder zero", ask: "stand still, upright",
    op: api.hardware.zero, body: () => ({ seconds: 2 }) },
  { name: "direction_left", label: "b. Direction, left", ask: "flex the left hip during the capture",
    op: api.hardware.direction, body: () => ({ side: "left", seconds: 4 }) },
  { name: "direction_right", label: "b. Direction, right", ask: "flex the right hip during the capture",
    op: api.hardware.direction, body: () => ({ side: "right", seconds: 4 }) },
  { name: "offset", label: "c. Cam-to-output offset", ask: "both sides unlocked",
    op: api.hardware.offset, body: () => ({ seconds: 2 }) },
  { name: "pulse_left", label: "d. Solenoid pulse, left", ask: "nobody wearing it", wearing: true,
    op: api.hardware.pulse, body: () => ({ side: "left", duration_ms: 300, nobody_wearing: nobody() }) },
  { name: "pulse_right", label: "d. Solenoid pulse, right", ask: "nobody wearing it", wearing: true,
    op: api.hardware.pulse, body: () => ({ side: "right", duration_ms: 300, nobody_wearing: nobody() }) },
  { name: "watchdog", label: "e. Watchdog test", ask: "nobody wearing it", wearing: true,
    op: api.hardware.watchdog, body: () => ({ side: "left", nobody_wearing: nobody() }) },
  { name: "hardware_release", label: "f. Hardware release (heartbeat)", ask: "nobody wearing it", wearing: true,
    op: api.hardware.hardwareRelease, body: () => ({ side: "left", nobody_wearing: nobody() }) },
  { name: "link", label: "g. Link statistics", ask: "", op: api.hardware.link, body: () => undefined },
];

const nobody = () => $("#nobody-wearing").checked;

function values(v) {
  return Object.entries(v || {}).map(([k, x]) =>
    `${k}: ${typeof x === "object" && x !== null ? JSON.stringify(x) : x}`).join("; ");
}

function showResult(name, result) {
  const row = document.querySelector(`#step-table tr[data-step="${name}"]`);
  const cell = row.querySelector(".result");
  if (!result) {
    cell.replaceChildren(h("span", { class: "muted" }, "not run"));
    row.querySelector(".values").textContent = "";
    delete row.dataset.passed;
    return;
  }
  row.dataset.passed = String(result.passed);
  cell.replaceChildren(h("span", { class: "badge", "data-status": result.passed ? "done" : "failed" },
    result.passed ? "passed" : "failed"), " ", result.message);
  row.querySelector(".values").textContent = values(result.values);
}

function profileRow(p) {
  return h("tr", { "data-profile": p.id }, h("td", {}, p.id),
    h("td", {}, h("span", { class: "badge", "data-status": p.status === "complete" ? "done" : p.status }, p.status)),
    h("td", {}, p.device), h("td", {}, p.unique_id || "–"), h("td", {}, p.firmware_version),
    h("td", {}, p.key_id || "–"),
    h("td", {}, p.encoder_offsets.join(", ")), h("td", {}, p.encoder_directions.join(", ")),
    h("td", {}, fmtDate(p.completed_at)));
}

async function refresh() {
  const [state, profiles] = await Promise.all([api.hardware.hardwareState(), api.hardware.profiles()]);
  $("#device").textContent = `device: ${state.device}` + (state.simulated ? " (simulated)" : "") +
    (state.active ? ` · profile in effect: ${state.active.id}` : " · no profile in effect");
  $("#identity").textContent = state.identity
    ? `on the link: ${state.identity}` : "the device has not proved its identity on the link yet";
  $("#applied").textContent = `applied encoder offsets ${state.applied_offsets.join(", ")}, ` +
    `directions ${state.applied_directions.join(", ")}` +
    (state.applied_note ? ` — ${state.applied_note}` : "");
  $("#firmware-notice").textContent = state.firmware_notice || "";
  const cooling = Object.entries(state.cooldown_s || {}).filter(([, s]) => s > 0);
  $("#cooldown").textContent = cooling.length
    ? "cooling down: " + cooling.map(([side, s]) => `${side} ${s} s`).join(", ") : "";
  for (const s of STEPS) showResult(s.name, state.draft ? state.draft.steps[s.name] : null);
  $("#profiles tbody").replaceChildren(...profiles.map(profileRow));
}

$("#step-table tbody").replaceChildren(...STEPS.map((s) => {
  const button = h("button", { type: "button", id: `run-${s.name}` }, "Run");
  button.addEventListener("click", () => act(button, $("#step-msg"), async () => {
    if (s.wearing && !nobody()) {
      throw new Error("tick “nobody wears the exoskeleton” first: a solenoid is energised");
    }
    const out = await s.op(s.body());
    showResult(s.name, out.result);
    await refresh();
    return `${s.label}: ${out.result.passed ? "passed" : "failed"}`;
  }));
  return h("tr", { "data-step": s.name },
    h("td", {}, s.label, s.ask ? h("div", { class: "muted small" }, s.ask) : null),
    h("td", {}, button), h("td", { class: "result" }), h("td", { class: "values small" }));
}));

$("#finish-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#finish"), $("#finish-msg"), async () => {
    const version = $("#firmware-version").value.trim();
    const p = await api.hardware.finish({ firmware_version: version || null });
    await refresh();
    return `profile ${p.id}: ${p.status}`;
  });
});

refresh().then(() => { document.body.dataset.ready = "true"; }).catch(showFatal);

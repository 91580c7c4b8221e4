// The state strip: which lock each side holds, whether the mechanism engaged, and the
// controller's action, large enough to read from across the lab.
import { actionLabel, plausibilityReasons } from "/static/names.js";

export function createStateStrip(root) {
  root.classList.add("strip");
  root.innerHTML = `
    <div class="strip-cell" id="strip-left" data-lock="off"><span class="strip-side">LEFT</span>
      <span class="strip-value">free</span><span class="strip-sub">mechanism –</span></div>
    <div class="strip-cell strip-action" id="strip-action" data-action="1"><span class="strip-side">ACTION</span>
      <span class="strip-value">${actionLabel(1)}</span><span class="strip-sub">trigger –</span>
      <span class="strip-sub strip-implausible" id="strip-implausible" hidden>implausible sample</span></div>
    <div class="strip-cell" id="strip-right" data-lock="off"><span class="strip-side">RIGHT</span>
      <span class="strip-value">free</span><span class="strip-sub">mechanism –</span></div>`;
  const left = root.querySelector("#strip-left");
  const right = root.querySelector("#strip-right");
  const action = root.querySelector("#strip-action");
  const implausible = root.querySelector("#strip-implausible");
  // Ticks whose sample failed a plausibility check (controller/tick_record.py Plausibility):
  // no lock is taken on them, and the strip says so while they last.
  const counts = { lockChanges: 0, lockOnSeen: 0, implausible: 0 };
  let last = null;

  const leftParts = [left.querySelector(".strip-value"), left.querySelector(".strip-sub")];
  const rightParts = [right.querySelector(".strip-value"), right.querySelector(".strip-sub")];
  const actionParts = [action.querySelector(".strip-value"), action.querySelector(".strip-sub")];
  // What is on screen, so that an unchanged tick touches no DOM (no style or layout work).
  const shown = { left: "", right: "", action: "", plausibility: 0 };

  function side(key, cell, parts, held, engaged) {
    const now = `${held ? 1 : 0}${engaged ? 1 : 0}`;
    if (shown[key] === now) return;
    shown[key] = now;
    cell.dataset.lock = held ? "on" : "off";
    cell.dataset.engaged = engaged ? "true" : "false";
    parts[0].textContent = held ? "LOCK" : "free";
    parts[1].textContent = `mechanism ${engaged ? "engaged" : "open"}`;
  }

  return {
    counts,
    // Count lock changes over every tick of a message (a short lock between two
    // redraws still counts).
    observe(columns) {
      const l = columns.lock_left || [];
      const r = columns.lock_right || [];
      for (const p of columns.plausibility || []) if (p) counts.implausible += 1;
      for (let i = 0; i < l.length; i++) {
        const key = `${l[i] ? 1 : 0}${r[i] ? 1 : 0}`;
        if (last !== null && key !== last) counts.lockChanges += 1;
        if (key !== "00") counts.lockOnSeen += 1;
        last = key;
      }
    },
    // `tick`: one tick's raw values (lock_left, lock_right, locked_*, action, trigger).
    update(tick) {
      if (!tick) return;
      side("left", left, leftParts, tick.lock_left, tick.locked_left);
      side("right", right, rightParts, tick.lock_right, tick.locked_right);
      const p = tick.plausibility || 0;
      if (shown.plausibility !== p) {
        shown.plausibility = p;
        implausible.hidden = !p;
        implausible.textContent = p ? `implausible sample: ${plausibilityReasons(p).join(", ")}` : "";
      }
      const a = tick.action ?? 1;
      const now = `${a}/${tick.trigger ? 1 : 0}`;
      if (shown.action === now) return;
      shown.action = now;
      action.dataset.action = String(a);
      actionParts[0].textContent = actionLabel(a);
      actionParts[1].textContent = `trigger ${tick.trigger ? "ON" : "off"}`;
    },
  };
}


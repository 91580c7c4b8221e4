// Event markers from the console: one button per label of the study (hotkeys 1-9), a
// free note, and the marker list of the session. The server stamps a marker with the
// newest tick, stores it with the running trial, sends it on the LSL marker stream and
// to every console (live WebSocket message "marker", backend/schemas/lab.py LiveMarker);
// the plots draw markers at their tick time.
import * as api from "/static/api_client.js";
import { act, h } from "/static/dom.js";

// What the browser tests read: markers stored from this page and seen on the stream.
const state = (window.exostudyMarkers = { labels: [], stored: [], seen: [], drawn: [] });

function typing(ev) {
  const el = ev.target;
  return el && (el.tagName === "INPUT" || el.tagName === "TEXTAREA" || el.tagName === "SELECT" ||
    el.isContentEditable);
}

// Builds the bar in `container` for session `sessionId`.
export async function createMarkerBar(container, sessionId) {
  const labels = (await api.lab.sessionMarkerLabels(sessionId)).labels;
  state.labels = labels;
  const msg = h("span", { class: "msg", id: "marker-msg" });
  const note = h("input", { id: "marker-note", size: 28, placeholder: "note (optional)",
    maxlength: 2000 });
  async function mark(label) {
    msg.className = "msg";
    msg.textContent = "…";
    try {
      const m = await api.lab.addMarker(sessionId, { label, note: note.value });
      state.stored.push(m);
      note.value = "";
      msg.textContent = `marked "${m.label}" at ${m.t == null ? "–" : m.t.toFixed(2) + " s"}` +
        (m.trial_id ? ` in trial ${m.trial_id}` : "");
      msg.classList.add("msg-ok");
    } catch (err) {
      msg.textContent = `marker not stored: ${err.message}`;
      msg.classList.add("msg-bad");
    }
  }
  const buttons = labels.map((label, i) => h("button", {
    type: "button", class: "marker-button", dataset: { hotkey: String(i + 1) },
    title: `hotkey ${i + 1}`, onclick: () => mark(label),
  }, h("kbd", {}, String(i + 1)), " ", label));
  container.replaceChildren(
    h("h2", {}, "Event markers ", h("span", { class: "muted small" },
      "(keys 1-9; stored with the running trial, sent on LSL)")),
    h("div", { class: "form-row" }, ...buttons, note,
      h("button", { type: "button", id: "marker-free", onclick: () => {
        if (note.value.trim()) mark("note");
      } }, "Mark note")),
    msg);
  container.hidden = false;
  document.addEventListener("keydown", (ev) => {
    if (ev.ctrlKey || ev.metaKey || ev.altKey || typing(ev)) return;
    const k = Number(ev.key);
    if (Number.isInteger(k) && k >= 1 && k <= labels.length) {
      ev.preventDefault();
      mark(labels[k - 1]);
    }
  });
  return { mark };
}

// Remembers markers seen on the stream (or loaded) for the plots' draw hook.
export function noteMarker(marker) {
  state.seen.push(marker);
}

// Which markers a plot drew last (labels), for the tests.
export function markDrawn(labels) {
  state.drawn = labels;
}

// The marker streams of other software (LSL): find those visible on the network, listen
// to one (its markers are stored with the running trial), stop listening.
export function createStreamPicker(container, sessionId) {
  const msg = h("span", { class: "msg", id: "lsl-msg" });
  const found = h("ul", { id: "lsl-found", class: "plain-list" });
  const subs = h("ul", { id: "lsl-subs", class: "plain-list" });
  async function showSubs() {
    const list = await api.lab.listMarkerStreams(sessionId);
    subs.replaceChildren(...list.filter((s) => s.active).map((s) => h("li", {},
      `${s.name} ${s.source_id ? `(${s.source_id})` : ""} · ${s.connected ? "connected" : "waiting"} `,
      h("button", { type: "button", onclick: async () => {
        await api.lab.unsubscribe(sessionId, s.id);
        await showSubs();
      } }, "Stop"))));
  }
  async function find() {
    msg.className = "msg";
    msg.textContent = "looking for LSL streams (1 s)…";
    try {
      const list = await api.lab.visibleStreams(sessionId);
      const others = list.filter((s) => !s.own);
      found.replaceChildren(...others.map((s) => h("li", {},
        `${s.name} · ${s.type} · ${s.hostname} `,
        s.type === "Markers" ? h("button", { type: "button", onclick: async () => {
          try {
            await api.lab.subscribe(sessionId, { name: s.name, source_id: s.source_id });
            await showSubs();
          } catch (err) { msg.textContent = err.message; msg.classList.add("msg-bad"); }
        } }, "Listen") : null)));
      msg.textContent = `${others.length} stream${others.length === 1 ? "" : "s"} of other software`;
    } catch (err) {
      msg.textContent = err.message;
      msg.classList.add("msg-bad");
    }
  }
  container.replaceChildren(
    h("h2", {}, "LSL marker streams ", h("span", { class: "muted small" },
      "(other software's markers, stored with the running trial)")),
    h("div", { class: "form-row" }, h("button", { type: "button", id: "lsl-find", onclick: find },
      "Find streams"), msg),
    found, h("h3", { class: "small" }, "listening to"), subs);
  container.hidden = false;
  showSubs().catch(() => {});
}

// The study's marker labels (hotkeys 1-9 in this order), edited as one line.
export async function createLabelEditor(container, studyId) {
  const input = h("input", { id: "marker-labels-input", size: 60 });
  const msg = h("span", { class: "msg", id: "marker-labels-msg" });
  input.value = (await api.lab.getMarkerLabels(studyId)).labels.join(", ");
  const save = h("button", { type: "button", id: "marker-labels-save", onclick: () =>
    act(save, msg, async () => {
      const labels = input.value.split(",").map((s) => s.trim()).filter(Boolean);
      const out = await api.lab.putMarkerLabels(studyId, { labels });
      input.value = out.labels.join(", ");
      return `saved ${out.labels.length} labels`;
    }) }, "Save labels");
  container.replaceChildren(
    h("h2", {}, "Event marker labels ", h("span", { class: "muted small" },
      "(comma-separated; keys 1-9 on the live and session pages, in this order)")),
    h("div", { class: "form-row" }, input, save), msg);
  container.hidden = false;
}

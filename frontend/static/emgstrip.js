// The live page's EMG strip: each subscribed channel's envelope (the server's causal
// envelope, decimated to 50 Hz: backend/emg/live_envelope.py) over the last seconds,
// its newest value in microvolts and its flags (clipping, flat, NaN counted), one row
// per channel, beside the lock states. Drawn on one small canvas per channel, at most
// once per animation frame.
import { NEUTRAL } from "/static/palette.js";

const ROW_HEIGHT = 34;
const UV = 1e6;

function fmtUv(v) {
  if (v == null) return "–";
  const uv = v * UV;
  return `${uv >= 100 ? uv.toFixed(0) : uv.toFixed(1)} µV`;
}

export function createEmgStrip(root, { windowS = 10 } = {}) {
  root.classList.add("emg-strip");
  // What the browser tests read: per label, the newest value (V) and flags.
  const counts = { messages: 0, values: 0, latest: {}, flags: {}, streams: 0 };
  const streams = new Map();  // subscription id -> { labels, t: [], v: [[]...], rows }
  let window_ = windowS;
  let frame = false;

  function makeStream(msg) {
    const box = document.createElement("div");
    box.className = "emg-stream";
    box.dataset.subscription = String(msg.subscription_id);
    const head = document.createElement("div");
    head.className = "small muted emg-head";
    head.textContent = `EMG stream ${msg.subscription_id} · session ${msg.session_id} · ` +
      `envelope at ${msg.fs.toFixed(0)} Hz (causal, for display)`;
    box.append(head);
    const rows = msg.labels.map((label) => {
      const row = document.createElement("div");
      row.className = "emg-row";
      row.dataset.channel = label;
      const name = document.createElement("span");
      name.className = "emg-label";
      name.textContent = label;
      const canvas = document.createElement("canvas");
      canvas.className = "emg-canvas";
      canvas.height = ROW_HEIGHT;
      const value = document.createElement("span");
      value.className = "emg-value mono";
      value.textContent = "–";
      const flags = document.createElement("span");
      flags.className = "emg-flags small";
      row.append(name, canvas, value, flags);
      box.append(row);
      return { row, canvas, value, flags, shownFlags: "" };
    });
    root.append(box);
    root.hidden = false;
    counts.streams += 1;
    return { labels: msg.labels, t: [], v: msg.labels.map(() => []), rows };
  }

  function draw() {
    frame = false;
    for (const s of streams.values()) {
      const tEnd = s.t.length ? s.t[s.t.length - 1] : 0;
      const t0 = tEnd - window_;
      let first = 0;
      while (first < s.t.length && s.t[first] < t0) first++;
      s.rows.forEach((r, c) => {
        const { canvas } = r;
        const width = Math.max(100, canvas.clientWidth);
        if (canvas.width !== width) canvas.width = width;
        const ctx = canvas.getContext("2d");
        ctx.clearRect(0, 0, canvas.width, canvas.height);
        const vals = s.v[c];
        let max = 0;
        for (let i = first; i < vals.length; i++) if (vals[i] > max) max = vals[i];
        if (!max) return;
        ctx.strokeStyle = r.row.dataset.flat === "true" ? "#b45309" : NEUTRAL;
        ctx.lineWidth = 1.5;
        ctx.beginPath();
        for (let i = first; i < vals.length; i++) {
          const x = ((s.t[i] - t0) / window_) * canvas.width;
          const y = canvas.height - 2 - (vals[i] / max) * (canvas.height - 4);
          if (i === first) ctx.moveTo(x, y); else ctx.lineTo(x, y);
        }
        ctx.stroke();
      });
    }
  }

  return {
    counts,
    setWindow(seconds) { window_ = seconds; },
    // One LiveEmg message (backend/schemas/live.py).
    push(msg) {
      counts.messages += 1;
      let s = streams.get(msg.subscription_id);
      if (!s || s.labels.join("\n") !== msg.labels.join("\n")) {
        if (s) s.rows[0].row.parentElement.remove();
        s = makeStream(msg);
        streams.set(msg.subscription_id, s);
      }
      s.t.push(...msg.t);
      msg.values.forEach((vals, c) => s.v[c].push(...vals));
      counts.values += msg.t.length;
      // Keep twice the longest window the page offers (60 s) at most.
      const keep = Math.ceil(msg.fs * 120);
      if (s.t.length > keep) {
        const cut = s.t.length - keep;
        s.t.splice(0, cut);
        for (const v of s.v) v.splice(0, cut);
      }
      msg.labels.forEach((label, c) => {
        const r = s.rows[c];
        const vals = msg.values[c];
        const latest = vals.length ? vals[vals.length - 1] : counts.latest[label] ?? null;
        counts.latest[label] = latest;
        if (latest != null) {
          r.value.textContent = fmtUv(latest);
          r.value.dataset.value = String(latest * UV);
        }
        const f = msg.flags[c];
        counts.flags[label] = f;
        const key = `${f.clipping}/${f.flat}/${f.non_finite}`;
        if (key === r.shownFlags) return;
        r.shownFlags = key;
        r.row.dataset.clipping = String(f.clipping);
        r.row.dataset.flat = String(f.flat);
        r.row.dataset.nonFinite = String(f.non_finite);
        const parts = [];
        if (f.clipping) parts.push("CLIPPING");
        if (f.flat) parts.push("FLAT");
        if (f.non_finite) parts.push(`NaN ${f.non_finite}`);
        r.flags.textContent = parts.join(" · ");
        r.row.classList.toggle("emg-flagged", parts.length > 0);
      });
      if (!frame) { frame = true; requestAnimationFrame(draw); }
    },
  };
}

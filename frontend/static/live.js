// Live console: one WebSocket, ring buffers, uPlot redrawn once per animation frame.
// Message formats are defined in backend/schemas/live.py (LiveTicks, LiveStatus).
import uPlot from "/vendor/uplot/uPlot.esm.js";

const WINDOW_S = 10;
const CAPACITY = WINDOW_S * 100;
const DEG = 180 / Math.PI;

// What the browser tests read: counts, not pixels.
const stats = (window.exostudyLive = {
  samples: 0, messages: 0, draws: 0, dropped: 0, gaps: 0, latencyMs: null, lastStatus: null,
  // Latency of each sample (worker read time to arrival here), last 3000, for benchmarks.
  latencies: [],
});

const cols = ["t", "q_left", "q_right", "post_squat", "post_stoop_left", "post_stoop_right",
  "post_other", "lock_left", "lock_right"];
const buf = Object.fromEntries(cols.map((c) => [c, []]));
let dirty = false;

function sizeOf(el) {
  return { width: Math.max(300, el.clientWidth - 4), height: 240 };
}

const anglesEl = document.getElementById("plot-angles");
const postEl = document.getElementById("plot-posteriors");
const drawHook = { draw: [() => { stats.draws += 1; }] };

const anglesPlot = new uPlot({
  ...sizeOf(anglesEl),
  scales: { x: { time: false } },
  axes: [{ label: "device time (s)" }, { label: "deg" }],
  series: [
    {},
    { label: "left hip", stroke: "#1f6feb", width: 2 },
    { label: "right hip", stroke: "#d9480f", width: 2 },
  ],
  hooks: drawHook,
}, [[], [], []], anglesEl);

const postPlot = new uPlot({
  ...sizeOf(postEl),
  scales: { x: { time: false }, p: { range: [0, 1.05] }, lock: { range: [-0.2, 6] } },
  axes: [{ label: "device time (s)" }, { scale: "p", label: "P(model | obs)" }],
  series: [
    {},
    { label: "squat", stroke: "#2b8a3e", scale: "p", width: 2, spanGaps: true },
    { label: "stoop left", stroke: "#1f6feb", scale: "p", width: 2, spanGaps: true },
    { label: "stoop right", stroke: "#d9480f", scale: "p", width: 2, spanGaps: true },
    { label: "other", stroke: "#868e96", scale: "p", width: 2, spanGaps: true },
    { label: "lock left", stroke: "#1f6feb", scale: "lock", width: 3, paths: uPlot.paths.stepped({ align: 1 }) },
    { label: "lock right", stroke: "#d9480f", scale: "lock", width: 3, paths: uPlot.paths.stepped({ align: 1 }) },
  ],
  hooks: drawHook,
}, [[], [], [], [], [], [], []], postEl);

window.addEventListener("resize", () => {
  anglesPlot.setSize(sizeOf(anglesEl));
  postPlot.setSize(sizeOf(postEl));
});

function append(columns) {
  const n = columns.t.length;
  for (const c of cols) {
    const src = columns[c];
    const dst = buf[c];
    for (let i = 0; i < n; i++) {
      let v = src[i];
      if (c === "q_left" || c === "q_right") v = v == null ? null : v * DEG;
      else if (c === "lock_left") v = v ? 1 : 0;
      else if (c === "lock_right") v = v ? 1.2 : 0.2;
      dst.push(v);
    }
    if (dst.length > CAPACITY) dst.splice(0, dst.length - CAPACITY);
  }
  stats.samples += n;
  const now = Date.now();
  for (let i = 0; i < n; i++) {
    const th = columns.t_host[i];
    if (th != null) stats.latencies.push(now - th * 1000);
  }
  if (stats.latencies.length > 3000) stats.latencies.splice(0, stats.latencies.length - 3000);
  const tHost = columns.t_host[n - 1];
  if (tHost != null) stats.latencyMs = now - tHost * 1000;
  dirty = true;
}

// At most ~30 redraws a second: smooth to the eye, and four consoles on a laptop leave
// the CPU to the control loop.
let lastDraw = 0;
function frame(ts) {
  if (dirty && ts - lastDraw >= 32) {
    lastDraw = ts;
    dirty = false;
    anglesPlot.setData([buf.t, buf.q_left, buf.q_right]);
    postPlot.setData([buf.t, buf.post_squat, buf.post_stoop_left, buf.post_stoop_right,
      buf.post_other, buf.lock_left, buf.lock_right]);
  }
  requestAnimationFrame(frame);
}
requestAnimationFrame(frame);

// Connection indicator: message and sample rates over the last second.
const conn = document.getElementById("conn");
const connText = document.getElementById("conn-text");
let lastMsgSeq = 0;
let windowStart = performance.now();
let windowMsgs = 0;
let windowSamples = 0;

function setConn(state, text) {
  conn.dataset.state = state;
  conn.className = "pill " + (state === "live" ? "pill-ok" : state === "stale" ? "pill-warn" : "pill-bad");
  connText.textContent = text;
}

setInterval(() => {
  const now = performance.now();
  const dt = (now - windowStart) / 1000;
  const mps = windowMsgs / dt;
  const sps = windowSamples / dt;
  stats.msgRate = mps;
  stats.sampleRate = sps;
  windowStart = now; windowMsgs = 0; windowSamples = 0;
  if (conn.dataset.state === "live" || conn.dataset.state === "stale") {
    const stale = mps < 1;
    setConn(stale ? "stale" : "live",
      `${stale ? "no data" : "live"} · ${mps.toFixed(0)} msg/s · ${sps.toFixed(0)} samples/s · ` +
      `latency ${stats.latencyMs == null ? "–" : stats.latencyMs.toFixed(0)} ms · dropped ${stats.dropped}`);
  }
  document.getElementById("stream-rate").textContent = `${sps.toFixed(0)} samples/s`;
  document.getElementById("stream-detail").textContent =
    `${mps.toFixed(0)} messages/s, latency ${stats.latencyMs == null ? "–" : stats.latencyMs.toFixed(0)} ms, ` +
    `dropped ${stats.dropped}, gaps ${stats.gaps}`;
}, 1000);

function showHealth(h) {
  stats.lastStatus = h;
  const w = h.worker;
  const ws = document.getElementById("worker-state");
  ws.dataset.alive = String(w.alive);
  ws.textContent = w.alive
    ? `alive · pid ${w.pid} · controller ${w.controller ?? "none"}`
    : `stopped${w.exit_reason ? ": " + w.exit_reason : ""}`;
  document.getElementById("worker-timing").textContent = w.alive && w.period_mean_ms != null
    ? `period ${w.period_mean_ms.toFixed(2)} ms · jitter p99 ${w.jitter_p99_ms.toFixed(2)} ms · ` +
      `overruns ${w.overruns} · restarts ${w.restarts}`
    : `restarts ${w.restarts}`;
  if (w.controller && document.activeElement !== controllerSel) controllerSel.value = w.controller;
  const d = h.device;
  const dsEl = document.getElementById("device-state");
  dsEl.dataset.alive = String(d.alive);
  dsEl.textContent = `${d.alive ? "sending" : "silent"} · ${d.kind}`;
  document.getElementById("device-detail").textContent =
    d.faults.length ? "faults: " + d.faults.join("; ") : "no faults";
}

const controllerSel = document.getElementById("controller");
const controllerMsg = document.getElementById("controller-msg");
controllerSel.addEventListener("change", async () => {
  controllerMsg.textContent = `switching to ${controllerSel.value}…`;
  const r = await fetch("/api/worker/controller", {
    method: "POST", headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ name: controllerSel.value }),
  });
  const body = await r.json();
  controllerMsg.textContent = r.ok ? `requested ${controllerSel.value}` : `refused: ${body.detail}`;
});

document.getElementById("calibrate").addEventListener("click", async (ev) => {
  ev.target.disabled = true;
  controllerMsg.textContent = "calibrating: the wearer stands still…";
  try {
    const r = await fetch("/api/worker/calibrate", {
      method: "POST", headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ seconds: 3 }),
    });
    const body = await r.json();
    const res = r.ok ? body : body.detail;
    controllerMsg.dataset.calibrated = String(r.ok);
    controllerMsg.textContent = typeof res === "string" ? `calibration failed: ${res}`
      : r.ok ? `calibrated: offsets ${res.offset_left_deg.toFixed(1)}°, ${res.offset_right_deg.toFixed(1)}° ` +
        `(std ${res.std_left_deg.toFixed(2)}°, ${res.std_right_deg.toFixed(2)}°)`
      : `calibration failed: ${res.message}`;
  } finally {
    ev.target.disabled = false;
  }
});

document.getElementById("restart").addEventListener("click", async (ev) => {
  ev.target.disabled = true;
  try {
    const r = await fetch("/api/worker/restart", { method: "POST" });
    if (r.ok) showHealth(await r.json());
  } finally {
    ev.target.disabled = false;
  }
});

let retryMs = 500;
function connect() {
  const proto = location.protocol === "https:" ? "wss:" : "ws:";
  const ws = new WebSocket(`${proto}//${location.host}/ws/live`);
  ws.onopen = () => { retryMs = 500; setConn("live", "live"); };
  ws.onmessage = (ev) => {
    const msg = JSON.parse(ev.data);
    if (msg.type === "ticks") {
      stats.messages += 1;
      windowMsgs += 1;
      windowSamples += msg.columns.t.length;
      if (lastMsgSeq && msg.msg_seq !== lastMsgSeq + 1) stats.gaps += msg.msg_seq - lastMsgSeq - 1;
      lastMsgSeq = msg.msg_seq;
      stats.dropped = msg.dropped;
      append(msg.columns);
    } else if (msg.type === "status") {
      showHealth(msg.health);
    }
  };
  ws.onclose = () => {
    setConn("down", `disconnected, retrying in ${(retryMs / 1000).toFixed(1)} s`);
    lastMsgSeq = 0;
    setTimeout(connect, retryMs);
    retryMs = Math.min(retryMs * 2, 5000);
  };
}
connect();

// Live console: one WebSocket, ring buffers, uPlot redrawn at most ~30 times a second.
// With ?trial=ID the same plots replay a stored trial, scrubbed with a slider.
import { ApiError } from "/static/api.js";
import * as api from "/static/api_client.js";
import { connectLive, Ring } from "/static/livestream.js";
import { createTimePlots } from "/static/timeplots.js";
import { addProgress, displayValue, lastTick, PLOT_COLUMNS } from "/static/tickdata.js";
import { createStateStrip } from "/static/statestrip.js";
import { createEmgStrip } from "/static/emgstrip.js";
import { createMarkerBar, markDrawn, noteMarker } from "/static/markers.js";
import { CATEGORY_NAMES, controllerLabel, CONTROLLER_NAMES, IDLE_CONTROLLER, MODEL_NAMES, tickColumn } from "/static/names.js";

const RATE_HZ = 100;
const STRIP_COLUMNS = ["lock_left", "lock_right", "locked_left", "locked_right", "action", "trigger"]
  .map(tickColumn);
const PLOTTED = ["t", ...new Set(Object.values(PLOT_COLUMNS).flat())];

// What the browser tests read: counts, not pixels.
const stats = (window.exostudyLive = {
  samples: 0, messages: 0, draws: 0, dropped: 0, gaps: 0, latencyMs: null, lastStatus: null,
  // Latency of each sample (worker read time to arrival here), last 3000, for benchmarks.
  latencies: [],
  // Of that, per message: server queuing the message to its arrival here (last 3000);
  // and per sample: worker read time to the first frame that drew it on the plots.
  transits: [], drawLatencies: [], firstDrawMs: null,
  paused: false, windowS: 10, replay: null,
  // Per model: the highest posterior seen and the samples it led; the highest progress.
  posteriorMax: {}, leading: {}, progressMax: null, leader: null, leaderChanges: 0,
});

function observePosteriors(columns) {
  const models = CATEGORY_NAMES;
  const posts = models.map((m) => columns[`post_${m}`] || []);
  for (let i = 0; i < columns.t.length; i++) {
    // The leading model, or "none" while no estimate runs (E-UMC between triggers).
    let lead = "none";
    let best = -1;
    models.forEach((m, k) => {
      const v = posts[k][i];
      if (v == null) return;
      if (v > (stats.posteriorMax[m] ?? -1)) stats.posteriorMax[m] = v;
      if (v > best) { best = v; lead = m; }
    });
    if (lead !== stats.leader) { stats.leaderChanges += 1; stats.leader = lead; }
  }
  for (const m of MODEL_NAMES) {
    for (const v of columns[`progress_${m}`] || []) {
      if (v == null) continue;
      stats.leading[m] = (stats.leading[m] ?? 0) + 1;
      if (v > (stats.progressMax ?? -1)) stats.progressMax = v;
    }
  }
}

const $ = (id) => document.getElementById(id);
const plots = createTimePlots({
  angles: $("plot-angles"), velocities: $("plot-velocities"),
  posteriors: $("plot-posteriors"), progress: $("plot-progress"), torques: $("plot-torques"),
}, { onDraw: () => { stats.draws += 1; }, onMarkersShown: markDrawn });
const strip = createStateStrip($("strip"));
stats.strip = strip.counts;
// EMG envelopes of the subscribed amplifiers, shown once the first arrives.
const emgStrip = createEmgStrip($("emg-strip"));
stats.emg = emgStrip.counts;

const pauseBtn = $("pause");
pauseBtn.addEventListener("click", () => {
  stats.paused = !stats.paused;
  pauseBtn.dataset.paused = String(stats.paused);
  pauseBtn.setAttribute("aria-pressed", String(stats.paused));
  pauseBtn.textContent = stats.paused ? "Resume live" : "Pause";
  pauseBtn.classList.toggle("active", stats.paused);
  dirty = true;
});

const windowSel = $("window");
windowSel.addEventListener("change", () => {
  stats.windowS = Number(windowSel.value);
  $("window-s").textContent = windowSel.value;
  if (ring) ring.resize(stats.windowS * RATE_HZ);
  emgStrip.setWindow(stats.windowS);
  if (replay) showReplay();
  dirty = true;
});

const trialId = new URLSearchParams(location.search).get("trial");
// With ?session=ID the marker buttons and hotkeys of that session's study are shown.
const markerSession = new URLSearchParams(location.search).get("session");
if (markerSession && !trialId) {
  createMarkerBar($("marker-bar"), Number(markerSession)).catch((err) => {
    $("marker-bar").hidden = false;
    $("marker-bar").textContent = `markers unavailable: ${err.message || err}`;
  });
}
let ring = null;
let replay = null;
let dirty = false;


// ---------------------------------------------------------------- live
// Only plots in view are redrawn live; one scrolled into view is brought up to date.
let visiblePlots = null;

// Receipt and drawing are decoupled: a message only updates the ring buffers and asks
// for a frame. Frames are requested only when something waits to be drawn (no idle
// animation loop), and a timer holds the request back until the frame would come at
// least DRAW_INTERVAL_MS after the last drawn one (30 per second on a 60 Hz display), so
// the main thread stays free to take the next message and no frame is spent idle.
const DRAW_INTERVAL_MS = 30;
const VSYNC_MS = 16.7;

function trim(values, keep = 3000) {
  if (values.length > keep) values.splice(0, values.length - keep);
}

function startLive() {
  let lastDraw = -Infinity;
  let latest = null;
  let frameQueued = false;
  let undrawn = [];  // t_host of samples received but not drawn yet
  function frame(ts) {
    frameQueued = false;
    if (!dirty || stats.paused) return;
    if (ts - lastDraw < DRAW_INTERVAL_MS - 5) {  // the timer fired early: next frame
      frameQueued = true;
      requestAnimationFrame(frame);
      return;
    }
    lastDraw = ts;
    dirty = false;
    plots.setData(ring.cols, visiblePlots);
    stats.drawnPlots = visiblePlots.size;
    strip.update(latest);
    if (visiblePlots.size && undrawn.length) {
      // uPlot draws in a microtask queued by setData: this one runs after it.
      const hosts = undrawn;
      undrawn = [];
      queueMicrotask(() => {
        const now = Date.now();
        for (const th of hosts) stats.drawLatencies.push(now - th * 1000);
        trim(stats.drawLatencies);
        // The first samples on screen (read by bench/bench_console_load.py).
        if (stats.firstDrawMs == null) {
          stats.firstDrawMs = performance.now();
          performance.mark("exostudy-first-draw");
        }
      });
    } else undrawn = [];
  }
  function requestDraw() {
    dirty = true;
    if (frameQueued) return;
    frameQueued = true;
    const wait = lastDraw + DRAW_INTERVAL_MS - VSYNC_MS / 2 - performance.now();
    if (wait > 0) setTimeout(() => requestAnimationFrame(frame), wait);
    else requestAnimationFrame(frame);
  }
  visiblePlots = plots.watchVisibility(requestDraw);
  ring = new Ring([...PLOTTED, ...STRIP_COLUMNS], stats.windowS * RATE_HZ);

  let windowStart = performance.now();
  let windowMsgs = 0;
  let windowSamples = 0;
  const live = connectLive({
    onTicks(msg) {
      const { columns } = msg;
      const n = columns.t.length;
      stats.messages += 1;
      windowMsgs += 1;
      windowSamples += n;
      stats.gaps = live.counts.gaps;
      stats.dropped = msg.dropped;
      ring.push(addProgress(columns), displayValue);
      observePosteriors(columns);
      strip.observe(columns);
      latest = lastTick(columns);
      stats.samples += n;
      const now = Date.now();
      for (let i = 0; i < n; i++) {
        const th = columns.t_host[i];
        if (th == null) continue;
        stats.latencies.push(now - th * 1000);
        if (!stats.paused) undrawn.push(th);
      }
      trim(stats.latencies);
      if (undrawn.length > 3000) undrawn.splice(0, undrawn.length - 3000);
      stats.transits.push(now - msg.sent_at * 1000);
      trim(stats.transits);
      const tHost = columns.t_host[n - 1];
      if (tHost != null) stats.latencyMs = now - tHost * 1000;
      requestDraw();
    },
    onStatus: showHealth,
    onMarker(m) { noteMarker(m); plots.addMarker(m); requestDraw(); },
    onEmg(msg) { if (!stats.paused) emgStrip.push(msg); },
    onState(state, retryMs) {
      if (state === "live") setConn("live", "live");
      else setConn("down", `disconnected, retrying in ${(retryMs / 1000).toFixed(1)} s`);
    },
  });

  setInterval(() => {
    const now = performance.now();
    const dt = (now - windowStart) / 1000;
    const mps = windowMsgs / dt;
    const sps = windowSamples / dt;
    stats.msgRate = mps;
    stats.sampleRate = sps;
    windowStart = now; windowMsgs = 0; windowSamples = 0;
    const lat = stats.latencyMs == null ? "–" : stats.latencyMs.toFixed(0);
    if (conn.dataset.state === "live" || conn.dataset.state === "stale") {
      const stale = mps < 1;
      setConn(stale ? "stale" : "live",
        `${stale ? "no data" : stats.paused ? "paused" : "live"} · ${mps.toFixed(0)} msg/s · ` +
        `${sps.toFixed(0)} samples/s · latency ${lat} ms · dropped ${stats.dropped}`);
    }
    $("stream-rate").textContent = `${sps.toFixed(0)} samples/s`;
    $("stream-detail").textContent = `${mps.toFixed(0)} messages/s, latency ${lat} ms, gaps ${stats.gaps}`;
    const dropped = $("dropped");
    dropped.dataset.dropped = String(stats.dropped);
    dropped.textContent = `dropped ${stats.dropped} message${stats.dropped === 1 ? "" : "s"}`;
    dropped.classList.toggle("warn-text", stats.dropped > 0);
  }, 1000);
}

// ---------------------------------------------------------------- replay
async function startReplay(id) {
  document.title = `ExoStudy · replay trial ${id}`;
  $("live-cards").hidden = true;
  pauseBtn.hidden = true;
  $("replay-bar").hidden = false;
  setConn("replay", `replay of trial ${id}`);
  const [trial, body] = await Promise.all([
    api.trials.get(id),
    api.trials.trialTicksJson(id).catch((err) => {
      if (err instanceof ApiError && err.status === 404) {
        throw new Error(`trial ${id} has no stored ticks (it has not run)`);
      }
      throw err;
    }),
  ]);
  const raw = addProgress(body.columns);
  const thr = trial.config_snapshot?.settings?.velocity_threshold;
  if (thr != null) plots.setThreshold(thr);
  $("mode-text").textContent = `replay · trial ${id} · ${controllerLabel(trial.condition || trial.controller)} · ` +
    `${trial.task} · ${trial.status}`;
  const disp = Object.fromEntries(PLOTTED.map((n) => [n, (raw[n] || []).map((v) => displayValue(n, v))]));
  replay = { raw, disp, n: raw.t.length, index: 0 };
  api.lab.trialMarkers(id).catch(() => []).then((list) => {
    list.forEach(noteMarker);
    plots.setMarkers(list);
  });
  stats.replay = { trialId: id, samples: replay.n, index: 0, loaded: true };
  const scrub = $("scrub");
  scrub.max = String(Math.max(0, replay.n - 1));
  scrub.value = String(Math.min(replay.n - 1, stats.windowS * RATE_HZ));
  scrub.addEventListener("input", showReplay);
  let timer = null;
  $("play").addEventListener("click", (ev) => {
    if (timer) { clearInterval(timer); timer = null; ev.target.textContent = "Play"; return; }
    ev.target.textContent = "Stop";
    timer = setInterval(() => {
      const next = Math.min(replay.n - 1, Number(scrub.value) + 5);
      scrub.value = String(next);
      showReplay();
      if (next >= replay.n - 1) { clearInterval(timer); timer = null; ev.target.textContent = "Play"; }
    }, 50);
  });
  showReplay();
}

function showReplay() {
  const end = Number($("scrub").value);
  const t = replay.raw.t;
  const from = t[end] - stats.windowS;
  let start = end;
  while (start > 0 && t[start - 1] >= from) start--;
  const view = {};
  for (const [k, v] of Object.entries(replay.disp)) view[k] = v.slice(start, end + 1);
  plots.setData(view);
  const tick = {};
  for (const k of STRIP_COLUMNS) tick[k] = replay.raw[k][end];
  strip.update(tick);
  replay.index = end;
  stats.replay.index = end;
  stats.replay.t = t[end];
  $("scrub-time").textContent = `${(t[end] - t[0]).toFixed(2)} s of ${(t[replay.n - 1] - t[0]).toFixed(2)} s`;
}

// ---------------------------------------------------------------- status
const conn = $("conn");
function setConn(state, text) {
  conn.dataset.state = state;
  conn.className = "pill " + (state === "live" || state === "replay" ? "pill-ok"
    : state === "stale" ? "pill-warn" : "pill-bad");
  $("conn-text").textContent = text;
}

const controllerSel = $("controller");
const controllerMsg = $("controller-msg");

function showHealth(h) {
  stats.lastStatus = h;
  const w = h.worker;
  const ws = $("worker-state");
  ws.dataset.alive = String(w.alive);
  ws.textContent = w.alive
    ? `alive · pid ${w.pid} · controller ${w.controller ?? "none"}`
    : `stopped${w.exit_reason ? ": " + w.exit_reason : ""}`;
  $("worker-timing").textContent = w.alive && w.period_mean_ms != null
    ? `period ${w.period_mean_ms.toFixed(2)} ms · jitter p99 ${w.jitter_p99_ms.toFixed(2)} ms · ` +
      `overruns ${w.overruns} · restarts ${w.restarts}`
    : `restarts ${w.restarts}`;
  // Storage faults: unwritten ticks and ticks lost (the backlog is bounded) stay visible.
  const db = h.database;
  if (db && (db.last_error || db.ticks_dropped)) {
    $("worker-timing").textContent += ` · database ${db.last_error ? "writes failing" : "writing"}` +
      `, ${db.backlog} waiting, ${db.ticks_dropped} ticks lost`;
  }
  if (w.controller && document.activeElement !== controllerSel) controllerSel.value = w.controller;
  const d = h.device;
  const dsEl = $("device-state");
  dsEl.dataset.alive = String(d.alive);
  dsEl.textContent = `${d.alive ? "sending" : "silent"} · ${d.kind}`;
  $("device-detail").textContent = d.faults.length ? "faults: " + d.faults.join("; ") : "no faults";
}

// The controllers the worker can run, from the vocabulary (the idle one records without
// locks). The idle one first: the worker starts with it.
const idleFirst = [...CONTROLLER_NAMES].sort((a, b) => Number(b === IDLE_CONTROLLER) - Number(a === IDLE_CONTROLLER));
controllerSel.replaceChildren(...idleFirst.map((name) => {
  const option = document.createElement("option");
  option.value = name;
  option.textContent = name === IDLE_CONTROLLER ? `${controllerLabel(name)} (recording, no locks)` : controllerLabel(name);
  return option;
}));

controllerSel.addEventListener("change", async () => {
  controllerMsg.textContent = `switching to ${controllerSel.value}…`;
  try {
    await api.worker.setController({ name: controllerSel.value });
    controllerMsg.textContent = `requested ${controllerSel.value}`;
  } catch (err) {
    controllerMsg.textContent = `refused: ${err.message}`;
  }
});

$("calibrate").addEventListener("click", async (ev) => {
  ev.target.disabled = true;
  controllerMsg.textContent = "calibrating: the wearer stands still…";
  try {
    const res = await api.worker.calibrate({ seconds: 3 });
    controllerMsg.dataset.calibrated = "true";
    controllerMsg.textContent = `calibrated: offsets ${res.offset_left_deg.toFixed(1)}°, ` +
      `${res.offset_right_deg.toFixed(1)}° (std ${res.std_left_deg.toFixed(2)}°, ${res.std_right_deg.toFixed(2)}°)`;
  } catch (err) {
    controllerMsg.dataset.calibrated = "false";
    controllerMsg.textContent = `calibration failed: ${err.message}`;
  } finally {
    ev.target.disabled = false;
  }
});

$("restart").addEventListener("click", async (ev) => {
  ev.target.disabled = true;
  try {
    showHealth(await api.worker.restart());
  } catch (err) {
    controllerMsg.textContent = `restart failed: ${err.message}`;
  } finally {
    ev.target.disabled = false;
  }
});

if (trialId) {
  startReplay(Number(trialId)).catch((err) => {
    setConn("down", String(err.message || err));
    $("mode-text").textContent = `replay of trial ${trialId}: ${err.message || err}`;
    stats.replay = { trialId: Number(trialId), loaded: false, error: String(err.message || err) };
  });
}
else startLive();

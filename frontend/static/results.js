// A study's results: the paper's tables and figures from the stored trials, the trials
// with their replay, timeline and what-if replay, and the leave-one-out model evaluation.
import * as api from "/static/api_client.js";
import { $, act, formData, h, showFatal } from "/static/dom.js";
import { cellNode, parseCsv, sortableTable, sortRows } from "/static/datatable.js";
import { showTrialEmg } from "/static/emgpanel.js";
import { CONTROLLER_NAMES, controllerInfo, controllerKey, controllerLabel, correctAction, SEGMENT_LABELS, STUDY_CONTROLLERS } from "/static/names.js";

const studyId = Number(location.pathname.split("/").at(-2));
// A baseline replays like the idle controller (it never locks): not offered as a what-if.
$("#whatif-controller").replaceChildren(...CONTROLLER_NAMES.filter((c) => !controllerInfo(c).baseline)
  .map((c) => h("option", { value: c }, controllerLabel(c))));
// `wide`: the JSON table is the paper's layout, participants as columns from index 2;
// the long form (one row per participant, controller and motion) is its CSV download.
const TABLES = [
  { name: "performance", title: "Intent estimation and decision performance", wide: true,
    longNotes: ["motion: SQ squat, AS asymmetric stoop (either side). Recognised: the correct "
      + "model's posterior reached 0.5 in the first half of the lift; decision (the paper's "
      + "rule): a squat is correct once both sides were commanded to lock in the first half, in "
      + "one decision or two, a stoop if its first lock decision there is the supporting side; "
      + "first_correct: the first lock decision alone; first_one_sided: squats whose first lock "
      + "was one side only."] },
  { name: "performance_by_kind", title: "Intent estimation and decision performance per lift kind", longOnly: true },
  { name: "false_positives", title: "False positive lock signals", wide: true,
    longNotes: ["signals: rising edges of the held lock command on either side; edges per side; "
      + "decisions: controller evaluations that chose a locking action; ticks with a lock held; the trials' duration."] },
  { name: "questionnaires", title: "Questionnaire results", wide: true,
    longNotes: ["highest: the participant's strictly highest score on that instrument."] },
  { name: "onset_to_lock", title: "Lift onset to lock" },
];
const FIGURES = [["peak_torques", "Peak exoskeleton torques per lift"],
  ["onset_to_lock", "Lift onset to lock"]];
let doc = null;
// The long forms, from the CSV downloads: name -> {header, rows}.
let long = {};
// Sort per table and layout: key -> {column name, dir}.
const sorts = {};

// What the browser tests read: per table, the header and rows as shown.
const state = (window.exostudyResults = {
  loaded: 0, whatIf: null, lopo: null, segments: null, layout: "paper", tables: {}, trials: [],
});

// Filter one table by the toolbar: a "participant" column filters rows, participant
// columns of the paper's layout are hidden, a "controller" column filters rows (rows
// with an empty controller, such as the stated preference, stay).
function filtered(table, wide) {
  const p = $("#filter-participant").value;
  const c = $("#filter-controller").value;
  const lower = table.header.map((x) => x.toLowerCase());
  const pCol = lower.indexOf("participant");
  const cCol = lower.indexOf("controller");
  let cols = table.header.map((_, i) => i);
  if (p && wide) cols = cols.filter((i) => i < 2 || table.header[i] === p);
  const rows = table.rows.filter((r) => (!p || pCol < 0 || r[pCol] === p)
    && (!c || cCol < 0 || r[cCol] == null || r[cCol] === "" || controllerKey(r[cCol]) === c));
  return {
    header: cols.map((i) => table.header[i]),
    rows: rows.map((r) => cols.map((i) => r[i])),
    // A controller filter the table cannot apply (the paper's cells join UMC/E-UMC).
    unfiltered: Boolean(c) && cCol < 0,
    // A participant filter on a table that pools every participant.
    pooled: Boolean(p) && pCol < 0 && !wide,
  };
}

// A sortable table; `record` names it in `state.tables` with its rows as shown.
function tableView(key, header, rows, extra = {}, record = null) {
  const s = sorts[key];
  const col = s ? header.indexOf(s.name) : -1;
  const sort = col >= 0 ? { col, dir: s.dir } : null;
  if (record) state.tables[record] = { header, rows: sortRows(rows, sort) };
  return h("div", { class: "scroll-x", "data-sort-key": key }, sortableTable({
    header, rows, sort,
    onSort: ({ col: i, dir }) => {
      sorts[key] = { name: header[i], dir };
      render();
      // The table was drawn anew: keep the keyboard on the header just pressed.
      document.querySelector(`[data-sort-key="${key}"] th button[data-col="${i}"]`)?.focus();
    },
    ...extra,
  }));
}

// Controller and condition keys ("eumc", "umc+personal") read as their labels ("E-UMC",
// "UMC (personal models)"); the rest as the table has them.
function labelled(header) {
  const cCol = header.map((x) => x.toLowerCase()).indexOf("controller");
  return { render: (r, col) => (col === cCol && CONTROLLER_NAMES.includes(controllerKey(r[col])) ? controllerLabel(r[col]) : cellNode(r[col])) };
}

function tableCard(spec, table, wide) {
  const layout = state.layout;
  const view = filtered(table, wide);
  return h("section", { class: "card", "data-table": spec.name, "data-layout": wide ? "paper" : "long" },
    h("h2", {}, spec.longOnly ? spec.title : table.title || spec.title),
    h("p", { class: "small" },
      h("a", { href: api.results.studyTable.url(studyId, spec.name, "csv"), download: "" }, "CSV"), " · ",
      h("a", { href: api.results.studyTable.url(studyId, spec.name, "md"), download: "" }, "Markdown"),
      h("span", { class: "muted" }, ` · ${view.rows.length} of ${table.rows.length} rows`)),
    tableView(`${spec.name}:${layout}`, view.header, view.rows, labelled(view.header), spec.name),
    table.rows.length ? null : h("p", { class: "muted small" }, "nothing to count yet"),
    view.pooled ? h("p", { class: "muted small" }, "This table pools every participant's lifts.") : null,
    view.unfiltered ? h("p", { class: "muted small" },
      "This layout lists the controllers together; choose “every count” to filter by controller.") : null,
    (table.notes || []).map((n) => h("p", { class: "muted small" }, n)));
}

function renderTables() {
  const layout = state.layout;
  state.tables = {};
  const cards = [];
  for (const spec of TABLES) {
    if (layout === "paper" && spec.longOnly) continue;
    const wide = layout === "paper" && spec.wide;
    // The long form from the CSV: the paper's title and notes describe the wide layout.
    const table = layout === "long" && spec.wide && long[spec.name]
      ? { ...long[spec.name], title: `${spec.title}: every count`, notes: spec.longNotes || [] }
      : doc.tables[spec.name];
    if (table) cards.push(tableCard(spec, table, wide));
  }
  $("#tables").replaceChildren(...cards);
  const lifts = long.lifts;
  if (lifts) {
    const view = filtered(lifts, false);
    $("#lifts-count").textContent = `(${view.rows.length} of ${lifts.rows.length} lifts)`;
    $("#lifts").replaceChildren(h("p", { class: "small" },
      h("a", { href: api.results.studyTable.url(studyId, "lifts", "csv"), download: "" }, "CSV"), " · ",
      h("a", { href: api.results.studyTable.url(studyId, "lifts", "md"), download: "" }, "Markdown"),
      h("span", { class: "muted" }, " · the data behind both figures; times in seconds from the lift's onset, torques in Nm")),
    tableView("lifts", view.header, view.rows, labelled(view.header), "lifts"));
  }
}

const TRIAL_HEADER = ["trial", "participant", "controller", "task", "ground truth", "lifts",
  "lifts cut by start or end", "gait trials", ""];

function trialLinks(t) {
  return [
    h("a", { href: `/live?trial=${t.trial_id}`, class: "replay-link" }, "Replay ›"), " ",
    h("a", { href: api.results.trialTimeline.url(t.trial_id, "svg"), class: "timeline-link", target: "_blank" }, "timeline"), " ",
    h("button", { type: "button", class: "open", onclick: () => openTrial(t) }, "Open"),
  ];
}

function renderTrials() {
  const p = $("#filter-participant").value;
  const c = $("#filter-controller").value;
  const trials = doc.trials.filter((t) => (!p || t.participant === p) && (!c || t.controller === c));
  state.trials = trials.map((t) => t.trial_id);
  const byId = new Map(trials.map((t) => [t.trial_id, t]));
  const rows = trials.map((t) => [t.trial_id, t.participant, controllerLabel(t.condition || t.controller),
    t.task, t.truth, t.lifts, t.incomplete_lifts, t.gait_trials, null]);
  $("#trials").replaceChildren(tableView("trials", TRIAL_HEADER, rows, {
    sortable: (col) => col < TRIAL_HEADER.length - 1,
    rowAttrs: (r) => ({ "data-trial": r[0], "data-controller": byId.get(r[0]).controller,
      class: currentTrial && currentTrial.trial_id === r[0] ? "selected" : null }),
    render: (r, col) => {
      const t = byId.get(r[0]);
      if (col === 1) return h("strong", {}, t.participant);
      if (col === 4) return h("span", { title: t.truth_note || null }, t.truth);
      if (col === TRIAL_HEADER.length - 1) return h("span", { class: "trial-actions" }, trialLinks(t));
      return r[col] == null ? "–" : String(r[col]);
    },
  }));
  $("#trials-empty").hidden = doc.trials.length > 0;
  const skipped = doc.skipped || [];
  $("#skipped").hidden = skipped.length === 0;
  $("#skipped").textContent = skipped.length
    ? `Not counted: ${skipped.map((s) => `trial ${s.trial_id} (${s.status})`).join(", ")}.` : "";
}

function render() {
  renderTables();
  renderTrials();
  $("#notes").replaceChildren(...doc.notes.map((n) => h("p", { class: "card warn-text small note" }, n)));
}

async function loadLong() {
  const names = ["lifts", ...TABLES.filter((t) => t.wide || t.longOnly).map((t) => t.name)];
  const texts = await Promise.all(names.map((n) => api.results.studyTable.text(studyId, n, "csv")));
  long = Object.fromEntries(names.map((n, i) => [n, parseCsv(texts[i])]));
}

async function loadResults() {
  const [study, results] = await Promise.all([
    api.studies.get(studyId), api.results.study(studyId)]);
  doc = results;
  await loadLong();
  document.title = `ExoStudy · results · ${study.name}`;
  $("#study-title").textContent = study.name;
  $("#study-link").textContent = study.name;
  $("#study-link").href = `/console/studies/${studyId}`;
  $("#export").href = api.trials.exportStudy.url(studyId);
  const fill = (sel, values, label = (v) => v) => {
    const current = sel.value;
    sel.replaceChildren(h("option", { value: "" }, "all"),
      ...values.map((v) => h("option", { value: v }, label(v))));
    sel.value = values.includes(current) ? current : "";
  };
  // Participants with trials, and those who only answered questionnaires.
  const codes = new Set(doc.trials.map((t) => t.participant));
  for (const spec of TABLES.filter((t) => t.wide)) {
    for (const code of (doc.tables[spec.name]?.header || []).slice(2)) codes.add(code);
  }
  fill($("#filter-participant"), [...codes].sort());
  // Controllers that ran a trial or were scored on a questionnaire.
  const ctls = new Set(doc.trials.map((t) => t.controller));
  const q = long.questionnaires;
  const qc = q ? q.header.indexOf("controller") : -1;
  if (qc >= 0) for (const r of q.rows) ctls.add(controllerKey(r[qc]));
  fill($("#filter-controller"), CONTROLLER_NAMES.filter((c) => ctls.has(c)), controllerLabel);
  render();
  // Figures are drawn by the server from the same evaluation (cached there).
  const stamp = Date.now();
  $("#figures").replaceChildren(...FIGURES.map(([n, title]) => {
    const msg = h("p", { class: "msg small" }, "drawing…");
    const img = h("img", { src: `${api.results.studyFigure.url(studyId, n, "svg")}?v=${stamp}`, alt: title, style: "width:100%;height:auto" });
    img.addEventListener("load", () => { msg.textContent = ""; });
    img.addEventListener("error", () => { msg.textContent = "the figure could not be drawn"; msg.classList.add("msg-bad"); });
    return h("figure", { "data-figure": n }, msg, img,
      h("figcaption", { class: "small" }, title, " · ",
        h("a", { href: api.results.studyFigure.url(studyId, n, "png"), download: "" }, "PNG"), " · ",
        h("a", { href: api.results.studyFigure.url(studyId, n, "svg"), download: "" }, "SVG")));
  }));
  state.loaded += 1;
  loadMuscle().catch((e) => { $("#muscle-msg").textContent = `muscle activity: ${e.message}`; });
}

// Muscle activity from the stored EMG: the reduction of each muscle's mean envelope
// against each baseline (mean, 95 % interval, Holm-corrected p), the figures, the
// quality flags of the trials (flagged data are kept and shown), the method.
async function loadMuscle() {
  const m = await api.results.studyMuscle(studyId);
  state.muscle = m;
  const reds = m.reductions.filter((r) => r.group === "all" && r.metric === "mean");
  const fmt = (x, d = 1) => (x == null ? "–" : x.toFixed(d));
  const cards = m.baselines.map((b) => {
    const rows = reds.filter((r) => r.baseline === b).map((r) => [r.channel,
      controllerLabel(r.condition), r.n, fmt(r.mean_pct), `${fmt(r.ci_low)} to ${fmt(r.ci_high)}`, fmt(r.p_holm, 3)]);
    return h("div", { "data-baseline": b }, h("h3", {}, `Reduction against ${controllerLabel(b)} (%)`),
      tableView(`muscle:${b}`, ["muscle", "controller", "participants", "mean", "95 % CI", "p (Holm)"], rows));
  });
  const flagged = m.trials.filter((t) => t.flags.length || t.lifts_without_emg);
  const files = [["lifts", "per lift"], ["summary", "means"], ["reductions", "reductions"], ["repeated_measures", "Friedman"]];
  $("#muscle-body").replaceChildren(
    h("p", { class: "small" }, `Normalisation: ${m.method.normalisation}; ${m.method.reduction}. CSV: `,
      ...files.flatMap(([n, t], i) => [i ? " · " : "", h("a", { href: api.results.studyMuscleTable.url(studyId, n, "csv"), download: "" }, t)])),
    ...(cards.length ? cards : [h("p", { class: "muted small" }, "No baseline condition with EMG: no reduction to show.")]),
    h("div", { class: "grid2" }, ...[["muscle_envelopes", "Envelope over the lift cycle"], ["muscle_reduction", "Reduction per muscle"]].map(([n, title]) =>
      h("figure", { "data-figure": n }, h("img", { src: `${api.results.studyMuscleFigure.url(studyId, n, "svg")}?v=${Date.now()}`, alt: title, style: "width:100%;height:auto" }),
        h("figcaption", { class: "small" }, title, " · ", h("a", { href: api.results.studyMuscleFigure.url(studyId, n, "png"), download: "" }, "PNG"))))),
    flagged.length ? h("p", { class: "small msg-bad" }, "Flagged trials (kept and shown): ",
      flagged.map((t) => `${t.trial_id} (${[...t.flags, ...(t.lifts_without_emg ? [`${t.lifts_without_emg} lifts without EMG`] : [])].join(", ")})`).join("; ")) : null,
    ...m.notes.map((n) => h("p", { class: "muted small" }, n)));
}

let currentTrial = null;
// The what-if replay's first suggestion: a study controller that differs from the
// trial's in whether it estimates intent (so the comparison shows what intent adds),
// else any other study controller.
function whatIfDefault(name) {
  const others = STUDY_CONTROLLERS.filter((c) => c !== name);
  const intent = controllerInfo(name)?.estimates_intent;
  return others.find((c) => controllerInfo(c)?.estimates_intent !== intent) ?? others[0] ?? name;
}

function openTrial(t) {
  currentTrial = t;
  $("#trial-panel").hidden = false;
  $("#panel-trial").textContent = `${t.trial_id} · ${t.participant} · ${controllerLabel(t.condition || t.controller)} · ${t.task}`;
  $("#panel-replay").href = `/live?trial=${t.trial_id}`;
  $("#panel-timeline-svg").href = api.results.trialTimeline.url(t.trial_id, "svg");
  $("#panel-timeline-png").href = api.results.trialTimeline.url(t.trial_id, "png");
  const msg = $("#panel-timeline-msg");
  msg.className = "msg small";
  msg.textContent = "drawing the timeline…";
  $("#panel-timeline").src = api.results.trialTimeline.url(t.trial_id, "svg");
  $("#whatif-controller").value = whatIfDefault(t.controller);
  loadSegments().catch((err) => { $("#seg-msg").textContent = err.message; });
  showTrialEmg(t.trial_id);
  $("#whatif").hidden = true;
  $("#whatif-msg").textContent = "";
  document.querySelectorAll("#trials tr.selected").forEach((tr) => tr.classList.remove("selected"));
  document.querySelector(`#trials tr[data-trial='${t.trial_id}']`)?.classList.add("selected");
  $("#trial-panel").scrollIntoView({ behavior: "smooth", block: "start" });
  $("#panel-replay").focus({ preventScroll: true });
}
$("#panel-timeline").addEventListener("load", () => { $("#panel-timeline-msg").textContent = ""; });
$("#panel-timeline").addEventListener("error", () => {
  $("#panel-timeline-msg").textContent = "the timeline could not be drawn (no stored ticks?)";
  $("#panel-timeline-msg").classList.add("msg-bad");
});

// ---------------------------------------------------------------- segments
function segRow(seg) {
  const num = (k) => h("input", { type: "number", min: 0, step: 1, name: k, value: seg[k], class: "narrow", "aria-label": k });
  return h("tr", { "data-segment": "" }, h("td", {}, num("start")), h("td", {}, num("peak")),
    h("td", {}, num("end")),
    h("td", {}, h("select", { name: "label", "aria-label": "label" },
      SEGMENT_LABELS.map((l) => h("option", { value: l, selected: l === seg.label ? "" : null }, l)))),
    h("td", {}, h("button", { type: "button", onclick: (ev) => ev.target.closest("tr").remove() }, "Remove")));
}

function showSegments(list) {
  $("#segments tbody").replaceChildren(...list.map(segRow));
  state.segments = list.length;
}

async function loadSegments() {
  showSegments(await api.trials.listTrialSegments(currentTrial.trial_id));
}

$("#seg-add").addEventListener("click", () => {
  $("#segments tbody").append(segRow({ start: 0, peak: 50, end: 100, label: "unlabelled" }));
});

$("#seg-propose").addEventListener("click", () =>
  act($("#seg-propose"), $("#seg-msg"), async () => {
    const id = currentTrial.trial_id;
    try {
      showSegments(await api.trials.autoSegment(id));
    } catch (err) {
      if (err.status !== 409 || !confirm("Replace the segments you set with a new proposal?")) throw err;
      showSegments(await api.trials.autoSegment(id, { replace: true }));
    }
    return "proposed: check the edges and labels, then save";
  }));

$("#seg-save").addEventListener("click", () =>
  act($("#seg-save"), $("#seg-msg"), async () => {
    const body = [...document.querySelectorAll("#segments tbody tr")].map((tr) => ({
      start: Number(tr.querySelector("[name=start]").value),
      peak: Number(tr.querySelector("[name=peak]").value),
      end: Number(tr.querySelector("[name=end]").value),
      label: tr.querySelector("[name=label]").value,
    }));
    showSegments(await api.trials.replaceTrialSegments(currentTrial.trial_id, body));
    await loadResults();
    return `saved ${body.length} segment${body.length === 1 ? "" : "s"}; the tables are recomputed`;
  }));

const METRICS = [["lifts", "lifts"], ["recognised", "recognised"],
  ["decision_correct", "decision correct"], ["decision_wrong", "decision wrong"],
  ["decision_missed", "decision missed"], ["false_positive_signals", "false-positive lock signals"],
  ["gait_trials", "gait trials"], ["lock_ticks", "ticks with a lock held"],
  ["onset_to_lock_median_s", "onset to lock, median (s)"], ["ticks", "ticks"]];

const fmtMetric = (v) => (v == null ? "–" : typeof v === "number" && !Number.isInteger(v) ? v.toFixed(3) : String(v));

function change(a, b) {
  if (a == null || b == null || a === b) return a === b ? "same" : "";
  if (typeof a !== "number" || typeof b !== "number") return "differs";
  const d = b - a;
  return `${d > 0 ? "+" : ""}${fmtMetric(Number.isInteger(d) ? d : Number(d.toFixed(4)))}`;
}

$("#whatif-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#whatif-run"), $("#whatif-msg"), async () => {
    const body = formData(ev.target);
    for (const k of ["model_set_id", "utility_set_id"]) if (body[k] != null) body[k] = Number(body[k]);
    const r = await api.results.trialWhatIf(currentTrial.trial_id, body);
    state.whatIf = r;
    const rate = body.rate_hz ? ` at ${body.rate_hz} Hz` : "";
    $("#whatif thead tr").replaceChildren(h("th", {}, "metric"),
      h("th", {}, `original (${controllerLabel(r.original.controller)}, as run)`),
      h("th", {}, `what-if (${controllerLabel(r.replay.controller)}${rate})`),
      h("th", {}, "change"));
    $("#whatif tbody").replaceChildren(...METRICS.map(([k, label]) => {
      const a = r.original[k];
      const b = r.replay[k];
      return h("tr", { "data-metric": k, class: a !== b ? "changed" : null },
        h("td", {}, label), h("td", {}, fmtMetric(a)), h("td", {}, fmtMetric(b)), h("td", { class: "muted" }, change(a, b)));
    }));
    $("#whatif").hidden = false;
    return `replayed against ${r.truth} truth; the stored trial is unchanged`;
  });
});

function pct(x) { return x == null ? "–" : `${(100 * x).toFixed(1)} %`; }

// `correct(row, col)`: the cells on the diagonal (right answers), drawn bold.
function confusion(title, conf, correct) {
  const rows = Object.keys(conf);
  const cols = rows.length ? Object.keys(conf[rows[0]]) : [];
  return h("div", {}, h("h3", { class: "small" }, title), h("table", { class: "list confusion" },
    h("thead", {}, h("tr", {}, h("th", {}, "true \\ predicted"), cols.map((c) => h("th", {}, c)))),
    h("tbody", {}, rows.map((r) => h("tr", { "data-true": r }, h("th", {}, r),
      cols.map((c) => h("td", { "data-predicted": c, class: correct(r, c) ? "diag" : null }, conf[r][c])))))));
}

$("#lopo-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#lopo-run"), $("#lopo-msg"), async () => {
    const id = $("#lopo-model-set").value;
    if (!id) throw new Error("model set: this study has no ready model set");
    const r = await api.results.modelEvaluation(studyId, { model_set_id: id });
    state.lopo = r;
    $("#lopo").replaceChildren(
      h("p", {}, `Recognition ${pct(r.recognition_accuracy)}, decisions ${pct(r.decision_accuracy)} over ${r.segments} segments.`),
      h("table", { class: "list" }, h("thead", {}, h("tr", {}, h("th", {}, "held out"),
        h("th", {}, "segments"), h("th", {}, "recognised"), h("th", {}, "correct decisions"))),
      h("tbody", {}, r.folds.map((f) => h("tr", {}, h("td", {}, f.participant),
        f.error ? h("td", { colspan: 3, class: "warn-text" }, f.error)
          : [h("td", {}, f.segments), h("td", {}, f.recognised), h("td", {}, f.correct)])))),
      h("div", { class: "grid2" },
        confusion("Recognition: first posterior to reach 0.5", r.recognition_confusion, (a, b) => a === b),
        confusion("First lock decision", r.decision_confusion, (a, b) => correctAction(a) === b)));
    return `done: ${r.folds.length} participants held out in turn`;
  });
});

async function loadModelSets() {
  const [models, utilities] = await Promise.all([
    api.models.listModelSets(studyId), api.models.listUtilitySets(studyId)]);
  const ready = (xs) => xs.filter((m) => m.status === "ready");
  const option = (m) => h("option", { value: m.id }, `${m.id} · ${m.name}`);
  $("#lopo-model-set").replaceChildren(...ready(models).map(option));
  $("#lopo-run").disabled = ready(models).length === 0;
  if (!ready(models).length) $("#lopo-msg").textContent = "this study has no ready model set yet";
  $("#whatif-model-set").replaceChildren(h("option", { value: "" }, "as run"), ...ready(models).map(option));
  $("#whatif-utility-set").replaceChildren(h("option", { value: "" }, "as run"), ...ready(utilities).map(option));
}

$("#layout").addEventListener("change", () => {
  state.layout = $("#layout").value;
  render();
});
for (const sel of ["#filter-participant", "#filter-controller"]) {
  $(sel).addEventListener("change", render);
}
$("#refresh").addEventListener("click", () =>
  act($("#refresh"), $("#results-msg"), async () => { await loadResults(); return "up to date"; }));

Promise.all([loadResults(), loadModelSets()]).catch(showFatal);

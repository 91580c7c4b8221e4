// A study's results: the paper's tables and figures from the stored trials, the trials
// with their replay, timeline and what-if replay, and the leave-one-out model evaluation.
import { api, get, post } from "/static/api.js";
import { $, act, formData, h, showFatal } from "/static/dom.js";

const studyId = Number(location.pathname.split("/").at(-2));
const TABLES = [
  ["performance", "Intent estimation and decision performance"],
  ["false_positives", "False positives in walking and stair walking"],
  ["questionnaires", "Questionnaires"],
  ["onset_to_lock", "Lift onset to lock"],
];
const FIGURES = [["peak_torques", "Peak exoskeleton torques per lift"],
  ["onset_to_lock", "Lift onset to lock"]];
const LABEL = { umc: "UMC", eumc: "E-UMC", pec: "PEC", none: "none" };
let doc = null;

// What the browser tests read.
const state = (window.exostudyResults = { loaded: 0, whatIf: null, lopo: null, segments: null });

function keep(row) {
  // A table row mentions a participant code or controller label in its cells; filter on that.
  const p = $("#filter-participant").value;
  const c = $("#filter-controller").value;
  const cells = row.map((v) => String(v ?? ""));
  return (!p || cells.includes(p) || !doc.trials.some((t) => cells.includes(t.participant)))
    && (!c || cells.some((v) => v.toLowerCase().replace("-", "") === c)
      || !cells.some((v) => Object.values(LABEL).includes(v)));
}

function tableCard(name, title, table) {
  const header = table.header;
  // A participant filter that names a column (wide layout) hides the other participants.
  const p = $("#filter-participant").value;
  const codes = new Set(doc.trials.map((t) => t.participant));
  const cols = header.map((_, i) => i).filter((i) => !p || !codes.has(header[i]) || header[i] === p);
  return h("section", { class: "card", "data-table": name },
    h("h2", {}, table.title || title),
    h("p", { class: "small" },
      h("a", { href: `/api/studies/${studyId}/results/${name}.csv`, download: "" }, "CSV"), " · ",
      h("a", { href: `/api/studies/${studyId}/results/${name}.md`, download: "" }, "Markdown")),
    h("div", { style: "overflow-x:auto" }, h("table", { class: "list" },
      h("thead", {}, h("tr", {}, cols.map((i) => h("th", {}, header[i])))),
      h("tbody", {}, table.rows.filter(keep).map((r) => h("tr", {},
        cols.map((i) => h("td", {}, r[i] == null ? "–" : String(r[i])))))))),
    table.rows.length ? null : h("p", { class: "muted small" }, "nothing to count yet"),
    (table.notes || []).map((n) => h("p", { class: "muted small" }, n)));
}

function render() {
  $("#tables").replaceChildren(...TABLES.filter(([n]) => doc.tables[n])
    .map(([n, title]) => tableCard(n, title, doc.tables[n])));
  $("#notes").replaceChildren(...doc.notes.map((n) => h("p", { class: "card warn-text small note" }, n)));
  const p = $("#filter-participant").value;
  const c = $("#filter-controller").value;
  const trials = doc.trials.filter((t) => (!p || t.participant === p) && (!c || t.controller === c));
  $("#trials tbody").replaceChildren(...trials.map((t) => h("tr", { "data-trial": t.trial_id },
    h("td", {}, t.trial_id), h("td", {}, h("strong", {}, t.participant)),
    h("td", {}, LABEL[t.controller] ?? t.controller), h("td", {}, t.task),
    h("td", { title: t.truth_note }, t.truth), h("td", {}, t.lifts), h("td", {}, t.gait_trials),
    h("td", {}, h("button", { type: "button", class: "open", onclick: () => openTrial(t) }, "Open")))));
  $("#trials-empty").hidden = doc.trials.length > 0;
}

async function loadResults() {
  const [study, results] = await Promise.all([
    get(`/api/studies/${studyId}`), get(`/api/studies/${studyId}/results`)]);
  doc = results;
  document.title = `ExoStudy · results · ${study.name}`;
  $("#study-title").textContent = study.name;
  $("#study-link").textContent = study.name;
  $("#study-link").href = `/console/studies/${studyId}`;
  $("#export").href = `/api/studies/${studyId}/export.zip`;
  const fill = (sel, values, label = (v) => v) => {
    const current = sel.value;
    sel.replaceChildren(h("option", { value: "" }, "all"),
      ...values.map((v) => h("option", { value: v }, label(v))));
    sel.value = values.includes(current) ? current : "";
  };
  fill($("#filter-participant"), [...new Set(doc.trials.map((t) => t.participant))]);
  fill($("#filter-controller"), [...new Set(doc.trials.map((t) => t.controller))], (v) => LABEL[v] ?? v);
  render();
  // Figures are drawn by the server from the same evaluation (cached there).
  const stamp = Date.now();
  $("#figures").replaceChildren(...FIGURES.map(([n, title]) => h("figure", { "data-figure": n },
    h("img", { src: `/api/studies/${studyId}/figures/${n}.svg?v=${stamp}`, alt: title, style: "max-width:100%" }),
    h("figcaption", { class: "small" }, title, " · ",
      h("a", { href: `/api/studies/${studyId}/figures/${n}.png`, download: "" }, "PNG"), " · ",
      h("a", { href: `/api/studies/${studyId}/figures/${n}.svg`, download: "" }, "SVG")))));
  state.loaded += 1;
}

let currentTrial = null;
function openTrial(t) {
  currentTrial = t;
  $("#trial-panel").hidden = false;
  $("#panel-trial").textContent = `${t.trial_id} · ${t.participant} · ${LABEL[t.controller] ?? t.controller}`;
  $("#panel-replay").href = `/live?trial=${t.trial_id}`;
  $("#panel-timeline-svg").href = `/api/trials/${t.trial_id}/figures/timeline.svg`;
  $("#panel-timeline-png").href = `/api/trials/${t.trial_id}/figures/timeline.png`;
  $("#panel-timeline").src = `/api/trials/${t.trial_id}/figures/timeline.svg`;
  $("#whatif-controller").value = t.controller === "pec" ? "umc" : "pec";
  loadSegments().catch((err) => { $("#seg-msg").textContent = err.message; });
  $("#whatif").hidden = true;
  $("#whatif-msg").textContent = "";
  $("#trial-panel").scrollIntoView({ behavior: "smooth", block: "start" });
}

// ---------------------------------------------------------------- segments
const SEG_LABELS = ["squat", "stoop_left", "stoop_right", "other", "unlabelled"];

function segRow(seg) {
  const num = (k) => h("input", { type: "number", min: 0, step: 1, name: k, value: seg[k], class: "narrow", "aria-label": k });
  return h("tr", { "data-segment": "" }, h("td", {}, num("start")), h("td", {}, num("peak")),
    h("td", {}, num("end")),
    h("td", {}, h("select", { name: "label", "aria-label": "label" },
      SEG_LABELS.map((l) => h("option", { value: l, selected: l === seg.label ? "" : null }, l)))),
    h("td", {}, h("button", { type: "button", onclick: (ev) => ev.target.closest("tr").remove() }, "Remove")));
}

function showSegments(list) {
  $("#segments tbody").replaceChildren(...list.map(segRow));
  state.segments = list.length;
}

async function loadSegments() {
  showSegments(await get(`/api/trials/${currentTrial.trial_id}/segments`));
}

$("#seg-add").addEventListener("click", () => {
  $("#segments tbody").append(segRow({ start: 0, peak: 50, end: 100, label: "unlabelled" }));
});

$("#seg-propose").addEventListener("click", () =>
  act($("#seg-propose"), $("#seg-msg"), async () => {
    const path = `/api/trials/${currentTrial.trial_id}/segment`;
    try {
      showSegments(await post(path));
    } catch (err) {
      if (err.status !== 409 || !confirm("Replace the segments you set with a new proposal?")) throw err;
      showSegments(await post(`${path}?replace=true`));
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
    showSegments(await api("PUT", `/api/trials/${currentTrial.trial_id}/segments`, body));
    await loadResults();
    return `saved ${body.length} segment${body.length === 1 ? "" : "s"}; the tables are recomputed`;
  }));

const METRICS = [["lifts", "lifts"], ["recognised", "recognised"],
  ["decision_correct", "decision correct"], ["decision_wrong", "decision wrong"],
  ["decision_missed", "decision missed"], ["false_positive_signals", "false-positive lock signals"],
  ["gait_trials", "gait trials"], ["lock_ticks", "ticks with a lock held"],
  ["onset_to_lock_median_s", "onset to lock, median (s)"], ["ticks", "ticks"]];

$("#whatif-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#whatif-run"), $("#whatif-msg"), async () => {
    const body = formData(ev.target);
    const r = await post(`/api/trials/${currentTrial.trial_id}/what-if`, body);
    state.whatIf = r;
    $("#whatif thead tr").replaceChildren(h("th", {}, "metric"),
      h("th", {}, `original (${LABEL[r.original.controller] ?? r.original.controller})`),
      h("th", {}, `what-if (${LABEL[r.replay.controller] ?? r.replay.controller})`));
    $("#whatif tbody").replaceChildren(...METRICS.map(([k, label]) => h("tr", { "data-metric": k },
      h("td", {}, label), h("td", {}, r.original[k] ?? "–"), h("td", {}, r.replay[k] ?? "–"))));
    $("#whatif").hidden = false;
    return `replayed against ${r.truth} truth; the stored trial is unchanged`;
  });
});

function pct(x) { return x == null ? "–" : `${(100 * x).toFixed(1)} %`; }

function confusion(title, conf) {
  const rows = Object.keys(conf);
  const cols = rows.length ? Object.keys(conf[rows[0]]) : [];
  return h("div", {}, h("h3", { class: "small" }, title), h("table", { class: "list" },
    h("thead", {}, h("tr", {}, h("th", {}, "true \\ predicted"), cols.map((c) => h("th", {}, c)))),
    h("tbody", {}, rows.map((r) => h("tr", {}, h("th", {}, r),
      cols.map((c) => h("td", { class: r === c ? "strong" : null }, conf[r][c])))))));
}

$("#lopo-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#lopo-run"), $("#lopo-msg"), async () => {
    const id = $("#lopo-model-set").value;
    if (!id) throw new Error("model set: this study has no ready model set");
    const r = await get(`/api/studies/${studyId}/model-evaluation?model_set_id=${id}`);
    state.lopo = r;
    $("#lopo").replaceChildren(
      h("p", {}, `Recognition ${pct(r.recognition_accuracy)}, decisions ${pct(r.decision_accuracy)} over ${r.segments} segments.`),
      h("table", { class: "list" }, h("thead", {}, h("tr", {}, h("th", {}, "held out"),
        h("th", {}, "segments"), h("th", {}, "recognised"), h("th", {}, "correct decisions"))),
      h("tbody", {}, r.folds.map((f) => h("tr", {}, h("td", {}, f.participant),
        f.error ? h("td", { colspan: 3, class: "warn-text" }, f.error)
          : [h("td", {}, f.segments), h("td", {}, f.recognised), h("td", {}, f.correct)])))),
      h("div", { class: "grid2" }, confusion("Recognition", r.recognition_confusion),
        confusion("First lock decision", r.decision_confusion)));
    return "done";
  });
});

async function loadModelSets() {
  const sets = (await get(`/api/studies/${studyId}/model-sets`)).filter((m) => m.status === "ready");
  $("#lopo-model-set").replaceChildren(...sets.map((m) => h("option", { value: m.id }, `${m.id} · ${m.name}`)));
}

for (const sel of ["#filter-participant", "#filter-controller"]) {
  $(sel).addEventListener("change", render);
}
$("#refresh").addEventListener("click", () =>
  act($("#refresh"), $("#results-msg"), async () => { await loadResults(); return "up to date"; }));

Promise.all([loadResults(), loadModelSets()]).catch(showFatal);

// Virtual cohorts: start one as a background job, follow its progress, show its tables
// and power curves (everything comes from api.cohorts.get).
import * as api from "/static/api_client.js";
import { $, act, fmtDate, h, showFatal } from "/static/dom.js";
import { progressView } from "/static/jobs.js";
import { controllerLabel, STUDY_CONTROLLERS } from "/static/names.js";

const fmt = (x, digits = 2) => (x == null ? "" : Number(x).toFixed(digits));
const fmtP = (p) => (p == null ? "" : p < 0.001 ? p.toExponential(1) : p.toFixed(3));

// One checkbox per controller a study compares, all ticked.
$("#cohort-controllers").replaceChildren(...STUDY_CONTROLLERS.map((name) => h("label", {},
  h("input", { type: "checkbox", name: `c-${name}`, id: `cohort-${name}`, value: name, checked: true }),
  ` ${controllerLabel(name)}`)));

function fill(table, header, rows) {
  table.querySelector("thead").replaceChildren(h("tr", {}, header.map((c) => h("th", {}, c))));
  table.querySelector("tbody").replaceChildren(...rows.map((r) => h("tr", {},
    r.map((c) => h("td", {}, c)))));
}

function n80(c) {
  return c.n_for_power == null ? `>${Math.max(...c.sizes)}` : String(c.n_for_power);
}

function comparisonRow(c) {
  return [c.metric, `${controllerLabel(c.a)} − ${controllerLabel(c.b)}`,
    `${fmt(c.mean_diff)} [${fmt(c.ci_low)}, ${fmt(c.ci_high)}]`, fmtP(c.p_value),
    fmt(c.rank_biserial), n80(c)];
}

function show(cohort) {
  const doc = cohort.result;
  $("#result").hidden = false;
  $("#result").dataset.cohort = cohort.id;
  $("#result-title").textContent = `${cohort.name} · ${doc.participants.length} participants` +
    (cohort.wall_s != null ? ` · ${cohort.wall_s} s` : "");
  $("#result-caveat").textContent = doc.caveat;
  const header = ["metric", "comparison", "mean difference [95 % CI]", "p (Wilcoxon)",
    "rank-biserial", "n for 80 % power"];
  const main = doc.main_comparisons.map(([m, a, b]) => doc.comparisons.find(
    (c) => c.metric === m && c.a === a && c.b === b)).filter(Boolean);
  fill($("#main-comparisons"), header, main.map(comparisonRow));
  fill($("#comparisons"), header, doc.comparisons.map(comparisonRow));
  const units = Object.fromEntries(doc.metrics.map((m) => [m.name, m.unit]));
  fill($("#summaries"), ["metric", "unit", "controller", "n", "mean", "95 % CI", "SD", "median"],
    doc.summaries.map((s) => [s.metric, units[s.metric], controllerLabel(s.controller), String(s.n),
      fmt(s.mean), `[${fmt(s.ci_low)}, ${fmt(s.ci_high)}]`, fmt(s.sd), fmt(s.median)]));
  const figure = (name, kind) => api.cohorts.cohortFigure.url(cohort.id, name, kind);
  $("#power-figure").src = figure("power", "svg");
  $("#distributions-figure").src = figure("distributions", "svg");
  $("#downloads").replaceChildren("Download: ", ...["participants", "metrics", "comparisons",
    "power"].flatMap((t) => [h("a", { href: api.cohorts.cohortTable.url(cohort.id, t, "csv") }, `${t}.csv`), " "]),
    h("a", { href: figure("power", "png") }, "power.png"));
  document.body.dataset.shown = String(cohort.id);
}

async function open(id) {
  const cohort = await api.cohorts.get(id);
  if (cohort.status === "ready") show(cohort);
  else if (cohort.status === "failed") $("#cohort-msg").textContent = cohort.error;
}

async function load() {
  const rows = await api.cohorts.list();
  $("#cohorts tbody").replaceChildren(...rows.map((c) => h("tr", { "data-cohort": c.id },
    h("td", {}, c.status === "ready"
      ? h("a", { href: `#${c.id}`, onclick: () => open(c.id).catch(showFatal) }, c.name)
      : c.name),
    h("td", {}, c.status), h("td", {}, c.wall_s != null ? `${c.wall_s} s` : ""),
    h("td", {}, fmtDate(c.created_at)))));
  $("#cohorts-empty").hidden = rows.length > 0;
  document.body.dataset.ready = "true";
}

$("#cohort-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#cohort-run"), $("#cohort-msg"), async () => {
    const controllers = [...document.querySelectorAll("#cohort-controllers input:checked")]
      .map((box) => box.value);
    const rate = $("#cohort-rate").value;
    const cohort = await api.cohorts.start({
      participants: Number($("#cohort-participants").value),
      seed: Number($("#cohort-seed").value), controllers,
      rate_hz: rate === "" ? null : Number(rate),
    });
    const bar = $("#cohort-progress");
    bar.hidden = false;
    const view = progressView(bar, $("#cohort-progress-text"));
    // A cohort belongs to no study: its progress comes with the cohort itself.
    for (;;) {
      const c = await api.cohorts.get(cohort.id);
      view({ status: c.status, progress: c.progress ?? 0, message: c.error });
      if (c.status === "failed") throw new Error(c.error || "the cohort failed");
      if (c.status === "ready") break;
      await new Promise((r) => setTimeout(r, 300));
    }
    await open(cohort.id);
    await load();
    return `cohort ${cohort.id} ready`;
  });
});

load().then(() => {
  const id = Number(location.hash.slice(1));
  if (id) return open(id);
  return null;
}).catch(showFatal);

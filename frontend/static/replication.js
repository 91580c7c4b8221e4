// The replication report: start one as a background job, follow it, show the newest
// report's claims (everything from api.replication.latest).
import * as api from "/static/api_client.js";
import { $, act, h, showFatal } from "/static/dom.js";
import { progressView } from "/static/jobs.js";

const num = (x) => (x == null ? "n/a" : Number(x).toPrecision(3));

function paperCell(c) {
  if (c.kind === "ordinal") return `${c.paper == null ? "" : `paper ${num(c.paper)}; `}direction`;
  return c.paper == null ? "" : num(c.paper);
}

function intervalCell(c) {
  const iv = c.interval || {};
  if (iv.mean == null) return "n/a";
  const text = iv.n > 1 ? `${num(iv.mean)} [${num(iv.low)}, ${num(iv.high)}]` : num(iv.mean);
  return `${text} ${c.unit || ""}`;
}

function show(report) {
  $("#rep-result").hidden = report == null;
  $("#rep-empty").hidden = report != null;
  if (report == null) return;
  $("#rep-open").href = api.replication.reportPage.url();
  $("#rep-title").textContent = `Newest report · ${report.folder}` +
    (report.wall_s != null ? ` · ${Math.round(report.wall_s)} s` : "");
  $("#rep-claims tbody").replaceChildren(...report.claims.map((c) => h("tr",
    { "data-verdict": c.verdict },
    h("td", {}, h("b", {}, c.key), h("br"), c.statement), h("td", {}, paperCell(c)),
    h("td", {}, intervalCell(c)),
    h("td", {}, c.unstable ? `${c.verdict}, unstable` : c.verdict), h("td", {}, c.reason))));
}

async function load() {
  const state = await api.replication.latest();
  show(state.report);
  document.body.dataset.ready = "true";
  return state;
}

$("#rep-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#rep-run"), $("#rep-msg"), async () => {
    const started = await api.replication.start({
      seeds: Number($("#rep-seeds").value),
      participants: Number($("#rep-participants").value),
    });
    const bar = $("#rep-progress");
    bar.hidden = false;
    const view = progressView(bar, $("#rep-progress-text"));
    for (;;) {
      const state = await api.replication.latest();
      const job = state.job && state.job.id === started.job_id ? state.job : null;
      if (job) view(job);
      if (job && (job.status === "failed" || job.status === "cancelled")) {
        throw new Error(job.message || `the replication ${job.status}`);
      }
      if (job && job.status === "done") break;
      await new Promise((r) => setTimeout(r, 500));
    }
    await load();
    return `report ${started.folder} ready`;
  });
});

load().catch(showFatal);

// Studies: list them and create one.
import * as api from "/static/api_client.js";
import { $, act, fmtDate, formData, h, showFatal } from "/static/dom.js";

async function load() {
  const studies = await api.studies.list();
  const body = $("#studies tbody");
  body.replaceChildren(...studies.map((s) => h("tr", { "data-study": s.id },
    h("td", {}, h("a", { href: `/console/studies/${s.id}` }, s.name)),
    h("td", {}, s.description || ""),
    h("td", {}, fmtDate(s.created_at)))));
  $("#studies-empty").hidden = studies.length > 0;
  // Usable: the list is drawn and its links work (read by bench/bench_console_load.py).
  document.body.dataset.ready = "true";
  performance.mark("exostudy-ready");
}

$("#study-form").addEventListener("submit", (ev) => {
  ev.preventDefault();
  act($("#study-create"), $("#study-msg"), async () => {
    const s = await api.studies.create(formData(ev.target));
    ev.target.reset();
    location.assign(`/console/studies/${s.id}`);
    return `created ${s.name}`;
  });
});

load().catch(showFatal);

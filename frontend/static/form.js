// The participant's form page: the token in the address is the only credential. It
// shows each form due (blinded labels only), then the preference question.
//
// A participant must not be able to misread a scale: every item shows the scale's
// anchors where the published instrument puts them (the SUS: "Strongly disagree" over
// 1, "Strongly agree" over 5), the page says which form of how many this is, the
// choices are large enough to tap on a tablet, and answers given so far survive a
// reload (kept in this tab's sessionStorage until the form is sent).
import { respond } from "/static/api.js";
import * as api from "/static/api_client.js";

const token = location.pathname.split("/").pop();
const root = document.getElementById("forms");

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
  for (const c of children) node.append(c);
  return node;
}

// The participant has no login: the page reads the answers itself (a 410 is a closed
// link, not a reason to go to the login page).
async function post(url, body) {
  const r = await respond("POST", url, body);
  const data = await r.json().catch(() => ({}));
  if (!r.ok) {
    const d = data.detail;
    throw new Error(Array.isArray(d) ? d.map((e) => `${e.loc.at(-1)}: ${e.msg}`).join("; ") : d);
  }
  return data;
}

// Answers in progress, per form, for this tab only (a shared tablet forgets them when
// the tab closes); cleared once the form is sent.
const draftKey = (index) => `exostudy-form-draft:${token.slice(0, 12)}:${index}`;
function loadDraft(index) {
  try { return JSON.parse(sessionStorage.getItem(draftKey(index)) || "{}"); }
  catch { return {}; }
}
function saveDraft(index, answers) {
  sessionStorage.setItem(draftKey(index), JSON.stringify(answers));
}

function progress(step, total) {
  return el("p", { class: "form-progress", id: "form-progress" }, `Form ${step} of ${total}`);
}

function renderForm(form, step, total) {
  const card = el("form", { class: "card participant-form", "data-form": String(form.index) });
  const about = form.condition_label ? ` (setting ${form.condition_label})` : "";
  card.append(progress(step, total), el("h2", {}, form.title + about),
              el("p", { class: "muted" }, form.instructions));
  const anchors = Object.fromEntries(form.scale.labels.map((l) => [l.value, l.label]));
  const draft = loadDraft(form.index);
  form.items.forEach((item, i) => {
    const group = el("fieldset", { class: "item", "data-item": item.id });
    group.append(el("legend", {}, `${i + 1}. ${item.text}`));
    const scale = el("div", { class: "scale scale-anchored", role: "radiogroup" });
    for (let v = form.scale.min; v <= form.scale.max; v++) {
      const input = el("input", { type: "radio", name: item.id, value: String(v) });
      if (draft[item.id] === v) input.checked = true;
      const anchor = anchors[v] ? el("span", { class: "anchor" }, anchors[v]) : "";
      const choice = el("label", { class: "choice" }, anchor, input,
                        el("span", { class: "value" }, String(v)));
      if (anchors[v]) input.setAttribute("aria-label", `${v}: ${anchors[v]}`);
      scale.append(choice);
    }
    group.append(scale);
    card.append(group);
  });
  card.addEventListener("change", (event) => {
    if (event.target.type !== "radio") return;
    const answers = loadDraft(form.index);
    answers[event.target.name] = Number(event.target.value);
    saveDraft(form.index, answers);
  });
  const msg = el("div", { class: "small", role: "alert" });
  card.append(el("button", { type: "submit", class: "primary send" }, "Send"), msg);
  card.addEventListener("submit", async (event) => {
    event.preventDefault();
    const answers = {};
    for (const item of form.items) {
      const checked = card.querySelector(`input[name="${item.id}"]:checked`);
      answers[item.id] = checked ? Number(checked.value) : null;
    }
    try {
      await post(api.participantForms.submitAnswers.url(token), { form: form.index, answers });
      sessionStorage.removeItem(draftKey(form.index));
      load();
    } catch (err) {
      msg.textContent = err.message;
    }
  });
  return card;
}

function renderPreference(pref, step, total) {
  const card = el("form", { class: "card participant-form", id: "preference" });
  card.append(progress(step, total), el("h2", {}, pref.question));
  const scale = el("div", { class: "scale scale-anchored", role: "radiogroup" });
  for (const c of pref.choices) {
    const label = c === "none" ? "no preference" : `setting ${c}`;
    scale.append(el("label", { class: "choice" },
                    el("input", { type: "radio", name: "choice", value: c }),
                    el("span", { class: "value" }, label)));
  }
  const msg = el("div", { class: "small", role: "alert" });
  card.append(scale, el("button", { type: "submit", class: "primary send" }, "Send"), msg);
  card.addEventListener("submit", async (event) => {
    event.preventDefault();
    const checked = card.querySelector("input[name=choice]:checked");
    if (!checked) { msg.textContent = "please choose one"; return; }
    try { await post(api.participantForms.submitPreference.url(token), { choice: checked.value }); load(); }
    catch (err) { msg.textContent = err.message; }
  });
  return card;
}

async function load() {
  const r = await respond("GET", api.participantForms.get.url(token));
  const data = await r.json().catch(() => ({}));
  root.replaceChildren();
  if (!r.ok) {
    root.append(el("p", { class: "card" }, r.status === 410 ? "Thank you: this link is closed." : String(data.detail)));
    return;
  }
  const pref = data.preference;
  const total = data.forms.length + (pref.due ? 1 : 0);
  const done = data.forms.filter((f) => f.submitted).length;
  const open = data.forms.filter((f) => !f.submitted);
  if (open.length) root.append(renderForm(open[0], done + 1, total));
  else if (pref.due && !pref.submitted) root.append(renderPreference(pref, total, total));
  window.scrollTo(0, 0);
}

load();

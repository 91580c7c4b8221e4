// The participant's form page: the token in the address is the only credential. It
// shows each form due (blinded labels only), then the preference question.
const token = location.pathname.split("/").pop();
const api = `/api/participant-forms/${encodeURIComponent(token)}`;
const root = document.getElementById("forms");

function el(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) node.setAttribute(k, v);
  for (const c of children) node.append(c);
  return node;
}

async function post(path, body) {
  const r = await fetch(api + path, {
    method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body),
  });
  const data = await r.json().catch(() => ({}));
  if (!r.ok) {
    const d = data.detail;
    throw new Error(Array.isArray(d) ? d.map((e) => `${e.loc.at(-1)}: ${e.msg}`).join("; ") : d);
  }
  return data;
}

function renderForm(form) {
  const card = el("form", { class: "card", "data-form": String(form.index) });
  const about = form.condition_label ? ` (setting ${form.condition_label})` : "";
  card.append(el("h2", {}, form.title + about), el("p", { class: "muted small" }, form.instructions));
  const ends = Object.fromEntries(form.scale.labels.map((l) => [l.value, l.label]));
  for (const item of form.items) {
    const scale = el("div", { class: "scale", role: "radiogroup" });
    for (let v = form.scale.min; v <= form.scale.max; v++) {
      const input = el("input", { type: "radio", name: item.id, value: String(v) });
      scale.append(el("label", { title: ends[v] || "" }, input, String(v)));
    }
    card.append(el("div", {}, item.text), scale);
  }
  const msg = el("div", { class: "small", role: "alert" });
  card.append(el("button", { type: "submit" }, "Send"), msg);
  card.addEventListener("submit", async (event) => {
    event.preventDefault();
    const answers = {};
    for (const item of form.items) {
      const checked = card.querySelector(`input[name="${item.id}"]:checked`);
      answers[item.id] = checked ? Number(checked.value) : null;
    }
    try {
      await post("/responses", { form: form.index, answers });
      load();
    } catch (err) {
      msg.textContent = err.message;
    }
  });
  return card;
}

function renderPreference(pref) {
  const card = el("form", { class: "card", id: "preference" });
  card.append(el("h2", {}, pref.question));
  const scale = el("div", { class: "scale" });
  for (const c of pref.choices) {
    const label = c === "none" ? "no preference" : `setting ${c}`;
    scale.append(el("label", {}, el("input", { type: "radio", name: "choice", value: c }), label));
  }
  const msg = el("div", { class: "small", role: "alert" });
  card.append(scale, el("button", { type: "submit" }, "Send"), msg);
  card.addEventListener("submit", async (event) => {
    event.preventDefault();
    const checked = card.querySelector("input[name=choice]:checked");
    if (!checked) { msg.textContent = "please choose one"; return; }
    try { await post("/preference", { choice: checked.value }); load(); }
    catch (err) { msg.textContent = err.message; }
  });
  return card;
}

async function load() {
  const r = await fetch(api);
  const data = await r.json().catch(() => ({}));
  root.replaceChildren();
  if (!r.ok) {
    root.append(el("p", { class: "card" }, r.status === 410 ? "Thank you: this link is closed." : String(data.detail)));
    return;
  }
  const open = data.forms.filter((f) => !f.submitted);
  if (open.length) root.append(renderForm(open[0]));
  else if (data.preference.due && !data.preference.submitted) root.append(renderPreference(data.preference));
}

load();

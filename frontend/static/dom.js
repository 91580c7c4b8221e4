// Small DOM builders and the status line each action reports to.

export function h(tag, attrs = {}, ...children) {
  const node = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (v == null || v === false) continue;
    if (k.startsWith("on")) node.addEventListener(k.slice(2), v);
    else if (k === "dataset") Object.assign(node.dataset, v);
    else if (k === "value") node.value = v;
    else if (k === "checked") node.checked = Boolean(v);
    else node.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) {
    if (c == null || c === false) continue;
    node.append(c instanceof Node ? c : String(c));
  }
  return node;
}

export const $ = (sel, root = document) => root.querySelector(sel);

// Show what an action did (or why it failed) next to it, and keep the button from being
// pressed twice while the request runs. `after` runs last, for buttons whose state
// depends on the outcome (a stop button stays disabled once nothing runs).
export async function act(button, msgEl, fn, after = null) {
  button.disabled = true;
  msgEl.className = "msg";
  msgEl.textContent = "…";
  try {
    const text = await fn();
    msgEl.textContent = text || "done";
    msgEl.classList.add("msg-ok");
  } catch (err) {
    msgEl.textContent = err.message;
    msgEl.classList.add("msg-bad");
  } finally {
    button.disabled = false;
    if (after) after();
  }
}

export function formData(form) {
  const out = {};
  for (const [k, v] of new FormData(form).entries()) {
    const input = form.elements[k];
    if (v === "") continue;
    out[k] = input && input.type === "number" ? Number(v) : v;
  }
  return out;
}

export function fmtDate(s) {
  return s ? new Date(s).toLocaleString() : "–";
}

// A page that cannot load its data says so at the top, instead of staying blank.
export function showFatal(err) {
  const banner = h("div", { class: "card fatal", role: "alert", id: "fatal" },
    h("strong", {}, "This page could not load: "), err.message || String(err));
  document.querySelector("main").prepend(banner);
}

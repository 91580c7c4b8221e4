// How the console talks to the server: JSON in and out, errors as readable text. The
// pages do not call this directly: they call the generated client (api_client.js),
// whose operations are made here, so that no page spells a route of its own.

export class ApiError extends Error {
  constructor(status, message) {
    super(message);
    this.status = status;
  }
}

function describe(detail) {
  if (typeof detail === "string") return detail;
  if (Array.isArray(detail)) {
    return detail.map((d) => `${(d.loc || []).slice(1).join(".")}: ${d.msg}`).join("; ");
  }
  if (detail && typeof detail === "object") return detail.message || JSON.stringify(detail);
  return "request failed";
}

// Methods that change nothing, so they carry no CSRF token.
const SAFE = new Set(["GET", "HEAD", "OPTIONS"]);

// The CSRF token the server set at login (the `exostudy_csrf` cookie); "" without one.
function csrfToken() {
  const m = (globalThis.document?.cookie || "").match(/(?:^|; )exostudy_csrf=([^;]+)/);
  return m ? decodeURIComponent(m[1]) : "";
}

// The pages' one request function: every request of every page is made here, so every
// change (POST, PUT, PATCH, DELETE) carries the CSRF token as the X-CSRF-Token header
// (the server refuses a change made with the session cookie without it, so another site
// cannot act with the cookie). It answers the Response as it came: the pages that read
// every status themselves (the login, the participant's form) call it directly.
export function respond(method, path, body) {
  const init = { method, headers: {} };
  if (body !== undefined) {
    init.headers["Content-Type"] = "application/json";
    init.body = JSON.stringify(body);
  }
  const token = SAFE.has(method) ? "" : csrfToken();
  if (token) init.headers["X-CSRF-Token"] = token;
  return fetch(path, init);
}

// A request; without a login, off to the login page, which brings the user back here.
async function send(method, path, body) {
  const r = await respond(method, path, body);
  if (r.status === 401) {
    location.assign(`/login?next=${encodeURIComponent(location.pathname + location.search)}`);
    throw new ApiError(401, "not logged in");
  }
  return r;
}

export async function request(method, path, body) {
  const r = await send(method, path, body);
  if (r.status === 204) return null;
  const data = await r.json().catch(() => null);
  if (!r.ok) throw new ApiError(r.status, describe(data && data.detail));
  return data;
}

// A text download (CSV): the body as a string.
export async function getText(path) {
  const r = await send("GET", path);
  if (!r.ok) throw new ApiError(r.status, `${path}: ${r.status}`);
  return r.text();
}

// One operation of the generated client. Its arguments: the path parameters in path
// order, then the body if it takes one, then an object of query parameters if it has
// any. A missing path parameter, an extra argument or an unknown query parameter
// throws at once, naming the operation, instead of asking the server for a wrong path.
export function operation(name, method, template, { params = [], query = [], body = false } = {}) {
  const fail = (why) => { throw new Error(`${name}: ${why}`); };
  function address(values, q) {
    let path = template;
    params.forEach((p, i) => {
      const v = values[i];
      if (v === undefined || v === null || v === "") fail(`${p} is missing`);
      path = path.replace(`{${p}}`, encodeURIComponent(String(v)));
    });
    if (q === undefined || q === null) return path;
    if (typeof q !== "object" || Array.isArray(q)) fail("the query parameters must be an object");
    const search = new URLSearchParams();
    for (const [k, v] of Object.entries(q)) {
      if (!query.includes(k)) fail(`no query parameter ${k} (it has: ${query.join(", ") || "none"})`);
      if (v === undefined || v === null) continue;
      for (const one of Array.isArray(v) ? v : [v]) search.append(k, String(one));
    }
    const text = search.toString();
    return text ? `${path}?${text}` : path;
  }
  function split(given, withBody) {
    // Trailing undefined arguments are absent ones (an optional body or query left out).
    const args = [...given];
    while (args.length && args[args.length - 1] === undefined) args.pop();
    const most = params.length + (withBody ? 1 : 0) + (query.length ? 1 : 0);
    if (args.length > most) fail(`takes at most ${most} arguments, got ${args.length}`);
    const rest = args.slice(params.length);
    return {
      path: address(args.slice(0, params.length), rest[withBody ? 1 : 0]),
      payload: withBody ? rest[0] : undefined,
    };
  }
  const call = (...args) => {
    const { path, payload } = split(args, body);
    return request(method, path, payload);
  };
  call.url = (...args) => split(args, false).path;
  call.text = (...args) => getText(split(args, false).path);
  call.method = method;
  call.path = template;
  call.operation = name;
  return Object.freeze(call);
}

// A reader of live WebSocket messages: the JSON text, checked to be a known `type`
// carrying every field its Python model sends (`fields`, generated from the models).
export function messageReader(fields) {
  return (text) => {
    const msg = JSON.parse(text);
    const expected = msg && typeof msg === "object" ? fields[msg.type] : undefined;
    if (!expected) throw new Error(`live message of unknown type ${JSON.stringify(msg && msg.type)}`);
    const missing = expected.filter((f) => !(f in msg));
    if (missing.length) throw new Error(`live ${msg.type} message without ${missing.join(", ")}`);
    return msg;
  };
}

// The generated API client and the operations api.js makes of it: the address each
// call asks, what it sends, and what a wrong call does (it throws before any request).
import assert from "node:assert/strict";
import { beforeEach, test } from "node:test";
import * as api from "/static/api_client.js";
import { ApiError, respond } from "/static/api.js";

let calls = [];
let answers = [];
const assigned = [];

globalThis.location = {
  pathname: "/console/sessions/4", search: "?x=1",
  assign: (url) => assigned.push(url),
};
globalThis.fetch = async (path, init) => {
  calls.push({ path, init });
  return answers.shift() || new Response("{}", { status: 200 });
};
const json = (data, status = 200) => new Response(JSON.stringify(data),
  { status, headers: { "Content-Type": "application/json" } });

beforeEach(() => { calls = []; answers = []; });

// Every operation of the client: [namespace, name, operation].
const OPERATIONS = Object.entries(api)
  .filter(([, v]) => v && typeof v === "object" && !Array.isArray(v))
  .flatMap(([ns, ops]) => Object.entries(ops)
    .filter(([, op]) => typeof op === "function")
    .map(([name, op]) => [ns, name, op]));

test("every operation is named after its namespace and builds its own path", () => {
  assert.ok(OPERATIONS.length > 100, `${OPERATIONS.length} operations`);
  for (const [ns, name, op] of OPERATIONS) {
    assert.equal(op.operation, `${ns}.${name}`);
    assert.match(op.method, /^(GET|POST|PUT|PATCH|DELETE)$/);
    assert.ok(op.path.startsWith("/api/"), op.path);
    const params = [...op.path.matchAll(/{([^}]+)}/g)].map((m) => m[1]);
    const expected = params.reduce((p, name_, i) => p.replace(`{${name_}}`, `v${i}`), op.path);
    assert.equal(op.url(...params.map((_, i) => `v${i}`)), expected);
  }
});

test("a call sends the method, the path with its parameters, and the JSON body", async () => {
  answers.push(json({ id: 7, status: "running" }));
  const out = await api.trials.start(7, { note: "x" });
  assert.deepEqual(out, { id: 7, status: "running" });
  assert.equal(calls.length, 1);
  assert.equal(calls[0].path, "/api/trials/7/start");
  assert.equal(calls[0].init.method, "POST");
  assert.equal(calls[0].init.body, JSON.stringify({ note: "x" }));
  assert.equal(calls[0].init.headers["Content-Type"], "application/json");

  await api.worker.restart();
  assert.equal(calls[1].path, "/api/worker/restart");
  assert.equal(calls[1].init.body, undefined);
});

test("path parameters are encoded and query parameters are the operation's own", () => {
  assert.equal(api.participantForms.get.url("a/b c?"), "/api/participant-forms/a%2Fb%20c%3F");
  assert.equal(api.results.studyTable.url(3, "lifts", "csv"), "/api/studies/3/results/lifts.csv");
  assert.equal(api.results.modelEvaluation.url(3, { model_set_id: 5, rate_hz: null }),
    "/api/studies/3/model-evaluation?model_set_id=5");
  assert.equal(api.recordings.autoSegment.url(9, {}), "/api/recordings/9/segment");
  assert.equal(api.recordings.autoSegment.url(9, { replace: true }),
    "/api/recordings/9/segment?replace=true");
  assert.equal(api.audit.list.url({ entity: "trial", limit: 5 }), "/api/audit?entity=trial&limit=5");
});

test("a wrong call throws, naming the operation, and asks nothing of the server", () => {
  assert.throws(() => api.trials.start(undefined, {}), /trials\.start: trial_id is missing/);
  assert.throws(() => api.trials.get(""), /trials\.get: trial_id is missing/);
  assert.throws(() => api.trials.get(1, 2), /trials\.get: takes at most 1 arguments, got 2/);
  assert.throws(() => api.results.modelEvaluation.url(3, { model: 5 }),
    /results\.modelEvaluation: no query parameter model \(it has: model_set_id, utility_set_id, rate_hz\)/);
  assert.throws(() => api.results.modelEvaluation.url(3, 5), /must be an object/);
  assert.equal(calls.length, 0);
});

test("refusals become ApiError with the server's reason; 204 is null", async () => {
  answers.push(json({ detail: [{ loc: ["body", "name"], msg: "Field required" }] }, 422));
  await assert.rejects(api.studies.create({}), (err) => err instanceof ApiError &&
    err.status === 422 && err.message === "name: Field required");
  answers.push(json({ detail: "no such trial" }, 404));
  await assert.rejects(api.trials.get(5), { status: 404, message: "no such trial" });
  answers.push(new Response(null, { status: 204 }));
  assert.equal(await api.auth.changePassword({}), null);
});

test("without a login the page goes to the login page and comes back", async () => {
  answers.push(json({ detail: "not logged in" }, 401));
  await assert.rejects(api.studies.list(), { status: 401 });
  assert.equal(assigned.at(-1), `/login?next=${encodeURIComponent("/console/sessions/4?x=1")}`);
});

test("a text answer is read as text", async () => {
  answers.push(new Response("a,b\n1,2\n", { status: 200 }));
  assert.equal(await api.results.studyTable.text(3, "lifts", "csv"), "a,b\n1,2\n");
  assert.equal(calls[0].path, "/api/studies/3/results/lifts.csv");
});

test("a change carries the login's CSRF token as X-CSRF-Token; a read does not", async () => {
  globalThis.document = { cookie: "other=1; exostudy_csrf=t%2Fk; x=2" };
  try {
    await api.trials.start(7, { note: "x" });
    await api.studies.list();
    await api.worker.restart();
    assert.equal(calls[0].init.headers["X-CSRF-Token"], "t/k");
    assert.equal(calls[1].init.method, "GET");
    assert.equal(calls[1].init.headers["X-CSRF-Token"], undefined);
    assert.equal(calls[2].init.headers["X-CSRF-Token"], "t/k");
    globalThis.document = { cookie: "" };  // no login yet (the login page): no header
    await respond("POST", api.auth.login.url(), { username: "a" });
    assert.equal(calls[3].init.headers["X-CSRF-Token"], undefined);
    assert.equal(calls[3].init.body, JSON.stringify({ username: "a" }));
  } finally {
    delete globalThis.document;
  }
});

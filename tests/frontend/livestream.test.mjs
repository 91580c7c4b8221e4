// The live page's reader of WebSocket messages, fed what the server sends: a ticks
// message written by backend/live/stream.py, status and marker messages dumped from
// their pydantic models (EXOSTUDY_LIVE_MESSAGES, written by test_javascript.py).
import assert from "node:assert/strict";
import { readFileSync } from "node:fs";
import { test } from "node:test";
import { LIVE_MESSAGES, readLiveMessage } from "/static/api_client.js";
import { connectLive } from "/static/livestream.js";

const file = process.env.EXOSTUDY_LIVE_MESSAGES;
if (!file) throw new Error("EXOSTUDY_LIVE_MESSAGES: the messages' file is not set");
const TEXTS = JSON.parse(readFileSync(file, "utf8"));
const byType = Object.fromEntries(TEXTS.map((t) => [JSON.parse(t).type, t]));

test("the server's messages are one of each type the client knows, and read back", () => {
  assert.deepEqual(Object.keys(byType).sort(), Object.keys(LIVE_MESSAGES).sort());
  assert.deepEqual(Object.keys(byType).sort(), ["emg", "marker", "status", "ticks"]);
  for (const text of TEXTS) assert.deepEqual(readLiveMessage(text), JSON.parse(text));
  // Every field the reader expects is one the server wrote, and the reverse.
  for (const [type, text] of Object.entries(byType)) {
    assert.deepEqual(Object.keys(JSON.parse(text)).sort(), [...LIVE_MESSAGES[type]].sort());
  }
});

test("a message without a field of its model, or of no known type, throws", () => {
  for (const [type, text] of Object.entries(byType)) {
    for (const field of LIVE_MESSAGES[type].filter((f) => f !== "type")) {
      const msg = JSON.parse(text);
      delete msg[field];
      assert.throws(() => readLiveMessage(JSON.stringify(msg)),
        new RegExp(`live ${type} message without ${field}`));
    }
  }
  assert.throws(() => readLiveMessage('{"type":"tick"}'), /unknown type "tick"/);
  assert.throws(() => readLiveMessage("3"), /unknown type/);
  assert.throws(() => readLiveMessage("null"), /unknown type/);
});

test("connectLive opens the live socket and hands each message to its callback", () => {
  const sockets = [];
  globalThis.location = { protocol: "http:", host: "lab:8000" };
  globalThis.WebSocket = class {
    constructor(url) { this.url = url; sockets.push(this); }
    close() {}
  };
  const got = { ticks: [], status: [], marker: [], emg: [] };
  const live = connectLive({
    onTicks: (m) => got.ticks.push(m), onStatus: (h) => got.status.push(h),
    onMarker: (m) => got.marker.push(m), onEmg: (m) => got.emg.push(m),
  });
  assert.equal(sockets.length, 1);
  assert.equal(sockets[0].url, "ws://lab:8000/ws/live");
  const ticks = JSON.parse(byType.ticks);
  const n = ticks.columns.t.length;
  sockets[0].onmessage({ data: byType.ticks });
  sockets[0].onmessage({ data: byType.status });
  sockets[0].onmessage({ data: byType.marker });
  sockets[0].onmessage({ data: byType.emg });
  // Two messages lost in between: the page counts the gap.
  sockets[0].onmessage({ data: JSON.stringify({ ...ticks, msg_seq: ticks.msg_seq + 3 }) });
  assert.equal(got.ticks.length, 2);
  assert.deepEqual(got.status, [JSON.parse(byType.status).health]);
  assert.deepEqual(got.marker, [JSON.parse(byType.marker).marker]);
  assert.deepEqual(got.emg, [JSON.parse(byType.emg)]);
  assert.deepEqual(live.counts, { messages: 2, samples: 2 * n, gaps: 2, dropped: ticks.dropped });
  live.close();
});

// The live WebSocket for any page: reconnects, counts messages, gaps and drops. Its
// path and message types come from the generated client (api_client.js), from the
// Python models backend/schemas/live.py (LiveTicks, LiveStatus) and
// backend/schemas/lab.py (LiveMarker), LiveEmg for the EMG strip; a message missing a
// field of its model throws.
import { readLiveMessage, sockets } from "/static/api_client.js";

export function connectLive({ onTicks, onStatus, onState, onMarker, onEmg }) {
  const counts = { messages: 0, samples: 0, gaps: 0, dropped: 0 };
  let lastSeq = 0;
  let retryMs = 500;
  let closed = false;
  let ws = null;

  function open() {
    const proto = location.protocol === "https:" ? "wss:" : "ws:";
    ws = new WebSocket(`${proto}//${location.host}${sockets.live}`);
    ws.onopen = () => { retryMs = 500; onState && onState("live"); };
    ws.onmessage = (ev) => {
      const msg = readLiveMessage(ev.data);
      if (msg.type === "ticks") {
        counts.messages += 1;
        counts.samples += msg.columns.t.length;
        if (lastSeq && msg.msg_seq !== lastSeq + 1) counts.gaps += msg.msg_seq - lastSeq - 1;
        lastSeq = msg.msg_seq;
        counts.dropped = msg.dropped;
        onTicks && onTicks(msg);
      } else if (msg.type === "status") {
        onStatus && onStatus(msg.health);
      } else if (msg.type === "marker") {
        onMarker && onMarker(msg.marker);
      } else if (msg.type === "emg") {
        onEmg && onEmg(msg);
      }
    };
    ws.onclose = () => {
      lastSeq = 0;
      if (closed) return;
      onState && onState("down", retryMs);
      setTimeout(open, retryMs);
      retryMs = Math.min(retryMs * 2, 5000);
    };
  }
  open();
  return { counts, close() { closed = true; ws && ws.close(); } };
}

// A fixed-length window of columns, newest last.
export class Ring {
  constructor(names, capacity) {
    this.names = names;
    this.capacity = capacity;
    this.cols = Object.fromEntries(names.map((n) => [n, []]));
  }
  push(columns, map = (name, v) => v) {
    const n = columns.t.length;
    for (const name of this.names) {
      const src = columns[name];
      const dst = this.cols[name];
      for (let i = 0; i < n; i++) dst.push(map(name, src ? src[i] : null));
      if (dst.length > this.capacity) dst.splice(0, dst.length - this.capacity);
    }
  }
  resize(capacity) {
    this.capacity = capacity;
    for (const dst of Object.values(this.cols)) {
      if (dst.length > capacity) dst.splice(0, dst.length - capacity);
    }
  }
  get length() { return this.cols.t ? this.cols.t.length : 0; }
}

// Connect to a live Foxglove WebSocket server (`euc-ros view`) with Foxglove's own client and print JSON.
//
//   node view_client.mjs URL SECONDS [SUBPROTOCOL]
//
// @foxglove/ws-protocol's FoxgloveClient over the `ws` package, offering SUBPROTOCOL (default
// foxglove.sdk.v1, the one foxglove-sdk servers accept). Subscribes to every channel the server
// advertises, for SECONDS from the moment the connection opens, and decodes every message with
// @foxglove/rosmsg2-serialization from the channel's ros2msg schema (parsed by @foxglove/rosmsg).
// Output, per topic: the channel's encodings and schema name, the message count, decode failures, the
// most bytes a message had after its last field, the span of receive times [s] and the rate over it
// (the client's clock, and the server's log times), and one decoded message (the first); then the
// server's name and capabilities and any problem (bigint as string, typed arrays as arrays).
import { performance } from "node:perf_hooks";

import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import wsProtocol from "@foxglove/ws-protocol"; // CommonJS: named exports through the default
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;
const [url, secondsText, subprotocol = "foxglove.sdk.v1"] = process.argv.slice(2);
const seconds = Number(secondsText);
if (!url || !(seconds > 0)) {
  console.error("usage: node view_client.mjs URL SECONDS [SUBPROTOCOL]");
  process.exit(2);
}

const ws = new WebSocket(url, [subprotocol]);
const client = new FoxgloveClient({ ws });
const channels = new Map(); // channel id -> per-topic record
const bySubscription = new Map(); // subscription id -> record
const problems = [];
let serverInfo = null;
let closedEarly = null;

function record(channel) {
  const out = {
    topic: channel.topic,
    encoding: channel.encoding,
    schemaName: channel.schemaName,
    schemaEncoding: channel.schemaEncoding ?? null,
    count: 0,
    failures: 0,
    trailing: 0,
    first_s: null,
    last_s: null,
    first_log_ns: null,
    last_log_ns: null,
    sample: null,
  };
  if (channel.encoding === "cdr" && channel.schemaEncoding === "ros2msg") {
    try {
      out.reader = new MessageReader(parse(channel.schema, { ros2: true }));
    } catch (err) {
      problems.push(`${channel.topic}: schema does not parse: ${err.message}`);
    }
  } else {
    problems.push(`${channel.topic}: ${channel.schemaEncoding}/${channel.encoding} is not ros2msg/cdr`);
  }
  return out;
}

client.on("serverInfo", (info) => {
  serverInfo = { name: info.name, capabilities: info.capabilities, sessionId: info.sessionId ?? null };
});
client.on("advertise", (advertised) => {
  for (const channel of advertised) {
    const rec = record(channel);
    channels.set(channel.id, rec);
    bySubscription.set(client.subscribe(channel.id), rec);
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const now = performance.now() / 1000;
  const rec = bySubscription.get(subscriptionId);
  if (!rec) return;
  rec.count += 1;
  rec.first_s ??= now;
  rec.last_s = now;
  rec.first_log_ns ??= timestamp;
  rec.last_log_ns = timestamp;
  if (!rec.reader) return;
  try {
    const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
    const decoded = rec.reader.readMessage(bytes);
    if (rec.reader.lastReadHadTrailingBytes()) {
      rec.trailing = Math.max(rec.trailing, bytes.byteLength - rec.reader.lastReadByteLength());
    }
    rec.sample ??= decoded;
  } catch (err) {
    rec.failures += 1;
    if (problems.length < 20) problems.push(`${rec.topic}: ${err.message}`);
  }
});
client.on("error", (err) => problems.push(`client error: ${err?.message ?? err}`));
client.on("close", (event) => {
  closedEarly ??= `connection closed (code ${event?.code ?? "?"})`;
});

const opened = await new Promise((resolve) => {
  const timer = setTimeout(() => resolve(false), 10000);
  ws.on("open", () => {
    clearTimeout(timer);
    resolve(true);
  });
  ws.on("error", (err) => {
    clearTimeout(timer);
    problems.push(`cannot connect to ${url}: ${err.message}`);
    resolve(false);
  });
});
if (!opened) {
  console.error(problems.join("\n") || `no connection to ${url} within 10 s`);
  process.exit(1);
}
await new Promise((resolve) => setTimeout(resolve, seconds * 1000));
const stillOpen = closedEarly === null;
client.close();

const topics = {};
for (const rec of channels.values()) {
  const { reader, ...out } = rec;
  const span = out.count > 1 ? out.last_s - out.first_s : 0;
  const logSpan = out.count > 1 ? Number(out.last_log_ns - out.first_log_ns) * 1e-9 : 0;
  out.span_s = span;
  out.rate_hz = span > 0 ? (out.count - 1) / span : null;
  out.log_rate_hz = logSpan > 0 ? (out.count - 1) / logSpan : null;
  topics[out.topic] = out;
}
if (!stillOpen) problems.push(closedEarly);
const json = JSON.stringify(
  { url, subprotocol: ws.protocol, serverInfo, topics, problems },
  (_key, value) => (typeof value === "bigint" ? value.toString() : ArrayBuffer.isView(value) ? Array.from(value) : value),
);
process.stdout.write(json + "\n");
process.exit(0);

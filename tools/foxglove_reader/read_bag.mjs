// Read an MCAP file with Foxglove's own libraries, as Foxglove Studio / Lichtblick do, and print JSON.
//
//   node read_bag.mjs FILE.mcap [TOPIC ...]
//
// @mcap/core's indexed reader (summary, chunk indexes) over @mcap/nodejs's file handle, with
// @mcap/support's decompressors; every message decoded by @foxglove/rosmsg2-serialization from the
// ros2msg schema embedded in the file (parsed by @foxglove/rosmsg). Output: per-topic message counts,
// the summary's statistics, decode failures, messages whose CDR has bytes the schema does not
// account for (the most bytes left after the last field, per topic), and every message of the TOPICs given (as JSON; bigint as string).
import { open } from "node:fs/promises";

import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { McapIndexedReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { loadDecompressHandlers } from "@mcap/support";

const [file, ...dumpTopics] = process.argv.slice(2);
if (!file) {
  console.error("usage: node read_bag.mjs FILE.mcap [TOPIC ...]");
  process.exit(2);
}

const handle = await open(file, "r");
const reader = await McapIndexedReader.Initialize({
  readable: new FileHandleReadable(handle),
  decompressHandlers: await loadDecompressHandlers(),
});

const readers = new Map(); // channel id -> MessageReader
const problems = [];
for (const [id, channel] of reader.channelsById) {
  const schema = reader.schemasById.get(channel.schemaId);
  if (!schema || schema.encoding !== "ros2msg" || channel.messageEncoding !== "cdr") {
    problems.push(`${channel.topic}: schema ${schema?.encoding}/${channel.messageEncoding} is not ros2msg/cdr`);
    continue;
  }
  const text = new TextDecoder().decode(schema.data);
  readers.set(id, new MessageReader(parse(text, { ros2: true })));
}

const counts = {};
const trailing = {};
const dumped = {};
let failures = 0;
for await (const message of reader.readMessages()) {
  const channel = reader.channelsById.get(message.channelId);
  const topic = channel.topic;
  counts[topic] = (counts[topic] ?? 0) + 1;
  const messageReader = readers.get(message.channelId);
  if (!messageReader) continue;
  try {
    const decoded = messageReader.readMessage(message.data);
    if (messageReader.lastReadHadTrailingBytes()) {
      // bytes after the last field: CDR end padding (< 8 bytes) is normal, more means a schema mismatch
      const left = message.data.byteLength - messageReader.lastReadByteLength();
      trailing[topic] = Math.max(trailing[topic] ?? 0, left);
    }
    if (dumpTopics.includes(topic)) (dumped[topic] ??= []).push(decoded);
  } catch (err) {
    failures += 1;
    if (problems.length < 20) problems.push(`${topic} at ${message.logTime}: ${err.message}`);
  }
}
await handle.close();

const statistics = reader.statistics
  ? {
      messageCount: reader.statistics.messageCount,
      channelMessageCounts: Object.fromEntries(
        [...reader.statistics.channelMessageCounts].map(([id, n]) => [reader.channelsById.get(id).topic, n]),
      ),
    }
  : null;
const json = JSON.stringify(
  { counts, statistics, failures, trailing, problems, messages: dumped },
  (_key, value) => (typeof value === "bigint" ? value.toString() : ArrayBuffer.isView(value) ? Array.from(value) : value),
);
process.stdout.write(json + "\n");

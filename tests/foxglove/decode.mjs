// Decode every message of a rosbag2 bag the way Foxglove does, and print it as JSON lines.
//
//   node decode.mjs <bag directory | .mcap | .db3> ...
//
// MCAP: @mcap/core's indexed reader (its stream reader for a file without a summary), chunk
// decompression from @mcap/support (zstd, lz4, bz2: what Foxglove loads), each channel's
// `ros2msg` schema parsed by @foxglove/rosmsg and its CDR messages read by
// @foxglove/rosmsg2-serialization's MessageReader: Foxglove's own path for ROS 2 MCAP files.
// sqlite3 (.db3): Foxglove's reader of those files (@foxglove/rosbag2-web over sql.js) gives the
// topics and raw rows; Foxglove decodes them with its built-in definitions of the common ROS 2
// types only, so the definitions come from the bag's `message_definitions` table here (rosbag2
// >= Iron writes it), decoded by the same MessageReader.
//
// One line per message, in each file's storage order:
//   {"file": "...", "topic": "/x", "type": "pkg/msg/T", "log_time": "<ns>", "message": {...}}
// JSON cannot hold every value a message can, so: 64-bit integers (BigInt) are written as
// {"$int": "<decimal>"}, non-finite floats as {"$float": "nan" | "inf" | "-inf"}, typed arrays as
// plain arrays. Floats are JavaScript numbers (float32 fields widened exactly), printed in the
// shortest form that reads back to the same double. Exit code 1 with a message on any failure.
import { readdirSync, readFileSync, statSync } from "node:fs";
import { open } from "node:fs/promises";
import { createRequire } from "node:module";
import { basename, join } from "node:path";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";
import { parse as parseMessageDefinition } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { SqliteSqljs } from "@foxglove/rosbag2-web";

function plain(value) {
  if (typeof value === "bigint") return { $int: value.toString() };
  if (typeof value === "number") {
    if (Number.isNaN(value)) return { $float: "nan" };
    if (!Number.isFinite(value)) return { $float: value > 0 ? "inf" : "-inf" };
    return value;
  }
  if (ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (Array.isArray(value)) return value.map(plain);
  if (value !== null && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, plain(v)]));
  }
  return value;
}

function emit(file, topic, type, logTime, message) {
  const line = { file, topic, type, log_time: logTime.toString(), message: plain(message) };
  process.stdout.write(JSON.stringify(line) + "\n");
}

// What Foxglove does with a channel whose schema encoding is ros2msg.
function ros2msgReader(schemaName, schemaText) {
  return new MessageReader(parseMessageDefinition(schemaText, { ros2: true }));
}

async function decodeMcap(path) {
  const decompressHandlers = await loadDecompressHandlers();
  const handle = await open(path, "r");
  const size = BigInt((await handle.stat()).size);
  const readable = {
    size: async () => size,
    read: async (offset, length) => {
      const buffer = new Uint8Array(Number(length));
      const { bytesRead } = await handle.read(buffer, 0, Number(length), Number(offset));
      if (bytesRead !== Number(length)) throw new Error(`${path}: short read at ${offset}`);
      return buffer;
    },
  };
  const readers = new Map(); // channel id -> MessageReader
  const name = basename(path);
  const decode = (channel, schema, logTime, data) => {
    if (schema === undefined) throw new Error(`${path}: channel ${channel.topic} has no schema`);
    if (channel.messageEncoding !== "cdr" || schema.encoding !== "ros2msg") {
      throw new Error(`${path}: ${channel.topic}: ${channel.messageEncoding}/${schema.encoding}, not cdr/ros2msg`);
    }
    let reader = readers.get(channel.id);
    if (reader === undefined) {
      reader = ros2msgReader(schema.name, new TextDecoder().decode(schema.data));
      readers.set(channel.id, reader);
    }
    emit(name, channel.topic, schema.name, logTime, reader.readMessage(data));
  };
  try {
    let indexed;
    try {
      indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    } catch {
      indexed = undefined; // no summary (a recorder killed): read it as a stream, as Foxglove does
    }
    if (indexed !== undefined) {
      for await (const message of indexed.readMessages()) {
        const channel = indexed.channelsById.get(message.channelId);
        decode(channel, indexed.schemasById.get(channel.schemaId), message.logTime, message.data);
      }
      return;
    }
  } finally {
    await handle.close();
  }
  const stream = new McapStreamReader({ decompressHandlers });
  stream.append(readFileSync(path));
  const schemas = new Map();
  const channels = new Map();
  for (let record; (record = stream.nextRecord()) !== undefined; ) {
    if (record.type === "Schema") schemas.set(record.id, record);
    else if (record.type === "Channel") channels.set(record.id, record);
    else if (record.type === "Message") {
      const channel = channels.get(record.channelId);
      decode(channel, schemas.get(channel.schemaId), record.logTime, record.data);
    }
  }
}

async function decodeDb3(path) {
  // sql.js finds its WebAssembly by URL in a browser; under Node it is handed the bytes.
  const wasm = createRequire(import.meta.url).resolve("@foxglove/sql.js/dist/sql-wasm.wasm");
  await SqliteSqljs.Initialize({ wasmBinary: readFileSync(wasm) });
  const bytes = new Uint8Array(readFileSync(path));
  const db = new SqliteSqljs(bytes);
  await db.open();
  const definitions = new Map();
  const tables = db.context.db.exec("select name from sqlite_master where type='table'")[0]?.values ?? [];
  if (tables.some(([table]) => table === "message_definitions")) {
    const rows = db.context.db.exec(
      "select topic_type, encoding, encoded_message_definition from message_definitions")[0]?.values ?? [];
    for (const [type, encoding, text] of rows) {
      if (encoding !== "ros2msg") throw new Error(`${path}: ${type}: definition encoding ${encoding}`);
      definitions.set(type, ros2msgReader(type, text));
    }
  }
  const name = basename(path);
  try {
    for await (const raw of db.readMessages({})) {
      const reader = definitions.get(raw.topic.type);
      if (reader === undefined) throw new Error(`${path}: no definition of ${raw.topic.type} in the bag`);
      const ns = BigInt(raw.timestamp.sec) * 1000000000n + BigInt(raw.timestamp.nsec);
      emit(name, raw.topic.name, raw.topic.type, ns, reader.readMessage(raw.data));
    }
  } finally {
    await db.close();
  }
}

function storageFiles(path) {
  if (!statSync(path).isDirectory()) return [path];
  // <bag>_0, <bag>_1, ..., <bag>_10: split order, as rosbag2 names them
  const key = (f) => Number((/_(\d+)\.(mcap|db3)$/.exec(f) ?? [0, -1])[1]);
  return readdirSync(path)
    .filter((f) => f.endsWith(".mcap") || f.endsWith(".db3"))
    .sort((a, b) => key(a) - key(b) || a.localeCompare(b))
    .map((f) => join(path, f));
}

async function main(paths) {
  if (paths.length === 0) throw new Error("usage: node decode.mjs <bag directory | .mcap | .db3> ...");
  for (const path of paths) {
    const files = storageFiles(path);
    if (files.length === 0) throw new Error(`${path}: no .mcap or .db3 storage file`);
    for (const file of files) {
      await (file.endsWith(".db3") ? decodeDb3(file) : decodeMcap(file));
    }
  }
}

main(process.argv.slice(2)).catch((error) => {
  process.stderr.write(`decode.mjs: ${error?.stack ?? error}\n`);
  process.exit(1);
});

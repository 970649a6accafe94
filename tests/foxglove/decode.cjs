// Read an MCAP file as Foxglove does: Foxglove's MCAP reader (@mcap/core), each channel's
// schema parsed from the text the file itself carries (@foxglove/rosmsg, ROS 2 msg syntax), each
// message decoded from CDR by @foxglove/rosmsg2-serialization. Nothing of kilobot_twin is used.
// Prints one JSON line per message: topic, log time (ns, as a string), the bytes left after the
// decoded message, the message (64-bit integers as strings, byte arrays as lists, NaN as null).
//   NODE_PATH=<folder with node_modules> node decode.cjs FILE.mcap
"use strict";
const { readFileSync } = require("node:fs");
const { McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const { decompress } = require("fzstd");

const reader = new McapStreamReader({
  decompressHandlers: { zstd: (data, size) => decompress(data, new Uint8Array(Number(size))) },
});
reader.append(readFileSync(process.argv[2]));
const schemas = new Map(), channels = new Map(), decoders = new Map();
const plain = (_k, v) => (typeof v === "bigint" ? v.toString() : ArrayBuffer.isView(v) ? Array.from(v) : v);
const out = [];
let rec;
while ((rec = reader.nextRecord())) {
  if (rec.type === "Schema") schemas.set(rec.id, rec);
  else if (rec.type === "Channel") channels.set(rec.id, rec);
  else if (rec.type === "Message") {
    const ch = channels.get(rec.channelId);
    let dec = decoders.get(ch.schemaId);
    if (dec === undefined) {
      const sc = schemas.get(ch.schemaId);
      if (sc.encoding !== "ros2msg" || ch.messageEncoding !== "cdr")
        throw new Error(`${ch.topic}: schema ${sc.encoding}, messages ${ch.messageEncoding}`);
      dec = new MessageReader(parse(new TextDecoder().decode(sc.data), { ros2: true }));
      decoders.set(ch.schemaId, dec);
    }
    const msg = dec.readMessage(rec.data);
    out.push(JSON.stringify({ topic: ch.topic, log_time: rec.logTime.toString(),
                              trailing: rec.data.byteLength - dec.lastReadByteLength(), msg }, plain));
  }
}
if (!reader.done()) throw new Error("the file ended before its footer");
process.stdout.write(out.join("\n") + "\n");

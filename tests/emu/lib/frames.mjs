// Just enough of the wire format (protocol/src/frame.rs) for the tests to pick frames out of
// the host's byte stream and to forge one the firmware must refuse, written from the format's
// description rather than shared with the Rust code, so it also checks that description:
//   0x00 | COBS( postcard(message) ++ CRC-32/ISO-HDLC(postcard(message)) LE ) | 0x00
// A Request is postcard { seq: u16 varint, command: enum (variant index varint, fields) }.

import zlib from 'node:zlib';

/** Variant indices of protocol::Command, in declaration order. */
export const COMMAND = { GetInfo: 0, Configure: 1, Start: 2, Stop: 3, Ping: 4, GetStatus: 5 };

export function cobsEncode(bytes) {
  const out = [0];
  let codeAt = 0;
  let code = 1;
  for (const b of bytes) {
    if (b === 0) {
      out[codeAt] = code;
      codeAt = out.length;
      out.push(0);
      code = 1;
      continue;
    }
    out.push(b);
    code++;
    if (code === 0xff) {
      out[codeAt] = code;
      codeAt = out.length;
      out.push(0);
      code = 1;
    }
  }
  out[codeAt] = code;
  return out;
}

export function cobsDecode(bytes) {
  const out = [];
  let i = 0;
  while (i < bytes.length) {
    const code = bytes[i++];
    if (code === 0 || i + code - 1 > bytes.length) return null;
    for (let k = 1; k < code; k++) out.push(bytes[i++]);
    if (code < 0xff && i < bytes.length) out.push(0);
  }
  return out;
}

export function varint(n) {
  const out = [];
  do {
    let b = n & 0x7f;
    n >>>= 7;
    if (n) b |= 0x80;
    out.push(b);
  } while (n);
  return out;
}

function readVarint(bytes, at) {
  let value = 0;
  let shift = 0;
  for (;;) {
    const b = bytes[at++];
    if (b === undefined) return null;
    value |= (b & 0x7f) << shift;
    if (!(b & 0x80)) return { value, at };
    shift += 7;
  }
}

/** A body with its CRC, COBS-encoded between delimiters. */
export function frame(body) {
  const crc = zlib.crc32(Uint8Array.from(body));
  const withCrc = [...body, crc & 0xff, (crc >>> 8) & 0xff, (crc >>> 16) & 0xff, crc >>> 24];
  return [0, ...cobsEncode(withCrc), 0];
}

/** The requests in a host-to-board byte stream: { seq, command, wire } (CRC checked). */
export function requests(stream) {
  const found = [];
  let start = 0;
  for (let i = 0; i <= stream.length; i++) {
    if (i < stream.length && stream[i] !== 0) continue;
    const raw = stream.slice(start, i);
    start = i + 1;
    if (raw.length === 0) continue;
    const decoded = cobsDecode(raw);
    if (!decoded || decoded.length < 5) continue;
    const body = decoded.slice(0, -4);
    const crc = decoded.slice(-4);
    const want = zlib.crc32(Uint8Array.from(body));
    if (crc[0] + crc[1] * 0x100 + crc[2] * 0x10000 + crc[3] * 0x1000000 !== want) continue;
    const seq = readVarint(body, 0);
    const command = seq && readVarint(body, seq.at);
    if (command) found.push({ seq: seq.value, command: command.value, wire: [0, ...raw, 0] });
  }
  return found;
}

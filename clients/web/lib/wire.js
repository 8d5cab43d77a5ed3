// Binary WebSocket messages: a little-endian uint32 header length, that many bytes of UTF-8
// JSON header, then the payload (a frame's encoded image, or an upload chunk).

/** Builds a binary message from a JSON-able header and a Buffer payload. */
export function encodeBinary(header, payload) {
  const json = Buffer.from(JSON.stringify(header), 'utf8');
  const prefix = Buffer.alloc(4);
  prefix.writeUInt32LE(json.length, 0);
  return Buffer.concat([prefix, json, payload ?? Buffer.alloc(0)]);
}

/**
 * Splits a binary message into { header, payload }. Throws an Error with a message a person
 * can read when the message is malformed (the caller turns it into INVALID_ARGUMENT).
 */
export function decodeBinary(data) {
  const buf = Buffer.isBuffer(data) ? data : Buffer.concat(data);
  if (buf.length < 4) throw new Error('binary message shorter than its 4-byte header length');
  const n = buf.readUInt32LE(0);
  if (n > buf.length - 4) throw new Error(`binary header length ${n} exceeds the message`);
  let header;
  try {
    header = JSON.parse(buf.subarray(4, 4 + n).toString('utf8'));
  } catch (e) {
    throw new Error(`binary header is not JSON: ${e.message}`);
  }
  if (header === null || typeof header !== 'object' || Array.isArray(header)) {
    throw new Error('binary header is not a JSON object');
  }
  return { header, payload: buf.subarray(4 + n) };
}

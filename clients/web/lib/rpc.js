// tesserad's gRPC API as the gateway uses it: the proto files loaded at run time, the client
// with its credentials, the RenderSettings schema the page builds its panel from, and gRPC
// errors in words a person can act on.
import fs from 'node:fs';
import path from 'node:path';
import grpc from '@grpc/grpc-js';
import protoLoader from '@grpc/proto-loader';

// Protobuf <-> JSON as the page sees it: proto field names, enums by name, 64-bit integers as
// numbers (byte counts and frame counters stay far below 2^53), and every field present in
// replies (zeros included; unset messages as null). Requests may leave out any field.
const LOADER_OPTIONS = { keepCase: true, longs: Number, enums: String, defaults: true, oneofs: false };

export function loadProto(protoDir) {
  const main = path.join(protoDir, 'tessera/v1/render_service.proto');
  if (!fs.existsSync(main)) throw new Error(`no ${main} (set --proto-dir)`);
  const definition = protoLoader.loadSync('tessera/v1/render_service.proto', {
    ...LOADER_OPTIONS,
    includeDirs: [protoDir],
  });
  return { definition, api: grpc.loadPackageDefinition(definition).tessera.v1 };
}

/** Channel credentials: plaintext, or TLS trusting `tlsCaFile` (else the system's CAs). */
export function makeCredentials({ tls, tlsCaFile }) {
  if (!tls) return grpc.credentials.createInsecure();
  return grpc.credentials.createSsl(tlsCaFile ? fs.readFileSync(tlsCaFile) : null);
}

/**
 * Per-call metadata: the bearer token, when tesserad wants one. (grpc-js attaches call
 * credentials only on TLS channels; metadata works on both.)
 */
export function callMetadata({ token }) {
  const md = new grpc.Metadata();
  if (token) md.set('authorization', `Bearer ${token}`);
  return md;
}

/**
 * A RenderService client for `address`. `channelOptions` adds grpc-js channel options (a
 * replica reached by its IP address under a DNS name gets that name as its TLS target name and
 * authority: see replicas.js).
 */
export function makeClient(api, address, options, channelOptions = {}) {
  return new api.RenderService(address, makeCredentials(options), {
    // A 16384x16384 PNG frame is ~1 GiB; the page asks for far less. This bounds what one
    // reply can make the gateway hold.
    'grpc.max_receive_message_length': 256 * 1024 * 1024,
    'grpc.max_send_message_length': 8 * 1024 * 1024,
    'grpc.keepalive_time_ms': 30000,
    ...channelOptions,
  });
}

/**
 * An error the gateway makes itself, with the gRPC status name the page gets (`code`, e.g.
 * 'UNAVAILABLE') and a message that names the field or replica at fault.
 */
export class GatewayError extends Error {
  constructor(code, message) {
    super(message);
    this.code = code;
  }
}

const SCALAR_TYPES = {
  TYPE_BOOL: 'bool',
  TYPE_UINT32: 'uint32',
  TYPE_INT32: 'int32',
  TYPE_FLOAT: 'float',
  TYPE_DOUBLE: 'float',
  TYPE_ENUM: 'enum',
};

/** The prefix every value of an enum shares ("AA_" for AaMode), UNSPECIFIED aside. */
function enumPrefix(names) {
  const named = names.filter((n) => !n.endsWith('_UNSPECIFIED'));
  if (named.length === 0) return '';
  let prefix = named[0];
  for (const n of named) while (!n.startsWith(prefix)) prefix = prefix.slice(0, -1);
  return prefix.slice(0, prefix.lastIndexOf('_') + 1);
}

/**
 * The RenderSettings fields, from the proto itself, with the choices the server offers
 * (ServerInfo.choices holds lower-case names like "vis_mlaa"; they map to the proto's enum
 * value names). A field the proto gains shows up in the page without a gateway change.
 */
export function settingsSchema(definition, choices = {}) {
  const fields = definition['tessera.v1.RenderSettings'].type.field;
  return fields.map((f) => {
    const entry = { name: f.name, type: SCALAR_TYPES[f.type] ?? 'other' };
    if (f.type === 'TYPE_ENUM') {
      const e = definition[`tessera.v1.${f.typeName.split('.').pop()}`];
      const values = e.type.value.map((v) => v.name);
      entry.enum = f.typeName.split('.').pop();
      entry.values = values.filter((v) => !v.endsWith('_UNSPECIFIED'));
      const offered = choices[f.name];
      if (Array.isArray(offered)) {
        const prefix = enumPrefix(values);
        entry.choices = offered
          .map((c) => `${prefix}${String(c).toUpperCase()}`)
          .filter((v) => values.includes(v));
      }
    } else if (Array.isArray(choices[f.name])) {
      entry.choices = choices[f.name].slice(); // samples, tile_size
    }
    return entry;
  });
}

const CODE_NAMES = Object.fromEntries(Object.entries(grpc.status).map(([k, v]) => [v, k]));

// What each status means for the person at the page, in one plain sentence.
const HINTS = {
  INVALID_ARGUMENT: 'The server refused the request',
  NOT_FOUND: 'Not found on the server',
  RESOURCE_EXHAUSTED: 'The server is at one of its limits',
  FAILED_PRECONDITION: 'The server cannot do that now',
  DATA_LOSS: 'A file was damaged on its way to the server',
  UNAVAILABLE: 'The render server cannot be reached (it may be restarting)',
  UNAUTHENTICATED: 'The gateway is not allowed to use the render server (check its token)',
  PERMISSION_DENIED: 'The gateway is not allowed to do that on the render server',
  DEADLINE_EXCEEDED: 'The server took too long to answer',
  ABORTED: 'This session was taken over by another connection',
  CANCELLED: 'Cancelled',
  INTERNAL: 'The server failed unexpectedly',
  UNKNOWN: 'The server failed unexpectedly',
  UNIMPLEMENTED: 'The server does not offer this (is it an older tesserad?)',
};

/** {code, message, hint} for a gRPC error or any Error (gateway-side errors pass `code`). */
export function describeError(err, code) {
  let name = code;
  if (!name && typeof err?.code === 'string' && Object.hasOwn(HINTS, err.code)) name = err.code;
  if (!name) name = typeof err?.code === 'number' ? CODE_NAMES[err.code] ?? 'UNKNOWN' : 'INTERNAL';
  let message = err?.details ?? err?.message ?? String(err);
  if (typeof err?.code === 'number' && message.startsWith(`${err.code} `)) {
    message = message.replace(/^\d+ [A-Z_]+: /, '');
  }
  return { code: name, message, hint: HINTS[name] ?? 'The request failed' };
}

export { grpc };

// The Khronos glTF-Validator as the oracle for Tessera's importer.
//
//   node tests/gltf/agreement.mjs --import-check BUILD/tests/tessera-import-check \
//       --assets ../shared/assets [--out DIR] [--transformed DIR]
//
// Over a corpus (every .gltf/.glb of the sample assets, files generated here from Box that
// each break one of the validator's rules for what the importer reads, or use a feature it must
// accept, and with --transformed the Draco, meshopt, quantized and sparse files tests/gltf/
// transform.mjs made with glTF Transform), it runs the validator and tessera-import-check and
// holds them to this agreement:
//   - a file with validator ERRORs is refused by Tessera, with a message naming the same place
//     (the validator's JSON pointer /accessors/2/count becomes accessors[2]: the object);
//   - a file without errors is loaded, or refused only for a documented reason (a required
//     extension Tessera does not support; an import limit: RESOURCE_EXHAUSTED).
// Known disagreements are listed in KNOWN below with their reason (and in the README). Prints a
// JSON summary; exits 1 on any other disagreement. Needs `npm ci` in tests/gltf.
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { createRequire } from 'node:module';

const require = createRequire(import.meta.url);
const validator = require('gltf-validator');

function parseArgs(argv) {
  const o = { out: fs.mkdtempSync(path.join(os.tmpdir(), 'gltf-agreement-')) };
  for (let i = 0; i < argv.length; i += 2) {
    const key = argv[i].replace(/^--/, '').replace(/-(.)/g, (_, c) => c.toUpperCase());
    if (!(key in { importCheck: 1, assets: 1, out: 1, transformed: 1 })) throw new Error(`unknown flag ${argv[i]}`);
    o[key] = argv[i + 1];
  }
  if (!o.importCheck || !o.assets) throw new Error('usage: --import-check BIN --assets DIR [--out DIR]');
  return o;
}
const args = parseArgs(process.argv.slice(2));

// Files Tessera refuses (or loads) against the validator's verdict, with the reason. Keyed by
// corpus name. Empty today: every case below agrees.
const KNOWN = {};

// ---- the corpus ----------------------------------------------------------------------------

function sampleFiles(dir) {
  const out = [];
  for (const model of fs.readdirSync(dir).sort()) {
    for (const variant of ['glTF', 'glTF-Binary', 'glTF-Embedded']) {
      const d = path.join(dir, model, variant);
      if (!fs.existsSync(d)) continue;
      for (const f of fs.readdirSync(d).sort()) {
        if (/\.(gltf|glb)$/i.test(f)) out.push({ name: `${model}/${variant}/${f}`, file: path.join(d, f) });
      }
    }
  }
  return out;
}

// Box.gltf with an edit: `edit(json, bin)` changes the JSON and may return a new .bin (Buffer).
const boxDir = path.join(args.assets, 'Box', 'glTF');
const boxJson = JSON.parse(fs.readFileSync(path.join(boxDir, 'Box.gltf'), 'utf8'));
const boxBin = fs.readFileSync(path.join(boxDir, 'Box0.bin'));

function generated(name, edit, rewrite = (text) => text) {
  const dir = path.join(args.out, 'cases', name);
  fs.mkdirSync(dir, { recursive: true });
  const j = structuredClone(boxJson);
  let bin = Buffer.from(boxBin);
  const newBin = edit(j, bin);
  if (newBin) bin = newBin;
  j.buffers[0].byteLength = bin.length;
  fs.writeFileSync(path.join(dir, 'Box0.bin'), bin);
  fs.writeFileSync(path.join(dir, 'Box.gltf'), rewrite(JSON.stringify(j)));
  return { name: `generated/${name}`, file: path.join(dir, 'Box.gltf') };
}

// Appends `bytes` to the buffer (4-byte aligned), adds a bufferView for them, returns its index.
function appendView(j, bin, bytes) {
  const pad = (4 - (bin.length % 4)) % 4;
  const offset = bin.length + pad;
  const out = Buffer.concat([bin, Buffer.alloc(pad), bytes]);
  j.bufferViews.push({ buffer: 0, byteOffset: offset, byteLength: bytes.length });
  return { bin: out, view: j.bufferViews.length - 1 };
}
const u16 = (values) => Buffer.from(new Uint16Array(values).buffer);
const f32 = (values) => Buffer.from(new Float32Array(values).buffer);
// Box's positions (accessor 2), to make sparse values that keep its min/max exact.
const boxPositions = new Float32Array(boxBin.buffer.slice(boxBin.byteOffset + 288, boxBin.byteOffset + 576));
const vertex = (i) => Array.from(boxPositions.slice(3 * i, 3 * i + 3));

// A sparse block on POSITION (accessor 2) with these indices; values: vertices 5 and 6.
function sparse(indices) {
  return (j, bin) => {
    const a = appendView(j, bin, u16(indices));
    const b = appendView(j, a.bin, f32([...vertex(5), ...vertex(6)]));
    j.accessors[2].sparse = { count: indices.length, indices: { bufferView: a.view, componentType: 5123 },
      values: { bufferView: b.view } };
    return b.bin;
  };
}

// COLOR_0 on Box's primitive: 24 RGBA colours as normalized unsigned bytes, then `edit` of the
// accessor (a type or componentType the spec does not allow for colours).
function colored(edit = () => {}) {
  return (j, bin) => {
    const data = Buffer.alloc(24 * 4);
    for (let i = 0; i < 24 * 4; i++) data[i] = (i * 37) % 256;
    const a = appendView(j, bin, data);
    j.bufferViews[a.view].target = 34962;
    j.accessors.push({ bufferView: a.view, componentType: 5121, normalized: true, count: 24, type: 'VEC4' });
    edit(j.accessors[j.accessors.length - 1]);
    j.meshes[0].primitives[0].attributes.COLOR_0 = j.accessors.length - 1;
    return a.bin;
  };
}

// POSITION as SHORT (KHR_mesh_quantization): positions x 1000, with exact min/max.
function quantized(declare) {
  return (j, bin) => {
    const q = Int16Array.from(boxPositions, (v) => Math.round(v * 1000));
    const data = Buffer.alloc(24 * 8);
    for (let i = 0; i < 24; i++) for (let c = 0; c < 3; c++) data.writeInt16LE(q[3 * i + c], 8 * i + 2 * c);
    const a = appendView(j, bin, data);
    j.bufferViews[a.view].byteStride = 8;
    j.bufferViews[a.view].target = 34962;
    j.accessors[2] = { bufferView: a.view, componentType: 5122, count: 24, type: 'VEC3',
      min: [0, 1, 2].map((c) => Math.min(...Array.from({ length: 24 }, (_, i) => q[3 * i + c]))),
      max: [0, 1, 2].map((c) => Math.max(...Array.from({ length: 24 }, (_, i) => q[3 * i + c]))) };
    j.nodes[1].scale = [0.001, 0.001, 0.001];
    if (declare) {
      j.extensionsUsed = ['KHR_mesh_quantization'];
      j.extensionsRequired = ['KHR_mesh_quantization'];
    }
    return a.bin;
  };
}

// An animation of Box's mesh node (nodes[1]; nodes[0] has a matrix): key times and values
// appended to the buffer, the sampler and channel as given (`edit` changes them after).
function animated({ times = [0, 1, 2], values = [0, 0, 0, 1, 0, 0, 1, 1, 0], type = 'VEC3',
  path = 'translation', interpolation = 'LINEAR', node = 1, edit = () => {} } = {}) {
  return (j, bin) => {
    const t = appendView(j, bin, f32(times));
    const v = appendView(j, t.bin, f32(values));
    const comps = { SCALAR: 1, VEC3: 3, VEC4: 4 }[type];
    j.accessors.push({ bufferView: t.view, componentType: 5126, count: times.length, type: 'SCALAR',
      min: [Math.min(...times)], max: [Math.max(...times)] });
    j.accessors.push({ bufferView: v.view, componentType: 5126, count: values.length / comps, type });
    const input = j.accessors.length - 2;
    j.animations = [{ samplers: [{ input, output: input + 1, interpolation }],
      channels: [{ sampler: 0, target: { node, path } }] }];
    edit(j);
    return v.bin;
  };
}

// BoxTextured.gltf with a 6x4 lossless WebP image (libwebp 1.2.4; the fuzz seed
// tests/fuzz/corpus/image/texture_lossless.webp) as images[1], file lossless.webp, and an edit.
const texturedDir = path.join(args.assets, 'BoxTextured', 'glTF');
const webp = Buffer.from('5249464640000000574542505650384c330000002f05c00010990a44f43f3611d1ff0091b6'
  + '8d7f6b3354787a0962c114778f298140b24cfe46b30848129f47cf7335028ca0770000', 'hex');
function texturedWith(name, edit) {
  const dir = path.join(args.out, 'cases', name);
  fs.mkdirSync(dir, { recursive: true });
  const j = JSON.parse(fs.readFileSync(path.join(texturedDir, 'BoxTextured.gltf'), 'utf8'));
  for (const f of ['BoxTextured0.bin', 'CesiumLogoFlat.png'])
    fs.copyFileSync(path.join(texturedDir, f), path.join(dir, f));
  fs.writeFileSync(path.join(dir, 'lossless.webp'), webp);
  j.images.push({ uri: 'lossless.webp', mimeType: 'image/webp' });
  j.extensionsUsed = ['EXT_texture_webp'];
  j.textures[0].extensions = { EXT_texture_webp: { source: 1 } };
  edit(j);
  fs.writeFileSync(path.join(dir, 'BoxTextured.gltf'), JSON.stringify(j));
  return { name: `generated/${name}`, file: path.join(dir, 'BoxTextured.gltf') };
}

function glbWith(name, edit) {
  const src = fs.readFileSync(path.join(args.assets, 'Box', 'glTF-Binary', 'Box.glb'));
  const out = Buffer.from(src);
  edit(out);
  const dir = path.join(args.out, 'cases', name);
  fs.mkdirSync(dir, { recursive: true });
  fs.writeFileSync(path.join(dir, 'Box.glb'), out);
  return { name: `generated/${name}`, file: path.join(dir, 'Box.glb') };
}

const cases = [
  // Must be refused: each breaks one rule of the structures the importer reads.
  generated('accessor_too_long', (j) => { j.accessors[2].count = 100; }),
  generated('accessor_offset_unaligned', (j) => { j.accessors[1].byteOffset = 2; }),
  generated('buffer_view_offset_unaligned', (j) => {
    j.bufferViews[1].byteOffset = 2;
    j.bufferViews[1].byteLength = 574;
    j.accessors[2].count = 23;
  }),
  generated('buffer_view_too_long', (j) => { j.bufferViews[0].byteLength = 1000; }),
  generated('index_out_of_range', (j, bin) => { bin.writeUInt16LE(999, 576); }),
  generated('normal_unnormalized_bytes', (j) => { j.accessors[1].componentType = 5121; }),
  generated('attribute_accessor_missing', (j) => { j.meshes[0].primitives[0].attributes.NORMAL = 9; }),
  generated('material_missing', (j) => { j.meshes[0].primitives[0].material = 5; }),
  generated('node_loop', (j) => { j.nodes[1].children = [0]; }),
  generated('scene_non_root_node', (j) => { j.scenes[0].nodes = [0, 1]; }),
  generated('sparse_indices_non_increasing', sparse([3, 1])),
  generated('sparse_index_out_of_range', sparse([3, 99])),
  generated('quantized_without_extension', quantized(false)),
  generated('texture_reference_missing', (j) => {
    j.materials[0].pbrMetallicRoughness.baseColorTexture = { index: 5 };
  }),
  generated('metallic_factor_out_of_range', (j) => { j.materials[0].pbrMetallicRoughness.metallicFactor = 2; }),
  generated('base_color_factor_length', (j) => { j.materials[0].pbrMetallicRoughness.baseColorFactor = [1, 0, 0]; }),
  generated('alpha_cutoff_negative', (j) => { j.materials[0].alphaMode = 'MASK'; j.materials[0].alphaCutoff = -1; }),
  generated('emissive_strength_negative', (j) => {
    j.extensionsUsed = ['KHR_materials_emissive_strength'];
    j.materials[0].emissiveFactor = [1, 1, 1];
    j.materials[0].extensions = { KHR_materials_emissive_strength: { emissiveStrength: -1 } };
  }),
  generated('vertex_colors', colored()),
  generated('vertex_colors_unnormalized', colored((a) => { delete a.normalized; })),
  generated('vertex_colors_vec2', colored((a) => { a.type = 'VEC2'; a.count = 48; })),
  generated('vertex_colors_not_clamped', (j, bin) => {
    const a = appendView(j, bin, f32(Array.from({ length: 24 * 3 }, (_, i) => (i === 7 ? 2 : 0.5))));
    j.accessors.push({ bufferView: a.view, componentType: 5126, count: 24, type: 'VEC3' });
    j.meshes[0].primitives[0].attributes.COLOR_0 = j.accessors.length - 1;
    return a.bin;
  }),
  generated('vertex_colors_unaligned', (j, bin) => {
    const a = appendView(j, bin, Buffer.alloc(24 * 3, 200));
    j.accessors.push({ bufferView: a.view, componentType: 5121, normalized: true, count: 24, type: 'VEC3' });
    j.meshes[0].primitives[0].attributes.COLOR_0 = j.accessors.length - 1;
    return a.bin;
  }),
  // KHR_materials_unlit: an empty object makes the material unlit; anything else is refused.
  generated('unlit_material', (j) => {
    j.extensionsUsed = ['KHR_materials_unlit'];
    j.materials[0].extensions = { KHR_materials_unlit: {} };
  }),
  generated('unlit_not_object', (j) => {
    j.extensionsUsed = ['KHR_materials_unlit'];
    j.materials[0].extensions = { KHR_materials_unlit: true };
  }),
  // KHR_materials_ior and KHR_materials_specular: their values in range (ior 0 included), out of
  // range, and the specular textures (a PNG on zero-filled texture coordinates).
  ...['valid', 'ior_zero', 'ior_below_one', 'specular_factor_over_one',
    'specular_color_negative', 'specular_textures', 'specular_texture_missing'].map((name) =>
    generated(`reflectance_${name}`, (j) => {
      j.extensionsUsed = ['KHR_materials_ior', 'KHR_materials_specular'];
      const ior = { ior: name === 'ior_zero' ? 0 : name === 'ior_below_one' ? 0.5 : 1.33 };
      const specular = {
        specularFactor: name === 'specular_factor_over_one' ? 1.5 : 0.5,
        specularColorFactor: name === 'specular_color_negative' ? [-1, 1, 1] : [2, 1, 0.5],
      };
      if (name.startsWith('specular_texture')) {
        j.accessors.push({ componentType: 5126, count: 24, type: 'VEC2' });
        j.meshes[0].primitives[0].attributes.TEXCOORD_0 = j.accessors.length - 1;
        j.images = [{ uri: 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8DwHwAFBQIAX8jx0gAAAABJRU5ErkJggg==' }];
        j.textures = [{ source: 0 }];
        specular.specularTexture = { index: name === 'specular_texture_missing' ? 3 : 0 };
        specular.specularColorTexture = { index: 0 };
      }
      j.materials[0].extensions = { KHR_materials_ior: ior, KHR_materials_specular: specular };
    })),
  generated('texture_transform_scale_length', (j, bin) => {
    j.extensionsUsed = ['KHR_texture_transform'];
    j.accessors.push({ componentType: 5126, count: 24, type: 'VEC2' });
    j.meshes[0].primitives[0].attributes.TEXCOORD_0 = 3;
    j.images = [{ uri: 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8DwHwAFBQIAX8jx0gAAAABJRU5ErkJggg==' }];
    j.textures = [{ source: 0 }];
    j.materials[0].pbrMetallicRoughness.baseColorTexture = {
      index: 0, extensions: { KHR_texture_transform: { scale: [2] } } };
  }),
  // EXT_texture_webp: a WebP source with the PNG as fallback, one without a fallback (the
  // extension required), and a source that names no image.
  texturedWith('webp_source_with_fallback', () => {}),
  texturedWith('webp_source_required', (j) => {
    j.extensionsRequired = ['EXT_texture_webp'];
    delete j.textures[0].source;
  }),
  texturedWith('webp_source_missing', (j) => { j.textures[0].extensions.EXT_texture_webp.source = 4; }),
  generated('texture_source_missing', (j) => {
    j.textures = [{ source: 4 }];
    j.materials[0].pbrMetallicRoughness.baseColorTexture = { index: 0 };
  }),
  generated('light_spot_cone_out_of_range', (j) => {
    j.extensionsUsed = ['KHR_lights_punctual'];
    j.extensions = { KHR_lights_punctual: { lights: [
      { type: 'spot', spot: { innerConeAngle: 0.2, outerConeAngle: 2.0 } }] } };
    j.nodes[0].extensions = { KHR_lights_punctual: { light: 0 } };
  }),
  generated('light_range_zero', (j) => {
    j.extensionsUsed = ['KHR_lights_punctual'];
    j.extensions = { KHR_lights_punctual: { lights: [{ type: 'point', range: 0 }] } };
    j.nodes[0].extensions = { KHR_lights_punctual: { light: 0 } };
  }),
  generated('light_reference_missing', (j) => {
    j.extensionsUsed = ['KHR_lights_punctual'];
    j.extensions = { KHR_lights_punctual: { lights: [{ type: 'point' }] } };
    j.nodes[0].extensions = { KHR_lights_punctual: { light: 3 } };
  }),
  generated('camera_yfov_zero', (j) => {
    j.cameras = [{ type: 'perspective', perspective: { yfov: 0, znear: 0.1 } }];
    j.nodes[0].camera = 0;
  }),
  generated('camera_zfar_below_znear', (j) => {
    j.cameras = [{ type: 'perspective', perspective: { yfov: 1, znear: 1, zfar: 0.5 } }];
    j.nodes[0].camera = 0;
  }),
  generated('camera_reference_missing', (j) => { j.nodes[0].camera = 2; }),
  generated('node_matrix_and_trs', (j) => { j.nodes[0].translation = [1, 0, 0]; }),
  generated('node_rotation_not_unit', (j) => { j.nodes[1].rotation = [0, 0, 0, 2]; }),
  generated('scene_reference_missing', (j) => { j.scene = 3; }),
  // Integers tinygltf's int cast wrapped (2^32 read as 0) or took as absent (-1, 0.5, "0").
  generated('node_mesh_beyond_32_bits', (j) => { j.nodes[1].mesh = 4294967296; }),
  generated('node_mesh_string', (j) => { j.nodes[1].mesh = '0'; }),
  generated('primitive_material_negative', (j) => { j.meshes[0].primitives[0].material = -1; }),
  generated('primitive_mode_fraction', (j) => { j.meshes[0].primitives[0].mode = 4.5; }),
  generated('node_children_beyond_32_bits', (j) => { j.nodes[0].children = [4294967297]; }),
  // Valid: integers written as floats (JSON.stringify would write 0 and 5126).
  generated('integers_written_as_floats', () => {}, (text) => text.replace('"mesh":0', '"mesh":0.0')
    .replace('"componentType":5126', '"componentType":5126.0').replace('"byteStride":12', '"byteStride":12.0')
    .replace('"count":24', '"count":24.0')),
  generated('extension_index_written_as_float', (j) => {
    j.extensionsUsed = ['KHR_lights_punctual'];
    j.extensions = { KHR_lights_punctual: { lights: [{ type: 'point' }] } };
    j.nodes[0].extensions = { KHR_lights_punctual: { light: 0 } };
  }, (text) => text.replace('"light":0', '"light":0.0')),
  generated('sparse_count_zero', (j, bin) => {
    const b = sparse([1, 3])(j, bin);
    j.accessors[2].sparse.count = 0;
    return b;
  }),
  glbWith('glb_json_chunk_too_long', (b) => { b.writeUInt32LE(b.readUInt32LE(12) + 400, 12); }),
  glbWith('glb_bad_magic', (b) => { b.write('gLTF', 0); }),
  generated('position_max_mismatch', (j) => { j.accessors[2].max = [0.6, 0.5, 0.5]; }),
  generated('normal_not_unit', (j, bin) => { bin.writeFloatLE(0.5, 0); }),
  generated('buffer_view_stride_not_multiple_of_4', (j) => {
    j.bufferViews[1].byteStride = 14;
    j.bufferViews[1].byteLength = 576;
    j.accessors[1].count = 20;
    j.accessors[2].byteOffset = 288;
    j.accessors[2].count = 2;
  }),
  generated('undeclared_extension', (j) => {
    j.materials[0].emissiveFactor = [1, 1, 1];
    j.materials[0].extensions = { KHR_materials_emissive_strength: { emissiveStrength: 2 } };
  }),
  generated('sampler_mag_filter_invalid', (j) => {
    j.samplers = [{ magFilter: 9999 }];
  }),
  generated('sampler_wrap_invalid', (j) => {
    j.samplers = [{ wrapS: 1234 }];
  }),
  generated('image_buffer_view_without_mime_type', (j, bin) => {
    const a = appendView(j, bin, Buffer.from('89504e470d0a1a0a', 'hex'));
    j.images = [{ bufferView: a.view }];
    return a.bin;
  }),
  generated('camera_orthographic_zfar_below_znear', (j) => {
    j.cameras = [{ type: 'orthographic', orthographic: { xmag: 1, ymag: 1, znear: 1, zfar: 0.5 } }];
    j.nodes[0].camera = 0;
  }),
  generated('camera_orthographic_ymag_zero', (j) => {
    j.cameras = [{ type: 'orthographic', orthographic: { xmag: 1, ymag: 0, znear: 0.1, zfar: 10 } }];
    j.nodes[0].camera = 0;
  }),
  generated('tangent_w_invalid', (j, bin) => {
    const t = [];
    for (let i = 0; i < 24; i++) t.push(1, 0, 0, 0.5);
    const a = appendView(j, bin, f32(t));
    j.accessors.push({ bufferView: a.view, componentType: 5126, count: 24, type: 'VEC4' });
    j.meshes[0].primitives[0].attributes.TANGENT = 3;
    return a.bin;
  }),
  glbWith('glb_version_1', (b) => { b.writeUInt32LE(1, 4); }),
  glbWith('glb_length_mismatch', (b) => { b.writeUInt32LE(b.readUInt32LE(8) - 4, 8); }),
  glbWith('glb_first_chunk_not_json', (b) => { b.write('BIN\0', 16); }),
  generated('position_nan', (j, bin) => {
    bin.writeFloatLE(NaN, 288);
    delete j.accessors[2].min;
    delete j.accessors[2].max;
  }),
  generated('index_primitive_restart', (j, bin) => { bin.writeUInt16LE(65535, 576); delete j.accessors[0].max; }),
  generated('accessor_float_normalized', (j) => { j.accessors[2].normalized = true; }),
  generated('sparse_count_too_big', (j, bin) => {
    const a = appendView(j, bin, u16([1, 3]));
    const b = appendView(j, a.bin, f32([...vertex(5), ...vertex(6)]));
    j.accessors[2].sparse = { count: 30, indices: { bufferView: a.view, componentType: 5123 },
      values: { bufferView: b.view } };
    return b.bin;
  }),
  generated('accessor_stride_smaller_than_element', (j) => {
    j.bufferViews[1].byteStride = 8;
  }),
  generated('buffer_data_uri_text_plain', (j, bin) => {
    j.buffers[0].uri = `data:text/plain;base64,${bin.toString('base64')}`;
  }),
  generated('asset_version_3', (j) => { j.asset.version = '3.0'; }),
  generated('indices_float', (j) => {
    j.accessors[0].componentType = 5126;
    j.accessors[0].count = 18;
    delete j.accessors[0].max;
    delete j.accessors[0].min;
  }),
  generated('indices_with_byte_stride', (j) => {
    j.bufferViews[0].byteStride = 4;
    j.accessors[0].count = 18;
    delete j.accessors[0].max; delete j.accessors[0].min;
  }),
  generated('attributes_share_view_without_stride', (j) => { delete j.bufferViews[1].byteStride; }),
  generated('attribute_name_invalid', (j) => { j.meshes[0].primitives[0].attributes.NORMAL_1 = 1; }),
  generated('attribute_count_unequal', (j) => { j.accessors[1].count = 20; }),
  generated('texcoord_1_without_texcoord_0', (j) => {
    j.accessors.push({ componentType: 5126, count: 24, type: 'VEC2' });
    j.meshes[0].primitives[0].attributes.TEXCOORD_1 = 3;
  }),
  generated('material_texcoord_missing', (j) => {
    j.images = [{ uri: 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8DwHwAFBQIAX8jx0gAAAABJRU5ErkJggg==' }];
    j.textures = [{ source: 0 }];
    j.materials[0].pbrMetallicRoughness.baseColorTexture = { index: 0, texCoord: 1 };
  }),
  generated('node_matrix_not_trs', (j) => { j.nodes[0].matrix[3] = 1; }),
  generated('node_two_parents', (j) => { j.nodes.push({ children: [1] }); j.scenes[0].nodes.push(2); }),
  generated('extension_required_not_used', (j) => { j.extensionsRequired = ['KHR_texture_transform']; }),
  generated('extensions_used_duplicate', (j) => {
    j.extensionsUsed = ['KHR_texture_transform', 'KHR_texture_transform'];
  }),
  generated('mesh_without_primitives', (j) => { j.meshes.push({ primitives: [] }); }),
  generated('accessors_empty_array', (j) => { j.samplers = []; }),
  generated('accessor_count_missing', (j) => { delete j.accessors[1].count; }),
  generated('image_data_invalid', (j) => {
    j.images = [{ uri: 'data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAEAAAAB' }];
    j.textures = [{ source: 0 }];
    j.materials[0].pbrMetallicRoughness.baseColorTexture = { index: 0 };
    j.accessors.push({ componentType: 5126, count: 24, type: 'VEC2' });
    j.meshes[0].primitives[0].attributes.TEXCOORD_0 = 3;
  }),
  generated('image_mime_type_mismatch', (j, bin) => {
    const png = Buffer.from('iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mP8z8DwHwAFBQIAX8jx0gAAAABJRU5ErkJggg==', 'base64');
    const a = appendView(j, bin, png);
    j.images = [{ bufferView: a.view, mimeType: 'image/jpeg' }];
    j.textures = [{ source: 0 }];
    j.materials[0].pbrMetallicRoughness.baseColorTexture = { index: 0 };
    j.accessors.push({ componentType: 5126, count: 24, type: 'VEC2' });
    j.meshes[0].primitives[0].attributes.TEXCOORD_0 = 3;
    return a.bin;
  }),
  glbWith('glb_empty_bin_chunk', (b) => {
    const n = b.readUInt32LE(12);
    b.writeUInt32LE(0, 20 + n);
  }),
  // Must be loaded: valid uses of what the importer supports.
  generated('sparse_valid', sparse([1, 3])),
  generated('quantized_valid', quantized(true)),
  generated('accessor_without_buffer_view', (j) => {
    j.accessors.push({ componentType: 5126, count: 24, type: 'VEC2' });
    j.meshes[0].primitives[0].attributes.TEXCOORD_0 = 3;
  }),
  // Animations (glTF 2.0 3.11): valid ones load, each broken rule is refused.
  generated('animation_linear_valid', animated()),
  generated('animation_step_rotation_valid', animated({ type: 'VEC4', path: 'rotation',
    interpolation: 'STEP', values: [0, 0, 0, 1, 0, 0.7071068, 0, 0.7071068, 0, 1, 0, 0] })),
  generated('animation_cubic_valid', animated({ interpolation: 'CUBICSPLINE', times: [0, 1],
    values: [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0] })),
  generated('animation_times_not_increasing', animated({ times: [0, 2, 1] })),
  generated('animation_times_negative', animated({ times: [-1, 0, 1] })),
  generated('animation_times_without_bounds', animated({ edit: (j) => {
    delete j.accessors[j.accessors.length - 2].min;
    delete j.accessors[j.accessors.length - 2].max;
  } })),
  generated('animation_output_count_wrong', animated({ values: [0, 0, 0, 1, 0, 0] })),
  generated('animation_output_type_wrong', animated({ path: 'rotation' })),
  generated('animation_cubic_one_key', animated({ interpolation: 'CUBICSPLINE', times: [0],
    values: [0, 0, 0, 1, 0, 0, 0, 0, 0] })),
  generated('animation_node_with_matrix', animated({ node: 0 })),
  generated('animation_duplicate_target', animated({ edit: (j) => {
    j.animations[0].channels.push({ sampler: 0, target: { node: 1, path: 'translation' } });
  } })),
  generated('animation_weights_without_morph_targets', animated({ type: 'SCALAR',
    path: 'weights', values: [0, 0.5, 1] })),
  generated('animation_sampler_missing', animated({ edit: (j) => {
    j.animations[0].channels[0].sampler = 3;
  } })),
  // Morph targets and skins (glTF 2.0 3.7.2.2, 3.7.3).
  generated('morph_target_valid', (j) => { j.meshes[0].primitives[0].targets = [{ POSITION: 2 }]; }),
  generated('morph_weights_count_wrong', (j) => {
    j.meshes[0].primitives[0].targets = [{ POSITION: 2 }];
    j.meshes[0].weights = [0, 1];
  }),
  generated('skin_joints_empty', (j) => { j.skins = [{ joints: [] }]; }),
  generated('skin_unused_valid', (j) => { j.skins = [{ joints: [0, 1] }]; }),
  // Valid, refused for a documented reason: a required extension Tessera does not read.
  generated('required_extension_unsupported', (j) => {
    j.extensionsUsed = ['KHR_materials_clearcoat'];
    j.extensionsRequired = ['KHR_materials_clearcoat'];
    j.materials[0].extensions = { KHR_materials_clearcoat: { clearcoatFactor: 0.5 } };
  }),
];

// The glTF Transform outputs (tests/gltf/transform.mjs): valid files the importer must load. The
// validator does not look inside EXT_meshopt_compression or KHR_draco_mesh_compression data, so
// for those extensions it only vouches for the rest of the file; the extensions' own rules are
// checked by the importer's unit tests (tests/unit/gltf_import_test.cpp, GltfCompressed*).
function transformedFiles(dir) {
  if (!dir) return [];
  const manifest = JSON.parse(fs.readFileSync(path.join(dir, 'manifest.json'), 'utf8'));
  return manifest.files.map((f) => ({ name: `transformed/${path.basename(f.file)}`, file: f.file }));
}

const corpus = [...sampleFiles(args.assets), ...cases, ...transformedFiles(args.transformed)];

// ---- the two verdicts -------------------------------------------------------------------------

async function validate(file) {
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) =>
          (err ? reject(err.toString()) : resolve(new Uint8Array(data))));
      }),
  });
  const errors = report.issues.messages.filter((m) => m.severity === 0);
  return { errors: report.issues.numErrors, first: errors[0], all: errors };
}

// /accessors/2/sparse/indices -> accessors[2] (the object the issue is in).
function place(pointer) {
  const m = /^\/([A-Za-z]+)\/(\d+)/.exec(pointer ?? '');
  return m ? `${m[1]}[${m[2]}]` : null;
}

const tessera = new Map();
const lines = execFileSync(args.importCheck, corpus.map((c) => c.file), { maxBuffer: 64 << 20 })
  .toString().trim().split('\n');
for (const line of lines) {
  const r = JSON.parse(line);
  tessera.set(r.file, r);
}

const results = [];
let failures = 0;
for (const c of corpus) {
  const v = await validate(c.file);
  const t = tessera.get(c.file);
  let verdict;
  if (v.errors > 0) {
    // Tessera stops at its first error; the validator lists them all: one of its places will do.
    const places = v.all.map((m) => place(m.pointer)).filter(Boolean);
    if (t.ok) verdict = 'validator errors, Tessera loads it';
    else if (places.length && !places.some((p) => t.message.includes(p)))
      verdict = `refused, but naming none of ${[...new Set(places)].join(', ')}`;
    else verdict = 'agree: refused';
  } else if (t.ok) {
    verdict = 'agree: loaded';
  } else if (/unsupported required extension/.test(t.message) || t.code === 'RESOURCE_EXHAUSTED') {
    verdict = 'agree: refused for a documented reason';
  } else {
    verdict = 'valid, Tessera refuses it';
  }
  const agreed = verdict.startsWith('agree');
  const known = KNOWN[c.name];
  if (!agreed && !known) failures++;
  results.push({
    name: c.name, verdict, known: known ?? undefined,
    validator: { errors: v.errors, code: v.first?.code, pointer: v.first?.pointer },
    tessera: t.ok ? { ok: true } : { ok: false, code: t.code, message: t.message.slice(0, 200) },
  });
}
const summary = {
  files: results.length,
  agree: results.filter((r) => r.verdict.startsWith('agree')).length,
  known: results.filter((r) => !r.verdict.startsWith('agree') && r.known).length,
  disagree: failures,
  results,
};
fs.writeFileSync(path.join(args.out, 'agreement.json'), JSON.stringify(summary, null, 2));
console.log(JSON.stringify(summary, null, 2));
process.exit(failures > 0 ? 1 : 0);

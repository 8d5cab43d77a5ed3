// Compressed and re-encoded versions of sample assets, made by tools nobody here wrote: the
// glTF Transform CLI (@gltf-transform/cli, tests/gltf/package-lock.json) for Draco, meshopt and
// quantization, and glTF Transform's writer for sparse accessors.
//
//   node tests/gltf/transform.mjs --assets ../shared/assets --out DIR [--assets-list A,B]
//
// Writes DIR/<asset>_<variant>.glb and DIR/manifest.json: per file the original, the variant
// and the command that made it. tests/render/compressed_test.cpp renders each against its
// original; tests/gltf/agreement.mjs adds them to the validator corpus (--transformed DIR).
import { execFileSync } from 'node:child_process';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';
import { NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS } from '@gltf-transform/extensions';
import { instance } from '@gltf-transform/functions';

const here = path.dirname(fileURLToPath(import.meta.url));
const cli = path.join(here, 'node_modules', '@gltf-transform', 'cli', 'bin', 'cli.js');

function parseArgs(argv) {
  const o = { assetsList: 'DamagedHelmet,Sponza,BoxTextured' };
  for (let i = 0; i < argv.length; i += 2) {
    const key = argv[i].replace(/^--/, '').replace(/-(.)/g, (_, c) => c.toUpperCase());
    if (!(key in { assets: 1, out: 1, assetsList: 1 })) throw new Error(`unknown flag ${argv[i]}`);
    o[key] = argv[i + 1];
  }
  if (!o.assets || !o.out) throw new Error('usage: --assets DIR --out DIR [--assets-list A,B]');
  return o;
}
const args = parseArgs(process.argv.slice(2));

const ORIGINALS = {
  DamagedHelmet: 'DamagedHelmet/glTF/DamagedHelmet.gltf',
  Sponza: 'Sponza/glTF/Sponza.gltf',
  BoxTextured: 'BoxTextured/glTF/BoxTextured.gltf',
};

// The CLI's defaults are what users get: Draco edgebreaker with 14-bit positions, 10-bit normals
// and 12-bit texture coordinates; meshopt with quantization (14-bit positions, 8-bit normals,
// 12-bit texture coordinates, EXT_meshopt_compression + KHR_mesh_quantization); quantize alone.
const CLI_VARIANTS = ['draco', 'meshopt', 'quantize'];

// Every vertex attribute stored as a sparse accessor without a bufferView (the values are the
// sparse block's; glTF 2.0 3.6.2.3). The CLI's `sparse` command only does this where a third of
// the values are zero, which no sample here has, so the writer is asked for it directly.
async function writeSparse(input, output) {
  const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
  const doc = await io.read(input);
  let count = 0;
  for (const mesh of doc.getRoot().listMeshes()) {
    for (const prim of mesh.listPrimitives()) {
      for (const semantic of prim.listSemantics()) {
        prim.getAttribute(semantic).setSparse(true);
        ++count;
      }
    }
  }
  await io.write(output, doc);
  return count;
}

fs.mkdirSync(args.out, { recursive: true });
const manifest = [];
for (const asset of args.assetsList.split(',')) {
  const original = path.join(args.assets, ORIGINALS[asset]);
  if (!ORIGINALS[asset] || !fs.existsSync(original)) throw new Error(`no asset ${asset} (${original})`);
  for (const variant of CLI_VARIANTS) {
    const file = path.join(args.out, `${asset}_${variant}.glb`);
    const argv = [variant, original, file];
    execFileSync(process.execPath, [cli, ...argv], { stdio: ['ignore', 'ignore', 'inherit'] });
    manifest.push({ asset, variant, original, file, command: `gltf-transform ${argv.join(' ')}` });
  }
  const file = path.join(args.out, `${asset}_sparse.glb`);
  const accessors = await writeSparse(original, file);
  manifest.push({
    asset, variant: 'sparse', original, file,
    command: `@gltf-transform/core NodeIO: every vertex attribute setSparse(true) (${accessors} accessors)`,
  });
}
// EXT_mesh_gpu_instancing: Box's mesh on 12 nodes of a grid, each turned and scaled its own way
// (BoxGrid.glb, the original), and what glTF Transform's instance() makes of it: one node whose
// extension holds the 12 transforms (BoxGrid_instance.glb).
{
  const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
  const doc = await io.read(path.join(args.assets, 'Box', 'glTF', 'Box.gltf'));
  const root = doc.getRoot();
  const mesh = root.listMeshes()[0];
  const scene = root.listScenes()[0];
  for (const node of root.listNodes()) node.dispose();
  for (let i = 0; i < 12; i++) {
    const angle = 0.4 * i;
    scene.addChild(doc.createNode(`box${i}`).setMesh(mesh)
      .setTranslation([(i % 4) * 1.6, Math.floor(i / 4) * 1.6, 0])
      .setRotation([0, Math.sin(angle / 2), 0, Math.cos(angle / 2)])
      .setScale(Array(3).fill(0.5 + 0.05 * i)));
  }
  const original = path.join(args.out, 'BoxGrid.glb');
  await io.write(original, doc);
  await doc.transform(instance({ min: 5 }));
  const file = path.join(args.out, 'BoxGrid_instance.glb');
  await io.write(file, doc);
  manifest.push({ asset: 'BoxGrid', variant: 'instance', original, file,
    command: '@gltf-transform/functions instance({min: 5}) of Box on 12 nodes' });
}
// COLOR_0: DamagedHelmet with a vertex colour made from each vertex's position (float RGBA in
// [0, 1]; HelmetColors.glb, the original), and what the CLI's draco, meshopt and quantize make of
// it (their colour quantization and compression of a generic attribute).
{
  const io = new NodeIO().registerExtensions(ALL_EXTENSIONS);
  const doc = await io.read(path.join(args.assets, ORIGINALS.DamagedHelmet));
  for (const mesh of doc.getRoot().listMeshes()) {
    for (const prim of mesh.listPrimitives()) {
      const position = prim.getAttribute('POSITION');
      const colors = new Float32Array(position.getCount() * 4);
      const p = [0, 0, 0];
      for (let i = 0; i < position.getCount(); i++) {
        position.getElement(i, p);
        colors.set([0.5 + 0.5 * Math.sin(3 * p[0]), 0.5 + 0.5 * Math.sin(3 * p[1] + 1),
          0.5 + 0.5 * Math.sin(3 * p[2] + 2), 1], 4 * i);
      }
      prim.setAttribute('COLOR_0', doc.createAccessor().setType('VEC4').setArray(colors)
        .setBuffer(position.getBuffer()));
    }
  }
  const original = path.join(args.out, 'HelmetColors.glb');
  await io.write(original, doc);
  for (const variant of CLI_VARIANTS) {
    const file = path.join(args.out, `HelmetColors_${variant}.glb`);
    const argv = [variant, original, file];
    execFileSync(process.execPath, [cli, ...argv], { stdio: ['ignore', 'ignore', 'inherit'] });
    manifest.push({ asset: 'HelmetColors', variant, original, file,
      command: `gltf-transform ${argv.join(' ')} (DamagedHelmet with COLOR_0 added)` });
  }
}
const version = JSON.parse(fs.readFileSync(path.join(here, 'node_modules', '@gltf-transform', 'cli',
                                                     'package.json'), 'utf8')).version;
fs.writeFileSync(path.join(args.out, 'manifest.json'),
                 JSON.stringify({ tool: `@gltf-transform/cli ${version}`, files: manifest }, null, 1));
console.log(JSON.stringify({ files: manifest.length, out: args.out }));

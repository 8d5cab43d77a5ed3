#!/usr/bin/env python3
"""Writes the fuzz targets' seed corpora (tests/fuzz/corpus/{gltf,image,request}).

The seeds are committed; run this again only to change them:
    tests/fuzz/make_seeds.py [--assets ../shared/assets]
glTF seeds are small sample assets packed as file sets (file_set.h) plus hand-made edge cases;
image seeds are small PNG/JPEG/WebP files behind a decoder-selector byte (fuzz_image.cpp), with PNG
variants made here (grey, palette, 16-bit, alpha); request seeds are text-format messages
encoded with `protoc --encode` behind a request-selector byte (fuzz_request.cpp).
"""
import argparse
import json
import os
import struct
import subprocess
import sys
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))


def write(kind, name, data):
    path = os.path.join(HERE, "corpus", kind, name)
    with open(path, "wb") as f:
        f.write(data)


def pack(files):
    """file_set.h: "TSFS", then (u16 name length, name, u32 size, data); the first is main."""
    out = bytearray(b"TSFS")
    for name, data in files:
        n = name.encode()
        out += struct.pack("<H", len(n)) + n + struct.pack("<I", len(data)) + data
    return bytes(out)


# WebP (EXT_texture_webp), 6x4 RGBA made with libwebp 1.2.4: lossless (VP8L), and lossy with
# alpha (VP8X, ALPH, VP8).
WEBP = {
    "lossless.webp": bytes.fromhex(
        "5249464640000000574542505650384c330000002f05c00010990a44f43f3611d1ff0091b68d7f6b33"
        "54787a0962c114778f298140b24cfe46b30848129f47cf7335028ca0770000"),
    "lossy_alpha.webp": bytes.fromhex(
        "524946468200000057454250565038580a00000010000000050000030000414c50480c000000010ff0"
        "c0ff8888d08488fe075650382050000000b001009d012a0600040002003425b00274010ef6a22000f8"
        "609b5efb7af460d380439ff3ff1ffe3fdbd80bbeed670f7c7ff836c4f9d50f60ff8eae6ff26ffd08fe"
        "a9ff1816ff937ff881050ef2000000"),
}


def gltf_file_set(path):
    """The .gltf and every file its buffers and images name (the main file first)."""
    base = os.path.dirname(path)
    with open(path, "rb") as f:
        main = f.read()
    files = [(os.path.basename(path), main)]
    doc = json.loads(main)
    for item in doc.get("buffers", []) + doc.get("images", []):
        uri = item.get("uri")
        if uri and not uri.startswith("data:"):
            with open(os.path.join(base, uri), "rb") as f:
                files.append((uri, f.read()))
    return files


def gltf_seeds(assets):
    for rel in ["Box/glTF/Box.gltf", "BoxTextured/glTF/BoxTextured.gltf",
                "TextureTransformTest/glTF/TextureTransformTest.gltf",
                "SimpleMeshes/glTF/SimpleMeshes.gltf", "TextureCoordinateTest/glTF/TextureCoordinateTest.gltf"]:
        name = os.path.basename(rel).replace(".gltf", "")
        write("gltf", name + ".tsfs", pack(gltf_file_set(os.path.join(assets, rel))))
    # BoxTextured sampling a WebP source (EXT_texture_webp), its PNG the fallback.
    files = gltf_file_set(os.path.join(assets, "BoxTextured/glTF/BoxTextured.gltf"))
    doc = json.loads(files[0][1])
    doc["extensionsUsed"] = ["EXT_texture_webp"]
    doc["images"].append({"uri": "lossless.webp", "mimeType": "image/webp"})
    doc["textures"][0]["extensions"] = {"EXT_texture_webp": {"source": len(doc["images"]) - 1}}
    files[0] = (files[0][0], json.dumps(doc).encode())
    write("gltf", "BoxTextured_webp.tsfs", pack(files + [("lossless.webp", WEBP["lossless.webp"])]))
    # Box drawn as three instances (EXT_mesh_gpu_instancing): TRANSLATION and SCALE after its
    # data.
    (name, main), (bin_name, data) = gltf_file_set(os.path.join(assets, "Box/glTF/Box.gltf"))
    doc = json.loads(main)
    data += b"\0" * ((-len(data)) % 4)
    offset = len(data)
    data += struct.pack("<9f", 0, 0, 0, 2, 0, 0, 0, 3, 0) + struct.pack("<9f", 1, 1, 1, 2, 2, 2, 1, .5, 1)
    doc["buffers"][0]["byteLength"] = len(data)
    views, accessors = len(doc["bufferViews"]), len(doc["accessors"])
    for k in range(2):
        doc["bufferViews"].append({"buffer": 0, "byteOffset": offset + 36 * k, "byteLength": 36})
        doc["accessors"].append({"bufferView": views + k, "componentType": 5126, "count": 3,
                                 "type": "VEC3"})
    doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]
    doc["nodes"][1]["extensions"] = {"EXT_mesh_gpu_instancing": {
        "attributes": {"TRANSLATION": accessors, "SCALE": accessors + 1}}}
    write("gltf", "Box_instanced.tsfs", pack([(name, json.dumps(doc).encode()), (bin_name, data)]))
    # Box with vertex colours (COLOR_0, normalized unsigned bytes) on an unlit, alpha-mask
    # material (KHR_materials_unlit).
    (name, main), (bin_name, data) = gltf_file_set(os.path.join(assets, "Box/glTF/Box.gltf"))
    doc = json.loads(main)
    data += b"\0" * ((-len(data)) % 4)
    offset = len(data)
    data += bytes((i * 37) % 256 for i in range(24 * 4))
    doc["buffers"][0]["byteLength"] = len(data)
    doc["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": 96})
    doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5121,
                             "normalized": True, "count": 24, "type": "VEC4"})
    doc["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = len(doc["accessors"]) - 1
    doc["extensionsUsed"] = ["KHR_materials_unlit"]
    doc["materials"][0]["extensions"] = {"KHR_materials_unlit": {}}
    doc["materials"][0]["alphaMode"] = "MASK"
    write("gltf", "Box_colors_unlit.tsfs", pack([(name, json.dumps(doc).encode()), (bin_name, data)]))
    # BoxTextured with an IOR and a specular factor, colour and both textures
    # (KHR_materials_ior, KHR_materials_specular), one of them transformed.
    files = gltf_file_set(os.path.join(assets, "BoxTextured/glTF/BoxTextured.gltf"))
    doc = json.loads(files[0][1])
    doc["extensionsUsed"] = ["KHR_materials_ior", "KHR_materials_specular", "KHR_texture_transform"]
    doc["materials"][0]["extensions"] = {
        "KHR_materials_ior": {"ior": 1.33},
        "KHR_materials_specular": {
            "specularFactor": 0.5, "specularColorFactor": [2, 1, 0.5],
            "specularTexture": {"index": 0},
            "specularColorTexture": {"index": 0, "extensions": {
                "KHR_texture_transform": {"scale": [2, 2]}}}}}
    files[0] = (files[0][0], json.dumps(doc).encode())
    write("gltf", "BoxTextured_specular.tsfs", pack(files))
    for rel in ["Box/glTF-Binary/Box.glb", "BoxTextured/glTF-Binary/BoxTextured.glb",
                "OrientationTest/glTF-Binary/OrientationTest.glb", "Box/glTF-Embedded/Box.gltf"]:
        with open(os.path.join(assets, rel), "rb") as f:
            write("gltf", os.path.basename(rel).replace(".", "_"), f.read())
    # Hand-made: features the samples lack (lights, cameras, strips, sparse, KHR extensions,
    # a deep hierarchy), each a small valid-looking asset the fuzzer can break.
    tri = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<3H", 0, 1, 2) + b"\0\0"
    buffer = {"byteLength": len(tri)}
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
             {"buffer": 0, "byteOffset": 36, "byteLength": 6}]
    accessors = [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                  "min": [0, 0, 0], "max": [1, 1, 0]},
                 {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}]
    doc = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual", "KHR_texture_transform",
                           "KHR_materials_emissive_strength"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"type": "point", "color": [1, 0.5, 0.2], "intensity": 10, "range": 5},
            {"type": "spot", "intensity": 3, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
            {"type": "directional", "intensity": 2}]}},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"children": [1, 2, 3, 4], "rotation": [0, 0.38, 0, 0.92]},
                  {"mesh": 0, "scale": [2, 2, 2]},
                  {"camera": 0, "translation": [0, 0, 3]},
                  {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [1, 1, 1]},
                  {"extensions": {"KHR_lights_punctual": {"light": 1}}, "children": [5]},
                  {"mesh": 1, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]}],
        "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 100}}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
                   {"primitives": [{"attributes": {"POSITION": 0}, "mode": 5},
                                   {"attributes": {"POSITION": 0}, "mode": 6, "material": 0}]}],
        "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0.5, 1],
                                                "metallicFactor": 0.2},
                       "emissiveFactor": [1, 1, 0],
                       "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4}},
                       "alphaMode": "MASK", "alphaCutoff": 0.4, "doubleSided": True}],
        "buffers": [dict(buffer, uri="tri.bin")],
        "bufferViews": views,
        "accessors": accessors,
    }
    write("gltf", "features.tsfs", pack([("features.gltf", json.dumps(doc).encode()), ("tri.bin", tri)]))
    # The same triangle as a .glb with the buffer in the BIN chunk.
    glb_doc = dict(doc, buffers=[buffer])
    js = json.dumps(glb_doc).encode()
    js += b" " * (-len(js) % 4)
    body = struct.pack("<I", len(js)) + b"JSON" + js + struct.pack("<I", len(tri)) + b"BIN\0" + tri
    write("gltf", "features_glb", b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body)
    # A data: URI buffer and a sparse accessor.
    import base64
    embedded = dict(doc, buffers=[dict(buffer, uri="data:application/octet-stream;base64," +
                                       base64.b64encode(tri).decode())])
    embedded["accessors"] = accessors + [{"bufferView": 0, "componentType": 5126, "count": 3,
                                          "type": "VEC3", "sparse": {"count": 1,
                                          "indices": {"bufferView": 1, "componentType": 5123},
                                          "values": {"bufferView": 0}}}]
    write("gltf", "embedded_sparse.gltf", json.dumps(embedded).encode())
    # Sparse without a base bufferView (zeros, then the block).
    zeros = dict(embedded)
    zeros["accessors"] = accessors + [{"componentType": 5126, "count": 3, "type": "VEC3",
                                       "sparse": {"count": 2,
                                                  "indices": {"bufferView": 1, "componentType": 5123},
                                                  "values": {"bufferView": 0}}}]
    zeros["meshes"] = [{"primitives": [{"attributes": {"POSITION": 2}, "indices": 1}]}]
    write("gltf", "sparse_zeros.gltf", json.dumps(zeros).encode())
    # KHR_mesh_quantization: SHORT positions (stride 8), normalized BYTE normals (stride 4),
    # UNSIGNED_SHORT texture coordinates, dequantized by the node's scale.
    qbin = (struct.pack("<12h", 0, 0, 0, 0, 100, 0, 0, 0, 0, 100, 0, 0) +
            struct.pack("<12b", 0, 0, 127, 0, 0, 127, 0, 0, -128, 0, 0, 0) +
            struct.pack("<6H", 0, 0, 2, 0, 0, 3))
    quant = {
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_mesh_quantization"],
        "extensionsRequired": ["KHR_mesh_quantization"],
        "nodes": [{"mesh": 0, "scale": [0.01, 0.01, 0.01]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}]}],
        "buffers": [{"byteLength": len(qbin), "uri": "q.bin"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 24, "byteStride": 8},
                        {"buffer": 0, "byteOffset": 24, "byteLength": 12, "byteStride": 4},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 12}],
        "accessors": [{"bufferView": 0, "componentType": 5122, "count": 3, "type": "VEC3"},
                      {"bufferView": 1, "componentType": 5120, "normalized": True, "count": 3,
                       "type": "VEC3"},
                      {"bufferView": 2, "componentType": 5123, "count": 3, "type": "VEC2"}],
    }
    write("gltf", "quantized.tsfs", pack([("quantized.gltf", json.dumps(quant).encode()), ("q.bin", qbin)]))
    # A chain of nodes 40 deep.
    chain = dict(doc)
    chain["nodes"] = [{"children": [i + 1], "translation": [0.1, 0, 0]} for i in range(39)] + [{"mesh": 0}]
    chain["scenes"] = [{"nodes": [0]}]
    write("gltf", "deep_chain.tsfs", pack([("chain.gltf", json.dumps(chain).encode()), ("tri.bin", tri)]))


def animation_seeds():
    """A triangle on a node moved by one animation: translation LINEAR, rotation STEP, scale
    CUBICSPLINE (keys 0, 1, 2 s; cubic values with in- and out-tangents)."""
    floats = lambda *v: struct.pack(f"<{len(v)}f", *v)
    tri = floats(0, 0, 0, 1, 0, 0, 0, 1, 0)
    times = floats(0, 1, 2)
    move = floats(0, 0, 0, 1, 0, 0, 1, 1, 0)
    turn = floats(0, 0, 0, 1, 0, 0.7071068, 0, 0.7071068, 0, 1, 0, 0)
    grow = floats(*([0, 0, 0, 1, 1, 1, 1, 0, 0] + [0, 0, 0, 2, 2, 2, 0, 0, 0] + [0, 1, 0, 1, 1, 1, 0, 0, 0]))
    parts, views, offset = [tri, times, move, turn, grow], [], 0
    for p in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(p)})
        offset += len(p)
    doc = {
        "asset": {"version": "2.0"},
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "moved"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"uri": "anim.bin", "byteLength": offset}],
        "bufferViews": views,
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
            {"bufferView": 1, "componentType": 5126, "count": 3, "type": "SCALAR", "min": [0], "max": [2]},
            {"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"},
            {"bufferView": 4, "componentType": 5126, "count": 9, "type": "VEC3"}],
        "animations": [{"name": "all", "samplers": [
            {"input": 1, "output": 2},
            {"input": 1, "output": 3, "interpolation": "STEP"},
            {"input": 1, "output": 4, "interpolation": "CUBICSPLINE"}],
            "channels": [{"sampler": i, "target": {"node": 0, "path": p}}
                         for i, p in enumerate(["translation", "rotation", "scale"])]}],
    }
    write("gltf", "animated.tsfs", pack([("animated.gltf", json.dumps(doc).encode()), ("anim.bin", b"".join(parts))]))


def generated_animation_seeds():
    """The skinned cylinder, the morphing cube and the TRS-animated cubes of
    tests/gltf/make_animated.py (skins, joints and weights, morph targets, every interpolation)."""
    sys.path.insert(0, os.path.join(ROOT, "tests", "gltf"))
    import make_animated
    for make in (make_animated.skinned_cylinder, make_animated.morph_cube, make_animated.trs_nodes):
        name, gltf, blob = make()
        text = (json.dumps(gltf, indent=1) + "\n").encode()
        write("gltf", name + ".tsfs", pack([(name + ".gltf", text), (name + ".bin", blob)]))


def png(width, height, color_type, bit_depth, rows, palette=None):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    raw = b"".join(b"\0" + r for r in rows)
    out = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, bit_depth,
                                                             color_type, 0, 0, 0))
    if palette:
        out += chunk(b"PLTE", palette)
    return out + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def image_seeds(assets):
    generated = {
        "grey8.png": png(4, 3, 0, 8, [bytes([x * 60 for x in range(4)])] * 3),
        "grey_alpha.png": png(2, 2, 4, 8, [b"\x10\xff\x80\x40"] * 2),
        "palette.png": png(3, 2, 3, 8, [b"\0\1\2"] * 2, palette=b"\xff\0\0\0\xff\0\0\0\xff"),
        "rgb16.png": png(2, 2, 2, 16, [b"\xff\xff\0\0\x12\x34" * 2] * 2),
        "rgba8.png": png(2, 1, 6, 8, [b"\1\2\3\4\5\6\7\x08"]),
    }
    files = list(generated.items())
    for rel in ["TextureTransformTest/glTF/Arrow.png", "Sponza/glTF/white.png",
                "Sponza/glTF/16885566240357350108.jpg"]:
        with open(os.path.join(assets, rel), "rb") as f:
            files.append((os.path.basename(rel), f.read()))
    files += list(WEBP.items())
    for name, data in files:
        write("image", "texture_" + name, b"\0" + data)  # as the importer decodes textures
        if name.endswith(".png"):
            write("image", "libpng_" + name, b"\1" + data)
        elif name.endswith(".webp"):
            write("image", "libwebp_" + name, b"\3" + data)
        else:
            write("image", "turbojpeg_" + name, b"\2" + data)


def encode(message, text):
    proto = os.path.join(ROOT, "proto")
    files = [os.path.join("tessera/v1", f) for f in ("render_service.proto", "job.proto")]
    return subprocess.run(["protoc", "--proto_path=" + proto, "--encode=tessera.v1." + message]
                          + files, input=text.encode(), capture_output=True, check=True).stdout


def varint(n):
    out = bytearray()
    while True:
        b = n & 0x7F
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def request_seeds(assets):
    # 0: an upload stream of Box.gltf + Box0.bin in two chunks each.
    files = gltf_file_set(os.path.join(assets, "Box/glTF/Box.gltf"))
    stream = []
    manifest = "manifest { main_file: \"Box.gltf\" " + " ".join(
        'files { name: "%s" size: %d }' % (n, len(d)) for n, d in files) + " }"
    stream.append(encode("UploadRequest", manifest))
    for i, (name, data) in enumerate(files):
        half = len(data) // 2
        for off, part in ((0, data[:half]), (half, data[half:])):
            escaped = "".join("\\%03o" % b for b in part)
            stream.append(encode("UploadRequest", 'chunk { file_index: %d offset: %d data: "%s" }'
                                 % (i, off, escaped)))
    write("request", "upload_box", b"\0" + b"".join(varint(len(m)) + m for m in stream))
    write("request", "upload_manifest_only", b"\0" + varint(len(stream[0])) + stream[0])
    # 1: render requests.
    look = "look_at { eye { x: 1 y: 2 z: 3 } target { } up { y: 1 } }"
    renders = {
        "render_lookat": 'scene_id: "demo" camera { %s yfov: 0.9 znear: 0.1 zfar: 50 } '
                         'settings { width: 64 height: 48 aa: AA_MSAA samples: 4 culling: CULLING_GPU_OCCLUSION }' % look,
        "render_matrix": 'scene_id: "demo" camera { view_matrix { m: [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,-5,1] } } '
                         'settings { width: 32 height: 32 aa: AA_TAA synthetic_lights: 64 tile_size: 8 '
                         'exposure_mode: EXPOSURE_FIXED exposure_ev: 1.5 debug_view: DEBUG_NORMALS jpeg_quality: 70 }',
        "render_frame": 'scene_id: "demo" camera { frame { direction { x: 1 y: 0.5 z: 0.2 } } } '
                        'settings { aa: AA_VIS_MLAA samples: 4 light_radius_min: 0.5 light_radius_max: 2 }',
        "render_scene_camera": 'camera { scene_camera: 0 } settings { aa: AA_FXAA jpeg_444: true }',
        "render_animation": 'scene_id: "demo" settings { width: 32 height: 24 animation: "walk" '
                            'scene_time: 1.25 loop: false }',
    }
    for name, text in renders.items():
        write("request", name, b"\1" + encode("RenderRequest", text))
    # 2: stream events.
    events = {
        "event_open": 'event_id: 1 open { scene_id: "demo" camera { %s } settings { width: 320 height: 240 } '
                      'target_fps: 30 interactive { enabled: true render_scale: 0.5 jpeg_quality: 50 rest_ms: 200 } }' % look,
        "event_update": 'event_id: 7 camera { %s } settings { aa: AA_TAA } target_fps: 60 refresh: true '
                        'interactive { render_scale: 0.25 }' % look,
        "event_open_h264": 'event_id: 1 open { scene_id: "demo" settings { width: 320 height: 240 } '
                           'video { codec: VIDEO_CODEC_H264 encoder: VIDEO_ENCODER_SOFTWARE crf: 20 '
                           'interactive_crf: 30 max_bitrate_kbps: 8000 keyframe_interval: 120 preset: "veryfast" } }',
        "event_video_update": 'event_id: 9 keyframe: true video { codec: VIDEO_CODEC_JPEG crf: 51 preset: "fast" }',
        "event_play": 'event_id: 3 settings { animation: "0" play: true scene_time: 0.5 loop: true }',
    }
    for name, text in events.items():
        write("request", name, b"\2" + encode("ClientEvent", text))
    # 3, 4: jobs.
    key = lambda f, x: 'keyframes { frame: %d look_at { eye { x: %g y: 1 z: 4 } target { } } yfov: 0.7 }' % (f, x)
    jobs = {
        "job_path": 'spec { name: "orbit" scene_id: "demo" settings { width: 64 height: 48 } '
                    'path { %s %s %s interpolation: INTERPOLATION_CATMULL_ROM znear: 0.1 } '
                    'frames { first: 0 last: 30 step: 2 } encoding: IMAGE_PNG '
                    'output: JOB_OUTPUT_SERVER_DIR output_dir: "renders/a" name_pattern: "f_%%04d.png" }'
                    % (key(0, -2), key(10, 0), key(30, 2)),
        "job_list": 'spec { scene_id: "demo" list { cameras { %s } cameras { frame { } } } '
                    'frames { first: 5 last: 6 } taa_frames: 4 settings { aa: AA_TAA } }' % look,
        "job_frames_only": 'spec { scene_id: "demo" frames { first: 0 last: 1000 step: 7 } }',
        "job_animation": 'spec { scene_id: "demo" frames { first: 0 last: 47 } fps: 24 '
                         'settings { width: 32 height: 24 animation: "none" scene_time: 0.5 } }',
    }
    for name, text in jobs.items():
        write("request", name, b"\3" + encode("SubmitJobRequest", text))
    write("request", "job_frame", b"\4" + encode(
        "RenderJobFrameRequest", jobs["job_path"].replace("spec {", "frame: 12 spec {", 1)))


def compressed_seeds(assets):
    """Box compressed by glTF Transform (tests/gltf, `npm ci` there first): Draco and meshopt
    .glb files, and meshopt as a .gltf + .bin file set (its fallback buffer has no uri)."""
    cli = os.path.join(ROOT, "tests", "gltf", "node_modules", "@gltf-transform", "cli", "bin", "cli.js")
    if not os.path.exists(cli):
        print("skipping the compressed seeds: run `npm ci` in tests/gltf", file=sys.stderr)
        return
    box = os.path.join(assets, "Box", "glTF", "Box.gltf")
    tmp = os.path.join(ROOT, "build", "seeds")
    os.makedirs(tmp, exist_ok=True)
    for variant in ("draco", "meshopt"):
        out = os.path.join(tmp, f"box_{variant}.glb")
        subprocess.run(["node", cli, variant, box, out], check=True, stdout=subprocess.DEVNULL)
        with open(out, "rb") as f:
            write("gltf", f"box_{variant}_glb", f.read())
    out = os.path.join(tmp, "box_meshopt.gltf")
    subprocess.run(["node", cli, "meshopt", box, out], check=True, stdout=subprocess.DEVNULL)
    write("gltf", "box_meshopt.tsfs", pack(gltf_file_set(out)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--assets", default=os.path.join(os.path.dirname(ROOT), "shared", "assets"))
    args = parser.parse_args()
    for kind in ("gltf", "image", "request"):
        os.makedirs(os.path.join(HERE, "corpus", kind), exist_ok=True)
    gltf_seeds(args.assets)
    animation_seeds()
    generated_animation_seeds()
    compressed_seeds(args.assets)
    image_seeds(args.assets)
    request_seeds(args.assets)
    for kind in ("gltf", "image", "request"):
        d = os.path.join(HERE, "corpus", kind)
        print(kind, len(os.listdir(d)), "seeds,", sum(os.path.getsize(os.path.join(d, f)) for f in os.listdir(d)), "bytes")


if __name__ == "__main__":
    sys.exit(main())

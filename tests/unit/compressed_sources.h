#pragma once
// Hand-built compressed glTF files for the importer's tests: a small wavy grid encoded here with
// the encoders of the libraries the importer decodes with (meshoptimizer, Draco), so every value
// the importer must produce is known.
#include <draco/compression/encode.h>
#include <draco/mesh/triangle_soup_mesh_builder.h>
#include <meshoptimizer.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "renderer/scene/gltf_import.h"

namespace tessera::testing {

// (n+1)^2 vertices on a wavy grid with unit normals and UVs in [0, 1]; 2 n^2 triangles.
struct TestMesh {
  std::vector<float> positions;  // xyz
  std::vector<float> normals;    // xyz, unit
  std::vector<float> uvs;        // uv
  std::vector<uint32_t> indices;
  size_t vertices() const { return positions.size() / 3; }
};

// The per-component bounds of the positions, as accessor min and max.
inline nlohmann::json Bound(const TestMesh& m, bool max) {
  nlohmann::json out = nlohmann::json::array();
  for (int c = 0; c < 3; ++c) {
    float v = m.positions[c];
    for (size_t i = c; i < m.positions.size(); i += 3)
      v = max ? std::max(v, m.positions[i]) : std::min(v, m.positions[i]);
    out.push_back(v);
  }
  return out;
}

inline TestMesh WavyGrid(int n) {
  TestMesh m;
  for (int y = 0; y <= n; ++y) {
    for (int x = 0; x <= n; ++x) {
      const float u = float(x) / float(n), v = float(y) / float(n);
      const float h = 0.1f * std::sin(6.0f * u) * std::cos(4.0f * v);
      m.positions.insert(m.positions.end(), {u, v, h});
      const float dx = 0.6f * std::cos(6.0f * u) * std::cos(4.0f * v);
      const float dy = -0.4f * std::sin(6.0f * u) * std::sin(4.0f * v);
      const float len = std::sqrt(dx * dx + dy * dy + 1.0f);
      m.normals.insert(m.normals.end(), {-dx / len, -dy / len, 1.0f / len});
      m.uvs.insert(m.uvs.end(), {u, 1.0f - v});
    }
  }
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const uint32_t a = uint32_t(y * (n + 1) + x), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
      m.indices.insert(m.indices.end(), {a, b, d, a, d, c});
    }
  }
  return m;
}

// A .glb (JSON chunk + BIN chunk) as a one-file GltfSource.
inline GltfSource GlbSource(const nlohmann::json& j, std::vector<uint8_t> bin,
                            const std::string& name = "m.glb") {
  std::string text = j.dump();
  text.resize((text.size() + 3) & ~size_t(3), ' ');
  bin.resize((bin.size() + 3) & ~size_t(3), 0);
  std::vector<uint8_t> out = {'g', 'l', 'T', 'F'};
  auto u32 = [&](uint32_t v) {
    for (int k = 0; k < 4; ++k) out.push_back(uint8_t(v >> (8 * k)));
  };
  u32(2);
  u32(uint32_t(12 + 8 + text.size() + 8 + bin.size()));
  u32(uint32_t(text.size()));
  u32(0x4E4F534Au);
  out.insert(out.end(), text.begin(), text.end());
  u32(uint32_t(bin.size()));
  u32(0x004E4942u);
  out.insert(out.end(), bin.begin(), bin.end());
  GltfSource src;
  src.main_file = name;
  src.files[name] = std::move(out);
  return src;
}

// The parts of a hand-built file, to edit before making it a source.
struct BuiltFile {
  nlohmann::json j;
  std::vector<uint8_t> bin;
  GltfSource Glb() const { return GlbSource(j, bin); }
  // The same as a .gltf with its compressed data in data.bin (the fallback keeps no uri).
  GltfSource Gltf() const {
    nlohmann::json t = j;
    t["buffers"][0]["uri"] = "data.bin";
    std::vector<uint8_t> data = bin;
    data.resize(t["buffers"][0]["byteLength"].get<size_t>(), 0);
    const std::string text = t.dump();
    GltfSource src;
    src.main_file = "m.gltf";
    src.files["m.gltf"].assign(text.begin(), text.end());
    src.files["data.bin"] = std::move(data);
    return src;
  }
};

inline size_t Append(std::vector<uint8_t>* bin, const std::vector<uint8_t>& bytes) {
  bin->resize((bin->size() + 3) & ~size_t(3), 0);
  const size_t at = bin->size();
  bin->insert(bin->end(), bytes.begin(), bytes.end());
  return at;
}

// EXT_meshopt_compression as gltfpack and glTF Transform write it: the compressed streams in
// buffers[0] (the BIN chunk), a fallback buffers[1] without data that four bufferViews decode
// into: positions (FLOAT, ATTRIBUTES), normals (normalized BYTE x4 through the OCTAHEDRAL filter,
// 8 bits, so KHR_mesh_quantization too), texture coordinates (FLOAT) and indices (UNSIGNED_INT,
// TRIANGLES).
inline BuiltFile MeshoptFile(const TestMesh& m) {
  const size_t n = m.vertices();
  BuiltFile f;
  nlohmann::json views = nlohmann::json::array();
  size_t decoded = 0;
  auto add = [&](const std::vector<uint8_t>& encoded, size_t stride, size_t count,
                 const char* mode, const char* filter) {
    const size_t at = Append(&f.bin, encoded);
    nlohmann::json ext = {{"buffer", 0}, {"byteOffset", at}, {"byteLength", encoded.size()},
                          {"byteStride", stride}, {"count", count}, {"mode", mode}};
    if (filter) ext["filter"] = filter;
    nlohmann::json view = {{"buffer", 1}, {"byteOffset", decoded}, {"byteLength", stride * count},
                           {"extensions", {{"EXT_meshopt_compression", ext}}}};
    if (std::string(mode) == "ATTRIBUTES") view["byteStride"] = stride;
    views.push_back(view);
    decoded += (stride * count + 3) & ~size_t(3);
  };
  auto vertices = [](const void* data, size_t count, size_t stride) {
    std::vector<uint8_t> out(meshopt_encodeVertexBufferBound(count, stride));
    out.resize(meshopt_encodeVertexBuffer(out.data(), out.size(), data, count, stride));
    return out;
  };
  add(vertices(m.positions.data(), n, 12), 12, n, "ATTRIBUTES", nullptr);
  std::vector<float> n4;
  for (size_t i = 0; i < n; ++i) {
    n4.insert(n4.end(), {m.normals[3 * i], m.normals[3 * i + 1], m.normals[3 * i + 2], 0.0f});
  }
  std::vector<int8_t> oct(4 * n);
  meshopt_encodeFilterOct(oct.data(), n, 4, 8, n4.data());
  add(vertices(oct.data(), n, 4), 4, n, "ATTRIBUTES", "OCTAHEDRAL");
  add(vertices(m.uvs.data(), n, 8), 8, n, "ATTRIBUTES", nullptr);
  std::vector<uint8_t> idx(meshopt_encodeIndexBufferBound(m.indices.size(), n));
  idx.resize(meshopt_encodeIndexBuffer(idx.data(), idx.size(), m.indices.data(), m.indices.size()));
  add(idx, 4, m.indices.size(), "TRIANGLES", nullptr);
  f.bin.resize((f.bin.size() + 3) & ~size_t(3), 0);
  f.j = {
      {"asset", {{"version", "2.0"}}},
      {"extensionsUsed", {"EXT_meshopt_compression", "KHR_mesh_quantization"}},
      {"extensionsRequired", {"EXT_meshopt_compression", "KHR_mesh_quantization"}},
      {"buffers",
       {{{"byteLength", f.bin.size()}},
        {{"byteLength", decoded}, {"extensions", {{"EXT_meshopt_compression", {{"fallback", true}}}}}}}},
      {"bufferViews", views},
      {"accessors",
       {{{"bufferView", 0}, {"componentType", 5126}, {"count", n}, {"type", "VEC3"},
         {"min", Bound(m, false)}, {"max", Bound(m, true)}},
        {{"bufferView", 1}, {"componentType", 5120}, {"normalized", true}, {"count", n},
         {"type", "VEC3"}},
        {{"bufferView", 2}, {"componentType", 5126}, {"count", n}, {"type", "VEC2"}},
        {{"bufferView", 3}, {"componentType", 5125}, {"count", m.indices.size()},
         {"type", "SCALAR"}}}},
      {"meshes",
       {{{"primitives",
          {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}}}, {"indices", 3}}}}}}},
      {"nodes", {{{"mesh", 0}}}}};
  return f;
}

// KHR_draco_mesh_compression as glTF Transform writes it: accessors without bufferViews, the
// Draco data in a bufferView of buffers[0]. Sequential encoding keeps the faces in order; no
// quantization, so the decoded values are the grid's own.
inline BuiltFile DracoFile(const TestMesh& m) {
  draco::TriangleSoupMeshBuilder builder;
  const int faces = int(m.indices.size() / 3);
  builder.Start(faces);
  const int pos = builder.AddAttribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  const int nrm = builder.AddAttribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
  const int uv = builder.AddAttribute(draco::GeometryAttribute::TEX_COORD, 2, draco::DT_FLOAT32);
  for (int f = 0; f < faces; ++f) {
    const uint32_t* t = &m.indices[3 * size_t(f)];
    builder.SetAttributeValuesForFace(pos, draco::FaceIndex(f), &m.positions[3 * t[0]],
                                      &m.positions[3 * t[1]], &m.positions[3 * t[2]]);
    builder.SetAttributeValuesForFace(nrm, draco::FaceIndex(f), &m.normals[3 * t[0]],
                                      &m.normals[3 * t[1]], &m.normals[3 * t[2]]);
    builder.SetAttributeValuesForFace(uv, draco::FaceIndex(f), &m.uvs[2 * t[0]],
                                      &m.uvs[2 * t[1]], &m.uvs[2 * t[2]]);
  }
  std::unique_ptr<draco::Mesh> mesh = builder.Finalize();
  draco::Encoder encoder;
  encoder.SetEncodingMethod(draco::MESH_SEQUENTIAL_ENCODING);
  draco::EncoderBuffer out;
  const draco::Status st = encoder.EncodeMeshToBuffer(*mesh, &out);
  if (!st.ok()) return {};
  BuiltFile f;
  f.bin.assign(out.data(), out.data() + out.size());
  const size_t points = mesh->num_points();
  f.j = {{"asset", {{"version", "2.0"}}},
         {"extensionsUsed", {"KHR_draco_mesh_compression"}},
         {"extensionsRequired", {"KHR_draco_mesh_compression"}},
         {"buffers", {{{"byteLength", (f.bin.size() + 3) & ~size_t(3)}}}},
         {"bufferViews", {{{"buffer", 0}, {"byteLength", f.bin.size()}}}},
         {"accessors",
          {{{"componentType", 5126}, {"count", points}, {"type", "VEC3"},
            {"min", Bound(m, false)}, {"max", Bound(m, true)}},
           {{"componentType", 5126}, {"count", points}, {"type", "VEC3"}},
           {{"componentType", 5126}, {"count", points}, {"type", "VEC2"}},
           {{"componentType", 5125}, {"count", m.indices.size()}, {"type", "SCALAR"}}}},
         {"meshes",
          {{{"primitives",
             {{{"attributes", {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}}},
               {"indices", 3},
               {"extensions",
                {{"KHR_draco_mesh_compression",
                  {{"bufferView", 0},
                   {"attributes",
                    {{"POSITION", mesh->attribute(pos)->unique_id()},
                     {"NORMAL", mesh->attribute(nrm)->unique_id()},
                     {"TEXCOORD_0", mesh->attribute(uv)->unique_id()}}}}}}}}}}}}},
         {"nodes", {{{"mesh", 0}}}}};
  return f;
}

}  // namespace tessera::testing

// Compressed glTF geometry: EXT_meshopt_compression and KHR_draco_mesh_compression, from files
// encoded here (compressed_sources.h) so that every decoded value is known, and each rule of the
// extensions' specifications the importer checks, broken one at a time. The Khronos validator
// does not look inside either extension, so these cases (not tests/gltf/agreement.mjs) are
// their conformance tests; glTF Transform's files are rendered in compressed_asset_tests.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "renderer/scene/gltf_import.h"
#include "tests/unit/compressed_sources.h"

namespace tessera {
namespace {

using nlohmann::json;
using testing::BuiltFile;
using testing::TestMesh;

void ExpectError(const absl::StatusOr<CpuScene>& r, absl::StatusCode code,
                 const std::vector<std::string>& needles) {
  ASSERT_FALSE(r.ok()) << "imported, but expected " << absl::StatusCodeToString(code);
  EXPECT_EQ(r.status().code(), code) << r.status();
  for (const std::string& n : needles) {
    EXPECT_NE(r.status().message().find(n), absl::string_view::npos)
        << "'" << n << "' not in: " << r.status().message();
  }
}

// The imported primitive is the grid: the same triangles in the same order (meshopt's index
// codec may rotate a triangle's corners, keeping its winding), positions and texture coordinates
// exact, normals within `normal_error`.
void ExpectGrid(const CpuScene& s, const TestMesh& m, float normal_error) {
  ASSERT_EQ(s.indices.size(), m.indices.size());
  auto position = [&](uint32_t k) {
    return glm::vec3(m.positions[3 * k], m.positions[3 * k + 1], m.positions[3 * k + 2]);
  };
  for (size_t t = 0; t < m.indices.size(); t += 3) {
    int rotation = -1;
    for (int r = 0; r < 3 && rotation < 0; ++r) {
      bool same = true;
      for (int c = 0; c < 3; ++c)
        same &= s.vertices[s.indices[t + c]].position == position(m.indices[t + (c + r) % 3]);
      if (same) rotation = r;
    }
    ASSERT_GE(rotation, 0) << "triangle " << t / 3 << " has other positions";
    for (int c = 0; c < 3; ++c) {
      const Vertex& v = s.vertices[s.indices[t + c]];
      const uint32_t k = m.indices[t + (c + rotation) % 3];
      ASSERT_EQ(v.uv0, glm::vec2(m.uvs[2 * k], m.uvs[2 * k + 1])) << "triangle " << t / 3;
      const glm::vec3 n(m.normals[3 * k], m.normals[3 * k + 1], m.normals[3 * k + 2]);
      ASSERT_LE(glm::length(v.normal - n), normal_error) << "triangle " << t / 3;
    }
  }
}

// One edit of a good file, and what the refusal must name.
struct Case {
  const char* what;
  std::function<void(BuiltFile&)> edit;
  std::vector<std::string> needles;
};

// Each edit of `good` alone is refused with INVALID_ARGUMENT naming the needles.
void ExpectEachRefused(const BuiltFile& good, const std::vector<Case>& cases) {
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    BuiltFile f = good;
    c.edit(f);
    ExpectError(ImportGltf(f.Glb()), absl::StatusCode::kInvalidArgument, c.needles);
  }
}

const TestMesh& Grid() {
  static const TestMesh m = testing::WavyGrid(12);  // 169 vertices, 288 triangles
  return m;
}

TEST(GltfCompressedMeshopt, DecodesIntoTheFallbackBuffer) {
  const BuiltFile f = testing::MeshoptFile(Grid());
  for (const GltfSource& src : {f.Glb(), f.Gltf()}) {
    SCOPED_TRACE(src.main_file);
    absl::StatusOr<CpuScene> s = ImportGltf(src);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(s->vertices.size(), Grid().vertices());
    // 8-bit octahedral normals: within 1/64 of the unit vector (the filter's error is ~1/127).
    ExpectGrid(*s, Grid(), 1.0f / 64.0f);
  }
}

// Each rule of EXT_meshopt_compression the importer checks, broken once, refused naming it.
TEST(GltfCompressedMeshopt, MalformedIsRefusedNamingTheField) {
  const BuiltFile good = testing::MeshoptFile(Grid());
  auto ext = [](json& j, int view) -> json& {
    return j["bufferViews"][view]["extensions"]["EXT_meshopt_compression"];
  };
  const std::vector<Case> cases = {
      {"unknown mode", [&](BuiltFile& f) { ext(f.j, 0)["mode"] = "QUADS"; },
       {"bufferViews[0].extensions.EXT_meshopt_compression.mode", "ATTRIBUTES, TRIANGLES or INDICES"}},
      {"stride not a multiple of 4",
       [&](BuiltFile& f) {
         ext(f.j, 0)["byteStride"] = 6;
         ext(f.j, 0)["count"] = 338;
         f.j["bufferViews"][0]["byteLength"] = 6 * 338;
       },
       {"bufferViews[0].extensions.EXT_meshopt_compression", "byteStride 6 for mode ATTRIBUTES"}},
      {"count x stride is not byteLength", [&](BuiltFile& f) { ext(f.j, 2)["count"] = 170; },
       {"bufferViews[2].extensions.EXT_meshopt_compression", "is not the bufferView's byteLength"}},
      {"triangles not a multiple of 3",
       [&](BuiltFile& f) {
         ext(f.j, 3)["count"] = 863;
         f.j["bufferViews"][3]["byteLength"] = 863 * 4;
       },
       {"bufferViews[3]", "count 863 for mode TRIANGLES"}},
      {"filter on indices", [&](BuiltFile& f) { ext(f.j, 3)["filter"] = "OCTAHEDRAL"; },
       {"bufferViews[3]", "needs mode ATTRIBUTES"}},
      {"octahedral on 12-byte elements", [&](BuiltFile& f) { ext(f.j, 0)["filter"] = "OCTAHEDRAL"; },
       {"bufferViews[0]", "byteStride 12 for filter OCTAHEDRAL"}},
      {"unknown filter", [&](BuiltFile& f) { ext(f.j, 1)["filter"] = "SPHERICAL"; },
       {"bufferViews[1].extensions.EXT_meshopt_compression.filter", "SPHERICAL"}},
      {"compressed data cut short",
       [&](BuiltFile& f) { ext(f.j, 0)["byteLength"] = ext(f.j, 0)["byteLength"].get<int>() / 2; },
       {"bufferViews[0].extensions.EXT_meshopt_compression", "does not decode"}},
      {"unknown codec version",
       [&](BuiltFile& f) { f.bin[ext(f.j, 0)["byteOffset"].get<size_t>()] = 0xa7; },
       {"bufferViews[0].extensions.EXT_meshopt_compression", "unsupported encoding version"}},
      {"compressed data past its buffer",
       [&](BuiltFile& f) { ext(f.j, 0)["byteOffset"] = f.bin.size() - 4; },
       {"bufferViews[0].extensions.EXT_meshopt_compression", "exceeds buffers[0]"}},
      {"compressed data in the fallback", [&](BuiltFile& f) { ext(f.j, 0)["buffer"] = 1; },
       {"bufferViews[0].extensions.EXT_meshopt_compression.buffer", "fallback buffer"}},
      {"plain view of the fallback",
       [&](BuiltFile& f) { f.j["bufferViews"].push_back({{"buffer", 1}, {"byteLength", 4}}); },
       {"bufferViews[4].buffer", "fallback buffer (no data), but this bufferView is not compressed"}},
      {"fallback not a boolean",
       [&](BuiltFile& f) { f.j["buffers"][1]["extensions"]["EXT_meshopt_compression"]["fallback"] = 1; },
       {"buffers[1].extensions.EXT_meshopt_compression.fallback", "not a boolean"}},
      {"image from a compressed view",
       [&](BuiltFile& f) {
         f.j["images"] = {{{"bufferView", 2}, {"mimeType", "image/png"}}};
       },
       {"images[0].bufferView", "meshopt-compressed"}},
      {"parent byteStride differs", [&](BuiltFile& f) { f.j["bufferViews"][0]["byteStride"] = 16; },
       {"bufferViews[0].byteStride", "is not the extension's byteStride (12)"}},
      {"more than the codec can encode",
       [&](BuiltFile& f) {
         ext(f.j, 2)["byteLength"] = 4;
         ext(f.j, 2)["count"] = 100000;
         f.j["bufferViews"][2]["byteLength"] = 800000;
         f.j["buffers"][1]["byteLength"] = 900000;
       },
       {"bufferViews[2].extensions.EXT_meshopt_compression", "more than meshopt's codecs"}},
      {"extension not declared",
       [&](BuiltFile& f) {
         f.j["extensionsUsed"] = {"KHR_mesh_quantization"};
         f.j["extensionsRequired"] = {"KHR_mesh_quantization"};
       },
       {"bufferViews[0].extensions.EXT_meshopt_compression", "not declared in extensionsUsed"}},
  };
  ExpectEachRefused(good, cases);
}

TEST(GltfCompressedMeshopt, FallbackBuffersAreBoundedBeforeAllocation) {
  BuiltFile f = testing::MeshoptFile(Grid());
  ImportLimits limits;
  limits.max_decoded_bytes = 1000;
  ExpectError(ImportGltf(f.Glb(), limits), absl::StatusCode::kResourceExhausted,
              {"bufferViews[", "max_decoded_bytes limit (1000)"});
  // A fallback claiming 2^60 bytes costs nothing: only what its bufferViews reach is allocated.
  f.j["buffers"][1]["byteLength"] = uint64_t(1) << 60;
  absl::StatusOr<CpuScene> s = ImportGltf(f.Glb());
  EXPECT_TRUE(s.ok()) << s.status();
}

TEST(GltfCompressedDraco, DecodesTheAccessors) {
  const BuiltFile f = testing::DracoFile(Grid());
  ASSERT_FALSE(f.bin.empty()) << "the Draco encoder failed";
  absl::StatusOr<CpuScene> s = ImportGltf(f.Glb());
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->vertices.size(), f.j["accessors"][0]["count"].get<size_t>());
  ExpectGrid(*s, Grid(), 1e-6f);  // no quantization: the values are exact
}

TEST(GltfCompressedDraco, MalformedIsRefusedNamingTheField) {
  const BuiltFile good = testing::DracoFile(Grid());
  ASSERT_FALSE(good.bin.empty());
  const std::string field = "meshes[0].primitives[0].extensions.KHR_draco_mesh_compression";
  auto ext = [](json& j) -> json& {
    return j["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"];
  };
  const std::vector<Case> cases = {
      {"bufferView out of range", [&](BuiltFile& f) { ext(f.j)["bufferView"] = 7; },
       {field + ".bufferView", "bufferView index 7 out of range"}},
      {"bufferView not a number", [&](BuiltFile& f) { ext(f.j)["bufferView"] = "0"; },
       {field + ".bufferView", "missing or not an integer"}},
      {"attributes missing", [&](BuiltFile& f) { ext(f.j).erase("attributes"); },
       {field + ".attributes", "missing or not an object"}},
      {"unknown Draco attribute id", [&](BuiltFile& f) { ext(f.j)["attributes"]["NORMAL"] = 9; },
       {field, "no attribute with id 9"}},
      {"attribute the primitive lacks", [&](BuiltFile& f) { ext(f.j)["attributes"]["COLOR_0"] = 1; },
       {field + ".attributes.COLOR_0", "the primitive has no COLOR_0 attribute"}},
      {"accessor count is not the points",
       [&](BuiltFile& f) {
         for (int a = 0; a < 3; ++a) f.j["accessors"][a]["count"] = f.j["accessors"][a]["count"].get<int>() + 1;
       },
       {field, "points"}},
      {"accessor counts differ", [&](BuiltFile& f) { f.j["accessors"][2]["count"] = 5; },
       {field, "accessors[2] has 5 elements"}},
      {"indices count is not the faces",
       [&](BuiltFile& f) { f.j["accessors"][3]["count"] = f.j["accessors"][3]["count"].get<int>() - 3; },
       {field, "indices"}},
      {"components differ", [&](BuiltFile& f) { f.j["accessors"][2]["type"] = "VEC3"; },
       {field, "has 2 components where its accessor has 3"}},
      {"triangle strip", [&](BuiltFile& f) { f.j["meshes"][0]["primitives"][0]["mode"] = 5; },
       {"meshes[0].primitives[0].mode", "only TRIANGLES"}},
      {"more indices than the accessor",
       [&](BuiltFile& f) { f.j["accessors"][3]["count"] = f.j["accessors"][3]["count"].get<int>() + 3; },
       {field, "indices"}},
      {"no indices", [&](BuiltFile& f) { f.j["meshes"][0]["primitives"][0].erase("indices"); },
       {"meshes[0].primitives[0]", "needs indices"}},
      {"data cut short",
       [&](BuiltFile& f) { f.j["bufferViews"][0]["byteLength"] = 40; },
       {field, "Draco"}},
      {"not Draco data",
       [&](BuiltFile& f) { std::fill(f.bin.begin(), f.bin.begin() + 16, uint8_t('x')); },
       {field, "Draco"}},
  };
  ExpectEachRefused(good, cases);
}

TEST(GltfCompressedDraco, DecodedSizeIsBoundedBeforeDecoding) {
  BuiltFile f = testing::DracoFile(Grid());
  // Not Draco data at all: the limit, checked first, is what refuses it.
  std::fill(f.bin.begin(), f.bin.end(), uint8_t(0xAB));
  ImportLimits limits;
  limits.max_decoded_bytes = 1000;
  ExpectError(ImportGltf(f.Glb(), limits), absl::StatusCode::kResourceExhausted,
              {"KHR_draco_mesh_compression", "max_decoded_bytes limit (1000)"});
}

// Both extensions are listed as supported (GetServerInfo, `tessera info`) and an unsupported
// one in extensionsUsed only is a warning.
TEST(GltfCompressed, ExtensionsAreListed) {
  const auto& names = SupportedGltfExtensions();
  EXPECT_NE(std::find(names.begin(), names.end(), "EXT_meshopt_compression"), names.end());
  EXPECT_NE(std::find(names.begin(), names.end(), "KHR_draco_mesh_compression"), names.end());
  BuiltFile f = testing::DracoFile(Grid());
  f.j["extensionsUsed"].push_back("KHR_texture_basisu");
  absl::StatusOr<CpuScene> s = ImportGltf(f.Glb());
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_FALSE(s->warnings.empty());
  EXPECT_NE(s->warnings[0].find("KHR_texture_basisu"), std::string::npos) << s->warnings[0];
}

}  // namespace
}  // namespace tessera

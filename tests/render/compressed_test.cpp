// Compressed and re-encoded glTF files made by a tool nobody here wrote (glTF Transform, run by
// tests/gltf/transform.mjs into $TESSERA_TRANSFORMED_DIR, a ctest fixture): Draco, meshopt
// (with KHR_mesh_quantization), quantize, and every attribute as a sparse accessor, of
// DamagedHelmet, Sponza and BoxTextured. Each must import with the original's triangles and
// about its vertices and bounds, and render like the original from the same camera.
//
// The bounds: glTF Transform quantizes positions to 14 bits, normals to 10 (Draco) or 8 bits
// (quantize, meshopt's octahedral filter) and texture coordinates to 12 bits. A 14-bit position
// moves by at most 1/32768 of the mesh's extent, a hundredth of a pixel here; 8-bit normals
// turn shading by up to about half a degree; 12-bit coordinates move a texel of a 2048-pixel
// texture by up to half a texel, and more where coordinates tile over a wide range (Sponza).
// Measured on lavapipe (each case prints its figures), plain PSNR against the original:
//   Draco 49.6 (BoxTextured), 50.4 (DamagedHelmet), 87.1 dB (Sponza);
//   meshopt and quantize 89.0, 45.4-46.1, 38.9 dB; sparse identical vertices.
// Planted decoder bugs, measured the same way: meshopt's octahedral filter skipped 18.8-22.7 dB;
// Draco texture coordinates off by 1% in u 19.4, 30.7, 37.2 dB. Hence 45 dB for Draco, 35 dB for
// meshopt and quantize (the quantized normals and coordinates cost them more), each about 4 dB
// under the worst good case and above every planted bug; sparse values must be exact.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "renderer/camera.h"
#include "renderer/image_io.h"
#include "renderer/scene/gltf_import.h"
#include "tests/render/golden.h"
#include "tests/render/shared_renderer.h"

namespace tessera {
namespace {

double MinPsnr(const std::string& variant) {
  if (variant == "draco") return 45.0;
  if (variant == "sparse") return 60.0;  // and the vertices are checked for equality
  if (variant == "instance") return 60.0;  // the same drawables, placed by the extension
  return 35.0;
}

struct Loaded {
  CpuScene cpu;
  SceneHandle scene;
};

std::string TransformedDir() { return Env("TESSERA_TRANSFORMED_DIR"); }

// The manifest transform.mjs wrote: "<asset>_<variant>" -> {original, file, command}.
const std::map<std::string, nlohmann::json>& Manifest() {
  static const std::map<std::string, nlohmann::json> entries = [] {
    std::map<std::string, nlohmann::json> out;
    absl::StatusOr<std::vector<uint8_t>> bytes = ReadFileBytes(TransformedDir() + "/manifest.json");
    if (!bytes.ok()) return out;
    const nlohmann::json m = nlohmann::json::parse(bytes->begin(), bytes->end());
    for (const nlohmann::json& f : m["files"]) {
      out[f["asset"].get<std::string>() + "_" + f["variant"].get<std::string>()] = f;
    }
    return out;
  }();
  return entries;
}

absl::StatusOr<Loaded> Load(const std::string& path) {
  absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
  if (!source.ok()) return source.status();
  absl::StatusOr<CpuScene> cpu = ImportGltf(*source);
  if (!cpu.ok()) return cpu.status();
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(*cpu);
  if (!scene.ok()) return scene.status();
  return Loaded{std::move(*cpu), std::move(*scene)};
}

// The originals, loaded once per binary (Sponza's textures take seconds to decode).
const Loaded& Original(const std::string& path) {
  static std::map<std::string, Loaded> cache;
  auto it = cache.find(path);
  if (it == cache.end()) {
    absl::StatusOr<Loaded> loaded = Load(path);
    EXPECT_TRUE(loaded.ok()) << loaded.status();
    it = cache.emplace(path, loaded.ok() ? std::move(*loaded) : Loaded{}).first;
  }
  return it->second;
}

struct Case {
  const char* asset;
  const char* variant;
};
void PrintTo(const Case& c, std::ostream* os) { *os << c.asset << "_" << c.variant; }

class CompressedAssetTest : public ::testing::TestWithParam<Case> {};

TEST_P(CompressedAssetTest, ImportsAndRendersLikeTheOriginal) {
  const Case& c = GetParam();
  const std::string key = std::string(c.asset) + "_" + c.variant;
  ASSERT_FALSE(TransformedDir().empty())
      << "TESSERA_TRANSFORMED_DIR is not set (ctest sets it; tests/gltf/transform.mjs fills it)";
  const auto entry = Manifest().find(key);
  ASSERT_NE(entry, Manifest().end()) << key << " is not in " << TransformedDir()
                                     << "/manifest.json";
  const nlohmann::json& e = entry->second;
  const Loaded& original = Original(e["original"].get<std::string>());
  ASSERT_NE(original.scene, nullptr);
  absl::StatusOr<Loaded> variant = Load(e["file"].get<std::string>());
  ASSERT_TRUE(variant.ok()) << variant.status() << " (made by: " << e["command"] << ")";

  // Counted against the original: the same triangles; the same vertices, except that Draco may
  // merge or split a few (its connectivity coder re-derives them from the faces).
  const CpuScene& a = original.cpu;
  const CpuScene& b = variant->cpu;
  EXPECT_EQ(b.indices.size() / 3, a.indices.size() / 3);
  EXPECT_EQ(b.drawables.size(), a.drawables.size());
  const double vertex_ratio = double(b.vertices.size()) / double(a.vertices.size());
  if (std::string(c.variant) == "draco") {
    EXPECT_NEAR(vertex_ratio, 1.0, 0.05);
  } else {
    EXPECT_EQ(b.vertices.size(), a.vertices.size());
  }
  // Bounds within the 14-bit quantization of the extent (and a float's rounding).
  const glm::vec3 extent = a.bounds.max - a.bounds.min;
  const float tolerance = glm::length(extent) * 2e-4f;
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(b.bounds.min[k], a.bounds.min[k], tolerance) << "bounds.min[" << k << "]";
    EXPECT_NEAR(b.bounds.max[k], a.bounds.max[k], tolerance) << "bounds.max[" << k << "]";
  }

  // The same camera for both: Sponza's atrium view, else the original's bounds framed.
  const bool sponza = std::string(c.asset) == "Sponza";
  Settings s;
  s.width = sponza ? 320 : 192;
  s.height = sponza ? 180 : 192;
  Camera camera = FrameBounds(a.bounds, 0.8f, float(s.width) / float(s.height),
                              glm::vec3(0.25f, 0.2f, 1.0f));
  if (sponza) {
    camera = Camera{};
    camera.eye = glm::vec3(9.0f, 1.6f, -0.4f);
    camera.target = glm::vec3(-5.0f, 3.5f, 0.3f);
  }
  Renderer& r = SharedRenderer();
  absl::StatusOr<Frame> want = r.Render(*original.scene, camera, s);
  absl::StatusOr<Frame> got = r.Render(*variant->scene, camera, s);
  ASSERT_TRUE(want.ok()) << want.status();
  ASSERT_TRUE(got.ok()) << got.status();
  absl::StatusOr<GoldenError> error = MeasureGoldenError(got->image, want->image);
  ASSERT_TRUE(error.ok()) << error.status();
  std::printf("%s: %zu -> %zu vertices, %zu triangles; %s\n", key.c_str(), a.vertices.size(),
              b.vertices.size(), b.indices.size() / 3, Describe(*error).c_str());
  const std::filesystem::path out_dir =
      std::filesystem::path(Env("TESSERA_TEST_OUTPUT_DIR", TESSERA_DEFAULT_OUTPUT_DIR)) /
      "compressed";
  std::filesystem::create_directories(out_dir);
  for (const auto& [name, image] : {std::pair{key, &got->image},
                                    std::pair{std::string(c.asset) + "_original", &want->image}}) {
    if (auto png = EncodePng(*image); png.ok())
      (void)WriteFileBytes((out_dir / (name + ".png")).string(), *png);
  }
  EXPECT_GE(error->plain_psnr, MinPsnr(c.variant)) << key << " (made by: " << e["command"] << ")";
  if (std::string(c.variant) == "sparse") {  // the sparse blocks hold the exact values
    ASSERT_EQ(b.vertices.size(), a.vertices.size());
    size_t differ = 0;
    for (size_t i = 0; i < a.vertices.size(); ++i) {
      differ += a.vertices[i].position != b.vertices[i].position ||
                a.vertices[i].normal != b.vertices[i].normal || a.vertices[i].uv0 != b.vertices[i].uv0;
    }
    EXPECT_EQ(differ, 0u) << "vertices differ from the original's";
  }
  ExpectNoValidationMessages(r);
}

std::vector<Case> AllCases() {
  std::vector<Case> cases;
  for (const char* asset : {"BoxTextured", "DamagedHelmet", "Sponza"})
    for (const char* variant : {"draco", "meshopt", "quantize", "sparse"})
      cases.push_back({asset, variant});
  cases.push_back({"BoxGrid", "instance"});  // EXT_mesh_gpu_instancing
  for (const char* variant : {"draco", "meshopt", "quantize"})
    cases.push_back({"HelmetColors", variant});  // COLOR_0, quantized and compressed
  return cases;
}

INSTANTIATE_TEST_SUITE_P(Transformed, CompressedAssetTest, ::testing::ValuesIn(AllCases()),
                         [](const ::testing::TestParamInfo<Case>& info) {
                           return std::string(info.param.asset) + "_" + info.param.variant;
                         });

}  // namespace
}  // namespace tessera

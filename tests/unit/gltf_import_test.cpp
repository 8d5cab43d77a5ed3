// glTF import: every sample asset in every variant, feature checks, and malformed input.
// Expected counts come from the assets README table (nodes, meshes, triangles drawn) and from
// parsing each file's JSON here with nlohmann (materials, textures, images, primitives), never
// from the importer itself.
#include "renderer/scene/gltf_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "renderer/image_io.h"
#include "renderer/scene/animation.h"
#include "renderer/scene/scene_animator.h"
#include "tests/unit/compressed_sources.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The assets directory: $TESSERA_ASSETS_DIR, else the one the build was configured with.
// Every test that needs it fails (not skips) when it is missing.
std::string AssetsDir() {
  const char* dir = std::getenv("TESSERA_ASSETS_DIR");
  return dir == nullptr ? std::string(TESSERA_DEFAULT_ASSETS_DIR) : std::string(dir);
}

#define REQUIRE_ASSETS()                                                       \
  ASSERT_FALSE(AssetsDir().empty())                                            \
      << "TESSERA_ASSETS_DIR is not set (point it at the glTF sample assets)"; \
  ASSERT_TRUE(fs::is_directory(AssetsDir())) << AssetsDir() << " is not a directory"

// From /work/shared/assets/README.md: nodes / meshes / triangles drawn, plus cameras placed.
struct ModelInfo {
  const char* name;
  uint32_t nodes;
  uint32_t meshes;
  uint64_t triangles;
  uint32_t cameras;
};
constexpr ModelInfo kModels[] = {
    {"Sponza", 1, 1, 262267, 0},
    {"DamagedHelmet", 1, 1, 15452, 0},
    {"Box", 2, 1, 12, 0},
    {"BoxTextured", 2, 1, 12, 0},
    {"AlphaBlendModeTest", 9, 9, 61, 0},
    {"MetalRoughSpheresNoTextures", 119, 102, 1040409, 0},
    {"TextureCoordinateTest", 5, 5, 10, 0},
    {"OrientationTest", 13, 13, 524, 0},
    {"SimpleMeshes", 2, 1, 2, 0},
    {"TextureTransformTest", 12, 9, 24, 0},
    {"MultiUVTest", 3, 1, 12, 1},  // node "Correction_Camera" places the one camera
};

std::vector<uint8_t> ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

// The JSON of a .gltf or of a .glb's first chunk.
json FileJson(const std::vector<uint8_t>& d) {
  if (d.size() >= 20 && std::memcmp(d.data(), "glTF", 4) == 0) {
    uint32_t len;
    std::memcpy(&len, &d[12], 4);
    return json::parse(d.begin() + 20, d.begin() + 20 + len);
  }
  return json::parse(d.begin(), d.end());
}

size_t ArraySize(const json& j, const char* key) { return j.contains(key) ? j[key].size() : 0; }

// Every variant of a model that is present: glTF/, glTF-Binary/, glTF-Embedded/.
std::vector<fs::path> Variants(const std::string& model) {
  std::vector<fs::path> out;
  for (const char* v : {"glTF", "glTF-Binary", "glTF-Embedded"}) {
    const fs::path dir = fs::path(AssetsDir()) / model / v;
    if (!fs::is_directory(dir)) continue;
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string ext = e.path().extension().string();
      if (ext == ".gltf" || ext == ".glb") out.push_back(e.path());
    }
  }
  return out;
}

absl::StatusOr<CpuScene> ImportFile(const fs::path& path) {
  absl::StatusOr<GltfSource> src = LoadGltfSourceFromDisk(path.string());
  if (!src.ok()) return src.status();
  return ImportGltf(*src);
}

// Sponza decodes 69 textures: import it once per test binary.
const absl::StatusOr<CpuScene>& SponzaScene() {
  static const absl::StatusOr<CpuScene>* scene =
      new absl::StatusOr<CpuScene>(ImportFile(fs::path(AssetsDir()) / "Sponza/glTF/Sponza.gltf"));
  return *scene;
}

bool Finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Structural invariants every imported scene must satisfy.
void ExpectValidScene(const CpuScene& s) {
  ASSERT_FALSE(s.bounds.empty());
  EXPECT_TRUE(Finite(s.bounds.min) && Finite(s.bounds.max));
  size_t bad_normals = 0, bad_tangents = 0;
  for (const Vertex& v : s.vertices) {
    if (std::abs(glm::length(v.normal) - 1.0f) > 1e-3f) ++bad_normals;
    if (std::abs(glm::length(glm::vec3(v.tangent)) - 1.0f) > 1e-3f ||
        std::abs(std::abs(v.tangent.w) - 1.0f) > 0.0f) {
      ++bad_tangents;
    }
  }
  EXPECT_EQ(bad_normals, 0u);
  EXPECT_EQ(bad_tangents, 0u);
  for (size_t i = 0; i < s.primitives.size(); ++i) {
    const Primitive& p = s.primitives[i];
    SCOPED_TRACE("primitive " + std::to_string(i));
    ASSERT_LE(uint64_t(p.first_vertex) + p.vertex_count, s.vertices.size());
    ASSERT_LE(uint64_t(p.first_index) + p.index_count, s.indices.size());
    EXPECT_EQ(p.index_count % 3, 0u);
    EXPECT_LT(p.material, s.materials.size());
    uint32_t max_index = 0;
    for (uint32_t k = 0; k < p.index_count; ++k) {
      max_index = std::max(max_index, s.indices[p.first_index + k]);
    }
    if (p.index_count > 0) {
      EXPECT_LT(max_index, p.vertex_count);
    }
  }
  uint64_t triangles = 0;
  for (const Drawable& d : s.drawables) {
    ASSERT_LT(d.primitive, s.primitives.size());
    ASSERT_LT(d.mesh, s.meshes.size());
    EXPECT_LT(s.primitives[d.primitive].material, s.materials.size());
    triangles += s.primitives[d.primitive].index_count / 3;
  }
  EXPECT_EQ(triangles, s.counts.triangles);
  for (const Texture& t : s.textures) {
    ASSERT_NE(t.image, nullptr);
    EXPECT_EQ(t.image->rgba8.size(), size_t(t.image->width) * t.image->height * 4);
  }
  for (const Material& m : s.materials) {
    for (const TextureRef* r : m.TextureSlots()) {
      EXPECT_GE(r->texture, -1);
      EXPECT_LT(r->texture, int32_t(s.textures.size()));
      EXPECT_LE(r->texcoord, 1u);
    }
    if (m.base_color.texture >= 0) {
      EXPECT_TRUE(s.textures[m.base_color.texture].srgb);
    }
    if (m.normal.texture >= 0) {
      EXPECT_FALSE(s.textures[m.normal.texture].srgb);
    }
  }
}

class GltfImportModelTest : public ::testing::TestWithParam<ModelInfo> {};

TEST_P(GltfImportModelTest, EveryVariantImportsWithTheFilesCounts) {
  REQUIRE_ASSETS();
  const ModelInfo& info = GetParam();
  const std::vector<fs::path> variants = Variants(info.name);
  ASSERT_FALSE(variants.empty()) << "no variant of " << info.name << " found";
  for (const fs::path& path : variants) {
    SCOPED_TRACE(path.string());
    const json j = FileJson(ReadBytes(path));
    size_t primitives = 0;
    bool uses_default_material = false;
    for (const json& mesh : j["meshes"]) {
      primitives += mesh["primitives"].size();
      for (const json& p : mesh["primitives"]) uses_default_material |= !p.contains("material");
    }
    absl::StatusOr<CpuScene> imported;
    const bool sponza = std::string(info.name) == "Sponza";
    if (!sponza) imported = ImportFile(path);
    const absl::StatusOr<CpuScene>& scene = sponza ? SponzaScene() : imported;
    ASSERT_TRUE(scene.ok()) << scene.status();
    const SceneCounts& c = scene->counts;
    EXPECT_EQ(c.nodes, info.nodes);
    EXPECT_EQ(c.nodes, ArraySize(j, "nodes"));
    EXPECT_EQ(c.meshes, info.meshes);
    EXPECT_EQ(c.meshes, ArraySize(j, "meshes"));
    EXPECT_EQ(c.triangles, info.triangles);
    EXPECT_EQ(c.primitives, primitives);
    EXPECT_EQ(c.materials, ArraySize(j, "materials"));
    EXPECT_EQ(scene->materials.size(), c.materials + (uses_default_material ? 1 : 0));
    EXPECT_EQ(c.textures, ArraySize(j, "textures"));
    EXPECT_EQ(c.images, ArraySize(j, "images"));
    EXPECT_EQ(c.cameras, info.cameras);
    EXPECT_EQ(scene->cameras.size(), info.cameras);
    EXPECT_EQ(c.lights, 0u);
    EXPECT_EQ(scene->name, path.filename().string());
    ExpectValidScene(*scene);
  }
}

INSTANTIATE_TEST_SUITE_P(Assets, GltfImportModelTest, ::testing::ValuesIn(kModels),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(GltfImportAssets, EveryModelDirectoryIsCovered) {
  REQUIRE_ASSETS();
  for (const auto& e : fs::directory_iterator(AssetsDir())) {
    if (!e.is_directory()) continue;
    const std::string name = e.path().filename().string();
    bool known = false;
    for (const ModelInfo& m : kModels) known |= name == m.name;
    EXPECT_TRUE(known) << name << " has no entry in kModels";
  }
}

TEST(GltfImportAssets, SponzaDetails) {
  REQUIRE_ASSETS();
  const absl::StatusOr<CpuScene>& s = SponzaScene();
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->primitives.size(), 103u);
  EXPECT_EQ(s->vertices.size(), 192812u);  // README: every primitive has NORMAL
  EXPECT_EQ(s->drawables.size(), 103u);
  // README: scene bounds after the node scale, x -15.37..14.40, y -1.01..11.44 (metres).
  EXPECT_NEAR(s->bounds.min.x, -15.37f, 0.02f);
  EXPECT_NEAR(s->bounds.max.y, 11.44f, 0.02f);
  size_t mask = 0;
  for (const Material& m : s->materials) mask += m.alpha_mode == AlphaMode::kMask;
  EXPECT_EQ(mask, 3u);
}

absl::StatusOr<CpuScene> ImportAsset(const std::string& rel) {
  return ImportFile(fs::path(AssetsDir()) / rel);
}

const Material* FindMaterial(const CpuScene& s, const std::string& name) {
  for (const Material& m : s.materials) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

TEST(GltfImportFeatures, TextureTransform) {
  REQUIRE_ASSETS();
  absl::StatusOr<CpuScene> s = ImportAsset("TextureTransformTest/glTF/TextureTransformTest.gltf");
  ASSERT_TRUE(s.ok()) << s.status();
  const Material* offset_u = FindMaterial(*s, "Offset U");
  const Material* rotation = FindMaterial(*s, "Rotation");
  const Material* all = FindMaterial(*s, "All");
  ASSERT_TRUE(offset_u && rotation && all);
  EXPECT_EQ(offset_u->base_color.offset, glm::vec2(0.5f, 0.0f));
  EXPECT_FLOAT_EQ(rotation->base_color.rotation, 0.39269908f);
  EXPECT_EQ(all->base_color.offset, glm::vec2(-0.2f, -0.1f));
  EXPECT_EQ(all->base_color.scale, glm::vec2(1.5f, 1.5f));
  EXPECT_FLOAT_EQ(all->base_color.rotation, 0.3f);
  ASSERT_GE(offset_u->base_color.texture, 0);
  EXPECT_EQ(s->textures[offset_u->base_color.texture].wrap_s, WrapMode::kClampToEdge);
  const Material* correct = FindMaterial(*s, "Correct");
  ASSERT_TRUE(correct && correct->base_color.texture >= 0);
  EXPECT_EQ(s->textures[correct->base_color.texture].wrap_s, WrapMode::kRepeat);  // no sampler
  // No NORMAL in this file: flat normals, one vertex per triangle corner.
  for (const Primitive& p : s->primitives) {
    EXPECT_EQ(p.vertex_count, p.index_count);
    for (uint32_t t = 0; t < p.index_count; t += 3) {
      const Vertex* v = &s->vertices[p.first_vertex + s->indices[p.first_index + t]];
      const glm::vec3 face =
          glm::cross(v[1].position - v[0].position, v[2].position - v[0].position);
      EXPECT_GT(glm::dot(face, v[0].normal), 0.0f);
    }
  }
}

TEST(GltfImportFeatures, MultiUvEmissiveUsesTexCoord1) {
  REQUIRE_ASSETS();
  absl::StatusOr<CpuScene> s = ImportAsset("MultiUVTest/glTF/MultiUVTest.gltf");
  ASSERT_TRUE(s.ok()) << s.status();
  const Material* m = FindMaterial(*s, "Material");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->base_color.texcoord, 0u);
  EXPECT_EQ(m->emissive.texcoord, 1u);
  ASSERT_GE(m->emissive.texture, 0);
  EXPECT_TRUE(s->textures[m->emissive.texture].srgb);
  EXPECT_EQ(s->textures.size(), 2u);
  ASSERT_EQ(s->cameras.size(), 1u);
  EXPECT_NEAR(s->cameras[0].yfov, 0.50338f, 1e-4f);
  EXPECT_NEAR(s->cameras[0].world[3].x, 7.4811f, 1e-3f);  // the parent node's translation
}

TEST(GltfImportFeatures, AlphaModes) {
  REQUIRE_ASSETS();
  absl::StatusOr<CpuScene> s = ImportAsset("AlphaBlendModeTest/glTF/AlphaBlendModeTest.gltf");
  ASSERT_TRUE(s.ok()) << s.status();
  const Material* blend = FindMaterial(*s, "MatBlend");
  const Material* c25 = FindMaterial(*s, "MatCutoff25");
  const Material* c75 = FindMaterial(*s, "MatCutoff75");
  const Material* cdef = FindMaterial(*s, "MatCutoffDefault");
  const Material* opaque = FindMaterial(*s, "MatOpaque");
  ASSERT_TRUE(blend && c25 && c75 && cdef && opaque);
  EXPECT_EQ(blend->alpha_mode, AlphaMode::kBlend);
  EXPECT_TRUE(blend->double_sided);
  EXPECT_EQ(c25->alpha_mode, AlphaMode::kMask);
  EXPECT_FLOAT_EQ(c25->alpha_cutoff, 0.25f);
  EXPECT_FLOAT_EQ(c75->alpha_cutoff, 0.75f);
  EXPECT_FLOAT_EQ(cdef->alpha_cutoff, 0.5f);
  EXPECT_EQ(opaque->alpha_mode, AlphaMode::kOpaque);
  // Used (texture, sRGB) pairs: 0 normal, 1 occlusion + metallic-roughness, 2 and 3 base colour.
  EXPECT_EQ(s->textures.size(), 4u);
  const Material* bed = FindMaterial(*s, "MatBed");
  ASSERT_NE(bed, nullptr);
  EXPECT_EQ(bed->occlusion.texture, bed->metallic_roughness.texture);
}

TEST(GltfImportFeatures, BoxTexturedHasOneSrgbTexture) {
  REQUIRE_ASSETS();
  for (const fs::path& path : Variants("BoxTextured")) {
    SCOPED_TRACE(path.string());
    absl::StatusOr<CpuScene> s = ImportFile(path);
    ASSERT_TRUE(s.ok()) << s.status();
    ASSERT_EQ(s->textures.size(), 1u);
    EXPECT_TRUE(s->textures[0].srgb);
    EXPECT_EQ(s->textures[0].image->width, 256u);
    EXPECT_EQ(s->textures[0].wrap_s, WrapMode::kRepeat);
    EXPECT_EQ(s->materials[0].base_color.texture, 0);
    // Generated tangents follow dP/du of each triangle.
    for (size_t t = 0; t < s->indices.size(); t += 3) {
      const Vertex& a = s->vertices[s->indices[t]];
      const Vertex& b = s->vertices[s->indices[t + 1]];
      const Vertex& c = s->vertices[s->indices[t + 2]];
      const glm::vec2 d1 = b.uv0 - a.uv0, d2 = c.uv0 - a.uv0;
      const float r = d1.x * d2.y - d2.x * d1.y;
      if (std::abs(r) < 1e-6f) continue;
      const glm::vec3 dpdu =
          ((b.position - a.position) * d2.y - (c.position - a.position) * d1.y) / r;
      EXPECT_GT(glm::dot(glm::vec3(a.tangent), dpdu), 0.0f) << "triangle " << t / 3;
    }
  }
}

// ----- Sources edited in memory ---------------------------------------------------------------

GltfSource Source(const std::string& rel) {
  absl::StatusOr<GltfSource> s = LoadGltfSourceFromDisk((fs::path(AssetsDir()) / rel).string());
  EXPECT_TRUE(s.ok()) << s.status();
  return s.ok() ? *s : GltfSource{};
}

GltfSource Edited(GltfSource src, const std::function<void(json&)>& edit) {
  std::vector<uint8_t>& main = src.files[src.main_file];
  json j = json::parse(main.begin(), main.end());
  edit(j);
  const std::string text = j.dump();
  main.assign(text.begin(), text.end());
  return src;
}

void ExpectError(const absl::StatusOr<CpuScene>& r, absl::StatusCode code,
                 const std::vector<std::string>& needles) {
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), code) << r.status();
  for (const std::string& n : needles) {
    EXPECT_NE(r.status().message().find(n), absl::string_view::npos)
        << "'" << n << "' not in: " << r.status().message();
  }
}

void ExpectInvalid(const absl::StatusOr<CpuScene>& r, const std::vector<std::string>& needles) {
  ExpectError(r, absl::StatusCode::kInvalidArgument, needles);
}

// Over one of the ImportLimits: RESOURCE_EXHAUSTED naming it.
void ExpectOverLimit(const absl::StatusOr<CpuScene>& r, const std::vector<std::string>& needles) {
  ExpectError(r, absl::StatusCode::kResourceExhausted, needles);
}

// A minimal PNG header (signature + IHDR + IEND); stb_image reads dimensions from IHDR.
std::vector<uint8_t> PngHeader(uint32_t w, uint32_t h) {
  std::vector<uint8_t> d = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  auto be32 = [&](uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) d.push_back(uint8_t(v >> s));
  };
  auto chunk = [&](const char* type, const std::vector<uint8_t>& body) {
    be32(uint32_t(body.size()));
    const size_t start = d.size();
    d.insert(d.end(), type, type + 4);
    d.insert(d.end(), body.begin(), body.end());
    uint32_t crc = 0xFFFFFFFFu;
    for (size_t i = start; i < d.size(); ++i) {
      crc ^= d[i];
      for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    be32(~crc);
  };
  std::vector<uint8_t> ihdr;
  for (uint32_t v : {w, h}) {
    for (int s = 24; s >= 0; s -= 8) ihdr.push_back(uint8_t(v >> s));
  }
  ihdr.insert(ihdr.end(), {8, 6, 0, 0, 0});
  chunk("IHDR", ihdr);
  chunk("IEND", {});
  return d;
}

// A self-contained glTF: 4 positions (a quad) in a base64 buffer, one primitive of `mode`.
GltfSource QuadSource(int mode) {
  const float pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::string raw(reinterpret_cast<const char*>(pos), sizeof(pos));
  static const char* kB64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string b64;
  for (size_t i = 0; i < raw.size(); i += 3) {
    uint32_t v = uint8_t(raw[i]) << 16;
    if (i + 1 < raw.size()) v |= uint8_t(raw[i + 1]) << 8;
    if (i + 2 < raw.size()) v |= uint8_t(raw[i + 2]);
    for (int k = 0; k < 4; ++k) {
      b64 += i + k <= raw.size() ? kB64[(v >> (18 - 6 * k)) & 63] : '=';
    }
  }
  json j = {
      {"asset", {{"version", "2.0"}}},
      {"buffers", {{{"byteLength", 48}, {"uri", "data:application/octet-stream;base64," + b64}}}},
      {"bufferViews", {{{"buffer", 0}, {"byteLength", 48}}}},
      {"accessors", {{{"bufferView", 0}, {"componentType", 5126}, {"count", 4}, {"type", "VEC3"}}}},
      {"meshes", {{{"primitives", {{{"attributes", {{"POSITION", 0}}}, {"mode", mode}}}}}}},
      {"nodes", {{{"mesh", 0}}}}};
  const std::string text = j.dump();
  GltfSource src;
  src.main_file = "quad.gltf";
  src.files["quad.gltf"].assign(text.begin(), text.end());
  return src;
}

TEST(GltfImportFeatures, StripsAndFansBecomeLists) {
  // glTF 2.0 section 3.7.2.1: strip triangle i is (i, i+1+i%2, i+2-i%2), fan i is (i+1, i+2, 0).
  const std::map<int, std::vector<int>> expected = {{5, {0, 1, 2, 1, 3, 2}},
                                                    {6, {1, 2, 0, 2, 3, 0}}};
  const glm::vec3 quad[4] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0}};
  for (const auto& [mode, corners] : expected) {
    SCOPED_TRACE(mode);
    absl::StatusOr<CpuScene> s = ImportGltf(QuadSource(mode));
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(s->counts.triangles, 2u);
    ASSERT_EQ(s->indices.size(), 6u);
    EXPECT_EQ(s->materials.size(), 1u);  // the default material
    EXPECT_EQ(s->counts.materials, 0u);
    ExpectValidScene(*s);
    // No NORMAL: unwelded, so corner k of the list is vertex indices[k].
    for (size_t k = 0; k < 6; ++k) {
      EXPECT_EQ(s->vertices[s->indices[k]].position, quad[corners[k]]) << "corner " << k;
    }
  }
  absl::StatusOr<CpuScene> points = ImportGltf(QuadSource(0));
  ASSERT_TRUE(points.ok()) << points.status();
  EXPECT_TRUE(points->drawables.empty());
  EXPECT_FALSE(points->warnings.empty());
}

TEST(GltfImportFeatures, LightsAndImageSharing) {
  REQUIRE_ASSETS();
  GltfSource src = Edited(Source("BoxTextured/glTF/BoxTextured.gltf"), [](json& j) {
    j["extensionsUsed"] = {"KHR_lights_punctual", "EXT_made_up"};
    j["extensions"]["KHR_lights_punctual"]["lights"] = {
        {{"type", "spot"},
         {"color", {1, 0.5, 0}},
         {"intensity", 5},
         {"range", 10},
         {"spot", {{"innerConeAngle", 0.1}, {"outerConeAngle", 0.5}}}}};
    j["nodes"][0]["matrix"][12] = 1.0;  // translation (1, 2, 3)
    j["nodes"][0]["matrix"][13] = 2.0;
    j["nodes"][0]["matrix"][14] = 3.0;
    j["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] = 0;
    j["materials"][0]["pbrMetallicRoughness"]["metallicRoughnessTexture"]["index"] = 0;
  });
  absl::StatusOr<CpuScene> s = ImportGltf(src);
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->lights.size(), 1u);
  EXPECT_EQ(s->counts.lights, 1u);
  const Light& l = s->lights[0];
  EXPECT_EQ(l.type, LightType::kSpot);
  EXPECT_EQ(l.position, glm::vec3(1, 2, 3));
  EXPECT_NEAR(l.direction.y, -1.0f, 1e-6f);  // node maps local -Z to world -Y
  EXPECT_FLOAT_EQ(l.outer_cone_angle, 0.5f);
  EXPECT_FLOAT_EQ(l.intensity, 5.0f);
  // One glTF texture used as sRGB and as linear data: two Textures, one shared image.
  ASSERT_EQ(s->textures.size(), 2u);
  EXPECT_NE(s->textures[0].srgb, s->textures[1].srgb);
  EXPECT_EQ(s->textures[0].image, s->textures[1].image);
  bool warned = false;
  for (const std::string& w : s->warnings) warned |= w.find("EXT_made_up") != std::string::npos;
  EXPECT_TRUE(warned);
}

TEST(GltfImportFeatures, UriDecodingMatchesFileKeys) {
  REQUIRE_ASSETS();
  // '+' is literal in RFC 3986 (tinygltf decodes it as a space); %20 is a space.
  for (const std::string& uri : {std::string("a+b.bin"), std::string("a%20b.bin")}) {
    GltfSource src =
        Edited(Source("Box/glTF/Box.gltf"), [&](json& j) { j["buffers"][0]["uri"] = uri; });
    src.files[uri == "a+b.bin" ? "a+b.bin" : "a b.bin"] = src.files["Box0.bin"];
    src.files.erase("Box0.bin");
    absl::StatusOr<CpuScene> s = ImportGltf(src);
    EXPECT_TRUE(s.ok()) << uri << ": " << s.status();
  }
}

TEST(GltfImportFiles, DiskLoaderRefusesEscapingUris) {
  const fs::path dir = fs::temp_directory_path() / ("tessera_gltf_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path file = dir / "esc.gltf";
  std::ofstream(file)
      << R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":4,"uri":"../x.bin"}]})";
  absl::StatusOr<GltfSource> s = LoadGltfSourceFromDisk(file.string());
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.status().message().find("../x.bin"), absl::string_view::npos) << s.status();
  absl::StatusOr<GltfSource> missing = LoadGltfSourceFromDisk((dir / "nope.gltf").string());
  ASSERT_FALSE(missing.ok());
  EXPECT_NE(missing.status().message().find("nope.gltf"), absl::string_view::npos);
  // A file the .gltf names that is not beside it: the message names the field that names it.
  std::ofstream(dir / "lone.gltf") << R"({"asset":{"version":"2.0"},"buffers":[{"byteLength":4}],
      "images":[{"uri":"a.png"},{"uri":"gone%20too.png"}]})";
  std::ofstream(dir / "a.png") << "x";
  absl::StatusOr<GltfSource> lone = LoadGltfSourceFromDisk((dir / "lone.gltf").string());
  ASSERT_FALSE(lone.ok());
  EXPECT_EQ(lone.status().code(), absl::StatusCode::kNotFound) << lone.status();
  for (const char* needle : {"lone.gltf", "images[1].uri", "gone%20too.png", "gone too.png"})
    EXPECT_NE(lone.status().message().find(needle), absl::string_view::npos)
        << "'" << needle << "' not in: " << lone.status().message();
  fs::remove_all(dir);
}

// A .glb that is not one (a renamed .gltf, a text or HTML page) says so, with its first bytes,
// instead of a JSON error about whatever it holds.
TEST(GltfImportMalformed, GlbWithoutTheMagic) {
  GltfSource src;
  src.main_file = "model.glb";
  const std::string text = R"({"asset": {"version": "2.0"}, "scenes": [)";
  src.files["model.glb"].assign(text.begin(), text.end());
  ExpectInvalid(ImportGltf(src), {"model.glb", "not a GLB container", "7b 22 61 73", "'glTF'"});
  src.main_file = "model.GLB";
  src.files["model.GLB"] = src.files["model.glb"];
  ExpectInvalid(ImportGltf(src), {"model.GLB", "not a GLB container"});
}

// A directory stands for the glTF file in it (a multi-file asset is usually handed over as its
// folder); one without, or with several, is an error naming it; a directory is never read as a
// file (it once made the loader allocate whatever tellg() said).
TEST(GltfImportFiles, DiskLoaderTakesTheGltfInADirectory) {
  const fs::path box = fs::path(AssetsDir()) / "Box/glTF";
  absl::StatusOr<GltfSource> s = LoadGltfSourceFromDisk(box.string());
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->main_file, "Box.gltf");
  EXPECT_EQ(s->files.count("Box0.bin"), 1u);
  absl::StatusOr<CpuScene> scene = ImportGltf(*s);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->counts.triangles, 12u);

  const fs::path dir =
      fs::temp_directory_path() / ("tessera_gltf_dir_" + std::to_string(::getpid()));
  fs::create_directories(dir / "sub");
  absl::StatusOr<GltfSource> none = LoadGltfSourceFromDisk(dir.string());
  ASSERT_FALSE(none.ok());
  EXPECT_EQ(none.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(none.status().message().find(dir.string()), absl::string_view::npos) << none.status();
  std::ofstream(dir / "a.gltf") << "{}";
  std::ofstream(dir / "b.GLB") << "glTF";
  absl::StatusOr<GltfSource> two = LoadGltfSourceFromDisk(dir.string());
  ASSERT_FALSE(two.ok());
  EXPECT_EQ(two.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(two.status().message().find("a.gltf, b.GLB"), absl::string_view::npos) << two.status();
  // A directory named like a glTF file is not a file.
  fs::create_directories(dir / "c.gltf");
  fs::remove(dir / "a.gltf");
  fs::remove(dir / "b.GLB");
  absl::StatusOr<GltfSource> named = LoadGltfSourceFromDisk((dir / "c.gltf").string() + "/.");
  ASSERT_FALSE(named.ok());
  absl::StatusOr<GltfSource> not_file = LoadGltfSourceFromDisk("/dev/null");
  ASSERT_FALSE(not_file.ok());
  EXPECT_NE(not_file.status().message().find("not a regular file"), absl::string_view::npos)
      << not_file.status();
  fs::remove_all(dir);
}

// ----- Malformed input: every case must be INVALID_ARGUMENT naming the culprit. -----------

TEST(GltfImportMalformed, EmptyFile) {
  for (const char* name : {"empty.gltf", "empty.glb"}) {
    GltfSource src;
    src.main_file = name;
    src.files[name] = {};
    ExpectInvalid(ImportGltf(src), {name, "empty"});
  }
  ExpectInvalid(ImportGltf(GltfSource{"missing.gltf", {}}), {"missing.gltf"});
}

TEST(GltfImportMalformed, TruncatedGlb) {
  REQUIRE_ASSETS();
  const GltfSource full = Source("Box/glTF-Binary/Box.glb");
  const size_t size = full.files.at("Box.glb").size();
  ASSERT_TRUE(ImportGltf(full).ok());
  for (size_t len : {size_t(1), size_t(4), size_t(12), size_t(19), size_t(20), size_t(21),
                     size_t(100), size / 2, size - 100, size - 4, size - 1}) {
    SCOPED_TRACE(len);
    GltfSource cut = full;
    cut.files["Box.glb"].resize(len);
    ExpectInvalid(ImportGltf(cut), {"Box.glb"});
  }
}

TEST(GltfImportMalformed, BadJson) {
  for (const std::string& text :
       std::vector<std::string>{"{\"asset\": {\"version\": \"2.0\"", "not json", "[1, 2]", "{}",
                                "{\"x\": 1e400}"}) {
    GltfSource src;
    src.main_file = "bad.gltf";
    src.files["bad.gltf"].assign(text.begin(), text.end());
    ExpectInvalid(ImportGltf(src), {"bad.gltf"});
  }
  // Too deep for tinygltf's recursion: refused before any parser runs.
  GltfSource deep;
  deep.main_file = "deep.gltf";
  deep.files["deep.gltf"].assign(100000, '[');
  ExpectOverLimit(ImportGltf(deep), {"deep.gltf: JSON: ", "max_json_depth limit (64)"});
}

TEST(GltfImportMalformed, MissingBufferFile) {
  REQUIRE_ASSETS();
  GltfSource src = Source("Box/glTF/Box.gltf");
  src.files.erase("Box0.bin");
  ExpectInvalid(ImportGltf(src), {"Box.gltf", "buffers[0]", "Box0.bin", "not in the file set"});
}

TEST(GltfImportMalformed, AccessorAndBufferViewOutOfRange) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["accessors"][2]["count"] = 1000000; })),
                {"Box.gltf: accessors[2]", "exceeds bufferViews[1].byteLength (576)"});
  ExpectOverLimit(
      ImportGltf(Edited(box, [](json& j) { j["accessors"][2]["count"] = 4000000000u; })),
      {"accessors[2].count", "4000000000 elements exceed the max_accessor_elements limit"});
  // With the limits lifted the size overflows 64 bits, which is over any limit.
  ImportLimits unlimited;
  unlimited.max_accessor_elements = unlimited.max_accessor_bytes = UINT64_MAX;
  ExpectOverLimit(ImportGltf(Edited(box,
                                    [](json& j) {
                                      j["accessors"][2]["count"] = 0x7fffffffffffffffull;
                                    }),
                             unlimited),
                  {"accessors[2]", "max_accessor_bytes limit"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["accessors"][2]["byteOffset"] = 300; })),
                {"accessors[2]"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["bufferViews"][0]["byteLength"] = 1000; })),
                {"bufferViews[0]", "buffers[0].byteLength (648)"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["bufferViews"][1]["buffer"] = 3; })),
                {"bufferViews[1].buffer"});
}

TEST(GltfImportMalformed, IndexValueOutOfRange) {
  REQUIRE_ASSETS();
  GltfSource src = Source("Box/glTF/Box.gltf");
  std::vector<uint8_t>& bin = src.files["Box0.bin"];
  bin[576 + 10] = 0xE7;  // index 5 (uint16 at bufferView 0 offset 576) becomes 999
  bin[576 + 11] = 0x03;
  // The accessor's declared max (23) no longer matches: refused for that first.
  ExpectInvalid(ImportGltf(src), {"accessors[0].max[0]", "23 is not the data's maximum (999)"});
  src = Edited(src, [](json& j) { j["accessors"][0].erase("max"); });
  ExpectInvalid(ImportGltf(src), {"accessors[0]", "index value 999", "vertex count 24"});
}

TEST(GltfImportMalformed, UrisLeavingTheFileSet) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  // The absolute path of the real Box0.bin exists on disk with the right size: the import must
  // still refuse it, which shows it never reads the file system.
  const std::string real = fs::absolute(fs::path(AssetsDir()) / "Box/glTF/Box0.bin").string();
  for (const std::string& uri :
       {std::string("../x.bin"), std::string("/etc/passwd"), std::string("file:///etc/passwd"),
        std::string("..\\x.bin"), std::string("%2e%2e/Box0.bin"), std::string("sub/../../x.bin"),
        std::string("C:/x.bin"), real}) {
    SCOPED_TRACE(uri);
    ExpectInvalid(ImportGltf(Edited(box, [&](json& j) { j["buffers"][0]["uri"] = uri; })),
                  {"buffers[0].uri", "'" + uri + "'", "not in the file set"});
  }
  GltfSource textured = Source("BoxTextured/glTF/BoxTextured.gltf");
  ExpectInvalid(
      ImportGltf(Edited(textured, [](json& j) { j["images"][0]["uri"] = "/etc/passwd"; })),
      {"images[0].uri", "'/etc/passwd' is not in the file set"});
}

TEST(GltfImportMalformed, AbsurdDeclaredSizes) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  ExpectInvalid(
      ImportGltf(Edited(box, [](json& j) { j["buffers"][0]["byteLength"] = 1000000000000000ull; })),
      {"buffers[0]", "byteLength (1000000000000000)"});
  // The same written as a float: an integer to the pre-scan, as the validator reads it.
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["buffers"][0]["byteLength"] = 1e15; })),
                {"buffers[0]", "byteLength (1000000000000000)"});
  GltfSource textured = Source("BoxTextured/glTF/BoxTextured.gltf");
  // A 33-byte file that claims 10^10 pixels is refused from its header.
  textured.files["CesiumLogoFlat.png"] = PngHeader(100000, 100000);
  ExpectOverLimit(ImportGltf(textured), {"images[0]", "CesiumLogoFlat.png", "100000x100000",
                                         "max_image_dimension limit (16384)"});
  textured.files["CesiumLogoFlat.png"] = PngHeader(16000, 16000);  // 1 GiB as RGBA8
  ExpectOverLimit(ImportGltf(textured), {"images[0]", "max_image_bytes limit"});
  textured.files["CesiumLogoFlat.png"] = {1, 2, 3, 4, 5};
  ExpectInvalid(ImportGltf(textured), {"images[0]", "not a PNG or JPEG image"});
}

// One asset per limit that is just over it; every limit in ImportLimitFields() must have one.
TEST(GltfImportLimits, EachLimitIsEnforcedAndNamed) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");  // 2 nodes (depth 2), 1 mesh, 24 vertices
  const GltfSource textured = Source("BoxTextured/glTF/BoxTextured.gltf");  // a 256x256 image
  const GltfSource meshopt = testing::MeshoptFile(testing::WavyGrid(4)).Glb();
  // Box with an animation of 2 keys (times and translations in a data-URI buffer of its own).
  const GltfSource animated = Edited(box, [](json& j) {
    const float data[] = {0, 1, 0, 0, 0, 1, 0, 0};
    const std::string bytes(reinterpret_cast<const char*>(data), sizeof data);
    j["buffers"].push_back({{"uri", "data:application/octet-stream;base64," +
                                        absl::Base64Escape(bytes)},
                            {"byteLength", sizeof data}});
    const int buffer = int(j["buffers"].size()) - 1, view = int(j["bufferViews"].size());
    const int acc = int(j["accessors"].size());
    j["bufferViews"].push_back({{"buffer", buffer}, {"byteOffset", 0}, {"byteLength", 8}});
    j["bufferViews"].push_back({{"buffer", buffer}, {"byteOffset", 8}, {"byteLength", 24}});
    j["accessors"].push_back({{"bufferView", view}, {"componentType", 5126}, {"count", 2},
                              {"type", "SCALAR"}, {"min", {0}}, {"max", {1}}});
    j["accessors"].push_back({{"bufferView", view + 1}, {"componentType", 5126}, {"count", 2},
                              {"type", "VEC3"}});
    j["animations"] = {{{"samplers", {{{"input", acc}, {"output", acc + 1}}}},
                        {"channels", {{{"sampler", 0},
                                       {"target", {{"node", 1}, {"path", "translation"}}}}}}}};
  });
  // Box with a skin no node uses (two joints), and with a morph target (its own positions).
  const GltfSource skinned = Edited(box, [](json& j) { j["skins"] = {{{"joints", {0, 1}}}}; });
  const GltfSource morphed = Edited(box, [](json& j) {
    j["meshes"][0]["primitives"][0]["targets"] = {{{"POSITION", 2}}};
  });
  const GltfSource lit = Edited(box, [](json& j) {
    j["extensionsUsed"] = {"KHR_lights_punctual"};
    j["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}}, {{"type", "point"}}};
  });
  struct Case {
    const char* limit;
    uint64_t value;
    const GltfSource* source;
    std::vector<std::string> needles;
  };
  const std::vector<Case> cases = {
      {"max_json_bytes", 100, &box, {"Box.gltf: JSON: ", "bytes exceed the max_json_bytes limit (100)"}},
      {"max_json_depth", 3, &box, {"JSON", "nested deeper than the max_json_depth limit (3)"}},
      {"max_json_values", 50, &box, {"JSON", "values exceed the max_json_values limit (50)"}},
      {"max_materials", 0, &box, {"materials: 1 materials exceed the max_materials limit (0)"}},
      {"max_nodes", 1, &box, {"nodes: 2 nodes exceed the max_nodes limit (1)"}},
      {"max_node_depth", 1, &box, {"nodes[1]: node depth 2 exceeds the max_node_depth limit (1)"}},
      {"max_meshes", 0, &box, {"meshes: 1 meshes exceed the max_meshes limit (0)"}},
      {"max_primitives", 0, &box, {"1 primitives exceed the max_primitives limit (0)"}},
      {"max_accessor_elements", 20, &box, {"accessors[", "max_accessor_elements limit (20)"}},
      {"max_accessor_bytes", 100, &box, {"accessors[", "max_accessor_bytes limit (100)"}},
      {"max_vertices", 10, &box, {"meshes[0].primitives[0]", "max_vertices limit (10)"}},
      {"max_indices", 10, &box, {"accessors[0]: index count 36 exceeds the max_indices limit (10)"}},
      {"max_image_dimension", 128, &textured,
       {"images[0]", "256x256 exceeds the max_image_dimension limit (128)"}},
      {"max_image_bytes", 1000, &textured,
       {"images[0]", "decodes to 262144 bytes, over the max_image_bytes limit (1000)"}},
      {"max_total_image_bytes", 1000, &textured, {"images[0]", "max_total_image_bytes limit"}},
      {"max_textures", 0, &textured, {"textures: 1 textures exceed the max_textures limit (0)"}},
      {"max_lights", 1, &lit, {"KHR_lights_punctual.lights", "max_lights limit (1)"}},
      {"max_drawables", 0, &box, {"nodes[1]", "max_drawables limit (0)"}},
      {"max_decoded_bytes", 100, &meshopt, {"bufferViews[", "max_decoded_bytes limit (100)"}},
      {"max_animation_keys", 1, &animated,
       {"animations[0].samplers[0].input", "max_animation_keys limit (1)"}},
      {"max_skin_joints", 1, &skinned, {"skins[0].joints", "max_skin_joints limit (1)"}},
      {"max_morph_targets", 0, &morphed, {"meshes[0]", "max_morph_targets limit (0)"}},
  };
  std::set<std::string> tested;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.limit);
    ImportLimits limits;
    ASSERT_EQ(ParseImportLimits(absl::StrCat(c.limit, "=", c.value), &limits), "");
    ExpectOverLimit(ImportGltf(*c.source, limits), c.needles);
    EXPECT_TRUE(ImportGltf(*c.source).ok()) << "the default limits must take it";
    tested.insert(c.limit);
  }
  for (const ImportLimitField& f : ImportLimitFields())
    EXPECT_TRUE(tested.count(f.name)) << f.name << " has no test case";
}

TEST(GltfImportLimits, ParseNamesWhatIsWrong) {
  ImportLimits limits;
  EXPECT_EQ(ParseImportLimits("max_nodes=5, max_json_bytes=1000000", &limits), "");
  EXPECT_EQ(limits.max_nodes, 5u);
  EXPECT_EQ(limits.max_json_bytes, 1000000u);
  EXPECT_EQ(ParseImportLimits("", &limits), "");
  EXPECT_EQ(limits.max_nodes, 5u);
  EXPECT_EQ(ParseImportLimits("max_nodez=5", &limits), "unknown limit 'max_nodez'");
  EXPECT_EQ(ParseImportLimits("max_nodes=-1", &limits),
            "max_nodes: '-1' is not a non-negative integer");
  EXPECT_EQ(ParseImportLimits("max_nodes=4294967296", &limits),
            "max_nodes: 4294967296 is larger than 4294967295");
  EXPECT_EQ(ParseImportLimits("max_nodes", &limits), "'max_nodes' is not name=value");
  // Nothing applied from a spec with an error.
  EXPECT_NE(ParseImportLimits("max_meshes=1,bogus=2", &limits), "");
  EXPECT_EQ(limits.max_meshes, ImportLimits{}.max_meshes);
}

// Numbers too large for float reach neither the scene nor the GPU.
TEST(GltfImportMalformed, NonFiniteNumbers) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  // JSON cannot spell infinity, and a number past double's range ("1e400") is a JSON error
  // (BadJson), so what reaches the converter is a finite double, possibly past float's range.
  auto light = [](double intensity) {
    return [intensity](json& j) {
      j["extensionsUsed"] = {"KHR_lights_punctual"};
      j["extensions"]["KHR_lights_punctual"]["lights"] = {
          {{"type", "point"}, {"intensity", intensity}}};
      j["nodes"][1]["extensions"]["KHR_lights_punctual"]["light"] = 0;
    };
  };
  ExpectInvalid(ImportGltf(Edited(box, light(1e300))),
                {"KHR_lights_punctual.lights[0]", "too large for float"});
  // A float, but far past any real light: clamped.
  absl::StatusOr<CpuScene> bright = ImportGltf(Edited(box, light(3e38)));
  ASSERT_TRUE(bright.ok()) << bright.status();
  ASSERT_EQ(bright->lights.size(), 1u);
  EXPECT_LE(bright->lights[0].intensity, 1e9f);
  // Finite numbers whose product is not: the world bounds overflow.
  ExpectInvalid(ImportGltf(Edited(box,
                                  [](json& j) {
                                    j["nodes"][0]["matrix"] = {3e38, 0, 0, 0, 0, 3e38, 0, 0,
                                                               0, 0, 3e38, 0, 3e38, 3e38, 3e38, 1};
                                  })),
                {"nodes[1]", "non-finite world bounds"});
  // Factors outside the spec's ranges are refused, naming the value (the glTF-Validator calls
  // them errors: tests/gltf/agreement.mjs); values the spec leaves unbounded are clamped to what
  // the shaders can use, not passed on as huge numbers.
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) {
                  j["materials"][0]["pbrMetallicRoughness"]["baseColorFactor"] = {5, -1, 1e30, 1};
                })),
                {"materials[0].pbrMetallicRoughness.baseColorFactor[0]", "5 is out of range [0, 1]"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["materials"][0]["emissiveFactor"] = {1e30, 0, 0}; })),
                {"materials[0].emissiveFactor[0]", "out of range [0, 1]"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["materials"][0]["emissiveFactor"] = {1, 0}; })),
                {"materials[0].emissiveFactor", "wants an array of 3 numbers"});
  absl::StatusOr<CpuScene> clamped = ImportGltf(Edited(box, [](json& j) {
    j["materials"][0]["alphaCutoff"] = 1e30;
  }));
  ASSERT_TRUE(clamped.ok()) << clamped.status();
  const Material& m = clamped->materials[0];
  EXPECT_EQ(m.alpha_cutoff, 1.0f);
  // A node scaled to zero is legal (it hides its mesh).
  EXPECT_TRUE(ImportGltf(Edited(box, [](json& j) { j["nodes"][1]["scale"] = {0, 0, 0}; })).ok());
}

// tinygltf copies every buffer and every image file it is pointed at: pointing many entries at
// one file must not multiply what an upload costs.
TEST(GltfImportMalformed, CopiesBoundedByTheFileSet) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  ExpectInvalid(ImportGltf(Edited(box,
                                  [](json& j) {
                                    for (int i = 0; i < 8; ++i) j["buffers"].push_back(j["buffers"][0]);
                                  })),
                {"buffers", "add up to more than the", "bytes of the file set"});
  const GltfSource textured = Source("BoxTextured/glTF/BoxTextured.gltf");
  ExpectInvalid(ImportGltf(Edited(textured,
                                  [](json& j) {
                                    for (int i = 0; i < 8; ++i) j["images"].push_back(j["images"][0]);
                                  })),
                {"images[", "copy more than twice the"});
}

TEST(GltfImportMalformed, UnsupportedRequiredExtension) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  for (const char* ext : {"KHR_texture_basisu", "KHR_materials_clearcoat"}) {
    ExpectInvalid(ImportGltf(Edited(box, [&](json& j) { j["extensionsRequired"] = {ext}; })),
                  {"extensionsRequired", std::string("unsupported required extension ") + ext});
  }
  EXPECT_TRUE(ImportGltf(Edited(box, [](json& j) {
                j["extensionsUsed"] = j["extensionsRequired"] = {"KHR_texture_transform"};
              })).ok());
  // Required but not used is refused (the schema: extensionsRequired is a subset).
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) {
                  j["extensionsRequired"] = {"KHR_texture_transform"};
                })),
                {"extensionsRequired[0]", "is not in extensionsUsed"});
  // Every supported extension may be required; one only used (not required) and unsupported is
  // ignored, and the scene's warnings name it.
  for (std::string_view ext : SupportedGltfExtensions()) {
    EXPECT_TRUE(ImportGltf(Edited(box, [&](json& j) {
                  j["extensionsUsed"] = j["extensionsRequired"] = {std::string(ext)};
                })).ok())
        << ext;
  }
  absl::StatusOr<CpuScene> used =
      ImportGltf(Edited(box, [](json& j) { j["extensionsUsed"] = {"KHR_materials_clearcoat"}; }));
  ASSERT_TRUE(used.ok()) << used.status();
  ASSERT_EQ(used->warnings.size(), 1u);
  EXPECT_NE(used->warnings[0].find("KHR_materials_clearcoat"), std::string::npos)
      << used->warnings[0];
}

// ----- EXT_texture_webp -------------------------------------------------------------------------

// BoxTextured with its texture as lossless WebP too (CesiumLogoFlat.webp, images[1]), and
// `edit` applied; the PNG's decoded pixels in *png.
GltfSource WebpBox(const std::function<void(json&)>& edit, RgbaImage* png = nullptr) {
  GltfSource src = Source("BoxTextured/glTF/BoxTextured.gltf");
  absl::StatusOr<RgbaImage> decoded = DecodePng(src.files.at("CesiumLogoFlat.png"));
  EXPECT_TRUE(decoded.ok()) << decoded.status();
  if (!decoded.ok()) return src;
  absl::StatusOr<std::vector<uint8_t>> webp = EncodeWebpLossless(*decoded);
  EXPECT_TRUE(webp.ok()) << webp.status();
  if (!webp.ok()) return src;
  src.files["CesiumLogoFlat.webp"] = *webp;
  if (png) *png = *decoded;
  return Edited(std::move(src), [&](json& j) {
    j["images"].push_back({{"uri", "CesiumLogoFlat.webp"}, {"mimeType", "image/webp"}});
    j["extensionsUsed"] = {"EXT_texture_webp"};
    j["textures"][0]["extensions"]["EXT_texture_webp"] = {{"source", 1}};
    edit(j);
  });
}

// The texture samples its WebP source: with a PNG fallback (the extension used), and without
// one (required); the pixels are the PNG's, whose lossless WebP copy it is.
TEST(GltfImportWebp, TheTextureSamplesItsWebpSource) {
  REQUIRE_ASSETS();
  RgbaImage png;
  const GltfSource with_fallback = WebpBox([](json&) {}, &png);
  const GltfSource webp_only = WebpBox([](json& j) {
    j["extensionsRequired"] = {"EXT_texture_webp"};
    j["textures"][0].erase("source");
  });
  for (const GltfSource* src : {&with_fallback, &webp_only}) {
    absl::StatusOr<CpuScene> s = ImportGltf(*src);
    ASSERT_TRUE(s.ok()) << s.status();
    ASSERT_EQ(s->textures.size(), 1u);
    ASSERT_NE(s->textures[0].image, nullptr);
    EXPECT_EQ(s->textures[0].image->name, "CesiumLogoFlat.webp");
    EXPECT_EQ(s->textures[0].image->width, png.width);
    EXPECT_EQ(s->textures[0].image->height, png.height);
    EXPECT_TRUE(s->textures[0].image->rgba8 == png.pixels) << "the WebP's pixels differ";
    EXPECT_TRUE(s->textures[0].srgb);
    EXPECT_EQ(s->warnings, std::vector<std::string>{});
  }
  // Without the extension in extensionsUsed its object is refused (as any undeclared one).
  ExpectInvalid(ImportGltf(WebpBox([](json& j) { j.erase("extensionsUsed"); })),
                {"textures[0].extensions.EXT_texture_webp", "not declared in extensionsUsed"});
}

// What a client may get wrong, each refused naming the field or image.
TEST(GltfImportWebp, MalformedSourcesAreRefusedNamingThem) {
  REQUIRE_ASSETS();
  ExpectInvalid(ImportGltf(WebpBox([](json& j) {
                  j["textures"][0]["extensions"]["EXT_texture_webp"]["source"] = 7;
                })),
                {"textures[0].extensions.EXT_texture_webp.source", "out of range (2 images)"});
  // Without a source (the schema does not require one) the extension names no image: the core
  // source, the PNG, is sampled.
  absl::StatusOr<CpuScene> no_source = ImportGltf(
      WebpBox([](json& j) { j["textures"][0]["extensions"]["EXT_texture_webp"].erase("source"); }));
  ASSERT_TRUE(no_source.ok()) << no_source.status();
  ASSERT_NE(no_source->textures[0].image, nullptr);
  EXPECT_EQ(no_source->textures[0].image->name, "CesiumLogoFlat.png");
  ExpectInvalid(
      ImportGltf(WebpBox([](json& j) { j["textures"][0]["extensions"]["EXT_texture_webp"] = 1; })),
      {"textures[0].extensions.EXT_texture_webp", "not an object"});
  // WebP data as a core source: glTF 2.0 allows only PNG and JPEG there.
  ExpectInvalid(ImportGltf(WebpBox([](json& j) {
                  j["textures"][0].erase("extensions");
                  j["textures"][0]["source"] = 1;
                })),
                {"images[1]", "WebP", "EXT_texture_webp"});
  // In a bufferView (as a .glb holds it), with its mimeType; the declared type is the data's.
  auto in_buffer_view = [](const char* mime_type) {
    GltfSource src = WebpBox([](json&) {});
    std::vector<uint8_t>& bin = src.files.at("BoxTextured0.bin");
    const std::vector<uint8_t> webp = src.files.at("CesiumLogoFlat.webp");
    src.files.erase("CesiumLogoFlat.webp");
    bin.resize((bin.size() + 3) / 4 * 4);
    const size_t offset = bin.size();
    bin.insert(bin.end(), webp.begin(), webp.end());
    return Edited(std::move(src), [&](json& j) {
      j["buffers"][0]["byteLength"] = bin.size();
      j["bufferViews"].push_back(
          {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", webp.size()}});
      j["images"][1] = {{"bufferView", j["bufferViews"].size() - 1}, {"mimeType", mime_type}};
    });
  };
  absl::StatusOr<CpuScene> viewed = ImportGltf(in_buffer_view("image/webp"));
  ASSERT_TRUE(viewed.ok()) << viewed.status();
  EXPECT_EQ(viewed->textures[0].image->width, 256u);
  ExpectInvalid(ImportGltf(in_buffer_view("image/png")),
                {"images[1].mimeType", "the data is image/webp"});
  // tinygltf 2.7 decodes no image/webp data: URI: refused saying so.
  ExpectInvalid(ImportGltf(WebpBox(
                    [](json& j) { j["images"][1]["uri"] = "data:image/webp;base64,UklGRg=="; })),
                {"images[1].uri", "a WebP image in a data: URI is not supported"});
  // Cut short: named, not decoded in part.
  GltfSource cut = WebpBox([](json&) {});
  cut.files["CesiumLogoFlat.webp"].resize(cut.files["CesiumLogoFlat.webp"].size() / 2);
  ExpectInvalid(ImportGltf(cut), {"images[1]", "CesiumLogoFlat.webp", "cannot decode"});
  // Its header's size is held to the limits before anything is decoded.
  ImportLimits small;
  small.max_image_dimension = 128;
  ExpectOverLimit(ImportGltf(WebpBox([](json&) {}), small), {"images[1]", "max_image_dimension"});
}

// ----- EXT_mesh_gpu_instancing ------------------------------------------------------------------

// Box (its mesh on nodes[1], under nodes[0]'s matrix) drawn as three instances: TRANSLATION,
// ROTATION and SCALE accessors (accessors[3..5]) appended to its buffer, and with `animated` a
// translation of nodes[1] from 0 to (5, 0, 0) over a second (accessors[6..7]); then `edit`.
constexpr float kInstanceT[9] = {0, 0, 0, 2, 0, 0, 0, 3, 0};
constexpr float kInstanceR[12] = {0, 0, 0, 1, 0, 0, 0.70710678f, 0.70710678f, 1, 0, 0, 0};
constexpr float kInstanceS[9] = {1, 1, 1, 2, 2, 2, 1, 0.5f, 1};
GltfSource InstancedBox(const std::function<void(json&)>& edit, bool animated = false,
                        float first_x = 0.0f, float first_rotation_x = 0.0f) {
  GltfSource src = Source("Box/glTF/Box.gltf");
  std::vector<uint8_t>& bin = src.files.at("Box0.bin");
  json views = json::array(), accessors = json::array();
  auto append = [&](const float* v, size_t n, const char* type, size_t count) {
    bin.resize((bin.size() + 3) / 4 * 4);
    views.push_back({{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", n * 4}});
    const auto* bytes = reinterpret_cast<const uint8_t*>(v);
    bin.insert(bin.end(), bytes, bytes + n * 4);
    accessors.push_back({{"componentType", 5126}, {"count", count}, {"type", type}});
  };
  float t[9];
  std::copy(std::begin(kInstanceT), std::end(kInstanceT), t);
  t[0] = first_x;
  append(t, 9, "VEC3", 3);
  float r[12];
  std::copy(std::begin(kInstanceR), std::end(kInstanceR), r);
  r[0] = first_rotation_x;
  append(r, 12, "VEC4", 3);
  append(kInstanceS, 9, "VEC3", 3);
  const float times[2] = {0, 1}, moves[6] = {0, 0, 0, 5, 0, 0};
  if (animated) {
    append(times, 2, "SCALAR", 2);
    accessors.back()["min"] = {0};
    accessors.back()["max"] = {1};
    append(moves, 6, "VEC3", 2);
  }
  return Edited(std::move(src), [&](json& j) {
    const size_t view0 = j["bufferViews"].size(), accessor0 = j["accessors"].size();
    for (size_t i = 0; i < views.size(); ++i) {
      j["bufferViews"].push_back(views[i]);
      accessors[i]["bufferView"] = view0 + i;
      j["accessors"].push_back(accessors[i]);
    }
    j["buffers"][0]["byteLength"] = bin.size();
    j["extensionsUsed"] = {"EXT_mesh_gpu_instancing"};
    j["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {
        {"TRANSLATION", accessor0}, {"ROTATION", accessor0 + 1}, {"SCALE", accessor0 + 2}};
    if (animated) {
      json sampler = {{"input", accessor0 + 3}, {"output", accessor0 + 4}};
      json channel = {{"sampler", 0}, {"target", {{"node", 1}, {"path", "translation"}}}};
      j["animations"] = json::array(
          {{{"samplers", json::array({sampler})}, {"channels", json::array({channel})}}});
    }
    edit(j);
  });
}

glm::mat4 InstanceMatrix(int i) {
  NodeTransform trs;
  trs.translation = glm::vec3(kInstanceT[3 * i], kInstanceT[3 * i + 1], kInstanceT[3 * i + 2]);
  trs.rotation = glm::quat(kInstanceR[4 * i + 3], kInstanceR[4 * i], kInstanceR[4 * i + 1],
                           kInstanceR[4 * i + 2]);
  trs.scale = glm::vec3(kInstanceS[3 * i], kInstanceS[3 * i + 1], kInstanceS[3 * i + 2]);
  return trs.Matrix();
}

void ExpectNear(const glm::mat4& a, const glm::mat4& b, const std::string& what) {
  for (int c = 0; c < 4; ++c)
    for (int r = 0; r < 4; ++r)
      EXPECT_NEAR(a[c][r], b[c][r], 1e-5f) << what << " [" << c << "][" << r << "]";
}

// The node's mesh is drawn once per instance (not once more for the node), each at the node's
// world transform times the instance's T * R * S.
TEST(GltfImportInstancing, EachInstanceIsADrawableUnderItsNode) {
  REQUIRE_ASSETS();
  absl::StatusOr<CpuScene> plain = ImportGltf(Source("Box/glTF/Box.gltf"));
  ASSERT_TRUE(plain.ok()) << plain.status();
  ASSERT_EQ(plain->drawables.size(), 1u);
  const glm::mat4 node_world = plain->drawables[0].world;
  absl::StatusOr<CpuScene> s = ImportGltf(InstancedBox([](json&) {}));
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->drawables.size(), 3u);
  EXPECT_EQ(s->counts.triangles, 3 * plain->counts.triangles);
  Aabb all;
  for (int i = 0; i < 3; ++i) {
    const Drawable& d = s->drawables[size_t(i)];
    SCOPED_TRACE(i);
    ExpectNear(d.instance, InstanceMatrix(i), "instance");
    ExpectNear(d.world, node_world * InstanceMatrix(i), "world");
    EXPECT_EQ(d.node, 1u);
    const Aabb expected = s->primitives[d.primitive].bounds.transformed(d.world);
    EXPECT_NEAR(glm::distance(d.world_bounds.min, expected.min), 0.0f, 1e-5f);
    EXPECT_NEAR(glm::distance(d.world_bounds.max, expected.max), 0.0f, 1e-5f);
    all.extend(d.world_bounds);
  }
  EXPECT_NEAR(glm::distance(s->bounds.min, all.min), 0.0f, 1e-5f);
  EXPECT_NEAR(glm::distance(s->bounds.max, all.max), 0.0f, 1e-5f);
  // Required, it loads the same; without extensionsUsed its object is refused.
  EXPECT_TRUE(ImportGltf(InstancedBox([](json& j) {
                j["extensionsRequired"] = {"EXT_mesh_gpu_instancing"};
              })).ok());
  ExpectInvalid(ImportGltf(InstancedBox([](json& j) { j.erase("extensionsUsed"); })),
                {"nodes[1].extensions.EXT_mesh_gpu_instancing", "not declared in extensionsUsed"});
  // Only the application's own attributes (_ID, ...): as many instances, each at the node.
  absl::StatusOr<CpuScene> ids = ImportGltf(InstancedBox([](json& j) {
    j["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"_ID", 3}};
  }));
  ASSERT_TRUE(ids.ok()) << ids.status();
  ASSERT_EQ(ids->drawables.size(), 3u);
  for (const Drawable& d : ids->drawables) ExpectNear(d.world, node_world, "_ID-only instance");
}

// An animated node moves its instances with it: each is posed at the node's posed world
// transform times its own.
TEST(GltfImportInstancing, AnAnimatedNodeCarriesItsInstances) {
  REQUIRE_ASSETS();
  absl::StatusOr<CpuScene> s = ImportGltf(InstancedBox([](json&) {}, /*animated=*/true));
  ASSERT_TRUE(s.ok()) << s.status();
  const std::unique_ptr<SceneAnimator> a = SceneAnimator::Create(*s);
  ASSERT_NE(a, nullptr);
  ASSERT_EQ(a->drawables().size(), 3u);
  EXPECT_TRUE(a->Pose(0, 1.0, false));
  const ScenePose pose = EvaluatePose(s->nodes, s->animations, 0, 1.0, false);
  for (size_t i = 0; i < 3; ++i) {
    const AnimatedDrawable& d = a->drawables()[i];
    const glm::mat4 expected = pose.world[1] * InstanceMatrix(int(d.drawable));
    ExpectNear(a->world()[i], expected, absl::StrCat("drawable ", d.drawable));
    // Moved by (5, 0, 0) in the node's frame, which nodes[0]'s matrix keeps along x.
    EXPECT_NEAR(a->world()[i][3].x - s->drawables[d.drawable].world[3].x, 5.0f, 1e-4f);
  }
}

// What a client may get wrong, each refused naming the node's extension and attribute.
TEST(GltfImportInstancing, MalformedInstancesAreRefusedNamingThem) {
  REQUIRE_ASSETS();
  const std::string at = "nodes[1].extensions.EXT_mesh_gpu_instancing";
  auto attributes = [](json& j) -> json& {
    return j["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"]["attributes"];
  };
  ExpectInvalid(ImportGltf(InstancedBox([](json& j) { j["accessors"][5]["count"] = 2; })),
                {at + ".attributes.SCALE", "count 2 differs from"});
  ExpectInvalid(ImportGltf(InstancedBox([](json& j) { j["accessors"][4]["type"] = "VEC3"; })),
                {at + ".attributes.ROTATION", "unsupported type/componentType"});
  // Indices in range, as numbers an int holds (tinygltf would wrap 2^32 + 1 to accessor 1).
  for (const int64_t bad : {int64_t{99}, int64_t{4294967297}, int64_t{-1}}) {
    ExpectInvalid(ImportGltf(InstancedBox([&](json& j) { attributes(j)["TRANSLATION"] = bad; })),
                  {at + ".attributes.TRANSLATION", "out of range"});
  }
  ExpectInvalid(ImportGltf(InstancedBox([&](json& j) { attributes(j) = json::object(); })),
                {at + ".attributes", "not an object naming at least one accessor"});
  ExpectInvalid(ImportGltf(InstancedBox([&](json& j) { attributes(j) = 3; })),
                {at + ".attributes", "not an object naming at least one accessor"});
  ExpectInvalid(ImportGltf(InstancedBox([](json& j) {
                  j["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"].erase("attributes");
                })),
                {at + ".attributes", "missing"});
  ExpectInvalid(ImportGltf(InstancedBox(
                    [](json& j) { j["nodes"][1]["extensions"]["EXT_mesh_gpu_instancing"] = 1; })),
                {at, "not an object"});
  ExpectInvalid(
      ImportGltf(InstancedBox([](json&) {}, false, std::numeric_limits<float>::infinity())),
      {at, "instance 0's transform is not finite"});
  ExpectInvalid(
      ImportGltf(InstancedBox([](json&) {}, false, 0.0f, std::numeric_limits<float>::quiet_NaN())),
      {at, "instance 0's rotation is not finite"});
  ImportLimits limits;
  limits.max_drawables = 2;
  ExpectOverLimit(ImportGltf(InstancedBox([](json&) {}), limits), {at, "max_drawables"});
  // Instances placed by zeros (an accessor without a bufferView) cost nothing to upload: a
  // million of them from a few bytes of JSON is refused, naming the budget.
  ExpectOverLimit(
      ImportGltf(InstancedBox([&](json& j) {
        j["accessors"].push_back({{"componentType", 5126}, {"count", 1 << 20}, {"type", "VEC3"}});
        attributes(j) = {{"TRANSLATION", j["accessors"].size() - 1}};
      })),
      {at, "instances placed by zeros or sparse data"});
  // Instancing a skinned mesh (the crowd's first body) is refused, as not supported.
  absl::StatusOr<GltfSource> crowd =
      LoadGltfSourceFromDisk(std::string(TESSERA_ANIMATED_DIR) + "/crowd.gltf");
  ASSERT_TRUE(crowd.ok()) << crowd.status();
  std::string skinned;
  absl::StatusOr<CpuScene> instanced_crowd = ImportGltf(Edited(*crowd, [&](json& j) {
    j["extensionsUsed"].push_back("EXT_mesh_gpu_instancing");
    for (size_t n = 0; n < j["nodes"].size(); ++n) {
      json& node = j["nodes"][n];
      if (!node.contains("skin")) continue;
      const int position =
          j["meshes"][node["mesh"].get<int>()]["primitives"][0]["attributes"]["POSITION"];
      node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"] = {{"TRANSLATION", position}};
      skinned = absl::StrCat("nodes[", n, "].extensions.EXT_mesh_gpu_instancing");
      break;
    }
  }));
  ASSERT_FALSE(skinned.empty());
  ExpectInvalid(instanced_crowd, {skinned, "instances of a skinned mesh are not supported"});
}

TEST(GltfImportMalformed, AssetVersion) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  // A glTF 1.0 file has another schema: refused, not half-read as 2.0.
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["asset"]["version"] = "1.0"; })),
                {"asset.version", "'1.0' is not supported (glTF 2.0 only)"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["asset"]["version"] = "3.0"; })),
                {"asset.version", "'3.0' is not supported"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["asset"]["version"] = 2; })),
                {"asset.version", "missing or not a string"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["asset"]["version"] = "2"; })),
                {"asset.version", "'2' is not a MAJOR.MINOR version"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["asset"]["minVersion"] = "2.1"; })),
                {"asset.minVersion", "'2.1' is not supported"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j.erase("asset"); })),
                {"asset", "missing"});
  // A later 2.x minor version is read: the spec keeps them compatible.
  EXPECT_TRUE(ImportGltf(Edited(box, [](json& j) { j["asset"]["version"] = "2.1"; })).ok());
  EXPECT_TRUE(ImportGltf(Edited(box, [](json& j) { j["asset"]["minVersion"] = "2.0"; })).ok());
}

TEST(GltfImportMalformed, NodeHierarchy) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("Box/glTF/Box.gltf");
  // A root listed twice, or a child listed as a root, would be placed more than once.
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["scenes"][0]["nodes"] = {0, 0}; })),
                {"scenes[0].nodes", "nodes[0] is listed twice"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["scenes"][0]["nodes"] = {0, 1}; })),
                {"scenes[0].nodes", "nodes[1] is not a root (it is a child of nodes[0])"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["nodes"][1]["children"] = {0}; })),
                {"nodes[", "cycle"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["nodes"][1]["children"] = {1}; })),
                {"nodes[1]", "cycle"});
  ExpectInvalid(ImportGltf(Edited(box,
                                  [](json& j) {
                                    j["nodes"].push_back({{"children", {1}}});
                                    j["scenes"][0]["nodes"].push_back(2);
                                  })),
                {"nodes[1]", "more than one parent"});
  ExpectInvalid(ImportGltf(Edited(box, [](json& j) { j["nodes"][0]["children"] = {7}; })),
                {"nodes[0].children", "node index 7"});
}

// tinygltf reads the core schema's integers into an int: it cast 2^32 to 0 and 2^32 + 1 to 1,
// and took a reference of -1, 0.5 or "0" as absent, so each of these loaded another file than
// the one sent (BoxTextured without its texture or material, a node without its mesh). The
// pre-scan refuses each, naming it.
TEST(GltfImportMalformed, IntegersAnIntDoesNotHoldAreRefused) {
  REQUIRE_ASSETS();
  const GltfSource textured = Source("BoxTextured/glTF/BoxTextured.gltf");
  const std::string index = " is not an index (an integer in [0, 2147483647])";
  struct Case {
    const char* field;
    std::function<json&(json&)> at;  // the object holding the field
    const char* key;
  };
  const Case cases[] = {
      {"scene", [](json& j) -> json& { return j; }, "scene"},
      {"nodes[1].mesh", [](json& j) -> json& { return j["nodes"][1]; }, "mesh"},
      {"nodes[1].camera", [](json& j) -> json& { return j["nodes"][1]; }, "camera"},
      {"nodes[1].skin", [](json& j) -> json& { return j["nodes"][1]; }, "skin"},
      {"meshes[0].primitives[0].material",
       [](json& j) -> json& { return j["meshes"][0]["primitives"][0]; }, "material"},
      {"meshes[0].primitives[0].indices",
       [](json& j) -> json& { return j["meshes"][0]["primitives"][0]; }, "indices"},
      {"meshes[0].primitives[0].attributes.POSITION",
       [](json& j) -> json& { return j["meshes"][0]["primitives"][0]["attributes"]; }, "POSITION"},
      {"materials[0].pbrMetallicRoughness.baseColorTexture.index",
       [](json& j) -> json& {
         return j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"];
       },
       "index"},
      {"materials[0].pbrMetallicRoughness.baseColorTexture.texCoord",
       [](json& j) -> json& {
         return j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"];
       },
       "texCoord"},
      {"textures[0].sampler", [](json& j) -> json& { return j["textures"][0]; }, "sampler"},
      {"textures[0].source", [](json& j) -> json& { return j["textures"][0]; }, "source"},
      {"accessors[1].bufferView", [](json& j) -> json& { return j["accessors"][1]; }, "bufferView"},
      {"bufferViews[0].buffer", [](json& j) -> json& { return j["bufferViews"][0]; }, "buffer"},
  };
  const json wide = uint64_t{4294967296};  // 2^32: the int cast gave 0, a valid index here
  for (const Case& c : cases) {
    for (const json& bad : {wide, json(int64_t{-1}), json(0.5), json("0")}) {
      SCOPED_TRACE(std::string(c.field) + " = " + bad.dump());
      ExpectInvalid(ImportGltf(Edited(textured, [&](json& j) { c.at(j)[c.key] = bad; })),
                    {"BoxTextured.gltf: ", c.field, ": " + bad.dump() + index});
    }
  }
  // In arrays of indices.
  ExpectInvalid(
      ImportGltf(Edited(textured, [](json& j) { j["nodes"][0]["children"] = {4294967297u}; })),
      {"nodes[0].children[0]: 4294967297" + index});
  ExpectInvalid(ImportGltf(Edited(textured, [](json& j) { j["scenes"][0]["nodes"] = {-1}; })),
                {"scenes[0].nodes[0]: -1" + index});
  ExpectInvalid(ImportGltf(Edited(textured, [](json& j) { j["nodes"][0]["children"] = 1; })),
                {"nodes[0].children", "not an array of indices"});
  // Enumerations: the int cast gave TRIANGLES for 2^32 + 4 and REPEAT for 2^32 + 10497.
  ExpectInvalid(
      ImportGltf(
          Edited(textured, [](json& j) { j["meshes"][0]["primitives"][0]["mode"] = 4294967300u; })),
      {"meshes[0].primitives[0].mode: 4294967300 is not an enumerated value (an integer in [0, "
       "2147483647])"});
  ExpectInvalid(
      ImportGltf(Edited(textured, [](json& j) { j["samplers"][0]["wrapS"] = 4294977793u; })),
      {"samplers[0].wrapS: 4294977793 is not an enumerated value"});
  ExpectInvalid(ImportGltf(Edited(textured, [](json& j) { j["samplers"][0]["wrapS"] = "REPEAT"; })),
                {"samplers[0].wrapS: \"REPEAT\" is not an enumerated value"});
  // Elsewhere in the schema: skins, animations, images, morph targets, other texture slots and
  // enumerations.
  auto refused = [&](const std::function<void(json&)>& edit, const std::string& message) {
    ExpectInvalid(ImportGltf(Edited(textured, edit)), {message});
  };
  refused([](json& j) { j["skins"] = {{{"joints", {0, -1}}}}; }, "skins[0].joints[1]: -1" + index);
  refused(
      [](json& j) {
        j["skins"] = {{{"joints", {0}}, {"skeleton", 0.5}}};
      },
      "skins[0].skeleton: 0.5" + index);
  refused(
      [](json& j) {
        j["animations"] = {{{"channels", {{{"sampler", 4294967296u}, {"target", {{"node", 1}}}}}},
                            {"samplers", {{{"input", 0}, {"output", 1}}}}}};
      },
      "animations[0].channels[0].sampler: 4294967296" + index);
  refused(
      [](json& j) {
        j["animations"] = {{{"channels", {{{"sampler", 0}, {"target", {{"node", "1"}}}}}},
                            {"samplers", {{{"input", 0}, {"output", 1}}}}}};
      },
      "animations[0].channels[0].target.node: \"1\"" + index);
  refused([](json& j) { j["images"][0]["bufferView"] = -2; }, "images[0].bufferView: -2" + index);
  refused(
      [](json& j) {
        j["meshes"][0]["primitives"][0]["targets"] = {{{"POSITION", -1}}};
      },
      "meshes[0].primitives[0].targets[0].POSITION: -1" + index);
  refused(
      [](json& j) {
        j["materials"][0]["occlusionTexture"] = {{"index", 4294967296u}};
      },
      "materials[0].occlusionTexture.index: 4294967296" + index);
  refused([](json& j) { j["samplers"][0]["wrapT"] = 0.5; },
          "samplers[0].wrapT: 0.5 is not an enumerated value (an integer in [0, 2147483647])");
  refused([](json& j) { j["accessors"][0]["componentType"] = -4294967296; },
          "accessors[0].componentType: -4294967296 is not an enumerated value");
  refused([](json& j) { j["bufferViews"][0]["target"] = "ARRAY_BUFFER"; },
          "bufferViews[0].target: \"ARRAY_BUFFER\" is not an enumerated value");
  // A sparse block's count is at least 1 and its offsets at least 0 (and all ints to tinygltf).
  auto sparse = [](json count, json offset) {
    return [=](json& j) {
      j["accessors"][2]["sparse"] = {
          {"count", count},
          {"indices", {{"bufferView", 0}, {"componentType", 5123}, {"byteOffset", offset}}},
          {"values", {{"bufferView", 1}}}};
    };
  };
  refused(sparse(0, 0),
          "accessors[2].sparse.count: 0 is not a count (an integer in [1, "
          "2147483647])");
  refused(sparse(1, -4),
          "accessors[2].sparse.indices.byteOffset: -4 is not a byte offset (an "
          "integer in [0, 2147483647])");
  refused(sparse(4294967297u, 0), "accessors[2].sparse.count: 4294967297 is not a count");
  // Sizes, which tinygltf reads as size_t (and took a negative or fractional one as 0).
  refused([](json& j) { j["accessors"][1]["byteOffset"] = -4; },
          "accessors[1].byteOffset: -4 is not a size (a non-negative integer)");
  refused([](json& j) { j["accessors"][1]["count"] = 24.5; },
          "accessors[1].count: 24.5 is not a size");
  refused([](json& j) { j["bufferViews"][0]["byteLength"] = "72"; },
          "bufferViews[0].byteLength: \"72\" is not a size");
  refused([](json& j) { j["buffers"][0]["byteLength"] = -1; },
          "buffers[0].byteLength: -1 is not a size");
  refused([](json& j) { j["scene"] = -1; }, "BoxTextured.gltf: scene: -1" + index);
  // At the ends of an int: past this check, to the checks of what they name.
  refused([](json& j) { j["textures"][0]["source"] = 2147483647; },
          "textures[0].source: image index 2147483647 out of range (1 images)");
  refused([](json& j) { j["meshes"][0]["primitives"][0]["mode"] = 2147483647; },
          "meshes[0].primitives[0].mode: invalid mode 2147483647");
  // (tinygltf took a negative mode as none: TRIANGLES.)
  refused([](json& j) { j["meshes"][0]["primitives"][0]["mode"] = -2; },
          "meshes[0].primitives[0].mode: -2 is not an enumerated value");
  // A float that is an integer is that integer (as the validator reads it): tinygltf took it as
  // no value, a node without its mesh; now the JSON it reads has the integer.
  for (const bool glb : {false, true}) {
    SCOPED_TRACE(glb ? "glb" : "gltf");
    auto floats = [](json& j) {
      j["nodes"][1]["mesh"] = 0.0;
      j["meshes"][0]["primitives"][0]["material"] = 0.0;
      j["accessors"][1]["componentType"] = 5126.0;
      j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 0.0;
      j["accessors"][1]["count"] = 24.0;
      j["accessors"][2]["byteOffset"] = 288.0;
      j["bufferViews"][1]["byteStride"] = 12.0;
      j["bufferViews"][0]["byteLength"] = 72.0;
    };
    absl::StatusOr<CpuScene> s;
    if (glb) {
      const std::vector<uint8_t>& main = textured.files.at(textured.main_file);
      json j = json::parse(main.begin(), main.end());
      floats(j);
      j["buffers"][0].erase("uri");  // the BIN chunk
      GltfSource src =
          testing::GlbSource(j, textured.files.at("BoxTextured0.bin"), "BoxTextured.glb");
      src.files["CesiumLogoFlat.png"] = textured.files.at("CesiumLogoFlat.png");
      s = ImportGltf(src);
    } else {
      s = ImportGltf(Edited(textured, floats));
    }
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(s->indices.size(), 36u);  // the mesh is drawn
    ASSERT_EQ(s->materials.size(), 1u);
    EXPECT_EQ(s->materials[0].base_color.texture, 0);
  }
  // Numbers are not ints: an integer beyond 32 bits where the schema has a number still loads.
  const absl::StatusOr<CpuScene> far = ImportGltf(Edited(textured, [](json& j) {
    j["nodes"][1]["translation"] = {4294967296u, 0, 0};
  }));
  EXPECT_TRUE(far.ok()) << far.status();
}

TEST(GltfImportMalformed, IndicesOutOfRange) {
  REQUIRE_ASSETS();
  const GltfSource box = Source("BoxTextured/glTF/BoxTextured.gltf");
  const std::vector<std::pair<std::function<void(json&)>, std::string>> cases = {
      {[](json& j) { j["nodes"][1]["mesh"] = 5; }, "nodes[1].mesh"},
      {[](json& j) { j["nodes"][1]["camera"] = 0; }, "nodes[1].camera"},
      {[](json& j) { j["scene"] = 4; }, "scene"},
      {[](json& j) { j["scenes"][0]["nodes"] = {9}; }, "scenes[0].nodes"},
      {[](json& j) { j["meshes"][0]["primitives"][0]["material"] = 3; },
       "meshes[0].primitives[0].material"},
      {[](json& j) { j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 42; },
       "meshes[0].primitives[0].attributes.POSITION"},
      {[](json& j) { j["meshes"][0]["primitives"][0]["attributes"].erase("POSITION"); },
       "POSITION is required"},
      {[](json& j) { j["meshes"][0]["primitives"][0]["indices"] = 42; },
       "meshes[0].primitives[0].indices"},
      {[](json& j) { j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = 3; },
       "accessors[3]"},  // a VEC2 accessor used as NORMAL
      {[](json& j) { j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 8; },
       "materials[0].pbrMetallicRoughness.baseColorTexture.index"},
      {[](json& j) { j["textures"][0]["source"] = 3; }, "textures[0].source"},
      {[](json& j) { j["textures"][0]["sampler"] = 3; }, "textures[0].sampler"},
      {[](json& j) {
         j["images"][0] = {{"bufferView", 9}, {"mimeType", "image/png"}};
       },
       "images[0].bufferView"},
      {[](json& j) {
         j["extensionsUsed"] = {"KHR_lights_punctual"};
         j["nodes"][1]["extensions"]["KHR_lights_punctual"]["light"] = 0;
       },
       "KHR_lights_punctual.light"},
      {[](json& j) { j["nodes"][1]["extensions"]["KHR_lights_punctual"]["light"] = 0; },
       "nodes[1].extensions.KHR_lights_punctual: not declared in extensionsUsed"},
      {[](json& j) {
         j["nodes"][0]["matrix"] = {1, 2, 3};
       },
       "nodes[0].matrix"},
      {[](json& j) {
         j["accessors"][0]["sparse"] = {{"count", 1},
                                        {"indices", {{"bufferView", 0}, {"componentType", 5123}}},
                                        {"values", {{"bufferView", 1}}}};
       },
       "accessors[0]"},
  };
  for (size_t i = 0; i < cases.size(); ++i) {
    SCOPED_TRACE("case " + std::to_string(i) + ": " + cases[i].second);
    ExpectInvalid(ImportGltf(Edited(box, cases[i].first)), {"BoxTextured.gltf: ", cases[i].second});
  }
}

}  // namespace
}  // namespace tessera

namespace tessera {
namespace {

// ----- Sparse accessors and KHR_mesh_quantization ----------------------------------------------

// Binary data for a hand-built glTF: values appended at 4-byte aligned offsets.
struct Bin {
  std::vector<uint8_t> bytes;
  template <typename T>
  size_t Add(std::initializer_list<T> values) {
    bytes.resize((bytes.size() + 3) & ~size_t(3), 0);
    const size_t at = bytes.size();
    for (T v : values) {
      const auto* p = reinterpret_cast<const uint8_t*>(&v);
      bytes.insert(bytes.end(), p, p + sizeof(T));
    }
    return at;
  }
};

// One triangle primitive with `attributes`, the accessors and views given, data in data.bin,
// and a node placing the mesh with `node` (e.g. a scale).
GltfSource TriangleSource(const Bin& bin, json views, json accessors, json attributes,
                          json node = json::object(), json extensions = json::array()) {
  for (json& v : views) v["buffer"] = 0;
  node["mesh"] = 0;
  json j = {{"asset", {{"version", "2.0"}}},
            {"buffers", {{{"byteLength", bin.bytes.size()}, {"uri", "data.bin"}}}},
            {"accessors", accessors},
            {"meshes", {{{"primitives", {{{"attributes", attributes}}}}}}},
            {"nodes", {node}}};
  if (!extensions.empty()) j["extensionsUsed"] = extensions;
  if (!views.empty()) j["bufferViews"] = views;  // the schema: no empty arrays
  const std::string text = j.dump();
  GltfSource src;
  src.main_file = "t.gltf";
  src.files["t.gltf"].assign(text.begin(), text.end());
  src.files["data.bin"] = bin.bytes;
  return src;
}

// The positions of the one flat-shaded triangle (no normals: a vertex per corner).
std::vector<glm::vec3> Positions(const CpuScene& s) {
  std::vector<glm::vec3> out;
  for (const Vertex& v : s.vertices) out.push_back(v.position);
  return out;
}

TEST(GltfImportSparse, ReplacesElementsOfTheBufferView) {
  Bin bin;
  const size_t base = bin.Add<float>({0, 0, 0, 1, 0, 0, 0, 1, 0});
  const size_t idx = bin.Add<uint16_t>({0, 2});
  const size_t val = bin.Add<float>({0, 0, 1, 0, 2, 0});
  const json views = {{{"byteOffset", base}, {"byteLength", 36}},
                      {{"byteOffset", idx}, {"byteLength", 4}},
                      {{"byteOffset", val}, {"byteLength", 24}}};
  const json accessors = {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3},
                           {"type", "VEC3"},
                           {"sparse", {{"count", 2},
                                       {"indices", {{"bufferView", 1}, {"componentType", 5123}}},
                                       {"values", {{"bufferView", 2}}}}}}};
  absl::StatusOr<CpuScene> s = ImportGltf(TriangleSource(bin, views, accessors, {{"POSITION", 0}}));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(Positions(*s), (std::vector<glm::vec3>{{0, 0, 1}, {1, 0, 0}, {0, 2, 0}}));
}

TEST(GltfImportSparse, WithoutABufferViewStartsFromZeros) {
  Bin bin;
  const size_t idx = bin.Add<uint8_t>({1, 2});
  const size_t val = bin.Add<float>({1, 0, 0, 0, 1, 0});
  const json views = {{{"byteOffset", idx}, {"byteLength", 2}},
                      {{"byteOffset", val}, {"byteLength", 24}}};
  const json accessors = {{{"componentType", 5126}, {"count", 3}, {"type", "VEC3"},
                           {"sparse", {{"count", 2},
                                       {"indices", {{"bufferView", 0}, {"componentType", 5121}}},
                                       {"values", {{"bufferView", 1}}}}}}};
  absl::StatusOr<CpuScene> s = ImportGltf(TriangleSource(bin, views, accessors, {{"POSITION", 0}}));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(Positions(*s), (std::vector<glm::vec3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}}));
  // And an accessor without bufferView or sparse block is all zeros (here: UVs).
  json zero_uv = accessors;
  zero_uv.push_back({{"componentType", 5126}, {"count", 3}, {"type", "VEC2"}});
  s = ImportGltf(TriangleSource(bin, views, zero_uv, {{"POSITION", 0}, {"TEXCOORD_0", 1}}));
  ASSERT_TRUE(s.ok()) << s.status();
  for (const Vertex& v : s->vertices) EXPECT_EQ(v.uv0, glm::vec2(0.0f));
}

// A bufferView-less accessor costs nothing to upload: what such accessors expand to is bounded
// by the upload's size (16x, at least 16 MiB), so a few hundred bytes cannot ask for gigabytes.
// An accessor used twice is read (and expanded) once.
TEST(GltfImportSparse, ZerosAreBoundedByTheUploadAndReadOnce) {
  Bin bin;
  bin.Add<float>({0});
  const json huge = {{{"componentType", 5126}, {"count", 40000000}, {"type", "VEC3"}}};
  ExpectOverLimit(ImportGltf(TriangleSource(bin, json::array(), huge, {{"POSITION", 0}})),
                  {"accessors[0]", "expands to 480000000 bytes of zeros or sparse data",
                   "16x the uploaded files"});
  Bin tri;
  tri.Add<float>({0, 0, 0, 1, 0, 0, 0, 1, 0});
  GltfSource twice = Edited(
      TriangleSource(tri, {{{"byteOffset", 0}, {"byteLength", 36}}},
                     {{{"bufferView", 0}, {"componentType", 5126}, {"count", 3}, {"type", "VEC3"}},
                      {{"componentType", 5126}, {"count", 3}, {"type", "VEC2"}}},
                     {{"POSITION", 0}, {"TEXCOORD_0", 1}}),
      [](json& j) { j["meshes"][0]["primitives"].push_back(j["meshes"][0]["primitives"][0]); });
  absl::StatusOr<CpuScene> s = ImportGltf(twice);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->primitives.size(), 2u);
  // Without a bufferView a byteOffset means nothing: refused.
  ExpectInvalid(ImportGltf(Edited(twice, [](json& j) { j["accessors"][1]["byteOffset"] = 4; })),
                {"accessors[1].byteOffset", "set without a bufferView"});
}

TEST(GltfImportSparse, MalformedBlocksAreRefusedNamingTheField) {
  Bin bin;
  const size_t idx = bin.Add<uint16_t>({2, 1});
  const size_t val = bin.Add<float>({1, 0, 0, 0, 1, 0});
  const json views = {{{"byteOffset", idx}, {"byteLength", 4}},
                      {{"byteOffset", val}, {"byteLength", 24}}};
  auto accessor = [](json sparse) {
    return json{{{"componentType", 5126}, {"count", 3}, {"type", "VEC3"}, {"sparse", sparse}}};
  };
  const json indices = {{"bufferView", 0}, {"componentType", 5123}};
  const json values = {{"bufferView", 1}};
  auto import = [&](json sparse, json v = json()) {
    return ImportGltf(TriangleSource(bin, v.is_null() ? views : v, accessor(sparse),
                                     {{"POSITION", 0}}));
  };
  ExpectInvalid(import({{"count", 2}, {"indices", indices}, {"values", values}}),
                {"t.gltf", "accessors[0].sparse.indices", "index 1 at position 1 does not increase"});
  ExpectInvalid(import({{"count", 4}, {"indices", indices}, {"values", values}}),
                {"accessors[0].sparse.count", "4 is not in 1..3"});
  json float_indices = indices;
  float_indices["componentType"] = 5126;
  ExpectInvalid(import({{"count", 2}, {"indices", float_indices}, {"values", values}}),
                {"accessors[0].sparse.indices.componentType", "FLOAT"});
  json short_values = views;
  short_values[1]["byteLength"] = 20;
  ExpectInvalid(import({{"count", 2}, {"indices", indices}, {"values", values}}, short_values),
                {"accessors[0].sparse.values", "exceeds bufferViews[1].byteLength (20)"});
  json strided = views;
  strided[1]["byteStride"] = 12;
  ExpectInvalid(import({{"count", 2}, {"indices", indices}, {"values", values}}, strided),
                {"accessors[0].sparse.values.bufferView", "has a byteStride"});
  json far = {{"bufferView", 7}};
  ExpectInvalid(import({{"count", 2}, {"indices", indices}, {"values", far}}),
                {"accessors[0].sparse.values.bufferView", "out of range"});
  Bin big;
  const size_t at = big.Add<uint16_t>({0, 9});
  big.Add<float>({1, 0, 0, 0, 1, 0});
  const json big_views = {{{"byteOffset", at}, {"byteLength", 4}},
                          {{"byteOffset", at + 4}, {"byteLength", 24}}};
  ExpectInvalid(ImportGltf(TriangleSource(big, big_views,
                                          accessor({{"count", 2}, {"indices", indices},
                                                    {"values", values}}),
                                          {{"POSITION", 0}})),
                {"accessors[0].sparse.indices", "index 9 at position 1 is out of range (count 3)"});
}

// KHR_mesh_quantization (what gltfpack writes): SHORT positions dequantized by the node's
// scale, normalized BYTE normals, unnormalized UNSIGNED_SHORT texture coordinates; refused
// without the extension in extensionsUsed, and types it does not allow are refused with it.
TEST(GltfImportQuantization, QuantizedAttributesAreDequantized) {
  Bin bin;
  const size_t pos = bin.Add<int16_t>({0, 0, 0, 0, 100, 0, 0, 0, 0, 100, 0, 0});  // stride 8
  const size_t nrm = bin.Add<int8_t>({0, 0, 127, 0, 0, 127, 0, 0, -128, 0, 0, 0});  // stride 4
  const size_t uv = bin.Add<uint16_t>({0, 0, 2, 0, 0, 3});
  const json views = {{{"byteOffset", pos}, {"byteLength", 24}, {"byteStride", 8}},
                      {{"byteOffset", nrm}, {"byteLength", 12}, {"byteStride", 4}},
                      {{"byteOffset", uv}, {"byteLength", 12}}};
  const json accessors = {
      {{"bufferView", 0}, {"componentType", 5122}, {"count", 3}, {"type", "VEC3"}},
      {{"bufferView", 1}, {"componentType", 5120}, {"normalized", true}, {"count", 3},
       {"type", "VEC3"}},
      {{"bufferView", 2}, {"componentType", 5123}, {"count", 3}, {"type", "VEC2"}}};
  const json attributes = {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 2}};
  const json scale = {{"scale", {0.01, 0.01, 0.01}}};
  const json ext = {"KHR_mesh_quantization"};
  absl::StatusOr<CpuScene> s =
      ImportGltf(TriangleSource(bin, views, accessors, attributes, scale, ext));
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->vertices.size(), 3u);
  EXPECT_EQ(Positions(*s), (std::vector<glm::vec3>{{0, 0, 0}, {100, 0, 0}, {0, 100, 0}}));
  EXPECT_NEAR(s->bounds.max.x, 1.0f, 1e-5f);  // world bounds: the node's scale dequantizes
  EXPECT_NEAR(s->bounds.max.y, 1.0f, 1e-5f);
  EXPECT_EQ(s->vertices[0].normal, glm::vec3(0, 0, 1));
  EXPECT_EQ(s->vertices[1].normal, glm::vec3(0, 1, 0));
  EXPECT_EQ(s->vertices[2].normal, glm::vec3(-1, 0, 0));
  EXPECT_EQ(s->vertices[1].uv0, glm::vec2(2, 0));
  EXPECT_EQ(s->vertices[2].uv0, glm::vec2(0, 3));

  // Normalized BYTE texture coordinates (not renormalized afterwards, so the clamp of -128 to -1
  // shows) and normalized SHORT tangents.
  Bin more = bin;
  // Two bytes a coordinate pair, in a 4-byte stride (vertex data is 4-byte aligned).
  const size_t uv8 = more.Add<int8_t>({0, 64, 0, 0, -128, 127, 0, 0, 127, -127, 0, 0});
  const size_t tng = more.Add<int16_t>({32767, 0, 0, 32767, 0, 32767, 0, -32767, 0, 0, 32767, 32767});
  json more_views = views;
  more_views.push_back({{"byteOffset", uv8}, {"byteLength", 12}, {"byteStride", 4}});
  more_views.push_back({{"byteOffset", tng}, {"byteLength", 24}});
  json more_accessors = accessors;
  more_accessors.push_back({{"bufferView", 3}, {"componentType", 5120}, {"normalized", true},
                            {"count", 3}, {"type", "VEC2"}});
  more_accessors.push_back({{"bufferView", 4}, {"componentType", 5122}, {"normalized", true},
                            {"count", 3}, {"type", "VEC4"}});
  s = ImportGltf(TriangleSource(more, more_views, more_accessors,
                                {{"POSITION", 0}, {"NORMAL", 1}, {"TEXCOORD_0", 3}, {"TANGENT", 4}},
                                scale, ext));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->vertices[0].uv0, glm::vec2(0.0f, 64.0f / 127.0f));
  EXPECT_EQ(s->vertices[1].uv0, glm::vec2(-1.0f, 1.0f));  // -128 clamps to -1
  EXPECT_EQ(s->vertices[2].uv0, glm::vec2(1.0f, -1.0f));
  EXPECT_EQ(s->vertices[0].tangent, glm::vec4(1, 0, 0, 1));
  EXPECT_EQ(s->vertices[1].tangent, glm::vec4(0, 1, 0, -1));  // w: the bitangent sign
  EXPECT_EQ(s->vertices[2].tangent, glm::vec4(0, 0, 1, 1));

  ExpectInvalid(ImportGltf(TriangleSource(bin, views, accessors, attributes, scale)),
                {"accessors[0]", "POSITION as SHORT needs KHR_mesh_quantization"});
  json unsigned_normals = accessors;
  unsigned_normals[1]["componentType"] = 5121;
  ExpectInvalid(ImportGltf(TriangleSource(bin, views, unsigned_normals, attributes, scale, ext)),
                {"accessors[1]", "unsupported type/componentType for NORMAL",
                 "normalized UNSIGNED_BYTE"});
  // Required is fine too: the extension is supported.
  GltfSource required = Edited(TriangleSource(bin, views, accessors, attributes, scale, ext),
                               [](json& j) { j["extensionsRequired"] = {"KHR_mesh_quantization"}; });
  EXPECT_TRUE(ImportGltf(required).ok());
}

// KHR_materials_unlit: the material is unlit and keeps its base colour (factor, texture, alpha
// mode); the textures only lighting reads are checked, not decoded, and emission is dropped.
TEST(GltfImportUnlit, TheMaterialKeepsOnlyItsBaseColour) {
  REQUIRE_ASSETS();
  auto unlit = [](const std::function<void(json&)>& more) {
    return Edited(Source("BoxTextured/glTF/BoxTextured.gltf"), [&](json& j) {
      j["extensionsUsed"] = {"KHR_materials_unlit"};
      json& m = j["materials"][0];
      m["extensions"]["KHR_materials_unlit"] = json::object();
      m["alphaMode"] = "MASK";
      m["normalTexture"] = {{"index", 0}};
      m["emissiveTexture"] = {{"index", 0}};
      m["emissiveFactor"] = {1, 0.5, 0};
      more(j);
    });
  };
  absl::StatusOr<CpuScene> s = ImportGltf(unlit([](json&) {}));
  ASSERT_TRUE(s.ok()) << s.status();
  ASSERT_EQ(s->materials.size(), 1u);
  const Material& m = s->materials[0];
  EXPECT_TRUE(m.unlit);
  EXPECT_EQ(m.alpha_mode, AlphaMode::kMask);
  EXPECT_EQ(m.base_color.texture, 0);
  EXPECT_EQ(m.normal.texture, -1);
  EXPECT_EQ(m.emissive.texture, -1);
  EXPECT_EQ(m.emissive_factor, glm::vec3(0.0f));
  EXPECT_EQ(s->textures.size(), 1u);
  EXPECT_EQ(s->warnings, std::vector<std::string>{});
  // Required, it loads as well; without the extension the same material is lit.
  EXPECT_TRUE(
      ImportGltf(unlit([](json& j) { j["extensionsRequired"] = {"KHR_materials_unlit"}; })).ok());
  absl::StatusOr<CpuScene> lit = ImportGltf(Source("BoxTextured/glTF/BoxTextured.gltf"));
  ASSERT_TRUE(lit.ok()) << lit.status();
  EXPECT_FALSE(lit->materials[0].unlit);
  // A texture it ignores still has to exist; the extension's value has to be an object.
  ExpectInvalid(ImportGltf(unlit([](json& j) {
                  j["materials"][0]["occlusionTexture"] = {{"index", 4}};
                })),
                {"materials[0].occlusionTexture.index", "out of range"});
  ExpectInvalid(ImportGltf(unlit([](json& j) {
                  j["materials"][0]["extensions"]["KHR_materials_unlit"] = true;
                })),
                {"materials[0].extensions.KHR_materials_unlit", "not an object"});
  ExpectInvalid(ImportGltf(unlit([](json& j) { j.erase("extensionsUsed"); })),
                {"materials[0].extensions.KHR_materials_unlit", "not declared in extensionsUsed"});
}

// KHR_materials_ior and KHR_materials_specular: the material keeps the IOR, the specular factor
// and colour, and their textures (the colour's in sRGB, the factor's linear); values their
// schemas forbid and malformed textureInfos are refused, naming them; unlit drops them.
TEST(GltfImportSpecular, TheMaterialKeepsItsReflectance) {
  REQUIRE_ASSETS();
  auto specular = [](const std::function<void(json&)>& more) {
    return Edited(Source("BoxTextured/glTF/BoxTextured.gltf"), [&](json& j) {
      j["extensionsUsed"] = {"KHR_materials_ior", "KHR_materials_specular",
                             "KHR_texture_transform"};
      json& e = j["materials"][0]["extensions"];
      e["KHR_materials_ior"] = {{"ior", 1.33}};
      e["KHR_materials_specular"] = {
          {"specularFactor", 0.25},
          {"specularColorFactor", {2, 1, 0.5}},
          {"specularTexture", {{"index", 0}}},
          {"specularColorTexture",
           {{"index", 0}, {"extensions", {{"KHR_texture_transform", {{"scale", {2, 3}}}}}}}}};
      more(j);
    });
  };
  absl::StatusOr<CpuScene> s = ImportGltf(specular([](json&) {}));
  ASSERT_TRUE(s.ok()) << s.status();
  const Material& m = s->materials[0];
  EXPECT_FLOAT_EQ(m.ior, 1.33f);
  EXPECT_FLOAT_EQ(m.specular_factor, 0.25f);
  EXPECT_EQ(m.specular_color_factor, glm::vec3(2.0f, 1.0f, 0.5f));
  ASSERT_GE(m.specular.texture, 0);
  ASSERT_GE(m.specular_color.texture, 0);
  EXPECT_FALSE(s->textures[m.specular.texture].srgb);
  EXPECT_TRUE(s->textures[m.specular_color.texture].srgb);
  EXPECT_EQ(m.specular_color.scale, glm::vec2(2.0f, 3.0f));  // KHR_texture_transform
  EXPECT_EQ(m.specular.scale, glm::vec2(1.0f));
  EXPECT_EQ(s->warnings, std::vector<std::string>{});
  // Without the extensions: IOR 1.5, specular 1, white.
  absl::StatusOr<CpuScene> plain = ImportGltf(Source("BoxTextured/glTF/BoxTextured.gltf"));
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_EQ(plain->materials[0].ior, 1.5f);
  EXPECT_EQ(plain->materials[0].specular_factor, 1.0f);
  EXPECT_EQ(plain->materials[0].specular_color_factor, glm::vec3(1.0f));
  EXPECT_EQ(plain->materials[0].specular.texture, -1);
  // Required, they load; ior 0 (F0 1: the specular-glossiness conversion) is allowed.
  s = ImportGltf(specular([](json& j) {
    j["extensionsRequired"] = {"KHR_materials_ior", "KHR_materials_specular"};
    j["materials"][0]["extensions"]["KHR_materials_ior"]["ior"] = 0;
  }));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_EQ(s->materials[0].ior, 0.0f);
  // What the schemas forbid.
  auto refused = [&](const std::function<void(json&)>& edit,
                     const std::vector<std::string>& words) {
    ExpectInvalid(ImportGltf(specular(edit)), words);
  };
  const std::string ior = "materials[0].extensions.KHR_materials_ior";
  const std::string sp = "materials[0].extensions.KHR_materials_specular";
  refused([](json& j) { j["materials"][0]["extensions"]["KHR_materials_ior"]["ior"] = 0.5; },
          {ior + ".ior", "out of range"});
  refused([](json& j) { j["materials"][0]["extensions"]["KHR_materials_ior"] = 1.5; },
          {ior, "not an object"});
  refused(
      [](json& j) {
        j["materials"][0]["extensions"]["KHR_materials_specular"]["specularFactor"] = 1.5;
      },
      {sp + ".specularFactor", "out of range"});
  refused(
      [](json& j) {
        j["materials"][0]["extensions"]["KHR_materials_specular"]["specularColorFactor"] = {1, -1,
                                                                                            1};
      },
      {sp + ".specularColorFactor[1]", "out of range"});
  refused(
      [](json& j) {
        j["materials"][0]["extensions"]["KHR_materials_specular"]["specularTexture"] = {
            {"index", 7}};
      },
      {sp + ".specularTexture.index", "out of range"});
  refused(
      [](json& j) {
        j["materials"][0]["extensions"]["KHR_materials_specular"]["specularColorTexture"] = {
            {"index", -1}};
      },
      {sp + ".specularColorTexture.index", "non-negative integer"});
  refused(
      [](json& j) {
        j["materials"][0]["extensions"]["KHR_materials_specular"]["specularTexture"] = {
            {"index", 0}, {"texCoord", 1}};
      },
      {"reads TEXCOORD_1"});
  // Malformed textureInfos, and integers past 32 bits (tinygltf would read 4294967296 as 0).
  auto texture_info = [&](json info, const std::vector<std::string>& words) {
    refused(
        [&](json& j) {
          j["materials"][0]["extensions"]["KHR_materials_specular"]["specularTexture"] = info;
        },
        words);
  };
  texture_info(0, {sp + ".specularTexture", "not an object"});
  texture_info({{"index", 0.5}}, {sp + ".specularTexture.index", "non-negative integer"});
  texture_info({{"index", "0"}}, {sp + ".specularTexture.index", "non-negative integer"});
  texture_info(json::object(), {sp + ".specularTexture.index", "non-negative integer"});
  texture_info({{"index", 0}, {"texCoord", 0.5}},
               {sp + ".specularTexture.texCoord", "non-negative integer"});
  texture_info({{"index", 4294967296u}},
               {sp + ".specularTexture.index", "4294967296 out of range"});
  s = ImportGltf(specular([](json& j) {
    json& e = j["materials"][0]["extensions"];
    e["KHR_materials_ior"]["ior"] = 4294967296u;
    e["KHR_materials_specular"]["specularColorFactor"] = {2147483648u, 0, 1};
  }));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_GT(s->materials[0].ior, 1e6f * 0.99f);
  EXPECT_GT(s->materials[0].specular_color_factor.r, 1e6f * 0.99f);
  refused([](json& j) { j.erase("extensionsUsed"); }, {"not declared in extensionsUsed"});
  // With KHR_materials_unlit (which both extensions' specs exclude) the material is unlit: the
  // reflectance is dropped and its textures are checked, not decoded.
  s = ImportGltf(specular([](json& j) {
    j["extensionsUsed"].push_back("KHR_materials_unlit");
    j["materials"][0]["extensions"]["KHR_materials_unlit"] = json::object();
  }));
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_TRUE(s->materials[0].unlit);
  EXPECT_EQ(s->materials[0].ior, 1.5f);
  EXPECT_EQ(s->materials[0].specular_factor, 1.0f);
  EXPECT_EQ(s->materials[0].specular.texture, -1);
  EXPECT_EQ(s->materials[0].specular_color.texture, -1);
  EXPECT_EQ(s->textures.size(), 1u);
}

// tinygltf keeps an extension's values as plain values with an integer cast to int, so an
// integer beyond 32 bits wrapped (4294967296 read as 0). The pre-scan makes such integers doubles:
// they read as themselves, clamped where the importer clamps, refused where an index is checked.
TEST(GltfImportExtensions, IntegersBeyond32BitsReadAsThemselves) {
  REQUIRE_ASSETS();
  const uint64_t wide = 4294967296u;  // 2^32: the int cast gives 0
  absl::StatusOr<CpuScene> s =
      ImportGltf(Edited(Source("BoxTextured/glTF/BoxTextured.gltf"), [&](json& j) {
        j["extensionsUsed"] = {"KHR_materials_emissive_strength", "KHR_texture_transform"};
        json& m = j["materials"][0];
        m["emissiveFactor"] = {1, 1, 1};
        m["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = wide;
        m["pbrMetallicRoughness"]["baseColorTexture"]["extensions"]["KHR_texture_transform"] = {
            {"scale", {wide, 1}}, {"offset", {-int64_t(wide) - 1, 0}}};
      }));
  ASSERT_TRUE(s.ok()) << s.status();
  const Material& m = s->materials[0];
  EXPECT_EQ(m.emissive_strength, 1e6f);  // clamped, not 0
  EXPECT_EQ(m.base_color.scale, glm::vec2(1e6f, 1.0f));
  EXPECT_EQ(m.base_color.offset, glm::vec2(-1e6f, 0.0f));
  // A light index of 2^32 is out of range, not light 0.
  ExpectInvalid(
      ImportGltf(Edited(Source("Box/glTF/Box.gltf"),
                        [&](json& j) {
                          j["extensionsUsed"] = {"KHR_lights_punctual"};
                          j["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}}};
                          j["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] = wide;
                        })),
      {"nodes[0].extensions.KHR_lights_punctual.light", "light index out of range"});
  // Below -2^31 too (-2^32 + 1: the int cast gives light 1).
  ExpectInvalid(ImportGltf(Edited(Source("Box/glTF/Box.gltf"),
                                  [&](json& j) {
                                    j["extensionsUsed"] = {"KHR_lights_punctual"};
                                    j["extensions"]["KHR_lights_punctual"]["lights"] = {
                                        {{"type", "point"}}, {{"type", "point"}}};
                                    j["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] =
                                        -int64_t(wide) + 1;
                                  })),
                {"nodes[0].extensions.KHR_lights_punctual.light", "light index out of range"});
  // In a .glb, whose JSON chunk the pre-scan re-writes around its BIN chunk.
  const GltfSource box = Source("Box/glTF/Box.gltf");
  const std::vector<uint8_t>& main = box.files.at(box.main_file);
  json j = json::parse(main.begin(), main.end());
  j["buffers"][0].erase("uri");  // the BIN chunk
  j["extensionsUsed"] = {"KHR_materials_emissive_strength"};
  j["materials"][0]["emissiveFactor"] = {1, 1, 1};
  j["materials"][0]["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = wide;
  absl::StatusOr<CpuScene> glb =
      ImportGltf(testing::GlbSource(j, box.files.at("Box0.bin"), "Box.glb"));
  ASSERT_TRUE(glb.ok()) << glb.status();
  EXPECT_EQ(glb->materials[0].emissive_strength, 1e6f);
  EXPECT_EQ(glb->vertices.size(), 24u);  // the BIN chunk still read
}

// Inside extensions too, a float that is an integer reads as the integer (as the validator
// reads it): a texture index 0.0 and a light index 0.0 were refused as "wants a non-negative
// integer" / out of range; a number field reads the same either way.
TEST(GltfImportExtensions, IntegersWrittenAsFloatsReadAsIntegers) {
  REQUIRE_ASSETS();
  absl::StatusOr<CpuScene> s =
      ImportGltf(Edited(Source("BoxTextured/glTF/BoxTextured.gltf"), [](json& j) {
        j["extensionsUsed"] = {"KHR_materials_specular", "KHR_materials_emissive_strength",
                               "KHR_lights_punctual"};
        json& m = j["materials"][0];
        m["emissiveFactor"] = {1, 1, 1};
        m["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = 2.0;
        m["extensions"]["KHR_materials_specular"] = {
            {"specularTexture", {{"index", 0.0}, {"texCoord", 0.0}}}, {"specularFactor", 1.0}};
        j["extensions"]["KHR_lights_punctual"]["lights"] = {
            {{"type", "point"}, {"color", {1.0, 0.5, 0.0}}, {"intensity", 3.0}}};
        j["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] = 0.0;
      }));
  ASSERT_TRUE(s.ok()) << s.status();
  const Material& m = s->materials[0];
  EXPECT_EQ(m.emissive_strength, 2.0f);
  EXPECT_EQ(m.specular_factor, 1.0f);
  ASSERT_GE(m.specular.texture, 0);
  EXPECT_EQ(m.specular.texcoord, 0u);
  ASSERT_EQ(s->lights.size(), 1u);
  EXPECT_EQ(s->lights[0].color, glm::vec3(1.0f, 0.5f, 0.0f));
  EXPECT_EQ(s->lights[0].intensity, 3.0f);
  // A fraction is still no index.
  ExpectInvalid(
      ImportGltf(Edited(Source("Box/glTF/Box.gltf"),
                        [](json& j) {
                          j["extensionsUsed"] = {"KHR_lights_punctual"};
                          j["extensions"]["KHR_lights_punctual"]["lights"] = {{{"type", "point"}}};
                          j["nodes"][0]["extensions"]["KHR_lights_punctual"]["light"] = 0.5;
                        })),
      {"nodes[0].extensions.KHR_lights_punctual.light", "light index 0.5 is not an integer"});
}

// ----- COLOR_0 ------------------------------------------------------------------------------

// Box (24 vertices) with COLOR_0: `count` elements of `type` ("VEC3"/"VEC4") in `component_type`,
// vertex i's channel c being `value(i, c)` in [0, 1] (stored as the type holds it), then `edit`.
GltfSource ColoredBox(const char* type, int component_type, bool normalized,
                      const std::function<float(int, int)>& value,
                      const std::function<void(json&)>& edit, int count = 24) {
  GltfSource src = Source("Box/glTF/Box.gltf");
  std::vector<uint8_t>& bin = src.files.at("Box0.bin");
  const int channels = std::string(type) == "VEC3" ? 3 : 4;
  const size_t size = component_type == 5126 ? 4 : component_type == 5123 ? 2 : 1;
  bin.resize((bin.size() + 3) / 4 * 4);
  const size_t offset = bin.size();
  for (int i = 0; i < count; ++i) {
    for (int c = 0; c < channels; ++c) {
      const float v = value(i, c);
      uint8_t bytes[4];
      if (size == 4) {
        std::memcpy(bytes, &v, 4);
      } else if (size == 2) {
        const uint16_t u = uint16_t(std::lround(v * 65535.0f));
        std::memcpy(bytes, &u, 2);
      } else {
        bytes[0] = uint8_t(std::lround(v * 255.0f));
      }
      bin.insert(bin.end(), bytes, bytes + size);
    }
    bin.resize((bin.size() + 3) / 4 * 4);  // each element 4-byte aligned (glTF 3.6.2.4)
  }
  const size_t stride = (channels * size + 3) / 4 * 4;
  return Edited(std::move(src), [&](json& j) {
    json view = {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bin.size() - offset}};
    if (stride != channels * size) view["byteStride"] = stride;
    j["bufferViews"].push_back(view);
    json accessor = {{"bufferView", j["bufferViews"].size() - 1},
                     {"componentType", component_type},
                     {"count", count},
                     {"type", type}};
    if (normalized) accessor["normalized"] = true;
    j["accessors"].push_back(accessor);
    j["buffers"][0]["byteLength"] = bin.size();
    j["meshes"][0]["primitives"][0]["attributes"]["COLOR_0"] = j["accessors"].size() - 1;
    edit(j);
  });
}

float Channel(int i, int c) { return float((i * 7 + c * 3) % 11) / 10.0f; }

// RGB and RGBA, as floats and as normalized unsigned bytes and shorts: each vertex's colour as
// the file gives it (RGB with alpha 1), and the primitive marked; without COLOR_0, white.
TEST(GltfImportVertexColors, EachVertexKeepsItsColour) {
  REQUIRE_ASSETS();
  struct Case {
    const char* type;
    int component_type;
    float tolerance;
  } cases[] = {{"VEC3", 5126, 1e-3f},
               {"VEC4", 5126, 1e-3f},
               {"VEC4", 5121, 1.0f / 255},
               {"VEC3", 5123, 1e-3f}};
  for (const Case& c : cases) {
    SCOPED_TRACE(std::string(c.type) + " " + std::to_string(c.component_type));
    absl::StatusOr<CpuScene> s = ImportGltf(
        ColoredBox(c.type, c.component_type, c.component_type != 5126, Channel, [](json&) {}));
    ASSERT_TRUE(s.ok()) << s.status();
    ASSERT_EQ(s->primitives.size(), 1u);
    EXPECT_TRUE(s->primitives[0].vertex_colors);
    ASSERT_EQ(s->vertices.size(), 24u);
    for (int i = 0; i < 24; ++i) {
      const glm::vec4 got = UnpackVertexColor(s->vertices[i].color);
      for (int ch = 0; ch < 4; ++ch) {
        const float want = ch == 3 && std::string(c.type) == "VEC3" ? 1.0f : Channel(i, ch);
        // Halves: 11 significant bits.
        EXPECT_NEAR(got[ch], want, c.tolerance + want / 1024.0f) << "vertex " << i << " ch " << ch;
      }
    }
    EXPECT_EQ(s->warnings, std::vector<std::string>{});
  }
  absl::StatusOr<CpuScene> plain = ImportGltf(Source("Box/glTF/Box.gltf"));
  ASSERT_TRUE(plain.ok()) << plain.status();
  EXPECT_FALSE(plain->primitives[0].vertex_colors);
  EXPECT_EQ(UnpackVertexColor(plain->vertices[0].color), glm::vec4(1.0f));
}

TEST(GltfImportVertexColors, MalformedColoursAreRefusedNamingThem) {
  REQUIRE_ASSETS();
  const std::string field = "meshes[0].primitives[0].attributes.COLOR_0";
  ExpectInvalid(ImportGltf(ColoredBox("VEC2", 5126, false, Channel, [](json&) {})),
                {field, "unsupported type/componentType for COLOR_0"});
  // Unnormalized bytes, signed shorts: not colours.
  ExpectInvalid(ImportGltf(ColoredBox("VEC4", 5121, false, Channel, [](json&) {})),
                {field, "unsupported type/componentType for COLOR_0"});
  ExpectInvalid(
      ImportGltf(ColoredBox("VEC4", 5123, true, Channel,
                            [](json& j) { j["accessors"].back()["componentType"] = 5122; })),
      {field, "unsupported type/componentType for COLOR_0"});
  ExpectInvalid(ImportGltf(ColoredBox(
                    "VEC4", 5126, false, Channel, [](json&) {}, 23)),
                {field, "COLOR_0 count 23 differs from POSITION count 24"});
  // Float values outside [0, 1] (the validator's ACCESSOR_NON_CLAMPED), NaN too.
  ExpectInvalid(ImportGltf(ColoredBox(
                    "VEC4", 5126, false,
                    [](int i, int c) { return i == 5 && c == 2 ? 4.0f : 0.5f; }, [](json&) {})),
                {field, "element 5 has 4 outside [0, 1]"});
  ExpectInvalid(ImportGltf(ColoredBox(
                    "VEC3", 5126, false, [](int i, int) { return i == 0 ? std::nanf("") : 0.5f; },
                    [](json&) {})),
                {field, "element 0 has nan outside [0, 1]"});
  // Three bytes a colour, tightly packed: not 4-byte aligned (MESH_PRIMITIVE_ACCESSOR_UNALIGNED).
  ExpectInvalid(
      ImportGltf(ColoredBox("VEC3", 5121, true, Channel,
                            [](json& j) { j["bufferViews"].back().erase("byteStride"); })),
      {field, "COLOR_0 data is not aligned to 4 bytes", "3-byte elements without a byteStride"});
}

}  // namespace
}  // namespace tessera

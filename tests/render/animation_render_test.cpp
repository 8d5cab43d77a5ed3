// Animated scenes on the device (renderer/features/skinning.cpp, shaders/skin.comp): the skinned
// and morphed vertices against the CPU reference (renderer/scene/animation.h), posed frames
// against the same geometry baked into a static scene, culling with the posed bounds, shadows
// re-rendered per pose, goldens at two times, and refusals naming settings.animation. The
// scenes come from tests/gltf/make_animated.py (a two-bone cylinder, a morphing cube, three
// TRS-animated cubes, a skinned crowd), generated at build time.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "renderer/camera.h"
#include "renderer/image_metrics.h"
#include "renderer/renderer.h"
#include "renderer/scene/animation.h"
#include "renderer/scene/gltf_import.h"
#include "renderer/scene/scene_animator.h"
#include "tests/render/golden.h"

namespace tessera {
namespace {

struct Loaded {
  CpuScene cpu;
  SceneHandle scene;
};

Loaded LoadPath(const std::string& path) {
  Loaded out;
  absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
  EXPECT_TRUE(source.ok()) << source.status();
  if (!source.ok()) return out;
  absl::StatusOr<CpuScene> cpu = ImportGltf(*source);
  EXPECT_TRUE(cpu.ok()) << cpu.status();
  if (cpu.ok()) out.cpu = std::move(*cpu);
  absl::StatusOr<SceneHandle> scene = SharedRenderer().LoadScene(*source);
  EXPECT_TRUE(scene.ok()) << scene.status();
  if (scene.ok()) out.scene = *scene;
  return out;
}

Loaded Load(const std::string& name) {
  return LoadPath(std::string(TESSERA_ANIMATED_DIR) + "/" + name + ".gltf");
}

// A generated scene with its glTF JSON edited by `edit`, written under `dir` next to the test's
// other output (with its buffer).
Loaded LoadEdited(const std::string& name, const std::string& dir_name,
                  const std::function<void(nlohmann::json&)>& edit) {
  const std::filesystem::path dir =
      std::filesystem::path(Env("TESSERA_TEST_OUTPUT_DIR", TESSERA_DEFAULT_OUTPUT_DIR)) / dir_name;
  std::filesystem::create_directories(dir);
  const std::filesystem::path from(TESSERA_ANIMATED_DIR);
  std::filesystem::copy_file(from / (name + ".bin"), dir / (name + ".bin"),
                             std::filesystem::copy_options::overwrite_existing);
  absl::StatusOr<std::vector<uint8_t>> text = ReadFileBytes((from / (name + ".gltf")).string());
  EXPECT_TRUE(text.ok()) << text.status();
  if (!text.ok()) return {};
  nlohmann::json gltf = nlohmann::json::parse(text->begin(), text->end());
  edit(gltf);
  const std::string out = gltf.dump();
  EXPECT_TRUE(WriteFileBytes((dir / (name + ".gltf")).string(),
                             std::vector<uint8_t>(out.begin(), out.end()))
                  .ok());
  return LoadPath((dir / (name + ".gltf")).string());
}

// The morphing cube without its normals: the importer gives it flat normals, which a morphed pose
// must recompute from the moved faces.
Loaded LoadFlatMorphCube() {
  return LoadEdited("morph_cube", "flat_morph", [](nlohmann::json& gltf) {
    for (auto& mesh : gltf["meshes"])
      for (auto& prim : mesh["primitives"]) prim["attributes"].erase("NORMAL");
  });
}

Settings Small(uint32_t w = 160, uint32_t h = 120) {
  Settings s;
  s.width = w;
  s.height = h;
  return s;
}

Settings At(Settings s, const std::string& animation, float t) {
  s.animation = animation;
  s.scene_time = t;
  return s;
}

Camera Framing(const SceneInfo& info, const Settings& s, glm::vec3 dir = {0.3f, 0.35f, 1.0f}) {
  // The rest bounds grown a little: the poses reach past them.
  Aabb b = info.bounds;
  const glm::vec3 pad = b.extent() * 0.35f;
  b.min -= pad;
  b.max += pad;
  return FrameBounds(b, 0.8f, float(s.width) / float(s.height), dir);
}

// A camera that sees the whole of what animation 0 sweeps (its poses at 21 times and the rest
// pose), so a golden shows every posed shape whole.
Camera SweptFraming(const Loaded& l, const Settings& s) {
  Aabb swept = l.scene->info().bounds;
  const std::unique_ptr<SceneAnimator> a = SceneAnimator::Create(l.cpu);
  const float duration = l.cpu.animations.at(0).duration;
  for (int k = 0; k <= 20; ++k) {
    a->Pose(0, duration * float(k) / 20.0f, false);
    for (const Aabb& b : a->bounds()) swept.extend(b);
  }
  return FrameBounds(swept, 0.8f, float(s.width) / float(s.height), {0.3f, 0.35f, 1.0f});
}

Frame RenderOk(const Scene& scene, const Camera& c, const Settings& s) {
  absl::StatusOr<Frame> f = SharedRenderer().Render(scene, c, s);
  EXPECT_TRUE(f.ok()) << f.status();
  return f.ok() ? std::move(*f) : Frame{};
}

// The CPU reference of one deformed vertex (glTF 3.7.2-3.7.3; what skin.comp computes).
struct Deformed {
  glm::vec3 position, normal;
};

// Vertex v of primitive p morphed by `weights`, then skinned by `joints` (if given).
Deformed Deform(const CpuScene& cpu, const Primitive& p, uint32_t v,
                const std::vector<float>& weights, const std::vector<glm::mat4>* joints) {
  const Vertex& rest = cpu.vertices[p.first_vertex + v];
  Deformed d{rest.position, rest.normal};
  if (p.morph_targets) {
    const MorphDelta* deltas = &cpu.morph_deltas[p.first_morph_delta + v];
    d.position = MorphPosition(rest.position, deltas, p.vertex_count, weights);
    for (size_t t = 0; t < weights.size(); ++t)
      d.normal += weights[t] * deltas[t * p.vertex_count].normal;
  }
  if (joints) {
    const glm::uvec4 j = cpu.skin_joints[p.first_vertex + v];
    const glm::vec4 w = cpu.skin_weights[p.first_vertex + v];
    glm::mat4 m(0.0f);
    for (int k = 0; k < 4; ++k) m += w[k] * (*joints)[j[k]];
    d.position = SkinPoint(d.position, j, w, *joints);
    d.normal = glm::mat3(m) * d.normal;
  }
  return d;
}

// The deformed vertex with its unit normal: for flat normals (no normals in the file), its
// deformed face's (corners 3t, 3t + 1, 3t + 2).
Deformed Reference(const CpuScene& cpu, const Primitive& p, uint32_t v,
                   const std::vector<float>& weights, const std::vector<glm::mat4>* joints) {
  Deformed d = Deform(cpu, p, v, weights, joints);
  if (!p.flat_normals) {
    d.normal = glm::normalize(d.normal);
    return d;
  }
  const uint32_t first = v - v % 3;
  const glm::vec3 a = Deform(cpu, p, first, weights, joints).position;
  const glm::vec3 b = Deform(cpu, p, first + 1, weights, joints).position;
  const glm::vec3 c = Deform(cpu, p, first + 2, weights, joints).position;
  d.normal = glm::normalize(glm::cross(b - a, c - a));
  return d;
}

// Every deformed drawable's vertices on the device after a frame at (animation, t) against the
// CPU reference.
void ExpectDeviceMatchesReference(const Loaded& l, int animation, float t, float tolerance) {
  const std::unique_ptr<SceneAnimator> animator = SceneAnimator::Create(l.cpu);
  ASSERT_NE(animator, nullptr);
  const ScenePose pose = EvaluatePose(l.cpu.nodes, l.cpu.animations, animation, t, true);
  uint32_t checked = 0;
  for (const AnimatedDrawable& ad : animator->drawables()) {
    if (!ad.deformed) continue;
    const Primitive& p = l.cpu.primitives[ad.primitive];
    absl::StatusOr<std::vector<Vertex>> device =
        SharedRenderer().ReadVerticesForTesting(*l.scene, ad.first_vertex, p.vertex_count);
    ASSERT_TRUE(device.ok()) << device.status();
    std::vector<float> weights = pose.weights[ad.node];
    weights.resize(p.morph_targets, 0.0f);
    std::vector<glm::mat4> joints;
    if (ad.skin >= 0) joints = JointMatrices(l.cpu.skins[size_t(ad.skin)], pose);
    for (uint32_t v = 0; v < p.vertex_count; ++v) {
      const Deformed want = Reference(l.cpu, p, v, weights, ad.skin >= 0 ? &joints : nullptr);
      const Vertex& got = (*device)[v];
      for (int k = 0; k < 3; ++k) {
        ASSERT_NEAR(got.position[k], want.position[k], tolerance)
            << "drawable " << ad.drawable << " vertex " << v << " axis " << k << " at t=" << t;
        ASSERT_NEAR(got.normal[k], want.normal[k], 1e-3f)
            << "drawable " << ad.drawable << " vertex " << v << " normal axis " << k;
      }
      EXPECT_EQ(got.uv0, l.cpu.vertices[p.first_vertex + v].uv0);
      ++checked;
    }
  }
  EXPECT_GT(checked, 0u);
}

TEST(AnimationRender, SkinnedAndMorphedVerticesMatchTheCpuReference) {
  struct Case {
    const char* file;
    const char* animation;
    std::vector<float> times;
  };
  for (const Case& c : {Case{"skinned_cylinder", "bend", {0.5f, 1.0f, 2.6f}},
                        Case{"morph_cube", "morph", {0.5f, 1.5f}},
                        Case{"crowd", "wave", {0.3f, 1.7f}}}) {
    SCOPED_TRACE(c.file);
    const Loaded l = Load(c.file);
    ASSERT_TRUE(l.scene);
    // The upload's device memory, copies and pose buffers included, is what the server's
    // admission check estimates from the CPU scene.
    EXPECT_EQ(SharedRenderer().EstimateDeviceBytes(l.cpu), l.scene->info().device_bytes);
    const Settings base = Small(64, 48);
    const Camera cam = Framing(l.scene->info(), base);
    for (float t : c.times) {
      const Frame f = RenderOk(*l.scene, cam, At(base, c.animation, t));
      EXPECT_GT(f.stats.animated_drawables, 0u);
      EXPECT_GT(f.stats.deformed_vertices, 0u) << "a new pose re-skins";
      ExpectDeviceMatchesReference(l, 0, t, 1e-4f);
      // The same pose again: nothing to re-skin, the same picture.
      const Frame again = RenderOk(*l.scene, cam, At(base, c.animation, t));
      EXPECT_EQ(again.stats.deformed_vertices, 0u);
      EXPECT_EQ(again.image.pixels, f.image.pixels);
    }
    // The rest pose (no animation) is skinned too: with the bind pose, the rest vertices.
    RenderOk(*l.scene, cam, At(base, "none", 0.0f));
    ExpectDeviceMatchesReference(l, -1, 0.0f, 1e-4f);
  }
  // Flat normals follow the morphed faces.
  const Loaded flat = LoadFlatMorphCube();
  ASSERT_TRUE(flat.scene);
  ASSERT_TRUE(flat.cpu.primitives[0].flat_normals);
  const Settings base = Small(64, 48);
  RenderOk(*flat.scene, Framing(flat.scene->info(), base), At(base, "morph", 1.5f));
  ExpectDeviceMatchesReference(flat, 0, 1.5f, 1e-4f);
  ExpectNoValidationMessages(SharedRenderer());
}

// The scene at (animation, t) with its pose baked in: the deformed vertices in place (world
// space for skinned ones), each drawable at its posed world matrix, no animation left.
CpuScene Baked(const CpuScene& cpu, int animation, float t) {
  CpuScene out = cpu;
  const std::unique_ptr<SceneAnimator> animator = SceneAnimator::Create(cpu);
  const ScenePose pose = EvaluatePose(cpu.nodes, cpu.animations, animation, t, true);
  for (const AnimatedDrawable& ad : animator->drawables()) {
    Drawable& d = out.drawables[ad.drawable];
    const Primitive& p = cpu.primitives[ad.primitive];
    d.world = ad.skin >= 0 ? glm::mat4(1.0f) : pose.world[ad.node];
    if (ad.deformed) {
      std::vector<float> weights = pose.weights[ad.node];
      weights.resize(p.morph_targets, 0.0f);
      std::vector<glm::mat4> joints;
      if (ad.skin >= 0) joints = JointMatrices(cpu.skins[size_t(ad.skin)], pose);
      Aabb object;
      for (uint32_t v = 0; v < p.vertex_count; ++v) {
        const Deformed r = Reference(cpu, p, v, weights, ad.skin >= 0 ? &joints : nullptr);
        out.vertices[p.first_vertex + v].position = r.position;
        out.vertices[p.first_vertex + v].normal = r.normal;
        object.extend(r.position);
      }
      out.primitives[ad.primitive].bounds = object;
    }
    d.world_bounds = out.primitives[ad.primitive].bounds.transformed(d.world);
  }
  for (Light& l : out.lights) {
    if (l.node < 0) continue;
    const glm::mat4& w = pose.world[size_t(l.node)];
    l.position = glm::vec3(w[3]);
    l.direction = glm::normalize(glm::mat3(w) * glm::vec3(0.0f, 0.0f, -1.0f));
  }
  for (SceneCamera& c : out.cameras)
    if (c.node >= 0) c.world = pose.world[size_t(c.node)];
  out.nodes.clear();
  out.animations.clear();
  out.skins.clear();
  out.skin_joints.clear();
  out.skin_weights.clear();
  out.morph_deltas.clear();
  for (Primitive& p : out.primitives) {
    p.skinned = false;
    p.morph_targets = 0;
  }
  out.bounds = Aabb{};
  for (const Drawable& d : out.drawables) out.bounds.extend(d.world_bounds);
  return out;
}

TEST(AnimationRender, PosedFramesMatchTheirPoseBakedIntoAStaticScene) {
  struct Case {
    const char* file;
    const char* animation;
    float t;
  };
  for (const Case& c : {Case{"skinned_cylinder", "bend", 1.0f}, Case{"morph_cube", "morph", 1.5f},
                        Case{"trs_nodes", "move", 0.75f}}) {
    SCOPED_TRACE(c.file);
    const Loaded l = Load(c.file);
    ASSERT_TRUE(l.scene);
    absl::StatusOr<SceneHandle> baked = SharedRenderer().LoadScene(Baked(l.cpu, 0, c.t));
    ASSERT_TRUE(baked.ok()) << baked.status();
    const Settings s = Small();
    const Camera cam = Framing(l.scene->info(), s);
    // Forward, the visibility buffer (it reads the vertices itself) and vis_mlaa; and vis_mlaa
    // with gpu_occlusion and culled local lights, the frame that binds the most storage buffers
    // (the skinning pass's, two culling phases', light culling's and vis_mlaa's).
    Settings visibility = s, vis_mlaa = s, busiest = s;
    visibility.pipeline = Pipeline::kVisibility;
    vis_mlaa.aa = AaMode::kVisMlaa;
    busiest.aa = AaMode::kVisMlaa;
    busiest.culling = CullingMode::kGpuOcclusion;
    busiest.synthetic_lights = 8;
    for (const Settings& v : {s, visibility, vis_mlaa, busiest}) {
      RenderOk(*l.scene, cam, At(v, c.animation, c.t + 0.25f));  // so the frame below re-poses
      const Frame posed = RenderOk(*l.scene, cam, At(v, c.animation, c.t));
      EXPECT_GT(posed.stats.animated_drawables, 0u);
      const Frame still = RenderOk(**baked, cam, v);
      absl::StatusOr<double> psnr = Psnr(posed.image, still.image);
      ASSERT_TRUE(psnr.ok()) << psnr.status();
      std::printf("%s at %.2f s against its baked pose (%s, %s): %.1f dB\n", c.file, c.t,
                  std::string(ToString(posed.settings.effective.pipeline)).c_str(),
                  std::string(ToString(posed.settings.effective.aa)).c_str(), *psnr);
      EXPECT_GE(*psnr, 45.0);
    }
    const Frame posed = RenderOk(*l.scene, cam, At(s, c.animation, c.t));
    // And the pose moved something: the rest pose looks different.
    const Frame rest = RenderOk(*l.scene, cam, s);
    absl::StatusOr<double> moved = Psnr(posed.image, rest.image);
    ASSERT_TRUE(moved.ok());
    EXPECT_LT(*moved, 30.0);
  }
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(AnimationRender, FileCamerasAndLightsFollowTheirAnimatedNodes) {
  // camera_light: the file's camera slides from x = -3 to 3 over 2 s and its point light from
  // x = -2 to 2. Rendering through the file camera at time t is the baked scene seen from the
  // camera's posed place, lit by the light at its posed place.
  const Loaded l = Load("camera_light");
  ASSERT_TRUE(l.scene);
  ASSERT_EQ(l.scene->info().cameras.size(), 1u);
  const Settings s = Small();
  const Camera file = FromSceneCamera(l.scene->info().cameras[0], 0);
  RgbaImage seen[2];
  int i = 0;
  for (float t : {0.5f, 1.5f}) {
    SCOPED_TRACE(t);
    const CpuScene baked = Baked(l.cpu, 0, t);
    absl::StatusOr<SceneHandle> still = SharedRenderer().LoadScene(baked);
    ASSERT_TRUE(still.ok()) << still.status();
    const Frame posed = RenderOk(*l.scene, file, At(s, "fly", t));
    const Frame want = RenderOk(**still, FromSceneCamera(baked.cameras[0]), s);
    absl::StatusOr<double> psnr = Psnr(posed.image, want.image);
    ASSERT_TRUE(psnr.ok());
    EXPECT_GE(*psnr, 45.0);
    seen[i++] = posed.image;
  }
  absl::StatusOr<double> between = Psnr(seen[0], seen[1]);
  ASSERT_TRUE(between.ok());
  EXPECT_LT(*between, 30.0) << "the camera moved";
  // The same camera without its scene_camera tag stays where the file put it at rest.
  const Frame rest = RenderOk(*l.scene, FromSceneCamera(l.scene->info().cameras[0]), At(s, "fly", 1.5f));
  EXPECT_NE(rest.image.pixels, seen[1].pixels);
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(AnimationRender, CullingUsesThePosedBounds) {
  // At t = 0.9 the "linear" cube has risen from (-2, 0, 0) to (-2, 0.9, 0) and turned. The
  // camera sees only the space above the rest pose: culling by the rest bounds would drop it.
  // (Not t = 1: the animation lasts 1 s, and looping shows 1 s as 0 s.)
  const Loaded l = Load("trs_nodes");
  ASSERT_TRUE(l.scene);
  Settings s = At(Small(), "move", 0.9f);
  Camera cam;
  cam.eye = glm::vec3(-2.0f, 1.5f, 3.0f);
  cam.target = glm::vec3(-2.0f, 1.5f, 0.0f);
  cam.yfov = 0.4f;
  s.culling = CullingMode::kNone;
  const Frame all = RenderOk(*l.scene, cam, s);
  for (CullingMode mode : {CullingMode::kCpuFrustum, CullingMode::kGpuFrustum,
                           CullingMode::kGpuOcclusion}) {
    s.culling = mode;
    const Frame culled = RenderOk(*l.scene, cam, s);
    SCOPED_TRACE(std::string(ToString(mode)));
    EXPECT_GE(culled.stats.drawables_drawn, 1u);
    EXPECT_LT(culled.stats.drawables_drawn, all.stats.drawables_drawn) << "the others are culled";
    EXPECT_EQ(culled.image.pixels, all.image.pixels);
  }
  // The cube is in the picture: something other than the clear colour at the centre.
  s.culling = CullingMode::kCpuFrustum;
  const Frame rest = RenderOk(*l.scene, cam, At(s, "move", 0.0f));
  EXPECT_EQ(rest.stats.drawables_drawn, 0u) << "at rest the cube is below the view";
  EXPECT_NE(rest.image.pixels, all.image.pixels);
  ExpectNoValidationMessages(SharedRenderer());
}

// Skinning and morph targets bind the posed vertices as one storage buffer (skin.comp): a
// deformed scene whose vertices exceed the device's storage buffer range is refused at upload,
// naming them. A scene whose animation only moves nodes binds none of its vertices so: it loads
// and renders the same under that range. (The range is taken as 2 KiB here, below both scenes'
// vertex buffers and above their materials', drawables' and culling records'.)
TEST(AnimationRender, StorageBufferRangeRefusesOnlyDeformedScenes) {
  constexpr uint64_t kRange = 2048;
  absl::StatusOr<std::unique_ptr<Renderer>> narrow =
      Renderer::Create({.validation = true, .max_storage_buffer_range = kRange});
  ASSERT_TRUE(narrow.ok()) << narrow.status();
  const Loaded moving = Load("trs_nodes");
  const Loaded deformed = Load("skinned_cylinder");
  ASSERT_TRUE(moving.scene);
  ASSERT_TRUE(deformed.scene);
  ASSERT_GT(moving.cpu.vertices.size() * sizeof(Vertex), kRange);
  ASSERT_GT(deformed.cpu.vertices.size() * sizeof(Vertex), kRange);

  absl::StatusOr<SceneHandle> refused = (*narrow)->LoadScene(deformed.cpu);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument) << refused.status();
  EXPECT_NE(refused.status().message().find("vertices (deformed"), std::string::npos)
      << refused.status();
  EXPECT_NE(refused.status().message().find("maxStorageBufferRange"), std::string::npos)
      << refused.status();

  absl::StatusOr<SceneHandle> loaded = (*narrow)->LoadScene(moving.cpu);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  const Settings s = At(Small(64, 48), "move", 0.5f);
  const Camera cam = Framing((*loaded)->info(), s);
  absl::StatusOr<Frame> got = (*narrow)->Render(**loaded, cam, s);
  ASSERT_TRUE(got.ok()) << got.status();
  const Frame want = RenderOk(*moving.scene, cam, s);
  EXPECT_EQ(got->image.pixels, want.image.pixels);
  EXPECT_EQ(got->stats.animated_drawables, want.stats.animated_drawables);
  EXPECT_GT(got->stats.animated_drawables, 0u);
  ExpectNoValidationMessages(**narrow);
}

TEST(AnimationRender, CachedShadowMapsAreRenderedAgainForANewPose) {
  const Loaded l = Load("skinned_cylinder");
  ASSERT_TRUE(l.scene);
  Settings s = Small();
  s.shadows = true;
  const Camera cam = Framing(l.scene->info(), s);
  RenderOk(*l.scene, cam, At(s, "bend", 0.25f));
  const Frame same = RenderOk(*l.scene, cam, At(s, "bend", 0.25f));
  EXPECT_EQ(same.stats.shadow_faces_rendered, 0u) << "an unchanged pose keeps its maps";
  const Frame moved = RenderOk(*l.scene, cam, At(s, "bend", 0.75f));
  EXPECT_GT(moved.stats.shadow_faces_rendered, 0u) << "a new pose casts a new shadow";
}

TEST(AnimationRender, GoldenImagesAtTwoTimes) {
  struct Case {
    const char* file;
    const char* animation;
    float times[2];
  };
  for (const Case& c : {Case{"skinned_cylinder", "bend", {0.4f, 1.0f}},
                        Case{"morph_cube", "morph", {1.0f, 1.6f}},
                        Case{"trs_nodes", "move", {0.3f, 0.8f}}}) {
    SCOPED_TRACE(c.file);
    const Loaded l = Load(c.file);
    ASSERT_TRUE(l.scene);
    const Settings s = Small();
    const Camera cam = SweptFraming(l, s);
    RgbaImage images[2];
    for (int i = 0; i < 2; ++i) {
      images[i] = RenderOk(*l.scene, cam, At(s, c.animation, c.times[i])).image;
      char name[96];
      std::snprintf(name, sizeof(name), "anim_%s_%03d", c.file, int(std::lround(c.times[i] * 100)));
      CompareWithGolden(name, images[i]);
    }
    absl::StatusOr<double> between = Psnr(images[0], images[1]);
    ASSERT_TRUE(between.ok());
    EXPECT_LT(*between, 30.0) << "the two times show different poses";
  }
}

// Small TAA frames, shaded in `pipeline`, TAA in `stage`.
Settings SmallTaa(Pipeline pipeline, PostStage stage) {
  Settings s = Small();
  s.aa = AaMode::kTaa;
  s.pipeline = pipeline;
  s.post_stage = stage;
  return s;
}

// Each animated drawable's world-space triangles in the pose at (animation, t): deformed ones
// from the CPU reference (skinned vertices are in world space), the others' rest vertices
// through their posed world matrix.
std::vector<std::vector<glm::vec3>> PosedTriangles(const Loaded& l, const SceneAnimator& animator,
                                                   int animation, float t) {
  const ScenePose pose = EvaluatePose(l.cpu.nodes, l.cpu.animations, animation, t, true);
  std::vector<std::vector<glm::vec3>> out;
  for (const AnimatedDrawable& ad : animator.drawables()) {
    const Primitive& p = l.cpu.primitives[ad.primitive];
    std::vector<float> weights = pose.weights[ad.node];
    weights.resize(p.morph_targets, 0.0f);
    std::vector<glm::mat4> joints;
    if (ad.skin >= 0) joints = JointMatrices(l.cpu.skins[size_t(ad.skin)], pose);
    const glm::mat4 world = ad.skin >= 0 ? glm::mat4(1.0f) : pose.world[ad.node];
    std::vector<glm::vec3>& corners = out.emplace_back();
    for (uint32_t k = 0; k < p.index_count; ++k) {
      const uint32_t v = l.cpu.indices[p.first_index + k];
      const glm::vec3 local =
          ad.deformed ? Deform(l.cpu, p, v, weights, ad.skin >= 0 ? &joints : nullptr).position
                      : l.cpu.vertices[p.first_vertex + v].position;
      corners.push_back(glm::vec3(world * glm::vec4(local, 1.0f)));
    }
  }
  return out;
}

// The nearest hit of a ray on a triangle list: the triangle and its barycentrics (b1, b2).
struct Hit {
  int triangle = -1;
  double t = 0.0, b1 = 0.0, b2 = 0.0;
};
Hit Intersect(const glm::dvec3& origin, const glm::dvec3& dir,
              const std::vector<glm::vec3>& corners) {
  Hit best;
  for (size_t i = 0; i + 2 < corners.size(); i += 3) {  // Moller-Trumbore, both sides
    const glm::dvec3 a(corners[i]), e1 = glm::dvec3(corners[i + 1]) - a,
        e2 = glm::dvec3(corners[i + 2]) - a;
    const glm::dvec3 p = glm::cross(dir, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-12) continue;
    const glm::dvec3 s = origin - a;
    const double b1 = glm::dot(s, p) / det;
    const glm::dvec3 q = glm::cross(s, e1);
    const double b2 = glm::dot(dir, q) / det, t = glm::dot(e2, q) / det;
    if (b1 < 0.0 || b2 < 0.0 || b1 + b2 > 1.0 || t <= 0.0) continue;
    if (best.triangle < 0 || t < best.t) best = {int(i / 3), t, b1, b2};
  }
  return best;
}

TEST(AnimationRender, TaaObjectMotionMatchesTheCpuReference) {
  // A still camera, TAA frames at t0 then t1 in one view: at each pixel whose visible drawable
  // is animated, the ray through the pixel centre (the jittered projection the frame rasterized
  // with) hits one of its triangles at t1; the same barycentrics in the t0 pose, through the t0
  // frame's unjittered view-projection, are where that point was on last frame's screen. The
  // motion pass must give its offset from where the camera alone puts the t1 point. Elsewhere
  // nothing moved: 0.
  // The skinned cylinder in the visibility pipeline (its visibility pass draws the depth); the
  // TRS cubes under a camera that moves between the frames; the morph cube's material an
  // alpha-mask one (the motion pass's alpha-test pipeline; its alpha is 1, so nothing is cut).
  struct Case {
    const char* file;
    const char* animation;
    float t0, t1;
    Pipeline pipeline;
    bool camera_moves = false;
    bool mask = false;
  };
  uint64_t view = 9100;
  for (const Case& c :
       {Case{"trs_nodes", "move", 0.30f, 0.45f, Pipeline::kForward, true, false},
        Case{"skinned_cylinder", "bend", 0.6f, 0.8f, Pipeline::kVisibility, false, false},
        Case{"morph_cube", "morph", 0.8f, 1.1f, Pipeline::kForward, false, true}}) {
    SCOPED_TRACE(c.file);
    const Loaded l = !c.mask ? Load(c.file)
                             : LoadEdited(c.file, "mask_motion", [](nlohmann::json& gltf) {
                                 for (auto& m : gltf["materials"]) {
                                   m["alphaMode"] = "MASK";
                                   m["alphaCutoff"] = 0.5;
                                 }
                               });
    ASSERT_TRUE(l.scene);
    const Settings s = SmallTaa(c.pipeline, Settings{}.post_stage);
    const Camera cam0 = SweptFraming(l, s);
    Camera cam = cam0;  // the second frame's
    if (c.camera_moves)
      cam = FrameBounds(l.scene->info().bounds, 0.8f, float(s.width) / float(s.height),
                        {0.45f, 0.3f, 1.0f});
    const std::unique_ptr<SceneAnimator> animator = SceneAnimator::Create(l.cpu);
    ASSERT_NE(animator, nullptr);
    const std::vector<std::vector<glm::vec3>> before = PosedTriangles(l, *animator, 0, c.t0);
    const std::vector<std::vector<glm::vec3>> after = PosedTriangles(l, *animator, 0, c.t1);
    ++view;
    FrameCapture first;
    absl::StatusOr<Frame> f0 =
        SharedRenderer().Render(*l.scene, cam0, At(s, c.animation, c.t0), view, &first);
    ASSERT_TRUE(f0.ok()) << f0.status();
    EXPECT_FALSE(first.motion.empty()) << "the first frame keeps its pose (the target is clear)";
    for (const glm::vec2& m : first.motion) ASSERT_EQ(m, glm::vec2(0.0f));
    // Another view of the scene at another time in between: the scene's pose is then that view's,
    // but this view's motion is from its own last frame.
    ASSERT_TRUE(
        SharedRenderer().Render(*l.scene, cam, At(s, c.animation, c.t0 + 0.5f), view + 50).ok());
    SharedRenderer().ForgetView(*l.scene, view + 50);
    FrameCapture cap;
    cap.want_ids = true;
    absl::StatusOr<Frame> f1 =
        SharedRenderer().Render(*l.scene, cam, At(s, c.animation, c.t1), view, &cap);
    ASSERT_TRUE(f1.ok()) << f1.status();
    ASSERT_EQ(cap.motion.size(), size_t(s.width) * s.height);
    const glm::mat4 prev_view_proj =
        ProjectionMatrix(cam0, float(s.width) / float(s.height)) * ViewMatrix(cam0);
    const glm::dmat4 inv_jittered = glm::inverse(glm::dmat4(cap.proj * cap.view));
    std::vector<int> animated_index(l.cpu.drawables.size(), -1);
    for (size_t i = 0; i < animator->drawables().size(); ++i)
      animated_index[animator->drawables()[i].drawable] = int(i);
    auto screen = [&](const glm::dvec3& p) {  // uv on last frame's screen
      const glm::dvec4 clip = glm::dmat4(prev_view_proj) * glm::dvec4(p, 1.0);
      return glm::dvec2(clip) / clip.w * 0.5 + 0.5;
    };
    uint32_t checked = 0, still = 0;
    double largest = 0.0;
    for (uint32_t y = 0; y < s.height; ++y) {
      for (uint32_t x = 0; x < s.width; ++x) {
        const size_t px = size_t(y) * s.width + x;
        const glm::vec2 got = cap.motion[px];
        const uint32_t id = cap.ids[px];
        const int a = id == 0 ? -1 : animated_index[id - 1];
        if (a < 0) {
          ASSERT_EQ(got, glm::vec2(0.0f)) << "pixel " << x << "," << y << " (id " << id << ")";
          ++still;
          continue;
        }
        const glm::dvec2 ndc((x + 0.5) / s.width * 2.0 - 1.0, (y + 0.5) / s.height * 2.0 - 1.0);
        glm::dvec4 near = inv_jittered * glm::dvec4(ndc, 1.0, 1.0);
        glm::dvec4 mid = inv_jittered * glm::dvec4(ndc, 0.5, 1.0);
        const glm::dvec3 origin = glm::dvec3(near) / near.w;
        const glm::dvec3 dir = glm::normalize(glm::dvec3(mid) / mid.w - origin);
        const Hit hit = Intersect(origin, dir, after[size_t(a)]);
        if (hit.triangle < 0) continue;  // the pixel centre grazes an edge: no reference
        auto point = [&](const std::vector<glm::vec3>& tris) {
          const size_t i = size_t(hit.triangle) * 3;
          return glm::dvec3(tris[i]) * (1.0 - hit.b1 - hit.b2) + glm::dvec3(tris[i + 1]) * hit.b1 +
                 glm::dvec3(tris[i + 2]) * hit.b2;
        };
        const glm::dvec2 want = screen(point(before[size_t(a)])) - screen(point(after[size_t(a)]));
        const double tolerance = 2e-3 + 0.01 * glm::length(want);
        ASSERT_NEAR(got.x, want.x, tolerance) << "pixel " << x << "," << y;
        ASSERT_NEAR(got.y, want.y, tolerance) << "pixel " << x << "," << y;
        largest = std::max(largest, glm::length(want) * s.width);
        ++checked;
      }
    }
    std::printf("%s %.2f -> %.2f s: %u moving pixels checked (largest motion %.1f px), %u still\n",
                c.file, c.t0, c.t1, checked, largest, still);
    EXPECT_GT(checked, 200u);
    EXPECT_GT(still, 200u);
    EXPECT_GT(largest, 2.0) << "the poses moved something on screen";
    // The same pose again: nothing moved, the motion pass does not run; nor when another view's
    // frame re-posed the scene in between (a job accumulating at one time while viewers render):
    // the two views' TAA frames are the same bytes.
    FrameCapture again, after_other;
    absl::StatusOr<Frame> plain =
        SharedRenderer().Render(*l.scene, cam, At(s, c.animation, c.t1), view, &again);
    ASSERT_TRUE(plain.ok());
    EXPECT_TRUE(again.motion.empty());
    const uint64_t twin = view + 60;
    ASSERT_TRUE(SharedRenderer().Render(*l.scene, cam0, At(s, c.animation, c.t0), twin).ok());
    ASSERT_TRUE(SharedRenderer().Render(*l.scene, cam, At(s, c.animation, c.t1), twin).ok());
    ASSERT_TRUE(
        SharedRenderer().Render(*l.scene, cam, At(s, c.animation, c.t0 + 0.5f), view + 50).ok());
    absl::StatusOr<Frame> interleaved =
        SharedRenderer().Render(*l.scene, cam, At(s, c.animation, c.t1), twin, &after_other);
    ASSERT_TRUE(interleaved.ok());
    EXPECT_TRUE(after_other.motion.empty());
    EXPECT_EQ(interleaved->image.pixels, plain->image.pixels);
    for (uint64_t v : {view, twin, view + 50}) SharedRenderer().ForgetView(*l.scene, v);
  }
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(AnimationRender, TaaFollowsAnimatedGeometry) {
  // A playing animation under a still camera, TAA at 30 frames a second: the last frame against
  // the same pose accumulated by TAA without motion (16 frames at that time in a fresh view, the
  // jittered supersample TAA converges on). Reprojecting by the camera alone, the moving
  // geometry's history comes from where it no longer is (clamped to the neighbourhood: smeared
  // edges and shading); with the motion pass it follows the geometry. Measured on lavapipe,
  // with / without the motion pass: the bending cylinder 41.4 / 30.0 dB, the TRS cubes
  // 38.8 / 30.6 dB. The growing morph cube 37.6 / 42.4 dB: its faces are flat colours, which the
  // camera's reprojection gets right anyway, and TAA takes the motion of the nearest surface
  // around a pixel (dilation, which keeps moving silhouettes sharp), so the background row just
  // above its rising top edge takes the cube's motion and a little of its colour. (Reading the
  // motion at the pixel itself instead of the dilated texel gives the cylinder 31.6 dB.)
  // The cases vary the pipeline (the visibility pass's depth) and TAA's stage (compute).
  struct Case {
    const char* file;
    const char* animation;
    float start;
    double min_psnr;
    Pipeline pipeline;
    PostStage stage;
  };
  uint64_t view = 9200;
  for (const Case& c :
       {Case{"skinned_cylinder", "bend", 0.2f, 36.0, Pipeline::kForward, PostStage::kFragment},
        Case{"trs_nodes", "move", 0.1f, 35.0, Pipeline::kVisibility, PostStage::kCompute},
        Case{"morph_cube", "morph", 0.5f, 35.0, Pipeline::kForward, PostStage::kCompute}}) {
    SCOPED_TRACE(c.file);
    const Loaded l = Load(c.file);
    ASSERT_TRUE(l.scene);
    const Settings s = SmallTaa(c.pipeline, c.stage);
    const Camera cam = SweptFraming(l, s);
    constexpr int kFrames = 16;
    const float end = c.start + float(kFrames - 1) / 30.0f;
    const uint64_t playing = ++view, still = ++view;
    FrameCapture moved, settled;
    for (int k = 0; k < kFrames; ++k) {
      const float t = c.start + float(k) / 30.0f;
      ASSERT_TRUE(SharedRenderer()
                      .Render(*l.scene, cam, At(s, c.animation, t), playing,
                              k + 1 == kFrames ? &moved : nullptr)
                      .ok());
    }
    for (int k = 0; k < kFrames; ++k)
      ASSERT_TRUE(SharedRenderer()
                      .Render(*l.scene, cam, At(s, c.animation, end), still,
                              k + 1 == kFrames ? &settled : nullptr)
                      .ok());
    SharedRenderer().ForgetView(*l.scene, playing);
    SharedRenderer().ForgetView(*l.scene, still);
    const double psnr = HdrPsnr(moved.hdr, settled.hdr);
    std::printf("%s playing from %.2f s, TAA's frame at %.2f s against it settled: %.1f dB\n",
                c.file, c.start, end, psnr);
    EXPECT_GE(psnr, c.min_psnr);
  }
  ExpectNoValidationMessages(SharedRenderer());
}

TEST(AnimationRender, AnimationsAreNamedOrIndexedAndOthersRefused) {
  const Loaded l = Load("skinned_cylinder");
  ASSERT_TRUE(l.scene);
  const Settings s = Small(32, 24);
  const Camera cam = Framing(l.scene->info(), s);
  const Frame by_name = RenderOk(*l.scene, cam, At(s, "bend", 1.0f));
  const Frame by_index = RenderOk(*l.scene, cam, At(s, "0", 1.0f));
  EXPECT_EQ(by_name.image.pixels, by_index.image.pixels);
  // Looping: 2 s is one period, so 3 s shows 1 s; without loop 3 s holds the end (= 0 s).
  const Frame looped = RenderOk(*l.scene, cam, At(s, "bend", 3.0f));
  EXPECT_EQ(looped.image.pixels, by_name.image.pixels);
  Settings held = At(s, "bend", 3.0f);
  held.loop = false;
  const Frame end = RenderOk(*l.scene, cam, held);
  const Frame start = RenderOk(*l.scene, cam, At(s, "bend", 0.0f));
  EXPECT_EQ(end.image.pixels, start.image.pixels);

  absl::StatusOr<Frame> unknown = SharedRenderer().Render(*l.scene, cam, At(s, "walk", 0.0f));
  ASSERT_FALSE(unknown.ok());
  EXPECT_EQ(unknown.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(unknown.status().message().find("settings.animation"), std::string::npos);
  EXPECT_NE(unknown.status().message().find("'bend'"), std::string::npos) << unknown.status();
  absl::StatusOr<Frame> index = SharedRenderer().Render(*l.scene, cam, At(s, "1", 0.0f));
  ASSERT_FALSE(index.ok());
  EXPECT_NE(index.status().message().find("out of range"), std::string::npos) << index.status();
  Settings too_long = At(s, std::string(kMaxAnimationNameBytes + 1, 'a'), 0.0f);
  absl::StatusOr<Frame> long_name = SharedRenderer().Render(*l.scene, cam, too_long);
  ASSERT_FALSE(long_name.ok());
  EXPECT_NE(long_name.status().message().find("settings.animation"), std::string::npos);
}

}  // namespace
}  // namespace tessera

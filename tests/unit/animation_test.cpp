// glTF animations on the CPU: sampling (LINEAR, STEP, CUBICSPLINE; slerped rotations; clamping),
// the animation clock (loop, clamp), poses through a hierarchy, and the importer: a generated
// file whose animated nodes are checked against hand-computed values at chosen times, and
// malformed animation data refused naming the field (or the max_animation_keys limit).
#include "renderer/scene/animation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "renderer/scene/cpu_scene.h"
#include "renderer/scene/gltf_import.h"
#include "renderer/scene/scene_animator.h"

namespace tessera {
namespace {

using json = nlohmann::json;

constexpr float kPi = 3.14159265358979f;

AnimationSampler Sampler(Interpolation i, std::vector<float> times, std::vector<float> values,
                         uint32_t width) {
  AnimationSampler s;
  s.interpolation = i;
  s.times = std::move(times);
  s.values = std::move(values);
  s.width = width;
  return s;
}

glm::vec3 Sample3(const AnimationSampler& s, float t) {
  float v[3];
  SampleAnimation(s, t, false, v);
  return {v[0], v[1], v[2]};
}

void ExpectNear(const glm::vec3& a, const glm::vec3& b, float eps = 1e-5f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

TEST(AnimationSample, LinearStepAndClamping) {
  const AnimationSampler lin =
      Sampler(Interpolation::kLinear, {1, 3}, {0, 0, 0, 4, -2, 10}, 3);
  ExpectNear(Sample3(lin, 2.0f), {2, -1, 5});
  ExpectNear(Sample3(lin, 2.5f), {3, -1.5f, 7.5f});
  ExpectNear(Sample3(lin, 0.0f), {0, 0, 0});   // before the first key: the first value
  ExpectNear(Sample3(lin, 9.0f), {4, -2, 10});  // after the last: the last
  const AnimationSampler step =
      Sampler(Interpolation::kStep, {0, 1, 2}, {0, 0, 0, 1, 1, 1, 5, 5, 5}, 3);
  ExpectNear(Sample3(step, 0.999f), {0, 0, 0});
  ExpectNear(Sample3(step, 1.0f), {1, 1, 1});
  ExpectNear(Sample3(step, 1.5f), {1, 1, 1});
  ExpectNear(Sample3(step, 2.0f), {5, 5, 5});
  const AnimationSampler one = Sampler(Interpolation::kLinear, {0.5f}, {7, 8, 9}, 3);
  ExpectNear(Sample3(one, 0.0f), {7, 8, 9});
  ExpectNear(Sample3(one, 3.0f), {7, 8, 9});
}

TEST(AnimationSample, CubicSplineIsTheHermiteCurveWithScaledTangents) {
  // One component, keys at t = 0 (value 0, out-tangent 2) and t = 2 (value 1, in-tangent -1):
  // p(u) = h00*0 + h10*dt*2 + h01*1 + h11*dt*(-1), dt = 2. At u = 0.5 (t = 1):
  // h10 = 0.125, h01 = 0.5, h11 = -0.125 -> 0.125*4 + 0.5 + 0.25 = 1.25.
  const AnimationSampler s = Sampler(Interpolation::kCubicSpline, {0, 2},
                                     {/*in*/ 9, /*v*/ 0, /*out*/ 2, /*in*/ -1, /*v*/ 1, /*out*/ 9},
                                     1);
  float v;
  SampleAnimation(s, 1.0f, false, &v);
  EXPECT_NEAR(v, 1.25f, 1e-6f);
  SampleAnimation(s, 0.0f, false, &v);
  EXPECT_NEAR(v, 0.0f, 1e-6f);  // the key value, not a tangent
  SampleAnimation(s, 2.0f, false, &v);
  EXPECT_NEAR(v, 1.0f, 1e-6f);
  // u = 0.25 (t = 0.5): h10 = 0.140625, h01 = 0.15625, h11 = -0.046875
  // -> 0.140625*4 + 0.15625 + 0.09375 = 0.8125.
  SampleAnimation(s, 0.5f, false, &v);
  EXPECT_NEAR(v, 0.8125f, 1e-6f);
}

TEST(AnimationSample, RotationsSlerpTheShorterArcAndStayUnit) {
  // 0 and 90 degrees about +Y (x, y, z, w); halfway is 45 degrees.
  const float h = std::sin(kPi / 4), c = std::cos(kPi / 4);
  const AnimationSampler s = Sampler(Interpolation::kLinear, {0, 1}, {0, 0, 0, 1, 0, h, 0, c}, 4);
  float q[4];
  SampleAnimation(s, 0.5f, true, q);
  EXPECT_NEAR(q[1], std::sin(kPi / 8), 1e-5f);
  EXPECT_NEAR(q[3], std::cos(kPi / 8), 1e-5f);
  // The same end given as -q (the same rotation): still the 45-degree one, not the long way.
  const AnimationSampler neg =
      Sampler(Interpolation::kLinear, {0, 1}, {0, 0, 0, 1, 0, -h, 0, -c}, 4);
  SampleAnimation(neg, 0.5f, true, q);
  EXPECT_NEAR(std::abs(q[1]), std::sin(kPi / 8), 1e-5f);
  EXPECT_NEAR(std::abs(q[3]), std::cos(kPi / 8), 1e-5f);
  // A cubic rotation comes back normalized.
  const AnimationSampler cubic = Sampler(
      Interpolation::kCubicSpline, {0, 1},
      {0, 0, 0, 0, /*v*/ 0, 0, 0, 1, /*out*/ 0, 1, 0, 0, /*in*/ 0, 1, 0, 0, /*v*/ 0, h, 0, c,
       0, 0, 0, 0},
      4);
  SampleAnimation(cubic, 0.3f, true, q);
  EXPECT_NEAR(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3], 1.0f, 1e-5f);
}

TEST(AnimationClock, LoopsOrClamps) {
  Animation a;
  a.duration = 2.0f;
  EXPECT_FLOAT_EQ(AnimationTime(a, 0.5, true), 0.5f);
  EXPECT_FLOAT_EQ(AnimationTime(a, 4.5, true), 0.5f);
  EXPECT_FLOAT_EQ(AnimationTime(a, -0.5, true), 1.5f);
  EXPECT_FLOAT_EQ(AnimationTime(a, 4.5, false), 2.0f);
  EXPECT_FLOAT_EQ(AnimationTime(a, -1.0, false), 0.0f);
  Animation still;  // a single key: duration 0
  EXPECT_FLOAT_EQ(AnimationTime(still, 3.0, true), 0.0f);
}

TEST(AnimationPose, ChildrenFollowTheirAnimatedParentWhateverTheFileOrder) {
  // nodes[0] is the child of nodes[1] (listed after it), offset 2 along +X.
  std::vector<SceneNode> nodes(2);
  nodes[0].parent = 1;
  nodes[0].rest.translation = {2, 0, 0};
  Animation a;
  a.samplers.push_back(Sampler(Interpolation::kLinear, {0, 1},
                               {0, 0, 0, 1, 0, std::sin(kPi / 4), 0, std::cos(kPi / 4)}, 4));
  a.channels.push_back({0, 1, AnimationPath::kRotation});
  a.duration = 1.0f;
  const std::vector<Animation> anims = {a};
  // At rest: the child at (2, 0, 0). At t = 1 the parent has turned 90 degrees about +Y:
  // +X goes to -Z, so the child is at (0, 0, -2).
  ScenePose rest = EvaluatePose(nodes, anims, -1, 0.0, false);
  ExpectNear(glm::vec3(rest.world[0][3]), {2, 0, 0});
  ScenePose end = EvaluatePose(nodes, anims, 0, 1.0, false);
  ExpectNear(glm::vec3(end.world[0][3]), {0, 0, -2}, 1e-5f);
  ExpectNear(glm::vec3(end.local[0][3]), {2, 0, 0});
}

// --- the importer ----------------------------------------------------------------------------

// A glTF file with three animated nodes (no meshes needed) and one buffer of floats.
struct Builder {
  json gltf = {{"asset", {{"version", "2.0"}}}, {"nodes", json::array()},
               {"accessors", json::array()}, {"bufferViews", json::array()}};
  std::vector<float> data;

  int Floats(const std::vector<float>& v, const char* type) {
    const size_t offset = data.size() * 4;
    data.insert(data.end(), v.begin(), v.end());
    const int comps = std::string(type) == "SCALAR" ? 1 : std::string(type) == "VEC3" ? 3 : 4;
    gltf["bufferViews"].push_back(
        {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", v.size() * 4}});
    gltf["accessors"].push_back({{"bufferView", gltf["bufferViews"].size() - 1},
                                 {"componentType", 5126},
                                 {"count", v.size() / comps},
                                 {"type", type}});
    if (comps == 1) {  // key times need their bounds (glTF 2.0 3.11)
      gltf["accessors"].back()["min"] = {*std::min_element(v.begin(), v.end())};
      gltf["accessors"].back()["max"] = {*std::max_element(v.begin(), v.end())};
    }
    return int(gltf["accessors"].size() - 1);
  }

  // The file's one animation: one LINEAR channel moving `path` of `node` by accessors `input`
  // (key times) and `output`.
  void OneChannelAnimation(int input, int output, int node, const char* path) {
    gltf["animations"] = json::array(
        {{{"samplers", {{{"input", input}, {"output", output}}}},
          {"channels", {{{"sampler", 0}, {"target", {{"node", node}, {"path", path}}}}}}}});
  }

  // VEC4 UNSIGNED_BYTE joint indices, 4 bytes per element: one float slot each.
  int Joints(const std::vector<std::array<uint8_t, 4>>& v) {
    const size_t offset = data.size() * 4;
    for (const auto& j : v) {
      float slot;
      std::memcpy(&slot, j.data(), 4);
      data.push_back(slot);
    }
    gltf["bufferViews"].push_back(
        {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", v.size() * 4}});
    gltf["accessors"].push_back({{"bufferView", gltf["bufferViews"].size() - 1},
                                 {"componentType", 5121},
                                 {"count", v.size()},
                                 {"type", "VEC4"}});
    return int(gltf["accessors"].size() - 1);
  }

  int Mat4s(const std::vector<glm::mat4>& m) {
    std::vector<float> v;
    for (const glm::mat4& x : m)
      for (int i = 0; i < 16; ++i) v.push_back(x[i / 4][i % 4]);
    const size_t offset = data.size() * 4;
    data.insert(data.end(), v.begin(), v.end());
    gltf["bufferViews"].push_back(
        {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", v.size() * 4}});
    gltf["accessors"].push_back({{"bufferView", gltf["bufferViews"].size() - 1},
                                 {"componentType", 5126},
                                 {"count", m.size()},
                                 {"type", "MAT4"}});
    return int(gltf["accessors"].size() - 1);
  }

  GltfSource Source() {
    json j = gltf;
    j["buffers"] = json::array({{{"uri", "anim.bin"}, {"byteLength", data.size() * 4}}});
    GltfSource s;
    s.main_file = "anim.gltf";
    const std::string text = j.dump();
    s.files["anim.gltf"].assign(text.begin(), text.end());
    std::vector<uint8_t> bin(data.size() * 4);
    std::memcpy(bin.data(), data.data(), bin.size());
    s.files["anim.bin"] = std::move(bin);
    return s;
  }
};

// nodes[0] translated LINEAR, nodes[1] STEP, nodes[2] CUBICSPLINE along +X over keys 0, 1, 2 s;
// nodes[3], a child of nodes[0] at +Y 1, follows it.
Builder TrsFile() {
  Builder b;
  for (int i = 0; i < 3; ++i) b.gltf["nodes"].push_back({{"name", "n" + std::to_string(i)}});
  b.gltf["nodes"][0]["children"] = {3};
  b.gltf["nodes"].push_back({{"name", "child"}, {"translation", {0, 1, 0}}});
  const int times = b.Floats({0, 1, 2}, "SCALAR");
  const int lin = b.Floats({0, 0, 0, 2, 0, 0, 2, 0, 4}, "VEC3");
  const int step = b.Floats({0, 0, 0, 3, 0, 0, 6, 0, 0}, "VEC3");
  // Cubic: values 0, 1, 0 along X with zero tangents except key 0's out-tangent 1.
  const int cubic = b.Floats({0, 0, 0, 0, 0, 0, 1, 0, 0,   // key 0: in, value, out
                              0, 0, 0, 1, 0, 0, 0, 0, 0,   // key 1
                              0, 0, 0, 0, 0, 0, 0, 0, 0},  // key 2
                             "VEC3");
  b.gltf["animations"] = json::array(
      {{{"name", "move"},
        {"samplers",
         {{{"input", times}, {"output", lin}},
          {{"input", times}, {"output", step}, {"interpolation", "STEP"}},
          {{"input", times}, {"output", cubic}, {"interpolation", "CUBICSPLINE"}}}},
        {"channels",
         {{{"sampler", 0}, {"target", {{"node", 0}, {"path", "translation"}}}},
          {{"sampler", 1}, {"target", {{"node", 1}, {"path", "translation"}}}},
          {{"sampler", 2}, {"target", {{"node", 2}, {"path", "translation"}}}}}}}});
  return b;
}

TEST(AnimationImport, TrsAnimationsEvaluateToHandComputedPositions) {
  absl::StatusOr<CpuScene> scene = ImportGltf(TrsFile().Source());
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->animations.size(), 1u);
  const Animation& a = scene->animations[0];
  EXPECT_EQ(a.name, "move");
  EXPECT_FLOAT_EQ(a.duration, 2.0f);
  EXPECT_EQ(a.channels.size(), 3u);
  ASSERT_EQ(scene->nodes.size(), 4u);
  EXPECT_EQ(scene->nodes[3].parent, 0);
  const auto at = [&](double t, int node) {
    return glm::vec3(EvaluatePose(scene->nodes, scene->animations, 0, t, false).world[node][3]);
  };
  // LINEAR: t = 0.5 -> (1, 0, 0); t = 1.5 -> (2, 0, 2).
  ExpectNear(at(0.5, 0), {1, 0, 0});
  ExpectNear(at(1.5, 0), {2, 0, 2});
  ExpectNear(at(1.5, 3), {2, 1, 2});  // the child, 1 above it
  // STEP: t = 0.99 -> key 0; t = 1.0 and 1.5 -> key 1; past the end -> the last key.
  ExpectNear(at(0.99, 1), {0, 0, 0});
  ExpectNear(at(1.5, 1), {3, 0, 0});
  ExpectNear(at(7.0, 1), {6, 0, 0});
  // CUBICSPLINE, interval 0..1 (dt 1): p = h10*1*1 + h01*1; at u = 0.5: 0.125 + 0.5 = 0.625.
  ExpectNear(at(0.5, 2), {0.625f, 0, 0});
  // Interval 1..2, value 1 -> 0, zero tangents: h00 at u = 0.5 is 0.5.
  ExpectNear(at(1.5, 2), {0.5f, 0, 0});
}

// `b`'s file is refused with `code`, the message naming each of `needles`.
void ExpectRefused(Builder b, absl::StatusCode code, const std::vector<std::string>& needles,
                   ImportLimits limits = {}) {
  absl::StatusOr<CpuScene> r = ImportGltf(b.Source(), limits);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), code) << r.status();
  for (const std::string& n : needles)
    EXPECT_NE(r.status().message().find(n), absl::string_view::npos)
        << "'" << n << "' not in: " << r.status().message();
}

// TrsFile() after `edit`, refused so.
void ExpectRefused(const std::function<void(Builder&)>& edit, absl::StatusCode code,
                   const std::vector<std::string>& needles, ImportLimits limits = {}) {
  Builder b = TrsFile();
  edit(b);
  ExpectRefused(std::move(b), code, needles, limits);
}

TEST(AnimationImport, MalformedAnimationsAreRefusedNamingTheField) {
  const auto invalid = absl::StatusCode::kInvalidArgument;
  // Key times that do not strictly increase (their declared bounds still right).
  ExpectRefused([](Builder& b) { b.data[1] = 0.0f; }, invalid,
                {"animations[0].samplers[0].input", "key 1", "strictly increase"});
  // Negative and non-finite times, and times without their bounds.
  ExpectRefused(
      [](Builder& b) {
        b.data[0] = -1.0f;
        b.gltf["accessors"][0]["min"] = {-1.0f};
      },
      invalid, {"animations[0].samplers[0].input", "key 0"});
  ExpectRefused(
      [](Builder& b) {
        b.data[1] = NAN;
        b.gltf["accessors"][0].erase("min");
        b.gltf["accessors"][0].erase("max");
      },
      invalid, {"samplers[0].input", "min and max"});
  // A non-finite value.
  ExpectRefused([](Builder& b) { b.data[3 + 4] = INFINITY; }, invalid,
                {"animations[0].samplers[0].output", "element 1", "not finite"});
  // Too few values for the keys, and a cubic sampler without its tangents.
  ExpectRefused([](Builder& b) { b.gltf["accessors"][1]["count"] = 2; }, invalid,
                {"samplers[0].output", "2 elements for 3 keys"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["samplers"][2]["output"] = 1; },
                invalid, {"samplers[2].output", "3 elements for 3 keys (expected 9)"});
  // Wrong types.
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["channels"][0]["target"]["path"] = "rotation"; },
                invalid, {"samplers[0].output", "VEC4"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["samplers"][0]["input"] = 1; }, invalid,
                {"samplers[0].input", "SCALAR FLOAT"});
  // Channels: an unknown path, a missing sampler or node, a node given as a matrix, the same
  // property twice, weights of a node without a mesh.
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["channels"][0]["target"]["path"] = "color"; },
                invalid, {"channels[0].target.path", "color"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["channels"][1]["sampler"] = 7; }, invalid,
                {"channels[1].sampler", "sampler index 7 out of range"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["channels"][1]["target"]["node"] = 9; },
                invalid, {"channels[1].target.node", "node index 9"});
  ExpectRefused(
      [](Builder& b) {
        b.gltf["nodes"][1]["matrix"] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
      },
      invalid, {"channels[1].target", "has a matrix"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["channels"][1]["target"]["node"] = 0; },
                invalid, {"channels[1].target", "earlier channel"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["channels"][1]["target"]["path"] = "weights"; },
                invalid, {"channels[1].target", "no mesh"});
  ExpectRefused([](Builder& b) { b.gltf["animations"][0]["samplers"][1]["interpolation"] = "SMOOTH"; },
                invalid, {"samplers[1].interpolation", "SMOOTH"});
  // A cubic sampler needs two keys.
  ExpectRefused(
      [](Builder& b) {
        const int t = b.Floats({0}, "SCALAR");
        const int v = b.Floats({0, 0, 0, 1, 1, 1, 0, 0, 0}, "VEC3");
        b.gltf["animations"][0]["samplers"][2]["input"] = t;
        b.gltf["animations"][0]["samplers"][2]["output"] = v;
      },
      invalid, {"samplers[2].input", "at least 2 keys"});
  // The key budget: 3 samplers of 3 keys are 9.
  ImportLimits tight;
  tight.max_animation_keys = 8;
  ExpectRefused([](Builder&) {}, absl::StatusCode::kResourceExhausted,
                {"samplers[2].input", "max_animation_keys limit (8)"}, tight);
  tight.max_animation_keys = 9;
  EXPECT_TRUE(ImportGltf(TrsFile().Source(), tight).ok());
}


// A skinned two-bone strip: 6 vertices at y = 0, 1, 2 (x = -0.5, 0.5), bone 0 at the origin,
// bone 1 at y = 1 (its child); the bottom row follows bone 0, the middle row both equally, the
// top row bone 1; the animation turns bone 1 by 90 degrees about +Z over 1 s.
Builder SkinnedFile() {
  Builder b;
  b.gltf["nodes"] = json::array({{{"name", "bone0"}, {"children", {1}}},
                                 {{"name", "bone1"}, {"translation", {0, 1, 0}}},
                                 {{"name", "strip"}, {"mesh", 0}, {"skin", 0}}});
  b.gltf["scenes"] = json::array({{{"nodes", {0, 2}}}});
  const int pos = b.Floats({-0.5f, 0, 0, 0.5f, 0, 0, -0.5f, 1, 0, 0.5f, 1, 0, -0.5f, 2, 0, 0.5f, 2, 0},
                           "VEC3");
  const int joints = b.Joints({{0, 1, 0, 0}, {0, 1, 0, 0}, {0, 1, 0, 0}, {0, 1, 0, 0},
                               {0, 1, 0, 0}, {0, 1, 0, 0}});
  const int weights = b.Floats({1, 0, 0, 0, 1, 0, 0, 0, 0.5f, 0.5f, 0, 0, 0.5f, 0.5f, 0, 0,
                                0, 1, 0, 0, 0, 1, 0, 0},
                               "VEC4");
  const int ibm = b.Mat4s({glm::mat4(1.0f), glm::translate(glm::mat4(1.0f), {0, -1, 0})});
  b.gltf["meshes"] = json::array(
      {{{"primitives",
         {{{"attributes", {{"POSITION", pos}, {"JOINTS_0", joints}, {"WEIGHTS_0", weights}}},
           {"mode", 4}}}}}});
  // No indices: the 6 vertices are two triangles.
  b.gltf["skins"] = json::array({{{"joints", {0, 1}}, {"inverseBindMatrices", ibm}}});
  const int times = b.Floats({0, 1}, "SCALAR");
  const float h = std::sin(kPi / 4), c = std::cos(kPi / 4);
  const int turn = b.Floats({0, 0, 0, 1, 0, 0, h, c}, "VEC4");
  b.OneChannelAnimation(times, turn, 1, "rotation");
  return b;
}

TEST(AnimationImport, SkinnedVerticesFollowTheirBonesAsComputedByHand) {
  absl::StatusOr<CpuScene> scene = ImportGltf(SkinnedFile().Source());
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->skins.size(), 1u);
  EXPECT_EQ(scene->skins[0].joints, (std::vector<uint32_t>{0, 1}));
  EXPECT_EQ(scene->nodes[2].skin, 0);
  ASSERT_EQ(scene->skin_joints.size(), scene->vertices.size());
  ASSERT_EQ(scene->primitives.size(), 1u);
  EXPECT_TRUE(scene->primitives[0].skinned);
  // Flat-shaded (no normals): each triangle corner is its own vertex; find the corners by
  // their rest position.
  const auto skinned_at = [&](double t, glm::vec3 rest) {
    const ScenePose pose = EvaluatePose(scene->nodes, scene->animations, 0, t, false);
    const std::vector<glm::mat4> jm = JointMatrices(scene->skins[0], pose);
    for (size_t v = 0; v < scene->vertices.size(); ++v)
      if (glm::length(scene->vertices[v].position - rest) < 1e-6f)
        return SkinPoint(rest, scene->skin_joints[v], scene->skin_weights[v], jm);
    ADD_FAILURE() << "no vertex at rest position";
    return glm::vec3(NAN);
  };
  // At rest (t = 0) every vertex stays.
  ExpectNear(skinned_at(0.0, {0.5f, 2, 0}), {0.5f, 2, 0});
  // t = 1: bone 1 turned 90 degrees about +Z at y = 1. Top vertex (0.5, 2): relative to the
  // bone (0.5, 1) -> turned (-1, 0.5) -> world (-1, 1.5). Middle (0.5, 1), half each: bone 0
  // keeps it, bone 1 turns (0.5, 0) to (0, 0.5) -> (0, 1.5); the blend is (0.25, 1.25).
  // Bottom vertices follow bone 0 alone: unmoved.
  ExpectNear(skinned_at(1.0, {0.5f, 2, 0}), {-1, 1.5f, 0});
  ExpectNear(skinned_at(1.0, {0.5f, 1, 0}), {0.25f, 1.25f, 0});
  ExpectNear(skinned_at(1.0, {0.5f, 0, 0}), {0.5f, 0, 0});
}

// A triangle with one morph target moving it +1 along X; its weight goes 0 -> 1 over 1 s.
Builder MorphFile() {
  Builder b;
  b.gltf["nodes"] = json::array({{{"name", "tri"}, {"mesh", 0}}});
  const int pos = b.Floats({0, 0, 0, 1, 0, 0, 0, 1, 0}, "VEC3");
  const int delta = b.Floats({1, 0, 0, 1, 0, 0, 1, 0, 0}, "VEC3");
  b.gltf["meshes"] = json::array({{{"primitives", {{{"attributes", {{"POSITION", pos}}},
                                                    {"targets", {{{"POSITION", delta}}}}}}},
                                   {"weights", {0.0}}}});
  const int times = b.Floats({0, 1}, "SCALAR");
  const int w = b.Floats({0, 1}, "SCALAR");
  b.OneChannelAnimation(times, w, 0, "weights");
  return b;
}

TEST(AnimationImport, MorphTargetsMoveByTheirAnimatedWeights) {
  absl::StatusOr<CpuScene> scene = ImportGltf(MorphFile().Source());
  ASSERT_TRUE(scene.ok()) << scene.status();
  const Primitive& p = scene->primitives[0];
  ASSERT_EQ(p.morph_targets, 1u);
  ASSERT_EQ(scene->morph_deltas.size(), p.first_morph_delta + p.vertex_count);
  EXPECT_EQ(scene->nodes[0].weights, std::vector<float>{0.0f});
  const ScenePose pose = EvaluatePose(scene->nodes, scene->animations, 0, 0.25, false);
  ASSERT_EQ(pose.weights[0].size(), 1u);
  EXPECT_FLOAT_EQ(pose.weights[0][0], 0.25f);
  for (uint32_t v = 0; v < p.vertex_count; ++v) {
    const glm::vec3 base = scene->vertices[p.first_vertex + v].position;
    ExpectNear(MorphPosition(base, &scene->morph_deltas[p.first_morph_delta + v], p.vertex_count,
                             pose.weights[0]),
               base + glm::vec3(0.25f, 0, 0));
  }
}

TEST(AnimationImport, MalformedSkinsAndMorphTargetsAreRefusedNamingTheField) {
  const auto invalid = absl::StatusCode::kInvalidArgument;
  Builder b = SkinnedFile();
  b.gltf["skins"][0]["joints"] = json::array();
  ExpectRefused(b, invalid, {"skins[0].joints", "is empty"});
  b = SkinnedFile();
  b.gltf["skins"][0]["joints"] = {0, 0};
  ExpectRefused(b, invalid, {"skins[0].joints[1]", "listed twice"});
  b = SkinnedFile();
  b.gltf["skins"][0]["joints"] = {0};  // the mesh uses joint 1
  b.gltf["skins"][0].erase("inverseBindMatrices");
  ExpectRefused(b, invalid, {"nodes[2].skin", "uses joint 1", "1 joints"});
  b = SkinnedFile();
  b.gltf["meshes"][0]["primitives"][0]["attributes"].erase("WEIGHTS_0");
  ExpectRefused(b, invalid, {"primitives[0].attributes", "JOINTS_0 and WEIGHTS_0"});
  b = SkinnedFile();
  b.data[18 + 6 + 0] = 0.5f;  // first vertex's weights sum to 0.5
  ExpectRefused(b, invalid, {"WEIGHTS_0", "element 0", "sum to 0.5"});
  b = SkinnedFile();
  b.gltf["nodes"][2].erase("skin");
  b.gltf["nodes"][0]["skin"] = 0;
  ExpectRefused(b, invalid, {"nodes[0].skin", "without a mesh"});
  b = SkinnedFile();
  b.gltf["accessors"][3]["count"] = 1;  // one inverse bind matrix for two joints
  ExpectRefused(b, invalid, {"skins[0].inverseBindMatrices", "1 matrices for 2 joints"});
  ImportLimits one_joint;
  one_joint.max_skin_joints = 1;
  ExpectRefused(SkinnedFile(), absl::StatusCode::kResourceExhausted,
          {"skins[0].joints", "max_skin_joints limit (1)"}, one_joint);

  Builder m = MorphFile();
  m.gltf["meshes"][0]["weights"] = {0.0, 1.0};
  ExpectRefused(m, invalid, {"meshes[0].weights", "2 weights for 1 morph targets"});
  m = MorphFile();
  m.gltf["accessors"][1]["count"] = 2;
  ExpectRefused(m, invalid, {"targets[0].POSITION", "2 deltas for 3 vertices"});
  ImportLimits no_targets;
  no_targets.max_morph_targets = 0;
  ExpectRefused(MorphFile(), absl::StatusCode::kResourceExhausted, {"max_morph_targets limit (0)"},
          no_targets);
}

}  // namespace
}  // namespace tessera

// --- SceneAnimator: what moves, where the copies go, and bounds that hold every pose ----------

namespace tessera {
namespace {

CpuScene ImportGenerated(const std::string& name) {
  absl::StatusOr<GltfSource> source =
      LoadGltfSourceFromDisk(std::string(TESSERA_ANIMATED_DIR) + "/" + name + ".gltf");
  EXPECT_TRUE(source.ok()) << source.status();
  if (!source.ok()) return {};
  absl::StatusOr<CpuScene> scene = ImportGltf(*source);
  EXPECT_TRUE(scene.ok()) << scene.status();
  return scene.ok() ? std::move(*scene) : CpuScene{};
}

TEST(SceneAnimator, StaticScenesHaveNoAnimator) {
  CpuScene scene = ImportGenerated("trs_nodes");
  ASSERT_FALSE(scene.nodes.empty());
  scene.animations.clear();  // nothing moves, nothing deforms
  EXPECT_EQ(SceneAnimator::Create(scene), nullptr);
  EXPECT_EQ(SceneAnimator::Create(CpuScene{}), nullptr);
}

TEST(SceneAnimator, DeformedDrawablesGetTheirOwnCopiesAfterTheSceneVertices) {
  const CpuScene crowd = ImportGenerated("crowd");
  const std::unique_ptr<SceneAnimator> a = SceneAnimator::Create(crowd);
  ASSERT_NE(a, nullptr);
  ASSERT_EQ(a->drawables().size(), 100u);  // 100 bodies share one mesh
  uint64_t next = crowd.vertices.size();
  for (const AnimatedDrawable& d : a->drawables()) {
    EXPECT_TRUE(d.deformed);
    EXPECT_GE(d.skin, 0);
    EXPECT_EQ(d.first_vertex, next);
    next += crowd.primitives[d.primitive].vertex_count;
  }
  EXPECT_EQ(a->copy_vertices(), next - crowd.vertices.size());
  EXPECT_EQ(a->VertexData(crowd).size(), next);
  EXPECT_EQ(a->joint_count(), 200u);
  // The TRS file's cubes move but do not deform: no copies, their own vertices.
  const CpuScene trs = ImportGenerated("trs_nodes");
  const std::unique_ptr<SceneAnimator> b = SceneAnimator::Create(trs);
  ASSERT_NE(b, nullptr);
  EXPECT_EQ(b->drawables().size(), 3u);
  EXPECT_EQ(b->copy_vertices(), 0u);
  for (const AnimatedDrawable& d : b->drawables()) {
    EXPECT_FALSE(d.deformed);
    EXPECT_EQ(d.first_vertex, trs.primitives[d.primitive].first_vertex);
  }
}

TEST(SceneAnimator, PosedBoundsHoldEveryDeformedVertexAndChangeOnlyWithThePose) {
  for (const char* name : {"skinned_cylinder", "morph_cube", "trs_nodes", "crowd"}) {
    SCOPED_TRACE(name);
    const CpuScene scene = ImportGenerated(name);
    const std::unique_ptr<SceneAnimator> a = SceneAnimator::Create(scene);
    ASSERT_NE(a, nullptr);
    EXPECT_TRUE(a->Pose(0, 0.0, true));
    EXPECT_FALSE(a->Pose(0, 0.0, true)) << "the same pose again";
    EXPECT_FALSE(a->Pose(0, scene.animations[0].duration, true)) << "looped to 0 s";
    for (int step = 0; step <= 24; ++step) {
      const double t = step * 0.1;
      a->Pose(0, t, true);
      const ScenePose pose = EvaluatePose(scene.nodes, scene.animations, 0, t, true);
      for (size_t i = 0; i < a->drawables().size(); ++i) {
        const AnimatedDrawable& d = a->drawables()[i];
        const Primitive& p = scene.primitives[d.primitive];
        std::vector<float> weights = pose.weights[d.node];
        weights.resize(p.morph_targets, 0.0f);
        std::vector<glm::mat4> joints;
        if (d.skin >= 0) joints = JointMatrices(scene.skins[size_t(d.skin)], pose);
        const Aabb& b = a->bounds()[i];
        for (uint32_t v = 0; v < p.vertex_count; ++v) {
          const uint32_t sv = p.first_vertex + v;
          glm::vec3 q = p.morph_targets
                            ? MorphPosition(scene.vertices[sv].position,
                                            &scene.morph_deltas[p.first_morph_delta + v],
                                            p.vertex_count, weights)
                            : scene.vertices[sv].position;
          q = d.skin >= 0 ? SkinPoint(q, scene.skin_joints[sv], scene.skin_weights[sv], joints)
                          : glm::vec3(a->world()[i] * glm::vec4(q, 1.0f));
          for (int k = 0; k < 3; ++k) {
            ASSERT_GE(q[k], b.min[k] - 1e-4f) << "t=" << t << " drawable " << d.drawable;
            ASSERT_LE(q[k], b.max[k] + 1e-4f) << "t=" << t << " drawable " << d.drawable;
          }
        }
      }
    }
  }
}

}  // namespace
}  // namespace tessera

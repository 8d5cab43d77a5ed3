#pragma once
// glTF animations on the CPU: the node hierarchy with its rest transforms, the animations the
// importer validated, and their evaluation at a scene time (every node's local and world
// matrix and morph weights). Plain data; no Vulkan, no tinygltf.
//
// Sampling follows glTF 2.0 (3.11 and Appendix C): times before the first key give the first
// value and after the last the last; STEP holds a key's value until the next key; LINEAR lerps
// translations, scales and weights and slerps rotations (the shorter arc); CUBICSPLINE is the
// Hermite spline through the key values with the in- and out-tangents scaled by the key
// interval, rotations normalized after.
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/quaternion.hpp>
#include <optional>
#include <string>
#include <vector>

namespace tessera {

// A node's local transform as translation, rotation and scale (glTF's TRS properties).
struct NodeTransform {
  glm::vec3 translation{0.0f};
  glm::quat rotation{1.0f, 0.0f, 0.0f, 0.0f};  // glm order: w, x, y, z
  glm::vec3 scale{1.0f};
  glm::mat4 Matrix() const;  // T * R * S
};

// One glTF node of the file, whether or not the default scene places it.
struct SceneNode {
  std::string name;
  int32_t parent = -1;
  NodeTransform rest;               // its TRS properties (identity when it has a matrix)
  std::optional<glm::mat4> matrix;  // its `matrix` property: such a node is never animated
  int32_t mesh = -1;
  int32_t skin = -1;           // into CpuScene::skins
  std::vector<float> weights;  // its morph weights at rest (the node's, else its mesh's)
};

enum class AnimationPath : uint8_t { kTranslation, kRotation, kScale, kWeights };
enum class Interpolation : uint8_t { kLinear, kStep, kCubicSpline };

struct AnimationSampler {
  Interpolation interpolation = Interpolation::kLinear;
  std::vector<float> times;  // finite, >= 0, strictly increasing, at least one
  // Per key `width` floats (3 for translation and scale, 4 for a rotation as x, y, z, w, the
  // morph target count for weights); CUBICSPLINE keys hold three such groups: in-tangent,
  // value, out-tangent.
  std::vector<float> values;
  uint32_t width = 0;
};

struct AnimationChannel {
  uint32_t sampler = 0;  // into Animation::samplers
  uint32_t node = 0;     // into the scene's nodes
  AnimationPath path = AnimationPath::kTranslation;
};

struct Animation {
  std::string name;
  std::vector<AnimationSampler> samplers;
  std::vector<AnimationChannel> channels;
  float duration = 0.0f;  // the last key time over its samplers (0 for a single key)
};

// Samples `s` at time `t` into out[0..width). Rotations (`rotation`: x, y, z, w) are slerped
// (LINEAR) or normalized (CUBICSPLINE).
void SampleAnimation(const AnimationSampler& s, float t, bool rotation, float* out);

// The animation's own time at scene time `scene_time` (seconds): with `loop` it wraps at the
// duration (negative times wrap too); without, it is clamped to [0, duration].
float AnimationTime(const Animation& a, double scene_time, bool loop);
// The same for a time `t` (finite) and a duration > 0, in double.
double WrapAnimationTime(double t, double duration, bool loop);

// Every node at one time.
struct ScenePose {
  std::vector<glm::mat4> local;
  std::vector<glm::mat4> world;
  std::vector<std::vector<float>> weights;  // per node, as SceneNode::weights sized
};

// The nodes' pose with `animation` (an index into `animations`; -1: the rest pose) at scene
// time `scene_time`. Nodes are in file order; a parent may come after its child.
ScenePose EvaluatePose(const std::vector<SceneNode>& nodes,
                       const std::vector<Animation>& animations, int animation,
                       double scene_time, bool loop);

// The CPU reference of skinning and morphing, what a GPU pre-pass must match (glTF 3.7.3):
// joint j's matrix is world(joints[j]) * inverse_bind[j], and a skinned vertex is
// sum_i weight_i * joint_matrix[joint_i] * position, in world space (the node's own transform
// does not apply). A morphed vertex is the base plus sum_t weight_t * delta_t.
struct Skin;
std::vector<glm::mat4> JointMatrices(const Skin& skin, const ScenePose& pose);
glm::vec3 SkinPoint(const glm::vec3& p, const glm::uvec4& joints, const glm::vec4& weights,
                    const std::vector<glm::mat4>& joint_matrices);
struct MorphDelta;
// `deltas`: target t's delta for this vertex at deltas[t * stride].
glm::vec3 MorphPosition(const glm::vec3& base, const MorphDelta* deltas, size_t stride,
                        const std::vector<float>& weights);

}  // namespace tessera

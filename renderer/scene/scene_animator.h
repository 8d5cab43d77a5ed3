#pragma once
// What an animated scene needs each frame, on the CPU (renderer/scene/animation.h evaluates the
// poses): which drawables move or deform, where the deformed ones' vertices go, and for a pose
// their world matrices, conservative world bounds, joint matrices and morph weights. GpuScene
// uploads the results and the skinning pass (renderer/features/skinning.cpp) deforms the
// vertices. Plain data; no Vulkan.
//
// File cameras and punctual lights on moving nodes follow them too (CameraWorld, PlaceLights).
// A drawable moves when an animation channel targets its node or an ancestor; it deforms when
// its primitive is skinned (and its node has a skin) or has morph targets. A deformed drawable
// gets its own copy of its primitive's vertices after the scene's (two nodes may show one mesh
// in different poses), which the pre-pass rewrites from the rest vertices for every new pose.
// Skinned vertices come out in world space (glTF 3.7.3: the node's own transform does not
// apply), so such a drawable's world matrix is the identity.
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include <glm/glm.hpp>

#include "renderer/scene/cpu_scene.h"

namespace tessera {

struct AnimatedDrawable {
  uint32_t drawable = 0;   // into CpuScene::drawables (and the Drawable buffer)
  uint32_t node = 0;
  glm::mat4 instance{1.0f};  // Drawable::instance: its transform under the node
  uint32_t primitive = 0;
  int32_t skin = -1;       // skinned: the node's skin (else -1)
  bool deformed = false;   // skinned or morphed: its vertices are rewritten each pose
  uint32_t first_vertex = 0;  // where the drawable's vertices are: its copy when deformed
  uint32_t joint_base = 0;    // skinned: its skin's first joint matrix in joints()
  uint32_t weight_base = 0;   // morphed: its node's first morph weight in weights()
};

class SceneAnimator {
 public:
  // nullptr when nothing in `scene` moves or deforms. The deformed drawables' copies are placed
  // from vertex scene.vertices.size() on.
  static std::unique_ptr<SceneAnimator> Create(const CpuScene& scene);

  const std::vector<AnimatedDrawable>& drawables() const { return drawables_; }
  // Vertices of the deformed copies (placed after the scene's), and the vertex data to upload:
  // the scene's followed by the copies (the rest vertices, until the first pose).
  uint64_t copy_vertices() const { return copy_vertices_; }
  uint64_t first_copy_vertex() const { return first_copy_vertex_; }
  std::vector<Vertex> VertexData(const CpuScene& scene) const;
  size_t joint_count() const { return joint_count_; }
  size_t weight_count() const { return weight_count_; }
  uint64_t deformed_vertices() const { return deformed_vertices_; }
  // Whether any drawable is skinned, and how many deformed drawables have vertices (the skinning
  // pass's jobs).
  bool skinned() const { return !skins_used_.empty(); }
  size_t skin_jobs() const { return skin_jobs_; }

  // Poses the scene with animation `animation` (-1: the rest pose) at `scene_time`. Returns
  // false when that is the pose already held (nothing changed).
  bool Pose(int animation, double scene_time, bool loop);
  // The last pose's identity: its animation and the time it was evaluated at (equal keys, equal
  // poses, whichever scene time and loop asked for it).
  uint64_t pose_key() const { return pose_key_; }
  // The last pose, per entry of drawables(): world matrix and world bounds; and the joint
  // matrices and morph weights the skinning pass reads.
  const std::vector<glm::mat4>& world() const { return world_; }
  const std::vector<Aabb>& bounds() const { return bounds_; }
  const std::vector<glm::mat4>& joints() const { return joints_; }
  const std::vector<float>& weights() const { return weights_; }
  // The world matrix of file camera `camera` (CpuScene::cameras) in the last pose, when its node
  // moves; and the lights on moving nodes placed at the last pose (position, direction).
  std::optional<glm::mat4> CameraWorld(uint32_t camera) const;
  void PlaceLights(std::vector<Light>* lights) const;
  bool moves_lights() const { return !lights_.empty(); }

 private:
  std::vector<SceneNode> nodes_;
  std::vector<Animation> animations_;
  std::vector<Skin> skins_;
  std::vector<AnimatedDrawable> drawables_;
  std::vector<Aabb> rest_bounds_;  // per drawables() entry: its primitive's object-space bounds
  // Per primitive (deformed ones only): the rest bounds, each morph target's delta bounds, and
  // per joint the bounds of the vertices it moves (skinned).
  struct PrimitiveBounds {
    Aabb rest;
    std::vector<Aabb> deltas;
    std::vector<std::pair<uint32_t, Aabb>> joints;
    uint32_t first_vertex = 0, vertex_count = 0, targets = 0;
  };
  std::vector<PrimitiveBounds> primitives_;  // indexed by primitive (empty entries unused)
  // The skins of the skinned drawables with their first joint in joints_, and the nodes of the
  // morphed ones with their first weight in weights_ and their weight count.
  std::vector<std::pair<uint32_t, uint32_t>> skins_used_;
  struct NodeWeights {
    uint32_t node = 0, base = 0, count = 0;
  };
  std::vector<NodeWeights> nodes_weighted_;
  // Cameras and lights (their index in CpuScene) on moving nodes, and the node's last world.
  struct MovingNode {
    uint32_t index = 0, node = 0;
    glm::mat4 world{1.0f};
  };
  std::vector<MovingNode> cameras_, lights_;
  uint64_t copy_vertices_ = 0, first_copy_vertex_ = 0;
  size_t skin_jobs_ = 0;
  uint64_t deformed_vertices_ = 0;
  size_t joint_count_ = 0, weight_count_ = 0;
  bool posed_ = false;
  uint64_t pose_key_ = 0;
  std::vector<glm::mat4> world_;
  std::vector<Aabb> bounds_;
  std::vector<glm::mat4> joints_;
  std::vector<float> weights_;
};

}  // namespace tessera

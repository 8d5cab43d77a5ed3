#include "renderer/scene/scene_animator.h"

#include <algorithm>
#include <bit>
#include <cmath>

namespace tessera {

std::unique_ptr<SceneAnimator> SceneAnimator::Create(const CpuScene& scene) {
  const size_t n = scene.nodes.size();
  if (n == 0) return nullptr;  // generated scenes have no nodes
  // Nodes a channel targets, then every node below one.
  std::vector<uint8_t> moving(n, 0);
  for (const Animation& a : scene.animations)
    for (const AnimationChannel& c : a.channels)
      if (c.node < n && c.path != AnimationPath::kWeights) moving[c.node] = 1;
  for (size_t i = 0; i < n; ++i) {
    if (moving[i]) continue;
    for (int32_t p = scene.nodes[i].parent, hops = 0; p >= 0 && size_t(p) < n && hops <= int(n);
         p = scene.nodes[size_t(p)].parent, ++hops) {
      if (moving[size_t(p)] == 1) {
        moving[i] = 2;  // moves with an ancestor
        break;
      }
    }
  }
  auto animator = std::unique_ptr<SceneAnimator>(new SceneAnimator());
  SceneAnimator& a = *animator;
  a.first_copy_vertex_ = scene.vertices.size();
  uint64_t next_vertex = a.first_copy_vertex_;
  // Joint matrices are the skin's (glTF 3.7.3: not the node's that draws the mesh) and morph
  // weights the node's: each is stored once, however many drawables use it.
  std::vector<int64_t> skin_base(scene.skins.size(), -1);
  std::vector<int64_t> node_weights(n, -1);
  std::vector<uint32_t> node_targets(n, 0);
  for (const Drawable& d : scene.drawables)
    if (d.node < n && d.primitive < scene.primitives.size())
      node_targets[d.node] = std::max(node_targets[d.node], scene.primitives[d.primitive].morph_targets);
  for (uint32_t i = 0; i < scene.drawables.size(); ++i) {
    const Drawable& d = scene.drawables[i];
    if (d.node >= n || d.primitive >= scene.primitives.size()) continue;
    const Primitive& p = scene.primitives[d.primitive];
    const SceneNode& node = scene.nodes[d.node];
    AnimatedDrawable ad;
    ad.drawable = i;
    ad.node = d.node;
    ad.instance = d.instance;
    ad.primitive = d.primitive;
    const bool skinned = p.skinned && node.skin >= 0 && size_t(node.skin) < scene.skins.size() &&
                         scene.skin_joints.size() == scene.vertices.size();
    ad.skin = skinned ? node.skin : -1;
    ad.deformed = skinned || p.morph_targets > 0;
    if (!ad.deformed && !moving[d.node]) continue;
    ad.first_vertex = p.first_vertex;
    if (ad.deformed) {
      ad.first_vertex = uint32_t(next_vertex);
      next_vertex += p.vertex_count;
      a.copy_vertices_ += p.vertex_count;
      if (p.vertex_count > 0) ++a.skin_jobs_;
      a.deformed_vertices_ += p.vertex_count;
      if (skinned) {
        int64_t& base = skin_base[size_t(node.skin)];
        if (base < 0) {
          base = int64_t(a.joint_count_);
          a.skins_used_.push_back({uint32_t(node.skin), uint32_t(base)});
          a.joint_count_ += scene.skins[size_t(node.skin)].joints.size();
        }
        ad.joint_base = uint32_t(base);
      }
      if (p.morph_targets > 0) {
        int64_t& base = node_weights[d.node];
        if (base < 0) {
          base = int64_t(a.weight_count_);
          a.nodes_weighted_.push_back({d.node, uint32_t(base), node_targets[d.node]});
          a.weight_count_ += node_targets[d.node];
        }
        ad.weight_base = uint32_t(base);
      }
      if (a.primitives_.size() <= d.primitive) a.primitives_.resize(d.primitive + 1);
      PrimitiveBounds& pb = a.primitives_[d.primitive];
      if (pb.vertex_count == 0 && p.vertex_count > 0) {
        pb.first_vertex = p.first_vertex;
        pb.vertex_count = p.vertex_count;
        pb.targets = p.morph_targets;
        for (uint32_t v = 0; v < p.vertex_count; ++v)
          pb.rest.extend(scene.vertices[p.first_vertex + v].position);
        pb.deltas.resize(p.morph_targets);
        for (uint32_t t = 0; t < p.morph_targets; ++t)
          for (uint32_t v = 0; v < p.vertex_count; ++v)
            pb.deltas[t].extend(
                scene.morph_deltas[p.first_morph_delta + uint64_t(t) * p.vertex_count + v].position);
        if (p.skinned && scene.skin_joints.size() == scene.vertices.size()) {
          std::vector<Aabb> boxes;
          for (uint32_t v = 0; v < p.vertex_count; ++v) {
            const glm::uvec4 j = scene.skin_joints[p.first_vertex + v];
            const glm::vec4 w = scene.skin_weights[p.first_vertex + v];
            for (int k = 0; k < 4; ++k) {
              if (w[k] == 0.0f) continue;
              if (boxes.size() <= j[k]) boxes.resize(j[k] + 1);
              boxes[j[k]].extend(scene.vertices[p.first_vertex + v].position);
            }
          }
          for (uint32_t j = 0; j < boxes.size(); ++j)
            if (!boxes[j].empty()) pb.joints.emplace_back(j, boxes[j]);
        }
      }
    }
    a.drawables_.push_back(ad);
    a.rest_bounds_.push_back(p.bounds);
  }
  // File cameras and lights whose node moves.
  for (uint32_t i = 0; i < scene.cameras.size(); ++i) {
    const int32_t node = scene.cameras[i].node;
    if (node >= 0 && size_t(node) < n && moving[size_t(node)])
      a.cameras_.push_back({i, uint32_t(node)});
  }
  for (uint32_t i = 0; i < scene.lights.size(); ++i) {
    const int32_t node = scene.lights[i].node;
    if (node >= 0 && size_t(node) < n && moving[size_t(node)])
      a.lights_.push_back({i, uint32_t(node)});
  }
  if (a.drawables_.empty() && a.cameras_.empty() && a.lights_.empty()) return nullptr;
  a.nodes_ = scene.nodes;
  a.animations_ = scene.animations;
  a.skins_ = scene.skins;
  a.world_.assign(a.drawables_.size(), glm::mat4(1.0f));
  a.bounds_.resize(a.drawables_.size());
  a.joints_.assign(a.joint_count_, glm::mat4(1.0f));
  a.weights_.assign(a.weight_count_, 0.0f);
  return animator;
}

std::optional<glm::mat4> SceneAnimator::CameraWorld(uint32_t camera) const {
  for (const MovingNode& c : cameras_)
    if (c.index == camera && posed_) return c.world;
  return std::nullopt;
}

void SceneAnimator::PlaceLights(std::vector<Light>* lights) const {
  for (const MovingNode& l : lights_) {
    if (l.index >= lights->size()) continue;
    Light& light = (*lights)[l.index];
    light.position = glm::vec3(l.world[3]);
    const glm::vec3 d = glm::mat3(l.world) * glm::vec3(0.0f, 0.0f, -1.0f);
    const float len = glm::length(d);
    light.direction = len > 0.0f && std::isfinite(len) ? d / len : glm::vec3(0.0f, 0.0f, -1.0f);
  }
}

std::vector<Vertex> SceneAnimator::VertexData(const CpuScene& scene) const {
  std::vector<Vertex> out;
  out.reserve(scene.vertices.size() + copy_vertices_);
  out = scene.vertices;
  for (const AnimatedDrawable& ad : drawables_) {
    if (!ad.deformed) continue;
    const Primitive& p = scene.primitives[ad.primitive];
    out.insert(out.end(), scene.vertices.begin() + p.first_vertex,
               scene.vertices.begin() + p.first_vertex + p.vertex_count);
  }
  return out;
}

bool SceneAnimator::Pose(int animation, double scene_time, bool loop) {
  if (animation >= int(animations_.size())) animation = -1;
  const float t =
      animation < 0 ? 0.0f : AnimationTime(animations_[size_t(animation)], scene_time, loop);
  // The animation and the bits of the time evaluated: equal keys, equal poses.
  const uint64_t key = (uint64_t(uint32_t(animation)) << 32) | std::bit_cast<uint32_t>(t);
  if (posed_ && key == pose_key_) return false;
  posed_ = true;
  pose_key_ = key;
  // AnimationTime already folded the loop: evaluate at the animation's own time, unlooped.
  const ScenePose pose = EvaluatePose(nodes_, animations_, animation, t, false);
  for (MovingNode& c : cameras_) c.world = pose.world[c.node];
  for (MovingNode& l : lights_) l.world = pose.world[l.node];
  for (const auto& [skin, base] : skins_used_) {
    const std::vector<glm::mat4> joints = JointMatrices(skins_[skin], pose);
    std::copy(joints.begin(), joints.end(), joints_.begin() + base);
  }
  for (const auto& [node, base, count] : nodes_weighted_) {
    const std::vector<float>& w = pose.weights[node];  // missing weights are 0
    for (uint32_t k = 0; k < count; ++k) weights_[base + k] = k < w.size() ? w[k] : 0.0f;
  }
  for (size_t i = 0; i < drawables_.size(); ++i) {
    const AnimatedDrawable& ad = drawables_[i];
    if (!ad.deformed) {
      world_[i] = pose.world[ad.node] * ad.instance;
      bounds_[i] = rest_bounds_[i].transformed(world_[i]);
      continue;
    }
    const PrimitiveBounds& pb = primitives_[ad.primitive];
    // How far the morph targets at their weights can move a vertex, per axis.
    glm::vec3 lo(0.0f), hi(0.0f);
    for (uint32_t k = 0; k < pb.targets; ++k) {
      const float wk = weights_[ad.weight_base + k];
      if (pb.deltas[k].empty()) continue;
      lo += glm::min(wk * pb.deltas[k].min, wk * pb.deltas[k].max);
      hi += glm::max(wk * pb.deltas[k].min, wk * pb.deltas[k].max);
    }
    auto grown = [&](const Aabb& b) {
      Aabb g;
      if (!b.empty()) {
        g.min = b.min + lo;
        g.max = b.max + hi;
      }
      return g;
    };
    if (ad.skin >= 0) {
      const size_t joints = skins_[size_t(ad.skin)].joints.size();
      world_[i] = glm::mat4(1.0f);
      // A skinned vertex is a convex blend of its joints' transforms of it: inside the union of
      // each joint's transformed box of the vertices it moves.
      Aabb b;
      for (const auto& [j, box] : pb.joints)
        if (j < joints) b.extend(grown(box).transformed(joints_[ad.joint_base + j]));
      bounds_[i] = b;
    } else {
      world_[i] = pose.world[ad.node] * ad.instance;
      bounds_[i] = grown(pb.rest).transformed(world_[i]);
    }
  }
  return true;
}

}  // namespace tessera

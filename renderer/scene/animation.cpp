#include "renderer/scene/animation.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>

#include "renderer/scene/cpu_scene.h"

namespace tessera {
namespace {

glm::quat Quat(const float* xyzw) { return glm::quat(xyzw[3], xyzw[0], xyzw[1], xyzw[2]); }

void Store(const glm::quat& q, float* xyzw) {
  xyzw[0] = q.x;
  xyzw[1] = q.y;
  xyzw[2] = q.z;
  xyzw[3] = q.w;
}

// glTF Appendix C: slerp along the shorter arc, lerp when the two are nearly the same.
glm::quat Slerp(glm::quat a, glm::quat b, float u) {
  float d = glm::dot(a, b);
  if (d < 0.0f) {
    b = -b;
    d = -d;
  }
  if (d > 0.9995f) return glm::normalize(a * (1.0f - u) + b * u);
  const float angle = std::acos(std::min(d, 1.0f));
  const float s = std::sin(angle);
  return a * (std::sin((1.0f - u) * angle) / s) + b * (std::sin(u * angle) / s);
}

}  // namespace

glm::mat4 NodeTransform::Matrix() const {
  return glm::translate(glm::mat4(1.0f), translation) * glm::mat4_cast(rotation) *
         glm::scale(glm::mat4(1.0f), scale);
}

void SampleAnimation(const AnimationSampler& s, float t, bool rotation, float* out) {
  const size_t keys = s.times.size();
  const uint32_t w = s.width;
  const bool cubic = s.interpolation == Interpolation::kCubicSpline;
  // Key k's value (the middle group of a cubic key).
  const auto value = [&](size_t k) { return s.values.data() + (cubic ? (3 * k + 1) * w : k * w); };
  const auto copy = [&](const float* v) { std::copy(v, v + w, out); };
  if (keys == 0) return;
  if (keys == 1 || t <= s.times.front()) return copy(value(0));
  if (t >= s.times.back()) return copy(value(keys - 1));
  // The interval [times[k], times[k + 1]) holding t.
  const size_t k = size_t(std::upper_bound(s.times.begin(), s.times.end(), t) - s.times.begin()) - 1;
  const float t0 = s.times[k], t1 = s.times[k + 1];
  const float dt = t1 - t0;
  const float u = (t - t0) / dt;
  switch (s.interpolation) {
    case Interpolation::kStep:
      return copy(value(k));
    case Interpolation::kLinear:
      if (rotation) return Store(Slerp(Quat(value(k)), Quat(value(k + 1)), u), out);
      for (uint32_t c = 0; c < w; ++c) out[c] = value(k)[c] * (1.0f - u) + value(k + 1)[c] * u;
      return;
    case Interpolation::kCubicSpline: {
      const float* v0 = value(k);
      const float* b0 = s.values.data() + (3 * k + 2) * w;  // out-tangent of key k
      const float* a1 = s.values.data() + (3 * (k + 1)) * w;  // in-tangent of key k + 1
      const float* v1 = value(k + 1);
      const float u2 = u * u, u3 = u2 * u;
      const float h00 = 2 * u3 - 3 * u2 + 1, h10 = u3 - 2 * u2 + u, h01 = -2 * u3 + 3 * u2,
                  h11 = u3 - u2;
      for (uint32_t c = 0; c < w; ++c)
        out[c] = h00 * v0[c] + h10 * dt * b0[c] + h01 * v1[c] + h11 * dt * a1[c];
      if (rotation) {
        glm::quat q = Quat(out);
        const float len = glm::length(q);
        Store(len > 0.0f ? q / len : glm::quat(1.0f, 0.0f, 0.0f, 0.0f), out);
      }
      return;
    }
  }
}

double WrapAnimationTime(double t, double duration, bool loop) {
  if (!loop) return std::clamp(t, 0.0, duration);
  t = std::fmod(t, duration);
  return t < 0.0 ? t + duration : t;
}

float AnimationTime(const Animation& a, double scene_time, bool loop) {
  const double d = a.duration;
  if (!(d > 0.0) || !std::isfinite(scene_time)) return 0.0f;
  return float(WrapAnimationTime(scene_time, d, loop));
}

ScenePose EvaluatePose(const std::vector<SceneNode>& nodes,
                       const std::vector<Animation>& animations, int animation,
                       double scene_time, bool loop) {
  const size_t n = nodes.size();
  std::vector<NodeTransform> trs(n);
  ScenePose pose;
  pose.weights.resize(n);
  for (size_t i = 0; i < n; ++i) {
    trs[i] = nodes[i].rest;
    pose.weights[i] = nodes[i].weights;
  }
  if (animation >= 0 && size_t(animation) < animations.size()) {
    const Animation& a = animations[animation];
    const float t = AnimationTime(a, scene_time, loop);
    float v[4];
    for (const AnimationChannel& c : a.channels) {
      if (c.node >= n || c.sampler >= a.samplers.size()) continue;  // the importer checked
      const AnimationSampler& s = a.samplers[c.sampler];
      switch (c.path) {
        case AnimationPath::kTranslation:
          SampleAnimation(s, t, false, v);
          trs[c.node].translation = glm::vec3(v[0], v[1], v[2]);
          break;
        case AnimationPath::kScale:
          SampleAnimation(s, t, false, v);
          trs[c.node].scale = glm::vec3(v[0], v[1], v[2]);
          break;
        case AnimationPath::kRotation:
          SampleAnimation(s, t, true, v);
          trs[c.node].rotation = Quat(v);
          break;
        case AnimationPath::kWeights:
          pose.weights[c.node].resize(s.width);
          SampleAnimation(s, t, false, pose.weights[c.node].data());
          break;
      }
    }
  }
  pose.local.resize(n);
  for (size_t i = 0; i < n; ++i)
    pose.local[i] = nodes[i].matrix ? *nodes[i].matrix : trs[i].Matrix();
  // World matrices parent first, whatever the file order (the hierarchy is acyclic).
  pose.world.assign(n, glm::mat4(1.0f));
  std::vector<uint8_t> done(n, 0);
  std::vector<size_t> chain;
  for (size_t i = 0; i < n; ++i) {
    for (size_t j = i; !done[j]; j = size_t(nodes[j].parent)) {
      chain.push_back(j);
      if (nodes[j].parent < 0) break;
    }
    for (auto it = chain.rbegin(); it != chain.rend(); ++it) {
      const int32_t p = nodes[*it].parent;
      pose.world[*it] = p < 0 ? pose.local[*it] : pose.world[size_t(p)] * pose.local[*it];
      done[*it] = 1;
    }
    chain.clear();
  }
  return pose;
}

std::vector<glm::mat4> JointMatrices(const Skin& skin, const ScenePose& pose) {
  std::vector<glm::mat4> out(skin.joints.size(), glm::mat4(1.0f));
  for (size_t j = 0; j < skin.joints.size(); ++j) {
    if (skin.joints[j] >= pose.world.size()) continue;  // the importer checked
    const glm::mat4 ibm = j < skin.inverse_bind.size() ? skin.inverse_bind[j] : glm::mat4(1.0f);
    out[j] = pose.world[skin.joints[j]] * ibm;
  }
  return out;
}

glm::vec3 SkinPoint(const glm::vec3& p, const glm::uvec4& joints, const glm::vec4& weights,
                    const std::vector<glm::mat4>& joint_matrices) {
  glm::vec4 out(0.0f);
  for (int i = 0; i < 4; ++i) {
    if (weights[i] == 0.0f || joints[i] >= joint_matrices.size()) continue;
    out += weights[i] * (joint_matrices[joints[i]] * glm::vec4(p, 1.0f));
  }
  return glm::vec3(out);
}

glm::vec3 MorphPosition(const glm::vec3& base, const MorphDelta* deltas, size_t stride,
                        const std::vector<float>& weights) {
  glm::vec3 p = base;
  for (size_t t = 0; t < weights.size(); ++t) p += weights[t] * deltas[t * stride].position;
  return p;
}

}  // namespace tessera

#include "renderer/shadows.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace tessera {
namespace {

std::array<glm::vec3, 8> Corners(const Aabb& b) {
  std::array<glm::vec3, 8> out;
  for (int i = 0; i < 8; ++i) out[i] = b.corner(i);
  return out;
}

// glm stores columns; the matrices here read better as rows.
glm::mat4 FromRows(const glm::vec4& r0, const glm::vec4& r1, const glm::vec4& r2,
                   const glm::vec4& r3) {
  return glm::transpose(glm::mat4(r0, r1, r2, r3));
}

// A perspective view from `eye` down `forward` in the frame (right, down, forward), which must
// be right-handed like the camera's (right, -up, -back) so triangles keep their winding. `t` is
// the tangent of the half-angle across the whole face; standard Z, near -> 0 and far -> 1.
glm::mat4 Perspective(const glm::vec3& right, const glm::vec3& down, const glm::vec3& forward,
                      const glm::vec3& eye, float t, float znear, float zfar) {
  const float a = zfar / (zfar - znear), b = -zfar * znear / (zfar - znear);
  const float ef = -glm::dot(forward, eye);
  return FromRows(glm::vec4(right / t, -glm::dot(right, eye) / t),
                  glm::vec4(down / t, -glm::dot(down, eye) / t), glm::vec4(a * forward, a * ef + b),
                  glm::vec4(forward, ef));
}

// tan(half-angle) of a face whose middle `resolution - 2 * border` texels span tan_inner.
float WidenByBorder(float tan_inner, uint32_t resolution) {
  const uint32_t res = std::max(resolution, 2 * kShadowBorderTexels + 1);
  return tan_inner * float(res) / float(res - 2 * kShadowBorderTexels);
}

uint32_t RoundUpPow2(uint32_t v) {
  uint32_t p = 1;
  while (p < v && p < (1u << 31)) p <<= 1;
  return p;
}

uint32_t Log2(uint32_t v) {
  uint32_t l = 0;
  while (v > 1) {
    v >>= 1;
    ++l;
  }
  return l;
}

bool Before(const AtlasRect& a, const AtlasRect& b) { return a.y != b.y ? a.y < b.y : a.x < b.x; }

}  // namespace

glm::mat3 LightBasis(glm::vec3 direction) {
  const float len = glm::length(direction);
  const glm::vec3 z =
      len > 0.0f && std::isfinite(len) ? direction / len : glm::vec3(0.0f, 0.0f, -1.0f);
  const glm::vec3 up =
      std::abs(z.y) > 0.99f ? glm::vec3(1.0f, 0.0f, 0.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
  const glm::vec3 x = glm::normalize(glm::cross(up, z));
  const glm::vec3 y = glm::cross(z, x);
  return glm::transpose(glm::mat3(x, y, z));
}

std::vector<Cascade> ComputeCascades(const Camera& camera, float aspect, glm::vec3 sun_direction,
                                     const Aabb& scene_bounds, float shadow_distance,
                                     const CascadeParams& params) {
  const uint32_t count = std::clamp(params.count, 1u, kMaxCascades);
  const uint32_t res = std::max(params.resolution, 2 * kShadowBorderTexels + 1);
  const float lambda = std::clamp(params.split_lambda, 0.0f, 1.0f);
  const float n = camera.znear;
  const float f =
      std::isfinite(shadow_distance) ? std::max(shadow_distance, n * 1.001f) : n * 1.001f;

  const glm::mat4 inv_view = glm::inverse(ViewMatrix(camera));
  const glm::vec3 eye(inv_view[3]);
  const glm::vec3 forward = -glm::normalize(glm::vec3(inv_view[2]));
  const float ty = std::tan(camera.yfov * 0.5f), tx = ty * aspect;
  const float k2 = tx * tx + ty * ty;

  const glm::mat3 basis = LightBasis(sun_direction);
  const glm::mat3 to_world = glm::transpose(basis);
  const glm::vec3 lx = to_world[0], ly = to_world[1], lz = to_world[2];

  // The depth range along the light covers every caster in the scene, whatever the slice.
  float zmin = std::numeric_limits<float>::max(), zmax = std::numeric_limits<float>::lowest();
  if (!scene_bounds.empty()) {
    for (const glm::vec3& c : Corners(scene_bounds)) {
      zmin = std::min(zmin, glm::dot(c, lz));
      zmax = std::max(zmax, glm::dot(c, lz));
    }
  }

  std::vector<Cascade> cascades(count);
  float a = n;
  for (uint32_t i = 0; i < count; ++i) {
    Cascade& c = cascades[i];
    const float s = float(i + 1) / float(count);
    const float b =
        i + 1 == count ? f : lambda * n * std::pow(f / n, s) + (1.0f - lambda) * (n + (f - n) * s);
    c.split_near = a;
    c.split_far = b;
    // The smallest sphere around the slice's corners, centred on the view axis: it depends on
    // the split distances and the field of view alone, so rotating the camera keeps its size.
    const float d = std::min(b, (a + b) * (1.0f + k2) * 0.5f);
    c.radius = std::max(std::sqrt((b - d) * (b - d) + b * b * k2),
                        std::sqrt((d - a) * (d - a) + a * a * k2));
    c.texel_world = 2.0f * c.radius / float(res - 2 * kShadowBorderTexels);
    // Snapping the centre to whole texels makes a moving camera shift the map by whole texels,
    // so static shadow edges do not shimmer.
    const glm::vec3 p = basis * (eye + forward * d);
    c.light_origin = glm::vec2(std::round(p.x / c.texel_world) * c.texel_world,
                               std::round(p.y / c.texel_world) * c.texel_world);
    c.center = to_world * glm::vec3(c.light_origin, p.z);

    float z0 = zmin, z1 = zmax;
    if (scene_bounds.empty()) {  // nothing casts: any valid range will do
      z0 = p.z - c.radius;
      z1 = p.z + c.radius;
    }
    const float pad = std::max(0.01f * (z1 - z0), 1e-3f);
    z0 -= pad;
    z1 += pad;
    const float half = c.radius + float(kShadowBorderTexels) * c.texel_world;
    // Clip x, y along -x, -y of the basis: (-x, -y, z) is right-handed like a camera's
    // (right, down, forward), so triangles keep the winding they have in the camera's view.
    c.view_proj =
        FromRows(glm::vec4(-lx / half, c.light_origin.x / half),
                 glm::vec4(-ly / half, c.light_origin.y / half),
                 glm::vec4(lz / (z1 - z0), -z0 / (z1 - z0)), glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));
    a = b;
  }
  return cascades;
}

float ShadowNear(const Light& light) {
  return light.range > 0.0f ? std::max(light.range * 0.002f, 1e-3f) : 0.01f;
}

float ShadowFar(const Light& light, const Aabb& scene_bounds) {
  const float far =
      light.range > 0.0f ? light.range : scene_bounds.farthest_distance(light.position);
  // A tiny range would put far before near.
  return std::max(far, ShadowNear(light) * 2.0f);
}

glm::mat4 SpotViewProj(const Light& light, uint32_t resolution, const Aabb& scene_bounds) {
  const float outer = std::clamp(light.outer_cone_angle, 1e-3f, glm::radians(89.0f));
  const float t = WidenByBorder(std::tan(outer), resolution);
  const glm::mat3 basis = glm::transpose(LightBasis(light.direction));
  return Perspective(-basis[0], -basis[1], basis[2], light.position, t, ShadowNear(light),
                     ShadowFar(light, scene_bounds));
}

glm::mat4 PointFaceViewProj(const Light& light, uint32_t face, uint32_t resolution,
                            const Aabb& scene_bounds) {
  // Forward and down per face; right = down x forward keeps (right, down, forward)
  // right-handed.
  static constexpr std::array<std::array<float, 6>, kCubeFaces> kFaces = {{
      {1, 0, 0, 0, -1, 0},
      {-1, 0, 0, 0, -1, 0},
      {0, 1, 0, 0, 0, 1},
      {0, -1, 0, 0, 0, -1},
      {0, 0, 1, 0, -1, 0},
      {0, 0, -1, 0, -1, 0},
  }};
  const auto& f = kFaces[std::min(face, kCubeFaces - 1)];
  const glm::vec3 forward(f[0], f[1], f[2]), down(f[3], f[4], f[5]);
  const glm::vec3 right = glm::cross(down, forward);
  return Perspective(right, down, forward, light.position, WidenByBorder(1.0f, resolution),
                     ShadowNear(light), ShadowFar(light, scene_bounds));
}

uint32_t CubeFace(glm::vec3 v) {
  const glm::vec3 a = glm::abs(v);
  if (a.x >= a.y && a.x >= a.z) return v.x >= 0.0f ? 0 : 1;
  if (a.y >= a.z) return v.y >= 0.0f ? 2 : 3;
  return v.z >= 0.0f ? 4 : 5;
}

std::vector<uint32_t> ChooseShadowedLights(const std::vector<Light>& lights,
                                           const Frustum& camera_frustum, glm::vec3 camera_position,
                                           uint32_t count) {
  struct Candidate {
    double importance;
    uint32_t index;
  };
  std::vector<Candidate> candidates;
  for (uint32_t i = 0; i < lights.size(); ++i) {
    const Light& l = lights[i];
    if (l.type != LightType::kPoint && l.type != LightType::kSpot) continue;
    if (!(l.range > 0.0f) || !std::isfinite(l.range)) continue;
    bool visible = true;
    for (const glm::vec4& p : camera_frustum) {
      if (glm::dot(glm::vec3(p), l.position) + p.w < -l.range) {
        visible = false;
        break;
      }
    }
    if (!visible) continue;
    // Distance to the sphere, floored at a tenth of the range so lights around the camera do
    // not all tie at infinity.
    const double range = l.range;
    const double dist = std::max(0.0, double(glm::length(camera_position - l.position)) - range);
    const double importance =
        double(l.intensity) * range * range / std::max(dist * dist, 0.01 * range * range);
    candidates.push_back({importance, i});
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& a, const Candidate& b) {
    return a.importance != b.importance ? a.importance > b.importance : a.index < b.index;
  });
  std::vector<uint32_t> out;
  for (uint32_t i = 0; i < candidates.size() && i < count; ++i) out.push_back(candidates[i].index);
  return out;
}

glm::mat4 AtlasTransform(const AtlasRect& rect, uint32_t atlas_size) {
  const float inv = 1.0f / float(atlas_size);
  const float s = 0.5f * float(rect.size) * inv;
  glm::mat4 m(1.0f);
  m[0][0] = s;
  m[1][1] = s;
  // Multiplied by clip w, so they survive the divide as plain offsets.
  m[3][0] = (float(rect.x) + 0.5f * float(rect.size)) * inv;
  m[3][1] = (float(rect.y) + 0.5f * float(rect.size)) * inv;
  return m;
}

ShadowAtlas::ShadowAtlas(uint32_t size, uint32_t min_face)
    : size_(std::max(size, 1u)), min_face_(std::clamp(min_face, 1u, size_)) {
  levels_ = Log2(size_ / min_face_) + 1;
  Clear();
}

void ShadowAtlas::BeginFrame() { ++frame_; }

void ShadowAtlas::Release(uint64_t key) {
  const auto held =
      std::find_if(held_.begin(), held_.end(), [key](const auto& h) { return h.first == key; });
  if (held == held_.end()) return;
  Free(held->second.rect, held->second.level);
  held_.erase(held);
}

void ShadowAtlas::Clear() {
  free_.assign(levels_, {});
  free_[0].push_back(AtlasRect{0, 0, size_});
  held_.clear();
}

uint32_t ShadowAtlas::faces() const { return uint32_t(held_.size()); }

uint64_t ShadowAtlas::texels_used() const {
  uint64_t sum = 0;
  for (const auto& [key, face] : held_) sum += uint64_t(face.rect.size) * face.rect.size;
  return sum;
}

std::optional<AtlasRect> ShadowAtlas::Allocate(uint32_t level) {
  // The nearest level with a free block, and in it the lowest (y, x): placement is a function
  // of the sequence of requests alone.
  int from = int(level);
  while (from >= 0 && free_[from].empty()) --from;
  if (from < 0) return std::nullopt;
  auto& list = free_[from];
  const auto it = std::min_element(list.begin(), list.end(), Before);
  AtlasRect block = *it;
  list.erase(it);
  for (uint32_t l = uint32_t(from); l < level; ++l) {
    const uint32_t h = block.size / 2;
    free_[l + 1].push_back({block.x + h, block.y, h});
    free_[l + 1].push_back({block.x, block.y + h, h});
    free_[l + 1].push_back({block.x + h, block.y + h, h});
    block.size = h;
  }
  return block;
}

void ShadowAtlas::Free(const AtlasRect& rect, uint32_t level) {
  if (level > 0) {
    const uint32_t parent = rect.size * 2;
    const uint32_t px = rect.x - rect.x % parent, py = rect.y - rect.y % parent;
    auto& list = free_[level];
    std::array<size_t, 3> found{};
    int n = 0;
    for (size_t i = 0; i < list.size() && n < 3; ++i) {
      const AtlasRect& b = list[i];
      if (b.x - b.x % parent == px && b.y - b.y % parent == py) found[n++] = i;
    }
    if (n == 3) {
      // Erase from the back so the earlier indices stay valid.
      std::sort(found.begin(), found.end());
      for (int k = 2; k >= 0; --k) list.erase(list.begin() + std::ptrdiff_t(found[k]));
      Free(AtlasRect{px, py, parent}, level - 1);
      return;
    }
  }
  free_[level].push_back(rect);
}

std::optional<ShadowAtlas::Placement> ShadowAtlas::Acquire(uint64_t key, uint32_t size,
                                                           uint64_t content) {
  const uint32_t face_size = std::clamp(RoundUpPow2(std::max(size, 1u)), min_face_, size_);
  const uint32_t level = Log2(size_ / face_size);

  auto held =
      std::find_if(held_.begin(), held_.end(), [key](const auto& h) { return h.first == key; });
  if (held != held_.end()) {
    Face& face = held->second;
    if (face.level == level) {
      face.last_frame = frame_;
      const bool cached = face.content == content;
      face.content = content;
      return Placement{face.rect, cached};
    }
    Free(face.rect, face.level);
    held_.erase(held);
  }

  std::optional<AtlasRect> rect = Allocate(level);
  if (!rect) {
    // Whether evicting every face of earlier frames would leave an aligned block of this size:
    // if not, fail without evicting faces that may still be cached next frame.
    const uint32_t cells = size_ / face_size;
    std::vector<bool> busy(size_t(cells) * cells, false);
    for (const auto& [k, face] : held_) {
      if (face.last_frame != frame_) continue;
      const uint32_t x0 = face.rect.x / face_size, y0 = face.rect.y / face_size;
      const uint32_t span = std::max(face.rect.size / face_size, 1u);
      for (uint32_t y = y0; y < y0 + span; ++y)
        for (uint32_t x = x0; x < x0 + span; ++x) busy[size_t(y) * cells + x] = true;
    }
    if (std::find(busy.begin(), busy.end(), false) == busy.end()) return std::nullopt;

    std::vector<std::pair<uint64_t, uint64_t>> victims;  // (last_frame, key): oldest first
    for (const auto& [k, face] : held_)
      if (face.last_frame < frame_) victims.emplace_back(face.last_frame, k);
    std::sort(victims.begin(), victims.end());
    for (const auto& [frame, victim] : victims) {
      const auto it = std::find_if(held_.begin(), held_.end(),
                                   [victim](const auto& h) { return h.first == victim; });
      Free(it->second.rect, it->second.level);
      held_.erase(it);
      ++evictions_;
      if ((rect = Allocate(level))) break;
    }
    if (!rect) return std::nullopt;  // unreachable: the check above found room
  }
  Face face;
  face.rect = *rect;
  face.content = content;
  face.last_frame = frame_;
  face.level = level;
  held_.emplace_back(key, face);
  return Placement{*rect, false};
}

uint64_t HashBytes(const void* data, size_t size, uint64_t seed) {
  const auto* bytes = static_cast<const unsigned char*>(data);
  uint64_t h = seed;
  for (size_t i = 0; i < size; ++i) {
    h ^= bytes[i];
    h *= 1099511628211ull;
  }
  return h;
}

}  // namespace tessera

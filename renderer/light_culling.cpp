#include "renderer/light_culling.h"

#include <algorithm>
#include <cmath>

#include "renderer/scene/hash.h"

namespace tessera {
namespace {

// Light i's random numbers depend on (seed, i, k) only, so a light does not change when the
// count does.
float Random(uint32_t seed, uint32_t i, uint32_t k) {
  return float(Lowbias32(Lowbias32(seed * 0x9e3779b9U + i) + k) >> 8) * (1.0f / 16777216.0f);
}

glm::vec3 Hue(float h) {
  const glm::vec3 k(0.0f, 2.0f / 3.0f, 1.0f / 3.0f);
  glm::vec3 c = glm::abs(glm::fract(glm::vec3(h) + k) * 6.0f - 3.0f) - 1.0f;
  return glm::clamp(c, 0.0f, 1.0f);
}

// The view-space bounding sphere of a light (a spot's cone inside its sphere).
glm::vec4 WorldSphere(const Light& l) {
  if (l.type != LightType::kSpot) return glm::vec4(l.position, l.range);
  const float a = l.outer_cone_angle, r = l.range;
  if (std::cos(a) < gpu::kWideSpotCos) {  // wide cone: the sphere of the cap's circle
    return glm::vec4(l.position + std::cos(a) * r * l.direction, std::sin(a) * r);
  }
  const float half = r / (2.0f * std::cos(a) * std::cos(a));
  return glm::vec4(l.position + half * l.direction, half);
}

struct TileFrustum {
  std::array<glm::vec3, 4> planes;  // through the eye, normals pointing inside
  std::array<glm::vec3, 4> rays;    // corner directions at view depth 1
};

// Corner rays of the tile through all four of its corners (a frustum from three corners is
// not the tile's), with plane normals oriented towards the tile's centre ray.
TileFrustum MakeTileFrustum(const glm::mat4& proj, const TileGrid& g, uint32_t tx, uint32_t ty) {
  const float x0 = float(tx * g.tile_size), y0 = float(ty * g.tile_size);
  const float x1 = float(std::min((tx + 1) * g.tile_size, g.width));
  const float y1 = float(std::min((ty + 1) * g.tile_size, g.height));
  auto ray = [&](float px, float py) {
    const float nx = 2.0f * px / float(g.width) - 1.0f;
    const float ny = 2.0f * py / float(g.height) - 1.0f;
    return glm::vec3(nx / proj[0][0], ny / proj[1][1], -1.0f);
  };
  TileFrustum f;
  f.rays = {ray(x0, y0), ray(x1, y0), ray(x1, y1), ray(x0, y1)};
  const glm::vec3 centre = ray(0.5f * (x0 + x1), 0.5f * (y0 + y1));
  for (int i = 0; i < 4; ++i) {
    glm::vec3 n = glm::normalize(glm::cross(f.rays[i], f.rays[(i + 1) % 4]));
    if (glm::dot(n, centre) < 0.0f) n = -n;
    f.planes[i] = n;
  }
  return f;
}

uint32_t SliceMask(float z0, float z1, float dmin, float scale) {
  // Clamped as floats: (z - dmin) * scale can exceed the int range when dmax ~ dmin.
  const int s0 = int(std::clamp(std::floor((z0 - dmin) * scale), 0.0f, 31.0f));
  const int s1 = int(std::clamp(std::floor((z1 - dmin) * scale), 0.0f, 31.0f));
  if (z1 < dmin) return 0u;
  const uint32_t hi = s1 == 31 ? 0xffffffffu : ((2u << s1) - 1u);
  return hi & ~((1u << s0) - 1u);
}

}  // namespace

std::vector<Light> MakeSyntheticLights(const Aabb& bounds, const SyntheticLightParams& p) {
  std::vector<Light> lights;
  if (bounds.empty()) return lights;
  lights.reserve(p.count);
  const glm::vec3 ext = bounds.extent();
  const float diag = glm::length(ext);
  const float r0 = p.radius_min > 0.0f ? p.radius_min : 0.01f * diag;
  const float r1 = std::max(r0, p.radius_max > 0.0f ? p.radius_max : 0.04f * diag);
  const uint32_t seed = p.seed;
  for (uint32_t i = 0; i < p.count; ++i) {
    Light l;
    l.name = "synthetic";
    l.type = LightType::kPoint;
    l.position =
        bounds.min + ext * glm::vec3(Random(seed, i, 0), Random(seed, i, 1), Random(seed, i, 2));
    l.range = r0 + (r1 - r0) * Random(seed, i, 3);
    if (p.animated) {  // a horizontal circle, 0.5..1.5 rad/s either way, random phase
      const float speed = (0.5f + Random(seed, i, 5)) * (Random(seed, i, 6) < 0.5f ? -1.0f : 1.0f);
      const float angle = 6.2831853f * Random(seed, i, 7) + speed * p.time;
      l.position += 0.5f * l.range * glm::vec3(std::cos(angle), 0.0f, std::sin(angle));
    }
    l.color = glm::mix(glm::vec3(1.0f), Hue(Random(seed, i, 4)), 0.7f);
    l.intensity = 0.3f * l.range * l.range;
    lights.push_back(l);
  }
  return lights;
}

gpu::GpuLightBounds BoundLight(const Light& light, const glm::mat4& view, const glm::mat4& proj,
                               float znear, const TileGrid& grid) {
  gpu::GpuLightBounds b{};
  const glm::vec4 ws = WorldSphere(light);
  const glm::vec3 c = glm::vec3(view * glm::vec4(glm::vec3(ws), 1.0f));
  const float r = ws.w;
  b.sphere = glm::vec4(c, r);
  if (light.type == LightType::kSpot) {
    b.cone = glm::vec4(glm::vec3(view * glm::vec4(light.position, 1.0f)),
                       std::cos(light.outer_cone_angle));
    b.cone2 = glm::vec4(glm::normalize(glm::mat3(view) * light.direction), light.range);
  } else {
    b.cone = glm::vec4(0.0f, 0.0f, 0.0f, -2.0f);
  }
  const int tx_max = int(grid.tiles_x()) - 1, ty_max = int(grid.tiles_y()) - 1;
  const float depth_near = -c.z - r;  // nearest view depth of the sphere
  if (-c.z + r < znear) {             // entirely behind the near plane
    b.tiles = glm::ivec4(1, 1, 0, 0);
    return b;
  }
  if (depth_near <= znear) {  // crosses the near plane: projection unbounded
    b.tiles = glm::ivec4(0, 0, tx_max, ty_max);
    return b;
  }
  // Project the 8 corners of the sphere's view-space box (all in front of the near plane).
  float px0 = 1e30f, py0 = 1e30f, px1 = -1e30f, py1 = -1e30f;
  for (int k = 0; k < 8; ++k) {
    const glm::vec3 p =
        c + r * glm::vec3(k & 1 ? 1.0f : -1.0f, k & 2 ? 1.0f : -1.0f, k & 4 ? 1.0f : -1.0f);
    const float nx = proj[0][0] * p.x / -p.z, ny = proj[1][1] * p.y / -p.z;
    const float sx = (nx * 0.5f + 0.5f) * float(grid.width);
    const float sy = (ny * 0.5f + 0.5f) * float(grid.height);
    px0 = std::min(px0, sx);
    px1 = std::max(px1, sx);
    py0 = std::min(py0, sy);
    py1 = std::max(py1, sy);
  }
  // Clamped to just outside the frame before the integer conversion (huge spheres close to the
  // near plane project far outside it).
  const float w = float(grid.width), h = float(grid.height);
  px0 = std::clamp(px0, -1.0f, w + 1.0f);
  px1 = std::clamp(px1, -1.0f, w + 1.0f);
  py0 = std::clamp(py0, -1.0f, h + 1.0f);
  py1 = std::clamp(py1, -1.0f, h + 1.0f);
  const float ts = float(grid.tile_size);
  const int x0 = std::max(0, int(std::floor(px0 / ts))),
            x1 = std::min(tx_max, int(std::floor(px1 / ts)));
  const int y0 = std::max(0, int(std::floor(py0 / ts))),
            y1 = std::min(ty_max, int(std::floor(py1 / ts)));
  b.tiles = (x0 > x1 || y0 > y1) ? glm::ivec4(1, 1, 0, 0) : glm::ivec4(x0, y0, x1, y1);
  return b;
}

std::vector<uint32_t> BinLightsByRow(const std::vector<gpu::GpuLightBounds>& bounds,
                                     uint32_t rows) {
  // Counts per row, then each row's [begin, end) after the 2 * rows header entries.
  std::vector<uint32_t> count(rows, 0u);
  for (const gpu::GpuLightBounds& b : bounds)
    if (b.tiles.x <= b.tiles.z)
      for (int y = std::max(b.tiles.y, 0); y <= std::min(b.tiles.w, int(rows) - 1); ++y)
        ++count[y];
  std::vector<uint32_t> out(2 * size_t(rows));
  uint32_t offset = 2 * rows;
  for (uint32_t r = 0; r < rows; ++r) {
    out[2 * r] = offset;
    offset += count[r];
    out[2 * r + 1] = offset;
  }
  out.resize(offset);
  std::vector<uint32_t> fill(rows);
  for (uint32_t r = 0; r < rows; ++r) fill[r] = out[2 * r];
  for (uint32_t i = 0; i < bounds.size(); ++i) {
    const gpu::GpuLightBounds& b = bounds[i];
    if (b.tiles.x <= b.tiles.z)
      for (int y = std::max(b.tiles.y, 0); y <= std::min(b.tiles.w, int(rows) - 1); ++y)
        out[fill[y]++] = i;
  }
  return out;
}

std::vector<uint32_t> TileLightLists::List(uint32_t tile) const {
  const uint32_t n = std::min(counts[tile] & ~gpu::kTileOverflowBit, gpu::kMaxLightsPerTile);
  const auto* first = lights.data() + size_t(tile) * gpu::kMaxLightsPerTile;
  return std::vector<uint32_t>(first, first + n);
}

TileLightLists CullLightsReference(const std::vector<gpu::GpuLightBounds>& bounds,
                                   const std::vector<float>& depth, const glm::mat4& proj,
                                   const TileGrid& grid, float inflate) {
  TileLightLists out;
  out.grid = grid;
  out.counts.assign(grid.tiles(), 0u);
  out.lights.assign(size_t(grid.tiles()) * gpu::kMaxLightsPerTile, 0u);
  const float p22 = proj[2][2], p32 = proj[3][2];
  for (uint32_t ty = 0; ty < grid.tiles_y(); ++ty) {
    for (uint32_t tx = 0; tx < grid.tiles_x(); ++tx) {
      const uint32_t tile = ty * grid.tiles_x() + tx;
      const uint32_t px0 = tx * grid.tile_size, py0 = ty * grid.tile_size;
      const uint32_t px1 = std::min(px0 + grid.tile_size, grid.width);
      const uint32_t py1 = std::min(py0 + grid.tile_size, grid.height);
      float dmin = 1e30f, dmax = 0.0f;
      for (uint32_t y = py0; y < py1; ++y)
        for (uint32_t x = px0; x < px1; ++x) {
          const float d = depth[size_t(y) * grid.width + x];
          if (d <= 0.0f) continue;  // sky
          const float z = ViewDepth(d, p22, p32);
          dmin = std::min(dmin, z);
          dmax = std::max(dmax, z);
        }
      if (dmax <= 0.0f) continue;  // no surface: no lights
      const float scale = 32.0f / std::max(dmax - dmin, 1e-20f);
      uint32_t mask = 0;
      for (uint32_t y = py0; y < py1; ++y)
        for (uint32_t x = px0; x < px1; ++x) {
          const float d = depth[size_t(y) * grid.width + x];
          if (d <= 0.0f) continue;
          const float z = ViewDepth(d, p22, p32);
          mask |= 1u << uint32_t(std::min(31.0f, (z - dmin) * scale));
        }
      const TileFrustum f = MakeTileFrustum(proj, grid, tx, ty);
      // The tile's bounding sphere between dmin and dmax, for the spot-light cone test.
      glm::vec3 tc(0.0f);
      for (const glm::vec3& r : f.rays) tc += r * (0.5f * (dmin + dmax));
      tc *= 0.25f;
      float tr = 0.0f;
      for (const glm::vec3& r : f.rays)
        tr = std::max({tr, glm::length(r * dmin - tc), glm::length(r * dmax - tc)});
      uint32_t count = 0;
      for (uint32_t i = 0; i < bounds.size(); ++i) {
        const gpu::GpuLightBounds& b = bounds[i];
        if (int(tx) < b.tiles.x || int(tx) > b.tiles.z || int(ty) < b.tiles.y ||
            int(ty) > b.tiles.w)
          continue;
        const glm::vec3 c(b.sphere);
        const float r = b.sphere.w + inflate;
        const float zc = -c.z;
        if (zc + r < dmin || zc - r > dmax) continue;
        bool outside = false;
        for (const glm::vec3& n : f.planes) outside |= glm::dot(n, c) < -r;
        if (outside) continue;
        if ((SliceMask(zc - r, zc + r, dmin, scale) & mask) == 0u) continue;
        if (b.cone.w > -1.5f) {  // spot: Wronski's cone vs the tile's sphere
          const glm::vec3 v = tc - glm::vec3(b.cone);
          const float v_len2 = glm::dot(v, v);
          const float v1 = glm::dot(v, glm::vec3(b.cone2));
          const float cos_a = b.cone.w, sin_a = std::sqrt(std::max(0.0f, 1.0f - cos_a * cos_a));
          const float closest = cos_a * std::sqrt(std::max(0.0f, v_len2 - v1 * v1)) - v1 * sin_a;
          const float rad = tr + inflate;
          if (closest > rad || v1 > rad + b.cone2.w || v1 < -rad) continue;
        }
        if (count < gpu::kMaxLightsPerTile)
          out.lights[size_t(tile) * gpu::kMaxLightsPerTile + count] = i;
        ++count;
      }
      out.counts[tile] =
          count > gpu::kMaxLightsPerTile ? (gpu::kMaxLightsPerTile | gpu::kTileOverflowBit) : count;
    }
  }
  return out;
}

TileStats ComputeTileStats(const std::vector<uint32_t>& counts) {
  TileStats s;
  if (counts.empty()) return s;
  std::vector<uint32_t> n;
  n.reserve(counts.size());
  double sum = 0.0;
  for (uint32_t c : counts) {
    if (c & gpu::kTileOverflowBit) ++s.overflows;
    n.push_back(c & ~gpu::kTileOverflowBit);
    sum += n.back();
  }
  std::sort(n.begin(), n.end());
  s.average = sum / double(n.size());
  s.p50 = n[(n.size() - 1) / 2];
  s.p95 = n[std::min(n.size() - 1, size_t(std::ceil(0.95 * double(n.size()))) - 1)];
  s.max = n.back();
  return s;
}

}  // namespace tessera

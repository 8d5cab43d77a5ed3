#include "renderer/scene/adjacency.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "absl/hash/hash.h"

namespace tessera {
namespace {

// A position snapped to a grid of 2^-20 of the primitive's size: a seam's vertices computed
// apart (e.g. a sphere's at 0 and 2 pi) still meet. Two positions either side of a cell border
// stay apart: rare, and then the edge only has no neighbour.
using Point = std::array<int64_t, 3>;
struct EdgeKey {
  Point a, b;  // a < b
  bool operator==(const EdgeKey& o) const { return a == o.a && b == o.b; }
  template <typename H>
  friend H AbslHashValue(H h, const EdgeKey& k) {
    return H::combine(std::move(h), k.a, k.b);
  }
};

// The cell holding grid coordinates q.
Point Round(const glm::dvec3& q) {
  return {std::llround(q.x), std::llround(q.y), std::llround(q.z)};
}

Point Snap(const glm::vec3& p, const glm::dvec3& origin, double step) {
  return Round((glm::dvec3(p) - origin) / step);  // 0..2^20 within the primitive
}

// The index ranges to do (TriangleAdjacency's rule): a primitive's, once; one overlapping a range
// already done is skipped.
template <typename Fn>
void ForEachIndexRange(const CpuScene& scene, Fn&& fn) {
  std::vector<bool> claimed(scene.indices.size(), false);
  for (const Primitive& p : scene.primitives) {
    const uint32_t triangles = p.index_count / 3;
    if (triangles == 0 || uint64_t(p.first_index) + 3 * triangles > scene.indices.size()) continue;
    if (claimed[p.first_index]) continue;
    bool overlaps = false;
    for (uint32_t i = 0; i < 3 * triangles; ++i) overlaps = overlaps || claimed[p.first_index + i];
    if (overlaps) continue;
    for (uint32_t i = 0; i < 3 * triangles; ++i) claimed[p.first_index + i] = true;
    fn(p, triangles);
  }
}

// The grid of a primitive's positions (its lowest corner and cell size: 2^-20 of its extent).
struct Grid {
  glm::dvec3 lo;
  double step;
};
// `position(i)`: corner i's position, or null for none.
template <typename Position>
Grid GridOf(uint32_t corners, Position&& position) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (uint32_t i = 0; i < corners; ++i) {
    const glm::vec3* q = position(i);
    if (!q) continue;
    lo = glm::min(lo, glm::dvec3(*q));
    hi = glm::max(hi, glm::dvec3(*q));
  }
  if (lo.x > hi.x) return {glm::dvec3(0.0), 1.0};  // no corner
  const glm::dvec3 size = hi - lo;
  const double extent = std::max(size.x, std::max(size.y, size.z));
  return {lo, extent > 0.0 ? std::ldexp(extent, -20) : 1.0};
}

// Whether texture coordinates u and w (xy set 0, zw set 1) agree in the sets `sets` (kUvSeam*)
// names: within 1e-4 of a uv unit (relative past 1: a vertex written twice differs by rounding, a
// seam by texels), up to whole units where the set is periodic.
bool UvSeamSame(const glm::vec4& u, const glm::vec4& w, uint32_t sets) {
  for (int c = 0; c < 4; ++c) {
    const uint32_t set = c < 2 ? kUvSeamSet0 : kUvSeamSet1;
    const uint32_t periodic = c < 2 ? kUvSeamPeriodic0 : kUvSeamPeriodic1;
    if ((sets & set) == 0) continue;
    float d = u[c] - w[c];
    if (sets & periodic) d -= std::round(d);
    if (!(std::abs(d) <= 1e-4f * std::max(1.0f, std::abs(u[c])))) return false;
  }
  return true;
}

// The texture coordinate sets one or more materials' textures read, and those of them some
// texture reads without whole-unit periods (bit k: set k), as UvSeamSets' bits.
struct UvUse {
  uint32_t read = 0, aperiodic = 0;
  void Add(const Material& m, const std::vector<Texture>& textures) {
    for (const TextureRef* ref : m.TextureSlots()) {
      if (ref->texture < 0 || static_cast<size_t>(ref->texture) >= textures.size()) continue;
      const uint32_t set = 1u << std::min(ref->texcoord, 1u);
      read |= set;
      const Texture& t = textures[ref->texture];
      const glm::mat3 u = ref->uv_transform();
      bool periodic = t.wrap_s == WrapMode::kRepeat && t.wrap_t == WrapMode::kRepeat;
      for (int c = 0; c < 2; ++c)
        for (int r = 0; r < 2; ++r)
          periodic = periodic && std::abs(u[c][r] - std::round(u[c][r])) <= 1e-6f;
      if (!periodic) aperiodic |= set;
    }
  }
  uint32_t Sets() const {
    static_assert(kUvSeamSet0 == 1u && kUvSeamSet1 == 2u && kUvSeamPeriodic0 == kUvSeamSet0 << 2 &&
                  kUvSeamPeriodic1 == kUvSeamSet1 << 2);
    return read | (read & ~aperiodic) << 2;
  }
};

}  // namespace

uint32_t UvSeamSets(const Material& m, const std::vector<Texture>& textures) {
  UvUse use;
  use.Add(m, textures);
  return use.Sets();
}

std::vector<uint32_t> SurfaceIndices(const CpuScene& scene) {
  std::vector<uint32_t> out(scene.indices.begin(), scene.indices.end());
  // The sets compared for an index range: those of every material drawn with it (primitives
  // sharing a range: the same mesh with other materials), periodic where periodic for each.
  std::unordered_map<uint32_t, UvUse> range_use;  // by first index
  for (const Primitive& p : scene.primitives)
    if (p.material < scene.materials.size())
      range_use[p.first_index].Add(scene.materials[p.material], scene.textures);
  ForEachIndexRange(scene, [&](const Primitive& p, uint32_t triangles) {
    const uint32_t corners = 3 * triangles;
    auto vertex = [&](uint32_t v) -> const Vertex& { return scene.vertices[p.first_vertex + v]; };
    auto index = [&](uint32_t i) { return scene.indices[p.first_index + i]; };
    auto inside = [&](uint32_t v) {
      return v < p.vertex_count && uint64_t(p.first_vertex) + v < scene.vertices.size();
    };
    const Grid grid = GridOf(corners, [&](uint32_t i) -> const glm::vec3* {
      return inside(index(i)) ? &vertex(index(i)).position : nullptr;
    });
    const uint32_t sets = range_use[p.first_index].Sets();
    auto cell_of = [&](const glm::vec3& q) { return (glm::dvec3(q) - grid.lo) / grid.step; };
    // Per grid cell, the vertices standing for themselves there; per vertex, the one it stands
    // for (kNoNeighbour: not met yet).
    std::unordered_map<Point, std::vector<uint32_t>, absl::Hash<Point>> cells;
    cells.reserve(corners);
    std::vector<uint32_t> stands(p.vertex_count, kNoNeighbour);
    for (uint32_t i = 0; i < corners; ++i) {
      const uint32_t v = index(i);
      if (!inside(v)) continue;  // stands for itself
      if (stands[v] == kNoNeighbour) {
        const Vertex& a = vertex(v);
        const glm::vec3 n = glm::normalize(a.normal);
        const glm::vec4 uv(a.uv0, a.uv1);
        // The same position: within half a cell on each axis, so in the vertex's own cell or
        // the next one on the side of the cell's centre it lies (8 cells): a seam's vertices
        // computed apart (a sphere's at 0 and 2 pi) meet across a cell border too.
        const glm::dvec3 q = cell_of(a.position);
        const Point k = Round(q);
        for (int c = 0; c < 8 && stands[v] == kNoNeighbour; ++c) {
          Point probe = k;
          for (int axis = 0; axis < 3; ++axis)
            if (c & (1 << axis)) probe[axis] += q[axis] >= double(k[axis]) ? 1 : -1;
          const auto found = cells.find(probe);
          if (found == cells.end()) continue;
          for (uint32_t r : found->second) {
            const Vertex& b = vertex(r);
            const glm::dvec3 d = glm::abs(cell_of(b.position) - q);
            if (std::max(d.x, std::max(d.y, d.z)) <= 0.5 &&
                glm::dot(n, glm::normalize(b.normal)) > 0.99f && a.color == b.color &&
                UvSeamSame(uv, glm::vec4(b.uv0, b.uv1), sets)) {
              stands[v] = r;
              break;
            }
          }
        }
        if (stands[v] == kNoNeighbour) {
          stands[v] = v;
          cells[k].push_back(v);
        }
      }
      out[p.first_index + i] = stands[v];
    }
  });
  return out;
}

std::vector<uint32_t> TriangleAdjacency(const CpuScene& scene) {
  std::vector<uint32_t> adjacency(scene.indices.size(), kNoNeighbour);
  // An index range is done once: primitives sharing one (the same mesh with other materials)
  // share its answer, and one overlapping a range already done is left without neighbours
  // rather than given triangle numbers counted from another first index.
  ForEachIndexRange(scene, [&](const Primitive& p, uint32_t triangles) {
    auto position = [&](uint32_t i) -> const glm::vec3& {
      return scene.vertices[p.first_vertex + scene.indices[p.first_index + i]].position;
    };
    const Grid grid = GridOf(3 * triangles, [&](uint32_t i) { return &position(i); });
    const glm::dvec3 lo = grid.lo;
    const double step = grid.step;
    // A map per primitive, sized for it (clearing one shared map costs its largest bucket array
    // again for every later primitive).
    std::unordered_map<EdgeKey, uint32_t, absl::Hash<EdgeKey>> first;  // edge -> 3t + e
    first.reserve(3 * size_t(triangles));
    for (uint32_t t = 0; t < triangles; ++t) {
      for (uint32_t e = 0; e < 3; ++e) {
        const Point a = Snap(position(3 * t + e), lo, step);
        const Point b = Snap(position(3 * t + (e + 1) % 3), lo, step);
        if (a == b) continue;
        const EdgeKey key = a < b ? EdgeKey{a, b} : EdgeKey{b, a};
        const auto [it, inserted] = first.try_emplace(key, 3 * t + e);
        if (inserted) continue;
        const uint32_t other = it->second;
        if (other / 3 == t) continue;  // a triangle folded onto its own edge
        uint32_t& back = adjacency[p.first_index + other];
        if (back == kNoNeighbour) back = t;
        adjacency[p.first_index + 3 * t + e] = other / 3;
      }
    }
  });
  return adjacency;
}

}  // namespace tessera

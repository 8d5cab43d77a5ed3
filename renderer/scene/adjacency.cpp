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

Point Snap(const glm::vec3& p, const glm::dvec3& origin, double step) {
  const glm::dvec3 q = (glm::dvec3(p) - origin) / step;  // 0..2^20 within the primitive
  return {std::llround(q.x), std::llround(q.y), std::llround(q.z)};
}

}  // namespace

std::vector<uint32_t> TriangleAdjacency(const CpuScene& scene) {
  std::vector<uint32_t> adjacency(scene.indices.size(), kNoNeighbour);
  // An index range is done once: primitives sharing one (the same mesh with other materials)
  // share its answer, and one overlapping a range already done is left without neighbours
  // rather than given triangle numbers counted from another first index.
  std::vector<bool> claimed(scene.indices.size(), false);
  for (const Primitive& p : scene.primitives) {
    const uint32_t triangles = p.index_count / 3;
    if (triangles == 0 || uint64_t(p.first_index) + 3 * triangles > scene.indices.size()) continue;
    if (claimed[p.first_index]) continue;
    bool overlaps = false;
    for (uint32_t i = 0; i < 3 * triangles; ++i) overlaps = overlaps || claimed[p.first_index + i];
    if (overlaps) continue;
    for (uint32_t i = 0; i < 3 * triangles; ++i) claimed[p.first_index + i] = true;
    auto position = [&](uint32_t i) -> const glm::vec3& {
      return scene.vertices[p.first_vertex + scene.indices[p.first_index + i]].position;
    };
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (uint32_t i = 0; i < 3 * triangles; ++i) {
      lo = glm::min(lo, glm::dvec3(position(i)));
      hi = glm::max(hi, glm::dvec3(position(i)));
    }
    const glm::dvec3 size = hi - lo;
    const double extent = std::max(size.x, std::max(size.y, size.z));
    const double step = extent > 0.0 ? std::ldexp(extent, -20) : 1.0;
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
  }
  return adjacency;
}

}  // namespace tessera

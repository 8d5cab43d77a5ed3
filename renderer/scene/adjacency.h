#pragma once
// Triangle adjacency across shared edges, for vis_mlaa_coverage analytic: its resolve tests the
// triangles next to the ones the pixels nearby show, so the thin triangles of a curved
// silhouette and the slivers of a fan, which no pixel centre shows, are still found.
#include <cstdint>
#include <vector>

#include "renderer/scene/cpu_scene.h"

namespace tessera {

inline constexpr uint32_t kNoNeighbour = 0xffffffffu;

// One entry per index of scene.indices: for index 3t + e of a primitive (t its triangle, counted
// from the primitive's first index), the primitive's other triangle sharing the edge from corner
// e to corner (e + 1) % 3, or kNoNeighbour. Edges are matched by their ends' positions, so a
// seam that splits vertices (normals, texture coordinates) still joins; where more than two
// triangles share an edge each is given one of the others. Degenerate edges have none.
// Primitives sharing an index range share its answer; a range that overlaps one already done
// without being it gets none.
std::vector<uint32_t> TriangleAdjacency(const CpuScene& scene);

}  // namespace tessera

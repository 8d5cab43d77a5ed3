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

// For vis_mlaa's surface test (SurfaceIndices below): the texture coordinate sets a material's
// textures read (kUvSeamSet0/1), and for each whether every texture reading it wraps REPEAT on
// both axes through a transform that maps whole uv steps to whole texel-grid periods (integer
// linear part: kUvSeamPeriodic0/1), so vertices whose coordinates differ by whole units sample
// the same texels. Untextured: 0 (no set compared).
inline constexpr uint32_t kUvSeamSet0 = 1u, kUvSeamSet1 = 2u;
inline constexpr uint32_t kUvSeamPeriodic0 = 4u, kUvSeamPeriodic1 = 8u;
uint32_t UvSeamSets(const Material& m, const std::vector<Texture>& textures);

// For vis_mlaa's surface test (common/vis_resolve.glsl, SameSurface: two triangles of a
// drawable are on one surface where they share a vertex): one entry per index of scene.indices,
// the primitive's vertex (numbered as its indices are) that stands for that index's vertex: the
// first of the primitive's vertices met in index order that stands for itself, is at the same
// position (within half a cell of TriangleAdjacency's grid, 2^-20 of the primitive's size, on
// each axis), has a normal within 8.1 degrees (dot > 0.99), the same vertex colour, and texture
// coordinates that agree, within 1e-4 (relative past 1 uv unit), in the sets UvSeamSets names (up
// to whole units where they repeat). So vertices split for a hard edge, a colour edge or a
// texture seam stand apart, and those split
// for nothing (or for a set no texture reads) stand for one another. Index ranges as
// TriangleAdjacency's; primitives sharing one (the same mesh with other materials) compare the
// sets any of their materials reads (periodic where periodic for all). Posed (skinned or
// morphed) vertices keep the answer for their rest positions. An index past its primitive's
// vertices stands for itself.
std::vector<uint32_t> SurfaceIndices(const CpuScene& scene);

}  // namespace tessera

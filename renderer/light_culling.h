#pragma once
// Forward+ light culling on the CPU side: synthetic lights, the per-light bounds the culling
// pass reads (each light projected once), the tile frustum, and a CPU reference of the whole
// per-tile culling that the GPU pass (shaders/light_cull.comp) must agree with.
//
// The tile test, in order: the light's tile rectangle; the tile's depth bounds (min/max view
// depth of the prepass over the tile, sky pixels ignored); the four side planes of the tile
// frustum, built from all four tile corners; the tile's 2.5D depth mask (32 slices between min
// and max depth, a bit per slice that holds a surface); for spots, the cone against the tile's
// bounding sphere. Every test is conservative: a light that lights any pixel of the tile stays.
#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <vector>

#include "renderer/scene/cpu_scene.h"
#include "shaders/common/gpu_types.h"

namespace tessera {

struct SyntheticLightParams {
  uint32_t count = 0;
  uint32_t seed = 1;
  float radius_min = 0.0f;  // world units; 0: 1% of the bounds' diagonal
  float radius_max = 0.0f;  // 0: 4% of the diagonal (at least radius_min)
  bool animated = false;    // each light circles its place, radius half its range
  float time = 0.0f;        // seconds
};

// Point lights inside `bounds`, a deterministic function of (bounds, params): light i is the
// same whatever the count. Random ranges in [radius_min, radius_max], random hues, intensity
// proportional to range^2 so each light makes a pool of similar brightness.
std::vector<Light> MakeSyntheticLights(const Aabb& bounds, const SyntheticLightParams& params);

struct TileGrid {
  uint32_t width = 0, height = 0, tile_size = 16;
  uint32_t tiles_x() const { return (width + tile_size - 1) / tile_size; }
  uint32_t tiles_y() const { return (height + tile_size - 1) / tile_size; }
  uint32_t tiles() const { return tiles_x() * tiles_y(); }
};

// The bounds of a point or spot light for the culling pass (view space; tile rectangle from
// the projected bounding box of the light's sphere, the whole grid when it crosses the near
// plane). `proj` is symmetric (renderer/camera.h).
gpu::GpuLightBounds BoundLight(const Light& light, const glm::mat4& view, const glm::mat4& proj,
                               float znear, const TileGrid& grid);

// The lights binned by tile row, in index order, as shaders/light_cull.comp reads them:
// row r's lights are [out[2r], out[2r + 1]) of the same array (light_bins.comp makes the same
// lists on the GPU, each row at 2 * rows + r * lights).
std::vector<uint32_t> BinLightsByRow(const std::vector<gpu::GpuLightBounds>& bounds, uint32_t rows);

// View depth (distance along -Z) of a depth-buffer value, from the projection: reverse Z with a
// finite or infinite far plane. depth_params as in FrameUniforms (x: proj[2][2], y: proj[3][2]).
inline float ViewDepth(float d, float p22, float p32) { return p32 / (d + p22); }

// The per-tile lists the GPU builds, for tests and statistics.
struct TileLightLists {
  TileGrid grid;
  std::vector<uint32_t> counts;  // per tile, may include kTileOverflowBit
  std::vector<uint32_t> lights;  // tile * kMaxLightsPerTile + k
  std::vector<uint32_t> List(uint32_t tile) const;
};

// The same culling as shaders/light_cull.comp. `depth` is the prepass depth buffer (row-major,
// width x height); `inflate` grows (> 0) or shrinks (< 0) every light by that many view-space
// units, so tests can bracket the GPU result against floating-point differences at the edges.
TileLightLists CullLightsReference(const std::vector<gpu::GpuLightBounds>& bounds,
                                   const std::vector<float>& depth, const glm::mat4& proj,
                                   const TileGrid& grid, float inflate = 0.0f);

// Lights-per-tile statistics over all tiles (tiles of sky count as 0).
struct TileStats {
  double average = 0.0;
  uint32_t p50 = 0, p95 = 0, max = 0;
  uint32_t overflows = 0;  // tiles that had more than kMaxLightsPerTile lights
};
TileStats ComputeTileStats(const std::vector<uint32_t>& counts);

}  // namespace tessera

#pragma once
// A generated city, for occlusion-culling tests and benchmarks: a grid of blocks of box
// buildings separated by streets. At street level almost everything is hidden behind the
// first row of buildings, so the scene separates frustum culling from occlusion culling.
#include <cstdint>

#include "renderer/scene/cpu_scene.h"

namespace tessera {

struct CityParams {
  uint32_t blocks_x = 10, blocks_z = 10;  // city blocks in a grid, separated by streets
  uint32_t buildings_per_side = 10;       // each block holds buildings_per_side^2 buildings
  uint32_t facade_detail = 2;  // each building side is a facade_detail x (facade_detail*2) grid
                               // of quads (more triangles per building)
  uint32_t seed = 1;           // heights/colours/variants, deterministic
};

// A city of box buildings on a ground grid, for occlusion culling: at street level almost
// everything is hidden behind the first row of buildings. Deterministic for equal params (the
// same bytes every call, on every platform: an integer hash, no std distributions).
//
// Layout (metres, +Y up, the city centred on the origin in x and z): each building stands on a
// 10 m x 10 m lot, blocks are buildings_per_side lots square, and 16 m streets run between the
// blocks and around the city edge. Buildings are 7-9 m wide and 8-60 m tall (taller towards
// the centre). Every building is one drawable: a unit building mesh (one of four variants:
// two facade tessellations with flat roofs, a hip roof, a gable roof) scaled into place.
// Counts and detail of 0 are treated as 1 (any seed is fine).
//
// Drawables, in this order: one ground quad per block and per street segment / crossing
// ((2*blocks_x+1) * (2*blocks_z+1)), the buildings (block by block), rooftop signs (a
// double-sided material), and glass canopies over some street crossings (the only
// alpha-blended drawables, at most 64). Cameras: "street", at eye height at the city edge,
// looking down the middle street. Lights: one sun.
CpuScene BuildCityScene(const CityParams& params = {});

// Where the streets are, for camera paths: centre x (or z) of street i between blocks, i in
// 0..blocks (inclusive, streets also run around the city edge). Street i runs between block
// i-1 and block i.
float CityStreetX(const CityParams& p, uint32_t i);
float CityStreetZ(const CityParams& p, uint32_t i);

}  // namespace tessera

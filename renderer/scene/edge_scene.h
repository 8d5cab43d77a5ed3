#pragma once
// A synthetic anti-aliasing test scene with known coverage: white shapes on a black background,
// facing the camera, laid out so that one world unit maps to a fixed number of pixels at the
// scene's render size. Each shape is a convex polygon whose exact coverage of every pixel is
// computed analytically (polygon clipping), so a renderer's AA can be scored per pixel.
//
// Contents: 91 cells, each holding a half-plane edge through the cell centre rotated
// 0, 1, ..., 90 degrees (the cell is filled on one side of the edge), and a row of thin wires
// (long rectangles 0.25 to 1.5 pixels wide at several angles). Cell borders lie on pixel
// boundaries, so only the rotated edges and the wires need anti-aliasing.
#include <cstdint>
#include <vector>

#include <glm/glm.hpp>

#include "renderer/scene/cpu_scene.h"

namespace tessera {

struct EdgeSceneParams {
  uint32_t cell = 24;  // cell size in pixels (>= 8)
  uint32_t gap = 8;    // background between cells, pixels
};

struct PixelPoint {
  double x = 0.0, y = 0.0;  // pixels: x right, y down, (0,0) the top-left corner of the image
};

struct EdgeScene {
  CpuScene scene;  // drawables: the background quad, then one per shape (in `shapes` order)
  // The camera the layout is made for: looking down -Z from `eye` at `target`, vertical field
  // of view `yfov` (radians), near plane `znear`; render at width x height.
  glm::vec3 eye{0.0f}, target{0.0f, 0.0f, -1.0f};
  float yfov = 0.5f;
  float znear = 0.1f;
  uint32_t width = 0, height = 0;
  std::vector<std::vector<PixelPoint>> shapes;  // convex polygons in pixel coordinates
  std::vector<float> coverage;  // width * height, row-major: the white area of each pixel
};

// Deterministic for equal params. Materials: white (base colour 1) for the shapes, black (0)
// for the background; render with the base-colour debug view so a pixel's linear value is its
// coverage.
EdgeScene BuildEdgeScene(const EdgeSceneParams& params = {});

// Area of the intersection of a convex polygon (either winding) with the unit pixel square
// [px, px+1] x [py, py+1].
double PolygonPixelCoverage(const std::vector<PixelPoint>& polygon, int px, int py);

}  // namespace tessera

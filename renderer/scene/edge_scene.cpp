// The synthetic anti-aliasing scene (see edge_scene.h). Everything is laid out in pixels first
// (convex polygons, exact coverage by clipping), then mapped onto a plane facing the camera at
// a scale where the perspective projection puts every polygon vertex back on its pixel
// coordinates. Doubles throughout the layout; only the vertex buffer is float.
//
// Layout at the default params (cell 24, gap 8): a 424 x 264 image, `gap` pixels of background
// around and between all cells.
//   Rows 0-6: 13 x 7 = 91 square half-plane cells, cell k (row-major) holds the edge at k
//     degrees: the cell square on one side of a line through (cell centre + (0.3, 0.3)) rising
//     k degrees counter-clockwise on screen from the horizontal. The covered side is the one
//     the normal (sin k, cos k) (pixel coordinates, y down) points into: below the edge at 0
//     degrees, below-right at 45, right at 90 -- cell k is cell 0 turned k degrees about the
//     point. The 0.3 px offset keeps the 0 and 90 degree edges off pixel boundaries.
//   Row 7: kWires.size() = 8 wire cells, `cell` px tall and as wide as fits in the row (44 px
//     at the defaults, any remainder of the division on the right), each holding one straight
//     wire through (cell centre + (0.3, 0.3)) cut off by the cell border (the strip of its
//     width intersected with the cell).
// Every polygon in `shapes` runs counter-clockwise as seen on screen (a negative shoelace area
// in y-down pixel coordinates), which is counter-clockwise seen from the camera in the world:
// the glTF front face. A cell smaller than 8 px is treated as 8. The scene also carries the
// layout's camera as scene camera 0 (aspect width / height, infinite far plane).
#include "renderer/scene/edge_scene.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <glm/glm.hpp>
#include <string>
#include <utility>
#include <vector>

namespace tessera {
namespace {

constexpr uint32_t kColumns = 13;
constexpr uint32_t kHalfPlaneRows = 7;
constexpr uint32_t kHalfPlanes = 91;  // 0..90 degrees
static_assert(kColumns * kHalfPlaneRows == kHalfPlanes);
constexpr uint32_t kMinCell = 8;          // leaves room for the 0.3 px offset and 1.5 px wires
constexpr double kEdgeOffset = 0.3;       // pixels, along x and y from the cell centre
constexpr double kShapeDepth = 10.0;      // D: the shapes lie on z = -D
constexpr double kBackgroundScale = 4.0;  // the background is this many times the view's size

// The wires: every width appears at two angles and every angle at two widths, so a thin wire
// and a thick one are seen both near horizontal (3: long stair steps, the hardest case for
// post-process AA) and at the other angles.
struct Wire {
  double width;  // pixels, across the wire
  int degrees;   // counter-clockwise on screen from the horizontal
};
constexpr std::array<Wire, 8> kWires = {{
    {0.25, 3},
    {0.5, 20},
    {1.0, 45},
    {1.5, 70},
    {0.25, 45},
    {0.5, 70},
    {1.0, 3},
    {1.5, 20},
}};

using Polygon = std::vector<PixelPoint>;

struct Layout {
  uint32_t cell, gap;
  uint32_t width, height;
  uint32_t wire_width;  // width of a wire cell (they are `cell` tall)
};

Layout MakeLayout(const EdgeSceneParams& p) {
  Layout l;
  l.cell = std::max(p.cell, kMinCell);
  l.gap = p.gap;
  l.width = kColumns * (l.cell + l.gap) + l.gap;
  l.height = (kHalfPlaneRows + 1) * (l.cell + l.gap) + l.gap;
  const uint32_t wires = static_cast<uint32_t>(kWires.size());
  l.wire_width = (l.width - (wires + 1) * l.gap) / wires;
  return l;
}

// sin and cos of whole degrees, exact at multiples of 90 so the 0 and 90 degree edges are
// exactly axis-aligned.
std::pair<double, double> SinCosDegrees(int degrees) {
  switch (((degrees % 360) + 360) % 360) {
    case 0:
      return {0.0, 1.0};
    case 90:
      return {1.0, 0.0};
    case 180:
      return {0.0, -1.0};
    case 270:
      return {-1.0, 0.0};
    default: {
      const double r = degrees * (3.14159265358979323846 / 180.0);
      return {std::sin(r), std::cos(r)};
    }
  }
}

// Sutherland-Hodgman against one half-plane: keeps the part of a convex polygon where
// a*x + b*y + c >= 0. The winding is kept; consecutive duplicate points are dropped.
Polygon ClipHalfPlane(const Polygon& poly, double a, double b, double c) {
  Polygon out;
  const size_t n = poly.size();
  out.reserve(n + 1);
  auto push = [&out](PixelPoint p) {
    if (out.empty() || std::abs(out.back().x - p.x) > 1e-12 || std::abs(out.back().y - p.y) > 1e-12)
      out.push_back(p);
  };
  for (size_t i = 0; i < n; ++i) {
    const PixelPoint& p = poly[i];
    const PixelPoint& q = poly[(i + 1) % n];
    const double fp = a * p.x + b * p.y + c, fq = a * q.x + b * q.y + c;
    if (fp >= 0.0) push(p);
    if ((fp >= 0.0) != (fq >= 0.0)) {
      const double t = fp / (fp - fq);
      push({p.x + t * (q.x - p.x), p.y + t * (q.y - p.y)});
    }
  }
  while (out.size() > 1 && std::abs(out.front().x - out.back().x) <= 1e-12 &&
         std::abs(out.front().y - out.back().y) <= 1e-12)
    out.pop_back();
  return out;
}

// Shoelace in pixel coordinates (y down): negative for polygons that run counter-clockwise
// on screen.
double SignedArea(const Polygon& poly) {
  double sum = 0.0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const PixelPoint& p = poly[i];
    const PixelPoint& q = poly[(i + 1) % poly.size()];
    sum += p.x * q.y - q.x * p.y;
  }
  return 0.5 * sum;
}

// The rectangle [x, x + w] x [y, y + h], counter-clockwise on screen (top-left, bottom-left,
// bottom-right, top-right), so every shape clipped from it is too.
Polygon Rect(double x, double y, double w, double h) {
  return {{x, y}, {x, y + h}, {x + w, y + h}, {x + w, y}};
}

// Half-plane cell k: the part of the cell on the (sin k, cos k) side of the edge.
Polygon HalfPlaneShape(const Layout& l, uint32_t k) {
  const double x0 = l.gap + double(k % kColumns) * (l.cell + l.gap);
  const double y0 = l.gap + double(k / kColumns) * (l.cell + l.gap);
  const double px = x0 + 0.5 * l.cell + kEdgeOffset, py = y0 + 0.5 * l.cell + kEdgeOffset;
  const auto [s, c] = SinCosDegrees(static_cast<int>(k));
  // n . (p - P) >= 0 with n = (s, c).
  return ClipHalfPlane(Rect(x0, y0, l.cell, l.cell), s, c, -(s * px + c * py));
}

// Wire i: the cell intersected with the strip |n . (p - C)| <= width / 2.
Polygon WireShape(const Layout& l, uint32_t i) {
  const double x0 = l.gap + double(i) * (l.wire_width + l.gap);
  const double y0 = l.gap + double(kHalfPlaneRows) * (l.cell + l.gap);
  const double cx = x0 + 0.5 * l.wire_width + kEdgeOffset, cy = y0 + 0.5 * l.cell + kEdgeOffset;
  const auto [s, c] = SinCosDegrees(kWires[i].degrees);
  const double half = 0.5 * kWires[i].width, d = s * cx + c * cy;
  Polygon poly = Rect(x0, y0, l.wire_width, l.cell);
  poly = ClipHalfPlane(poly, s, c, half - d);    // n . p >= d - half
  return ClipHalfPlane(poly, -s, -c, half + d);  // n . p <= d + half
}

std::string DegreesName(const char* what, double value, int degrees) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%s %g px %d deg", what, value, degrees);
  return buf;
}

// Pixel space -> the world, on the plane z = z.
struct PixelToWorld {
  double width, height, scale;  // world units per pixel on the shape plane
  glm::vec3 operator()(double x, double y, double z) const {
    return glm::vec3(float((x - 0.5 * width) * scale), float((0.5 * height - y) * scale), float(z));
  }
};

uint32_t AddMaterial(CpuScene& scene, const std::string& name, glm::vec4 base) {
  Material m;
  m.name = name;
  m.base_color_factor = base;
  m.metallic_factor = 0.0f;
  m.roughness_factor = 1.0f;
  // Single-sided: every polygon is wound counter-clockwise as seen from the camera (the glTF
  // front face), so back-face culling keeps them all.
  m.double_sided = false;
  scene.materials.push_back(std::move(m));
  return static_cast<uint32_t>(scene.materials.size() - 1);
}

// A flat convex polygon facing +Z (towards the camera) as one mesh with one primitive, drawn
// once with the identity transform. `points` run counter-clockwise seen from +Z; the fan
// (0, i, i + 1) keeps that winding.
void AddFlatPolygon(CpuScene& scene, const std::string& name, const std::vector<glm::vec3>& points,
                    const std::vector<glm::vec2>& uvs, uint32_t material) {
  Primitive prim;
  prim.first_vertex = static_cast<uint32_t>(scene.vertices.size());
  prim.first_index = static_cast<uint32_t>(scene.indices.size());
  prim.material = material;
  for (size_t i = 0; i < points.size(); ++i) {
    Vertex v;
    v.position = points[i];
    v.normal = glm::vec3(0.0f, 0.0f, 1.0f);
    v.tangent = glm::vec4(1.0f, 0.0f, 0.0f, 1.0f);  // uv.x grows right, uv.y grows down
    v.uv0 = uvs[i];
    v.uv1 = uvs[i];
    scene.vertices.push_back(v);
    prim.bounds.extend(points[i]);
  }
  prim.vertex_count = static_cast<uint32_t>(points.size());
  for (uint32_t i = 1; i + 1 < prim.vertex_count; ++i)
    scene.indices.insert(scene.indices.end(), {0u, i, i + 1});
  prim.index_count = static_cast<uint32_t>(scene.indices.size()) - prim.first_index;

  const uint32_t prim_index = static_cast<uint32_t>(scene.primitives.size());
  scene.primitives.push_back(prim);
  Mesh mesh;
  mesh.name = name;
  mesh.primitives.push_back(prim_index);
  scene.meshes.push_back(std::move(mesh));
  Drawable d;
  d.primitive = prim_index;
  d.mesh = static_cast<uint32_t>(scene.meshes.size() - 1);
  d.node = static_cast<uint32_t>(scene.drawables.size());
  d.world_bounds = prim.bounds;  // identity transform
  scene.drawables.push_back(d);
}

}  // namespace

double PolygonPixelCoverage(const std::vector<PixelPoint>& polygon, int px, int py) {
  if (polygon.size() < 3) return 0.0;
  const double x0 = px, y0 = py;
  Polygon p = ClipHalfPlane(polygon, 1.0, 0.0, -x0);             // x >= px
  if (p.size() >= 3) p = ClipHalfPlane(p, -1.0, 0.0, x0 + 1.0);  // x <= px + 1
  if (p.size() >= 3) p = ClipHalfPlane(p, 0.0, 1.0, -y0);        // y >= py
  if (p.size() >= 3) p = ClipHalfPlane(p, 0.0, -1.0, y0 + 1.0);  // y <= py + 1
  if (p.size() < 3) return 0.0;
  return std::min(std::abs(SignedArea(p)), 1.0);
}

EdgeScene BuildEdgeScene(const EdgeSceneParams& params) {
  const Layout l = MakeLayout(params);
  EdgeScene out;
  out.width = l.width;
  out.height = l.height;
  CpuScene& scene = out.scene;
  scene.name = "edges";

  // Shapes, in drawable order: the half-planes by angle, then the wires.
  out.shapes.reserve(kHalfPlanes + kWires.size());
  std::vector<std::string> names;
  for (uint32_t k = 0; k < kHalfPlanes; ++k) {
    out.shapes.push_back(HalfPlaneShape(l, k));
    names.push_back("half-plane " + std::to_string(k) + " deg");
  }
  for (uint32_t i = 0; i < kWires.size(); ++i) {
    out.shapes.push_back(WireShape(l, i));
    names.push_back(DegreesName("wire", kWires[i].width, kWires[i].degrees));
  }

  // Pixel (x, y) on the plane z = -D maps to world ((x - W/2) s, (H/2 - y) s): the projection
  // of ProjectionMatrix (x_ndc = f x / (aspect D), y_ndc = -f y / D with f = 1 / tan(yfov/2),
  // aspect = W/H) followed by the viewport (ndc -1..1 -> pixel 0..W, y down) takes it back to
  // (x, y) exactly when s = 2 D tan(yfov/2) / H.
  const double tan_half = std::tan(0.5 * double(out.yfov));
  const PixelToWorld to_world{double(l.width), double(l.height),
                              2.0 * kShapeDepth * tan_half / double(l.height)};

  const uint32_t white = AddMaterial(scene, "white", glm::vec4(1.0f));
  const uint32_t black = AddMaterial(scene, "black", glm::vec4(0.0f, 0.0f, 0.0f, 1.0f));

  // The background: at twice the depth it would need to be twice the size to fill the view;
  // kBackgroundScale times more than that covers other aspect ratios and camera tweaks too.
  {
    const double mx = 0.5 * l.width * kBackgroundScale, my = 0.5 * l.height * kBackgroundScale;
    const double depth = 2.0 * kShapeDepth;
    // The pixel mapping scaled by 2 about the image centre lands on the same view rays at 2D.
    const PixelToWorld far{to_world.width, to_world.height, to_world.scale * 2.0};
    std::vector<glm::vec3> points;
    std::vector<glm::vec2> uvs;
    for (const PixelPoint& p : Rect(0.5 * l.width - mx, 0.5 * l.height - my, 2 * mx, 2 * my)) {
      points.push_back(far(p.x, p.y, -depth));
      uvs.emplace_back(float(p.x / l.width), float(p.y / l.height));
    }
    AddFlatPolygon(scene, "background", points, uvs, black);
  }
  for (size_t i = 0; i < out.shapes.size(); ++i) {
    std::vector<glm::vec3> points;
    std::vector<glm::vec2> uvs;
    for (const PixelPoint& p : out.shapes[i]) {
      points.push_back(to_world(p.x, p.y, -kShapeDepth));
      uvs.emplace_back(float(p.x / l.width), float(p.y / l.height));
    }
    AddFlatPolygon(scene, names[i], points, uvs, white);
  }
  for (const Drawable& d : scene.drawables) scene.bounds.extend(d.world_bounds);

  // The camera the layout is made for, so clients can select it as scene camera 0.
  SceneCamera cam;
  cam.name = "edges";
  cam.world = glm::mat4(1.0f);  // at the origin looking down -Z, +Y up (out.eye, out.target)
  cam.yfov = out.yfov;
  cam.aspect = float(l.width) / float(l.height);
  cam.znear = out.znear;
  cam.zfar = 0.0f;
  scene.cameras.push_back(cam);

  // Coverage: shapes never share a pixel (cells are apart and on pixel boundaries), so the sum
  // is at most 1 up to rounding; the clamp only guards that.
  std::vector<double> sum(size_t{l.width} * l.height, 0.0);
  for (const Polygon& poly : out.shapes) {
    double min_x = poly[0].x, max_x = poly[0].x, min_y = poly[0].y, max_y = poly[0].y;
    for (const PixelPoint& p : poly) {
      min_x = std::min(min_x, p.x);
      max_x = std::max(max_x, p.x);
      min_y = std::min(min_y, p.y);
      max_y = std::max(max_y, p.y);
    }
    const int x_begin = std::max(0, int(std::floor(min_x)));
    const int x_end = std::min(int(l.width), int(std::ceil(max_x)));
    const int y_begin = std::max(0, int(std::floor(min_y)));
    const int y_end = std::min(int(l.height), int(std::ceil(max_y)));
    for (int y = y_begin; y < y_end; ++y)
      for (int x = x_begin; x < x_end; ++x)
        sum[size_t(y) * l.width + size_t(x)] += PolygonPixelCoverage(poly, x, y);
  }
  out.coverage.resize(sum.size());
  for (size_t i = 0; i < sum.size(); ++i) out.coverage[i] = float(std::clamp(sum[i], 0.0, 1.0));

  CountGeneratedScene(scene);
  return out;
}

}  // namespace tessera

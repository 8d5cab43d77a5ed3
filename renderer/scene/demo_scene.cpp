#include "renderer/scene/demo_scene.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <glm/gtc/constants.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace tessera {
namespace {

constexpr float kPi = glm::pi<float>();
constexpr float kTwoPi = 2.0f * glm::pi<float>();

// Every texture is the same size: the renderer groups textures into sampler-array buckets by
// size and colour space, so one size keeps the demo at two buckets.
constexpr uint32_t kTexSize = 256;

// ---- geometry ------------------------------------------------------------------------------

// A point of a parametric surface. The directions need not be normalized (and du may even be
// a limit direction, as at a sphere's poles); only their orientation matters.
struct SurfacePoint {
  glm::vec3 position;
  glm::vec3 normal;
  glm::vec3 du;  // direction in which uv.x grows
  glm::vec3 dv;  // direction in which uv.y grows
  glm::vec2 uv;
};

using SurfaceFn = std::function<SurfacePoint(float s, float t)>;

// Appends geometry to the scene buffers and returns the primitive describing it.
class MeshBuilder {
 public:
  explicit MeshBuilder(CpuScene* scene) : scene_(scene) {}

  // Tessellates a surface over s, t in [0, 1] into nu x nv quads and appends it as one
  // primitive (not yet added to the scene).
  Primitive AddSurface(const SurfaceFn& fn, uint32_t nu, uint32_t nv, uint32_t material) {
    Primitive prim;
    prim.first_vertex = static_cast<uint32_t>(scene_->vertices.size());
    prim.first_index = static_cast<uint32_t>(scene_->indices.size());
    prim.material = material;
    for (uint32_t j = 0; j <= nv; ++j) {
      for (uint32_t i = 0; i <= nu; ++i) {
        const SurfacePoint p = fn(float(i) / float(nu), float(j) / float(nv));
        scene_->vertices.push_back(MakeVertex(p));
        prim.bounds.extend(p.position);
      }
    }
    prim.vertex_count = static_cast<uint32_t>(scene_->vertices.size()) - prim.first_vertex;
    const uint32_t row = nu + 1;
    for (uint32_t j = 0; j < nv; ++j) {
      for (uint32_t i = 0; i < nu; ++i) {
        const uint32_t a = j * row + i, b = a + 1, c = a + row, d = c + 1;
        AddTriangle(prim, a, b, d);
        AddTriangle(prim, a, d, c);
      }
    }
    prim.index_count = static_cast<uint32_t>(scene_->indices.size()) - prim.first_index;
    return prim;
  }

 private:
  static Vertex MakeVertex(const SurfacePoint& p) {
    Vertex v;
    v.position = p.position;
    v.normal = glm::normalize(p.normal);
    // Gram-Schmidt so the tangent is exactly orthogonal to the normal.
    const glm::vec3 t = glm::normalize(p.du - v.normal * glm::dot(v.normal, p.du));
    // glTF: bitangent = cross(N, T) * w, and it points "up" in the image, i.e. towards
    // decreasing v (the first image row is v = 0).
    const float w = glm::dot(glm::cross(v.normal, t), -p.dv) < 0.0f ? -1.0f : 1.0f;
    v.tangent = glm::vec4(t, w);
    v.uv0 = p.uv;
    v.uv1 = p.uv;
    return v;
  }

  // Winds each triangle counter-clockwise as seen from its normals' side (glTF front face)
  // and drops the zero-area triangles that pole rows produce.
  void AddTriangle(const Primitive& prim, uint32_t a, uint32_t b, uint32_t c) {
    const Vertex* base = scene_->vertices.data() + prim.first_vertex;
    const glm::vec3 n =
        glm::cross(base[b].position - base[a].position, base[c].position - base[a].position);
    if (glm::length(n) < 1e-9f) return;
    const glm::vec3 avg = base[a].normal + base[b].normal + base[c].normal;
    if (glm::dot(n, avg) < 0.0f) std::swap(b, c);
    scene_->indices.insert(scene_->indices.end(), {a, b, c});
  }

  CpuScene* scene_;
};

SurfaceFn Sphere(float radius) {
  return [radius](float s, float t) {
    // theta from the north pole, v = 0 at the top so the image is upright.
    const float phi = s * kTwoPi, theta = t * kPi;
    const glm::vec3 n(std::sin(theta) * std::cos(phi), std::cos(theta),
                      -std::sin(theta) * std::sin(phi));
    SurfacePoint p;
    p.position = n * radius;
    p.normal = n;
    p.du = glm::vec3(-std::sin(phi), 0.0f, -std::cos(phi));  // d/dphi without sin(theta)
    p.dv = glm::vec3(std::cos(theta) * std::cos(phi), -std::sin(theta),
                     -std::cos(theta) * std::sin(phi));
    p.uv = glm::vec2(s, t);
    return p;
  };
}

// Torus around the Y axis.
SurfaceFn Torus(float major, float minor) {
  return [major, minor](float s, float t) {
    const float phi = s * kTwoPi, theta = t * kTwoPi;
    const glm::vec3 radial(std::cos(phi), 0.0f, -std::sin(phi));
    const glm::vec3 around(-std::sin(phi), 0.0f, -std::cos(phi));
    // theta runs downwards over the outer equator so the mapping is not mirrored (w = +1).
    const glm::vec3 n = radial * std::cos(theta) - glm::vec3(0, 1, 0) * std::sin(theta);
    SurfacePoint p;
    p.position = radial * major + n * minor;
    p.normal = n;
    p.du = around;
    p.dv = -radial * std::sin(theta) - glm::vec3(0, 1, 0) * std::cos(theta);
    p.uv = glm::vec2(s * 4.0f, t);  // stretch along the ring to keep texels square-ish
    return p;
  };
}

// Open tube standing on y = 0; the texture repeats `u_repeats` times around it.
SurfaceFn Tube(float radius, float height, float u_repeats) {
  return [=](float s, float t) {
    const float phi = s * kTwoPi;
    const glm::vec3 n(std::cos(phi), 0.0f, -std::sin(phi));
    SurfacePoint p;
    p.position = n * radius + glm::vec3(0.0f, height * (1.0f - t), 0.0f);
    p.normal = n;
    p.du = glm::vec3(-std::sin(phi), 0.0f, -std::cos(phi));
    p.dv = glm::vec3(0.0f, -1.0f, 0.0f);
    p.uv = glm::vec2(s * u_repeats, t);
    return p;
  };
}

// A flat rectangle centred at `center`, facing `normal`, with the image upright along `up`.
SurfaceFn Quad(glm::vec3 center, glm::vec3 normal, glm::vec3 up, glm::vec2 size,
               glm::vec2 uv_scale) {
  const glm::vec3 right = glm::cross(up, normal);  // right x up = normal: seen from outside
  return [=](float s, float t) {
    SurfacePoint p;
    p.position = center + right * ((s - 0.5f) * size.x) + up * ((0.5f - t) * size.y);
    p.normal = normal;
    p.du = right;
    p.dv = -up;
    p.uv = glm::vec2(s, t) * uv_scale;
    return p;
  };
}

// A cube of edge `size` centred at the origin, one primitive, each face showing the whole
// texture upright.
Primitive AddBox(MeshBuilder& mb, CpuScene& scene, float size, uint32_t material) {
  struct Face {
    glm::vec3 n, up;
  };
  const Face faces[6] = {{{1, 0, 0}, {0, 1, 0}},  {{-1, 0, 0}, {0, 1, 0}}, {{0, 0, 1}, {0, 1, 0}},
                         {{0, 0, -1}, {0, 1, 0}}, {{0, 1, 0}, {0, 0, -1}}, {{0, -1, 0}, {0, 0, 1}}};
  Primitive box;
  for (int f = 0; f < 6; ++f) {
    const Primitive face = mb.AddSurface(
        Quad(faces[f].n * (size * 0.5f), faces[f].n, faces[f].up, glm::vec2(size), glm::vec2(1.0f)),
        2, 2, material);
    if (f == 0) {
      box = face;
    } else {
      box.index_count += face.index_count;
      // Face indices are relative to their own first vertex; rebase onto the box's.
      for (uint32_t i = face.first_index; i < face.first_index + face.index_count; ++i) {
        scene.indices[i] += face.first_vertex - box.first_vertex;
      }
      box.vertex_count += face.vertex_count;
      box.bounds.extend(face.bounds);
    }
  }
  return box;
}

// ---- procedural textures -------------------------------------------------------------------

float SmoothStep(float e0, float e1, float x) {
  const float t = std::clamp((x - e0) / (e1 - e0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

uint8_t ToByte(float v) {
  return static_cast<uint8_t>(std::lround(std::clamp(v, 0.0f, 1.0f) * 255.0f));
}

// Cheap integer hash for per-tile variation: deterministic on every platform.
float Hash01(uint32_t x, uint32_t y) {
  uint32_t h = x * 0x8da6b343u ^ y * 0xd8163841u ^ 0x9e3779b9u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return float(h & 0xFFFFu) / 65535.0f;
}

// Bilinearly interpolated hash on a `cell`-pixel lattice, tileable over kTexSize: a hash per
// texel would turn into harsh speckle once differentiated into normals.
float ValueNoise(int x, int y, int cell) {
  const int cells = static_cast<int>(kTexSize) / cell;
  const int cx = x / cell, cy = y / cell;
  const float fx = float(x % cell) / float(cell), fy = float(y % cell) / float(cell);
  auto h = [cells](int i, int j) {
    return Hash01(static_cast<uint32_t>(i % cells), static_cast<uint32_t>(j % cells));
  };
  const float top = h(cx, cy) + (h(cx + 1, cy) - h(cx, cy)) * fx;
  const float bottom = h(cx, cy + 1) + (h(cx + 1, cy + 1) - h(cx, cy + 1)) * fx;
  return top + (bottom - top) * fy;
}

std::shared_ptr<const Image> MakeImage(const std::string& name,
                                       const std::function<glm::vec4(uint32_t, uint32_t)>& px) {
  auto img = std::make_shared<Image>();
  img->name = name;
  img->width = kTexSize;
  img->height = kTexSize;
  img->rgba8.resize(size_t{kTexSize} * kTexSize * 4);
  for (uint32_t y = 0; y < kTexSize; ++y) {
    for (uint32_t x = 0; x < kTexSize; ++x) {
      const glm::vec4 c = px(x, y);
      uint8_t* out = &img->rgba8[(size_t{y} * kTexSize + x) * 4];
      for (int k = 0; k < 4; ++k) out[k] = ToByte(c[k]);
    }
  }
  return img;
}

// 4x4 tiles with grout lines and a little per-tile brightness variation (sRGB values).
std::shared_ptr<const Image> CheckerImage() {
  constexpr uint32_t kTile = kTexSize / 4;
  return MakeImage("demo_checker", [](uint32_t x, uint32_t y) {
    const uint32_t tx = x / kTile, ty = y / kTile;
    const uint32_t lx = x % kTile, ly = y % kTile;
    const bool grout = lx < 2 || ly < 2;
    const float jitter = 0.06f * (Hash01(tx, ty) - 0.5f);
    glm::vec3 c =
        ((tx + ty) % 2 == 0) ? glm::vec3(0.80f, 0.78f, 0.74f) : glm::vec3(0.22f, 0.24f, 0.28f);
    c += jitter;
    if (grout) c = glm::vec3(0.12f);
    return glm::vec4(c, 1.0f);
  });
}

// Brick height field, tileable: 4 courses of 2 bricks, odd courses offset by half a brick.
float BrickHeight(int x, int y) {
  constexpr int kN = static_cast<int>(kTexSize);
  constexpr int kCourse = kN / 4, kBrick = kN / 2, kMortar = 3, kBevel = 6;
  x = ((x % kN) + kN) % kN;
  y = ((y % kN) + kN) % kN;
  const int course = y / kCourse;
  const int bx = (x + (course % 2) * (kBrick / 2)) % kBrick;
  const int by = y % kCourse;
  // Distance to the nearest mortar line, in pixels.
  const int edge = std::min({bx, kBrick - 1 - bx, by, kCourse - 1 - by}) - kMortar;
  if (edge < 0) return 0.0f;
  return SmoothStep(0.0f, float(kBevel), float(edge)) * (0.9f + 0.08f * ValueNoise(x, y, 4));
}

// Tangent-space normal map of the bricks. OpenGL convention as glTF specifies: +X right,
// +Y up in the image (towards row 0), so a slope rising with the row index tilts +Y.
std::shared_ptr<const Image> BrickNormalImage() {
  constexpr float kStrength = 2.5f;
  return MakeImage("demo_brick_normal", [](uint32_t ux, uint32_t uy) {
    const int x = static_cast<int>(ux), y = static_cast<int>(uy);
    const float dhdx = 0.5f * (BrickHeight(x + 1, y) - BrickHeight(x - 1, y));
    const float dhdrow = 0.5f * (BrickHeight(x, y + 1) - BrickHeight(x, y - 1));
    const glm::vec3 n = glm::normalize(glm::vec3(-dhdx * kStrength, dhdrow * kStrength, 1.0f));
    return glm::vec4(n * 0.5f + 0.5f, 1.0f);
  });
}

// glTF metallic-roughness: G roughness, B metallic. Bands alternate metal / dielectric down
// the image; roughness is a triangle wave across it so the sphere seam stays continuous.
std::shared_ptr<const Image> MetallicRoughnessImage() {
  return MakeImage("demo_metallic_roughness", [](uint32_t x, uint32_t y) {
    const float u = (float(x) + 0.5f) / float(kTexSize);
    const float roughness = 0.12f + 0.76f * std::abs(2.0f * u - 1.0f);
    const float metallic = ((y / (kTexSize / 8)) % 2 == 0) ? 1.0f : 0.0f;
    return glm::vec4(1.0f, roughness, metallic, 1.0f);
  });
}

// Painted panel with a grid of round holes (alpha 0) for the alpha-mask object, with a
// 1.5-pixel soft edge so the cutoff lands on a clean circle.
std::shared_ptr<const Image> CutoutImage() {
  constexpr uint32_t kCell = kTexSize / 4;
  return MakeImage("demo_cutout", [](uint32_t x, uint32_t y) {
    const glm::vec2 local(float(x % kCell) + 0.5f, float(y % kCell) + 0.5f);
    const float d = glm::length(local - glm::vec2(kCell * 0.5f));
    const float alpha = std::clamp((d - kCell * 0.33f) / 1.5f + 0.5f, 0.0f, 1.0f);
    const bool stripe = ((x + y) / 16) % 2 == 0;
    const glm::vec3 c = stripe ? glm::vec3(0.92f, 0.50f, 0.12f) : glm::vec3(0.85f, 0.40f, 0.08f);
    return glm::vec4(c, alpha);
  });
}

// ---- assembly ------------------------------------------------------------------------------

uint32_t AddTexture(CpuScene& scene, std::shared_ptr<const Image> image, bool srgb) {
  Texture tex;
  tex.image = std::move(image);
  tex.srgb = srgb;
  scene.textures.push_back(std::move(tex));
  return static_cast<uint32_t>(scene.textures.size() - 1);
}

uint32_t AddMaterial(CpuScene& scene, Material m) {
  scene.materials.push_back(std::move(m));
  return static_cast<uint32_t>(scene.materials.size() - 1);
}

Material Pbr(const std::string& name, glm::vec4 base, float metallic, float roughness) {
  Material m;
  m.name = name;
  m.base_color_factor = base;
  m.metallic_factor = metallic;
  m.roughness_factor = roughness;
  return m;
}

// One object = one mesh with one primitive, instanced once.
void AddObject(CpuScene& scene, const std::string& name, Primitive prim, const glm::mat4& world) {
  const uint32_t prim_index = static_cast<uint32_t>(scene.primitives.size());
  scene.primitives.push_back(prim);
  Mesh mesh;
  mesh.name = name;
  mesh.primitives.push_back(prim_index);
  scene.meshes.push_back(std::move(mesh));
  Drawable d;
  d.world = world;
  d.primitive = prim_index;
  d.mesh = static_cast<uint32_t>(scene.meshes.size() - 1);
  d.node = static_cast<uint32_t>(scene.drawables.size());
  d.world_bounds = prim.bounds.transformed(world);
  scene.drawables.push_back(d);
}

Primitive WithMaterial(Primitive p, uint32_t material) {
  p.material = material;
  return p;
}

glm::mat4 Translate(float x, float y, float z) {
  return glm::translate(glm::mat4(1.0f), glm::vec3(x, y, z));
}

glm::mat4 RotateY(const glm::mat4& m, float radians) {
  return glm::rotate(m, radians, glm::vec3(0, 1, 0));
}

Light MakePoint(const std::string& name, glm::vec3 color, float candela, glm::vec3 pos) {
  Light l;
  l.name = name;
  l.type = LightType::kPoint;
  l.color = color;
  l.intensity = candela;
  l.range = 8.0f;
  l.position = pos;
  return l;
}

}  // namespace

CpuScene BuildDemoScene() {
  CpuScene scene;
  scene.name = "Tessera demo";
  MeshBuilder mb(&scene);

  // Textures.
  const uint32_t checker_tex = AddTexture(scene, CheckerImage(), /*srgb=*/true);
  const uint32_t brick_normal_tex = AddTexture(scene, BrickNormalImage(), /*srgb=*/false);
  const uint32_t mr_tex = AddTexture(scene, MetallicRoughnessImage(), /*srgb=*/false);
  const uint32_t cutout_tex = AddTexture(scene, CutoutImage(), /*srgb=*/true);

  // Materials.
  Material floor = Pbr("Floor tiles", glm::vec4(1.0f), 0.0f, 0.55f);
  floor.base_color.texture = static_cast<int32_t>(checker_tex);
  const uint32_t floor_mat = AddMaterial(scene, floor);
  const uint32_t gold_mat =
      AddMaterial(scene, Pbr("Polished gold", glm::vec4(1.0f, 0.77f, 0.34f, 1.0f), 1.0f, 0.2f));
  const uint32_t copper_mat =
      AddMaterial(scene, Pbr("Brushed copper", glm::vec4(0.95f, 0.64f, 0.54f, 1.0f), 1.0f, 0.55f));
  const uint32_t plastic_mat =
      AddMaterial(scene, Pbr("Red plastic", glm::vec4(0.8f, 0.05f, 0.04f, 1.0f), 0.0f, 0.3f));
  Material bricks = Pbr("White bricks", glm::vec4(0.9f, 0.9f, 0.88f, 1.0f), 0.0f, 0.85f);
  bricks.normal.texture = static_cast<int32_t>(brick_normal_tex);
  const uint32_t brick_mat = AddMaterial(scene, bricks);
  Material textured = Pbr("Checker metal-roughness", glm::vec4(1.0f), 1.0f, 1.0f);
  textured.base_color.texture = static_cast<int32_t>(checker_tex);
  textured.base_color.scale = glm::vec2(4.0f, 2.0f);  // KHR_texture_transform: smaller tiles
  textured.metallic_roughness.texture = static_cast<int32_t>(mr_tex);
  const uint32_t textured_mat = AddMaterial(scene, textured);
  Material cutout = Pbr("Perforated panel", glm::vec4(1.0f), 0.0f, 0.5f);
  cutout.base_color.texture = static_cast<int32_t>(cutout_tex);
  cutout.alpha_mode = AlphaMode::kMask;
  cutout.alpha_cutoff = 0.5f;
  cutout.double_sided = true;
  const uint32_t cutout_mat = AddMaterial(scene, cutout);
  Material glass = Pbr("Tinted glass", glm::vec4(0.55f, 0.8f, 1.0f, 0.35f), 0.0f, 0.05f);
  glass.alpha_mode = AlphaMode::kBlend;
  const uint32_t glass_mat = AddMaterial(scene, glass);

  // Geometry. The spheres share one vertex/index range: primitives differ only in material.
  const Primitive floor_prim =
      mb.AddSurface(Quad(glm::vec3(0.0f), glm::vec3(0, 1, 0), glm::vec3(0, 0, -1), glm::vec2(12.0f),
                         glm::vec2(6.0f)),
                    12, 12, floor_mat);
  const Primitive sphere = mb.AddSurface(Sphere(0.5f), 64, 40, gold_mat);
  const Primitive torus = mb.AddSurface(Torus(0.42f, 0.15f), 64, 24, copper_mat);
  const Primitive box = AddBox(mb, scene, 0.9f, brick_mat);
  const Primitive tube = mb.AddSurface(Tube(0.4f, 1.1f, 3.0f), 48, 4, cutout_mat);

  AddObject(scene, "Floor", floor_prim, glm::mat4(1.0f));
  AddObject(scene, "Gold sphere", sphere, Translate(-1.6f, 0.5f, 0.3f));
  // Stand the ring up (its axis horizontal), resting on the floor.
  AddObject(
      scene, "Copper torus", torus,
      glm::rotate(RotateY(Translate(0.1f, 0.57f, -1.3f), 0.5f), kPi * 0.5f, glm::vec3(1, 0, 0)));
  AddObject(scene, "Red plastic sphere", WithMaterial(sphere, plastic_mat),
            Translate(-0.15f, 0.5f, 0.55f));
  AddObject(scene, "Brick box", box, RotateY(Translate(-1.5f, 0.45f, -1.7f), 0.45f));
  AddObject(scene, "Textured sphere", WithMaterial(sphere, textured_mat),
            RotateY(Translate(1.4f, 0.5f, 0.35f), -0.6f));
  AddObject(scene, "Perforated tube", tube, Translate(1.75f, 0.0f, -1.35f));
  AddObject(scene, "Glass sphere", WithMaterial(sphere, glass_mat),
            glm::scale(Translate(0.55f, 0.45f, 1.95f), glm::vec3(0.9f)));

  // Lights: a warm sun from the camera's side plus coloured pools on the floor.
  Light sun;
  sun.name = "Sun";
  sun.type = LightType::kDirectional;
  sun.color = glm::vec3(1.0f, 0.92f, 0.80f);
  sun.intensity = 2.5f;
  sun.direction = glm::normalize(glm::vec3(-0.45f, -1.0f, -0.35f));
  scene.lights.push_back(sun);
  scene.lights.push_back(
      MakePoint("Red point", glm::vec3(1.0f, 0.25f, 0.18f), 25.0f, {-2.6f, 1.8f, 1.2f}));
  scene.lights.push_back(
      MakePoint("Blue point", glm::vec3(0.22f, 0.40f, 1.0f), 30.0f, {2.7f, 2.0f, 0.9f}));
  scene.lights.push_back(
      MakePoint("Green point", glm::vec3(0.30f, 1.0f, 0.35f), 20.0f, {0.0f, 1.6f, -2.8f}));
  Light spot;
  spot.name = "Spot";
  spot.type = LightType::kSpot;
  spot.color = glm::vec3(1.0f, 0.96f, 0.9f);
  spot.intensity = 45.0f;
  spot.range = 12.0f;
  spot.position = glm::vec3(0.0f, 4.5f, 1.5f);
  spot.direction = glm::normalize(glm::vec3(-0.2f, 0.5f, 0.2f) - spot.position);
  spot.inner_cone_angle = 0.25f;
  spot.outer_cone_angle = 0.45f;
  scene.lights.push_back(spot);

  // A 3/4 view from the front right, slightly above the objects.
  SceneCamera cam;
  cam.name = "Demo camera";
  cam.world = glm::inverse(glm::lookAt(glm::vec3(4.0f, 2.6f, 4.8f), glm::vec3(0.0f, 0.45f, 0.0f),
                                       glm::vec3(0.0f, 1.0f, 0.0f)));
  cam.yfov = 0.75f;
  cam.znear = 0.05f;
  cam.zfar = 100.0f;
  scene.cameras.push_back(cam);

  for (const Drawable& d : scene.drawables) scene.bounds.extend(d.world_bounds);

  CountGeneratedScene(scene);
  return scene;
}

}  // namespace tessera

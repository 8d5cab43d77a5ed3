// The generated city scene (see city_scene.h): thousands of box buildings for occlusion
// culling. The geometry is a handful of unit meshes (four building variants, a ground quad, a
// sign quad, a canopy box) shared by every drawable and placed by translation + non-uniform
// scale, so the vertex buffer stays a few hundred vertices however large the city is; the
// draw count and the triangle count are what grow.
#include "renderer/scene/city_scene.h"

#include "renderer/scene/hash.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <string>
#include <utility>
#include <vector>

namespace tessera {
namespace {

// ---- layout --------------------------------------------------------------------------------

constexpr float kLot = 10.0f;     // each building stands on a kLot x kLot lot
constexpr float kStreet = 16.0f;  // street width, kerb to kerb
constexpr float kMinWidth = 7.0f, kMaxWidth = 9.0f;
constexpr float kMinHeight = 8.0f, kMaxHeight = 60.0f;
// A building's centre moves at most this fraction of its free lot margin off the lot centre:
// with 9 m buildings two neighbours keep at least 0.5 m between them.
constexpr float kJitter = 0.25f;
// Buildings taller than this always get a flat roof (a hip roof on a tower reads as a spire).
constexpr float kFlatRoofAbove = 30.0f;
// Pitched-roof variants: the walls stop at this fraction of the height, the roof fills the rest.
constexpr float kPitchedWallTop = 0.8f;
constexpr float kSignChance = 0.025f;  // besides the tallest flat-roofed building per block
constexpr float kCanopyHeight = 4.5f, kCanopyThickness = 0.25f, kCanopySize = 12.0f;
constexpr uint32_t kMaxCanopies = 64;  // keep the blended set small
constexpr float kEyeHeight = 1.7f;

// The parameters with zeros replaced by ones, and the derived sizes.
struct Layout {
  uint32_t blocks_x, blocks_z, per_side, detail, seed;
  float block;  // block edge length
};

Layout MakeLayout(const CityParams& p) {
  Layout l;
  l.blocks_x = std::max(p.blocks_x, 1u);
  l.blocks_z = std::max(p.blocks_z, 1u);
  l.per_side = std::max(p.buildings_per_side, 1u);
  l.detail = std::max(p.facade_detail, 1u);
  l.seed = p.seed;
  l.block = float(l.per_side) * kLot;
  return l;
}

// Centre of street i along one axis of a city of `blocks` blocks, the city centred on 0.
float StreetCentre(uint32_t blocks, float block, uint32_t i) {
  const float total = float(blocks) * block + float(blocks + 1) * kStreet;
  return -0.5f * total + 0.5f * kStreet + float(i) * (block + kStreet);
}

// Low edge of block b along one axis (block b lies between streets b and b + 1).
float BlockMin(uint32_t blocks, float block, uint32_t b) {
  return StreetCentre(blocks, block, b) + 0.5f * kStreet;
}

// ---- deterministic randomness (Lowbias32, renderer/scene/hash.h) ---------------------------

// What each hash of a lot decides, so the decisions are independent of each other.
enum Salt : uint32_t {
  kSaltWidthX = 1,
  kSaltWidthZ,
  kSaltOffsetX,
  kSaltOffsetZ,
  kSaltHeight,
  kSaltVariant,
  kSaltMaterial,
  kSaltSign,
  kSaltSignHeight,
};

uint32_t Hash(uint32_t seed, uint32_t x, uint32_t z, Salt salt) {
  uint32_t h = Lowbias32(seed + 0x9e3779b9u);
  h = Lowbias32(h ^ x);
  h = Lowbias32(h ^ (z * 0x85ebca6bu));
  return Lowbias32(h ^ (static_cast<uint32_t>(salt) * 0xc2b2ae35u));
}

// Uniform in [0, 1): the top 24 bits, exact in a float.
float Hash01(uint32_t seed, uint32_t x, uint32_t z, Salt salt) {
  return float(Hash(seed, x, z, salt) >> 8) * (1.0f / 16777216.0f);
}

// ---- geometry ------------------------------------------------------------------------------

// Appends flat-shaded faces to the scene buffers as one primitive. Every face is planar with
// its own vertices (hard edges), wound counter-clockwise seen from outside (glTF front face),
// with uv0 = uv1 running 0..1 across the face, v = 0 at the top, so tangent.w is always +1.
class PrimitiveBuilder {
 public:
  PrimitiveBuilder(CpuScene* scene, uint32_t material) : scene_(scene) {
    prim_.first_vertex = static_cast<uint32_t>(scene_->vertices.size());
    prim_.first_index = static_cast<uint32_t>(scene_->indices.size());
    prim_.material = material;
  }

  // A parallelogram from `bottom_left` spanned by `right` and `up` (right x up points out of
  // the solid), tessellated into nu x nv quads.
  void AddGrid(glm::vec3 bottom_left, glm::vec3 right, glm::vec3 up, uint32_t nu, uint32_t nv) {
    const glm::vec3 n = glm::normalize(glm::cross(right, up));
    const glm::vec3 t = glm::normalize(right);
    const uint32_t base = LocalVertexCount();
    for (uint32_t j = 0; j <= nv; ++j) {
      for (uint32_t i = 0; i <= nu; ++i) {
        const float s = float(i) / float(nu), v = float(j) / float(nv);
        AddVertex(bottom_left + right * s + up * v, n, t, glm::vec2(s, 1.0f - v));
      }
    }
    const uint32_t row = nu + 1;
    for (uint32_t j = 0; j < nv; ++j) {
      for (uint32_t i = 0; i < nu; ++i) {
        const uint32_t a = base + j * row + i, b = a + 1, c = b + row, d = a + row;
        scene_->indices.insert(scene_->indices.end(), {a, b, c, a, c, d});
      }
    }
  }

  // A triangle over the edge bottom_left -> bottom_right, rising to `apex` (a roof face or a
  // gable end).
  void AddTriangle(glm::vec3 bottom_left, glm::vec3 bottom_right, glm::vec3 apex) {
    const glm::vec3 edge = bottom_right - bottom_left, rise = apex - bottom_left;
    const glm::vec3 n = glm::normalize(glm::cross(edge, rise));
    const glm::vec3 t = glm::normalize(edge);
    const glm::vec3 b = glm::cross(n, t);  // up the face
    const float width = glm::length(edge), height = glm::dot(rise, b);
    const uint32_t base = LocalVertexCount();
    for (const glm::vec3& p : {bottom_left, bottom_right, apex}) {
      const glm::vec3 d = p - bottom_left;
      AddVertex(p, n, t, glm::vec2(glm::dot(d, t) / width, 1.0f - glm::dot(d, b) / height));
    }
    scene_->indices.insert(scene_->indices.end(), {base, base + 1, base + 2});
  }

  Primitive Finish() {
    prim_.vertex_count = LocalVertexCount();
    prim_.index_count = static_cast<uint32_t>(scene_->indices.size()) - prim_.first_index;
    return prim_;
  }

 private:
  uint32_t LocalVertexCount() const {
    return static_cast<uint32_t>(scene_->vertices.size()) - prim_.first_vertex;
  }

  void AddVertex(glm::vec3 p, glm::vec3 n, glm::vec3 t, glm::vec2 uv) {
    Vertex v;
    v.position = p;
    v.normal = n;
    v.tangent = glm::vec4(t, 1.0f);  // bitangent = cross(n, t) points up the face, towards v=0
    v.uv0 = uv;
    v.uv1 = uv;
    scene_->vertices.push_back(v);
    prim_.bounds.extend(p);
  }

  CpuScene* scene_;
  Primitive prim_;
};

// The four walls of a unit footprint x, z in [-0.5, 0.5]: bottom-left corner seen from
// outside, and the direction to the right along the wall.
struct Wall {
  glm::vec3 bottom_left, right;
};
constexpr std::array<Wall, 4> kWalls = {{
    {{0.5f, 0.0f, 0.5f}, {0.0f, 0.0f, -1.0f}},   // +X
    {{-0.5f, 0.0f, -0.5f}, {0.0f, 0.0f, 1.0f}},  // -X
    {{-0.5f, 0.0f, 0.5f}, {1.0f, 0.0f, 0.0f}},   // +Z
    {{0.5f, 0.0f, -0.5f}, {-1.0f, 0.0f, 0.0f}},  // -Z
}};

enum class Roof { kFlat, kHip, kGable };

struct BuildingVariant {
  const char* name;
  Roof roof;
  uint32_t detail_scale;  // facade quads per wall: (d * scale) x (2 * d * scale)
};
constexpr std::array<BuildingVariant, 4> kVariants = {{
    {"flat", Roof::kFlat, 1},
    {"flat fine", Roof::kFlat, 2},
    {"hip roof", Roof::kHip, 1},
    {"gable roof", Roof::kGable, 1},
}};

// A closed unit building (no floor): footprint x, z in [-0.5, 0.5], y in [0, 1]. Convex, so
// every face points away from the centre of its bounds.
Primitive AddBuilding(CpuScene& scene, const BuildingVariant& variant, uint32_t detail,
                      uint32_t material) {
  PrimitiveBuilder pb(&scene, material);
  const float wall_top = variant.roof == Roof::kFlat ? 1.0f : kPitchedWallTop;
  const glm::vec3 up(0.0f, wall_top, 0.0f);
  const uint32_t nu = detail * variant.detail_scale;
  for (const Wall& w : kWalls) pb.AddGrid(w.bottom_left, w.right, up, nu, 2 * nu);
  const float rise = 1.0f - wall_top;
  switch (variant.roof) {
    case Roof::kFlat:
      pb.AddGrid({-0.5f, 1.0f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f}, 1, 1);
      break;
    case Roof::kHip:  // a pyramid over the whole footprint
      for (const Wall& w : kWalls) {
        pb.AddTriangle(w.bottom_left + up, w.bottom_left + up + w.right, {0.0f, 1.0f, 0.0f});
      }
      break;
    case Roof::kGable:  // ridge along x: two slopes facing +-z, gable ends on the x walls
      pb.AddGrid({-0.5f, wall_top, 0.5f}, {1.0f, 0.0f, 0.0f}, {0.0f, rise, -0.5f}, 1, 1);
      pb.AddGrid({0.5f, wall_top, -0.5f}, {-1.0f, 0.0f, 0.0f}, {0.0f, rise, 0.5f}, 1, 1);
      for (int i = 0; i < 2; ++i) {
        const Wall& w = kWalls[i];
        pb.AddTriangle(w.bottom_left + up, w.bottom_left + up + w.right,
                       {w.bottom_left.x, 1.0f, 0.0f});
      }
      break;
  }
  return pb.Finish();
}

// Unit quad on y = 0 facing +Y, x, z in [-0.5, 0.5].
Primitive AddGroundQuad(CpuScene& scene, uint32_t material) {
  PrimitiveBuilder pb(&scene, material);
  pb.AddGrid({-0.5f, 0.0f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f}, 1, 1);
  return pb.Finish();
}

// Unit upright quad on z = 0 facing +Z, x in [-0.5, 0.5], y in [0, 1]. One-sided geometry:
// the material must be double-sided for it to be seen from behind.
Primitive AddSignQuad(CpuScene& scene, uint32_t material) {
  PrimitiveBuilder pb(&scene, material);
  pb.AddGrid({-0.5f, 0.0f, 0.0f}, {1.0f, 0.0f, 0.0f}, {0.0f, 1.0f, 0.0f}, 1, 1);
  return pb.Finish();
}

// Closed unit box, x, z in [-0.5, 0.5], y in [0, 1], all six faces.
Primitive AddUnitBox(CpuScene& scene, uint32_t material) {
  PrimitiveBuilder pb(&scene, material);
  for (const Wall& w : kWalls) pb.AddGrid(w.bottom_left, w.right, {0.0f, 1.0f, 0.0f}, 1, 1);
  pb.AddGrid({-0.5f, 1.0f, 0.5f}, {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f}, 1, 1);  // top
  pb.AddGrid({-0.5f, 0.0f, -0.5f}, {1.0f, 0.0f, 0.0f}, {0.0f, 0.0f, 1.0f}, 1, 1);  // bottom
  return pb.Finish();
}

// ---- assembly ------------------------------------------------------------------------------

uint32_t AddMaterial(CpuScene& scene, const std::string& name, glm::vec4 base, float roughness) {
  Material m;
  m.name = name;
  m.base_color_factor = base;
  m.metallic_factor = 0.0f;
  m.roughness_factor = roughness;
  scene.materials.push_back(std::move(m));
  return static_cast<uint32_t>(scene.materials.size() - 1);
}

// Adds the primitive as a mesh of its own; returns the primitive index (= the mesh index:
// every mesh here has exactly one primitive and they are added together).
uint32_t AddMesh(CpuScene& scene, const std::string& name, const Primitive& prim) {
  const uint32_t index = static_cast<uint32_t>(scene.primitives.size());
  scene.primitives.push_back(prim);
  Mesh mesh;
  mesh.name = name;
  mesh.primitives.push_back(index);
  scene.meshes.push_back(std::move(mesh));
  return index;
}

void AddDrawable(CpuScene& scene, uint32_t mesh, const glm::mat4& world) {
  Drawable d;
  d.world = world;
  d.primitive = mesh;
  d.mesh = mesh;
  d.node = static_cast<uint32_t>(scene.drawables.size());
  d.world_bounds = scene.primitives[mesh].bounds.transformed(world);
  scene.drawables.push_back(d);
}

// Translation times non-uniform scale, written out so the matrix holds exactly these numbers.
glm::mat4 PlaceScaled(glm::vec3 position, glm::vec3 scale) {
  glm::mat4 m(1.0f);
  m[0][0] = scale.x;
  m[1][1] = scale.y;
  m[2][2] = scale.z;
  m[3] = glm::vec4(position, 1.0f);
  return m;
}

// One building's lot decisions, before it is emitted.
struct Building {
  glm::vec3 base;  // centre of the footprint on the ground
  glm::vec3 size;  // width x, height, depth z
  uint32_t variant;
  uint32_t material;  // 0..3, index into the building materials
  uint32_t gx, gz;    // lot coordinates over the whole city
};

Building PlanBuilding(const Layout& l, uint32_t bx, uint32_t bz, uint32_t lx, uint32_t lz,
                      glm::vec2 half_city) {
  Building b;
  b.gx = bx * l.per_side + lx;
  b.gz = bz * l.per_side + lz;
  auto rnd = [&](Salt salt) { return Hash01(l.seed, b.gx, b.gz, salt); };
  const float lot_x = BlockMin(l.blocks_x, l.block, bx) + (float(lx) + 0.5f) * kLot;
  const float lot_z = BlockMin(l.blocks_z, l.block, bz) + (float(lz) + 0.5f) * kLot;
  const float width = kMinWidth + (kMaxWidth - kMinWidth) * rnd(kSaltWidthX);
  const float depth = kMinWidth + (kMaxWidth - kMinWidth) * rnd(kSaltWidthZ);
  const float off_x = (kLot - width) * kJitter * (2.0f * rnd(kSaltOffsetX) - 1.0f);
  const float off_z = (kLot - depth) * kJitter * (2.0f * rnd(kSaltOffsetZ) - 1.0f);
  // Downtown: 1 in the middle of the city, 0 at its edge; the tallest towers stand there.
  const float downtown = std::clamp(
      1.0f - std::max(std::abs(lot_x) / half_city.x, std::abs(lot_z) / half_city.y), 0.0f, 1.0f);
  const float u = rnd(kSaltHeight);
  const float height = kMinHeight + (kMaxHeight - kMinHeight) * u * u * (0.5f + 0.5f * downtown);
  b.base = glm::vec3(lot_x + off_x, 0.0f, lot_z + off_z);
  b.size = glm::vec3(width, height, depth);
  const uint32_t pick = Hash(l.seed, b.gx, b.gz, kSaltVariant);
  b.variant = height > kFlatRoofAbove ? pick % 2 : pick % 4;  // variants 0, 1 are flat
  b.material = Hash(l.seed, b.gx, b.gz, kSaltMaterial) % 4;
  return b;
}

}  // namespace

float CityStreetX(const CityParams& p, uint32_t i) {
  const Layout l = MakeLayout(p);
  return StreetCentre(l.blocks_x, l.block, i);
}

float CityStreetZ(const CityParams& p, uint32_t i) {
  const Layout l = MakeLayout(p);
  return StreetCentre(l.blocks_z, l.block, i);
}

CpuScene BuildCityScene(const CityParams& params) {
  const Layout l = MakeLayout(params);
  CpuScene scene;
  scene.name = "city";

  // Materials: four facade finishes, asphalt and pavement (all opaque, single-sided), the
  // double-sided signs and the blended glass, so every render group and cull mode is used.
  std::array<uint32_t, 4> facade_mats;
  facade_mats[0] = AddMaterial(scene, "Concrete", {0.62f, 0.60f, 0.57f, 1.0f}, 0.85f);
  facade_mats[1] = AddMaterial(scene, "Brick", {0.55f, 0.27f, 0.20f, 1.0f}, 0.80f);
  facade_mats[2] = AddMaterial(scene, "Sandstone", {0.76f, 0.66f, 0.48f, 1.0f}, 0.75f);
  facade_mats[3] = AddMaterial(scene, "Slate cladding", {0.35f, 0.42f, 0.50f, 1.0f}, 0.60f);
  const uint32_t asphalt_mat = AddMaterial(scene, "Asphalt", {0.10f, 0.10f, 0.11f, 1.0f}, 0.90f);
  const uint32_t pavement_mat = AddMaterial(scene, "Pavement", {0.45f, 0.45f, 0.43f, 1.0f}, 0.85f);
  const uint32_t sign_mat = AddMaterial(scene, "Sign", {0.95f, 0.72f, 0.12f, 1.0f}, 0.6f);
  scene.materials[sign_mat].double_sided = true;
  const uint32_t glass_mat = AddMaterial(scene, "Canopy glass", {0.55f, 0.8f, 0.9f, 0.5f}, 0.1f);
  scene.materials[glass_mat].alpha_mode = AlphaMode::kBlend;

  // Geometry. The facade materials share each variant's vertex range (primitives that differ
  // only in material), and so do asphalt and pavement.
  std::array<std::array<uint32_t, 4>, kVariants.size()> building_meshes;
  for (size_t v = 0; v < kVariants.size(); ++v) {
    const Primitive prim = AddBuilding(scene, kVariants[v], l.detail, facade_mats[0]);
    for (size_t m = 0; m < facade_mats.size(); ++m) {
      Primitive p = prim;
      p.material = facade_mats[m];
      const std::string name = std::string("Building ") + kVariants[v].name + " / " +
                               scene.materials[facade_mats[m]].name;
      building_meshes[v][m] = AddMesh(scene, name, p);
    }
  }
  const Primitive ground = AddGroundQuad(scene, asphalt_mat);
  const uint32_t street_mesh = AddMesh(scene, "Street", ground);
  Primitive pavement = ground;
  pavement.material = pavement_mat;
  const uint32_t block_mesh = AddMesh(scene, "Block ground", pavement);
  const uint32_t sign_mesh = AddMesh(scene, "Sign", AddSignQuad(scene, sign_mat));
  const uint32_t canopy_mesh = AddMesh(scene, "Canopy", AddUnitBox(scene, glass_mat));

  // Ground: a (2 * blocks + 1)^2 grid of cells, even cells streets, odd cells blocks, so a
  // street crossing, a street segment and a block are each one drawable.
  auto cell = [&l](uint32_t blocks, uint32_t c) {  // centre and width along one axis
    if (c % 2 == 0) return glm::vec2(StreetCentre(blocks, l.block, c / 2), kStreet);
    return glm::vec2(BlockMin(blocks, l.block, c / 2) + 0.5f * l.block, l.block);
  };
  for (uint32_t cz = 0; cz <= 2 * l.blocks_z; ++cz) {
    for (uint32_t cx = 0; cx <= 2 * l.blocks_x; ++cx) {
      const glm::vec2 x = cell(l.blocks_x, cx), z = cell(l.blocks_z, cz);
      const bool block = cx % 2 == 1 && cz % 2 == 1;
      AddDrawable(scene, block ? block_mesh : street_mesh,
                  PlaceScaled({x.x, 0.0f, z.x}, {x.y, 1.0f, z.y}));
    }
  }

  // Buildings, block by block; each block's tallest flat-roofed building (and a few others)
  // carries a sign, drawn after all buildings.
  const glm::vec2 half_city(-StreetCentre(l.blocks_x, l.block, 0) + 0.5f * kStreet,
                            -StreetCentre(l.blocks_z, l.block, 0) + 0.5f * kStreet);
  std::vector<glm::mat4> signs;
  std::vector<Building> block;
  for (uint32_t bz = 0; bz < l.blocks_z; ++bz) {
    for (uint32_t bx = 0; bx < l.blocks_x; ++bx) {
      block.clear();
      for (uint32_t lz = 0; lz < l.per_side; ++lz) {
        for (uint32_t lx = 0; lx < l.per_side; ++lx) {
          block.push_back(PlanBuilding(l, bx, bz, lx, lz, half_city));
        }
      }
      const Building* tallest_flat = nullptr;
      for (const Building& b : block) {
        if (kVariants[b.variant].roof != Roof::kFlat) continue;
        if (!tallest_flat || b.size.y > tallest_flat->size.y) tallest_flat = &b;
      }
      for (const Building& b : block) {
        AddDrawable(scene, building_meshes[b.variant][b.material], PlaceScaled(b.base, b.size));
        const bool flat = kVariants[b.variant].roof == Roof::kFlat;
        if (flat && (&b == tallest_flat || Hash01(l.seed, b.gx, b.gz, kSaltSign) < kSignChance)) {
          // Standing across the middle of the roof, facing +-z.
          const float height = 2.0f + 2.0f * Hash01(l.seed, b.gx, b.gz, kSaltSignHeight);
          signs.push_back(PlaceScaled(b.base + glm::vec3(0.0f, b.size.y, 0.0f),
                                      {0.6f * b.size.x, height, 1.0f}));
        }
      }
    }
  }
  for (const glm::mat4& world : signs) AddDrawable(scene, sign_mesh, world);

  // Glass canopies over every third street crossing (a fixed pattern, so even a one-block city
  // has one), above head height and inside the crossing.
  uint32_t canopies = 0;
  for (uint32_t j = 0; j <= l.blocks_z; ++j) {
    for (uint32_t i = 0; i <= l.blocks_x && canopies < kMaxCanopies; ++i) {
      if ((i + 2 * j) % 3 != 0) continue;
      AddDrawable(scene, canopy_mesh,
                  PlaceScaled({StreetCentre(l.blocks_x, l.block, i), kCanopyHeight,
                               StreetCentre(l.blocks_z, l.block, j)},
                              {kCanopySize, kCanopyThickness, kCanopySize}));
      ++canopies;
    }
  }

  for (const Drawable& d : scene.drawables) scene.bounds.extend(d.world_bounds);

  // A low afternoon sun, slanted so streets in both directions get shadowed walls.
  Light sun;
  sun.name = "Sun";
  sun.type = LightType::kDirectional;
  sun.color = glm::vec3(1.0f, 0.94f, 0.85f);
  sun.intensity = 3.0f;
  sun.direction = glm::normalize(glm::vec3(-0.45f, -1.0f, -0.3f));
  scene.lights.push_back(sun);

  // At eye height in the middle street's crossing with the city's +z edge street, looking down
  // the street (-Z, the camera's own forward: no rotation needed).
  SceneCamera cam;
  cam.name = "street";
  cam.world = PlaceScaled({StreetCentre(l.blocks_x, l.block, l.blocks_x / 2), kEyeHeight,
                           StreetCentre(l.blocks_z, l.block, l.blocks_z)},
                          glm::vec3(1.0f));
  cam.yfov = 0.9f;
  cam.znear = 0.1f;
  cam.zfar = std::max(1000.0f, 1.5f * glm::length(scene.bounds.extent()));
  scene.cameras.push_back(cam);

  CountGeneratedScene(scene);
  return scene;
}

}  // namespace tessera

// CPU references of the image-based lighting shaders (see ibl.h): the cube map addressing of
// shaders/common/cube.glsl, the procedural sky of shaders/common/ibl_sky.glsl, and the
// split-sum BRDF integration of shaders/ibl_brdf.comp (with the GGX helpers of
// shaders/common/ibl_ggx.glsl). Keep each function in step with its shader.
#include "renderer/ibl.h"

#include <cmath>
#include <cstdint>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace tessera {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The constants of ibl_sky.glsl (see there for what they mean).
constexpr float kSkyGroundBlend = 0.04f;
constexpr float kSkyGlowWide = 0.15f;
constexpr float kSkyGlowTight = 0.6f;
constexpr float kSkySunInner = 0.0087266f;
constexpr float kSkySunOuter = 0.0174531f;
constexpr float kSkySunDisc = 40.0f;

// GLSL's built-ins, as the spec defines them.
float Clamp(float x, float lo, float hi) { return std::fmin(std::fmax(x, lo), hi); }

float SmoothStep(float edge0, float edge1, float x) {
  float t = Clamp((x - edge0) / (edge1 - edge0), 0.0f, 1.0f);
  return t * t * (3.0f - 2.0f * t);
}

glm::vec3 Mix(glm::vec3 x, glm::vec3 y, float a) { return x * (1.0f - a) + y * a; }

// bitfieldReverse for 32 bits.
uint32_t ReverseBits(uint32_t v) {
  v = ((v >> 1) & 0x55555555u) | ((v & 0x55555555u) << 1);
  v = ((v >> 2) & 0x33333333u) | ((v & 0x33333333u) << 2);
  v = ((v >> 4) & 0x0F0F0F0Fu) | ((v & 0x0F0F0F0Fu) << 4);
  v = ((v >> 8) & 0x00FF00FFu) | ((v & 0x00FF00FFu) << 8);
  return (v >> 16) | (v << 16);
}

// ibl_ggx.glsl's IblVisibilitySmithGgxCorrelated (= shading.glsl's), in double.
double VisibilitySmithGgxCorrelated(double n_dot_v, double n_dot_l, double alpha) {
  double a2 = alpha * alpha;
  double gv = n_dot_l * std::sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
  double gl = n_dot_v * std::sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
  double s = gv + gl;
  return s > 0.0 ? 0.5 / s : 0.0;
}

}  // namespace

SkyParams DefaultSky(glm::vec3 sun_dir, glm::vec3 sun_color) {
  SkyParams p;
  float len = glm::length(sun_dir);
  if (std::isfinite(len) && len > 0.0f) p.sun_dir = sun_dir / len;
  p.sun_color = sun_color;
  return p;
}

glm::vec2 IntegrateBrdfReference(float n_dot_v, float roughness, uint32_t samples) {
  if (samples == 0) return glm::vec2(0.0f);
  double nv = n_dot_v;
  double alpha = double(roughness) * double(roughness);
  double a2 = alpha * alpha;
  // Tangent space: n = +Z, v in the xz plane.
  double vx = std::sqrt(std::fmax(1.0 - nv * nv, 0.0)), vz = nv;
  double a = 0.0, b = 0.0;
  for (uint32_t k = 0; k < samples; ++k) {
    // Hammersley point k (IblHammersley) -> GGX half vector (IblSampleGgx).
    double xi_x = double(k) / double(samples);
    double xi_y = double(ReverseBits(k)) * 2.3283064365386963e-10;
    double phi = 2.0 * kPi * xi_x;
    double cos_theta = std::sqrt((1.0 - xi_y) / (1.0 + (a2 - 1.0) * xi_y));
    double sin_theta = std::sqrt(std::fmax(1.0 - cos_theta * cos_theta, 0.0));
    double hx = sin_theta * std::cos(phi), hz = cos_theta;  // hy does not enter (v.y = 0)
    double v_dot_h = vx * hx + vz * hz;
    double n_dot_l = 2.0 * v_dot_h * hz - vz;  // l = 2 (v . h) h - v, its z
    double n_dot_h = hz;
    if (n_dot_l > 0.0 && v_dot_h > 0.0) {
      double vis = VisibilitySmithGgxCorrelated(nv, n_dot_l, alpha);
      double g_vis = vis * n_dot_l * 4.0 * v_dot_h / n_dot_h;
      double fc = std::pow(1.0 - v_dot_h, 5.0);
      a += (1.0 - fc) * g_vis;
      b += fc * g_vis;
    }
  }
  return glm::vec2(float(a / samples), float(b / samples));
}

glm::vec3 CubeDirection(uint32_t face, glm::vec2 uv) {
  float a = uv.x * 2.0f - 1.0f;  // sc / |ma|
  float b = uv.y * 2.0f - 1.0f;  // tc / |ma|
  glm::vec3 d;
  // clang-format off
  switch (face) {
    case 0: d = glm::vec3(1.0f, -b, -a); break;   // +X: sc = -rz, tc = -ry
    case 1: d = glm::vec3(-1.0f, -b, a); break;   // -X: sc = +rz, tc = -ry
    case 2: d = glm::vec3(a, 1.0f, b); break;     // +Y: sc = +rx, tc = +rz
    case 3: d = glm::vec3(a, -1.0f, -b); break;   // -Y: sc = +rx, tc = -rz
    case 4: d = glm::vec3(a, -b, 1.0f); break;    // +Z: sc = +rx, tc = -ry
    default: d = glm::vec3(-a, -b, -1.0f); break;  // -Z: sc = -rx, tc = -ry
  }
  // clang-format on
  return glm::normalize(d);
}

glm::vec3 ProceduralSkyReference(glm::vec3 dir, glm::vec3 sun_dir, glm::vec3 sun_color,
                                 glm::vec3 zenith, glm::vec3 horizon, glm::vec3 ground) {
  float y = Clamp(dir.y, -1.0f, 1.0f);
  float h = 1.0f - std::fmax(y, 0.0f);
  glm::vec3 sky = Mix(zenith, horizon, h * h);
  float below = SmoothStep(0.0f, kSkyGroundBlend, -y);
  glm::vec3 color = Mix(sky, ground, below);

  float c = Clamp(glm::dot(dir, sun_dir), 0.0f, 1.0f);
  float c2 = c * c;
  float c4 = c2 * c2;
  float c8 = c4 * c4;
  float c16 = c8 * c8;
  float c32 = c16 * c16;
  float c64 = c32 * c32;
  float chord = glm::length(dir - sun_dir);
  float disc = 1.0f - SmoothStep(kSkySunInner, kSkySunOuter, chord);
  float sun = kSkyGlowWide * c8 + kSkyGlowTight * c64 + kSkySunDisc * disc;
  color += sun_color * (sun * (1.0f - below));
  return glm::max(color, glm::vec3(0.0f));
}

}  // namespace tessera

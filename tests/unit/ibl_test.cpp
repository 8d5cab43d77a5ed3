// Image-based lighting on the CPU (renderer/ibl.h, the references of the IBL shaders): the cube
// map addressing against the Vulkan spec's face selection, the split-sum BRDF integration
// against a brute-force quadrature of the same BRDF and against Karis' analytic fit, and the
// procedural sky (finite, continuous at the horizon, brightest at the sun, as bright as the
// hemisphere ambient it replaces). Pure math: nothing here touches Vulkan.
#include "renderer/ibl.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>
#include <random>

namespace tessera {
namespace {

constexpr double kPi = 3.14159265358979323846;

::testing::AssertionResult Near(glm::vec3 a, glm::vec3 b, float tol) {
  if (glm::all(glm::lessThanEqual(glm::abs(a - b), glm::vec3(tol)))) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << "(" << a.x << ", " << a.y << ", " << a.z << ") vs ("
                                       << b.x << ", " << b.y << ", " << b.z << ")";
}

// ---- cube map addressing ---------------------------------------------------------------------

struct FaceUv {
  uint32_t face;
  glm::vec2 uv;
};

// The Vulkan spec's "Cube Map Face Selection" table, written out independently of
// CubeDirection: the major axis picks the face, then s = (sc / |ma| + 1) / 2 and
// t = (tc / |ma| + 1) / 2. (Ties between axes are the implementation's choice; callers avoid
// them.)
FaceUv SelectFace(glm::vec3 r) {
  const glm::vec3 m = glm::abs(r);
  uint32_t face;
  float sc, tc, ma;
  if (m.x >= m.y && m.x >= m.z) {
    ma = m.x;
    if (r.x >= 0.0f) {
      face = 0, sc = -r.z, tc = -r.y;  // +X
    } else {
      face = 1, sc = r.z, tc = -r.y;  // -X
    }
  } else if (m.y >= m.z) {
    ma = m.y;
    if (r.y >= 0.0f) {
      face = 2, sc = r.x, tc = r.z;  // +Y
    } else {
      face = 3, sc = r.x, tc = -r.z;  // -Y
    }
  } else {
    ma = m.z;
    if (r.z >= 0.0f) {
      face = 4, sc = r.x, tc = -r.y;  // +Z
    } else {
      face = 5, sc = -r.x, tc = -r.y;  // -Z
    }
  }
  return {face, glm::vec2((sc / ma + 1.0f) * 0.5f, (tc / ma + 1.0f) * 0.5f)};
}

TEST(IblCubeTest, FaceCentresAreTheAxes) {
  const glm::vec3 axes[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (uint32_t f = 0; f < 6; ++f) {
    EXPECT_TRUE(Near(CubeDirection(f, glm::vec2(0.5f)), axes[f], 1e-6f)) << "face " << f;
  }
}

TEST(IblCubeTest, CornersFollowTheVulkanTable) {
  const float k = 1.0f / std::sqrt(3.0f);
  // +X, uv (0, 0): s = 0 -> sc = -rz = -|ma| -> rz = +1; t = 0 -> tc = -ry = -|ma| -> ry = +1.
  EXPECT_TRUE(Near(CubeDirection(0, glm::vec2(0.0f)), glm::vec3(1, 1, 1) * k, 1e-6f));
  // +X, uv (1, 0): rz = -1 (s grows towards -Z), ry = +1.
  EXPECT_TRUE(Near(CubeDirection(0, glm::vec2(1.0f, 0.0f)), glm::vec3(1, 1, -1) * k, 1e-6f));
  // +Y, uv (0, 0): sc = +rx = -1 -> rx = -1; tc = +rz = -1 -> rz = -1 (the top row faces -Z).
  EXPECT_TRUE(Near(CubeDirection(2, glm::vec2(0.0f)), glm::vec3(-1, 1, -1) * k, 1e-6f));
  // -Y, uv (0, 0): sc = +rx -> rx = -1; tc = -rz = -1 -> rz = +1.
  EXPECT_TRUE(Near(CubeDirection(3, glm::vec2(0.0f)), glm::vec3(-1, -1, 1) * k, 1e-6f));
  // -Z, uv (0, 0): sc = -rx = -1 -> rx = +1; tc = -ry = -1 -> ry = +1.
  EXPECT_TRUE(Near(CubeDirection(5, glm::vec2(0.0f)), glm::vec3(1, 1, -1) * k, 1e-6f));
  // Every face's first row (t = 0) is its top: +Y for the four side faces.
  for (uint32_t f : {0u, 1u, 4u, 5u}) {
    EXPECT_GT(CubeDirection(f, glm::vec2(0.5f, 0.0f)).y, 0.7f) << "face " << f;
  }
}

TEST(IblCubeTest, RoundTripsThroughFaceSelection) {
  std::mt19937 rng(1234);
  std::uniform_int_distribution<uint32_t> face_dist(0, 5);
  // Away from the edges, where the major axis is a tie.
  std::uniform_real_distribution<float> uv_dist(0.01f, 0.99f);
  for (int i = 0; i < 1000; ++i) {
    const uint32_t face = face_dist(rng);
    const glm::vec2 uv(uv_dist(rng), uv_dist(rng));
    const glm::vec3 d = CubeDirection(face, uv);
    ASSERT_NEAR(glm::length(d), 1.0f, 1e-5f);
    const FaceUv back = SelectFace(d);
    ASSERT_EQ(back.face, face) << "uv " << uv.x << ", " << uv.y;
    ASSERT_NEAR(back.uv.x, uv.x, 1e-5f) << "face " << face;
    ASSERT_NEAR(back.uv.y, uv.y, 1e-5f) << "face " << face;
  }
}

TEST(IblCubeTest, NeighbouringFacesMeetAtTheirEdges) {
  // +Z's right edge (s = 1) is +X's left edge (s = 0), row for row; +Y's bottom row (t = 1)
  // is +Z's top row (t = 0), column for column.
  for (float x = 0.0f; x <= 1.0f; x += 0.125f) {
    EXPECT_TRUE(
        Near(CubeDirection(4, glm::vec2(1.0f, x)), CubeDirection(0, glm::vec2(0.0f, x)), 1e-6f));
    EXPECT_TRUE(
        Near(CubeDirection(2, glm::vec2(x, 1.0f)), CubeDirection(4, glm::vec2(x, 0.0f)), 1e-6f));
  }
}

// ---- split-sum BRDF ------------------------------------------------------------------------

// The same integral as IntegrateBrdfReference, by brute-force quadrature over the light
// direction (mu = cos theta_l, phi) instead of importance sampling, written from the BRDF of
// shaders/common/shading.glsl: integral of D V F n_dot_l, split into F0 * A + B.
glm::dvec2 BruteForceBrdf(double n_dot_v, double roughness, int n) {
  const double alpha = roughness * roughness, a2 = alpha * alpha;
  const glm::dvec3 v(std::sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v);
  glm::dvec2 ab(0.0);
  for (int i = 0; i < n; ++i) {
    const double mu = (i + 0.5) / n;
    const double sin_l = std::sqrt(1.0 - mu * mu);
    for (int j = 0; j < n; ++j) {
      const double phi = 2.0 * kPi * (j + 0.5) / n;
      const glm::dvec3 l(sin_l * std::cos(phi), sin_l * std::sin(phi), mu);
      const glm::dvec3 h = glm::normalize(l + v);
      const double f = h.z * h.z * (a2 - 1.0) + 1.0;
      const double d = a2 / (kPi * f * f);
      const double gv = mu * std::sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
      const double gl = n_dot_v * std::sqrt(mu * mu * (1.0 - a2) + a2);
      const double vis = 0.5 / (gv + gl);
      const double fc = std::pow(1.0 - glm::dot(v, h), 5.0);
      const double w = d * vis * mu * (1.0 / n) * (2.0 * kPi / n);  // dl = dmu dphi
      ab += w * glm::dvec2(1.0 - fc, fc);
    }
  }
  return ab;
}

// shading.glsl's EnvBrdfApprox as (scale, bias).
glm::vec2 EnvBrdfApprox(float roughness, float n_dot_v) {
  const glm::vec4 c0(-1.0f, -0.0275f, -0.572f, 0.022f);
  const glm::vec4 c1(1.0f, 0.0425f, 1.04f, -0.04f);
  const glm::vec4 r = roughness * c0 + c1;
  const float a004 = std::min(r.x * r.x, std::exp2(-9.28f * n_dot_v)) * r.x + r.y;
  return glm::vec2(-1.04f, 1.04f) * a004 + glm::vec2(r.z, r.w);
}

TEST(IblBrdfTest, NeverGainsEnergy) {
  for (int j = 0; j < 8; ++j) {
    for (int i = 0; i < 8; ++i) {
      const float n_dot_v = (i + 0.5f) / 8.0f, roughness = (j + 0.5f) / 8.0f;
      const glm::vec2 ab = IntegrateBrdfReference(n_dot_v, roughness, kIblBrdfSamples);
      EXPECT_GE(ab.x, 0.0f) << n_dot_v << ", " << roughness;
      EXPECT_GE(ab.y, 0.0f) << n_dot_v << ", " << roughness;
      EXPECT_LE(ab.x + ab.y, 1.0f + 1e-3f) << n_dot_v << ", " << roughness;
    }
  }
}

TEST(IblBrdfTest, SmoothMirrorReflectsEverything) {
  // Roughness ~0, seen head on: every sample reflects, G ~= 1, and the Fresnel terms sum to 1.
  for (float roughness : {0.0f, 0.01f, 0.03f}) {
    const glm::vec2 ab = IntegrateBrdfReference(0.999f, roughness, kIblBrdfSamples);
    EXPECT_NEAR(ab.x + ab.y, 1.0f, 0.02f) << roughness;
    EXPECT_LT(ab.y, 0.01f) << roughness;  // Schlick's Fresnel adds nothing head on
  }
}

TEST(IblBrdfTest, FresnelBiasGrowsTowardsGrazingAndEnergyFallsWithRoughness) {
  for (int j = 0; j < 8; ++j) {
    const float roughness = (j + 0.5f) / 8.0f;
    float prev_b = 2.0f;
    for (int i = 0; i < 8; ++i) {
      const float n_dot_v = (i + 0.5f) / 8.0f;
      const float b = IntegrateBrdfReference(n_dot_v, roughness, kIblBrdfSamples).y;
      EXPECT_LE(b, prev_b + 1e-4f) << n_dot_v << ", " << roughness;
      prev_b = b;
    }
  }
  // Head on, a rougher surface loses more to masking and shadowing.
  float prev_sum = 2.0f;
  for (int j = 0; j < 8; ++j) {
    const glm::vec2 ab = IntegrateBrdfReference(0.9375f, (j + 0.5f) / 8.0f, kIblBrdfSamples);
    EXPECT_LE(ab.x + ab.y, prev_sum + 1e-4f) << j;
    prev_sum = ab.x + ab.y;
  }
}

TEST(IblBrdfTest, MatchesBruteForceQuadrature) {
  // 512 importance samples are within ~0.01 of the integral for these roughnesses.
  for (float roughness : {0.3f, 0.5f, 0.7f, 1.0f}) {
    for (float n_dot_v : {0.1f, 0.3f, 0.6f, 0.9f}) {
      const glm::dvec2 want = BruteForceBrdf(n_dot_v, roughness, 600);
      const glm::vec2 got = IntegrateBrdfReference(n_dot_v, roughness, kIblBrdfSamples);
      EXPECT_NEAR(got.x, want.x, 0.015) << n_dot_v << ", " << roughness;
      EXPECT_NEAR(got.y, want.y, 0.015) << n_dot_v << ", " << roughness;
      // Many more samples converge to it.
      const glm::vec2 fine = IntegrateBrdfReference(n_dot_v, roughness, 1u << 16);
      EXPECT_NEAR(fine.x, want.x, 2e-3) << n_dot_v << ", " << roughness;
      EXPECT_NEAR(fine.y, want.y, 2e-3) << n_dot_v << ", " << roughness;
    }
  }
}

TEST(IblBrdfTest, CloseToKarisFitWhereItHolds) {
  // The fit was made for UE4's table (Schlick-Smith G, k = alpha / 2), which shadows more than
  // the height-correlated Smith G used here: at mid roughness and n_dot_v the two differ by up
  // to ~0.14 in A. Where they agree (low or high roughness), within 0.08.
  const float points[][2] = {{0.1f, 0.9f},
                             {0.25f, 0.25f},
                             {0.8f, 0.6f},
                             {0.8f, 0.9f},
                             {0.9f, 0.7f}};  // (roughness, n_dot_v)
  for (const auto& p : points) {
    const glm::vec2 ab = IntegrateBrdfReference(p[1], p[0], kIblBrdfSamples);
    const glm::vec2 fit = EnvBrdfApprox(p[0], p[1]);
    EXPECT_NEAR(ab.x, fit.x, 0.08f) << "roughness " << p[0] << ", n_dot_v " << p[1];
    EXPECT_NEAR(ab.y, fit.y, 0.08f) << "roughness " << p[0] << ", n_dot_v " << p[1];
  }
}

// ---- procedural sky ------------------------------------------------------------------------

glm::vec3 Sky(const SkyParams& s, glm::vec3 dir) {
  return ProceduralSkyReference(dir, s.sun_dir, s.sun_color, s.zenith, s.horizon, s.ground);
}

float Luminance(glm::vec3 c) { return glm::dot(c, glm::vec3(0.2126f, 0.7152f, 0.0722f)); }

glm::vec3 RandomDirection(std::mt19937& rng) {
  std::normal_distribution<float> n(0.0f, 1.0f);
  for (;;) {
    const glm::vec3 v(n(rng), n(rng), n(rng));
    const float len = glm::length(v);
    if (len > 1e-3f) return v / len;
  }
}

TEST(IblSkyTest, FiniteAndNonNegative) {
  std::mt19937 rng(42);
  const SkyParams skies[] = {
      DefaultSky(glm::vec3(0.0f), glm::vec3(0.0f)),               // no sun
      DefaultSky(glm::vec3(0.0f), glm::vec3(5.0f)),               // zero sun_dir, bright sun
      DefaultSky(glm::vec3(0.3f, 0.8f, -0.2f), glm::vec3(4.0f)),  // sun up
      DefaultSky(glm::vec3(0.5f, -0.3f, 0.1f), glm::vec3(4.0f)),  // sun below the horizon
      DefaultSky(glm::vec3(0.0f, 1.0f, 0.0f), glm::vec3(1000.0f)),
  };
  for (const SkyParams& s : skies) {
    for (int i = 0; i < 10000; ++i) {
      const glm::vec3 c = Sky(s, RandomDirection(rng));
      for (int k = 0; k < 3; ++k) {
        ASSERT_TRUE(std::isfinite(c[k])) << i;
        ASSERT_GE(c[k], 0.0f) << i;
      }
    }
    // Straight at the sun: the disc's radiance stays far below FP16's 65504.
    ASSERT_TRUE(std::isfinite(Luminance(Sky(s, s.sun_dir))));
    EXPECT_LT(Luminance(Sky(s, s.sun_dir)), 50.0f * std::max(s.sun_color.x, 1.0f));
  }
  // A zero sun_dir leaves no sun at all.
  const SkyParams none = DefaultSky(glm::vec3(0.0f), glm::vec3(0.0f));
  const SkyParams zero_dir = DefaultSky(glm::vec3(0.0f), glm::vec3(5.0f));
  for (int i = 0; i < 100; ++i) {
    const glm::vec3 d = RandomDirection(rng);
    EXPECT_TRUE(Near(Sky(zero_dir, d), Sky(none, d), 1e-6f));
  }
}

TEST(IblSkyTest, ContinuousAcrossTheHorizon) {
  const SkyParams skies[] = {DefaultSky(glm::vec3(0.0f), glm::vec3(0.0f)),
                             DefaultSky(glm::vec3(0.6f, 0.3f, 0.2f), glm::vec3(3.0f))};
  for (const SkyParams& s : skies) {
    for (int k = 0; k < 16; ++k) {
      const float phi = float(2.0 * kPi * k / 16.0);
      const float r = std::sqrt(1.0f - 1e-8f);
      const glm::vec3 above(r * std::cos(phi), 1e-4f, r * std::sin(phi));
      const glm::vec3 below(r * std::cos(phi), -1e-4f, r * std::sin(phi));
      const glm::vec3 a = Sky(s, above), b = Sky(s, below);
      for (int c = 0; c < 3; ++c) EXPECT_LT(std::abs(a[c] - b[c]), 0.05f * a[c]) << k;
    }
  }
}

TEST(IblSkyTest, BrighterTowardsTheHorizonWithoutASun) {
  const SkyParams s = DefaultSky(glm::vec3(0.0f), glm::vec3(0.0f));
  float prev = 0.0f;
  for (int k = 16; k >= 0; --k) {  // from the zenith down to the horizon
    const float y = k / 16.0f;
    const float lum = Luminance(Sky(s, glm::vec3(std::sqrt(1.0f - y * y), y, 0.0f)));
    EXPECT_GE(lum, prev) << y;
    prev = lum;
  }
  EXPECT_TRUE(Near(Sky(s, glm::vec3(0, 1, 0)), s.zenith, 1e-6f));
  EXPECT_TRUE(Near(Sky(s, glm::vec3(1, 0, 0)), s.horizon, 1e-6f));
  EXPECT_TRUE(Near(Sky(s, glm::vec3(0, -1, 0)), s.ground, 1e-6f));
}

TEST(IblSkyTest, TheSunIsTheBrightestDirection) {
  std::mt19937 rng(7);
  for (const glm::vec3 sun :
       {glm::vec3(0.3f, 0.8f, -0.2f), glm::vec3(-0.7f, 0.1f, 0.4f), glm::vec3(0.0f, 1.0f, 0.0f)}) {
    const SkyParams s = DefaultSky(sun, glm::vec3(2.0f, 1.9f, 1.7f));
    const float at_sun = Luminance(Sky(s, s.sun_dir));
    for (int i = 0; i < 10000; ++i) {
      const glm::vec3 d = RandomDirection(rng);
      ASSERT_LT(Luminance(Sky(s, d)), at_sun) << d.x << ", " << d.y << ", " << d.z;
    }
    // ... and the disc is small: 2 degrees away only the glow is left.
    const glm::vec3 t = glm::normalize(glm::cross(s.sun_dir, glm::vec3(0.3f, 0.1f, 0.9f)));
    const glm::vec3 off = glm::normalize(s.sun_dir + 0.035f * t);
    EXPECT_LT(Luminance(Sky(s, off)), 0.1f * at_sun);
  }
}

// E(n) / pi of the sky for normal n (what the irradiance cube stores), by the same quadrature
// as shaders/ibl_irradiance.comp: cube texels weighted by solid angle times cos+.
glm::vec3 SkyIrradiance(const SkyParams& s, glm::vec3 n, int size) {
  glm::dvec3 sum(0.0);
  double weight = 0.0;
  for (uint32_t f = 0; f < 6; ++f) {
    for (int j = 0; j < size; ++j) {
      for (int i = 0; i < size; ++i) {
        const glm::vec2 uv((i + 0.5f) / size, (j + 0.5f) / size);
        const glm::vec3 d = CubeDirection(f, uv);
        const double a = 2.0 * uv.x - 1.0, b = 2.0 * uv.y - 1.0;
        const double solid_angle = 1.0 / std::pow(1.0 + a * a + b * b, 1.5);  // up to a constant
        const double c = std::max(0.0f, glm::dot(n, d));
        sum += glm::dvec3(Sky(s, d)) * (solid_angle * c);
        weight += solid_angle * c;
      }
    }
  }
  return glm::vec3(sum / weight);
}

TEST(IblSkyTest, AsBrightAsTheHemisphereAmbient) {
  // The hemisphere ambient lights a surface facing up with the sky colour and one facing down
  // with the ground colour; the default procedural sky gives the same irradiance.
  const SkyParams s = DefaultSky(glm::vec3(0.0f), glm::vec3(0.0f));
  EXPECT_TRUE(
      Near(SkyIrradiance(s, glm::vec3(0, 1, 0), 64), glm::vec3(0.40f, 0.52f, 0.75f), 0.01f));
  EXPECT_TRUE(
      Near(SkyIrradiance(s, glm::vec3(0, -1, 0), 64), glm::vec3(0.24f, 0.21f, 0.18f), 0.01f));
  // Sideways: between the two, like the hemisphere's (0.32, 0.365, 0.465).
  EXPECT_TRUE(
      Near(SkyIrradiance(s, glm::vec3(1, 0, 0), 64), glm::vec3(0.32f, 0.365f, 0.465f), 0.05f));
}

TEST(IblSkyTest, DefaultSkyNormalizesTheSun) {
  const SkyParams s = DefaultSky(glm::vec3(0.0f, 3.0f, 4.0f), glm::vec3(1.0f));
  EXPECT_TRUE(Near(s.sun_dir, glm::vec3(0.0f, 0.6f, 0.8f), 1e-6f));
  EXPECT_TRUE(Near(DefaultSky(glm::vec3(0.0f), glm::vec3(1.0f)).sun_dir, glm::vec3(0.0f), 0.0f));
  const float nan = std::nanf("");
  EXPECT_TRUE(
      Near(DefaultSky(glm::vec3(nan, 0.0f, 1.0f), glm::vec3(1.0f)).sun_dir, glm::vec3(0.0f), 0.0f));
}

}  // namespace
}  // namespace tessera

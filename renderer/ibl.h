#pragma once
// Image-based lighting on the CPU: reference implementations of what the IBL compute shaders
// compute (pure math, unit-tested without a device), and the default procedural sky.
//
// Conventions shared with shaders/ibl_*.comp and shaders/common/{cube,ibl_sky,ibl_ggx}.glsl:
//  - Cube faces are layers 0..5 = +X, -X, +Y, -Y, +Z, -Z, addressed as Vulkan's samplerCube
//    does (spec "Cube Map Face Selection"); uv in [0, 1]^2 is (s, t): s along the image's x,
//    t along its y. A texel's centre is uv = (texel + 0.5) / size.
//  - The irradiance cube stores E(n) / pi (Lambert radiance for albedo 1): multiply it by the
//    diffuse colour. A uniform environment of radiance L stores L.
//  - The prefiltered specular cube's level m holds the GGX-filtered (N = V = R) environment for
//    the perceptual roughness the caller chose for it (level 0: roughness 0, the env itself).
//  - The BRDF LUT is 64 x 64 rg16f: x -> n_dot_v = (x + 0.5) / 64, y -> perceptual roughness
//    = (y + 0.5) / 64; it holds (A, B) with specular albedo = F0 * A + B.
#include <cstdint>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace tessera {

// The split-sum BRDF LUT's size and sample count (shaders/ibl_brdf.comp).
inline constexpr uint32_t kIblBrdfLutSize = 64;
inline constexpr uint32_t kIblBrdfSamples = 512;

// The procedural sky's parameters (shaders/common/ibl_sky.glsl). The default colours match the
// hemisphere ambient's brightness (sky (0.40, 0.52, 0.75), ground (0.24, 0.21, 0.18)): with no
// sun, a surface facing up gets the irradiance E / pi ~= (0.40, 0.52, 0.75) and one facing down
// ~= the ground colour, while the sky itself brightens towards the horizon.
struct SkyParams {
  glm::vec3 sun_dir{0.0f};    // towards the sun, normalized; zero: no sun
  glm::vec3 sun_color{0.0f};  // sun radiance scale (glow and disc are multiples of it)
  glm::vec3 zenith{0.36f, 0.49f, 0.744f};
  glm::vec3 horizon{0.60f, 0.67f, 0.78f};
  glm::vec3 ground{0.24f, 0.21f, 0.18f};
};

// The default sky with a sun towards `sun_dir` (normalized here; a zero or non-finite vector
// gives no sun) of radiance scale `sun_color`.
SkyParams DefaultSky(glm::vec3 sun_dir, glm::vec3 sun_color);

// The split-sum environment BRDF (A, B) for perceptual `roughness` (alpha = roughness^2) at
// `n_dot_v`, estimated with `samples` Hammersley points exactly as shaders/ibl_brdf.comp does
// (double precision inside). Specular albedo = F0 * A + B.
glm::vec2 IntegrateBrdfReference(float n_dot_v, float roughness, uint32_t samples);

// The unit direction through point `uv` of cube face `face` (shaders/common/cube.glsl).
glm::vec3 CubeDirection(uint32_t face, glm::vec2 uv);

// The sky radiance along `dir` (shaders/common/ibl_sky.glsl, ProceduralSky, line for line).
glm::vec3 ProceduralSkyReference(glm::vec3 dir, glm::vec3 sun_dir, glm::vec3 sun_color,
                                 glm::vec3 zenith, glm::vec3 horizon, glm::vec3 ground);

}  // namespace tessera

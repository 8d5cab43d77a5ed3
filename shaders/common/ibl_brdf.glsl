#ifndef TESSERA_IBL_BRDF_GLSL
#define TESSERA_IBL_BRDF_GLSL
// Image-based lighting, step 4: the split-sum environment BRDF lookup table (Karis, UE4 2013),
// the second factor of the split sum, for the BRDF of shading.glsl (GGX D, height-correlated
// Smith visibility V, Schlick Fresnel). 64 x 64, one invocation per texel:
//   x: n_dot_v = (x + 0.5) / 64,  y: perceptual roughness = (y + 0.5) / 64 (alpha = r^2)
// so a linear sampler at uv = (n_dot_v, roughness) reads the table with clamp to edge. Each
// texel stores (A, B): the directional albedo of the specular lobe for F0 is F0 * A + B.
//
// Derivation. With f = D V F (V = G / (4 n_dot_l n_dot_v), the shading.glsl convention) and
// Schlick F = F0 + (1 - F0) Fc, Fc = (1 - v_dot_h)^5, i.e. F = F0 (1 - Fc) + Fc:
//   integral f n_dot_l dl = F0 * integral D V (1 - Fc) n_dot_l dl + integral D V Fc n_dot_l dl.
// Half vectors h are drawn with pdf D n_dot_h (IblSampleGgx), so l = reflect(-v, h) has
// pdf D n_dot_h / (4 v_dot_h), and each sample's estimate of D V n_dot_l / pdf(l) is
//   G_vis = V * n_dot_l * 4 * v_dot_h / n_dot_h        (D cancels)
// giving A = mean(G_vis (1 - Fc)), B = mean(G_vis Fc). Samples with l below the surface count
// as zero. renderer/ibl.cpp (IntegrateBrdfReference) computes the same in double precision.
#include "common/ibl_ggx.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

// RG16F, or RGBA16F (.rg used) on devices without R16G16_SFLOAT storage images, one of Vulkan's
// optional storage formats (renderer/ibl_maps.cpp; DeviceInfo::storage_rg16f).
#ifdef IBL_LUT_RGBA16F
layout(set = 0, binding = 0, rgba16f) writeonly uniform image2D u_lut;
#else
layout(set = 0, binding = 0, rg16f) writeonly uniform image2D u_lut;
#endif

const uint kLutSize = 64;
const uint kSamples = 512;

void main() {
  uvec2 id = gl_GlobalInvocationID.xy;
  if (id.x >= kLutSize || id.y >= kLutSize) return;
  float n_dot_v = (float(id.x) + 0.5) / float(kLutSize);
  float roughness = (float(id.y) + 0.5) / float(kLutSize);
  float alpha = roughness * roughness;
  // Tangent space: n = +Z, v in the xz plane.
  vec3 v = vec3(sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v);

  float a = 0.0;
  float b = 0.0;
  for (uint k = 0u; k < kSamples; ++k) {
    vec3 h = IblSampleGgx(IblHammersley(k, kSamples), alpha);
    float v_dot_h = dot(v, h);
    vec3 l = 2.0 * v_dot_h * h - v;
    float n_dot_l = l.z;
    float n_dot_h = h.z;
    if (n_dot_l > 0.0 && v_dot_h > 0.0) {
      float vis = VisibilitySmithGgxCorrelated(n_dot_v, n_dot_l, alpha);
      float g_vis = vis * n_dot_l * 4.0 * v_dot_h / n_dot_h;
      float fc = pow(max(1.0 - v_dot_h, 0.0), 5.0);  // v_dot_h may round above 1
      a += (1.0 - fc) * g_vis;
      b += fc * g_vis;
    }
  }
  imageStore(u_lut, ivec2(id), vec4(a, b, 0.0, 0.0) / float(kSamples));
}
#endif

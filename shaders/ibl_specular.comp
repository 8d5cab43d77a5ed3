#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// Image-based lighting, step 3: one mip level of the prefiltered specular cube map, the first
// factor of Karis' split sum (UE4, 2013): the environment convolved with the GGX lobe of this
// level's roughness under the assumption N = V = R, weighted by n_dot_l. One invocation per
// texel of the level, gl_GlobalInvocationID.z = face; the output is a view of that one level.
//
//   out(R) = sum_k L(l_k) n_dot_l_k / sum_k n_dot_l_k,  l_k = reflect(-V, h_k), h_k ~ GGX
//
// (the n_dot_l weighting is Karis'; it is not an exact estimator, but it is what the split sum
// expects). Filtered importance sampling (Colbert and Krivanek, GPU Gems 3 ch. 20) lets a few
// samples do: each reads the env at the mip whose texels cover the solid angle its sample stands
// for, Omega_s = 1 / (N pdf), against a mip-0 texel's Omega_p = 4 pi / (6 size0^2):
//
//   lod = 0.5 * log2(Omega_s / Omega_p) + 1     (0.5: the mip halves the size, quarters area;
//                                                +1: Colbert's bias, smoother for few samples)
//
// with pdf(l) = D(h) n_dot_h / (4 v_dot_h) = D(h) / 4, since n_dot_h = v_dot_h when N = V.
// Roughness 0 is the mirror: the env itself at lod 0.
#include "common/cube.glsl"
#include "common/ibl_ggx.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(set = 0, binding = 0) uniform samplerCube u_env;  // linear, mip chain made by blits
layout(set = 0, binding = 1, rgba16f) uniform writeonly image2DArray u_out;  // one mip level
layout(push_constant) uniform Push { TS_PUSH_IBL_SPECULAR } push;  // common/gpu_types.h

// alpha below this is treated as this: D at n_dot_h = 1 is 1 / (pi alpha^2), and alpha = 0
// would make it 0 / 0. (The smallest shaded roughness, 0.03, has alpha 9e-4.)
const float kMinAlpha = 1e-4;

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint size = push.size.x;
  if (id.x >= size || id.y >= size || id.z >= 6u) return;
  vec3 n = CubeDirection(id.z, (vec2(id.xy) + 0.5) / float(size));
  float roughness = push.params.x;
  if (roughness <= 0.0) {
    imageStore(u_out, ivec3(id), vec4(textureLod(u_env, n, 0.0).rgb, 1.0));
    return;
  }
  float alpha = max(roughness * roughness, kMinAlpha);
  uint count = max(uint(push.params.w), 1u);
  float max_lod = max(push.params.z - 1.0, 0.0);
  float size0 = max(push.params.y, 1.0);
  float omega_p = 4.0 * kPi / (6.0 * size0 * size0);

  vec3 sum = vec3(0.0);
  float weight = 0.0;
  for (uint k = 0u; k < count; ++k) {
    vec3 h = IblTangentToWorld(IblSampleGgx(IblHammersley(k, count), alpha), n);
    float n_dot_h = dot(n, h);  // = v_dot_h (N = V), > 0 by construction
    vec3 l = 2.0 * n_dot_h * h - n;
    float n_dot_l = dot(n, l);
    if (n_dot_l > 0.0) {
      float pdf = DistributionGgx(n_dot_h, alpha) * 0.25;
      float omega_s = 1.0 / (float(count) * pdf);
      float lod = clamp(0.5 * log2(omega_s / omega_p) + 1.0, 0.0, max_lod);
      sum += textureLod(u_env, l, lod).rgb * n_dot_l;
      weight += n_dot_l;
    }
  }
  // weight > 0 always (the sample with h = n has n_dot_l = 1); guarded for safety.
  vec3 color = weight > 0.0 ? sum / weight : textureLod(u_env, n, 0.0).rgb;
  imageStore(u_out, ivec3(id), vec4(color, 1.0));
}

#version 460
#extension GL_GOOGLE_include_directive : require
#include "common/gpu_types.h"
// Image-based lighting, step 2: the diffuse irradiance cube map, by brute-force integration over
// every texel of one (small) mip level of the environment. One invocation per output texel,
// gl_GlobalInvocationID.z = face. For the output direction n it stores
//
//   E(n) / pi = (1 / pi) * integral over the sphere of L(w) max(n . w, 0) dw,
//
// the Lambert radiance for albedo 1: the shader multiplies it by the diffuse colour directly
// (no 1/pi, no pi). A uniform environment of radiance L stores exactly L.
//
// Discretisation: texel i of the chosen level has centre direction w_i and exact solid angle
// W_i (common/cube.glsl), with c_i = max(n . w_i, 0). Since the integral of max(n . w, 0) over
// the sphere is exactly pi,
//
//   E(n) / pi = integral(L cos+) / integral(cos+) ~= sum(W_i c_i L_i) / sum(W_i c_i),
//
// which is what is stored. Normalising by the discrete sum(W_i c_i) rather than by the constant
// pi (or by sum(W_i) / 4, the same thing in the limit) makes a uniform L come out as exactly L
// at any level size: the factor 1/pi and the quadrature error of the cosine cancel.
//
// Cost: 6 * z^2 env lookups per output texel (those with c_i > 0, i.e. about half, are taken).
// Irradiance is very smooth: a 16^2 env level and a 16^2 or 32^2 output are plenty.
#include "common/cube.glsl"

layout(local_size_x = 8, local_size_y = 8, local_size_z = 1) in;

layout(set = 0, binding = 0) uniform samplerCube u_env;  // linear, mip chain made by blits
layout(set = 0, binding = 1, rgba16f) uniform writeonly image2DArray u_out;
layout(push_constant) uniform Push { TS_PUSH_IBL_IRRADIANCE } push;  // common/gpu_types.h

void main() {
  uvec3 id = gl_GlobalInvocationID;
  uint out_size = push.size.x;
  if (id.x >= out_size || id.y >= out_size || id.z >= 6u) return;
  vec3 n = CubeDirection(id.z, (vec2(id.xy) + 0.5) / float(out_size));

  uint z = max(push.size.z, 1u);
  float lod = float(push.size.y);
  float texel = 2.0 / float(z);  // a texel's width in face coordinates ([-1, 1] per face)
  vec3 sum = vec3(0.0);
  float weight = 0.0;
  for (uint j = 0u; j < z; ++j) {
    float y0 = float(j) * texel - 1.0;
    for (uint i = 0u; i < z; ++i) {
      float x0 = float(i) * texel - 1.0;
      // The same (i, j) has the same solid angle on every face: compute it once for all six.
      float solid_angle = CubeRectSolidAngle(x0, y0, x0 + texel, y0 + texel);
      // Sampling at the texel's centre with an integer lod returns exactly that texel.
      vec2 uv = (vec2(i, j) + 0.5) / float(z);
      for (uint face = 0u; face < 6u; ++face) {
        vec3 w = CubeDirection(face, uv);
        float c = dot(n, w);
        if (c > 0.0) {
          sum += (solid_angle * c) * textureLod(u_env, w, lod).rgb;
          weight += solid_angle * c;
        }
      }
    }
  }
  vec3 irradiance = weight > 0.0 ? sum / weight : vec3(0.0);
  imageStore(u_out, ivec3(id), vec4(irradiance, 1.0));
}

#version 460
#extension GL_GOOGLE_include_directive : require
// Bloom's upsample as a compute shader (common/bloom_up.glsl): the output is a storage image after
// the inputs.
#define TESSERA_COMPUTE
#include "common/bloom_up.glsl"

layout(set = 0, binding = 2, rgba16f) uniform writeonly image2D u_out;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  ivec2 size = imageSize(u_out);
  if (any(greaterThanEqual(p, size))) return;
  v_uv = (vec2(p) + 0.5) / vec2(size);
  PostMain();
  imageStore(u_out, p, out_color);
}

#version 460
#extension GL_GOOGLE_include_directive : require
// TAA as a compute shader (common/taa.glsl): the outputs are storage images after the inputs.
#define TESSERA_COMPUTE
#include "common/taa.glsl"

layout(set = 0, binding = 4, rgba16f) uniform writeonly image2D u_out_color;
layout(set = 0, binding = 5, rgba16f) uniform writeonly image2D u_out_history;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(p, imageSize(u_out_color)))) return;
  PostMain();
  imageStore(u_out_color, p, out_color);
  imageStore(u_out_history, p, out_history);
}

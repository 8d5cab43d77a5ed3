#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's geometric AA as a compute shader (common/geometric_aa.glsl): the output is a
// storage image after the inputs.
#define TESSERA_COMPUTE
#include "common/geometric_aa.glsl"

layout(set = 0, binding = 3, rgba16f) uniform writeonly image2D u_out_color;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(p, imageSize(u_out_color)))) return;
  PostMain();
  imageStore(u_out_color, p, out_color);
}

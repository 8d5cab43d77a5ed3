#version 460
#extension GL_GOOGLE_include_directive : require
// The tonemap as a compute shader (common/tonemap.glsl) into an RGBA8 UNORM storage image, sRGB
// encoded here (an sRGB format is no storage format): the bytes the sRGB target would hold.
#define TESSERA_COMPUTE
#include "common/tonemap.glsl"
#include "common/srgb.glsl"

layout(set = 0, binding = 5, rgba8) uniform writeonly image2D u_out;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(p, imageSize(u_out)))) return;
  PostMain();
  imageStore(u_out, p, vec4(EncodeSrgb(out_color.rgb), out_color.a));
}

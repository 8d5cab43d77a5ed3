#version 460
#extension GL_GOOGLE_include_directive : require
// FXAA as a compute shader (common/fxaa.glsl) into an RGBA8 UNORM storage image, sRGB encoded
// here: the bytes fxaa.frag's sRGB target would hold.
#define TESSERA_COMPUTE
#include "common/fxaa.glsl"
#include "common/srgb.glsl"

layout(set = 0, binding = 1, rgba8) uniform writeonly image2D u_out;

void main() {
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(p, imageSize(u_out)))) return;
  PostMain();
  imageStore(u_out, p, vec4(EncodeSrgb(out_color.rgb), out_color.a));
}

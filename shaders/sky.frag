#version 460
#extension GL_GOOGLE_include_directive : require
// Background: drawn as a full-screen triangle at the far plane (depth 0 in reverse Z) after the
// opaque geometry, so only pixels no surface covered run this shader.
#include "common/scene.glsl"
#include "common/sky.glsl"

layout(location = 0) out vec4 out_color;

void main() {
  // The camera ray through the pixel's centre, as the visibility pipeline's background takes it.
  out_color = vec4(SkyRadiance(normalize(RayDirection(gl_FragCoord.xy))), 1.0);
}

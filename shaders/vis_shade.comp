#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility pipeline's shading: one dispatch per material (its set 1 bound, as a forward
// draw's) over the pixels vis_classify listed for it, each shaded once. The surface is rebuilt
// from the pixel's visibility id (common/vis_surface.glsl) at the pixel's centre and shaded by
// the forward path's material and lighting (common/shading.glsl).
#define TESSERA_COMPUTE
vec2 g_pixel;  // the pixel's centre, for shading.glsl's tile and AO lookups
#define SHADING_PIXEL g_pixel
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/textures.glsl"
#include "common/shadows.glsl"
#include "common/shading.glsl"
#include "common/vis.glsl"
#include "common/vis_surface.glsl"

layout(local_size_x = kShadeGroupSize) in;

layout(push_constant) uniform Push { TS_PUSH_SHADE } push;
layout(set = kVisSet, binding = kShadeBindingId) uniform usampler2D u_vis_id;
layout(set = kVisSet, binding = kShadeBindingColor, rgba16f) uniform writeonly image2D u_color;
layout(set = kVisSet, binding = kShadeBindingEntries, std430) readonly buffer EntryBlock {
  GpuShadeEntry entries[];
};
layout(set = kVisSet, binding = kShadeBindingPixels, std430) readonly buffer PixelBlock {
  uint pixels[];
};

void main() {
  uint m = push.params.x;
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint i = group * kShadeGroupSize + gl_LocalInvocationIndex;
  if (i >= entries[m].dispatch.w) return;
  uint packed = pixels[entries[m].list.x + i];
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  g_pixel = vec2(p) + 0.5;
  uint id = texelFetch(u_vis_id, p, 0).r;
  Triangle tri = LoadTriangle(id);
  vec3 b = Barycentrics(tri.p0, tri.e1, tri.e2, RayDirection(g_pixel));
  imageStore(u_color, p, vec4(ShadeSurface(VisSurface(tri, b, g_pixel), false).rgb, 1.0));
}

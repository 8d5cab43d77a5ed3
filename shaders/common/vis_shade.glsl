// The visibility pipeline's and vis_mlaa's shading (vis_shade.comp, vis_shade_mlaa.comp): one
// dispatch per material (its set 1 bound, as a forward draw's) over the pixels vis_classify
// listed for it, each shaded once. The surface is rebuilt from the pixel's visibility id
// (common/vis_surface.glsl) and shaded by the forward path's material and lighting
// (common/shading.glsl): at the pixel's centre, or with VIS_MLAA at the mean position of the
// samples the resolve gave the pixel's surface (vis_resolve.comp). With SHADE_ALL_MATERIALS
// (vis_shade_all*.comp, DeviceInfo::shade_all_materials) one dispatch shades every pixel and the
// sky instead, with no lists (below).
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

#ifdef SHADE_ALL_MATERIALS
layout(push_constant) uniform Push { TS_PUSH_SHADE } push;
layout(set = kVisSet, binding = kShadeBindingEntries, std430) buffer EntryBlock {
  GpuShadeEntry entries[];
};
layout(set = kVisSet, binding = kShadeBindingPixels, std430) readonly buffer PixelBlock {
  uint pixels[];
};
#else
#include "common/shade_lists.glsl"
#endif
layout(set = kVisSet, binding = kShadeBindingId) uniform usampler2D u_vis_id;
layout(set = kVisSet, binding = kShadeBindingColor, rgba16f) uniform writeonly image2D u_color;
#ifdef VIS_MLAA
layout(set = kVisSet, binding = kShadeBindingCoverage) uniform usampler2D u_vis_coverage;
#include "common/runner_up_shading.glsl"
#endif

#ifdef SHADE_ALL_MATERIALS
// One dispatch shades every material (DeviceInfo::shade_all_materials, common/textures.glsl): over
// the frame in 8x8 tiles (kClassifyTile, as the classification's), a pixel an invocation, or with
// SHADE_RUNNER_UPS over vis_mlaa's blend list, an entry an invocation (the runner-up surfaces no
// neighbour shows). push.params: x the sky's entry, y vis_mlaa's edge list's entry, z 1 where the
// shading counts each surface in its material's entry (one sample: vis_mlaa's resolve counted
// them). The sky's pixels are counted in the sky's entry, as the classification counts them.
#include "common/shade_append.glsl"
#include "common/blend_list.glsl"

// The colour of the surface of visibility id `id` at `pixel`, shaded with its material `m`.
vec3 ShadeId(uint id, uint m, vec2 pixel) {
  Triangle tri = LoadTriangle(id);
  material = materials[m];
  vec3 b = Barycentrics(tri.p0, tri.e1, tri.e2, RayDirection(pixel));
  return ShadeSurface(VisSurface(tri, b, pixel), false).rgb;
}
uint MaterialOf(uint id) { return DrawableIds(VisDrawable(id, frame.aa.x)).y; }

void main() {
#ifdef SHADE_RUNNER_UPS
  uint entry;
  if (!BlendListEntry(push.params.y, entry)) return;
  uvec2 record = runner_ups[entry];
  if ((record.y & 0xffu) == 0u || RunnerUpSource(record.y) != kRunnerUpShaded) return;
  uint packed = pixels[entry];
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  g_pixel = vec2(p) + 0.5;
  vec2 pixel = vec2(p) + RunnerUpMean(record.y);
  // The sky where it is the runner-up: in the direction of its samples' mean.
  StoreRunnerUpColor(entry, record.x == 0u ? VisBackground(pixel, kIblCode)
                                           : ShadeId(record.x, MaterialOf(record.x), pixel));
#else
  uint l = gl_LocalInvocationIndex;
  ivec2 p = ivec2(gl_WorkGroupID.xy) * int(kClassifyTile) +
            ivec2(l % kClassifyTile, l / kClassifyTile);
  if (any(greaterThanEqual(p, ivec2(frame.counts.zw)))) return;
  g_pixel = vec2(p) + 0.5;
  uint id = texelFetch(u_vis_id, p, 0).r;
  if (id == 0u) {  // the sky (or a debug view's background), at the pixel's centre
    if (push.params.w != 0u) Append(push.params.x, kCountBackground);  // a capture asks
    imageStore(u_color, p, vec4(VisBackground(g_pixel, kIblCode), 1.0));
    return;
  }
  uint m = MaterialOf(id);
  if (push.params.z != 0u) Append(m, kCountPixels);
#ifdef VIS_MLAA
  // At the mean position of the samples the resolve gave the pixel's surface, in the triangle
  // holding it (common/vis_resolve.glsl, ContainingId).
  vec2 pixel = vec2(p) + CoverageMean(texelFetch(u_vis_coverage, p, 0).r);
#else
  vec2 pixel = g_pixel;
#endif
  imageStore(u_color, p, vec4(ShadeId(id, m, pixel), 1.0));
#endif
}
#else
void main() {
  uint m = push.params.x;
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint i = group * kShadeGroupSize + gl_LocalInvocationIndex;
  if (i >= entries[m].dispatch.w) return;
  uint packed = pixels[entries[m].list.x + i];
#ifdef VIS_MLAA
  // A runner-up surface (kRunnerUpEntry | its edge list index): its id and samples are the
  // resolve's record, its colour goes to the edge colours for geometric AA.
  uint runner_up = packed & ~kRunnerUpEntry;
  bool is_runner_up = (packed & kRunnerUpEntry) != 0u;
  if (is_runner_up) packed = pixels[runner_up];
#endif
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  g_pixel = vec2(p) + 0.5;
#ifdef VIS_MLAA
  uint id;
  vec2 mean;
  if (is_runner_up) {
    uvec2 record = runner_ups[runner_up];
    id = record.x;
    mean = RunnerUpMean(record.y);
  } else {
    id = texelFetch(u_vis_id, p, 0).r;
    mean = CoverageMean(texelFetch(u_vis_coverage, p, 0).r);
  }
  // The resolve gave the id whose triangle holds the mean position where one of the surface's
  // samples' triangles does (common/vis_resolve.glsl, ContainingId).
  vec2 pixel = vec2(p) + mean;
  Triangle tri = LoadTriangle(id);
  vec3 b = Barycentrics(tri.p0, tri.e1, tri.e2, RayDirection(pixel));
  vec3 color = ShadeSurface(VisSurface(tri, b, pixel), false).rgb;
  if (is_runner_up) {
    StoreRunnerUpColor(runner_up, color);
    return;
  }
  imageStore(u_color, p, vec4(color, 1.0));
#else
  uint id = texelFetch(u_vis_id, p, 0).r;
  vec2 pixel = g_pixel;
  Triangle tri = LoadTriangle(id);
  vec3 b = Barycentrics(tri.p0, tri.e1, tri.e2, RayDirection(pixel));
  imageStore(u_color, p, vec4(ShadeSurface(VisSurface(tri, b, pixel), false).rgb, 1.0));
#endif
}
#endif

// The visibility pipeline's background (vis_sky.comp, vis_sky_mlaa.comp): the sky (or a debug
// view's plain background) at the pixels vis_classify listed as covered by no surface, each once;
// with VIS_MLAA also where the sky is a pixel's runner-up surface (vis_resolve.comp), in the
// direction of its samples' mean, into the edge colours.
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/vis.glsl"

layout(local_size_x = kShadeGroupSize) in;

#include "common/shade_lists.glsl"
layout(set = kVisSet, binding = kShadeBindingColor, rgba16f) uniform writeonly image2D u_color;
#ifdef VIS_MLAA
#include "common/runner_up_shading.glsl"
#endif

// Linear HDR background of debug views (as the forward pass's clear).
const vec3 kDebugBackground = vec3(0.030, 0.034, 0.042);

void main() {
  uint sky = push.params.x;
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint i = group * kShadeGroupSize + gl_LocalInvocationIndex;
  if (i >= entries[sky].dispatch.w) return;
  uint packed = pixels[entries[sky].list.x + i];
  vec2 at = vec2(0.5);  // in the pixel
#ifdef VIS_MLAA
  uint runner_up = packed & ~kRunnerUpEntry;
  bool is_runner_up = (packed & kRunnerUpEntry) != 0u;
  if (is_runner_up) {
    packed = pixels[runner_up];
    at = RunnerUpMean(runner_ups[runner_up].y);
  }
#endif
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  vec3 color = kDebugBackground;
  if (frame.counts.y == kDebugNone) {
    vec2 ndc = (vec2(p) + at) / vec2(frame.counts.zw) * 2.0 - 1.0;
    vec4 world = frame.inv_view_proj * vec4(ndc, 1.0, 1.0);  // on the near plane
    color = SkyRadiance(normalize(world.xyz / world.w - frame.camera_position.xyz));
  }
#ifdef VIS_MLAA
  if (is_runner_up) {
    StoreRunnerUpColor(runner_up, color);
    return;
  }
#endif
  imageStore(u_color, p, vec4(color, 1.0));
}

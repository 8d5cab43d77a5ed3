// vis_mlaa's sky where it is a pixel's runner-up surface (vis_resolve.comp) and no neighbour shows
// it (vis_sky_mlaa.comp): the sky (or a debug view's plain background) in the direction of its
// samples' mean, into the edge colours. (Where the sky is the surface a pixel shows, the
// classification writes it: vis_classify.glsl; a plain entry in the sky's list is shaded at the
// pixel's centre all the same.) Needs VIS_MLAA defined (the runner-up records).
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/vis.glsl"

layout(local_size_x = kShadeGroupSize) in;

#include "common/shade_lists.glsl"
layout(set = kVisSet, binding = kShadeBindingColor, rgba16f) uniform writeonly image2D u_color;
#include "common/runner_up_shading.glsl"

void main() {
  uint sky = push.params.x;
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint i = group * kShadeGroupSize + gl_LocalInvocationIndex;
  if (i >= entries[sky].dispatch.w) return;
  uint packed = pixels[entries[sky].list.x + i];
  vec2 at = vec2(0.5);  // in the pixel
  uint runner_up = packed & ~kRunnerUpEntry;
  bool is_runner_up = (packed & kRunnerUpEntry) != 0u;
  if (is_runner_up) {
    packed = pixels[runner_up];
    at = RunnerUpMean(runner_ups[runner_up].y);
  }
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  vec3 color = VisBackground(vec2(p) + at, true);
  if (is_runner_up) {
    StoreRunnerUpColor(runner_up, color);
    return;
  }
  imageStore(u_color, p, vec4(color, 1.0));
}

// vis_mlaa's sky where it is a pixel's runner-up surface (vis_resolve.comp) and no neighbour shows
// it (vis_sky_mlaa.comp): the sky (or a debug view's plain background) in the direction of its
// samples' mean, into the edge colours. Where the sky is the surface a pixel shows, the
// classification writes it (vis_classify.glsl), so the sky's list holds runner-ups only. (Where
// the shading is one dispatch, vis_shade_all_runner_ups.comp shades the sky's runner-ups.) Needs
// VIS_MLAA defined (the runner-up records).
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/vis.glsl"

layout(local_size_x = kShadeGroupSize) in;

#include "common/shade_lists.glsl"
#include "common/runner_up_shading.glsl"

void main() {
  uint sky = push.params.x;
  uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
  uint i = group * kShadeGroupSize + gl_LocalInvocationIndex;
  if (i >= entries[sky].dispatch.w) return;
  // kRunnerUpEntry | the edge list entry whose runner-up surface the sky is.
  uint runner_up = pixels[entries[sky].list.x + i] & ~kRunnerUpEntry;
  uint packed = pixels[runner_up];
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  vec2 at = RunnerUpMean(runner_ups[runner_up].y);  // in the pixel
  StoreRunnerUpColor(runner_up, VisBackground(vec2(p) + at, true));
}

// The visibility pipeline's classification (vis_classify.comp, and vis_classify_atomic.comp for
// devices without subgroup ballots; vis_mlaa's: the _mlaa ones; the scan for both:
// vis_classify_scan.comp): which material each pixel shows, and per material the list
// of its pixels, so that the shading pass runs one indirect dispatch per material over exactly
// its pixels (every invocation shades a pixel; lavapipe runs masked-off lanes at full cost, so a
// dispatch over tiles would shade tiles' other pixels too). Its modes (specialization
// constant 0, a pipeline per mode: lavapipe runs the code of untaken branches under a lane mask,
// so one pipeline for every mode cost the fill the scan's loops; the scan is a shader of its
// own, below):
//  - kClassifyCount: count each material's pixels;
//  - kClassifyScan (one workgroup): each material's first list entry and its dispatch size, and
//    the sizes of the dispatches below (SkyDispatches). Its own shader, vis_classify_scan.comp
//    (VIS_CLASSIFY_SCAN), for every device and both pipelines: the only step with workgroup
//    barriers and shared memory. SwiftShader runs each workgroup of a shader that has barriers
//    as coroutines, reachable or not: the fill's 8x8 workgroups cost 2.8x as much (DamagedHelmet
//    640x360, visibility pipeline: the classification 90 -> 32 ms);
//  - kClassifyFill or kClassifyFillListSky (the other's dispatch is empty): append each pixel to
//    its material's list, and write the background where no surface is, or list those pixels
//    (counted in the sky entry's list.z where kCountSky says so);
//  - kClassifySky: the background at each listed pixel.
// The appends of a subgroup's lanes that show one material are one atomic (WaveMatch by
// peeling: the lanes of the first lane's material take their ranks from a ballot).
// With VIS_MLAA (vis_classify_mlaa.comp) the resolve has counted each pixel's surface (and each
// runner-up surface left to be shaded) in its material's entry, so kClassifyCount does not run;
// the runner-ups are listed too, as kRunnerUpEntry | their edge list index, by a step dispatched
// over the resolve's blend list (the edge pixels with a runner-up: kClassifyFillRunnerUps).
#include "common/scene.glsl"
#include "common/sky.glsl"
#include "common/vis.glsl"

layout(local_size_x = kClassifyTile, local_size_y = kClassifyTile) in;

layout(push_constant) uniform Push { TS_PUSH_SHADE } push;
layout(set = kVisSet, binding = kShadeBindingId) uniform usampler2D u_vis_id;
layout(set = kVisSet, binding = kShadeBindingEntries, std430) buffer EntryBlock {
  GpuShadeEntry entries[];
};
// (Read by vis_mlaa's runner-up step: the resolve's blend list.)
layout(set = kVisSet, binding = kShadeBindingPixels, std430) buffer PixelBlock {
  uint pixels[];
};
layout(set = kVisSet, binding = kShadeBindingColor, rgba16f) uniform writeonly image2D u_color;
#ifdef VIS_MLAA
layout(set = kVisSet, binding = kShadeBindingRunnerUps, std430) readonly buffer RunnerUpBlock {
  uvec2 runner_ups[];
};
#endif

const uint kNoMaterial = 0xffffffffu;

#include "common/shade_append.glsl"
#include "common/blend_list.glsl"

layout(constant_id = 0) const uint kMode = kClassifyCount;
// Whether the frame has IBL (Settings::ibl), whose environment map is the sky: a pipeline each,
// so a frame without it does not pay the map's lookup at every pixel.
layout(constant_id = 1) const bool kBackgroundIbl = false;
// Whether the fill counts the pixels it writes the sky at (frames with a FrameCapture: the tests
// check that every pixel is listed or the sky): one subgroup atomic per 8 lanes that hold sky,
// about 8 ms of a mostly-sky 1280x720 frame on lavapipe, which other frames skip.
layout(constant_id = 2) const bool kCountSky = false;

// The sky: where a frame shows little of it, the fill lists its pixels (kClassifyFillListSky)
// and kClassifySky writes the background there, a pixel an invocation; else the fill writes it
// (kClassifyFill). The scan knows how many pixels show the sky (those no list counted), so it
// sizes one fill's dispatch to the frame and the other's to nothing. lavapipe ran the
// background's code (with IBL, the environment map's lookup) for every lane of the fill, sky or
// not: 5.5 ms of Sponza's 12.3 ms classification in its full stack, where the sky is 1% of the
// frame. Listing the pixels costs more where the sky shows much (1280x720, one sample:
// DamagedHelmet, mostly sky, classification and shading 68-72 -> 96-128 ms listing them all).
uint SkyListEntry() { return push.params.y + 3u; }  // ShadeBuffers::sky_list_entry
uint FillEntry(bool list_sky) { return push.params.y + (list_sky ? 5u : 4u); }
// The sky is listed where it shows in less than 1 / kListSkyBelow of the frame. Sponza at
// 1280x720 with the sky at 10, 28 and 35% of the frame, two rounds each (one sample), listed
// against written by the fill: classification 11.5 against 13.0-14.8 ms, 12.4-13.0 against
// 12.6-13.1, 14.0-14.2 against 12.7-13.1; with IBL 11.8 against 15.5-16.0, 13.0-13.2 against
// 15.4-15.5, 15.8-16.5 against 15.2-15.3.
const uint kListSkyBelow = 3u;

#ifdef VIS_CLASSIFY_SCAN
shared uint s_sums[kClassifyTile * kClassifyTile];

// (Scan's first invocation.) The materials' lists start at `base` and hold `total` entries: the
// sky's pixels are the frame's less those, less vis_mlaa's runner-ups (counted in the edge
// list's entry), which the lists hold too. The sky's list follows the materials' lists.
void SkyDispatches(uint base, uint total) {
  uint frame_pixels = frame.counts.z * frame.counts.w;
  uint runner_ups = push.params.z != 0u ? entries[push.params.y + 1u].list.x : 0u;
  uint sky = frame_pixels - (total - runner_ups);
  bool list_sky = sky < frame_pixels / kListSkyBelow;
  entries[SkyListEntry()].dispatch = uvec4(DispatchFor(list_sky ? sky : 0u), 0u);
  entries[SkyListEntry()].list = uvec4(base + total, 0u, 0u, 0u);
  uvec4 tiles = uvec4((frame.counts.zw + kClassifyTile - 1u) / kClassifyTile, 1u, 0u);
  entries[FillEntry(list_sky)].dispatch = tiles;
  entries[FillEntry(!list_sky)].dispatch = uvec4(0u, 0u, 1u, 0u);
}

// One workgroup: each invocation sums a run of materials, the workgroup scans the 64 sums, and
// each invocation writes its run's offsets and dispatch sizes.
void Scan() {
  const uint lanes = kClassifyTile * kClassifyTile;
  uint materials = push.params.y + 1u;  // and the sky
  uint run = (materials + lanes - 1u) / lanes;
  uint i = gl_LocalInvocationIndex;
  uint begin = min(i * run, materials), end = min(begin + run, materials);
  uint sum = 0u;
  for (uint m = begin; m < end; ++m) sum += entries[m].dispatch.w;
  s_sums[i] = sum;
  barrier();
  for (uint step = 1u; step < lanes; step *= 2u) {  // inclusive Hillis-Steele scan
    uint add = i >= step ? s_sums[i - step] : 0u;
    barrier();
    s_sums[i] += add;
    barrier();
  }
  // vis_mlaa: the lists follow the resolve's edge list and blend list, which geometric AA reads
  // after them.
  uint edges = push.params.y + 1u;
  uint base = push.params.z != 0u ? BlendListStart(edges) + BlendListLength(edges) : 0u;
  uint offset = base + s_sums[i] - sum;
  if (i == 0u) SkyDispatches(base, s_sums[lanes - 1u]);
  for (uint m = begin; m < end; ++m) {
    uint count = entries[m].dispatch.w;
    entries[m].dispatch.xyz = DispatchFor(count);
    entries[m].list = uvec4(offset, 0u, 0u, 0u);
    offset += count;
  }
}

void main() { Scan(); }
#else
void main() {
  if (kMode == kClassifySky) {  // one listed pixel each
    uint group = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    uint k = group * kShadeGroupSize + gl_LocalInvocationIndex;
    if (k >= entries[SkyListEntry()].list.y) return;
    uint packed = pixels[entries[SkyListEntry()].list.x + k];
    ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
    imageStore(u_color, p, vec4(VisBackground(vec2(p) + 0.5, kBackgroundIbl), 1.0));
    return;
  }
#ifdef VIS_MLAA
  if (kMode == kClassifyFillRunnerUps) {
    // One blend list entry per invocation (the workgroup's 64 invocations, as the shading's).
    uint i;  // the edge list entry it names
    if (!BlendListEntry(push.params.y + 1u, i)) return;
    uvec2 r = runner_ups[i];
    if ((r.y & 0xffu) == 0u || RunnerUpSource(r.y) != kRunnerUpShaded) return;
    uint m = r.x == 0u ? push.params.y : DrawableIds(VisDrawable(r.x, frame.aa.x)).y;
    uint slot = Append(m, kCountCursor);
    pixels[entries[m].list.x + slot] = kRunnerUpEntry | i;
    return;
  }
#endif
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  bool inside = all(lessThan(p, ivec2(frame.counts.zw)));
  uint id = inside ? texelFetch(u_vis_id, p, 0).r : 0u;
  // The last pass over the pixels writes the sky where no surface is (vis_mlaa: where the
  // surface a pixel shows is the sky), at the pixel's centre, or lists those pixels for
  // kClassifySky (see SkyListEntry), and counts them in the sky entry's list.z. vis_mlaa also
  // lists the sky where it is a pixel's runner-up surface (kClassifyFillRunnerUps), shaded at
  // its samples' mean.
  bool sky = inside && id == 0u;
  if (kMode == kClassifyFill && sky) {
    imageStore(u_color, p, vec4(VisBackground(vec2(p) + 0.5, kBackgroundIbl), 1.0));
  }
  if (kMode == kClassifyFillListSky && sky) {
    uint slot = Append(SkyListEntry(), kCountCursor);
    pixels[entries[SkyListEntry()].list.x + slot] = uint(p.x) | (uint(p.y) << 16);
  }
  if (kCountSky && kMode != kClassifyCount && sky) Append(push.params.y, kCountBackground);
  uint m = !inside || id == 0u ? kNoMaterial : DrawableIds(VisDrawable(id, frame.aa.x)).y;
  if (m == kNoMaterial) return;
  if (kMode == kClassifyCount) {
    Append(m, kCountPixels);
  } else {
    uint slot = Append(m, kCountCursor);
    pixels[entries[m].list.x + slot] = uint(p.x) | (uint(p.y) << 16);
  }
}
#endif

#version 460
#extension GL_GOOGLE_include_directive : require
// vis_mlaa's geometric AA over the edge pixels with more than one surface only
// (common/geometric_aa.glsl), in place in the frame's HDR colour: every other pixel's surface owns
// all its samples and passes through, so the pass costs per edge, not per pixel of the frame. The
// resolve listed them in its blend list (entry push.edges + 1, its indices into the edge list,
// entry push.edges, following that list at the start of the pixel lists; dispatched 64 to a
// workgroup); kGeometricAaBlend writes each one's blend into a list of colours (its neighbours are
// read unchanged), kGeometricAaWrite stores them into the image. The mode is specialization constant 0, a pipeline each (lavapipe
// runs an untaken branch under a lane mask: with a push-constant mode the store paid for the
// blend). A pixel's runner-up surface (vis_resolve.comp) takes the share of its samples in the
// blend.
#define TESSERA_COMPUTE
#define GEOMETRIC_AA_EDGES
#include "common/geometric_aa.glsl"

layout(set = 0, binding = kGeometricAaBindingEntries, std430) readonly buffer EntryBlock {
  GpuShadeEntry entries[];
};
layout(set = 0, binding = kGeometricAaBindingPixels, std430) readonly buffer PixelBlock {
  uint pixels[];
};
layout(set = 0, binding = kGeometricAaBindingColors, std430) buffer ColorBlock {
  uvec2 colors[];  // RGBA16F, packed: the runner-up's shaded colour, then the blend
};
layout(set = 0, binding = kGeometricAaBindingRunnerUps, std430) readonly buffer RunnerUpBlock {
  uvec2 runner_ups[];  // vis_resolve.comp's record per edge pixel
};

layout(constant_id = 0) const uint kMode = kGeometricAaBlend;

#include "common/blend_list.glsl"

void main() {
  uint i;  // the edge list entry
  if (!BlendListEntry(push.edges, i)) return;
  uint packed = pixels[i];
  ivec2 p = ivec2(packed & 0xffffu, packed >> 16);
  if (kMode == kGeometricAaBlend) {
    // The runner-up surface's colour: a neighbour's that shows it, or its own shading.
    uint runner_word = runner_ups[i].y;
    uint runner_mask = runner_word & 0xffu;
    vec4 runner = vec4(0.0);
    if (runner_mask != 0u) {
      uint source = RunnerUpSource(runner_word);
      runner.rgb = source < 8u ? Fetch(p + kNeighbours[source])
                               : vec3(unpackHalf2x16(colors[i].x), unpackHalf2x16(colors[i].y).x);
      runner.a = float(bitCount(runner_mask)) / float(push.samples);
    }
    vec4 c = GeometricAa(p, runner, RunnerUpMean(runner_word));
    colors[i] = uvec2(packHalf2x16(c.rg), packHalf2x16(c.ba));
  } else {
    imageStore(u_hdr, p, vec4(unpackHalf2x16(colors[i].x), unpackHalf2x16(colors[i].y)));
  }
}

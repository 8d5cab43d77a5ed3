#version 460
#extension GL_GOOGLE_include_directive : require
// Bloom's downsample as a compute shader (common/bloom_down.glsl): the output is a storage image after
// the inputs.
//
// Variant kBloomDownQuads, for a level exactly half its source (the first level of an even-sized
// frame, and any later one whose source has even sides): output pixel p's taps then sit on source
// texel corners, its 9 outer taps (a b c f g h k l m) at the corners 2p - 1, 2p + 1, 2p + 3 per
// axis and its 4 inner ones (d e i j) at 2p and 2p + 2 (corner c lies between texels c - 1 and
// c), so neighbouring pixels share them. One invocation filters 2x2 pixels from their 25
// distinct taps (16 outer, 9 inner) instead of 4 x 13: on lavapipe the first level went 9.3 ->
// 6.0 ms at 1280x720 (a workgroup's taps shared through shared memory saved only 0.8 ms: its
// loads, stores and barrier cost about what the taps did). The taps are the same bilinear taps
// at the same places, so the result is the other variant's (a corner's uv, c / source size, may
// round differently in the last bit).
#define TESSERA_COMPUTE
#include "common/bloom_down.glsl"

layout(set = 0, binding = 2, rgba16f) uniform writeonly image2D u_out;

const bool kQuads = (kVariant & kBloomDownQuads) != 0u;

void main() {
  ivec2 size = imageSize(u_out);
  if (kQuads) {
    // Invocation q filters the 2x2 pixels 2q + (0 | 1, 0 | 1): their outer taps at the corners
    // 4q - 1 + 2t (t = 0..3 per axis), their inner ones at 4q + 2t (t = 0..2).
    BeginLevel();
    ivec2 q = ivec2(gl_GlobalInvocationID.xy);
    vec3 o[4][4], n[3][3];
    for (int y = 0; y < 4; ++y)
      for (int x = 0; x < 4; ++x) o[y][x] = TapAt(vec2(4 * q - 1 + 2 * ivec2(x, y)) * push.src.xy);
    for (int y = 0; y < 3; ++y)
      for (int x = 0; x < 3; ++x) n[y][x] = TapAt(vec2(4 * q + 2 * ivec2(x, y)) * push.src.xy);
    for (int y = 0; y < 2; ++y) {
      for (int x = 0; x < 2; ++x) {
        ivec2 p = 2 * q + ivec2(x, y);
        if (any(greaterThanEqual(p, size))) continue;
        imageStore(u_out, p, BloomDown(o[y][x], o[y][x + 1], o[y][x + 2], n[y][x], n[y][x + 1],
                                       o[y + 1][x], o[y + 1][x + 1], o[y + 1][x + 2], n[y + 1][x],
                                       n[y + 1][x + 1], o[y + 2][x], o[y + 2][x + 1],
                                       o[y + 2][x + 2]));
      }
    }
    return;
  }
  ivec2 p = ivec2(gl_GlobalInvocationID.xy);
  if (any(greaterThanEqual(p, size))) return;
  v_uv = (vec2(p) + 0.5) / vec2(size);
  PostMain();
  imageStore(u_out, p, out_color);
}

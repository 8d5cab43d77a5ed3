#version 460
#extension GL_GOOGLE_include_directive : require
// GPU light binning, step 1: each local light projected once into its GpuLightBounds, one
// invocation per light. The same math as BoundLight (renderer/light_culling.cpp), which is the
// reference in the tests; keep the two in step. light_bins.comp then bins the lights by tile row
// and light_cull.comp builds the tile lists.
#include "common/gpu_types.h"

layout(local_size_x = kLightCullGroupSize) in;

layout(set = 0, binding = kCullBindingFrame, std140) uniform FrameBlock { FrameUniforms frame; };
layout(set = 0, binding = kCullBindingLightBounds, std430) writeonly buffer BoundsBlock {
  GpuLightBounds light_bounds[];
};
layout(set = 0, binding = kCullBindingLocalLights, std430) readonly buffer LightBlock {
  GpuLight lights[];
};

void main() {
  uint i = gl_GlobalInvocationID.x;
  if (i >= frame.lighting.x) return;
  GpuLight l = lights[i];
  bool spot = uint(l.direction_type.w) == kLightSpot;
  vec3 position = l.position_range.xyz;
  float range = l.position_range.w;
  vec3 direction = l.direction_type.xyz;  // normalized by the CPU
  // spot.xy = (s, -cos_outer * s) with s > 0 (ToGpu in renderer/features/forward_plus.cpp).
  float cos_outer = -l.spot.y / l.spot.x;

  // The world-space bounding sphere (a spot's cone inside its own sphere).
  vec4 ws = vec4(position, range);
  if (spot) {
    if (cos_outer < kWideSpotCos) {  // wide cone: the cap's circle
      float sin_outer = sqrt(max(0.0, 1.0 - cos_outer * cos_outer));
      ws = vec4(position + cos_outer * range * direction, sin_outer * range);
    } else {
      float half_len = range / (2.0 * cos_outer * cos_outer);
      ws = vec4(position + half_len * direction, half_len);
    }
  }
  GpuLightBounds b;
  vec3 c = (frame.view * vec4(ws.xyz, 1.0)).xyz;
  float r = ws.w;
  b.sphere = vec4(c, r);
  if (spot) {
    b.cone = vec4((frame.view * vec4(position, 1.0)).xyz, cos_outer);
    b.cone2 = vec4(normalize(mat3(frame.view) * direction), range);
  } else {
    b.cone = vec4(0.0, 0.0, 0.0, -2.0);
    b.cone2 = vec4(0.0);
  }
  int tx_max = int(frame.lighting.z) - 1, ty_max = int(frame.depth_params.z) - 1;
  float znear = frame.params.y;
  if (-c.z + r < znear) {  // entirely behind the near plane
    b.tiles = ivec4(1, 1, 0, 0);
  } else if (-c.z - r <= znear) {  // crosses the near plane: projection unbounded
    b.tiles = ivec4(0, 0, tx_max, ty_max);
  } else {
    // The 8 corners of the sphere's view-space box, projected (all in front of the near plane).
    vec2 size = vec2(frame.counts.zw);
    vec2 lo = vec2(1e30), hi = vec2(-1e30);
    for (int k = 0; k < 8; ++k) {
      vec3 p = c + r * vec3((k & 1) != 0 ? 1.0 : -1.0, (k & 2) != 0 ? 1.0 : -1.0,
                            (k & 4) != 0 ? 1.0 : -1.0);
      vec2 ndc = vec2(frame.proj[0][0] * p.x / -p.z, frame.proj[1][1] * p.y / -p.z);
      vec2 s = (ndc * 0.5 + 0.5) * size;
      lo = min(lo, s);
      hi = max(hi, s);
    }
    // Clamped to just outside the frame before the integer conversion.
    lo = clamp(lo, vec2(-1.0), size + 1.0);
    hi = clamp(hi, vec2(-1.0), size + 1.0);
    float ts = float(frame.lighting.y);
    ivec2 t0 = max(ivec2(0), ivec2(floor(lo / ts)));
    ivec2 t1 = min(ivec2(tx_max, ty_max), ivec2(floor(hi / ts)));
    b.tiles = (t0.x > t1.x || t0.y > t1.y) ? ivec4(1, 1, 0, 0) : ivec4(t0, t1);
  }
  light_bounds[i] = b;
}

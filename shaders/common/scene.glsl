// Descriptor set 0 of the scene passes and the position transform every scene vertex shader
// shares. The transform is `precise` (no FMA contraction or reassociation), so the depth
// prepass and the shading pass produce bit-identical depths, which the GREATER_OR_EQUAL test
// of the shading pass relies on. (`invariant gl_Position` would say the same, but glslang puts
// the decoration on a block member, which this validation layer's SPIR-V checker flags.)
#ifndef TESSERA_SCENE_GLSL
#define TESSERA_SCENE_GLSL
#include "gpu_types.h"

layout(set = 0, binding = kBindingFrame, std140) uniform FrameBlock { FrameUniforms frame; };
layout(set = 0, binding = kBindingLights, std140) uniform LightBlock {
  GpuLight lights[kMaxLights];
};
layout(set = 0, binding = kBindingDrawables, std430) readonly buffer DrawableBlock {
  GpuDrawable drawables[];
};
layout(set = 0, binding = kBindingMaterials, std430) readonly buffer MaterialBlock {
  GpuMaterial materials[];
};
layout(set = 0, binding = kBindingLocalLights, std430) readonly buffer LocalLightBlock {
  GpuLight local_lights[];
};
layout(set = 0, binding = kBindingTileCounts, std430) readonly buffer TileCountBlock {
  uint tile_counts[];
};
layout(set = 0, binding = kBindingTileLights, std430) readonly buffer TileLightBlock {
  uint tile_lights[];
};
layout(set = 0, binding = kBindingLocalLightTexels) uniform usamplerBuffer local_light_texels;
layout(set = 0, binding = kBindingTileLightTexels) uniform usamplerBuffer tile_light_texels;

// COLOR_0 as the vertex holds it, four halves (scene::Vertex::color), as RGBA.
vec4 VertexColorOf(uvec2 halves) {
  return vec4(unpackHalf2x16(halves.x), unpackHalf2x16(halves.y));
}

vec4 ClipPosition(mat4 world, vec3 position) {
  precise vec4 world_position = world * vec4(position, 1.0);
  precise vec4 clip = frame.view_proj * world_position;
  return clip;
}

// World-space direction (not normalized) of the camera ray through a point in framebuffer
// pixels, from the camera to the point's place on the near plane: the visibility shading's
// surfaces and the sky of both pipelines. Affine in the pixel: the frame's rays come from
// renderer/camera.h's PixelRaysFor (why not unproject per pixel: there).
vec3 RayDirection(vec2 pixel) {
  return frame.ray_origin.xyz + pixel.x * frame.ray_dx.xyz + pixel.y * frame.ray_dy.xyz;
}
#endif

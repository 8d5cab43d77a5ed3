#version 460
#extension GL_GOOGLE_include_directive : require
// Depth prepass for alpha-mask materials: discard where alpha is below the cutoff.
#include "common/scene.glsl"
#include "common/textures.glsl"

layout(location = 3) in vec2 v_uv0;
layout(location = 4) in vec2 v_uv1;

void main() {
  UvGradients grads = ComputeUvGradients(v_uv0, v_uv1);
  float alpha = material.base_color_factor.a;
  GpuTextureRef t = material.base_color_tex;
  if (HasTexture(t)) alpha *= SampleTexture(u_base_color_tex, t, v_uv0, v_uv1, grads).a;
  if (alpha < material.params2.x) discard;
}

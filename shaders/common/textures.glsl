// The draw's material (set 1): the material as a uniform block, and per texture slot the
// sampler2DArray bucket holding it; the layer comes from the material. Sampling uses explicit gradients (UvGradients below):
// the per-texture wrap applied here then does not disturb mip selection, and no derivative is
// taken of a value loaded from a buffer: llvmpipe masks buffer loads for helper invocations, so
// such derivatives are garbage along triangle edges (seen as bright seams on the diagonals).
#ifndef TESSERA_TEXTURES_GLSL
#define TESSERA_TEXTURES_GLSL
#include "gpu_types.h"

#ifdef SHADE_ALL_MATERIALS
// The visibility shading in one dispatch (DeviceInfo::shade_all_materials): one dispatch shades
// every material, so set 1 is the scene's bucket set, indexed by each texture's bucket (the
// device indexes sampler arrays: DeviceInfo::sampler_indexing), and `material` is the shaded
// pixel's, which the shading reads from the scene's material buffer (common/scene.glsl) before
// ShadeSurface.
layout(set = kMaterialSet, binding = kBindingBuckets) uniform sampler2DArray
    u_buckets[kMaxTextureBuckets];
GpuMaterial material;
#else
layout(set = kMaterialSet, binding = kBindingMaterialUniform, std140) uniform MaterialUniform {
  GpuMaterial material;
};
layout(set = kMaterialSet, binding = kBindingBaseColorTex) uniform sampler2DArray u_base_color_tex;
layout(set = kMaterialSet, binding = kBindingMetallicRoughnessTex) uniform sampler2DArray u_metallic_roughness_tex;
layout(set = kMaterialSet, binding = kBindingNormalTex) uniform sampler2DArray u_normal_tex;
layout(set = kMaterialSet, binding = kBindingOcclusionTex) uniform sampler2DArray u_occlusion_tex;
layout(set = kMaterialSet, binding = kBindingEmissiveTex) uniform sampler2DArray u_emissive_tex;
layout(set = kMaterialSet, binding = kBindingSpecularColorTex) uniform sampler2DArray u_specular_color_tex;
layout(set = kMaterialSet, binding = kBindingSpecularTex) uniform sampler2DArray u_specular_tex;
#endif

// glTF wrap modes: 0 repeat (the sampler does it), 1 clamp to edge, 2 mirrored repeat.
float WrapCoord(float x, int mode) {
  if (mode == 1) return clamp(x, 0.0, 1.0);
  if (mode == 2) return 1.0 - abs(mod(x, 2.0) - 1.0);
  return x;
}

bool HasTexture(GpuTextureRef t) { return t.info.x >= 0; }

// Screen-space derivatives of both uv sets, taken once in uniform control flow from the
// interpolants alone: xy = TEXCOORD_0, zw = TEXCOORD_1.
struct UvGradients {
  vec4 dx;
  vec4 dy;
};

#ifndef TESSERA_COMPUTE
UvGradients ComputeUvGradients(vec2 uv0, vec2 uv1) {
  vec4 uv = vec4(uv0, uv1);
  return UvGradients(dFdx(uv), dFdy(uv));
}
#endif

// Where texture t is sampled for these uvs: its layer's coordinates (KHR_texture_transform and
// its wrap applied) and their gradients.
void TextureLookup(GpuTextureRef t, vec2 uv0, vec2 uv1, UvGradients g, out vec3 at, out vec2 dx,
                   out vec2 dy) {
  bool second = t.info.z == 1;
  vec3 uv = vec3(second ? uv1 : uv0, 1.0);
  vec2 tuv = vec2(dot(t.row0.xyz, uv), dot(t.row1.xyz, uv));  // KHR_texture_transform
  // The transform is affine, so its gradients are the linear part applied to the uv's.
  mat2 linear = mat2(t.row0.x, t.row1.x, t.row0.y, t.row1.y);
  dx = linear * (second ? g.dx.zw : g.dx.xy);
  dy = linear * (second ? g.dy.zw : g.dy.xy);
  vec2 wrapped = vec2(WrapCoord(tuv.x, t.info.w & 3), WrapCoord(tuv.y, (t.info.w >> 2) & 3));
  at = vec3(wrapped, float(t.info.y));
}

#ifdef SHADE_ALL_MATERIALS
// The bucket is indexed where it is sampled, so that the index keeps its nonuniform decoration.
vec4 SampleBucket(GpuTextureRef t, vec2 uv0, vec2 uv1, UvGradients g) {
  vec3 at;
  vec2 dx, dy;
  TextureLookup(t, uv0, uv1, g, at, dx, dy);
  return textureGrad(u_buckets[nonuniformEXT(t.info.x)], at, dx, dy);
}
// Texture t of a material slot whose bucket is `bucket` where each material has its own set.
#define SAMPLE_TEXTURE(bucket, t, uv0, uv1, g) SampleBucket(t, uv0, uv1, g)
#else
vec4 SampleTexture(sampler2DArray bucket, GpuTextureRef t, vec2 uv0, vec2 uv1, UvGradients g) {
  vec3 at;
  vec2 dx, dy;
  TextureLookup(t, uv0, uv1, g, at, dx, dy);
  return textureGrad(bucket, at, dx, dy);
}
#define SAMPLE_TEXTURE(bucket, t, uv0, uv1, g) SampleTexture(bucket, t, uv0, uv1, g)
#endif

#ifndef TESSERA_COMPUTE
// The alpha test of alpha-mask materials (glTF alphaCutoff): whether the fragment at these uvs is
// cut out (base colour alpha below the cutoff). The passes that draw depth or ids of alpha-mask
// geometry discard such fragments, so every pass sees the same holes.
bool CutOut(vec2 uv0, vec2 uv1, float vertex_alpha) {
  UvGradients grads = ComputeUvGradients(uv0, uv1);
  // In ShadeSurface's order (factor, texture, vertex), so both cut at the same pixels.
  float alpha = material.base_color_factor.a;
  GpuTextureRef t = material.base_color_tex;
  if (HasTexture(t)) alpha *= SampleTexture(u_base_color_tex, t, uv0, uv1, grads).a;
  alpha *= vertex_alpha;
  return alpha < material.params2.x;
}
#endif
#endif

// Compile-time checks that the C++ mirrors of the GPU structs in shaders/common/gpu_types.h
// have the sizes and offsets the GLSL std140/std430 rules give them, and that the vertex
// layout matches the pipeline's attribute offsets.
#include <cstddef>

#include "renderer/scene/cpu_scene.h"
#include "shaders/common/gpu_types.h"

namespace tessera::gpu {

static_assert(sizeof(GpuTextureRef) == 48);
static_assert(offsetof(GpuTextureRef, row1) == 16);
static_assert(offsetof(GpuTextureRef, info) == 32);

static_assert(sizeof(GpuMaterial) == 96 + 7 * 48);
static_assert(offsetof(GpuMaterial, emissive) == 16);
static_assert(offsetof(GpuMaterial, params) == 32);
static_assert(offsetof(GpuMaterial, params2) == 48);
static_assert(offsetof(GpuMaterial, flags) == 64);
static_assert(offsetof(GpuMaterial, specular) == 80);
static_assert(offsetof(GpuMaterial, base_color_tex) == 96);
static_assert(offsetof(GpuMaterial, emissive_tex) == 96 + 4 * 48);
static_assert(offsetof(GpuMaterial, specular_color_tex) == 96 + 5 * 48);
static_assert(offsetof(GpuMaterial, specular_tex) == 96 + 6 * 48);
static_assert(sizeof(GpuMaterial) % 16 == 0, "std430 array stride");

static_assert(sizeof(GpuDrawable) == 192);
static_assert(offsetof(GpuDrawable, normal_matrix) == 64);
static_assert(offsetof(GpuDrawable, ids) == 128);
static_assert(offsetof(GpuDrawable, sphere) == 144);
static_assert(offsetof(GpuDrawable, aabb_max) == 176);
// vis.glsl reads a drawable as kDrawableTexels texels of 16 bytes (world: texels 0-3, normal
// matrix 4-6, ids 8).
static_assert(sizeof(GpuDrawable) == kDrawableTexels * 16);
static_assert(offsetof(GpuDrawable, normal_matrix) == 4 * 16);
static_assert(offsetof(GpuDrawable, ids) == 8 * 16);
static_assert(sizeof(Vertex) == kVertexTexels * 8);
static_assert(sizeof(GpuLight) == kGpuLightTexels * 16);  // shading.glsl's LocalLight

static_assert(sizeof(GpuLight) == 64);
static_assert(offsetof(GpuLight, spot) == 48);
static_assert(sizeof(GpuLight) * kMaxLights <= 16384, "fits the minimum maxUniformBufferRange");

static_assert(sizeof(GpuLightBounds) == 64);
static_assert(offsetof(GpuLightBounds, tiles) == 16);
static_assert(offsetof(GpuLightBounds, cone2) == 48);

static_assert(sizeof(GpuCullItem) == 48);
static_assert(offsetof(GpuCullItem, slot) == 16);
static_assert(offsetof(GpuCullItem, flags) == 32);

static_assert(sizeof(CullUniforms) == 64 + 6 * 16 + 4 * 16);
static_assert(offsetof(CullUniforms, planes) == 64);
static_assert(offsetof(CullUniforms, counts) == 160);
static_assert(offsetof(CullUniforms, offsets) == 176);
static_assert(offsetof(CullUniforms, hiz) == 192);
static_assert(offsetof(CullUniforms, frame) == 208);
static_assert(kDrawCommandWords == 5 + 4, "VkDrawIndexedIndirectCommand, VkDrawIndirectCommand");

static_assert(sizeof(FrameUniforms) == 4 * 64 + 11 * 16);
static_assert(offsetof(FrameUniforms, prev_view_proj) == 368);
static_assert(offsetof(FrameUniforms, aa) == 352);
static_assert(offsetof(FrameUniforms, lighting) == 320);
static_assert(offsetof(FrameUniforms, depth_params) == 336);
static_assert(offsetof(FrameUniforms, ray_origin) == 192);
static_assert(offsetof(FrameUniforms, ray_dy) == 224);
static_assert(offsetof(FrameUniforms, camera_position) == 240);
static_assert(offsetof(FrameUniforms, counts) == 288);
static_assert(offsetof(FrameUniforms, params) == 304);

static_assert(sizeof(GpuShadowView) == 80);
static_assert(offsetof(ShadowUniforms, cascade_spheres) == 32);
static_assert(offsetof(ShadowUniforms, shadowed) == 96);
static_assert(offsetof(ShadowUniforms, views) == 96 + kMaxShadowedLights * 4);
static_assert(sizeof(ShadowUniforms) == 96 + kMaxShadowedLights * 4 + kMaxShadowViews * 80);
static_assert(sizeof(ShadowUniforms) <= 16384, "must fit the smallest maxUniformBufferRange");

// Push-constant blocks: within the 128 bytes every device has, std430 offsets.
static_assert(sizeof(TonemapPush) == 32);
static_assert(sizeof(GeometricAaPush) == 16);
static_assert(sizeof(TaaPush) == 96 && offsetof(TaaPush, params) == 64 &&
              offsetof(TaaPush, motion) == 80);
static_assert(sizeof(MotionPush) == 80 && offsetof(MotionPush, kept) == 64);
static_assert(sizeof(FxaaPush) == 8);
static_assert(sizeof(SsaoPush) == 48);
static_assert(sizeof(SsaoBlurPush) == 32);
static_assert(sizeof(BloomDownPush) == 48);
static_assert(sizeof(BloomUpPush) == 16);
static_assert(sizeof(ExposurePush) == 32);
static_assert(sizeof(SkinPush) == 16);
static_assert(sizeof(GpuSkinJob) == 48);
static_assert(sizeof(HizPush) == 24 && offsetof(HizPush, dst_size) == 8 &&
              offsetof(HizPush, mode) == 16 && offsetof(HizPush, src_level) == 20);
static_assert(sizeof(IblEnvPush) == 96 && offsetof(IblEnvPush, size) == 80);
static_assert(sizeof(IblIrradiancePush) == 16);
static_assert(sizeof(IblSpecularPush) == 32);
static_assert(sizeof(ShadowPush) == 64);
static_assert(sizeof(ShadePush) == 16);
static_assert(sizeof(GpuShadeEntry) == 32);

}  // namespace tessera::gpu

namespace tessera {
static_assert(sizeof(Vertex) == 64);
static_assert(sizeof(Vertex) == gpu::kVertexFloats * 4);
static_assert(offsetof(Vertex, normal) == 12);
static_assert(offsetof(Vertex, tangent) == 24);
static_assert(offsetof(Vertex, uv0) == 40);
static_assert(offsetof(Vertex, uv1) == 48);
static_assert(offsetof(Vertex, color) == 56);
}  // namespace tessera

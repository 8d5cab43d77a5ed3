// One truth for the layouts, bindings and limits shared by GLSL and C++.
// Included by shaders (GLSL 460) and by renderer/ C++ code, where the GLSL types map to GLM
// and renderer/gpu_layout_check.cpp static_asserts every size and offset.
// Every struct here is made of 16-byte members only, so std140 and std430 agree.
#ifndef TESSERA_SHADERS_COMMON_GPU_TYPES_H
#define TESSERA_SHADERS_COMMON_GPU_TYPES_H

#ifdef __cplusplus
#include <cstdint>
#include <glm/glm.hpp>
namespace tessera::gpu {
using vec4 = glm::vec4;
using ivec4 = glm::ivec4;
using uvec4 = glm::uvec4;
using mat4 = glm::mat4;
using vec2 = glm::vec2;
using uvec2 = glm::uvec2;
using uint = uint32_t;
#define TS_CONST inline constexpr
#else
#define TS_CONST const
#endif

// ---- limits -------------------------------------------------------------------------------
// Global (directional) lights live in a uniform buffer: on lavapipe UBO reads in the per-pixel
// light loop are ~6x cheaper than SSBO reads. 256 * 64 B = 16 KiB, inside maxUniformBufferRange.
TS_CONST uint kMaxLights = 256;
// Local (point and spot) lights live in a storage buffer, up to the scene's lights plus 65536
// synthetic ones, and are shaded from per-tile lists built by the light-culling pass.
TS_CONST uint kMaxLocalLights = 65536 + 4096;
// Per-tile list capacity. A tile with more lights keeps the first kMaxLightsPerTile (lowest
// indices) and sets kTileOverflowBit in its count; the frame reports the overflow.
TS_CONST uint kMaxLightsPerTile = 256;
TS_CONST uint kTileOverflowBit = 0x80000000u;
TS_CONST uint kLightCullGroupSize = 64;  // tiles per light-culling workgroup
// Textures are grouped into sampler2DArray "buckets" by size and colour space (lavapipe cannot
// index an array of samplers dynamically); a material's texture is a (bucket, layer) pair.
TS_CONST uint kMaxTextureBuckets = 8;

// ---- descriptor set 0: the frame ------------------------------------------------------------
TS_CONST uint kBindingFrame = 0;        // uniform FrameUniforms
TS_CONST uint kBindingLights = 1;       // uniform LightBlock { GpuLight lights[kMaxLights]; }
TS_CONST uint kBindingDrawables = 2;    // buffer GpuDrawable[]
TS_CONST uint kBindingMaterials = 3;    // buffer GpuMaterial[]
TS_CONST uint kBindingLocalLights = 4;  // buffer GpuLight[] (point and spot lights)
TS_CONST uint kBindingTileCounts = 5;   // buffer uint[] lights per tile (| kTileOverflowBit)
TS_CONST uint kBindingTileLights = 6;   // buffer uint[] tile * kMaxLightsPerTile + k -> light
TS_CONST uint kBindingShadows = 7;      // uniform ShadowUniforms (views of the shadow atlas)
TS_CONST uint kBindingShadowAtlas = 8;  // sampler2DShadow: the shadow atlas (LESS_OR_EQUAL)
TS_CONST uint kBindingAo = 9;           // sampler2D: SSAO visibility (r), bilinear
TS_CONST uint kBindingIrradiance = 10;  // samplerCube: IBL diffuse irradiance / pi
TS_CONST uint kBindingSpecular = 11;    // samplerCube: IBL prefiltered specular (roughness mips)
TS_CONST uint kBindingBrdfLut = 12;     // sampler2D: split-sum BRDF (A, B) by (n.v, roughness)
TS_CONST uint kBindingEnvironment = 13;  // samplerCube: IBL's sky, the background with ibl
// The local lights and the tiles' light lists again, as uniform texel buffers (R32G32B32A32_UINT,
// kGpuLightTexels per light; R32_UINT), for the reason kVisBindingIndexTexels gives. Read where
// both fit maxTexelBufferElements (FrameFeatures::light_texels): shading.glsl's specialization
// constant kLightTexelsConstant; else the storage buffers.
TS_CONST uint kBindingLocalLightTexels = 14;
TS_CONST uint kBindingTileLightTexels = 15;
TS_CONST uint kLightTexelsConstant = 4;
TS_CONST uint kGpuLightTexels = 4;  // sizeof(GpuLight) / 16
// ---- shadows (shaders/common/shadows.glsl, renderer/shadows.h) --------------------------------
// Every shadow map of a frame is a "view" in one atlas: the sun's cascades first, then per
// shadowed local light one view (spot) or six (point: +X, -X, +Y, -Y, +Z, -Z). A light finds its
// views through GpuLight.shadow: x first view + 1 (0: unshadowed), y view count.
// 4 cascades + 32 point lights x 6 faces; 196 x 80 B + the header stay inside 16 KiB.
TS_CONST uint kMaxShadowedLights = 32;
TS_CONST uint kMaxShadowViews = 4 + kMaxShadowedLights * 6;
// ShadowUniforms.counts.w bits.
TS_CONST uint kShadowsOn = 1u;
TS_CONST uint kSsaoOn = 2u;
// shading.glsl's specialization constant 0, the effects its pipeline has code for:
// kShadowsOn | kSsaoOn | kIblOn | kLocalLightsOn (the frame has point or spot lights with a
// range: the tile lists' loop) | kGlobalLightsOn (the frame has global lights for the global
// lights' loop: any without shadows, more than one with them, where the first is shaded on its
// own).
TS_CONST uint kIblOn = 4u;
TS_CONST uint kLocalLightsOn = 8u;
TS_CONST uint kGlobalLightsOn = 16u;
// ---- the light-culling compute pass (its own set 0) ------------------------------------------
TS_CONST uint kCullBindingFrame = 0;        // uniform FrameUniforms
TS_CONST uint kCullBindingLightBounds = 1;  // buffer GpuLightBounds[]
TS_CONST uint kCullBindingDepth = 2;        // sampler2D: the depth prepass
TS_CONST uint kCullBindingTileCounts = 3;   // buffer uint[] (written)
TS_CONST uint kCullBindingTileLights = 4;   // buffer uint[] (written)
// The lights binned by tile row (on the CPU, or on the GPU by light_bins.comp): entries 2r and
// 2r + 1 are where row r's lights (sorted) begin and end in the same array.
TS_CONST uint kCullBindingRowLights = 5;
TS_CONST uint kCullBindingLocalLights = 6;  // buffer GpuLight[]: light_bounds.comp reads them
// ---- geometry culling (cull.comp, its own set 0) ----------------------------------------------
// One workgroup walks the cull items in order, so the commands it appends come out in item
// order: frames are reproducible and equal, pixel for pixel, whatever the mode.
TS_CONST uint kCullGroupSize = 256;
TS_CONST uint kCullBindingUniforms = 0;  // readonly buffer CullUniforms
TS_CONST uint kCullBindingItems = 1;     // buffer GpuCullItem[] (read)
TS_CONST uint kCullBindingDrawables = 2; // buffer GpuDrawable[] (bounds; read)
TS_CONST uint kCullBindingCommands = 3;  // buffer uint[] draw commands (kDrawCommandWords, written)
TS_CONST uint kCullBindingCounts = 4;    // buffer uint[] draw counts + kCullStat* (written)
TS_CONST uint kCullBindingBases = 5;     // buffer uint[] scratch: visible items before each range
TS_CONST uint kCullBindingVisPrev = 6;   // buffer uint[] visibility bits of the last frame (read)
TS_CONST uint kCullBindingVisNext = 7;   // buffer uint[] visibility bits of this frame (written)
TS_CONST uint kCullBindingHiz = 8;       // sampler2D: the depth pyramid (texelFetch)
// Phases of cull.comp (CullUniforms.counts.w).
TS_CONST uint kCullPhaseFrustum = 0;  // gpu_frustum: draw what is in the frustum
TS_CONST uint kCullPhaseEarly = 1;    // gpu_occlusion 1: what was visible last frame, in frustum
TS_CONST uint kCullPhaseLate = 2;     // gpu_occlusion 2: the rest, tested against the pyramid
// Statistics after the draw counts of a phase (counts buffer, per phase).
TS_CONST uint kCullStatInFrustum = 0;  // items that passed the frustum test
TS_CONST uint kCullStatVisible = 1;    // late phase: items that also passed the occlusion test
// Late phase: items the first phase drew (visible last frame) that are occluded now: the most
// that seeding the first phase with last frame's reprojected depth could have saved.
TS_CONST uint kCullStatStale = 2;
TS_CONST uint kCullStatCount = 4;
// A draw command (renderer/features/pass.h DrawCommand): the indexed draw, then the same draw
// non-indexed for pulled vertices (vertexCount = indexCount, firstVertex = firstIndex,
// firstInstance = the drawable; common/vis_pull.glsl).
TS_CONST uint kDrawCommandWords = 9;
// The depth pyramid (hiz_build.comp): level 0 is the depth at the power of two at or below half
// the frame size, each texel the farthest (reverse Z: minimum) depth of the pixels it covers.
TS_CONST uint kHizGroupSize = 8;  // 8x8 texels per workgroup
TS_CONST uint kHizBindingSource = 0;  // sampler2D: the depth (level 0) or the pyramid (min sampler)
TS_CONST uint kHizBindingDest = 1;    // image2D r32f: the level written

// ---- descriptor set 1: one material ---------------------------------------------------------
// One set per material, bound when the material changes between draws: binding 0 is the
// material itself as a uniform buffer range, binding 1 + k the bucket (sampler2DArray) holding
// its texture for slot k (the layer is in GpuMaterial). Both choices are about lavapipe, which
// cannot know that a material index is the same for a whole draw:
//  - choosing the bucket in the shader (a switch over 8 bindings) runs every case: +45% on the
//    shading pass;
//  - reading the material from the storage buffer by index costs 2.4x the whole shading pass
//    of Sponza (356 -> 150 ms at 720p) against this uniform read.
// The indexable storage buffer (kBindingMaterials) stays for passes that need any material.
TS_CONST uint kMaterialSet = 1;
TS_CONST uint kBindingMaterialUniform = 0;
TS_CONST uint kBindingBaseColorTex = 1;
TS_CONST uint kBindingMetallicRoughnessTex = 2;
TS_CONST uint kBindingNormalTex = 3;
TS_CONST uint kBindingOcclusionTex = 4;
TS_CONST uint kBindingEmissiveTex = 5;
TS_CONST uint kBindingSpecularColorTex = 6;  // KHR_materials_specular's specularColorTexture
TS_CONST uint kBindingSpecularTex = 7;       // and its specularTexture
TS_CONST uint kMaterialTextureSlots = 7;
// Or, in the visibility shading of a device that indexes sampler arrays (DeviceInfo::
// shade_all_materials, common/textures.glsl's SHADE_ALL_MATERIALS), set 1 is the scene's bucket
// set: every bucket, indexed by a texture's bucket (GpuTextureRef::info.x), the materials read from
// the scene's material buffer (kBindingMaterials).
TS_CONST uint kBindingBuckets = 0;  // sampler2DArray[kMaxTextureBuckets]
// The slots a material has a texture in, bit k for slot k (binding 1 + k): the shading's
// specialization constant 1 (common/shading.glsl), a pipeline per set of slots the scene's
// materials use, so each holds no code for the slots its materials lack (lavapipe samples a
// texture under a lane mask even where the branch to it is untaken). Above the slots, one more
// bit: the material's primitives have vertex colours (GpuMaterial::flags.w), so a material without
// has no colour multiply, and its varying is read by nothing (the attribute stays bound). All:
// the general pipeline.
TS_CONST uint kMaterialVertexColors = 1u << kMaterialTextureSlots;
// And one more: the material's specular colour may be tinted (KHR_materials_specular: a colour
// texture, or a factor whose channels differ), so its diffuse light needs the largest channel's
// Fresnel term of its own (shading.glsl's Reflectance::f0_diffuse); else that is the specular's.
TS_CONST uint kMaterialTintedSpecular = kMaterialVertexColors << 1;
TS_CONST uint kMaterialTexturesAll = (kMaterialTintedSpecular << 1) - 1u;
// The tonemap pass has its own set: binding 0 is the HDR colour as a sampler2D.
// ---- vis_mlaa (shaders/common/vis.glsl) ------------------------------------------------------
// A visibility id: (drawable + 1) << triangle_bits | triangle; 0 = no surface (the sky).
// triangle_bits is 20 (12 bits of drawable) unless the scene has more than 4095 drawables; then
// the drawable takes the bits it needs and the triangles the rest (FrameUniforms.aa.x).
TS_CONST uint kVisDefaultTriangleBits = 20;
TS_CONST uint kVisSet = 2;              // the vis passes' own descriptor set
// resolve: the visibility ids, usampler2DMS (raster coverage) or usampler2D (analytic: one sample)
TS_CONST uint kVisBindingSamples = 0;
TS_CONST uint kVisBindingIndices = 2;   // resolve, classify, shade: buffer uint[] the index buffer
TS_CONST uint kVisBindingVertices = 3;  // resolve, classify, shade: buffer float[] the vertices
// The same buffers and the scene's drawables as uniform texel buffers (resolve, classification
// and shading sets): lavapipe loads a storage-buffer word at a per-lane offset in a loop over the
// lanes, one word at a time, and fetches a texel of up to four words in one gather. The
// vertices as R32G32_UINT (kVertexTexels per vertex), the indices as R32_UINT, the drawables as
// R32G32B32A32_UINT (kDrawableTexels each), all bit-exact (uintBitsToFloat). Read where the
// scene's buffers fit maxTexelBufferElements (GpuScene::vis_texels): vis.glsl's specialization
// constant kVisTexelsConstant; else the storage buffers (the views then cover what fits).
TS_CONST uint kVisBindingIndexTexels = 10;
TS_CONST uint kVisBindingVertexTexels = 11;
TS_CONST uint kVisBindingDrawableTexels = 12;
TS_CONST uint kVisTexelsConstant = 3;
TS_CONST uint kVertexTexels = 8;     // kVertexFloats / 2
TS_CONST uint kDrawableTexels = 12;  // sizeof(GpuDrawable) / 16 (gpu_layout_check.cpp)
// skin.comp: the scene's vertex buffer (read the rest vertices, write the deformed copies),
// per vertex its joints and weights (two uvec4: joints, then the weights' float bits), the morph
// deltas (kMorphDeltaFloats each: position, normal, tangent), and the pose (joint matrices, then
// morph weights, as floats).
TS_CONST uint kSkinBindingVertices = 0;
TS_CONST uint kSkinBindingAttributes = 1;
TS_CONST uint kSkinBindingDeltas = 2;
TS_CONST uint kSkinBindingPose = 3;
TS_CONST uint kSkinBindingJobs = 4;
TS_CONST uint kSkinJobSkinned = 1u;  // the drawable's vertices are skinned
TS_CONST uint kSkinJobFlat = 2u;     // flat normals (Primitive::flat_normals): recomputed per face
TS_CONST uint kMorphDeltaFloats = 9;
TS_CONST uint kSkinGroupSize = 64;
TS_CONST uint kVertexFloats = 16;  // scene::Vertex: position 3, normal 3, tangent 4, uv 2+2,
                                   // colour 2 (four halves)
// motion.frag: the motion of a point that was behind last frame's camera (a uv offset that
// puts TAA's history lookup off screen; a finite RG16F value).
TS_CONST float kMotionOffScreen = 4096.0;
// ---- the visibility pipeline (vis_classify.comp, vis_shade.comp, vis_sky_mlaa.comp;
// features/vis_shade.cpp) ------------------------------------------------------------------------
// Set 2 of these passes: the ids, the HDR colour they write, the scene's index and vertex
// buffers (kVisBindingIndices / kVisBindingVertices, as vis_mlaa's), the per-material entries
// and the pixel lists.
TS_CONST uint kShadeBindingId = 0;       // usampler2D: the visibility id per pixel
TS_CONST uint kShadeBindingColor = 1;    // image2D rgba16f: the HDR colour (written)
TS_CONST uint kShadeBindingEntries = 4;  // GpuShadeEntry[materials + 3] (sky, edges, blend)
TS_CONST uint kShadeBindingPixels = 5;   // buffer uint[]: x | y << 16, grouped by material
TS_CONST uint kShadeBindingCoverage = 6;  // vis_mlaa: usampler2D, the resolve's coverage word
// vis_mlaa's runner-up surfaces, one uvec2 per entry of the resolve's edge list: the id to shade
// and its coverage word (mask 0: none). Written by vis_resolve.comp, read by the classification,
// the shading and geometric AA.
TS_CONST uint kShadeBindingRunnerUps = 8;
// vis_mlaa: per edge list entry a uvec2, RGBA16F packed: the runner-up's shaded colour (written
// by the shading), then geometric AA's blend.
TS_CONST uint kShadeBindingEdgeColors = 9;
// A pixel-list entry with this bit set is a runner-up: the low bits are its edge list index.
TS_CONST uint kRunnerUpEntry = 0x80000000u;
// vis_resolve.comp's set 2: the samples (kVisBindingSamples), the ids and coverage words it
// writes (r32ui storage images), the index and vertex buffers, and the entries and pixel lists
// of the shading (the edge list, and the blend list after it, borrow the pixel lists and the two
// entries after the sky's: common/blend_list.glsl).
TS_CONST uint kResolveBindingId = 1;
TS_CONST uint kResolveBindingCoverage = 6;
// vis_mlaa_coverage analytic: buffer uint[], per index of the index buffer the triangle across
// that edge (renderer/scene/adjacency.h; 0xffffffff: none).
TS_CONST uint kResolveBindingAdjacency = 7;
// vis_mlaa's surface test: buffer uint[] and the same as a uniform texel buffer (R32_UINT, read
// as kVisTexelsConstant says), per index of the index buffer the vertex standing for it
// (renderer/scene/adjacency.h, SurfaceIndices).
TS_CONST uint kResolveBindingSurfaces = 13;
TS_CONST uint kResolveBindingSurfaceTexels = 14;
// vis_resolve.comp's modes (specialization constant 1, a pipeline per mode; push params.y is the
// edge list's entry, the blend list's the next).
TS_CONST uint kResolveUniform = 0;  // per pixel: samples that agree are written, others listed
TS_CONST uint kResolveArgs = 1;     // one workgroup: the size of the dispatch over entry params.x
// per listed edge pixel: group the samples by surface; list those with a runner-up (the blend list)
TS_CONST uint kResolveEdges = 2;
// per blend list entry: drops the runner-up where a neighbour geometric AA borrows from shows it
// (it needs the ids kResolveEdges wrote); counts the others (edge entry list.x)
TS_CONST uint kResolveRunnerUps = 3;
// vis_classify and the one-dispatch shading: 8x8 pixels per workgroup.
TS_CONST uint kClassifyTile = 8;
TS_CONST uint kShadeGroupSize = 64;      // vis_shade: pixels per workgroup
// A material's dispatch is at most this many workgroups wide (more rows above: the indirect
// dispatch stays inside maxComputeWorkGroupCount, 65535, at any frame size).
TS_CONST uint kShadeDispatchWidth = 4096;
// vis_classify's modes (specialization constant 0, a pipeline per mode).
TS_CONST uint kClassifyCount = 0;  // count each material's pixels
TS_CONST uint kClassifyScan = 1;   // one workgroup: list offsets and dispatch sizes
// Append each pixel to its material's list; write the background where no surface is.
TS_CONST uint kClassifyFill = 2;
// vis_mlaa: append the runner-up surfaces to be shaded (dispatched over the blend list). With
// vis_mlaa the resolve counted every pixel and runner-up already: kClassifyCount does not run.
TS_CONST uint kClassifyFillRunnerUps = 3;
// kClassifyFill, but listing the pixels where no surface is in the sky list's entry (the fourth
// after the materials': ShadeBuffers::sky_list_entry) rather than writing the background there;
// the scan sizes the dispatch of one of the two to the frame, the other's to nothing.
TS_CONST uint kClassifyFillListSky = 4;
// Per listed sky pixel: the background.
TS_CONST uint kClassifySky = 5;
// (vis_classify's params.z is 1 when vis_mlaa's edge list and blend list, the entries after the
// sky's, hold the start of the pixel lists: the materials' lists then follow them, and geometric
// AA reads them last.)
// geometric_aa_edges.comp's modes (specialization constant 0, a pipeline each) and its set 0's
// bindings after the samplers of the
// coverage (1) and ids (2).
TS_CONST uint kGeometricAaBlend = 1;  // per listed edge pixel: its blend, into the colour list
TS_CONST uint kGeometricAaWrite = 2;  // per listed edge pixel: the blend, into the HDR colour
TS_CONST uint kGeometricAaBindingEntries = 3;
TS_CONST uint kGeometricAaBindingPixels = 4;
TS_CONST uint kGeometricAaBindingColors = 5;
TS_CONST uint kGeometricAaBindingOut = 6;
TS_CONST uint kGeometricAaBindingRunnerUps = 7;


// ---- enums (values match the C++ enums in renderer/settings.h and scene/cpu_scene.h) ---------
TS_CONST uint kAlphaOpaque = 0;
TS_CONST uint kAlphaMask = 1;
TS_CONST uint kAlphaBlend = 2;

TS_CONST uint kLightDirectional = 0;
TS_CONST uint kLightPoint = 1;
TS_CONST uint kLightSpot = 2;
// A spot whose outer cone is wider than this (cos below it; 0.8 rad) is bounded by the sphere
// of its cap's circle, a narrower one by its own sphere (both bound the cone beyond 45 degrees).
// Not at 45 degrees itself: that is glTF's default outer angle, where the CPU's cos and the
// GPU's would fall on either side of the line.
TS_CONST float kWideSpotCos = 0.69670671;

TS_CONST uint kDebugNone = 0;
TS_CONST uint kDebugNormals = 1;
TS_CONST uint kDebugDepth = 2;
TS_CONST uint kDebugBaseColor = 3;
TS_CONST uint kDebugLightHeatmap = 4;
TS_CONST uint kDebugCullingOverlay = 5;
TS_CONST uint kDebugAaMask = 6;
TS_CONST uint kDebugShadowAtlas = 7;  // the tonemap pass shows the atlas
TS_CONST uint kDebugCascades = 8;     // surfaces tinted by the sun cascade that shadows them
TS_CONST uint kDebugSsao = 9;         // the tonemap pass shows the blurred AO
TS_CONST uint kDebugBloom = 10;       // the tonemap pass shows the bloom
// The tonemap's variant (specialization constant 0, a pipeline per variant used): what it shows
// (bits 0-2) and its effects.
TS_CONST uint kTonemapViewColor = 0;  // the frame: exposed, bloom added, tonemapped
TS_CONST uint kTonemapViewBloom = 1;  // the bloom at strength 1, tonemapped
TS_CONST uint kTonemapViewAtlas = 2;  // the shadow atlas's depths
TS_CONST uint kTonemapViewSsao = 3;   // the blurred ambient obscurance
TS_CONST uint kTonemapViewPlain = 4;  // other debug views: the colour as the shading wrote it
TS_CONST uint kTonemapBloom = 8;
TS_CONST uint kTonemapPhotographic = 16;  // else Khronos PBR Neutral
TS_CONST uint kTonemapAutoExposure = 32;
// The bloom downsample's variant (specialization constant 0): the first level (exposure, Karis
// average and threshold) and, in compute, 2x2 pixels an invocation for a level exactly half its
// source (bloom_down.comp: the four pixels' 52 taps are 25 distinct ones).
TS_CONST uint kBloomDownFirst = 1;
TS_CONST uint kBloomDownQuads = 2;

// Vertex attribute locations of the single scene vertex buffer (see scene::Vertex).
TS_CONST uint kAttrPosition = 0;
TS_CONST uint kAttrNormal = 1;
TS_CONST uint kAttrTangent = 2;
TS_CONST uint kAttrUv0 = 3;
TS_CONST uint kAttrUv1 = 4;
TS_CONST uint kAttrColor = 5;  // R32G32_UINT: COLOR_0 as four halves (scene.glsl's VertexColorOf)
// What the alpha-mask passes' vertex shaders read (depth prepass, shadows, visibility, motion,
// drawable ids): the position, the uvs and the colour whose alphas CutOut multiplies.
TS_CONST uint kAlphaMaskAttributes =
    (1u << kAttrPosition) | (1u << kAttrUv0) | (1u << kAttrUv1) | (1u << kAttrColor);
// Pulled vertices (common/vis_pull.glsl): the drawables buffer as a vertex buffer at this
// binding, per instance (firstInstance = the drawable), its world matrix's columns at locations
// kAttrDrawableWorld + 0..3 and its ids at kAttrDrawableIds.
TS_CONST uint kDrawableInputBinding = 1;
TS_CONST uint kAttrDrawableWorld = 8;
TS_CONST uint kAttrDrawableIds = 12;

// ---- structs --------------------------------------------------------------------------------
// A material's reference to one texture layer. uv' = (dot(row0.xyz, (uv,1)), dot(row1.xyz, (uv,1)))
// carries KHR_texture_transform.
struct GpuTextureRef {
  vec4 row0;
  vec4 row1;
  ivec4 info;  // x: bucket (-1 = none), y: layer, z: texcoord set (0/1), w: wrap s | wrap t << 2
};

struct GpuMaterial {
  vec4 base_color_factor;  // linear RGBA
  vec4 emissive;           // rgb: emissive factor * KHR_materials_emissive_strength
  vec4 params;             // x metallic, y roughness, z normal scale, w occlusion strength
  vec4 params2;            // x alpha cutoff (MASK), yzw unused
  uvec4 flags;             // x alpha mode (kAlpha*), y double sided, z unlit, w vertex colours
  // The dielectric's reflectance (KHR_materials_ior, KHR_materials_specular). rgb: its F0 before
  // the specular colour texture and the clamp to 1, i.e. ((ior - 1) / (ior + 1))^2 x
  // specularColorFactor (0.04 without either extension); a: specularFactor, the dielectric's F90
  // and the weight of its F0.
  vec4 specular;
  GpuTextureRef base_color_tex;
  GpuTextureRef metallic_roughness_tex;
  GpuTextureRef normal_tex;
  GpuTextureRef occlusion_tex;
  GpuTextureRef emissive_tex;
  GpuTextureRef specular_color_tex;  // rgb, sRGB: multiplies specular.rgb
  GpuTextureRef specular_tex;        // a: multiplies specular.a
};

// One node x primitive instance. Drawn with firstInstance = drawable index, so shaders find
// it through gl_InstanceIndex (no push constant per draw).
struct GpuDrawable {
  mat4 world;
  // Inverse transpose of world's upper 3x3, in a mat4 for layout; [3][3] the tangent frame's
  // handedness: -1 where world mirrors (negative determinant), else 1.
  mat4 normal_matrix;
  uvec4 ids;           // x primitive, y material, z first index, w vertex offset (int bits)
  vec4 sphere;         // world bounding sphere: xyz centre, w radius
  vec4 aabb_min;       // world AABB
  vec4 aabb_max;
};

// One drawable as geometry culling sees it, in the scene's item order: opaque, alpha-mask,
// blend; within a group single-sided before double-sided, then by material. A "segment" is a run
// of items drawn with one state (group, cull mode, material): one indirect draw; a "batch" a
// run of opaque items with one cull mode (the depth prepass needs no material).
struct GpuCullItem {
  uvec4 draw;   // x first index, y index count, z vertex offset (int bits), w drawable
  uvec4 slot;   // x segment, y segment's first item, z batch (~0u: none), w batch's first item
  uvec4 flags;  // x: 1 last item of its segment, 2 last item of its batch; yzw unused
};

// Uniforms of cull.comp: the view the drawables are tested against (a parameter, so shadow
// views can reuse the pass) and where the phase writes.
struct CullUniforms {
  mat4 view_proj;
  vec4 planes[6];  // frustum planes (xyz normal, w distance), inside: dot(n, p) + w >= 0
  uvec4 counts;    // x items, y segments, z batches, w phase (kCullPhase*)
  uvec4 offsets;   // x this phase's first command (segments; batches follow after `items`),
                   // y this phase's first count (segments, then batches, then kCullStat*)
  uvec4 hiz;       // x level-0 width, y height, z levels, w unused
  uvec4 frame;     // x frame width, y height (pixels of the depth the pyramid was built from)
};

// glTF KHR_lights_punctual, in world space.
struct GpuLight {
  vec4 position_range;   // xyz position, w range (0 = infinite)
  vec4 color_intensity;  // rgb linear colour, a intensity (candela for point/spot, lux for sun)
  vec4 direction_type;   // xyz direction the light points to, w type (kLight*)
  vec4 spot;             // x angle scale, y angle offset (glTF spot falloff),
                         // z first shadow view + 1 (0: unshadowed), w the sun's cascade count;
                         // a shadowed local light's: its index in ShadowUniforms.shadowed
};

// One shadow map in the atlas (renderer/shadows.h has the conventions).
struct GpuShadowView {
  mat4 world_to_atlas;  // world -> (atlas uv, depth) after the divide by w
  vec4 params;          // x world size of a texel (orthographic) or of a texel at distance 1
                        // (perspective), y 1 for perspective, zw unused
};

struct ShadowUniforms {
  uvec4 counts;  // x views, y sun cascades, z unused, w kShadowsOn | kSsaoOn
  vec4 atlas;    // x atlas size in texels, y 1 / size, z normal offset in texels, w unused
  vec4 cascade_spheres[4];  // world xyz centre, w radius (the sphere the cascade covers)
  // The shadowed local lights' indices in the local lights, four to an element (GpuLight.spot.w
  // of each is its place here): the shading meets them in its light lists as bits of a mask and
  // shades them after the others (shading.glsl's DirectLight).
  uvec4 shadowed[kMaxShadowedLights / 4];
  GpuShadowView views[kMaxShadowViews];
};

// What the light-culling pass needs of a local light, each light projected once, not once per
// tile (by BoundLight on the CPU, or light_bounds.comp): the view-space bounding sphere, the
// rectangle of tiles it can touch, and for spots the cone.
struct GpuLightBounds {
  vec4 sphere;  // view space: xyz centre, w radius (a spot's cone is bounded by this sphere)
  ivec4 tiles;  // inclusive tile rectangle x0, y0, x1, y1 (x0 > x1: off screen)
  vec4 cone;    // spots: view-space apex xyz, w cos(outer angle); points: w = -2
  vec4 cone2;   // spots: view-space direction xyz, w range
};

struct FrameUniforms {
  mat4 view;
  mat4 proj;
  mat4 view_proj;
  // The camera ray through a point of the frame (xyz; renderer/camera.h's PixelRays, from the
  // jittered view_proj): scene.glsl's RayDirection(pixel) = ray_origin + pixel.x * ray_dx +
  // pixel.y * ray_dy.
  vec4 ray_origin;
  vec4 ray_dx;
  vec4 ray_dy;
  vec4 camera_position;  // xyz world position
  vec4 ambient_sky;      // rgb radiance from above; w: 1 with IBL (the environment maps)
  vec4 ambient_ground;   // rgb radiance from below
  uvec4 counts;          // x light count, y debug view (kDebug*), z width, w height
  vec4 params;           // x unused (exposure is the tonemap pass's push constant), y near, z far
  uvec4 lighting;        // x local lights, y tile size px, z tiles per row, w bits: 1 tile
                         // lists, 2 2.5D depth mask in light culling
  vec4 depth_params;     // view depth of a depth-buffer value d: y / (d + x); z tiles per column
  uvec4 aa;              // vis_mlaa: x triangle bits of a visibility id, y samples; zw unused
  mat4 prev_view_proj;   // taa: last frame's unjittered view-projection (the motion pass)
};

// The visibility pipeline's record of one material in a frame: its pixels and its dispatch.
struct GpuShadeEntry {
  uvec4 dispatch;  // xyz: VkDispatchIndirectCommand of its shading, w: pixel count
  uvec4 list;      // x: its first pixel in the lists, y: fill cursor, z: the sky's entry only,
                   // the pixels the classification wrote the sky at; w unused (vis_mlaa's
                   // edge list entry: x the runner-up surfaces shaded)
};

// ---- push constants ---------------------------------------------------------------------------
// Each pass's push-constant block, its members written once: the shader declares
//   layout(push_constant) uniform Push { TS_PUSH_TONEMAP } push;
// and C++ gets the struct of the same members below (sizes static_asserted in
// renderer/gpu_layout_check.cpp; push-constant blocks are std430, which these layouts match).
// tonemap.frag: exposure = Exposure()'s params; bloom x: strength / levels (the upsample chain
// sums its levels), y: 1 / levels. What it shows, bloom, the curve and auto exposure are its
// variant (kTonemap*, specialization constant 0).
#define TS_PUSH_TONEMAP \
  vec4 exposure;        \
  vec4 bloom;
// geometric_aa.frag: the visibility samples, 1 to show the coverage mask, id triangle bits;
// geometric_aa_edges.comp: also the edge list's entry (the blend list's is the next).
#define TS_PUSH_GEOMETRIC_AA \
  uint samples;              \
  uint show_mask;            \
  uint triangle_bits;        \
  uint edges;
// taa.frag: this frame's unjittered clip space -> last frame's; params x: current-frame
// weight, y: history valid (1) or not (0), zw: 1/width, 1/height; motion x: 1 when the motion
// target (binding 3) holds this frame's object motion (else binding 3 is a stand-in), y: 1 when
// the camera moved since the view's last frame.
#define TS_PUSH_TAA \
  mat4 reproject;   \
  vec4 params;      \
  vec4 motion;
// motion.vert: the drawable's world matrix in last frame's pose; kept x: the first vertex of the
// view's kept copy (the deformed vertices of its last frame), y: 1 when this drawable's vertices
// are in it (deformed), 0 when its rest vertices moved rigidly.
#define TS_PUSH_MOTION \
  mat4 prev_world;     \
  uvec4 kept;
// fxaa.frag / fxaa.comp: 1/width, 1/height.
#define TS_PUSH_FXAA vec2 inv_size;
// ssao.frag: proj x: proj[0][0], y: proj[1][1] (negative: Vulkan clip y is down), z: proj[2][2],
// w: proj[3][2]; params x: radius (world units), y: intensity (1 = default), z: bias (world
// units); size xy: depth size in pixels, zw: output size in pixels.
#define TS_PUSH_SSAO \
  vec4 proj;         \
  vec4 params;       \
  uvec4 size;
// ssao_blur.frag: dir xy: step, (1, 0) or (0, 1), zw: image size in texels; params x: depth
// sharpness (e.g. 8).
#define TS_PUSH_SSAO_BLUR \
  ivec4 dir;              \
  vec4 params;
// bloom_down.frag: src xy: 1 / source size in texels, zw unused (the variant, kBloomDownFirst,
// says which level is the first); threshold x: threshold (exposed linear HDR), y: knee (soft knee
// width); exposure: Exposure()'s params (first level).
#define TS_PUSH_BLOOM_DOWN \
  vec4 src;                \
  vec4 threshold;          \
  vec4 exposure;
// bloom_up.frag: xy: 1 / u_low size in texels; zw unused.
#define TS_PUSH_BLOOM_UP vec4 params;
// exposure.comp: size xy: HDR size in pixels, z: grid width, w: grid height (sample points);
// params x: rate (>= 1: this frame's value at once, else the fraction of the way to move),
// y: min log2 luminance, z: max log2 luminance.
// skin.comp: one workgroup per kSkinGroupSize vertices of every deformed drawable, in one
// dispatch (or several of at most maxComputeWorkGroupCount[0] workgroups): jobs = (job count,
// the dispatch's first workgroup, unused, unused).
#define TS_PUSH_SKIN \
  uvec4 jobs;
#define TS_PUSH_EXPOSURE \
  uvec4 size;            \
  vec4 params;
// hiz_build.comp: pixels of the source level, texels of the level written, mode (0: from the
// depth buffer, 1: min sampler, 2: four fetches), source mip (modes 1, 2).
#define TS_PUSH_HIZ \
  uvec2 src_size;   \
  uvec2 dst_size;   \
  uint mode;        \
  uint src_level;
// ibl_env.comp: xyz towards the sun (normalized, or zero: no sun); rgb sun radiance scale; sky
// radiance straight up, at the horizon, below the horizon; size x: face size in texels.
#define TS_PUSH_IBL_ENV \
  vec4 sun_dir;         \
  vec4 sun_color;       \
  vec4 zenith;          \
  vec4 horizon;         \
  vec4 ground;          \
  uvec4 size;
// ibl_irradiance.comp: x output face size, y env mip level integrated over, z that level's
// face size.
#define TS_PUSH_IBL_IRRADIANCE uvec4 size;
// ibl_specular.comp: params x: perceptual roughness of this level (alpha = x^2), y: env mip-0
// face size in texels, z: env mip count, w: sample count; size x: this level's face size.
#define TS_PUSH_IBL_SPECULAR \
  vec4 params;               \
  uvec4 size;
// shadow.vert, shadow_mask.vert: world -> the face's clip space.
#define TS_PUSH_SHADOW mat4 view_proj;
// vis_classify.comp: y materials (the sky's entry is the next; the mode is a specialization
// constant); vis_shade.comp: x the material shaded; vis_sky_mlaa.comp: x the sky's entry;
// vis_resolve.comp: y the edge list's entry, x the entry kResolveArgs sizes (the mode is a
// specialization constant); vis_shade_all*.comp: x the sky's entry, y the edge list's entry, z 1
// where the shading counts the surfaces it shades in their materials' entries (one sample), w 1
// where it counts the sky's pixels in the sky's entry (a capture asks).
#define TS_PUSH_SHADE uvec4 params;

#ifdef __cplusplus
struct TonemapPush {
  TS_PUSH_TONEMAP
};
struct GeometricAaPush {
  TS_PUSH_GEOMETRIC_AA
};
struct TaaPush {
  TS_PUSH_TAA
};
struct MotionPush {
  TS_PUSH_MOTION
};
struct FxaaPush {
  TS_PUSH_FXAA
};
struct SsaoPush {
  TS_PUSH_SSAO
};
struct SsaoBlurPush {
  TS_PUSH_SSAO_BLUR
};
struct BloomDownPush {
  TS_PUSH_BLOOM_DOWN
};
struct BloomUpPush {
  TS_PUSH_BLOOM_UP
};
struct ExposurePush {
  TS_PUSH_EXPOSURE
};
struct SkinPush {
  TS_PUSH_SKIN
};
// One deformed drawable of skin.comp, in the scene's job buffer: range = (first source vertex,
// first output vertex, vertex count, kSkinJob* flags), pose = (first joint matrix of the
// drawable's skin in the pose buffer, first morph weight there, morph targets, first morph delta
// of the primitive), groups = (its first workgroup, unused...).
struct GpuSkinJob {
  uvec4 range;
  uvec4 pose;
  uvec4 groups;
};
struct HizPush {
  TS_PUSH_HIZ
};
struct IblEnvPush {
  TS_PUSH_IBL_ENV
};
struct IblIrradiancePush {
  TS_PUSH_IBL_IRRADIANCE
};
struct IblSpecularPush {
  TS_PUSH_IBL_SPECULAR
};
struct ShadowPush {
  TS_PUSH_SHADOW
};
struct ShadePush {
  TS_PUSH_SHADE
};
#endif

#ifdef __cplusplus
}  // namespace tessera::gpu
#endif
#undef TS_CONST
#endif  // TESSERA_SHADERS_COMMON_GPU_TYPES_H

// The surface shading of the forward path, shared with vis_mlaa's shading pass (same material
// evaluation, BRDF and light lists): the glTF 2.0 metallic-roughness BRDF (Appendix B of the
// spec): GGX distribution, height-correlated Smith visibility, Schlick Fresnel, Lambert diffuse.
// Global (directional) lights from the lights UBO, local lights from the tile lists (or all of
// them, brute force), shadowed through the shadow atlas (shadows.glsl), plus a hemisphere
// ambient with an analytic split-sum specular term, darkened by SSAO. Needs scene.glsl, sky.glsl,
// textures.glsl (the material in set 1) and shadows.glsl. The pixel (its forward+ tile and AO
// texel) is gl_FragCoord in fragment shaders; a compute shader defines TESSERA_COMPUTE and
// SHADING_PIXEL (the pixel's centre in framebuffer pixels) before including this.
#ifndef TESSERA_SHADING_GLSL
#define TESSERA_SHADING_GLSL
#ifndef SHADING_PIXEL
#define SHADING_PIXEL gl_FragCoord.xy
#endif

#include "common/brdf.glsl"

// A point of a surface to shade, in world space.
struct SurfaceInput {
  vec3 world;
  vec3 normal;   // interpolated vertex normal (not normalized)
  vec4 tangent;  // xyz world tangent, w bitangent sign
  vec2 uv0;
  vec2 uv1;
  vec4 color;  // COLOR_0 (white without): multiplies the base colour and its alpha
  UvGradients grads;
  bool front_facing;
};

// What a surface point reflects, from its material (ShadeSurface): the diffuse colour; the
// specular reflectance at normal (f0) and grazing (f90) incidence, the dielectric's
// (KHR_materials_ior, KHR_materials_specular) mixed with the metal's by metallic; GGX's alpha.
// The diffuse light is what the Fresnel term leaves, from f0_diffuse: f0 with the dielectric's
// colour as one value, the largest of its channels (KHR_materials_specular's max_value, so a
// coloured specular does not tint the diffuse light with its complement). Without a coloured
// specular, f0_diffuse is f0.
struct Reflectance {
  vec3 c_diff;
  vec3 f0;
  vec3 f0_diffuse;
  float f90;
  float alpha;
};

// Karis' analytic fit of the split-sum environment BRDF: its (scale, bias) of F0 and F90.
vec2 EnvBrdfApprox(float roughness, float n_dot_v) {
  const vec4 c0 = vec4(-1.0, -0.0275, -0.572, 0.022);
  const vec4 c1 = vec4(1.0, 0.0425, 1.04, -0.04);
  vec4 r = roughness * c0 + c1;
  float a004 = min(r.x * r.x, exp2(-9.28 * n_dot_v)) * r.x + r.y;
  return vec2(-1.04, 1.04) * a004 + r.zw;
}


layout(set = 0, binding = kBindingAo) uniform sampler2D u_ao;
// IBL (renderer/ibl_maps.h): irradiance / pi, the specular chain (roughness r at mip r * (n - 1)),
// the split-sum BRDF table at (n_dot_v, roughness).
layout(set = 0, binding = kBindingIrradiance) uniform samplerCube u_irradiance;
layout(set = 0, binding = kBindingSpecular) uniform samplerCube u_specular;
layout(set = 0, binding = kBindingBrdfLut) uniform sampler2D u_brdf_lut;
// Pipelines are built per set of the effects shadows, SSAO and IBL, local lights and the global
// lights' loop (constant 0: kShadowsOn | kSsaoOn | kIblOn | kLocalLightsOn | kGlobalLightsOn):
// lavapipe runs the code of an untaken branch at a cost (each doubled the shading pass of frames
// without them), so a frame's pipeline has the code of its effects only.
layout(constant_id = 0) const uint kLightingEffects = 0u;
const bool kShadowCode = (kLightingEffects & kShadowsOn) != 0u;
const bool kSsaoCode = (kLightingEffects & kSsaoOn) != 0u;
const bool kIblCode = (kLightingEffects & kIblOn) != 0u;
const bool kLocalLightCode = (kLightingEffects & kLocalLightsOn) != 0u;
const bool kGlobalLoopCode = (kLightingEffects & kGlobalLightsOn) != 0u;
// The texture slots the shaded materials have, whether they have vertex colours and whether
// their specular colour may be tinted (gpu::kMaterialTexturesAll: any): a pipeline per set
// of slots a scene's materials use, so the sampling code of the slots they lack is not there at
// all (lavapipe ran it under a lane mask: Sponza, whose materials have no occlusion or emissive
// textures, shaded 20-27% slower with it).
layout(constant_id = 1) const uint kMaterialTextures = kMaterialTexturesAll;

// The debug view the surfaces show (normals, base_color, depth, light_heatmap, cascades; else
// kDebugNone: lit), a pipeline per view for the same reason.
layout(constant_id = 2) const uint kShadingDebugView = kDebugNone;

// (Constant 3 is vis.glsl's.) The local lights and the tiles' lists through their texel views
// (gpu_types.h, kBindingLocalLightTexels), where the frame's fit the device's texel limit.
layout(constant_id = kLightTexelsConstant) const bool kLightTexels = false;
GpuLight LocalLight(uint i) {
  if (!kLightTexels) return local_lights[i];
  int t = int(i * kGpuLightTexels);
  GpuLight l;
  l.position_range = uintBitsToFloat(texelFetch(local_light_texels, t));
  l.color_intensity = uintBitsToFloat(texelFetch(local_light_texels, t + 1));
  l.direction_type = uintBitsToFloat(texelFetch(local_light_texels, t + 2));
  l.spot = uintBitsToFloat(texelFetch(local_light_texels, t + 3));
  return l;
}
uint TileLight(uint k) {
  return kLightTexels ? texelFetch(tile_light_texels, int(k)).x : tile_lights[k];
}

// Whether the material has a texture in `slot` (its binding - kBindingBaseColorTex).
bool MaterialHas(uint slot, GpuTextureRef t) {
  return (kMaterialTextures & (1u << slot)) != 0u && HasTexture(t);
}

// One punctual light's contribution (glTF KHR_lights_punctual attenuation and spot falloff),
// times its shadow. `ng` is the unperturbed surface normal (the shadow lookup's normal offset).
// `shadowed` is a constant at every call: the shader compiler keeps the lookup's code only where
// it is true (on lavapipe, an untaken branch to a lookup inside the light loop still doubled the
// shading pass); `sun`: the light is the sun, looked up through its cascades (LightShadow).
vec3 ShadeLight(GpuLight light, vec3 p, vec3 n, vec3 ng, vec3 v, float n_dot_v, Reflectance r,
                bool shadowed, bool sun) {
  uint type = uint(light.direction_type.w);
  vec3 l;
  float attenuation = 1.0;
  if (type == kLightDirectional) {
    l = -light.direction_type.xyz;
  } else {
    vec3 to_light = light.position_range.xyz - p;
    float d2 = max(dot(to_light, to_light), 1e-8);
    l = to_light * inversesqrt(d2);
    float range = light.position_range.w;
    attenuation = 1.0 / d2;
    if (range > 0.0) {
      float q = d2 / (range * range);
      attenuation *= clamp(1.0 - q * q, 0.0, 1.0);  // glTF: 1 - (d/range)^4
    }
    if (type == kLightSpot) {
      float cd = dot(light.direction_type.xyz, -l);
      float s = clamp(cd * light.spot.x + light.spot.y, 0.0, 1.0);
      attenuation *= s * s;
    }
  }
  float n_dot_l = dot(n, l);
  if (n_dot_l <= 0.0 || attenuation <= 0.0) return vec3(0.0);
  if (shadowed && light.spot.z > 0.0) {
    attenuation *= LightShadow(light, p, ng, sun);
    if (attenuation <= 0.0) return vec3(0.0);
  }
  vec3 h = normalize(l + v);
  float n_dot_h = max(dot(n, h), 0.0);
  float v_dot_h = max(dot(v, h), 0.0);
  // Schlick's Fresnel from f0 to f90: f0 (1 - w) + f90 w.
  float w = SchlickWeight(v_dot_h);
  float f90_w = r.f90 * w;
  vec3 f = r.f0 * (1.0 - w) + f90_w;
  vec3 diffuse = (1.0 - (r.f0_diffuse * (1.0 - w) + f90_w)) * r.c_diff / kPi;
  vec3 specular = f * DistributionGgx(n_dot_h, r.alpha) *
                  VisibilitySmithGgxCorrelated(n_dot_v, n_dot_l, r.alpha);
  vec3 radiance = light.color_intensity.rgb * light.color_intensity.a * attenuation;
  return (diffuse + specular) * radiance * n_dot_l;
}

// Every light's contribution at a point: the global lights (directional, or point and spot
// lights without a range), then the local ones of the tile's list (or all of them, brute
// force), with shadows where the frame's pipeline has them (kShadowCode).
// With shadows, the sun (the one global light PlaceSun shadows) and the shadowed local lights
// are shaded in a loop of their own, after the list's, one shadow lookup an iteration: the
// list's loop shades the lights without a shadow map and sets a bit per shadowed light it meets
// (its place in ShadowUniforms.shadowed). A lookup behind a per-light branch in the list's loop
// ran for every light of the list on lavapipe, under a lane mask (19% of Sponza's full-stack
// shading); a lookup per kind of light ran each kind's code for the other (README,
// "Specialization, not branches"). The sun is the shadowed loop's first iteration: lavapipe runs
// a loop's body at least once, and with the sun shaded before it, that first iteration looked a
// shadow up for no light at every pixel without a shadowed local light in its tile (Sponza's
// full stack at 1280x720: the loop cost 30 of the shading's 140 ms).
// The loops test their end at the bottom of the body, where a `for` tests it at the top:
// lavapipe's loops (gallivm) only mask a lane off when it leaves, and branch back while any lane
// is left, so after the last lane left at the top the body ran once more with every lane masked
// off; the shadowed loop (one to a few iterations) paid that on every pixel. So each loop runs
// its body at least once, and drops what a lane computes past its own end.
vec3 DirectLight(vec3 p, vec3 n, vec3 ng, vec3 v, float n_dot_v, Reflectance r, bool tiled,
                 uint tile, uint tile_count) {
  vec3 color = vec3(0.0);
  // A shadowed sun is global light 0 (PrepareLights puts the directional lights first, PlaceSun
  // shadows the first and counts its cascades in shadow.counts.y), shaded below with its shadow.
  // Without one, that light 0 is the loop's here. The loop is only in pipelines for frames with
  // global lights for it (kGlobalLoopCode): with shadows, more than one; a loop's body ran on
  // lavapipe with nothing to shade (Sponza's full stack, whose one global light is the sun:
  // shading 164-180 -> 152-167 ms without it).
  bool sun = kShadowCode && shadow.counts.y > 0u;
  if (kGlobalLoopCode) {
    // (A later iteration's i is below the count; the first's is 0 or 1, in lights[]'s range.)
    for (uint i = sun ? 1u : 0u;;) {
      vec3 c = ShadeLight(lights[i], p, n, ng, v, n_dot_v, r, false, false);
      color += i < frame.counts.x ? c : vec3(0.0);
      if (++i >= frame.counts.x) break;
    }
  }
  uint shadowed = 0u;  // bit i: ShadowUniforms.shadowed's light i lights this point's list
  // Only in pipelines for frames with local lights (kLocalLightCode): on lavapipe the loop cost
  // 10 ms of plain Sponza's shading with no light to shade.
  if (kLocalLightCode) {
    uint count = tiled ? tile_count : frame.lighting.x;
    uint base = tile * kMaxLightsPerTile;
    for (uint k = 0u;;) {
      // Only the first iteration of an empty list is not live (k is 0): its slot's stale index
      // is replaced by light 0, and the light dropped.
      bool live = k < count;
      GpuLight light = LocalLight(live ? (tiled ? TileLight(base + k) : k) : 0u);
      vec3 c = ShadeLight(light, p, n, ng, v, n_dot_v, r, false, false);
      bool mapped = kShadowCode && light.spot.z > 0.0;
      if (live && mapped) shadowed |= 1u << uint(light.spot.w);
      color += live && !mapped ? c : vec3(0.0);
      if (++k >= count) break;
    }
  }
  // Light 0 with the sun's lookup (LightShadow looks up only a light that has a map): the sun,
  // or without the global loop the frame's one global light, if any.
  bool sun_first = kGlobalLoopCode ? sun : frame.counts.x > 0u;
  if (kShadowCode && !kLocalLightCode) {
    vec3 c = ShadeLight(lights[0], p, n, ng, v, n_dot_v, r, true, true);
    color += sun_first ? c : vec3(0.0);
  } else if (kShadowCode) {
    // Counted, at least once: as a do-while on `shadowed` lavapipe shaded a few hundred of
    // Sponza's pixels differently in every run where tiles held three or more shadowed lights
    // (their lanes' company changes with the lists' order; VisibilityPipelineTest.
    // ShadowedLocalLightsRenderTheSameEveryTime). Tested at the top, the count cost Sponza's
    // full stack 10-15% of its shading against the do-while (an extra, masked-off iteration).
    uint iterations = max(uint(bitCount(shadowed)) + (sun_first ? 1u : 0u), 1u);
    for (uint it = 0u;;) {
      bool is_sun = sun_first && it == 0u;
      bool any = is_sun || shadowed != 0u;  // else this iteration's light is dropped
      uint i = is_sun || shadowed == 0u ? 0u : uint(findLSB(shadowed));
      if (!is_sun) shadowed &= shadowed - 1u;
      // (Local light 0 stands in where there is no shadowed one: an index in range.)
      GpuLight light;
      if (is_sun) {
        light = lights[0];
      } else {
        light = LocalLight(any ? shadow.shadowed[i / 4u][i % 4u] : 0u);
      }
      vec3 c = ShadeLight(light, p, n, ng, v, n_dot_v, r, true, is_sun);
      color += any ? c : vec3(0.0);
      if (++it >= iterations) break;
    }
  }
  return color;
}

// Blue -> green -> yellow -> red as a tile's light count goes 0 -> 16 -> 32 -> 64+.
vec3 Heat(uint count) {
  float t = clamp(float(count) / 64.0, 0.0, 1.0);
  vec3 c = t < 0.25 ? mix(vec3(0.0, 0.0, 0.4), vec3(0.0, 0.8, 0.0), t * 4.0)
         : t < 0.5  ? mix(vec3(0.0, 0.8, 0.0), vec3(1.0, 1.0, 0.0), (t - 0.25) * 4.0)
                    : mix(vec3(1.0, 1.0, 0.0), vec3(1.0, 0.0, 0.0), (t - 0.5) * 2.0);
  return count == 0u ? vec3(0.02) : c;
}

// The lit colour of the surface (alpha: the material's for blended materials, else 1), or the
// debug view's colour. With `alpha_test`, alpha-mask materials discard below their cutoff.
vec4 ShadeSurface(SurfaceInput s, bool alpha_test) {
  GpuMaterial m = material;
  vec4 base = m.base_color_factor;
  if (MaterialHas(0u, m.base_color_tex)) base *= SAMPLE_TEXTURE(u_base_color_tex, m.base_color_tex, s.uv0, s.uv1, s.grads);
  // The mask passes' CutOut multiplies the same alpha. Only where the material's primitives have
  // colours (else every vertex is white, and nothing reads the varying).
  if ((kMaterialTextures & kMaterialVertexColors) != 0u) base *= s.color;
  // The prepass discarded these too; without the same test here the shading pass would draw
  // the cut-out surface over whatever is behind it (its depth is nearer).
#ifndef TESSERA_COMPUTE
  if (alpha_test && m.flags.x == kAlphaMask && base.a < m.params2.x) discard;
#endif

  float metallic = m.params.x;
  float roughness = m.params.y;
  if (MaterialHas(1u, m.metallic_roughness_tex)) {
    vec4 mr = SAMPLE_TEXTURE(u_metallic_roughness_tex, m.metallic_roughness_tex, s.uv0, s.uv1, s.grads);
    roughness *= mr.g;
    metallic *= mr.b;
  }
  roughness = clamp(roughness, 0.03, 1.0);
  metallic = clamp(metallic, 0.0, 1.0);

  // Back faces (drawn only for double-sided materials) use the flipped frame.
  float side = s.front_facing ? 1.0 : -1.0;
  vec3 n = normalize(s.normal) * side;
  vec3 ng = n;
  if (MaterialHas(2u, m.normal_tex)) {
    vec3 t = s.tangent.xyz * side;
    t = normalize(t - n * dot(n, t));
    vec3 b = cross(n, t) * s.tangent.w;
    vec3 tn = SAMPLE_TEXTURE(u_normal_tex, m.normal_tex, s.uv0, s.uv1, s.grads).xyz * 2.0 - 1.0;
    tn.xy *= m.params.z;
    n = normalize(mat3(t, b, n) * tn);
  }
  float ao = 1.0;
  if (MaterialHas(3u, m.occlusion_tex)) {
    ao = 1.0 + m.params.w * (SAMPLE_TEXTURE(u_occlusion_tex, m.occlusion_tex, s.uv0, s.uv1, s.grads).r - 1.0);
  }
  vec3 emissive = m.emissive.rgb;
  if (MaterialHas(4u, m.emissive_tex)) emissive *= SAMPLE_TEXTURE(u_emissive_tex, m.emissive_tex, s.uv0, s.uv1, s.grads).rgb;

  const uint debug_view = kShadingDebugView;
  if (debug_view == kDebugNormals) { return vec4(n * 0.5 + 0.5, 1.0); }
  if (debug_view == kDebugBaseColor) { return vec4(base.rgb, 1.0); }
  if (debug_view == kDebugDepth) {
    // Log-scaled view distance: near plane white, 10^4 near-plane distances black.
    float dist = length(frame.camera_position.xyz - s.world);
    float g = 1.0 - clamp(log2(dist / frame.params.y) / log2(1.0e4), 0.0, 1.0);
    return vec4(vec3(g), 1.0);
  }

  vec3 v = normalize(frame.camera_position.xyz - s.world);
  float n_dot_v = max(dot(n, v), 1e-4);
  // The dielectric's F0 and F90 (KHR_materials_specular's dielectric_f0 and _f90: the F0 from
  // the IOR times the specular colour, clamped to 1, times the specular weight; F90 the weight).
  // 0.04 and 1 without the extensions.
  vec3 specular_color = m.specular.rgb;
  if (MaterialHas(5u, m.specular_color_tex)) specular_color *= SAMPLE_TEXTURE(u_specular_color_tex, m.specular_color_tex, s.uv0, s.uv1, s.grads).rgb;
  float specular_weight = m.specular.a;
  if (MaterialHas(6u, m.specular_tex)) specular_weight *= SAMPLE_TEXTURE(u_specular_tex, m.specular_tex, s.uv0, s.uv1, s.grads).a;
  vec3 dielectric_f0 = min(specular_color, vec3(1.0)) * specular_weight;
  float dielectric_f0_max = max(max(dielectric_f0.r, dielectric_f0.g), dielectric_f0.b);
  Reflectance r;
  r.c_diff = mix(base.rgb, vec3(0.0), metallic);
  r.f0 = mix(dielectric_f0, base.rgb, metallic);
  // Only pipelines for tinted specular colours have the diffuse term's own Fresnel: untinted,
  // f0_diffuse is f0, and the shader compiler shares the two terms.
  r.f0_diffuse = (kMaterialTextures & kMaterialTintedSpecular) != 0u
                     ? mix(vec3(dielectric_f0_max), base.rgb, metallic)
                     : r.f0;
  r.f90 = mix(specular_weight, 1.0, metallic);
  r.alpha = roughness * roughness;

  // The tile this pixel belongs to, and its light list (built by the light-culling pass).
  uint tile_size = frame.lighting.y;
  uint tile = uint(SHADING_PIXEL.y) / tile_size * frame.lighting.z + uint(SHADING_PIXEL.x) / tile_size;
  // Blended surfaces are not in the prepass depth the lists were culled against: brute force.
  bool tiled = (frame.lighting.w & 1u) != 0u && m.flags.x != kAlphaBlend;
  uint tile_count = tiled && kLocalLightCode ? (tile_counts[tile] & ~kTileOverflowBit) : 0u;
  if (debug_view == kDebugLightHeatmap) {
    return vec4(Heat(tiled ? tile_count : frame.lighting.x), 1.0);
  }
  // KHR_materials_unlit: the base colour as it is, whatever the lights (the frame's exposure and
  // tonemapper still apply, as to everything else).
  if (m.flags.z != 0u) return vec4(base.rgb, m.flags.x == kAlphaBlend ? base.a : 1.0);

  // The pipeline's kShadowCode alone says whether DirectLight looks shadows up: a choice at run
  // time between two calls (on shadow.counts.w, which PrepareShadows sets whenever kShadowCode
  // is on) ran both on lavapipe (Sponza's full stack: shading 179-182 -> 169-171 ms).
  vec3 color = DirectLight(s.world, n, ng, v, n_dot_v, r, tiled, tile, tile_count);

  // Ambient. With IBL: the split sum, the irradiance cube times the diffuse colour plus the
  // prefiltered environment along the reflection times the BRDF table's scales of F0 and F90.
  // Without: hemisphere irradiance for diffuse; for specular the hemisphere seen along the
  // reflection vector, blurred towards the average as roughness grows, with Karis' analytic fit
  // of the BRDF table.
  vec3 reflected = reflect(-v, n);
  vec3 irradiance, env;
  vec2 ab;
  if (kIblCode && IblOn()) {
    float mips = float(textureQueryLevels(u_specular));
    irradiance = textureLod(u_irradiance, n, 0.0).rgb;
    env = textureLod(u_specular, reflected, roughness * (mips - 1.0)).rgb;
    ab = textureLod(u_brdf_lut, vec2(n_dot_v, roughness), 0.0).rg;
  } else {
    irradiance = Hemisphere(n);
    env = mix(Hemisphere(reflected), 0.5 * (frame.ambient_sky.rgb + frame.ambient_ground.rgb),
              roughness);
    ab = EnvBrdfApprox(roughness, n_dot_v);
  }
  vec3 ambient = irradiance * r.c_diff + env * (r.f0 * ab.x + r.f90 * ab.y);
  // SSAO darkens the ambient light only (direct light has its shadows). Blended surfaces are
  // not in the depth it was computed from.
  if (kSsaoCode && (shadow.counts.w & kSsaoOn) != 0u && m.flags.x != kAlphaBlend)
    ao *= textureLod(u_ao, SHADING_PIXEL / vec2(frame.counts.zw), 0.0).r;
  color += ambient * ao;
  color += emissive;
  if (kShadowCode && debug_view == kDebugCascades) {
    // Lit colour, tinted by the cascade; darker where the sun is shadowed.
    float lum = dot(color, vec3(0.2126, 0.7152, 0.0722));
    return vec4(CascadeColor(s.world) * (0.25 + 0.75 * clamp(lum, 0.0, 1.0)), 1.0);
  }

  return vec4(color, m.flags.x == kAlphaBlend ? base.a : 1.0);
}
#endif

// The procedural sky that image-based lighting is prefiltered from (ibl_env.comp renders it into
// the environment cube map): a zenith -> horizon gradient above, the ground below (blended in
// just under the horizon so there is no hard edge), and a sun: a wide and a tight glow around
// it plus a small disc with a smooth edge. Pure function of its arguments (no frame data), so
// it can be included anywhere. renderer/ibl.cpp has the same function on the CPU
// (ProceduralSkyReference, line for line, and the default colours); keep the two in step.
#ifndef TESSERA_IBL_SKY_GLSL
#define TESSERA_IBL_SKY_GLSL

// The ground fades in over this much of dir.y below the horizon (0.04: about 2.3 degrees).
const float kSkyGroundBlend = 0.04;
// Glow around the sun, in units of sun_color: kSkyGlowWide * cos^8 + kSkyGlowTight * cos^64 of
// the angle to the sun (cos^8 halves at ~24 degrees, cos^64 at ~8.5 degrees).
const float kSkyGlowWide = 0.15;
const float kSkyGlowTight = 0.6;
// The sun disc: full radiance out to 0.5 degrees, fading to nothing at 1 degree (measured as
// the chord |dir - sun_dir| = 2 sin(angle / 2), which unlike acos(dot) keeps its precision for
// small angles). A 128^2 face's texel spans ~0.7 degrees, so the fade covers about a texel.
const float kSkySunInner = 0.0087266;  // 2 sin(0.25 degrees)
const float kSkySunOuter = 0.0174531;  // 2 sin(0.5 degrees)
// The disc's radiance in units of sun_color. Bounded, so an FP16 environment (max 65504) holds
// the peak sun for any sun_color below ~1500.
const float kSkySunDisc = 40.0;

// Sky radiance seen along `dir` (normalized, +Y up). `sun_dir` points towards the sun
// (normalized, or zero for no sun), `sun_color` scales the sun's glow and disc. `zenith`,
// `horizon` and `ground` are the radiances straight up, at the horizon and below it. Finite and
// non-negative for every finite input.
vec3 ProceduralSky(vec3 dir, vec3 sun_dir, vec3 sun_color, vec3 zenith, vec3 horizon,
                   vec3 ground) {
  float y = clamp(dir.y, -1.0, 1.0);
  // Above: the horizon's weight falls off as (1 - y)^2, so the sky brightens smoothly towards
  // the horizon; at y = 0 it is exactly `horizon`, where the ground blend starts.
  float h = 1.0 - max(y, 0.0);
  vec3 sky = mix(zenith, horizon, h * h);
  float below = smoothstep(0.0, kSkyGroundBlend, -y);  // 0 above the horizon, 1 past the blend
  vec3 color = mix(sky, ground, below);

  // The sun: cos^8 and cos^64 by repeated squaring (no pow(0, n) corner cases).
  float c = clamp(dot(dir, sun_dir), 0.0, 1.0);
  float c2 = c * c;
  float c4 = c2 * c2;
  float c8 = c4 * c4;
  float c16 = c8 * c8;
  float c32 = c16 * c16;
  float c64 = c32 * c32;
  float chord = length(dir - sun_dir);  // >= 1 for a zero sun_dir: no disc
  float disc = 1.0 - smoothstep(kSkySunInner, kSkySunOuter, chord);
  float sun = kSkyGlowWide * c8 + kSkyGlowTight * c64 + kSkySunDisc * disc;
  color += sun_color * (sun * (1.0 - below));  // the ground hides a sun below the horizon
  return max(color, vec3(0.0));
}
#endif

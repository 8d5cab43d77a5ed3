// The environment: a two-colour hemisphere (sky above, ground below) that is both the visible
// background and the ambient light, so what metals reflect is what the camera sees. With IBL
// (frame.ambient_sky.w = 1) the procedural sky baked into a cube map (renderer/ibl_maps.h) is
// both instead.
#ifndef TESSERA_SKY_GLSL
#define TESSERA_SKY_GLSL

layout(set = 0, binding = kBindingEnvironment) uniform samplerCube u_environment;

bool IblOn() { return frame.ambient_sky.w > 0.5; }

vec3 Hemisphere(vec3 dir) {
  return mix(frame.ambient_ground.rgb, frame.ambient_sky.rgb, clamp(dir.y * 0.5 + 0.5, 0.0, 1.0));
}

// The background along `dir`.
vec3 SkyRadiance(vec3 dir) {
  return IblOn() ? textureLod(u_environment, dir, 0.0).rgb : Hemisphere(dir);
}
#endif

// The environment: a two-colour hemisphere (sky above, ground below) that is both the visible
// background and the ambient light, so what metals reflect is what the camera sees.
#ifndef TESSERA_SKY_GLSL
#define TESSERA_SKY_GLSL

vec3 Hemisphere(vec3 dir) {
  return mix(frame.ambient_ground.rgb, frame.ambient_sky.rgb, clamp(dir.y * 0.5 + 0.5, 0.0, 1.0));
}
#endif

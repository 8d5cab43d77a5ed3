// The sRGB transfer function (IEC 61966-2-1), per channel: what an sRGB colour attachment does
// to a shader's output, for compute shaders that write the bytes into a UNORM storage image.
#ifndef TESSERA_SRGB_GLSL
#define TESSERA_SRGB_GLSL
vec3 EncodeSrgb(vec3 c) {
  c = clamp(c, 0.0, 1.0);
  return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}
#endif

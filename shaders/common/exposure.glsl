// The exposure multiplier, shared by the tonemap pass and bloom's first downsample (bloom is
// thresholded in exposed units, so what blooms does not depend on how bright the scene is).
// params: x = 2^exposure_ev, y = 1 for auto exposure (else fixed), z = the key: the exposed
// luma the frame's average maps to (middle grey). With auto, `state` (1x1, written by
// exposure.comp) holds the view's adapted average log2 luma.
#ifndef TESSERA_EXPOSURE_GLSL
#define TESSERA_EXPOSURE_GLSL
float Exposure(sampler2D state, vec4 params) {
  if (params.y < 0.5) return params.x;
  return params.x * params.z * exp2(-texelFetch(state, ivec2(0), 0).r);
}
#endif

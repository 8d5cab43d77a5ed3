// The terms of the glTF 2.0 metallic-roughness BRDF (Appendix B of the spec): the GGX
// distribution, the height-correlated Smith visibility and Schlick's Fresnel. Shared by the
// shading (shading.glsl) and the IBL prefilter passes (ibl_ggx.glsl), so the table the split sum
// reads is integrated from the very BRDF the lights are shaded with. No bindings: any stage may
// include it.
#ifndef TESSERA_BRDF_GLSL
#define TESSERA_BRDF_GLSL

const float kPi = 3.14159265359;

float DistributionGgx(float n_dot_h, float alpha) {
  float a2 = alpha * alpha;
  float f = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
  return a2 / (kPi * f * f);
}

float VisibilitySmithGgxCorrelated(float n_dot_v, float n_dot_l, float alpha) {
  float a2 = alpha * alpha;
  float gv = n_dot_l * sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
  float gl = n_dot_v * sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
  float s = gv + gl;
  return s > 0.0 ? 0.5 / s : 0.0;
}

// Schlick's weight (1 - v.h)^5 by multiplication: lavapipe builds pow as exp2(log2) with their
// polynomials and special cases, which in the lights' loop cost once per light and pixel.
float SchlickWeight(float v_dot_h) {
  float x = clamp(1.0 - v_dot_h, 0.0, 1.0);
  float x2 = x * x;
  return x2 * x2 * x;
}

#endif

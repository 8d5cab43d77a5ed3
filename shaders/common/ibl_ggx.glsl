// GGX importance sampling shared by the IBL prefilter passes (ibl_specular.comp, ibl_brdf.comp):
// Hammersley points, GGX half-vector sampling, and copies of the GGX distribution and the
// height-correlated Smith visibility of shading.glsl (that file needs the frame data and cannot
// be included by a compute shader; the names carry an Ibl prefix so a shader may include both).
// Keep IblDistributionGgx and IblVisibilitySmithGgxCorrelated identical to DistributionGgx and
// VisibilitySmithGgxCorrelated in shading.glsl, and everything here in step with renderer/ibl.cpp.
#ifndef TESSERA_IBL_GGX_GLSL
#define TESSERA_IBL_GGX_GLSL

const float kIblPi = 3.14159265359;

// Point i of an n-point Hammersley set in [0, 1)^2: (i / n, radical inverse of i in base 2).
vec2 IblHammersley(uint i, uint n) {
  return vec2(float(i) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
}

// A half vector (tangent space, +Z = normal) distributed as D(h) * n_dot_h, the GGX normal
// distribution projected on the normal, from a uniform point xi: phi = 2 pi xi.x and
// cos^2(theta) = (1 - xi.y) / (1 + (alpha^2 - 1) xi.y), the inverse of the CDF of theta.
vec3 IblSampleGgx(vec2 xi, float alpha) {
  float a2 = alpha * alpha;
  float phi = 2.0 * kIblPi * xi.x;
  float cos_theta = sqrt((1.0 - xi.y) / (1.0 + (a2 - 1.0) * xi.y));
  float sin_theta = sqrt(max(1.0 - cos_theta * cos_theta, 0.0));
  return vec3(sin_theta * cos(phi), sin_theta * sin(phi), cos_theta);
}

// Tangent-space vector `t` in the world, around the unit normal `n` (any tangent frame will do:
// the GGX lobe is isotropic).
vec3 IblTangentToWorld(vec3 t, vec3 n) {
  vec3 up = abs(n.z) < 0.999 ? vec3(0.0, 0.0, 1.0) : vec3(1.0, 0.0, 0.0);
  vec3 tx = normalize(cross(up, n));
  vec3 ty = cross(n, tx);
  return tx * t.x + ty * t.y + n * t.z;
}

float IblDistributionGgx(float n_dot_h, float alpha) {
  float a2 = alpha * alpha;
  float f = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
  return a2 / (kIblPi * f * f);
}

float IblVisibilitySmithGgxCorrelated(float n_dot_v, float n_dot_l, float alpha) {
  float a2 = alpha * alpha;
  float gv = n_dot_l * sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
  float gl = n_dot_v * sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
  float s = gv + gl;
  return s > 0.0 ? 0.5 / s : 0.0;
}
#endif

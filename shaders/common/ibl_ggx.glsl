// GGX importance sampling shared by the IBL prefilter passes (ibl_specular.comp, ibl_brdf.comp):
// Hammersley points and GGX half-vector sampling; the BRDF terms themselves are brdf.glsl's, the
// shading's own. Keep everything here in step with renderer/ibl.cpp.
#ifndef TESSERA_IBL_GGX_GLSL
#define TESSERA_IBL_GGX_GLSL

#include "common/brdf.glsl"

// Point i of an n-point Hammersley set in [0, 1)^2: (i / n, radical inverse of i in base 2).
vec2 IblHammersley(uint i, uint n) {
  return vec2(float(i) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
}

// A half vector (tangent space, +Z = normal) distributed as D(h) * n_dot_h, the GGX normal
// distribution projected on the normal, from a uniform point xi: phi = 2 pi xi.x and
// cos^2(theta) = (1 - xi.y) / (1 + (alpha^2 - 1) xi.y), the inverse of the CDF of theta.
vec3 IblSampleGgx(vec2 xi, float alpha) {
  float a2 = alpha * alpha;
  float phi = 2.0 * kPi * xi.x;
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

#endif

#pragma once
// tessera.v1.Vec3 <-> glm, shared by the wire conversions (convert.cpp) and the job camera
// paths (job_spec.cpp).
#include <cmath>

#include <glm/vec3.hpp>

#include "tessera/v1/settings.pb.h"

namespace tessera {

inline bool Finite(const v1::Vec3& v) {
  return std::isfinite(v.x()) && std::isfinite(v.y()) && std::isfinite(v.z());
}

inline glm::vec3 Vec(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

inline void SetVec(const glm::vec3& v, v1::Vec3* out) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

}  // namespace tessera

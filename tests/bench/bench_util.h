#pragma once
// Helpers shared by the benchmark programs: order statistics of timings, argument parsing.
#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"

namespace tessera::bench {

inline double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Nearest-rank percentile, p in (0, 100].
inline double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t rank = static_cast<size_t>(std::ceil(p / 100.0 * double(v.size())));
  return v[std::clamp<size_t>(rank, 1, v.size()) - 1];
}

// "X,Y,Z" -> a vector, or nullopt when it is not three numbers.
inline std::optional<glm::vec3> ParseVec3(const std::string& s) {
  const std::vector<std::string> p = absl::StrSplit(s, ',');
  glm::vec3 v(0.0f);
  if (p.size() != 3) return std::nullopt;
  for (int i = 0; i < 3; ++i)
    if (!absl::SimpleAtof(p[i], &v[i])) return std::nullopt;
  return v;
}

}  // namespace tessera::bench

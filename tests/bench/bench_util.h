#pragma once
// Helpers shared by the benchmark programs: order statistics of timings, argument parsing.
#include <errno.h>  // program_invocation_short_name

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <glm/glm.hpp>
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

// The extremes, for the spread of a figure (0 for none).
inline double Min(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::min_element(v.begin(), v.end());
}
inline double Max(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

// Nearest-rank percentile, p in (0, 100].
inline double Percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const size_t rank = static_cast<size_t>(std::ceil(p / 100.0 * double(v.size())));
  return v[std::clamp<size_t>(rank, 1, v.size()) - 1];
}

// Prints "PROGRAM: msg" and exits with status 2 (bad arguments or a failed run).
[[noreturn]] inline void Fail(const std::string& msg) {
  std::fprintf(stderr, "%s: %s\n", program_invocation_short_name, msg.c_str());
  std::exit(2);
}

// "X,Y,Z" -> a vector; anything else fails.
inline glm::vec3 ParseVec3(const std::string& s) {
  const std::vector<std::string> p = absl::StrSplit(s, ',');
  glm::vec3 v(0.0f);
  if (p.size() != 3) Fail("want X,Y,Z: " + s);
  for (int i = 0; i < 3; ++i)
    if (!absl::SimpleAtof(p[i], &v[i])) Fail("not a number: " + p[i]);
  return v;
}

}  // namespace tessera::bench

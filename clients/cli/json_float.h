#pragma once
// A float for JSON output, shared by the `tessera` CLI and tessera-render (no proto here).
#include <charconv>
#include <cmath>
#include <cstdlib>

namespace tessera::cli {

// The shortest decimal that reads back as the same float, so 0.8f prints as 0.8 and not
// 0.800000011920929.
inline double FloatForJson(float f) {
  if (!std::isfinite(f)) return f;
  char buf[32];
  const auto [end, ec] = std::to_chars(buf, buf + sizeof(buf) - 1, f);
  if (ec != std::errc()) return f;
  *end = '\0';
  return std::strtod(buf, nullptr);
}

}  // namespace tessera::cli

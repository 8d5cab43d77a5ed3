#pragma once
// SPIR-V of the shaders in shaders/, compiled at build time and linked into the binary.
#include <cstdint>
#include <span>
#include <string_view>

namespace tessera {
// Returns the SPIR-V words of shader `name` (its file name, e.g. "forward.frag"), or an empty span.
std::span<const uint32_t> EmbeddedShader(std::string_view name);
}  // namespace tessera

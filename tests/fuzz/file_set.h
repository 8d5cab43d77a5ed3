#pragma once
// The glTF fuzz target's input format: a whole in-memory file set in one byte string.
//
//   "TSFS" then records of  u16 name length, name, u32 data length, data  (little endian);
//   the first record is the main file. A record cut short ends the set.
//   Anything else is one main file, "fuzz.glb" when it starts with "glTF", else "fuzz.gltf".
//
// tests/fuzz/make_seeds.py writes the first form from a .gltf on disk (seed corpus).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>

#include "renderer/scene/gltf_import.h"

namespace tessera::fuzz {

// The server's import limits, tightened where a fuzzer needs to stay fast and far below its
// memory limits (run.sh: -malloc_limit_mb=512, -rss_limit_mb=2048).
inline ImportLimits FuzzImportLimits() {
  ImportLimits limits;
  limits.max_vertices = 1u << 20;
  limits.max_indices = 1u << 22;
  limits.max_accessor_elements = 1u << 20;
  limits.max_accessor_bytes = 64u << 20;
  limits.max_image_dimension = 4096;
  limits.max_image_bytes = 64u << 20;
  limits.max_total_image_bytes = 128u << 20;
  limits.max_drawables = 1u << 16;
  limits.max_decoded_bytes = 64u << 20;
  return limits;
}

inline GltfSource UnpackFileSet(const uint8_t* data, size_t size) {
  GltfSource src;
  if (size < 4 || std::memcmp(data, "TSFS", 4) != 0) {
    src.main_file = size >= 4 && std::memcmp(data, "glTF", 4) == 0 ? "fuzz.glb" : "fuzz.gltf";
    src.files[src.main_file].assign(data, data + size);
    return src;
  }
  size_t at = 4;
  auto read = [&](size_t n, uint64_t* out) {
    if (size - at < n) return false;
    *out = 0;
    for (size_t i = 0; i < n; ++i) *out |= uint64_t(data[at + i]) << (8 * i);
    at += n;
    return true;
  };
  uint64_t name_len = 0, data_len = 0;
  while (read(2, &name_len) && size - at >= name_len) {
    std::string name(reinterpret_cast<const char*>(data + at), name_len);
    at += name_len;
    if (!read(4, &data_len) || size - at < data_len) break;
    if (src.main_file.empty()) src.main_file = name;
    src.files[name].assign(data + at, data + at + data_len);  // a repeated name: the last wins
    at += data_len;
  }
  if (src.main_file.empty()) src.main_file = "fuzz.gltf";  // an empty set: "not in the file set"
  return src;
}

}  // namespace tessera::fuzz

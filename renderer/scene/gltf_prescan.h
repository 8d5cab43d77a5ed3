#pragma once
// Internal to the glTF importer (gltf_import.cpp): the checks that run before tinygltf sees the
// data. GLB container, JSON nesting depth, and a pre-scan of the JSON (required extensions,
// buffer/image URIs against the file set, buffer and bufferView ranges, image bufferViews,
// primitive indices). Deliberately free of tinygltf and nlohmann headers.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "renderer/scene/gltf_decode.h"
#include "renderer/scene/gltf_import.h"

namespace tessera::gltf_internal {

// Cuts long strings (base64 URIs, tinygltf dumps) so messages stay readable.
std::string Quote(absl::string_view s);

// "<file>: <field>: <what>", the shape of every import error.
template <typename... Args>
absl::Status Invalid(absl::string_view file, absl::string_view field, const Args&... what) {
  return absl::InvalidArgumentError(absl::StrCat(file, ": ", field, ": ", what...));
}

// "<file>: <field>: <what>" as RESOURCE_EXHAUSTED, for an asset over one of the ImportLimits
// (`what` names the limit).
template <typename... Args>
absl::Status OverLimit(absl::string_view file, absl::string_view field, const Args&... what) {
  return absl::ResourceExhaustedError(absl::StrCat(file, ": ", field, ": ", what...));
}

// What the pre-scan found, for the tinygltf load that follows. `bytes` and `text` point into
// the GltfSource that was scanned and live as long as it does.
struct PreScanResult {
  bool is_glb = false;                          // the main file starts with the GLB magic
  const std::vector<uint8_t>* bytes = nullptr;  // the main file, as in the file set
  absl::string_view text;                       // the JSON tinygltf reads: the whole file or
                                                // the GLB JSON chunk, or in `rewritten`
  // The main file as tinygltf is to read it, when the JSON had to change for it (meshopt
  // fallback buffers); `text` then points into it (its heap buffer survives moves).
  std::vector<uint8_t> rewritten;
  // A core integer field was written as a float (1.0): the JSON is re-written with the integer.
  bool integers_rewritten = false;
  const std::vector<uint8_t>& main_bytes() const { return rewritten.empty() ? *bytes : rewritten; }
  std::map<uint32_t, uint64_t> fallback_buffers;  // buffer index -> byteLength (no data)
  std::map<uint32_t, MeshoptView> meshopt_views;  // bufferView index -> what it decodes
  // (mesh, primitive) -> its indices accessor, for Draco primitives (taken out of the JSON).
  std::map<std::pair<uint32_t, uint32_t>, uint32_t> draco_indices;
  std::map<std::string, std::string> alias;     // tinygltf-decoded URI -> key in source.files
  std::vector<bool> image_needed;  // per image: a texture samples it (its WebP source, if any)
  std::vector<bool> image_webp;    // per image: an EXT_texture_webp source (may be WebP data)
  // Per texture with an EXT_texture_webp source (where extensionsUsed lists it): that image.
  std::map<uint32_t, uint32_t> webp_sources;
  // Per node with EXT_mesh_gpu_instancing (where extensionsUsed lists it): its attributes, each
  // name and accessor index (checked in range; at least one).
  std::map<uint32_t, std::vector<std::pair<std::string, uint32_t>>> instancing;
  // Per material with KHR_materials_ior or KHR_materials_specular: their values as the pre-scan
  // read and checked them (tinygltf keeps an extension's integers as 32-bit ints, so an index or
  // a factor written as 4294967296 would reach the importer as 0).
  struct Reflectance {
    double ior = 1.5;                            // 0, or at least 1
    double specular_factor = 1.0;                // [0, 1]
    double specular_color[3] = {1.0, 1.0, 1.0};  // non-negative
    // The textureInfos' texture indices (checked in range; -1: none) and texCoords.
    int32_t specular_texture = -1, specular_color_texture = -1;
    uint32_t specular_texcoord = 0, specular_color_texcoord = 0;
  };
  std::map<uint32_t, Reflectance> reflectance;
  std::vector<std::string> warnings;            // unsupported extensionsUsed, in order
};

// Checks source before tinygltf sees it; INVALID_ARGUMENT "<file>: <field>: <what>" if unsafe,
// RESOURCE_EXHAUSTED naming the limit if it is over one of `limits` that the JSON alone tells
// (JSON size and depth, counts of nodes, meshes, primitives, textures and lights, accessor
// sizes).
absl::StatusOr<PreScanResult> PreScanGltf(const GltfSource& source, const ImportLimits& limits);

}  // namespace tessera::gltf_internal

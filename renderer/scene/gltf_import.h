#pragma once
// glTF 2.0 import from memory. The file set is untrusted: nothing is ever read from disk,
// every size and index is checked, and errors name the file and the field.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/scene/cpu_scene.h"

namespace tessera {

// A glTF asset as a named set of files: the main .gltf or .glb plus whatever its URIs name
// (buffers, images), keyed by the URI as written in the file (after %-decoding).
struct GltfSource {
  std::string main_file;  // key of the .gltf/.glb in `files`
  std::map<std::string, std::vector<uint8_t>> files;
};

struct ImportLimits {
  uint64_t max_vertices = 1u << 26;  // after expansion to the scene vertex buffer
  uint64_t max_indices = 1u << 28;
  uint32_t max_image_dimension = 16384;    // per side; larger images are an error
  uint64_t max_image_pixels = 1ull << 26;  // per image
  uint32_t max_drawables = 1u << 20;
};

// Parses, validates and converts `source` into a CpuScene (default scene, or scene 0).
// Errors are INVALID_ARGUMENT with a message naming the file and the glTF field, e.g.
// "Box.gltf: accessors[2]: byteOffset + count*stride exceeds bufferViews[1]".
absl::StatusOr<CpuScene> ImportGltf(const GltfSource& source, const ImportLimits& limits = {});

// Builds a GltfSource from a file on disk: the .gltf/.glb itself plus every buffer and image
// URI it names that resolves to a file in the same directory tree. For trusted local tools
// (render tool, CLI uploads); the importer itself never touches the file system.
absl::StatusOr<GltfSource> LoadGltfSourceFromDisk(const std::string& path);

}  // namespace tessera

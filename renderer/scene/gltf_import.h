#pragma once
// glTF 2.0 import from memory. The file set is untrusted: nothing is ever read from disk,
// every size and index is checked, and errors name the file and the field.
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/scene/cpu_scene.h"
#include "renderer/scene/import_limits.h"

namespace tessera {

// A glTF asset as a named set of files: the main .gltf or .glb plus whatever its URIs name
// (buffers, images), keyed by the URI as written in the file (after %-decoding).
struct GltfSource {
  std::string main_file;  // key of the .gltf/.glb in `files`
  std::map<std::string, std::vector<uint8_t>> files;
};

// Parses, validates and converts `source` into a CpuScene (default scene, or scene 0).
// Errors are INVALID_ARGUMENT with a message naming the file and the glTF field, e.g.
// "Box.gltf: accessors[2]: byteOffset + count*stride exceeds bufferViews[1]", or
// RESOURCE_EXHAUSTED naming the limit in `limits` (import_limits.h) the asset exceeds.
absl::StatusOr<CpuScene> ImportGltf(const GltfSource& source, const ImportLimits& limits = {});

// The glTF extensions the importer reads (a file may also require them); any other one in
// extensionsUsed is ignored with a warning, and a file that requires one is refused.
const std::vector<std::string_view>& SupportedGltfExtensions();

// Builds a GltfSource from a file on disk: the .gltf/.glb itself plus every buffer and image
// URI it names that resolves to a file in the same directory tree. A directory means the one
// .gltf or .glb in it (NOT_FOUND naming it when there is none, INVALID_ARGUMENT listing them when
// there are several); anything else that is not a regular file is INVALID_ARGUMENT. For trusted
// local tools (render tool, CLI uploads); the importer itself never touches the file system.
absl::StatusOr<GltfSource> LoadGltfSourceFromDisk(const std::string& path);

// A decoded texture image: RGBA8, width x height.
struct DecodedImage {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> rgba8;
};

// Decodes a texture image the way the importer does: PNG (libpng) or JPEG (TurboJPEG), the
// types glTF 2.0 allows, or WebP (libwebp; the importer allows it for EXT_texture_webp
// sources only), to RGBA8. The header is read first, so a size over
// limits.max_image_dimension or max_image_bytes is refused (RESOURCE_EXHAUSTED naming the
// limit) before any pixel memory is allocated; anything else that does not decode is
// INVALID_ARGUMENT. Messages do not name the image: the caller does.
absl::StatusOr<DecodedImage> DecodeTextureImage(const uint8_t* bytes, size_t size,
                                                const ImportLimits& limits);

}  // namespace tessera

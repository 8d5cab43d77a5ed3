#pragma once
// Internal to the glTF importer: the decoders of compressed geometry, behind a header free of
// their libraries' headers. EXT_meshopt_compression bufferViews decode with meshoptimizer
// (Debian's libmeshoptimizer-dev), KHR_draco_mesh_compression primitives with Draco
// (libdraco-dev). The input is untrusted: every parameter the decoders would assert on is checked
// first, the output is written only into memory the caller sized, and a decoder failure is an
// error status whose message says what failed (the caller adds the file and the field).
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace tessera::gltf_internal {

// bufferViews[i].extensions.EXT_meshopt_compression, as checked by the pre-scan.
struct MeshoptView {
  enum class Mode { kAttributes, kTriangles, kIndices };
  enum class Filter { kNone, kOctahedral, kQuaternion, kExponential };
  uint32_t buffer = 0;      // where the compressed bytes are
  uint64_t byte_offset = 0;
  uint64_t byte_length = 0;
  uint32_t byte_stride = 0;  // of the decoded elements
  uint64_t count = 0;        // decoded elements
  Mode mode = Mode::kAttributes;
  Filter filter = Filter::kNone;
};

// What is wrong with the decode parameters of `v` (the rules of the extension's specification,
// which are also what meshoptimizer asserts), or "" when they are valid.
std::string CheckMeshoptParameters(const MeshoptView& v);

// Decodes `src` (the compressed bytes) into `dst`, which holds exactly count x byteStride bytes,
// and applies the filter. `v` must have passed CheckMeshoptParameters.
absl::Status DecodeMeshopt(const MeshoptView& v, std::span<const uint8_t> src,
                           std::span<uint8_t> dst);

// One attribute wanted from a Draco mesh: the Draco attribute's unique id and the accessor it
// fills (glTF component type and component count); values are converted to that type, packed.
struct DracoAttributeRequest {
  uint32_t unique_id = 0;
  int component_type = 0;  // a glTF componentType (5120..5126)
  int components = 0;      // 1..4 (SCALAR..VEC4)
  std::vector<uint8_t>* out = nullptr;
};

struct DracoMesh {
  uint64_t points = 0;            // vertices
  std::vector<uint8_t> index_bytes;  // a triangle list, UNSIGNED_INT as glTF stores it
};

// Decodes a Draco mesh and fills each request with `points` elements. Refuses a point cloud, a
// mesh with more than `max_points` points or `max_indices` indices (what its accessors declare;
// checked before anything is copied out), a missing attribute id, and an attribute whose
// component count differs from the request. Draco's own working memory during the decode grows
// with the data's declared counts; the caller has bounded the output, not that.
absl::StatusOr<DracoMesh> DecodeDraco(std::span<const uint8_t> bytes,
                                      std::span<DracoAttributeRequest> requests,
                                      uint64_t max_points, uint64_t max_indices);

}  // namespace tessera::gltf_internal

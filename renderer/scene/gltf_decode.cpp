#include "renderer/scene/gltf_decode.h"

#include <draco/compression/decode.h>
#include <meshoptimizer.h>

#include <cstring>
#include <limits>
#include <memory>

#include "absl/strings/str_cat.h"

namespace tessera::gltf_internal {

std::string CheckMeshoptParameters(const MeshoptView& v) {
  using Mode = MeshoptView::Mode;
  using Filter = MeshoptView::Filter;
  const uint32_t s = v.byte_stride;
  if (v.count == 0) return "count must be at least 1";
  switch (v.mode) {
    case Mode::kAttributes:
      if (s == 0 || s > 256 || s % 4 != 0) {
        return absl::StrCat("byteStride ", s,
                            " for mode ATTRIBUTES: wants a multiple of 4 up to 256");
      }
      break;
    case Mode::kTriangles:
      if (v.count % 3 != 0) {
        return absl::StrCat("count ", v.count, " for mode TRIANGLES: wants a multiple of 3");
      }
      [[fallthrough]];
    case Mode::kIndices:
      if (s != 2 && s != 4) {
        return absl::StrCat("byteStride ", s, " for mode ",
                            v.mode == Mode::kTriangles ? "TRIANGLES" : "INDICES",
                            ": wants 2 or 4");
      }
      break;
  }
  if (v.filter != Filter::kNone && v.mode != Mode::kAttributes) {
    return "a filter other than NONE needs mode ATTRIBUTES";
  }
  if (v.filter == Filter::kOctahedral && s != 4 && s != 8) {
    return absl::StrCat("byteStride ", s, " for filter OCTAHEDRAL: wants 4 or 8");
  }
  if (v.filter == Filter::kQuaternion && s != 8) {
    return absl::StrCat("byteStride ", s, " for filter QUATERNION: wants 8");
  }
  return "";  // EXPONENTIAL: a multiple of 4, as ATTRIBUTES requires
}

absl::Status DecodeMeshopt(const MeshoptView& v, std::span<const uint8_t> src,
                           std::span<uint8_t> dst) {
  using Mode = MeshoptView::Mode;
  using Filter = MeshoptView::Filter;
  if (const std::string bad = CheckMeshoptParameters(v); !bad.empty()) {
    return absl::InvalidArgumentError(bad);
  }
  uint64_t size = 0;
  if (__builtin_mul_overflow(v.count, uint64_t(v.byte_stride), &size) || size != dst.size()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "count x byteStride (", v.count, " x ", v.byte_stride, ") is not the ", dst.size(),
        " bytes of the bufferView"));
  }
  int rc = 0;
  switch (v.mode) {
    case Mode::kAttributes:
      rc = meshopt_decodeVertexBuffer(dst.data(), v.count, v.byte_stride, src.data(), src.size());
      break;
    case Mode::kTriangles:
      rc = meshopt_decodeIndexBuffer(dst.data(), v.count, v.byte_stride, src.data(), src.size());
      break;
    case Mode::kIndices:
      rc = meshopt_decodeIndexSequence(dst.data(), v.count, v.byte_stride, src.data(), src.size());
      break;
  }
  if (rc != 0) {
    const char* what = v.mode == Mode::kAttributes ? "vertex" : "index";
    return absl::InvalidArgumentError(absl::StrCat(
        "meshopt ", what, " data does not decode (meshoptimizer error ", rc, ": ",
        rc == -1 ? "unsupported encoding version" : "malformed or truncated data", ")"));
  }
  switch (v.filter) {
    case Filter::kNone:
      break;
    case Filter::kOctahedral:
      meshopt_decodeFilterOct(dst.data(), v.count, v.byte_stride);
      break;
    case Filter::kQuaternion:
      meshopt_decodeFilterQuat(dst.data(), v.count, v.byte_stride);
      break;
    case Filter::kExponential:
      meshopt_decodeFilterExp(dst.data(), v.count, v.byte_stride);
      break;
  }
  return absl::OkStatus();
}

namespace {

template <typename T>
bool CopyConverted(const draco::PointAttribute& att, uint64_t points, int components,
                   std::vector<uint8_t>* out) {
  out->assign(points * components * sizeof(T), 0);
  T* dst = reinterpret_cast<T*>(out->data());
  for (uint64_t p = 0; p < points; ++p) {
    const draco::AttributeValueIndex avi = att.mapped_index(draco::PointIndex(uint32_t(p)));
    if (avi.value() >= att.size()) return false;
    if (!att.ConvertValue<T>(avi, int8_t(components), dst + p * components)) return false;
  }
  return true;
}

}  // namespace

absl::StatusOr<DracoMesh> DecodeDraco(std::span<const uint8_t> bytes,
                                      std::span<DracoAttributeRequest> requests,
                                      uint64_t max_points, uint64_t max_indices) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  draco::StatusOr<draco::EncodedGeometryType> type =
      draco::Decoder::GetEncodedGeometryType(&buffer);
  if (!type.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("Draco: ", type.status().error_msg_string()));
  }
  if (type.value() != draco::TRIANGULAR_MESH) {
    return absl::InvalidArgumentError("Draco: the data is a point cloud, not a triangle mesh");
  }
  draco::Decoder decoder;
  draco::StatusOr<std::unique_ptr<draco::Mesh>> decoded = decoder.DecodeMeshFromBuffer(&buffer);
  if (!decoded.ok()) {
    return absl::InvalidArgumentError(
        absl::StrCat("Draco: ", decoded.status().error_msg_string()));
  }
  const draco::Mesh& mesh = *decoded.value();
  DracoMesh result;
  result.points = mesh.num_points();
  const uint64_t index_count = uint64_t(mesh.num_faces()) * 3;
  if (result.points > max_points) {
    return absl::InvalidArgumentError(
        absl::StrCat("Draco: ", result.points, " points, more than the accessors' ", max_points));
  }
  if (index_count > max_indices) {
    return absl::InvalidArgumentError(absl::StrCat("Draco: ", index_count,
                                                     " indices, more than the accessor's ",
                                                     max_indices));
  }
  result.index_bytes.resize(index_count * 4);
  for (uint32_t f = 0; f < mesh.num_faces(); ++f) {
    const draco::Mesh::Face& face = mesh.face(draco::FaceIndex(f));
    for (int c = 0; c < 3; ++c) {
      const uint32_t i = face[c].value();
      if (i >= result.points) {
        return absl::InvalidArgumentError(absl::StrCat("Draco: face ", f, " names point ", i,
                                                       " of ", result.points));
      }
      std::memcpy(&result.index_bytes[(uint64_t(f) * 3 + c) * 4], &i, 4);
    }
  }
  for (DracoAttributeRequest& r : requests) {
    const draco::PointAttribute* att = mesh.GetAttributeByUniqueId(r.unique_id);
    if (att == nullptr) {
      return absl::InvalidArgumentError(
          absl::StrCat("Draco: the data has no attribute with id ", r.unique_id));
    }
    if (att->num_components() != r.components) {
      return absl::InvalidArgumentError(absl::StrCat(
          "Draco: attribute ", r.unique_id, " has ", int(att->num_components()),
          " components where its accessor has ", r.components));
    }
    bool ok = false;
    switch (r.component_type) {
      case 5120: ok = CopyConverted<int8_t>(*att, result.points, r.components, r.out); break;
      case 5121: ok = CopyConverted<uint8_t>(*att, result.points, r.components, r.out); break;
      case 5122: ok = CopyConverted<int16_t>(*att, result.points, r.components, r.out); break;
      case 5123: ok = CopyConverted<uint16_t>(*att, result.points, r.components, r.out); break;
      case 5125: ok = CopyConverted<uint32_t>(*att, result.points, r.components, r.out); break;
      case 5126: ok = CopyConverted<float>(*att, result.points, r.components, r.out); break;
      default:
        return absl::InvalidArgumentError(
            absl::StrCat("Draco: componentType ", r.component_type, " is not an attribute type"));
    }
    if (!ok) {
      return absl::InvalidArgumentError(absl::StrCat(
          "Draco: attribute ", r.unique_id, " does not convert to its accessor's componentType ",
          r.component_type, " (a value out of range, or data shorter than its points)"));
    }
  }
  return result;
}

}  // namespace tessera::gltf_internal

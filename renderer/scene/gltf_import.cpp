// glTF 2.0 import. The input comes from the network, so the JSON is pre-scanned (gltf_prescan.cpp:
// URIs, buffer and bufferView ranges, required extensions) before tinygltf sees it, tinygltf only
// reads from the in-memory file set, and every index and size of the parsed model is checked again
// before it is dereferenced.
#include "renderer/scene/gltf_import.h"

#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <deque>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <span>
#include <tuple>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "common/status_macros.h"
#include "renderer/image_io.h"
#include "renderer/scene/gltf_prescan.h"

namespace tessera {
namespace {

using gltf_internal::Invalid;
using gltf_internal::OverLimit;
using gltf_internal::Quote;

constexpr size_t kMaxWarnings = 100;  // hostile files must not grow the warning list forever
// Bound on unbounded material parameters (emissive strength, normal scale, UV transforms):
// far past any real asset, far below where float products overflow in a shader.
constexpr float kMaxFactor = 1e6f;
// Candela or lux: the sun is 1e5 lux.
constexpr float kMaxLightIntensity = 1e9f;

// double -> float outside the float range is undefined behaviour; clamp instead.
float ToFloat(double d) {
  if (std::isnan(d)) return 0.0f;
  constexpr double kMax = std::numeric_limits<float>::max();
  return static_cast<float>(std::clamp(d, -kMax, kMax));
}

// ---------------------------------------------------------------------------------------------
// tinygltf callbacks: files come only from the file set; images decode with libpng and
// TurboJPEG (image_io.h), the decoders the frames use, and EXT_texture_webp's sources with
// libwebp. Not stb_image: fuzzing found that the Debian 12 build writes past a Huffman table on
// a crafted JPEG (tests/fuzz/regressions/image), and glTF 2.0 allows only PNG and JPEG images
// anyway.

struct LoadContext {
  const GltfSource* source = nullptr;
  const ImportLimits* limits = nullptr;
  std::map<std::string, std::string> alias;  // tinygltf-decoded URI -> key in source->files
  std::vector<bool> image_needed;            // referenced by some texture
  std::vector<bool> image_webp;              // an EXT_texture_webp source: may be WebP
  uint64_t decoded_bytes = 0;                // RGBA8 bytes of the images decoded so far
  absl::Status error;                        // first error raised inside a callback
};

bool FsFileExists(const std::string& path, void* user) {
  return static_cast<LoadContext*>(user)->alias.count(path) > 0;
}

std::string FsExpandFilePath(const std::string& path, void*) { return path; }

bool FsReadWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                     void* user) {
  const auto* ctx = static_cast<LoadContext*>(user);
  const auto a = ctx->alias.find(path);
  const auto f =
      a == ctx->alias.end() ? ctx->source->files.end() : ctx->source->files.find(a->second);
  if (f == ctx->source->files.end()) {
    if (err) *err += path + ": not in the file set\n";
    return false;
  }
  out->assign(f->second.begin(), f->second.end());
  return true;
}

bool FsWriteWholeFile(std::string* err, const std::string&, const std::vector<unsigned char>&,
                      void*) {
  if (err) *err += "writing is not allowed\n";
  return false;
}

// The header's size against the limits: before the decode allocates, and again after it (the
// decoder may disagree with its own header).
absl::Status CheckImageSize(int64_t w, int64_t h, const ImportLimits& lim,
                            uint64_t already_decoded) {
  if (w <= 0 || h <= 0) return absl::InvalidArgumentError(absl::StrCat(w, "x", h, " has no pixels"));
  if (uint64_t(w) > lim.max_image_dimension || uint64_t(h) > lim.max_image_dimension) {
    return absl::ResourceExhaustedError(absl::StrCat(
        w, "x", h, " exceeds the max_image_dimension limit (", lim.max_image_dimension, ")"));
  }
  uint64_t bytes = 0, total = 0;
  if (__builtin_mul_overflow(uint64_t(w) * uint64_t(h), uint64_t{4}, &bytes) ||
      bytes > lim.max_image_bytes) {
    return absl::ResourceExhaustedError(absl::StrCat(w, "x", h, " decodes to ", bytes,
                                                     " bytes, over the max_image_bytes limit (",
                                                     lim.max_image_bytes, ")"));
  }
  if (__builtin_add_overflow(already_decoded, bytes, &total) || total > lim.max_total_image_bytes) {
    return absl::ResourceExhaustedError(
        absl::StrCat(w, "x", h, " brings the decoded images to ", total,
                     " bytes, over the max_total_image_bytes limit (", lim.max_total_image_bytes,
                     ")"));
  }
  return absl::OkStatus();
}

uint32_t Be32(const uint8_t* p) {
  return uint32_t(p[0]) << 24 | uint32_t(p[1]) << 16 | uint32_t(p[2]) << 8 | uint32_t(p[3]);
}
uint32_t Be16(const uint8_t* p) { return uint32_t(p[0]) << 8 | uint32_t(p[1]); }

// Width and height from a PNG's IHDR or a JPEG's SOF marker, read without a decoder, so that
// the size is checked before anything is allocated. False when the header is cut short or
// declares no size.
bool ReadImageHeader(const uint8_t* d, size_t n, uint32_t* w, uint32_t* h) {
  static constexpr uint8_t kPng[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (n >= 24 && std::memcmp(d, kPng, 8) == 0 && std::memcmp(d + 12, "IHDR", 4) == 0) {
    *w = Be32(d + 16);
    *h = Be32(d + 20);
    return *w > 0 && *h > 0;
  }
  if (n < 4 || d[0] != 0xFF || d[1] != 0xD8) return false;
  for (size_t i = 2; i + 4 <= n;) {
    if (d[i] != 0xFF) return false;
    const uint8_t marker = d[i + 1];
    if (marker == 0xFF) {  // fill byte
      ++i;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) {  // markers without a length
      i += 2;
      continue;
    }
    if (marker == 0xD9 || marker == 0xDA) return false;  // end of image, start of scan
    const size_t length = Be16(d + i + 2);
    if (length < 2) return false;
    // SOF0..SOF15, except DHT (C4), JPG (C8) and DAC (CC): length, precision, height, width.
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
      if (i + 9 > n) return false;
      *h = Be16(d + i + 5);
      *w = Be16(d + i + 7);
      return *w > 0 && *h > 0;
    }
    i += 2 + length;
  }
  return false;
}

bool IsPng(const uint8_t* d, size_t n) { return n >= 8 && std::memcmp(d, "\x89PNG\r\n\x1a\n", 8) == 0; }
bool IsJpeg(const uint8_t* d, size_t n) { return n >= 3 && d[0] == 0xFF && d[1] == 0xD8 && d[2] == 0xFF; }
// The media type the data's signature says, or null for none of the three.
const char* MimeTypeOf(const uint8_t* d, size_t n) {
  return IsPng(d, n)                              ? "image/png"
         : IsJpeg(d, n)                           ? "image/jpeg"
         : IsWebp(std::span<const uint8_t>(d, n)) ? "image/webp"
                                                  : nullptr;
}

// PNG or JPEG, or with `webp` (an EXT_texture_webp source) WebP too.
absl::StatusOr<DecodedImage> DecodeImage(const uint8_t* bytes, size_t size,
                                         const ImportLimits& limits, uint64_t already_decoded,
                                         bool webp) {
  if (bytes == nullptr || size == 0) return absl::InvalidArgumentError("no image data");
  const std::span<const uint8_t> file(bytes, size);
  const char* mime_type = MimeTypeOf(bytes, size);
  const bool png = mime_type && std::strcmp(mime_type, "image/png") == 0;
  const bool is_webp = mime_type && std::strcmp(mime_type, "image/webp") == 0;
  if (is_webp && !webp) {
    return absl::InvalidArgumentError(
        "a WebP image, which glTF allows only as a texture's EXT_texture_webp source");
  }
  if (mime_type == nullptr) {
    return absl::InvalidArgumentError(
        webp ? "not a PNG, JPEG or WebP image"
             : "not a PNG or JPEG image (the image types glTF 2.0 allows)");
  }
  const char* type = png ? "PNG" : is_webp ? "WebP" : "JPEG";
  uint32_t w = 0, h = 0;
  if (is_webp ? !ReadWebpSize(file, &w, &h) : !ReadImageHeader(bytes, size, &w, &h)) {
    return absl::InvalidArgumentError(
        absl::StrCat("cannot decode: the ", type, " header is cut short or declares no size"));
  }
  RETURN_IF_ERROR(CheckImageSize(w, h, limits, already_decoded));
  const uint64_t max_pixels = uint64_t(w) * h;  // what the header promised, and was checked
  absl::StatusOr<RgbaImage> image = png       ? DecodePng(file, max_pixels)
                                    : is_webp ? DecodeWebp(file, max_pixels)
                                              : DecodeJpeg(file, max_pixels);
  if (!image.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("cannot decode: ", image.status().message()));
  }
  if (image->width != w || image->height != h) {
    return absl::InvalidArgumentError(absl::StrCat("cannot decode: the header says ", w, "x", h,
                                                   ", the data ", image->width, "x",
                                                   image->height));
  }
  return DecodedImage{.width = w, .height = h, .rgba8 = std::move(image->pixels)};
}

// Decodes every image a texture uses to RGBA8, after checking the size its header declares.
bool LoadImage(tinygltf::Image* image, const int index, std::string* err, std::string*, int, int,
               const unsigned char* bytes, int size, void* user) {
  auto* ctx = static_cast<LoadContext*>(user);
  // The declared type (a bufferView image's mimeType, a data: URI's media type) is the data's.
  const size_t n = size_t(std::max(size, 0));
  const char* actual = MimeTypeOf(bytes, n);
  if (actual != nullptr && !image->mimeType.empty() && image->mimeType != actual) {
    if (ctx->error.ok()) {
      ctx->error = Invalid(ctx->source->main_file, absl::StrCat("images[", index, "].mimeType"),
                           "'", Quote(image->mimeType), "', but the data is ", actual);
    }
    if (err) err->append(std::string(ctx->error.message()));
    return false;
  }
  if (index < 0 || size_t(index) >= ctx->image_needed.size() || !ctx->image_needed[index]) {
    return true;  // no texture uses it: skip the decode
  }
  const bool webp = size_t(index) < ctx->image_webp.size() && ctx->image_webp[index];
  absl::StatusOr<DecodedImage> decoded =
      DecodeImage(bytes, size_t(std::max(size, 0)), *ctx->limits, ctx->decoded_bytes, webp);
  if (decoded.ok()) {
    ctx->decoded_bytes += decoded->rgba8.size();
    image->width = int(decoded->width);
    image->height = int(decoded->height);
    image->component = 4;
    image->bits = 8;
    image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    image->image = std::move(decoded->rgba8);
    return true;
  }
  const std::string& name = image->name.empty() ? image->uri : image->name;
  if (ctx->error.ok()) {
    const std::string named = name.empty() ? "" : absl::StrCat(" (", Quote(name), ")");
    ctx->error = absl::Status(decoded.status().code(),
                              absl::StrCat(ctx->source->main_file, ": images[", index, "]", named,
                                           ": ", decoded.status().message()));
  }
  if (err) err->append(std::string(ctx->error.message()));
  return false;
}

// ---------------------------------------------------------------------------------------------
// Geometry helpers.

struct AccessorView {
  const uint8_t* data = nullptr;
  uint64_t count = 0;
  uint64_t stride = 0;
  int component_type = 0;
  int component_size = 0;
  int type = 0;
  int components = 0;
  bool normalized = false;
  int index = 0;
};

template <typename T>
T Load(const uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(v));  // glTF data need not be aligned
  return v;
}

uint32_t ReadUint(const AccessorView& a, uint64_t i, int c = 0) {
  const uint8_t* p = a.data + i * a.stride + c * a.component_size;
  switch (a.component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return Load<uint16_t>(p);
    default:
      return Load<uint32_t>(p);
  }
}

// One component as a float: FLOAT as stored; integers normalized (glTF 2.0 3.11: unsigned
// c / max, signed max(c / max, -1)) or, unnormalized (KHR_mesh_quantization), their value.
float ReadComponent(const AccessorView& a, uint64_t i, int c) {
  const uint8_t* p = a.data + i * a.stride + c * a.component_size;
  switch (a.component_type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT:
      return Load<float>(p);
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const float v = float(Load<int8_t>(p));
      return a.normalized ? std::max(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      const float v = float(Load<int16_t>(p));
      return a.normalized ? std::max(v / 32767.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return a.normalized ? float(p[0]) / 255.0f : float(p[0]);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return a.normalized ? float(Load<uint16_t>(p)) / 65535.0f : float(Load<uint16_t>(p));
    default:
      return float(Load<uint32_t>(p));
  }
}

// One component as stored (never normalized), as accessor.min and accessor.max give it.
double RawComponent(const AccessorView& a, uint64_t i, int c) {
  if (a.component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) return double(ReadUint(a, i, c));
  AccessorView raw = a;
  raw.normalized = false;
  return double(ReadComponent(raw, i, c));
}

// The validator's bound on |length - 1| of a unit vector ("slightly greater than the maximum
// error of signed 8-bit quantization"), for normals and tangents.
constexpr float kUnitLengthError = 0.00674f;

glm::vec4 ReadVec(const AccessorView& a, uint64_t i) {
  glm::vec4 out(0.0f);
  for (int c = 0; c < std::min(a.components, 4); ++c) out[c] = ReadComponent(a, i, c);
  return out;
}

const char* ComponentTypeName(int t) {
  switch (t) {
    case TINYGLTF_COMPONENT_TYPE_BYTE: return "BYTE";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return "UNSIGNED_BYTE";
    case TINYGLTF_COMPONENT_TYPE_SHORT: return "SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return "UNSIGNED_SHORT";
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: return "UNSIGNED_INT";
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return "FLOAT";
    default: return "an unknown componentType";
  }
}

bool Finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

glm::vec3 NormalizeOr(const glm::vec3& v, const glm::vec3& fallback) {
  const float len = glm::length(v);
  return len > 1e-20f && std::isfinite(len) ? v / len : fallback;
}

glm::vec3 AnyPerpendicular(const glm::vec3& n) {
  const glm::vec3 axis = std::abs(n.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
  return glm::normalize(axis - n * glm::dot(n, axis));
}

// Per-vertex tangents from UV derivatives (Lengyel), orthogonalized against the normal; w is
// the bitangent sign. Summing unnormalized directions weights triangles by area and avoids
// dividing by tiny UV determinants.
void GenerateTangents(const std::vector<uint32_t>& tri, std::vector<Vertex>* verts) {
  std::vector<glm::vec3> tan(verts->size(), glm::vec3(0.0f)), bit(verts->size(), glm::vec3(0.0f));
  for (size_t t = 0; t + 2 < tri.size(); t += 3) {
    const Vertex &v0 = (*verts)[tri[t]], &v1 = (*verts)[tri[t + 1]], &v2 = (*verts)[tri[t + 2]];
    const glm::vec3 e1 = v1.position - v0.position, e2 = v2.position - v0.position;
    const glm::vec2 d1 = v1.uv0 - v0.uv0, d2 = v2.uv0 - v0.uv0;
    const float r = d1.x * d2.y - d2.x * d1.y;
    if (!(std::abs(r) > 1e-20f)) continue;
    const float s = r > 0.0f ? 1.0f : -1.0f;
    for (int k = 0; k < 3; ++k) {
      tan[tri[t + k]] += (e1 * d2.y - e2 * d1.y) * s;
      bit[tri[t + k]] += (e2 * d1.x - e1 * d2.x) * s;
    }
  }
  for (size_t i = 0; i < verts->size(); ++i) {
    Vertex& v = (*verts)[i];
    const glm::vec3 t =
        NormalizeOr(tan[i] - v.normal * glm::dot(v.normal, tan[i]), AnyPerpendicular(v.normal));
    v.tangent = glm::vec4(t, glm::dot(glm::cross(v.normal, t), bit[i]) < 0.0f ? -1.0f : 1.0f);
  }
}

// Strips and fans become lists (glTF 2.0 spec, section 3.7.2.1 winding rules).
std::vector<uint32_t> ToTriangleList(int mode, std::vector<uint32_t> idx) {
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    idx.resize(idx.size() - idx.size() % 3);
    return idx;
  }
  std::vector<uint32_t> tri;
  for (size_t i = 0; i + 2 < idx.size(); ++i) {
    if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
      tri.insert(tri.end(), {idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]});
    } else {
      tri.insert(tri.end(), {idx[i + 1], idx[i + 2], idx[0]});
    }
  }
  return tri;
}

double NumberOr(const tinygltf::Value& obj, const char* key, double fallback) {
  if (!obj.IsObject() || !obj.Has(key) || !obj.Get(key).IsNumber()) return fallback;
  return obj.Get(key).GetNumberAsDouble();
}

void ReadNumbers(const tinygltf::Value& obj, const char* key, int n, float* out) {
  if (!obj.IsObject() || !obj.Has(key) || !obj.Get(key).IsArray()) return;
  const tinygltf::Value& a = obj.Get(key);
  if (a.ArrayLen() != size_t(n)) return;
  for (int i = 0; i < n; ++i) {
    if (!a.Get(i).IsNumber()) return;
  }
  for (int i = 0; i < n; ++i) out[i] = ToFloat(a.Get(i).GetNumberAsDouble());
}

// A textureInfo inside an extension with the index and texCoord the pre-scan read (tinygltf
// keeps extension values as plain values, integers as 32-bit ints) and its KHR_texture_transform;
// index -1: none.
tinygltf::TextureInfo ExtensionTextureInfo(const tinygltf::Value& ext, const char* key,
                                           int32_t index, uint32_t texcoord) {
  tinygltf::TextureInfo info;
  if (index < 0 || !ext.IsObject() || !ext.Has(key)) return info;
  const tinygltf::Value& v = ext.Get(key);
  info.index = index;
  info.texCoord = int(texcoord);
  if (v.Has("extensions") && v.Get("extensions").Has("KHR_texture_transform"))
    info.extensions["KHR_texture_transform"] = v.Get("extensions").Get("KHR_texture_transform");
  return info;
}

// ---------------------------------------------------------------------------------------------
// Conversion of the parsed (and now range-checked) model into the CpuScene.

class Converter {
 public:
  Converter(const std::string& file, const ImportLimits& limits, tinygltf::Model* model,
            CpuScene* scene, uint64_t source_bytes, const gltf_internal::PreScanResult& pre)
      : file_(file),
        limits_(limits),
        m_(*model),
        s_(*scene),
        max_vertices_(std::min<uint64_t>(limits.max_vertices, UINT32_MAX)),
        max_indices_(std::min<uint64_t>(limits.max_indices, UINT32_MAX)),
        generated_budget_(std::max<uint64_t>(kMinGeneratedBytes,
                                             kGeneratedPerSourceByte * source_bytes)),
        pre_(pre) {}

  absl::Status Run() {
    // EXT_meshopt_compression fallback buffers: the memory the compressed bufferViews decode
    // into (their sum is bounded by max_decoded_bytes in the pre-scan).
    for (const auto& [index, length] : pre_.fallback_buffers) {
      RETURN_IF_ERROR(CheckIndex("buffers", index, m_.buffers.size(), "buffer"));
      m_.buffers[index].data.assign(length, 0);
    }
    for (const auto& [primitive, accessor] : pre_.draco_indices) {
      const auto [mesh, prim] = primitive;
      if (mesh < m_.meshes.size() && prim < m_.meshes[mesh].primitives.size())
        m_.meshes[mesh].primitives[prim].indices = int(accessor);
    }
    SceneCounts& c = s_.counts;
    c.nodes = uint32_t(m_.nodes.size());
    c.meshes = uint32_t(m_.meshes.size());
    for (const tinygltf::Mesh& mesh : m_.meshes) c.primitives += uint32_t(mesh.primitives.size());
    c.materials = uint32_t(m_.materials.size());
    c.textures = uint32_t(m_.textures.size());
    c.images = uint32_t(m_.images.size());
    for (size_t i = 0; i < m_.materials.size(); ++i) RETURN_IF_ERROR(ConvertMaterial(int(i)));
    RETURN_IF_ERROR(CheckHierarchy());
    std::vector<int> roots;
    if (m_.defaultScene >= 0) {
      RETURN_IF_ERROR(CheckIndex("scene", m_.defaultScene, m_.scenes.size(), "scene"));
    }
    if (!m_.scenes.empty()) {
      const int scene = std::max(m_.defaultScene, 0);
      roots = m_.scenes[scene].nodes;
      // Each node is then visited once: roots are distinct and have no parent (glTF requires
      // both), so neither the traversal nor the lights and cameras it places can multiply.
      const std::string field = absl::StrCat("scenes[", scene, "].nodes");
      std::vector<bool> seen(m_.nodes.size(), false);
      for (int r : roots) {
        RETURN_IF_ERROR(CheckIndex(field, r, m_.nodes.size(), "node"));
        if (seen[r]) return Err(field, "nodes[", r, "] is listed twice");
        if (parent_[r] >= 0) {
          return Err(field, "nodes[", r, "] is not a root (it is a child of nodes[", parent_[r], "])");
        }
        seen[r] = true;
      }
    } else {
      for (size_t i = 0; i < m_.nodes.size(); ++i) {
        if (parent_[i] < 0) roots.push_back(int(i));
      }
    }
    // Iterative traversal: the hierarchy is acyclic (checked), and depth cannot blow the stack.
    std::vector<std::pair<int, glm::mat4>> stack;
    for (auto r = roots.rbegin(); r != roots.rend(); ++r) stack.emplace_back(*r, glm::mat4(1.0f));
    while (!stack.empty()) {
      const auto [node, parent_world] = stack.back();
      stack.pop_back();
      ASSIGN_OR_RETURN(glm::mat4 local, LocalMatrix(node));
      const glm::mat4 world = parent_world * local;
      RETURN_IF_ERROR(PlaceNode(node, world));
      const std::vector<int>& children = m_.nodes[node].children;
      for (auto c = children.rbegin(); c != children.rend(); ++c) stack.emplace_back(*c, world);
    }
    c.lights = uint32_t(s_.lights.size());
    c.cameras = uint32_t(s_.cameras.size());
    RETURN_IF_ERROR(ConvertSkins());
    RETURN_IF_ERROR(ConvertNodes());
    RETURN_IF_ERROR(ConvertAnimations());
    // Every vertex has skin data once one has (zeros for the unskinned).
    if (!s_.skin_joints.empty()) {
      s_.skin_joints.resize(s_.vertices.size(), glm::uvec4(0));
      s_.skin_weights.resize(s_.vertices.size(), glm::vec4(0.0f));
    }
    return absl::OkStatus();
  }

  // ---- the node hierarchy and animations (animation.h) ---------------------------------------

  // The morph target count of a mesh (every primitive must have the same; glTF 2.0 3.7.2.2).
  absl::StatusOr<size_t> MorphTargets(int mesh) {
    const tinygltf::Mesh& m = m_.meshes[mesh];
    const size_t n = m.primitives.empty() ? 0 : m.primitives[0].targets.size();
    if (n > limits_.max_morph_targets)
      return OverMax(absl::StrCat("meshes[", mesh, "].primitives[0].targets"), "morph target count",
                     n, "max_morph_targets", limits_.max_morph_targets);
    for (size_t p = 1; p < m.primitives.size(); ++p) {
      if (m.primitives[p].targets.size() != n)
        return Err(absl::StrCat("meshes[", mesh, "].primitives[", p, "].targets"),
                   m.primitives[p].targets.size(), " morph targets, but primitives[0] has ", n,
                   " (every primitive of a mesh has the same number)");
    }
    if (!m.weights.empty() && m.weights.size() != n)
      return Err(absl::StrCat("meshes[", mesh, "].weights"), m.weights.size(),
                 " weights for ", n, " morph targets");
    return n;
  }

  // Every node of the file, placed or not: what animations move.
  absl::Status ConvertNodes() {
    s_.nodes.resize(m_.nodes.size());
    for (size_t i = 0; i < m_.nodes.size(); ++i) {
      const tinygltf::Node& n = m_.nodes[i];
      const std::string path = absl::StrCat("nodes[", i, "]");
      SceneNode& out = s_.nodes[i];
      out.name = n.name;
      out.parent = parent_[i];
      RETURN_IF_ERROR(LocalTransform(int(i), &out.rest, &out.matrix));
      const glm::mat4 local = out.matrix ? *out.matrix : out.rest.Matrix();
      for (int c = 0; c < 4; ++c) {
        if (!Finite(glm::vec3(local[c])) || !std::isfinite(local[c][3]))
          return Err(path, "transform is not finite");
      }
      if (n.mesh >= 0) {
        RETURN_IF_ERROR(CheckIndex(path + ".mesh", n.mesh, m_.meshes.size(), "mesh"));
        out.mesh = n.mesh;
        ASSIGN_OR_RETURN(const size_t targets, MorphTargets(n.mesh));
        if (!n.weights.empty() && n.weights.size() != targets)
          return Err(path + ".weights", n.weights.size(), " weights for the ", targets,
                     " morph targets of meshes[", n.mesh, "]");
        const std::vector<double>& w = !n.weights.empty() ? n.weights : m_.meshes[n.mesh].weights;
        out.weights.assign(targets, 0.0f);
        for (size_t k = 0; k < w.size(); ++k) out.weights[k] = ToFloat(w[k]);
      } else if (!n.weights.empty()) {
        return Err(path + ".weights", "set on a node without a mesh");
      }
      if (n.skin >= 0) {
        RETURN_IF_ERROR(CheckIndex(path + ".skin", n.skin, s_.skins.size(), "skin"));
        if (n.mesh < 0) return Err(path + ".skin", "set on a node without a mesh");
        out.skin = n.skin;
        // The converted primitives of its mesh (meshes of placed nodes are converted).
        if (const auto it = mesh_cache_.find(n.mesh); it != mesh_cache_.end()) {
          for (uint32_t prim : s_.meshes[it->second].primitives) {
            if (!s_.primitives[prim].skinned)
              return Err(path + ".skin", "meshes[", n.mesh,
                         "] has a primitive without JOINTS_0 and WEIGHTS_0");
            const uint32_t max_joint = max_joint_[prim];
            if (max_joint >= s_.skins[n.skin].joints.size())
              return Err(path + ".skin", "meshes[", n.mesh, "] uses joint ", max_joint,
                         " but skins[", n.skin, "] has ", s_.skins[n.skin].joints.size(),
                         " joints");
          }
        }
      }
    }
    return absl::OkStatus();
  }

  // glTF 2.0 3.11: samplers' key times (SCALAR float, >= 0, strictly increasing) and values
  // (of the channel's path, as many as the keys, three times for CUBICSPLINE), channels that
  // name a sampler, a node without a matrix, a path, each (node, path) once per animation.
  absl::Status ConvertAnimations() {
    uint64_t keys_total = 0;
    for (size_t ai = 0; ai < m_.animations.size(); ++ai) {
      const tinygltf::Animation& ga = m_.animations[ai];
      const std::string apath = absl::StrCat("animations[", ai, "]");
      Animation a;
      a.name = ga.name.empty() ? absl::StrCat("animation ", ai) : ga.name;
      if (ga.channels.empty()) return Err(apath + ".channels", "is empty");
      if (ga.samplers.empty()) return Err(apath + ".samplers", "is empty");
      // A sampler's width follows from the channels that use it: the path decides it.
      std::vector<std::optional<AnimationPath>> used_as(ga.samplers.size());
      std::vector<size_t> width(ga.samplers.size(), 0);
      std::set<std::pair<int, AnimationPath>> targets;
      for (size_t ci = 0; ci < ga.channels.size(); ++ci) {
        const tinygltf::AnimationChannel& gc = ga.channels[ci];
        const std::string cpath = absl::StrCat(apath, ".channels[", ci, "]");
        RETURN_IF_ERROR(CheckIndex(cpath + ".sampler", gc.sampler, ga.samplers.size(), "sampler"));
        if (gc.target_node < 0) continue;  // glTF: a channel without a node is ignored
        RETURN_IF_ERROR(
            CheckIndex(cpath + ".target.node", gc.target_node, m_.nodes.size(), "node"));
        AnimationPath path;
        size_t w = 0;
        if (gc.target_path == "translation") {
          path = AnimationPath::kTranslation, w = 3;
        } else if (gc.target_path == "rotation") {
          path = AnimationPath::kRotation, w = 4;
        } else if (gc.target_path == "scale") {
          path = AnimationPath::kScale, w = 3;
        } else if (gc.target_path == "weights") {
          path = AnimationPath::kWeights;
          const int mesh = m_.nodes[gc.target_node].mesh;
          if (mesh < 0) return Err(cpath + ".target", "animates the weights of nodes[",
                                   gc.target_node, "], which has no mesh");
          ASSIGN_OR_RETURN(w, MorphTargets(mesh));
          if (w == 0) return Err(cpath + ".target", "animates the weights of nodes[",
                                 gc.target_node, "], whose mesh has no morph targets");
        } else {
          return Err(cpath + ".target.path", "\"", absl::CHexEscape(gc.target_path.substr(0, 64)),
                     "\" is not translation, rotation, scale or weights");
        }
        if (!m_.nodes[gc.target_node].matrix.empty())
          return Err(cpath + ".target", "animates nodes[", gc.target_node,
                     "], which has a matrix (only nodes given as TRS can be animated)");
        if (!targets.insert({gc.target_node, path}).second)
          return Err(cpath + ".target", "nodes[", gc.target_node, "] ", gc.target_path,
                     " is animated by an earlier channel of this animation too");
        if (used_as[gc.sampler] && width[gc.sampler] != w)
          return Err(cpath + ".sampler", "samplers[", gc.sampler, "] gives ", width[gc.sampler],
                     " values per key to another channel and ", w, " to this one");
        used_as[gc.sampler] = path;
        width[gc.sampler] = w;
        a.channels.push_back(AnimationChannel{.sampler = uint32_t(gc.sampler),
                                              .node = uint32_t(gc.target_node),
                                              .path = path});
      }
      a.samplers.resize(ga.samplers.size());
      for (size_t si = 0; si < ga.samplers.size(); ++si) {
        const tinygltf::AnimationSampler& gs = ga.samplers[si];
        const std::string spath = absl::StrCat(apath, ".samplers[", si, "]");
        AnimationSampler& out = a.samplers[si];
        if (gs.interpolation.empty() || gs.interpolation == "LINEAR") {
          out.interpolation = Interpolation::kLinear;
        } else if (gs.interpolation == "STEP") {
          out.interpolation = Interpolation::kStep;
        } else if (gs.interpolation == "CUBICSPLINE") {
          out.interpolation = Interpolation::kCubicSpline;
        } else {
          return Err(spath + ".interpolation", "\"",
                     absl::CHexEscape(gs.interpolation.substr(0, 64)),
                     "\" is not LINEAR, STEP or CUBICSPLINE");
        }
        ASSIGN_OR_RETURN(AccessorView in, View(gs.input, spath + ".input"));
        const std::string in_field = absl::StrCat(spath, ".input (accessors[", gs.input, "])");
        if (in.type != TINYGLTF_TYPE_SCALAR || in.component_type != TINYGLTF_COMPONENT_TYPE_FLOAT)
          return Err(in_field, "key times must be SCALAR FLOAT");
        if (in.count == 0) return Err(in_field, "has no keys");
        if (m_.accessors[gs.input].minValues.empty() || m_.accessors[gs.input].maxValues.empty())
          return Err(in_field, "key times need min and max (glTF 2.0 3.11)");
        if (keys_total + in.count > limits_.max_animation_keys)
          return OverMax(in_field, "animation key count", keys_total + in.count,
                         "max_animation_keys", limits_.max_animation_keys);
        keys_total += in.count;
        out.times.resize(in.count);
        for (uint64_t k = 0; k < in.count; ++k) {
          const float t = ReadComponent(in, k, 0);
          if (!std::isfinite(t) || t < 0.0f)
            return Err(in_field, "key ", k, " is at ", t, " s (times are finite and >= 0)");
          if (k > 0 && !(t > out.times[k - 1]))
            return Err(in_field, "key ", k, " at ", t, " s does not come after key ", k - 1,
                       " at ", out.times[k - 1], " s (times strictly increase)");
          out.times[k] = t;
        }
        a.duration = std::max(a.duration, out.times.back());
        if (!used_as[si]) continue;  // no channel uses it: its values are never read
        const AnimationPath path = *used_as[si];
        out.width = uint32_t(width[si]);
        const bool cubic = out.interpolation == Interpolation::kCubicSpline;
        if (cubic && in.count < 2)
          return Err(in_field, "a CUBICSPLINE sampler needs at least 2 keys");
        ASSIGN_OR_RETURN(AccessorView ov, View(gs.output, spath + ".output"));
        const std::string out_field =
            absl::StrCat(spath, ".output (accessors[", gs.output, "])");
        const bool is_float = ov.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT;
        const bool ok_type =
            path == AnimationPath::kWeights     ? ov.type == TINYGLTF_TYPE_SCALAR
            : path == AnimationPath::kRotation ? ov.type == TINYGLTF_TYPE_VEC4
                                               : ov.type == TINYGLTF_TYPE_VEC3;
        // Rotations and weights may also be normalized integers (glTF 2.0 3.11, table 3).
        const bool ok_component =
            is_float || ((path == AnimationPath::kRotation || path == AnimationPath::kWeights) &&
                         ov.normalized && ov.component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT);
        if (!ok_type || !ok_component)
          return Err(out_field, "values of ", path == AnimationPath::kWeights ? "weights"
                                              : path == AnimationPath::kRotation ? "rotation"
                                              : "translation or scale",
                     " must be ", path == AnimationPath::kWeights ? "SCALAR" :
                                   path == AnimationPath::kRotation ? "VEC4" : "VEC3",
                     path == AnimationPath::kTranslation || path == AnimationPath::kScale
                         ? " FLOAT" : " FLOAT or normalized integers");
        // Weights are SCALAR: one element per target per key. Others: one element per key.
        const bool weights = path == AnimationPath::kWeights;
        const uint64_t elements_per_key = (cubic ? 3 : 1) * (weights ? width[si] : 1);
        if (ov.count != in.count * elements_per_key)
          return Err(out_field, ov.count, " elements for ", in.count, " keys (expected ",
                     in.count * elements_per_key, ")");
        out.values.resize(ov.count * uint64_t(ov.components));
        size_t o = 0;
        for (uint64_t e = 0; e < ov.count; ++e) {
          for (int c = 0; c < ov.components; ++c) {
            const float v = ReadComponent(ov, e, c);
            if (!std::isfinite(v)) return Err(out_field, "element ", e, " is not finite");
            out.values[o++] = v;
          }
        }
      }
      s_.animations.push_back(std::move(a));
    }
    return absl::OkStatus();
  }

 private:
  template <typename... Args>
  absl::Status Err(absl::string_view field, const Args&... what) const {
    return Invalid(file_, field, what...);
  }

  // "<field>: <what> <value> exceeds the <limit> limit (<max>)" as RESOURCE_EXHAUSTED.
  absl::Status OverMax(absl::string_view field, absl::string_view what, uint64_t value,
                       absl::string_view limit, uint64_t max) const {
    return OverLimit(file_, field, what, " ", value, " exceeds the ", limit, " limit (", max, ")");
  }

  // "<field>: <what> index <i> out of range (<count> <what>s)" unless 0 <= index < count.
  absl::Status CheckIndex(absl::string_view field, int64_t index, size_t count,
                          const char* what) const {
    if (index >= 0 && uint64_t(index) < count) return absl::OkStatus();
    const bool es = absl::EndsWith(what, "h") || absl::EndsWith(what, "s");  // meshes
    return Err(field, what, " index ", index, " out of range (", count, " ", what,
               es ? "es)" : "s)");
  }

  void Warn(std::string msg) {
    if (s_.warnings.size() < kMaxWarnings) s_.warnings.push_back(std::move(msg));
  }

  // The bytes of bufferView `index` for `field`, checked against its buffer.
  absl::StatusOr<std::span<const uint8_t>> ViewBytes(const std::string& field, int index) {
    RETURN_IF_ERROR(CheckIndex(field, index, m_.bufferViews.size(), "bufferView"));
    const tinygltf::BufferView& bv = m_.bufferViews[index];
    const std::string bv_field = absl::StrCat("bufferViews[", index, "]");
    RETURN_IF_ERROR(CheckIndex(bv_field + ".buffer", bv.buffer, m_.buffers.size(), "buffer"));
    const size_t have = m_.buffers[bv.buffer].data.size();
    if (bv.byteOffset > have || bv.byteLength > have - bv.byteOffset) {
      return Err(bv_field, "byteOffset + byteLength exceeds buffers[", bv.buffer, "] (", have,
                 " bytes)");
    }
    const std::span<uint8_t> bytes(m_.buffers[bv.buffer].data.data() + bv.byteOffset,
                                   bv.byteLength);
    if (const auto mv = pre_.meshopt_views.find(uint32_t(index));
        mv != pre_.meshopt_views.end() && decoded_views_.insert(index).second) {
      RETURN_IF_ERROR(DecodeMeshoptView(index, mv->second, bytes));
    }
    return std::span<const uint8_t>(bytes);
  }

  // EXT_meshopt_compression: decodes bufferViews[index] into its own bytes (in a fallback
  // buffer, or over the uncompressed copy), once, the first time the view is read.
  absl::Status DecodeMeshoptView(int index, const gltf_internal::MeshoptView& mv,
                                 std::span<uint8_t> out) {
    const std::string field =
        absl::StrCat("bufferViews[", index, "].extensions.EXT_meshopt_compression");
    RETURN_IF_ERROR(CheckIndex(field + ".buffer", mv.buffer, m_.buffers.size(), "buffer"));
    const std::vector<unsigned char>& src = m_.buffers[mv.buffer].data;
    if (mv.byte_offset > src.size() || mv.byte_length > src.size() - mv.byte_offset) {
      return Err(field, "byteOffset + byteLength exceeds buffers[", mv.buffer, "] (", src.size(),
                 " bytes)");
    }
    const absl::Status decoded = gltf_internal::DecodeMeshopt(
        mv, std::span<const uint8_t>(src.data() + mv.byte_offset, mv.byte_length), out);
    if (!decoded.ok()) return Err(field, decoded.message());
    return absl::OkStatus();
  }

  // KHR_draco_mesh_compression: decodes the primitive's Draco bufferView into packed copies of
  // the accessors it names (and its indices), which View() then returns. The accessors' declared
  // sizes count against max_decoded_bytes before the decoder runs; what it decodes must match
  // them (points = the attributes' count, 3 x faces = the indices' count).
  absl::Status DecodeDracoPrimitive(const tinygltf::Primitive& p, const std::string& path) {
    const auto it = p.extensions.find("KHR_draco_mesh_compression");
    if (!draco_ || it == p.extensions.end()) return absl::OkStatus();
    const std::string field = path + ".extensions.KHR_draco_mesh_compression";
    const tinygltf::Value& ext = it->second;
    if (!ext.IsObject()) return Err(field, "not an object");
    const tinygltf::Value& view = ext.Get("bufferView");
    const tinygltf::Value& attributes = ext.Get("attributes");
    if (!view.IsInt()) return Err(field + ".bufferView", "missing or not an integer");
    if (!attributes.IsObject()) return Err(field + ".attributes", "missing or not an object");
    if (p.indices < 0) return Err(path, "a Draco-compressed primitive needs indices");
    // Draco decodes a triangle list; the extension also allows strips, which Tessera does not
    // read from Draco data (refused rather than drawn as the wrong triangles).
    if (p.mode >= 0 && p.mode != TINYGLTF_MODE_TRIANGLES) {
      return Err(path + ".mode", "mode ", p.mode, " with KHR_draco_mesh_compression: only ",
                 "TRIANGLES (4) is supported");
    }
    RETURN_IF_ERROR(CheckIndex(path + ".indices", p.indices, m_.accessors.size(), "accessor"));
    ASSIGN_OR_RETURN(std::span<const uint8_t> bytes, ViewBytes(field + ".bufferView",
                                                               view.GetNumberAsInt()));
    struct Target {
      int accessor;
      std::vector<uint8_t>* data;
    };
    std::vector<Target> targets;
    std::vector<gltf_internal::DracoAttributeRequest> requests;
    uint64_t points = 0, budget = 0;
    for (const std::string& name : attributes.Keys()) {
      const std::string at = absl::StrCat(field, ".attributes.", name);
      const tinygltf::Value& id = attributes.Get(name);
      if (!id.IsInt() || id.GetNumberAsInt() < 0) return Err(at, "not a non-negative integer");
      const auto a = p.attributes.find(name);
      if (a == p.attributes.end()) return Err(at, "the primitive has no ", name, " attribute");
      RETURN_IF_ERROR(CheckIndex(at, a->second, m_.accessors.size(), "accessor"));
      const tinygltf::Accessor& acc = m_.accessors[a->second];
      const int components = tinygltf::GetNumComponentsInType(uint32_t(acc.type));
      const int size = tinygltf::GetComponentSizeInBytes(uint32_t(acc.componentType));
      if (components <= 0 || size <= 0) {
        return Err(absl::StrCat("accessors[", a->second, "]"), "invalid type/componentType");
      }
      if (targets.empty()) points = acc.count;
      if (acc.count != points) {
        return Err(at, "accessors[", a->second, "] has ", acc.count, " elements where ",
                   "the primitive's other Draco attributes have ", points);
      }
      budget += uint64_t(acc.count) * uint64_t(components * size);  // each <= 1 GiB (pre-scan)
      targets.push_back({a->second, &owned_.emplace_back()});
      requests.push_back({.unique_id = uint32_t(id.GetNumberAsInt()),
                          .component_type = acc.componentType,
                          .components = components,
                          .out = targets.back().data});
    }
    const uint64_t index_count = m_.accessors[p.indices].count;
    budget += index_count * 4;
    if (budget > limits_.max_decoded_bytes - std::min(decoded_bytes_, limits_.max_decoded_bytes)) {
      return OverLimit(file_, field, "decodes to ", budget, " bytes, which with the ",
                       decoded_bytes_, " decoded before exceed the max_decoded_bytes limit (",
                       limits_.max_decoded_bytes, ")");
    }
    decoded_bytes_ += budget;
    absl::StatusOr<gltf_internal::DracoMesh> mesh =
        gltf_internal::DecodeDraco(bytes, std::span(requests), points, index_count);
    if (!mesh.ok()) {
      return absl::Status(mesh.status().code(),
                          absl::StrCat(file_, ": ", field, ": ", mesh.status().message()));
    }
    if (mesh->points != points) {
      return Err(field, "the Draco data has ", mesh->points, " points where the accessors have ",
                 points);
    }
    if (mesh->index_bytes.size() != index_count * 4) {
      return Err(field, "the Draco data has ", mesh->index_bytes.size() / 4,
                 " indices where accessors[", p.indices, "] has ", index_count);
    }
    for (const Target& t : targets) {
      AccessorView v = PackedView(t.accessor);
      v.data = t.data->data();
      views_[t.accessor] = v;
      draco_accessors_.insert(t.accessor);
    }
    // The indices as decoded: UNSIGNED_INT, whatever the accessor declares.
    AccessorView iv = PackedView(p.indices);
    iv.component_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
    iv.component_size = iv.stride = 4;
    iv.data = owned_.emplace_back(std::move(mesh->index_bytes)).data();
    views_[p.indices] = iv;
    return absl::OkStatus();
  }

  // `count` tightly packed elements of `size` bytes at `offset` in bufferView `view` (sparse
  // indices and values: glTF gives them no byteStride).
  absl::StatusOr<const uint8_t*> PackedRange(const std::string& field, int view, uint64_t offset,
                                             uint64_t count, uint64_t size) {
    ASSIGN_OR_RETURN(std::span<const uint8_t> bytes, ViewBytes(field + ".bufferView", view));
    if (m_.bufferViews[view].byteStride != 0) {
      return Err(field + ".bufferView", "bufferViews[", view,
                 "] has a byteStride; sparse indices and values are tightly packed");
    }
    uint64_t end = 0;
    if (__builtin_mul_overflow(count, size, &end) || __builtin_add_overflow(end, offset, &end) ||
        end > bytes.size()) {
      return Err(field, "byteOffset ", offset, " + ", count, " x ", size,
                 " bytes exceeds bufferViews[", view, "].byteLength (", bytes.size(), ")");
    }
    return bytes.data() + offset;
  }

  absl::StatusOr<AccessorView> View(int index, const std::string& use) {
    RETURN_IF_ERROR(CheckIndex(use, index, m_.accessors.size(), "accessor"));
    if (const auto it = views_.find(index); it != views_.end()) return it->second;
    const tinygltf::Accessor& a = m_.accessors[index];
    const std::string field = absl::StrCat("accessors[", index, "]");
    if (a.count > limits_.max_accessor_elements) {
      return OverMax(field + ".count", "element count", a.count, "max_accessor_elements",
                     limits_.max_accessor_elements);
    }
    AccessorView v = PackedView(index);
    if (v.component_size <= 0 || v.components <= 0) return Err(field, "invalid type/componentType");
    const uint64_t elem = v.stride;
    if (a.bufferView >= 0) {
      ASSIGN_OR_RETURN(std::span<const uint8_t> bytes, ViewBytes(field + ".bufferView", a.bufferView));
      const tinygltf::BufferView& bv = m_.bufferViews[a.bufferView];
      const std::string bv_field = absl::StrCat("bufferViews[", a.bufferView, "]");
      v.stride = bv.byteStride ? bv.byteStride : elem;
      if (v.stride < elem) {
        return Err(bv_field + ".byteStride", v.stride, " is smaller than the ", elem,
                   "-byte elements of ", field);
      }
      // glTF 2.0 3.6.2.4: offsets into the bufferView and into the buffer, and the stride, are
      // multiples of the component size.
      const uint64_t cs = uint64_t(v.component_size);
      if (a.byteOffset % cs != 0) {
        return Err(field + ".byteOffset", a.byteOffset, " is not a multiple of the ", cs,
                   "-byte component size");
      }
      if ((bv.byteOffset + a.byteOffset) % cs != 0) {
        return Err(field, "its offset in buffers[", bv.buffer, "] (", bv.byteOffset, " + ",
                   a.byteOffset, ") is not a multiple of the ", cs, "-byte component size");
      }
      if (v.stride % cs != 0) {
        return Err(bv_field + ".byteStride", v.stride, " is not a multiple of the ", cs,
                   "-byte component size of ", field);
      }
      if (a.count > 0) {
        uint64_t span = 0, end = 0;
        const bool overflow = __builtin_mul_overflow(uint64_t(a.count - 1), v.stride, &span) ||
                              __builtin_add_overflow(span, elem, &end) ||
                              __builtin_add_overflow(end, uint64_t(a.byteOffset), &end);
        if (overflow || end > bytes.size()) {
          return Err(field, "byteOffset + count*stride (",
                     overflow ? "overflows 64 bits" : absl::StrCat(end), ") exceeds ", bv_field,
                     ".byteLength (", bytes.size(), ")");
        }
      }
      v.data = bytes.data() + a.byteOffset;
    } else if (a.byteOffset != 0) {
      return Err(field + ".byteOffset", "set without a bufferView");
    }
    if (a.bufferView < 0 || a.sparse.isSparse) {
      // glTF 2.0 3.6.2.3: without a bufferView the elements are zeros; a sparse block then
      // replaces some of them. Both are made into a packed copy, bounded like every accessor
      // (max_accessor_bytes, also checked before parsing).
      uint64_t bytes = 0;
      if (__builtin_mul_overflow(uint64_t(a.count), elem, &bytes) ||
          bytes > limits_.max_accessor_bytes) {
        return OverMax(field, "size in bytes", bytes, "max_accessor_bytes",
                       limits_.max_accessor_bytes);
      }
      // Zeros and sparse blocks cost nothing to upload: what they expand to is bounded by the
      // upload's size, so a few hundred bytes of JSON cannot ask for gigabytes.
      if (bytes > generated_budget_ - generated_bytes_) {
        return OverLimit(file_, field, "expands to ", bytes, " bytes of zeros or sparse data; "
                         "all such accessors may hold ", generated_budget_, " bytes (",
                         kGeneratedPerSourceByte, "x the uploaded files, at least ",
                         kMinGeneratedBytes, ")");
      }
      generated_bytes_ += bytes;
      std::vector<uint8_t>& dense = owned_.emplace_back(bytes, uint8_t(0));
      if (v.data != nullptr) {
        for (uint64_t i = 0; i < a.count; ++i)
          std::memcpy(dense.data() + i * elem, v.data + i * v.stride, elem);
      }
      if (a.sparse.isSparse) RETURN_IF_ERROR(ApplySparse(a, field, elem, dense.data()));
      v.data = dense.data();
      v.stride = elem;
    }
    RETURN_IF_ERROR(CheckMinMax(a, v, field));
    views_[index] = v;
    return v;
  }

  // glTF 2.0 3.6.2.5: an accessor's min and max, when given, are its data's per component (as
  // stored, compared at the component type's precision). Not for Draco-decoded accessors
  // (DecodeDracoPrimitive), whose min and max describe the data before its lossy coding.
  absl::Status CheckMinMax(const tinygltf::Accessor& a, const AccessorView& v,
                           const std::string& field) {
    if (a.minValues.empty() && a.maxValues.empty()) return absl::OkStatus();
    std::vector<double> lo(v.components, std::numeric_limits<double>::infinity());
    std::vector<double> hi(v.components, -std::numeric_limits<double>::infinity());
    for (uint64_t i = 0; i < v.count; ++i) {
      for (int c = 0; c < v.components; ++c) {
        const double x = RawComponent(v, i, c);
        lo[c] = std::min(lo[c], x);
        hi[c] = std::max(hi[c], x);
      }
    }
    const bool is_float = v.component_type == TINYGLTF_COMPONENT_TYPE_FLOAT;
    for (const auto& [name, declared, actual] :
         {std::tuple{"min", &a.minValues, &lo}, std::tuple{"max", &a.maxValues, &hi}}) {
      if (declared->empty()) continue;
      if (declared->size() != size_t(v.components)) {
        return Err(absl::StrCat(field, ".", name), declared->size(), " values for ",
                   v.components, " components");
      }
      for (int c = 0; c < v.components && v.count > 0; ++c) {
        const double d = (*declared)[c], x = (*actual)[c];
        if (is_float ? float(d) != float(x) : d != x) {
          return Err(absl::StrCat(field, ".", name, "[", c, "]"), d,
                     " is not the data's ", name, "imum (", x, ")");
        }
      }
    }
    return absl::OkStatus();
  }

  // Accessor `index`'s shape, its elements tightly packed; no data yet.
  AccessorView PackedView(int index) const {
    const tinygltf::Accessor& a = m_.accessors[index];
    AccessorView v;
    v.component_size = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
    v.components = tinygltf::GetNumComponentsInType(uint32_t(a.type));
    v.count = a.count;
    v.component_type = a.componentType;
    v.type = a.type;
    v.normalized = a.normalized;
    v.index = index;
    v.stride = uint64_t(std::max(v.component_size, 0)) * uint64_t(std::max(v.components, 0));
    return v;
  }

  // glTF 2.0 3.6.2.3: sparse.count elements replaced, at indices that strictly increase, each
  // below the accessor's count.
  absl::Status ApplySparse(const tinygltf::Accessor& a, const std::string& field, uint64_t elem,
                           uint8_t* dense) {
    const auto& sp = a.sparse;
    const std::string sparse = field + ".sparse";
    if (sp.count < 1 || uint64_t(sp.count) > a.count) {
      return Err(sparse + ".count", sp.count, " is not in 1..", a.count, " (the accessor's count)");
    }
    const uint64_t n = uint64_t(sp.count);
    const int it = sp.indices.componentType;
    if (it != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE && it != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
        it != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
      return Err(sparse + ".indices.componentType", ComponentTypeName(it),
                 " (", it, "): wants UNSIGNED_BYTE, UNSIGNED_SHORT or UNSIGNED_INT");
    }
    if (sp.indices.byteOffset < 0 || sp.values.byteOffset < 0)
      return Err(sparse, "negative byteOffset");
    const uint64_t isize = uint64_t(tinygltf::GetComponentSizeInBytes(uint32_t(it)));
    ASSIGN_OR_RETURN(const uint8_t* indices,
                     PackedRange(sparse + ".indices", sp.indices.bufferView,
                                 uint64_t(sp.indices.byteOffset), n, isize));
    ASSIGN_OR_RETURN(const uint8_t* values,
                     PackedRange(sparse + ".values", sp.values.bufferView,
                                 uint64_t(sp.values.byteOffset), n, elem));
    AccessorView iv;
    iv.data = indices;
    iv.stride = isize;
    iv.component_type = it;
    iv.component_size = int(isize);
    uint64_t previous = 0;
    for (uint64_t k = 0; k < n; ++k) {
      const uint64_t i = ReadUint(iv, k);
      if (i >= a.count) {
        return Err(sparse + ".indices", "index ", i, " at position ", k,
                   " is out of range (count ", a.count, ")");
      }
      if (k > 0 && i <= previous) {
        return Err(sparse + ".indices", "index ", i, " at position ", k,
                   " does not increase (previous ", previous, ")");
      }
      previous = i;
      std::memcpy(dense + i * elem, values + k * elem, elem);
    }
    return absl::OkStatus();
  }

  // How many accessors read bufferView `view`.
  size_t AccessorsOfView(int view) {
    if (accessors_of_view_.empty()) {
      accessors_of_view_.assign(m_.bufferViews.size(), 0);
      for (const tinygltf::Accessor& a : m_.accessors) {
        if (a.bufferView >= 0 && size_t(a.bufferView) < m_.bufferViews.size())
          ++accessors_of_view_[a.bufferView];
      }
    }
    return accessors_of_view_[view];
  }

  // Whether `a` may hold attribute `name`: FLOAT; texture coordinates also normalized unsigned
  // byte/short (core glTF); with KHR_mesh_quantization in extensionsUsed, positions any byte or
  // short type, normals and tangents normalized signed ones, texture coordinates any byte or
  // short type.
  bool AllowedComponents(const AccessorView& a, const std::string& name, bool* needs_ext) const {
    *needs_ext = false;
    const int t = a.component_type;
    const bool unsigned_small =
        t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE || t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    // glTF 2.0 3.7.2.1: joint indices are unsigned integers; weights float or normalized.
    if (name == "JOINTS_0") return unsigned_small && !a.normalized;
    // glTF 2.0 3.7.2.1: weights and colours are float or normalized unsigned byte/short.
    if (name == "WEIGHTS_0" || name == "COLOR_0")
      return t == TINYGLTF_COMPONENT_TYPE_FLOAT || (unsigned_small && a.normalized);
    if (t == TINYGLTF_COMPONENT_TYPE_FLOAT) return true;
    const bool small = t == TINYGLTF_COMPONENT_TYPE_BYTE ||
                       t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                       t == TINYGLTF_COMPONENT_TYPE_SHORT ||
                       t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT;
    const bool is_signed = t == TINYGLTF_COMPONENT_TYPE_BYTE || t == TINYGLTF_COMPONENT_TYPE_SHORT;
    if (!small) return false;
    const bool uv = name.rfind("TEXCOORD_", 0) == 0;
    if (uv && a.normalized && !is_signed) return true;  // core
    *needs_ext = true;
    if (name == "POSITION" || uv) return true;
    return a.normalized && is_signed;  // NORMAL, TANGENT
  }

  // An optional vertex attribute: of `type` (or `other_type`, if given) with an allowed component
  // type (AllowedComponents) and, unless it is POSITION, as many elements as POSITION.
  absl::StatusOr<AccessorView> Attribute(const tinygltf::Primitive& p, const std::string& path,
                                         const char* name, int type, uint64_t count,
                                         int other_type = -1) {
    const auto it = p.attributes.find(name);
    if (it == p.attributes.end()) return AccessorView{};
    absl::StatusOr<AccessorView> v = View(it->second, absl::StrCat(path, ".attributes.", name));
    if (!v.ok()) return v;
    // Named as both the primitive's attribute and the accessor.
    const std::string field =
        absl::StrCat(path, ".attributes.", name, " (accessors[", v->index, "])");
    bool needs_ext = false;
    const bool allowed = AllowedComponents(*v, name, &needs_ext);
    const std::string what =
        absl::StrCat(v->normalized ? "normalized " : "", ComponentTypeName(v->component_type));
    if ((v->type != type && v->type != other_type) || !allowed) {
      return Err(field, "unsupported type/componentType for ", name, " (",
                 tinygltf::GetNumComponentsInType(uint32_t(v->type)), " x ", what, ")");
    }
    if (needs_ext && !quantization_) {
      return Err(field, name, " as ", what,
                 " needs KHR_mesh_quantization in extensionsUsed (else FLOAT)");
    }
    if (count != UINT64_MAX && v->count != count) {
      return Err(field, name, " count ", v->count, " differs from POSITION count ", count);
    }
    const tinygltf::Accessor& a = m_.accessors[v->index];
    if (a.bufferView < 0) return v;
    // glTF 2.0 3.6.2.4: a bufferView that several vertex attributes share states its stride, and
    // vertex attribute data is 4-byte aligned (the validator's MESH_PRIMITIVE_ACCESSOR_UNALIGNED):
    // its offset, and a tightly packed element's size.
    const bool packed = m_.bufferViews[a.bufferView].byteStride == 0;
    if (packed && AccessorsOfView(a.bufferView) > 1) {
      return Err(field, "bufferViews[", a.bufferView, "] holds ", AccessorsOfView(a.bufferView),
                 " accessors but has no byteStride");
    }
    const uint64_t element = uint64_t(v->components) * uint64_t(v->component_size);
    if (a.byteOffset % 4 != 0 || (packed && element % 4 != 0)) {
      return Err(field, name, " data is not aligned to 4 bytes (byteOffset ", a.byteOffset, ", ",
                 element, "-byte elements", packed ? " without a byteStride" : "", ")");
    }
    return v;
  }

  absl::StatusOr<std::vector<uint32_t>> Indices(const tinygltf::Primitive& p,
                                                const std::string& path, uint64_t n) {
    std::vector<uint32_t> idx;
    if (p.indices < 0) {
      if (n > max_indices_) return OverMax(path, "vertex count", n, "max_indices", max_indices_);
      for (uint64_t i = 0; i < n; ++i) idx.push_back(uint32_t(i));
      return idx;
    }
    absl::StatusOr<AccessorView> iv = View(p.indices, path + ".indices");
    if (!iv.ok()) return iv.status();
    const std::string accessor = absl::StrCat("accessors[", p.indices, "]");
    const std::string field = absl::StrCat(path, ".indices (", accessor, ")");
    if (iv->type != TINYGLTF_TYPE_SCALAR ||
        (iv->component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
         iv->component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT &&
         iv->component_type != TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)) {
      return Err(field, "indices must be unsigned byte/short/int scalars");
    }
    if (iv->count > max_indices_)
      return OverMax(accessor, "index count", iv->count, "max_indices", max_indices_);
    if (const int view = m_.accessors[p.indices].bufferView;
        view >= 0 && m_.bufferViews[view].byteStride != 0) {
      return Err(field, "bufferViews[", view, "] has a byteStride; index data is tightly packed");
    }
    idx.resize(iv->count);
    for (uint64_t i = 0; i < iv->count; ++i) {
      idx[i] = ReadUint(*iv, i);
      if (idx[i] >= n) {
        return Err(field, "index value ", idx[i], " at position ", i,
                   " is out of range (vertex count ", n, ")");
      }
    }
    return idx;
  }

  absl::Status ConvertPrimitive(int mesh, int index, const tinygltf::Primitive& p,
                                std::vector<uint32_t>* out) {
    const std::string path = absl::StrCat("meshes[", mesh, "].primitives[", index, "]");
    const int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
    if (mode < TINYGLTF_MODE_TRIANGLES) {
      Warn(absl::StrCat(path, ": points/lines primitive (mode ", mode, ") skipped"));
      return absl::OkStatus();
    }
    if (mode > TINYGLTF_MODE_TRIANGLE_FAN) return Err(path + ".mode", "invalid mode ", mode);
    RETURN_IF_ERROR(DecodeDracoPrimitive(p, path));
    absl::StatusOr<AccessorView> pos =
        Attribute(p, path, "POSITION", TINYGLTF_TYPE_VEC3, UINT64_MAX);
    if (!pos.ok()) return pos.status();
    if (pos->data == nullptr) return Err(path + ".attributes", "POSITION is required");
    const uint64_t n = pos->count;
    if (n > max_vertices_) return OverMax(path, "vertex count", n, "max_vertices", max_vertices_);
    absl::StatusOr<std::vector<uint32_t>> idx = Indices(p, path, n);
    if (!idx.ok()) return idx.status();
    if (mode == TINYGLTF_MODE_TRIANGLES && idx->size() % 3 != 0) {
      Warn(path + ": index count is not a multiple of 3; the rest is dropped");
    }
    if (mode != TINYGLTF_MODE_TRIANGLES && idx->size() > 2 &&
        (idx->size() - 2) * 3 > max_indices_) {
      return OverMax(path, "triangle-list index count", (idx->size() - 2) * 3, "max_indices",
                     max_indices_);
    }
    std::vector<uint32_t> tri = ToTriangleList(mode, std::move(*idx));

    absl::StatusOr<AccessorView> attrs[4] = {
        Attribute(p, path, "NORMAL", TINYGLTF_TYPE_VEC3, n),
        Attribute(p, path, "TANGENT", TINYGLTF_TYPE_VEC4, n),
        Attribute(p, path, "TEXCOORD_0", TINYGLTF_TYPE_VEC2, n),
        Attribute(p, path, "TEXCOORD_1", TINYGLTF_TYPE_VEC2, n)};
    for (const auto& a : attrs) RETURN_IF_ERROR(a.status());
    const AccessorView &nrm = *attrs[0], &tng = *attrs[1], &uv0 = *attrs[2], &uv1 = *attrs[3];
    // glTF 2.0 3.7.2.1: COLOR_0 is RGB or RGBA (alpha 1). Other colour sets are not read.
    absl::StatusOr<AccessorView> color_view =
        Attribute(p, path, "COLOR_0", TINYGLTF_TYPE_VEC4, n, TINYGLTF_TYPE_VEC3);
    RETURN_IF_ERROR(color_view.status());
    const AccessorView& col = *color_view;
    // Draco-decoded colours are clamped (PackVertexColor): its dequantization rounds past 1.
    const bool col_lossy = draco_accessors_.count(col.index) != 0;
    absl::StatusOr<AccessorView> joints_view = Attribute(p, path, "JOINTS_0", TINYGLTF_TYPE_VEC4, n);
    absl::StatusOr<AccessorView> weights_view = Attribute(p, path, "WEIGHTS_0", TINYGLTF_TYPE_VEC4, n);
    RETURN_IF_ERROR(joints_view.status());
    RETURN_IF_ERROR(weights_view.status());
    if ((joints_view->data == nullptr) != (weights_view->data == nullptr))
      return Err(path + ".attributes", "JOINTS_0 and WEIGHTS_0 come together (one is missing)");
    const bool skinned = joints_view->data != nullptr;
    const bool has_normals = nrm.data != nullptr;
    const bool has_tangents = has_normals && tng.data != nullptr;  // spec: else ignore them
    const uint64_t out_vertices = has_normals ? n : tri.size();    // flat: a vertex per corner
    if (s_.vertices.size() + out_vertices > max_vertices_) {
      return OverMax(path, "the scene's vertex count", s_.vertices.size() + out_vertices,
                     "max_vertices", max_vertices_);
    }
    if (s_.indices.size() + tri.size() > max_indices_) {
      return OverMax(path, "the scene's index count", s_.indices.size() + tri.size(),
                     "max_indices", max_indices_);
    }
    auto finite_uv = [](glm::vec4 u) {
      return std::isfinite(u.x) && std::isfinite(u.y) ? glm::vec2(u) : glm::vec2(0.0f);
    };
    std::vector<Vertex> verts(n);
    for (uint64_t i = 0; i < n; ++i) {
      Vertex& v = verts[i];
      v.position = glm::vec3(ReadVec(*pos, i));
      if (!Finite(v.position)) {
        return Err(absl::StrCat("accessors[", pos->index, "]"), "non-finite POSITION value");
      }
      if (has_normals) {
        v.normal = glm::vec3(ReadVec(nrm, i));
        const float length = glm::length(v.normal);
        if (!(std::abs(length - 1.0f) <= kUnitLengthError)) {
          return Err(absl::StrCat(path, ".attributes.NORMAL (accessors[", nrm.index, "])"),
                     "element ", i, " is not of unit length (", length, ")");
        }
      }
      if (tng.data != nullptr) {
        const glm::vec4 t = ReadVec(tng, i);
        const float length = glm::length(glm::vec3(t));
        const std::string field =
            absl::StrCat(path, ".attributes.TANGENT (accessors[", tng.index, "])");
        if (!(std::abs(length - 1.0f) <= kUnitLengthError)) {
          return Err(field, "element ", i, " is not of unit length (", length, ")");
        }
        if (t.w != 1.0f && t.w != -1.0f) {
          return Err(field, "element ", i, " has w ", t.w, " (the bitangent sign: 1 or -1)");
        }
        if (has_tangents) v.tangent = t;
      }
      if (uv0.data) v.uv0 = finite_uv(ReadVec(uv0, i));
      if (uv1.data) v.uv1 = finite_uv(ReadVec(uv1, i));
      if (col.data) {
        glm::vec4 c = ReadVec(col, i);
        if (col.type == TINYGLTF_TYPE_VEC3) c.a = 1.0f;
        // glTF 2.0 3.7.2.1: colours are in [0, 1] (the validator's ACCESSOR_NON_CLAMPED).
        for (int ch = 0; ch < 4; ++ch) {
          if (!(c[ch] >= 0.0f && c[ch] <= 1.0f) && !(col_lossy && std::isfinite(c[ch]))) {
            return Err(absl::StrCat(path, ".attributes.COLOR_0 (accessors[", col.index, "])"),
                       "element ", i, " has ", c[ch], " outside [0, 1]");
          }
        }
        v.color = PackVertexColor(c);
      }
    }
    // The file's vertex each output vertex comes from (flat shading duplicates them).
    std::vector<uint32_t> source(n);
    for (uint64_t i = 0; i < n; ++i) source[i] = uint32_t(i);
    if (!has_normals) {
      // Flat shading: every triangle gets its own three vertices carrying the face normal.
      std::vector<Vertex> flat(tri.size());
      source.assign(tri.begin(), tri.end());
      for (size_t t = 0; t < tri.size(); t += 3) {
        const glm::vec3 fn =
            NormalizeOr(glm::cross(verts[tri[t + 1]].position - verts[tri[t]].position,
                                   verts[tri[t + 2]].position - verts[tri[t]].position),
                        glm::vec3(0, 0, 1));
        for (size_t k = t; k < t + 3; ++k) {
          flat[k] = verts[tri[k]];
          flat[k].normal = fn;
          tri[k] = uint32_t(k);
        }
      }
      verts = std::move(flat);
    }
    for (Vertex& v : verts) {
      v.normal = NormalizeOr(v.normal, glm::vec3(0, 0, 1));
      if (has_tangents) {
        v.tangent = glm::vec4(NormalizeOr(glm::vec3(v.tangent), AnyPerpendicular(v.normal)),
                              v.tangent.w < 0.0f ? -1.0f : 1.0f);
      }
    }
    if (!has_tangents) GenerateTangents(tri, &verts);

    Primitive prim;
    prim.first_index = uint32_t(s_.indices.size());
    prim.index_count = uint32_t(tri.size());
    prim.first_vertex = uint32_t(s_.vertices.size());
    prim.vertex_count = uint32_t(verts.size());
    prim.flat_normals = !has_normals;
    for (const Vertex& v : verts) prim.bounds.extend(v.position);
    if (p.material >= 0) {
      RETURN_IF_ERROR(CheckIndex(path + ".material", p.material, m_.materials.size(), "material"));
    }
    if (p.material < 0 && default_material_ < 0) {
      default_material_ = int32_t(s_.materials.size());
      s_.materials.push_back(Material{.name = "default"});  // glTF defaults: white, 1, 1
    }
    prim.material = uint32_t(p.material >= 0 ? p.material : default_material_);
    prim.vertex_colors = col.data != nullptr;
    if (skinned) RETURN_IF_ERROR(ReadSkinning(path, *joints_view, *weights_view, source, &prim));
    RETURN_IF_ERROR(ReadMorphTargets(mesh, path, p, source, has_normals, &prim));
    s_.vertices.insert(s_.vertices.end(), verts.begin(), verts.end());
    s_.indices.insert(s_.indices.end(), tri.begin(), tri.end());
    out->push_back(uint32_t(s_.primitives.size()));
    s_.primitives.push_back(prim);
    return absl::OkStatus();
  }

  // Each glTF mesh is converted once, however many nodes instance it.
  // JOINTS_0 / WEIGHTS_0 of a primitive into the scene's per-vertex skin arrays (padded with
  // zeros for the unskinned vertices before it). Weights are >= 0, finite, and sum to 1 within
  // 1% (then made exact); joint indices are checked against the skin of each node that draws
  // the mesh (ConvertNodes).
  absl::Status ReadSkinning(const std::string& path, const AccessorView& jv,
                            const AccessorView& wv, const std::vector<uint32_t>& source,
                            Primitive* prim) {
    const std::string wfield =
        absl::StrCat(path, ".attributes.WEIGHTS_0 (accessors[", wv.index, "])");
    s_.skin_joints.resize(prim->first_vertex, glm::uvec4(0));
    s_.skin_weights.resize(prim->first_vertex, glm::vec4(0.0f));
    uint32_t max_joint = 0;
    for (uint32_t src : source) {
      glm::uvec4 j(0);
      glm::vec4 w(0.0f);
      for (int c = 0; c < 4; ++c) {
        j[c] = ReadUint(jv, src, c);
        w[c] = ReadComponent(wv, src, c);
        if (!std::isfinite(w[c]) || w[c] < 0.0f)
          return Err(wfield, "element ", src, " has weight ", w[c], " (weights are >= 0)");
        if (w[c] > 0.0f) max_joint = std::max(max_joint, j[c]);
      }
      const float sum = w.x + w.y + w.z + w.w;
      if (!(std::abs(sum - 1.0f) <= 0.01f))
        return Err(wfield, "element ", src, "'s weights sum to ", sum, ", not 1");
      s_.skin_joints.push_back(j);
      s_.skin_weights.push_back(w / sum);
    }
    prim->skinned = true;
    max_joint_[uint32_t(s_.primitives.size())] = max_joint;
    return absl::OkStatus();
  }

  // The primitive's morph targets' POSITION, NORMAL and TANGENT deltas (VEC3, one per vertex,
  // finite), for its output vertices. Other target attributes are ignored with a warning.
  absl::Status ReadMorphTargets(int mesh, const std::string& path, const tinygltf::Primitive& p,
                                const std::vector<uint32_t>& source, bool has_normals,
                                Primitive* prim) {
    if (p.targets.empty()) return absl::OkStatus();
    ASSIGN_OR_RETURN(const size_t targets, MorphTargets(mesh));
    const uint64_t deltas = uint64_t(targets) * source.size();
    if (s_.morph_deltas.size() + deltas > max_vertices_)
      return OverMax(path + ".targets", "morph delta count", s_.morph_deltas.size() + deltas,
                     "max_vertices", max_vertices_);
    prim->morph_targets = uint32_t(targets);
    prim->first_morph_delta = s_.morph_deltas.size();
    s_.morph_deltas.resize(s_.morph_deltas.size() + deltas);
    MorphDelta* out = s_.morph_deltas.data() + prim->first_morph_delta;
    for (size_t t = 0; t < targets; ++t) {
      const std::string tpath = absl::StrCat(path, ".targets[", t, "]");
      for (const auto& [name, accessor] : p.targets[t]) {
        glm::vec3 MorphDelta::*member = name == "POSITION" ? &MorphDelta::position
                                        : name == "NORMAL"  ? &MorphDelta::normal
                                        : name == "TANGENT" ? &MorphDelta::tangent
                                                            : nullptr;
        if (member == nullptr) {
          Warn(absl::StrCat(tpath, ": morph attribute ", name, " ignored"));
          continue;
        }
        ASSIGN_OR_RETURN(AccessorView v, View(accessor, absl::StrCat(tpath, ".", name)));
        const std::string field = absl::StrCat(tpath, ".", name, " (accessors[", v.index, "])");
        bool needs_ext = false;
        if (v.type != TINYGLTF_TYPE_VEC3 || !AllowedComponents(v, name, &needs_ext) ||
            (needs_ext && !quantization_))
          return Err(field, "morph deltas must be VEC3 FLOAT (or quantized with "
                            "KHR_mesh_quantization)");
        if (v.count != CountOf(p, "POSITION"))
          return Err(field, v.count, " deltas for ", CountOf(p, "POSITION"), " vertices");
        if (member != &MorphDelta::position && !has_normals) continue;  // flat: recomputed
        for (size_t k = 0; k < source.size(); ++k) {
          const glm::vec3 d = glm::vec3(ReadVec(v, source[k]));
          if (!Finite(d)) return Err(field, "element ", source[k], " is not finite");
          out[t * source.size() + k].*member = d;
        }
      }
    }
    return absl::OkStatus();
  }

  uint64_t CountOf(const tinygltf::Primitive& p, const char* attribute) const {
    const auto it = p.attributes.find(attribute);
    return it == p.attributes.end() ? 0 : uint64_t(m_.accessors[it->second].count);
  }

  // glTF 2.0 3.7.3: a skin's joints (nodes, distinct, at most max_skin_joints) and inverse bind
  // matrices (MAT4 FLOAT, at least one per joint, finite; identity when absent).
  absl::Status ConvertSkins() {
    for (size_t si = 0; si < m_.skins.size(); ++si) {
      const tinygltf::Skin& gs = m_.skins[si];
      const std::string path = absl::StrCat("skins[", si, "]");
      Skin out;
      out.name = gs.name;
      if (gs.joints.empty()) return Err(path + ".joints", "is empty");
      if (gs.joints.size() > limits_.max_skin_joints)
        return OverMax(path + ".joints", "joint count", gs.joints.size(), "max_skin_joints",
                       limits_.max_skin_joints);
      std::set<int> seen;
      for (size_t j = 0; j < gs.joints.size(); ++j) {
        RETURN_IF_ERROR(CheckIndex(absl::StrCat(path, ".joints[", j, "]"), gs.joints[j],
                                   m_.nodes.size(), "node"));
        if (!seen.insert(gs.joints[j]).second)
          return Err(absl::StrCat(path, ".joints[", j, "]"), "nodes[", gs.joints[j],
                     "] is listed twice");
        out.joints.push_back(uint32_t(gs.joints[j]));
      }
      if (gs.skeleton >= 0)
        RETURN_IF_ERROR(CheckIndex(path + ".skeleton", gs.skeleton, m_.nodes.size(), "node"));
      out.inverse_bind.assign(out.joints.size(), glm::mat4(1.0f));
      if (gs.inverseBindMatrices >= 0) {
        ASSIGN_OR_RETURN(AccessorView v, View(gs.inverseBindMatrices, path + ".inverseBindMatrices"));
        const std::string field =
            absl::StrCat(path, ".inverseBindMatrices (accessors[", v.index, "])");
        if (v.type != TINYGLTF_TYPE_MAT4 || v.component_type != TINYGLTF_COMPONENT_TYPE_FLOAT)
          return Err(field, "must be MAT4 FLOAT");
        if (v.count < out.joints.size())
          return Err(field, v.count, " matrices for ", out.joints.size(), " joints");
        for (size_t j = 0; j < out.joints.size(); ++j) {
          for (int e = 0; e < 16; ++e) {
            const float x = ReadComponent(v, j, e);
            if (!std::isfinite(x)) return Err(field, "element ", j, " is not finite");
            glm::value_ptr(out.inverse_bind[j])[e] = x;
          }
        }
      }
      s_.skins.push_back(std::move(out));
    }
    return absl::OkStatus();
  }

  absl::StatusOr<uint32_t> ConvertMesh(int mesh) {
    if (const auto it = mesh_cache_.find(mesh); it != mesh_cache_.end()) return it->second;
    const tinygltf::Mesh& gm = m_.meshes[mesh];
    Mesh out{.name = gm.name};
    for (size_t i = 0; i < gm.primitives.size(); ++i) {
      RETURN_IF_ERROR(ConvertPrimitive(mesh, int(i), gm.primitives[i], &out.primitives));
    }
    s_.meshes.push_back(std::move(out));
    return mesh_cache_[mesh] = uint32_t(s_.meshes.size() - 1);
  }

  std::shared_ptr<const Image> ImageFor(int index) {
    std::shared_ptr<const Image>& image = image_cache_[index];
    tinygltf::Image& gi = m_.images[index];
    if (image == nullptr && gi.width > 0 && gi.height > 0 && gi.component == 4 && gi.bits == 8 &&
        gi.image.size() == size_t(gi.width) * size_t(gi.height) * 4) {
      auto img = std::make_shared<Image>();
      img->name = !gi.name.empty()  ? gi.name
                  : !gi.uri.empty() ? Quote(gi.uri)
                                    : absl::StrCat("images[", index, "]");
      img->width = uint32_t(gi.width);
      img->height = uint32_t(gi.height);
      img->rgba8 = std::move(gi.image);  // the model is ours; no need to copy the pixels
      image = std::move(img);
    }
    return image;
  }

  // One CpuScene texture per (glTF texture, colour space) actually used.
  absl::StatusOr<int32_t> TextureFor(int texture, bool srgb) {
    if (const auto it = texture_cache_.find({texture, srgb}); it != texture_cache_.end()) {
      return it->second;
    }
    const tinygltf::Texture& gt = m_.textures[texture];
    const std::string field = absl::StrCat("textures[", texture, "]");
    // EXT_texture_webp's source where the texture has one (the pre-scan checked it is an
    // image); its core source is then a fallback for other viewers.
    int source = gt.source;
    if (const auto webp = pre_.webp_sources.find(uint32_t(texture));
        webp != pre_.webp_sources.end()) {
      source = int(webp->second);
    } else if (source >= 0) {
      RETURN_IF_ERROR(CheckIndex(field + ".source", source, m_.images.size(), "image"));
    }
    if (gt.sampler >= 0) {
      RETURN_IF_ERROR(CheckIndex(field + ".sampler", gt.sampler, m_.samplers.size(), "sampler"));
    }
    int32_t& result = texture_cache_[{texture, srgb}] = -1;
    Texture t{.image = source >= 0 ? ImageFor(source) : nullptr, .srgb = srgb};
    if (t.image == nullptr) {
      Warn(field +
           ": no decoded image source (an extension's source other than "
           "EXT_texture_webp's, e.g. KHR_texture_basisu's, is not supported)");
      return result;
    }
    auto wrap = [this](int w) {
      if (w == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return WrapMode::kClampToEdge;
      if (w == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return WrapMode::kMirroredRepeat;
      if (w != TINYGLTF_TEXTURE_WRAP_REPEAT) Warn(absl::StrCat("unknown wrap mode ", w));
      return WrapMode::kRepeat;
    };
    if (gt.sampler >= 0) {
      t.wrap_s = wrap(m_.samplers[gt.sampler].wrapS);
      t.wrap_t = wrap(m_.samplers[gt.sampler].wrapT);
    }
    result = int32_t(s_.textures.size());
    s_.textures.push_back(std::move(t));
    return result;
  }

  // A textureInfo (any of the three tinygltf flavours) with its KHR_texture_transform.
  template <typename Info>
  absl::Status TextureSlot(const Info& info, bool srgb, const std::string& path, TextureRef* out) {
    if (info.index < 0) return absl::OkStatus();
    RETURN_IF_ERROR(CheckIndex(path + ".index", info.index, m_.textures.size(), "texture"));
    auto texcoord = [&](double tc) -> uint32_t {
      if (tc == 0.0 || tc == 1.0) return uint32_t(tc);
      Warn(absl::StrCat(path, ": texCoord ", tc, " is not supported; using 0"));
      return 0;
    };
    out->texcoord = texcoord(info.texCoord);
    if (const auto it = info.extensions.find("KHR_texture_transform");
        it != info.extensions.end()) {
      const tinygltf::Value& x = it->second;
      ReadNumbers(x, "offset", 2, &out->offset.x);
      ReadNumbers(x, "scale", 2, &out->scale.x);
      out->offset = glm::clamp(out->offset, -kMaxFactor, kMaxFactor);
      out->scale = glm::clamp(out->scale, -kMaxFactor, kMaxFactor);
      out->rotation = std::clamp(ToFloat(NumberOr(x, "rotation", 0.0)), -kMaxFactor, kMaxFactor);
      if (x.IsObject() && x.Has("texCoord")) out->texcoord = texcoord(NumberOr(x, "texCoord", -1));
    }
    absl::StatusOr<int32_t> t = TextureFor(info.index, srgb);
    if (!t.ok()) return t.status();
    out->texture = *t;
    return absl::OkStatus();
  }

  absl::Status ConvertMaterial(int index) {
    const tinygltf::Material& gm = m_.materials[index];
    const tinygltf::PbrMetallicRoughness& pbr = gm.pbrMetallicRoughness;
    const std::string path = absl::StrCat("materials[", index, "]");
    Material m{.name = gm.name};
    // The pre-scan refused factors outside the ranges the spec gives them (ValueRanges); the
    // ones the spec leaves unbounded are clamped here, so no shader multiplies by a huge number.
    for (size_t i = 0; pbr.baseColorFactor.size() == 4 && i < 4; ++i)
      m.base_color_factor[int(i)] = ToFloat(pbr.baseColorFactor[i]);
    for (size_t i = 0; gm.emissiveFactor.size() == 3 && i < 3; ++i)
      m.emissive_factor[int(i)] = ToFloat(gm.emissiveFactor[i]);
    m.metallic_factor = ToFloat(pbr.metallicFactor);
    m.roughness_factor = ToFloat(pbr.roughnessFactor);
    if (const auto it = gm.extensions.find("KHR_materials_emissive_strength");
        it != gm.extensions.end()) {
      m.emissive_strength =
          std::clamp(ToFloat(NumberOr(it->second, "emissiveStrength", 1)), 0.0f, kMaxFactor);
    }
    m.normal_scale = std::clamp(ToFloat(gm.normalTexture.scale), -kMaxFactor, kMaxFactor);
    m.occlusion_strength = ToFloat(gm.occlusionTexture.strength);
    if (gm.alphaMode == "MASK") {
      m.alpha_mode = AlphaMode::kMask;
    } else if (gm.alphaMode == "BLEND") {
      m.alpha_mode = AlphaMode::kBlend;
    } else if (gm.alphaMode != "OPAQUE") {
      Warn(absl::StrCat(path, ".alphaMode: unknown '", Quote(gm.alphaMode), "'; using OPAQUE"));
    }
    m.alpha_cutoff = std::clamp(ToFloat(gm.alphaCutoff), 0.0f, 1.0f);
    m.double_sided = gm.doubleSided;
    // The pre-scan refused an extension value that is not an object.
    m.unlit = gm.extensions.count("KHR_materials_unlit") != 0;
    const std::string pbr_path = path + ".pbrMetallicRoughness";
    RETURN_IF_ERROR(
        TextureSlot(pbr.baseColorTexture, true, pbr_path + ".baseColorTexture", &m.base_color));
    // An unlit material reads nothing but its base colour: the other textures are checked, not
    // decoded (their colour spaces and transforms no shader would use).
    auto lit_slot = [&](const auto& info, bool srgb, const std::string& field, TextureRef* out) {
      if (!m.unlit) return TextureSlot(info, srgb, field, out);
      if (info.index < 0) return absl::OkStatus();
      return CheckIndex(field + ".index", info.index, m_.textures.size(), "texture");
    };
    RETURN_IF_ERROR(lit_slot(pbr.metallicRoughnessTexture, false,
                             pbr_path + ".metallicRoughnessTexture", &m.metallic_roughness));
    RETURN_IF_ERROR(lit_slot(gm.normalTexture, false, path + ".normalTexture", &m.normal));
    RETURN_IF_ERROR(lit_slot(gm.occlusionTexture, false, path + ".occlusionTexture", &m.occlusion));
    RETURN_IF_ERROR(lit_slot(gm.emissiveTexture, true, path + ".emissiveTexture", &m.emissive));
    // KHR_materials_ior and KHR_materials_specular, as the pre-scan read and checked them (ior 0
    // or at least 1, specularFactor in [0, 1], specularColorFactor non-negative).
    if (const auto it = pre_.reflectance.find(uint32_t(index)); it != pre_.reflectance.end()) {
      const gltf_internal::PreScanResult::Reflectance& r = it->second;
      m.ior = std::min(ToFloat(r.ior), kMaxFactor);
      m.specular_factor = ToFloat(r.specular_factor);
      for (int c = 0; c < 3; ++c)
        m.specular_color_factor[c] = std::min(ToFloat(r.specular_color[c]), kMaxFactor);
      const auto ext = gm.extensions.find("KHR_materials_specular");
      const tinygltf::Value none;
      const tinygltf::Value& x = ext != gm.extensions.end() ? ext->second : none;
      const std::string field = path + ".extensions.KHR_materials_specular";
      RETURN_IF_ERROR(lit_slot(
          ExtensionTextureInfo(x, "specularTexture", r.specular_texture, r.specular_texcoord),
          false, field + ".specularTexture", &m.specular));
      RETURN_IF_ERROR(
          lit_slot(ExtensionTextureInfo(x, "specularColorTexture", r.specular_color_texture,
                                        r.specular_color_texcoord),
                   true, field + ".specularColorTexture", &m.specular_color));
    }
    if (m.unlit) {
      m.emissive_factor = glm::vec3(0.0f);
      m.emissive_strength = 1.0f;
      // (Either extension with KHR_materials_unlit is against their specs; unlit wins.)
      m.ior = 1.5f;
      m.specular_factor = 1.0f;
      m.specular_color_factor = glm::vec3(1.0f);
    }
    s_.materials.push_back(std::move(m));
    return absl::OkStatus();
  }

  // glTF requires disjoint strict trees; anything else could loop or explode combinatorially.
  absl::Status CheckHierarchy() {
    const size_t count = m_.nodes.size();
    parent_.assign(count, -1);
    for (size_t i = 0; i < count; ++i) {
      for (int c : m_.nodes[i].children) {
        const std::string field = absl::StrCat("nodes[", i, "]");
        RETURN_IF_ERROR(CheckIndex(field + ".children", c, count, "node"));
        if (size_t(c) == i) return Err(field, "node hierarchy contains a cycle (own child)");
        if (parent_[c] >= 0) {
          return Err(absl::StrCat("nodes[", c, "]"), "node has more than one parent (nodes[",
                     parent_[c], "] and nodes[", i, "])");
        }
        parent_[c] = int(i);
      }
    }
    // With one parent each, a node is in a cycle exactly when its parent chain never ends.
    std::vector<uint8_t> state(count, 0);  // 0 unknown, 1 on the current walk, 2 reaches a root
    std::vector<int> walk;
    for (size_t i = 0; i < count; ++i) {
      walk.clear();
      int n = int(i);
      for (; n >= 0 && state[n] == 0; n = parent_[n]) {
        state[n] = 1;
        walk.push_back(n);
      }
      if (n >= 0 && state[n] == 1) {
        return Err(absl::StrCat("nodes[", n, "]"), "node hierarchy contains a cycle");
      }
      for (int w : walk) state[w] = 2;
    }
    // Depth (a root is 1) bounds the traversal; each node's is its parent's plus one.
    std::vector<uint32_t> depth(count, 0);
    for (size_t i = 0; i < count; ++i) {
      walk.clear();
      int n = int(i);
      for (; n >= 0 && depth[n] == 0; n = parent_[n]) walk.push_back(n);
      uint32_t d = n >= 0 ? depth[n] : 0;
      for (auto w = walk.rbegin(); w != walk.rend(); ++w) depth[*w] = ++d;
      if (depth[i] > limits_.max_node_depth) {
        return OverLimit(file_, absl::StrCat("nodes[", i, "]"), "node depth ", depth[i],
                         " exceeds the max_node_depth limit (", limits_.max_node_depth, ")");
      }
    }
    return absl::OkStatus();
  }

  // A node's local transform as the file gives it: its matrix, or its TRS properties (a
  // rotation normalized; a zero one stays the identity).
  absl::Status LocalTransform(int index, NodeTransform* trs, std::optional<glm::mat4>* matrix) {
    const tinygltf::Node& n = m_.nodes[index];
    const std::string path = absl::StrCat("nodes[", index, "]");
    *trs = NodeTransform{};
    matrix->reset();
    if (!n.matrix.empty()) {
      if (n.matrix.size() != 16) return Err(path + ".matrix", "expected 16 numbers");
      glm::mat4 m(1.0f);
      for (int i = 0; i < 16; ++i) glm::value_ptr(m)[i] = ToFloat(n.matrix[i]);
      *matrix = m;
      return absl::OkStatus();
    }
    if (!n.translation.empty() && n.translation.size() != 3) {
      return Err(path + ".translation", "expected 3 numbers");
    }
    if (!n.rotation.empty() && n.rotation.size() != 4) {
      return Err(path + ".rotation", "expected 4 numbers");
    }
    if (!n.scale.empty() && n.scale.size() != 3) return Err(path + ".scale", "expected 3 numbers");
    for (size_t i = 0; i < n.translation.size(); ++i) trs->translation[int(i)] = ToFloat(n.translation[i]);
    for (size_t i = 0; i < n.scale.size(); ++i) trs->scale[int(i)] = ToFloat(n.scale[i]);
    if (n.rotation.size() == 4) {
      const glm::quat r(ToFloat(n.rotation[3]), ToFloat(n.rotation[0]), ToFloat(n.rotation[1]),
                        ToFloat(n.rotation[2]));
      const float len = glm::length(r);
      if (len > 1e-12f && std::isfinite(len)) trs->rotation = r / len;
    }
    return absl::OkStatus();
  }

  absl::StatusOr<glm::mat4> LocalMatrix(int index) {
    NodeTransform trs;
    std::optional<glm::mat4> matrix;
    RETURN_IF_ERROR(LocalTransform(index, &trs, &matrix));
    return matrix ? *matrix : trs.Matrix();
  }

  // EXT_mesh_gpu_instancing: the transforms of node `index`'s instances under it (T * R * S of
  // its TRANSLATION, ROTATION and SCALE accessors, each optional, all of one count), or one
  // identity without the extension. Each instance of its mesh's `primitives` is a drawable, so
  // the count is held to max_drawables before anything is read.
  absl::StatusOr<std::vector<glm::mat4>> Instances(int index, size_t primitives) {
    // The pre-scan read the extension: at least one attribute, each an accessor that exists.
    const auto instancing = pre_.instancing.find(uint32_t(index));
    if (instancing == pre_.instancing.end()) return std::vector<glm::mat4>{glm::mat4(1.0f)};
    const std::string path = absl::StrCat("nodes[", index, "].extensions.EXT_mesh_gpu_instancing");
    if (m_.nodes[index].skin >= 0) {
      return Err(path, "instances of a skinned mesh are not supported");
    }
    static constexpr const char* kNames[3] = {"TRANSLATION", "ROTATION", "SCALE"};
    AccessorView views[3];
    uint64_t count = UINT64_MAX;
    std::string first;       // the attribute that set `count`
    bool generated = false;  // an accessor of zeros or sparse blocks (costs nothing to upload)
    // Every attribute, the application's own (_ID, ...) too: all of one count, which an
    // instance has even where none of the three transform attributes is given.
    for (const auto& [name, accessor] : instancing->second) {
      const std::string field = absl::StrCat(path, ".attributes.", name);
      ASSIGN_OR_RETURN(const AccessorView v, View(int(accessor), field));
      generated = generated || m_.accessors[accessor].bufferView < 0 ||
                  m_.accessors[accessor].sparse.isSparse;
      if (count != UINT64_MAX && v.count != count) {
        return Err(field, "count ", v.count, " differs from ", first, "'s ", count);
      }
      if (count == UINT64_MAX) first = name;
      count = v.count;
      const int k = int(std::find(std::begin(kNames), std::end(kNames), name) - std::begin(kNames));
      if (k == 3) continue;
      // The extension's table: ROTATION as FLOAT or normalized signed BYTE/SHORT (a NORMAL's
      // types, without needing KHR_mesh_quantization); TRANSLATION and SCALE as FLOAT, or
      // (leniently, as positions) any 8- or 16-bit integer type with KHR_mesh_quantization.
      const bool rotation = k == 1;
      bool needs_ext = false;
      const bool allowed = AllowedComponents(v, rotation ? "NORMAL" : "POSITION", &needs_ext) &&
                           (rotation || !needs_ext || quantization_);
      const std::string what =
          absl::StrCat(v.normalized ? "normalized " : "", ComponentTypeName(v.component_type));
      if (v.type != (rotation ? TINYGLTF_TYPE_VEC4 : TINYGLTF_TYPE_VEC3) || !allowed) {
        return Err(field, "unsupported type/componentType for ", name, " (",
                   tinygltf::GetNumComponentsInType(uint32_t(v.type)), " x ", what, ")");
      }
      views[k] = v;
    }
    if (count * std::max<size_t>(primitives, 1) >
        uint64_t(limits_.max_drawables) -
            std::min<uint64_t>(s_.drawables.size(), limits_.max_drawables)) {
      return OverMax(path, "drawable count", s_.drawables.size() + count * primitives,
                     "max_drawables", limits_.max_drawables);
    }
    // Instances placed by zeros or sparse blocks would let a few bytes of JSON ask for a million
    // drawables: they count against those accessors' budget, at what a drawable costs.
    if (generated) {
      const uint64_t bytes = count * std::max<size_t>(primitives, 1) * kInstanceBytes;
      if (bytes > generated_budget_ - generated_bytes_) {
        return OverLimit(file_, path, count, " instances placed by zeros or sparse data stand for ",
                         bytes, " bytes of drawables (", kInstanceBytes, " each); all such data ",
                         "may hold ", generated_budget_, " bytes (", kGeneratedPerSourceByte,
                         "x the uploaded files, at least ", kMinGeneratedBytes, ")");
      }
      generated_bytes_ += bytes;
    }
    std::vector<glm::mat4> out;
    out.reserve(count);
    for (uint64_t i = 0; i < count; ++i) {
      NodeTransform trs;
      if (views[0].data) trs.translation = glm::vec3(ReadVec(views[0], i));
      if (views[1].data) {
        const glm::vec4 q = ReadVec(views[1], i);
        const glm::quat r(q.w, q.x, q.y, q.z);
        const float len = glm::length(r);
        if (!std::isfinite(len)) return Err(path, "instance ", i, "'s rotation is not finite");
        if (len > 1e-12f) trs.rotation = r / len;
      }
      if (views[2].data) trs.scale = glm::vec3(ReadVec(views[2], i));
      const glm::mat4 m = trs.Matrix();
      for (int c = 0; c < 4; ++c) {
        if (!Finite(glm::vec3(m[c])) || !std::isfinite(m[c][3]))
          return Err(path, "instance ", i, "'s transform is not finite");
      }
      out.push_back(m);
    }
    return out;
  }

  absl::Status PlaceNode(int index, const glm::mat4& world) {
    const tinygltf::Node& n = m_.nodes[index];
    const std::string path = absl::StrCat("nodes[", index, "]");
    for (int c = 0; c < 4; ++c) {
      if (!Finite(glm::vec3(world[c])) || !std::isfinite(world[c][3])) {
        return Err(path, "world transform is not finite");
      }
    }
    if (n.mesh >= 0) {
      RETURN_IF_ERROR(CheckIndex(path + ".mesh", n.mesh, m_.meshes.size(), "mesh"));
      absl::StatusOr<uint32_t> mesh = ConvertMesh(n.mesh);
      if (!mesh.ok()) return mesh.status();
      ASSIGN_OR_RETURN(const std::vector<glm::mat4> instances,
                       Instances(index, s_.meshes[*mesh].primitives.size()));
      for (const glm::mat4& instance : instances) {
        const glm::mat4 placed = world * instance;
        for (uint32_t prim : s_.meshes[*mesh].primitives) {
          if (s_.drawables.size() >= limits_.max_drawables) {
            return OverMax(path, "drawable count", s_.drawables.size() + 1, "max_drawables",
                           limits_.max_drawables);
          }
          const Primitive& p = s_.primitives[prim];
          const Aabb world_bounds = p.bounds.transformed(placed);
          // Finite positions times a finite transform can still overflow float.
          if (!Finite(world_bounds.min) || !Finite(world_bounds.max)) {
            return Err(path, "mesh ", *mesh, " placed by this node has non-finite world bounds");
          }
          s_.drawables.push_back(Drawable{.world = placed,
                                          .primitive = prim,
                                          .mesh = *mesh,
                                          .node = uint32_t(index),
                                          .world_bounds = world_bounds,
                                          .instance = instance});
          s_.bounds.extend(s_.drawables.back().world_bounds);
          s_.counts.triangles += p.index_count / 3;
        }
      }
    }
    if (n.camera >= 0) {
      RETURN_IF_ERROR(CheckIndex(path + ".camera", n.camera, m_.cameras.size(), "camera"));
      const tinygltf::Camera& gc = m_.cameras[n.camera];
      const tinygltf::PerspectiveCamera& p = gc.perspective;
      if (gc.type == "perspective" &&
          !(std::isfinite(p.yfov) && std::isfinite(p.aspectRatio) && std::isfinite(p.znear) &&
            std::isfinite(p.zfar))) {
        Warn(absl::StrCat(path, ": camera ", n.camera, " has non-finite parameters; skipped"));
      } else if (gc.type == "perspective") {
        SceneCamera cam{.name = gc.name, .world = world, .node = int32_t(index)};
        if (p.yfov > 0.0 && p.yfov < 3.14) cam.yfov = ToFloat(p.yfov);
        if (p.aspectRatio > 0.0) cam.aspect = ToFloat(p.aspectRatio);
        if (p.znear > 0.0) cam.znear = ToFloat(p.znear);
        if (p.zfar > p.znear) cam.zfar = ToFloat(p.zfar);
        s_.cameras.push_back(cam);
      } else {
        Warn(absl::StrCat(path, ": camera type '", Quote(gc.type), "' is not supported; skipped"));
      }
    }
    const auto ext = n.extensions.find("KHR_lights_punctual");
    if (ext == n.extensions.end()) return absl::OkStatus();
    const double li = NumberOr(ext->second, "light", -1.0);
    if (li != std::floor(li)) {  // 0.5 read as light 0
      return Err(path + ".extensions.KHR_lights_punctual.light", "light index ", li,
                 " is not an integer");
    }
    if (!(li >= 0.0 && li < double(m_.lights.size()))) {
      return Err(path + ".extensions.KHR_lights_punctual.light", "light index out of range (",
                 m_.lights.size(), " lights)");
    }
    const tinygltf::Light& gl = m_.lights[size_t(li)];
    const std::string light_field =
        absl::StrCat("extensions.KHR_lights_punctual.lights[", size_t(li), "]");
    // Light parameters reach the shaders as floats multiplied together: refuse what float
    // cannot hold, and clamp the rest to what a real light has.
    auto fits = [](double v) { return std::abs(v) <= double(std::numeric_limits<float>::max()); };
    bool fit = fits(gl.intensity) && fits(gl.range) && fits(gl.spot.innerConeAngle) &&
               fits(gl.spot.outerConeAngle);
    for (double c : gl.color) fit = fit && fits(c);
    if (!fit) return Err(light_field, "color, intensity, range or cone angle is too large for float");
    Light l{.name = gl.name, .node = int32_t(index)};
    if (gl.type == "directional") {
      l.type = LightType::kDirectional;
    } else if (gl.type == "spot") {
      l.type = LightType::kSpot;
    } else if (gl.type != "point") {
      Warn(absl::StrCat(path, ": light type '", Quote(gl.type), "' is not supported; skipped"));
      return absl::OkStatus();
    }
    for (size_t i = 0; gl.color.size() == 3 && i < 3; ++i)
      l.color[int(i)] = std::clamp(ToFloat(gl.color[i]), 0.0f, 1.0f);  // linear RGB, spec: 0..1
    l.intensity = std::clamp(ToFloat(gl.intensity), 0.0f, kMaxLightIntensity);
    l.range = std::max(0.0f, ToFloat(gl.range));
    l.inner_cone_angle = std::max(0.0f, ToFloat(gl.spot.innerConeAngle));
    l.outer_cone_angle = std::max(l.inner_cone_angle, ToFloat(gl.spot.outerConeAngle));
    l.position = glm::vec3(world[3]);
    l.direction = NormalizeOr(glm::mat3(world) * glm::vec3(0, 0, -1), glm::vec3(0, 0, -1));
    s_.lights.push_back(l);
    return absl::OkStatus();
  }

  const std::string& file_;
  const ImportLimits& limits_;
  tinygltf::Model& m_;
  CpuScene& s_;
  const uint64_t max_vertices_, max_indices_;
  int32_t default_material_ = -1;
  std::vector<int> parent_;             // per node, -1 for roots
  std::map<uint32_t, uint32_t> max_joint_;  // skinned primitive -> largest joint index it uses
  std::map<int, uint32_t> mesh_cache_;  // glTF mesh -> CpuScene::meshes
  std::map<std::pair<int, bool>, int32_t> texture_cache_;
  std::map<int, std::shared_ptr<const Image>> image_cache_;
  // Accessors as read (View), and the packed copies made of sparse and bufferView-less ones,
  // bounded by the upload's size.
  static constexpr uint64_t kGeneratedPerSourceByte = 16;
  static constexpr uint64_t kMinGeneratedBytes = 16ull << 20;
  // What an EXT_mesh_gpu_instancing drawable costs, as Instances() charges it to that budget:
  // its CpuScene record, its GPU record and its draw.
  static constexpr uint64_t kInstanceBytes = 256;
  const uint64_t generated_budget_;
  uint64_t generated_bytes_ = 0;
  std::map<int, AccessorView> views_;
  std::deque<std::vector<uint8_t>> owned_;
  // Compressed geometry: meshopt bufferViews decoded so far, and what Draco decoded (bounded by
  // max_decoded_bytes together with the meshopt fallback buffers the pre-scan counted).
  const gltf_internal::PreScanResult& pre_;
  std::set<int> decoded_views_;
  // Accessors whose data DecodeDracoPrimitive decoded: lossy, so a colour may overshoot [0, 1]
  // by the dequantization's rounding (the validator does not read them).
  std::set<int> draco_accessors_;
  std::vector<size_t> accessors_of_view_;  // AccessorsOfView, counted on first use
  uint64_t decoded_bytes_ = [this] {
    uint64_t fallback = 0;
    for (const auto& [index, length] : pre_.fallback_buffers) fallback += length;
    return fallback;
  }();
  // KHR_draco_mesh_compression is in extensionsUsed: primitives may be Draco-compressed.
  const bool draco_ = Uses("KHR_draco_mesh_compression");
  // KHR_mesh_quantization is in extensionsUsed: attributes may be quantized.
  const bool quantization_ = Uses("KHR_mesh_quantization");

  bool Uses(const char* extension) const {
    return std::find(m_.extensionsUsed.begin(), m_.extensionsUsed.end(), extension) !=
           m_.extensionsUsed.end();
  }
};

}  // namespace

const std::vector<std::string_view>& SupportedGltfExtensions() {
  static const std::vector<std::string_view> names{
      "EXT_mesh_gpu_instancing",    "EXT_meshopt_compression", "EXT_texture_webp",
      "KHR_draco_mesh_compression", "KHR_lights_punctual",     "KHR_materials_emissive_strength",
      "KHR_materials_ior",          "KHR_materials_specular",  "KHR_materials_unlit",
      "KHR_mesh_quantization",      "KHR_texture_transform"};
  return names;
}

absl::StatusOr<CpuScene> ImportGltf(const GltfSource& source, const ImportLimits& limits) {
  const std::string& file = source.main_file;
  absl::StatusOr<gltf_internal::PreScanResult> pre = gltf_internal::PreScanGltf(source, limits);
  if (!pre.ok()) return pre.status();
  const std::vector<uint8_t>& bytes = pre->main_bytes();
  const absl::string_view text = pre->text;
  const bool is_glb = pre->is_glb;
  CpuScene scene;
  scene.name = file;
  scene.warnings = std::move(pre->warnings);
  LoadContext ctx{.source = &source,
                  .limits = &limits,
                  .alias = std::move(pre->alias),
                  .image_needed = std::move(pre->image_needed),
                  .image_webp = std::move(pre->image_webp)};

  tinygltf::TinyGLTF loader;
  loader.SetFsCallbacks(
      {&FsFileExists, &FsExpandFilePath, &FsReadWholeFile, &FsWriteWholeFile, &ctx});
  loader.SetImageLoader(&LoadImage, &ctx);
  tinygltf::Model model;
  std::string err, warn;
  bool ok = false;
  try {
    ok = is_glb ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(),
                                              static_cast<unsigned int>(bytes.size()), "")
                : loader.LoadASCIIFromString(&model, &err, &warn, text.data(),
                                             static_cast<unsigned int>(text.size()), "");
  } catch (const std::exception& e) {
    err = e.what();
  }
  if (!ctx.error.ok()) return ctx.error;
  if (!ok) {
    while (!err.empty() && err.back() == '\n') err.pop_back();
    return Invalid(file, "tinygltf", Quote(err.empty() ? "cannot parse" : err));
  }
  for (size_t start = 0, end; start < warn.size(); start = end + 1) {
    end = std::min(warn.find('\n', start), warn.size());
    if (end > start && scene.warnings.size() < kMaxWarnings) {
      scene.warnings.push_back("tinygltf: " + Quote(warn.substr(start, end - start)));
    }
  }
  try {
    uint64_t source_bytes = 0;
    for (const auto& [name, data] : source.files) source_bytes += data.size();
    RETURN_IF_ERROR(Converter(file, limits, &model, &scene, source_bytes, *pre).Run());
  } catch (const std::bad_alloc&) {
    return Invalid(file, "file", "too large to import (out of memory)");
  }
  if (scene.warnings.size() >= kMaxWarnings) scene.warnings.push_back("more warnings omitted");
  return scene;
}

absl::StatusOr<DecodedImage> DecodeTextureImage(const uint8_t* bytes, size_t size,
                                                const ImportLimits& limits) {
  return DecodeImage(bytes, size, limits, 0, /*webp=*/true);
}

}  // namespace tessera

// glTF 2.0 import. The input comes from the network, so the JSON is pre-scanned (URIs, buffer
// and bufferView ranges, required extensions) before tinygltf sees it, tinygltf only reads from
// the in-memory file set, and every index and size of the parsed model is checked again before
// it is dereferenced.
#include "renderer/scene/gltf_import.h"

#include <stb/stb_image.h>
#include <tiny_gltf.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <utility>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace tessera {
namespace {

using nlohmann::json;

constexpr int kMaxJsonDepth = 64;     // tinygltf walks extras/extensions recursively
constexpr size_t kMaxWarnings = 100;  // hostile files must not grow the warning list forever
constexpr size_t kMaxQuoted = 120;    // longest string quoted in a message

constexpr const char* kSupportedExtensions[] = {
    "KHR_texture_transform", "KHR_materials_emissive_strength", "KHR_lights_punctual"};

bool IsSupportedExtension(const std::string& name) {
  for (const char* e : kSupportedExtensions) {
    if (name == e) return true;
  }
  return false;
}

// Cuts long strings (base64 URIs, tinygltf dumps) so messages stay readable.
std::string Quote(absl::string_view s) {
  if (s.size() <= kMaxQuoted) return std::string(s);
  return absl::StrCat(s.substr(0, kMaxQuoted), "...");
}

float ToFloat(double d) {
  // double -> float outside the float range is undefined behaviour; clamp instead.
  if (std::isnan(d)) return 0.0f;
  return static_cast<float>(std::clamp<double>(d, -std::numeric_limits<float>::max(),
                                               std::numeric_limits<float>::max()));
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// RFC 3986 %-decoding, the way keys of GltfSource::files are written.
std::string PercentDecode(absl::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '%' && i + 2 < s.size() && HexValue(s[i + 1]) >= 0 && HexValue(s[i + 2]) >= 0) {
      out += static_cast<char>(HexValue(s[i + 1]) * 16 + HexValue(s[i + 2]));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// tinygltf decodes URIs its own way ('+' is a space, bad hex is 0) before calling the file
// callbacks; we map that spelling back to the real key.
std::string TinygltfDecode(absl::string_view s) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    if (s[i] == '+') {
      out += ' ';
    } else if (s[i] == '%' && s.size() > i + 2) {
      out += static_cast<char>((std::max(HexValue(s[i + 1]), 0) << 4) |
                               std::max(HexValue(s[i + 2]), 0));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// The data: URI media types tinygltf 2.7 decodes; anything else it would treat as a file name.
bool IsTinygltfDataUri(absl::string_view uri, size_t* payload) {
  static constexpr const char* kPrefixes[] = {
      "data:application/octet-stream;base64,", "data:application/gltf-buffer;base64,",
      "data:image/jpeg;base64,", "data:image/png;base64,", "data:image/bmp;base64,",
      "data:image/gif;base64,", "data:text/plain;base64,"};
  for (const char* p : kPrefixes) {
    if (uri.substr(0, std::strlen(p)) == p) {
      *payload = uri.size() - std::strlen(p);
      return true;
    }
  }
  return false;
}

bool HasScheme(absl::string_view s) {
  size_t colon = s.find(':');
  if (colon == absl::string_view::npos || colon == 0) return false;
  for (size_t i = 0; i < colon; ++i) {
    const char c = s[i];
    const bool ok = std::isalpha(static_cast<unsigned char>(c)) ||
                    (i > 0 && (std::isdigit(static_cast<unsigned char>(c)) || c == '+' ||
                               c == '-' || c == '.'));
    if (!ok) return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Raw file checks: GLB container and JSON nesting.

uint32_t ReadU32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

struct GlbChunks {
  absl::string_view json;
  const uint8_t* bin = nullptr;
  size_t bin_size = 0;
};

// Checks the GLB container so that a truncated file gets a precise message.
absl::Status ParseGlb(const std::string& file, const std::vector<uint8_t>& d, GlbChunks* out) {
  auto err = [&](absl::string_view what) {
    return absl::InvalidArgumentError(absl::StrCat(file, ": GLB: ", what));
  };
  if (d.size() < 20) {
    return err(absl::StrCat("file is truncated (", d.size(), " bytes, header needs 20)"));
  }
  if (d.size() > std::numeric_limits<uint32_t>::max()) return err("file is 4 GiB or larger");
  const uint32_t version = ReadU32(&d[4]), length = ReadU32(&d[8]);
  if (version != 2) return err(absl::StrCat("version ", version, " is not supported"));
  if (length > d.size()) {
    return err(absl::StrCat("file is truncated: header declares length ", length,
                            " but the file has ", d.size(), " bytes"));
  }
  const uint64_t json_len = ReadU32(&d[12]);
  if (ReadU32(&d[16]) != 0x4E4F534Au) return err("first chunk is not JSON");
  if (20 + json_len > length) {
    return err(absl::StrCat("file is truncated: JSON chunk of ", json_len,
                            " bytes exceeds the file length ", length));
  }
  out->json = absl::string_view(reinterpret_cast<const char*>(&d[20]), json_len);
  const uint64_t bin_at = 20 + json_len;
  if (bin_at + 8 <= length && ReadU32(&d[bin_at + 4]) == 0x004E4942u) {
    const uint64_t bin_len = ReadU32(&d[bin_at]);
    if (bin_at + 8 + bin_len > length) {
      return err(absl::StrCat("file is truncated: BIN chunk of ", bin_len,
                              " bytes exceeds the file length ", length));
    }
    out->bin = &d[bin_at + 8];
    out->bin_size = bin_len;
  }
  return absl::OkStatus();
}

// tinygltf recurses over arrays/objects in extras; a deep document would overflow the stack.
bool JsonTooDeep(absl::string_view text) {
  int depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') ++i;
      else if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      if (++depth > kMaxJsonDepth) return true;
    } else if (c == ']' || c == '}') {
      --depth;
    }
  }
  return false;
}

// ---------------------------------------------------------------------------------------------
// Callback context shared with tinygltf: the file set, and which images need decoding.

struct LoadContext {
  const GltfSource* source = nullptr;
  const ImportLimits* limits = nullptr;
  std::map<std::string, std::string> alias;  // tinygltf-decoded URI -> key in source->files
  std::vector<bool> image_needed;           // referenced by some texture
  std::string error;                        // first error raised inside a callback
};

bool FsFileExists(const std::string& path, void* user) {
  return static_cast<LoadContext*>(user)->alias.count(path) > 0;
}

std::string FsExpandFilePath(const std::string& path, void*) { return path; }

bool FsReadWholeFile(std::vector<unsigned char>* out, std::string* err, const std::string& path,
                     void* user) {
  auto* ctx = static_cast<LoadContext*>(user);
  auto a = ctx->alias.find(path);
  auto f = a == ctx->alias.end() ? ctx->source->files.end() : ctx->source->files.find(a->second);
  if (f == ctx->source->files.end()) {
    if (err) *err += "not in the file set";
    return false;
  }
  out->assign(f->second.begin(), f->second.end());
  return true;
}

bool FsWriteWholeFile(std::string* err, const std::string&, const std::vector<unsigned char>&,
                      void*) {
  if (err) *err += "writing is not allowed";
  return false;
}

// Decodes every needed image to RGBA8 with stb_image, after checking the declared size.
bool LoadImage(tinygltf::Image* image, const int index, std::string* err, std::string*, int,
               int, const unsigned char* bytes, int size, void* user) {
  auto* ctx = static_cast<LoadContext*>(user);
  if (index < 0 || size_t(index) >= ctx->image_needed.size() || !ctx->image_needed[index]) {
    return true;  // no texture uses it: skip the decode
  }
  const std::string what = absl::StrCat(
      ctx->source->main_file, ": images[", index, "] (",
      Quote(image->name.empty() ? image->uri : image->name), "): ");
  auto fail = [&](const std::string& msg) {
    if (ctx->error.empty()) ctx->error = what + msg;
    if (err) *err += what + msg;
    return false;
  };
  if (bytes == nullptr || size <= 0) return fail("no image data");
  int w = 0, h = 0, comp = 0;
  if (!stbi_info_from_memory(bytes, size, &w, &h, &comp)) {
    return fail(absl::StrCat("cannot decode: ", stbi_failure_reason()));
  }
  const ImportLimits& lim = *ctx->limits;
  auto check = [&](int iw, int ih) {
    if (iw <= 0 || ih <= 0 || uint32_t(iw) > lim.max_image_dimension ||
        uint32_t(ih) > lim.max_image_dimension) {
      return absl::StrCat(iw, "x", ih, " exceeds the maximum dimension ",
                          lim.max_image_dimension);
    }
    if (uint64_t(iw) * uint64_t(ih) > lim.max_image_pixels) {
      return absl::StrCat(iw, "x", ih, " exceeds the maximum of ", lim.max_image_pixels,
                          " pixels");
    }
    return std::string();
  };
  if (std::string m = check(w, h); !m.empty()) return fail(m);
  stbi_uc* pixels = stbi_load_from_memory(bytes, size, &w, &h, &comp, 4);
  if (pixels == nullptr) return fail(absl::StrCat("cannot decode: ", stbi_failure_reason()));
  if (std::string m = check(w, h); !m.empty()) {
    stbi_image_free(pixels);
    return fail(m);
  }
  image->width = w;
  image->height = h;
  image->component = 4;
  image->bits = 8;
  image->pixel_type = TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
  image->image.assign(pixels, pixels + size_t(w) * size_t(h) * 4);
  stbi_image_free(pixels);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Pre-scan of the JSON (nlohmann) for what tinygltf would otherwise trust or resolve itself.

bool JsonUint(const json* v, uint64_t* out) {
  if (v == nullptr) return false;
  if (v->is_number_unsigned()) {
    *out = v->get<uint64_t>();
    return true;
  }
  if (v->is_number_integer() && v->get<int64_t>() >= 0) {
    *out = uint64_t(v->get<int64_t>());
    return true;
  }
  return false;
}

const json* Member(const json& o, const char* key) {
  if (!o.is_object()) return nullptr;
  auto it = o.find(key);
  return it == o.end() ? nullptr : &*it;
}

class PreScanner {
 public:
  PreScanner(const GltfSource& src, const GlbChunks* glb, LoadContext* ctx,
             std::vector<std::string>* warnings)
      : src_(src), glb_(glb), ctx_(ctx), warnings_(warnings) {}

  absl::Status Run(const json& j) {
    if (!j.is_object()) return Err("JSON", "the top level is not an object");
    if (const json* req = Member(j, "extensionsRequired"); req && req->is_array()) {
      for (const json& e : *req) {
        const std::string name = e.is_string() ? e.get<std::string>() : e.dump();
        if (!IsSupportedExtension(name)) {
          return Err("extensionsRequired",
                     absl::StrCat("unsupported required extension ", Quote(name)));
        }
      }
    }
    if (const json* used = Member(j, "extensionsUsed"); used && used->is_array()) {
      for (const json& e : *used) {
        if (e.is_string() && !IsSupportedExtension(e.get<std::string>())) {
          warnings_->push_back(absl::StrCat("extension ", Quote(e.get<std::string>()),
                                            " is not supported; ignored"));
        }
      }
    }
    std::vector<uint64_t> buffer_lengths;
    if (absl::Status s = ScanBuffers(j, &buffer_lengths); !s.ok()) return s;
    if (absl::Status s = ScanBufferViews(j, buffer_lengths); !s.ok()) return s;
    if (absl::Status s = ScanMeshes(j); !s.ok()) return s;
    return ScanImages(j);
  }

 private:
  absl::Status Err(absl::string_view field, absl::string_view what) const {
    return absl::InvalidArgumentError(absl::StrCat(src_.main_file, ": ", field, ": ", what));
  }

  // Maps an external URI to its key in the file set, or explains why it cannot be used.
  absl::StatusOr<std::string> Resolve(const std::string& field, const std::string& uri) {
    const std::string key = PercentDecode(uri);
    std::string why;
    if (key.empty()) {
      why = " (empty URI)";
    } else if (key.find('\\') != std::string::npos || key.find('\0') != std::string::npos) {
      why = " (backslashes and NUL are not allowed)";
    } else if (key[0] == '/') {
      why = " (absolute paths are not allowed)";
    } else if (HasScheme(key)) {
      why = " (URI schemes other than data: are not allowed)";
    } else if (key == ".." || key.rfind("../", 0) == 0 || key.find("/../") != std::string::npos ||
               (key.size() >= 3 && key.compare(key.size() - 3, 3, "/..") == 0)) {
      why = " (it leaves the asset directory)";
    } else if (src_.files.count(key) == 0) {
      why = "";
    } else {
      ctx_->alias.emplace(TinygltfDecode(uri), key);
      return key;
    }
    return Err(field, absl::StrCat("'", Quote(uri), "' is not in the file set", why));
  }

  absl::Status ScanBuffers(const json& j, std::vector<uint64_t>* lengths) {
    const json* buffers = Member(j, "buffers");
    if (buffers == nullptr || !buffers->is_array()) return absl::OkStatus();
    for (size_t i = 0; i < buffers->size(); ++i) {
      const json& b = (*buffers)[i];
      const std::string field = absl::StrCat("buffers[", i, "]");
      uint64_t length = 0;
      if (!JsonUint(Member(b, "byteLength"), &length)) {
        return Err(field + ".byteLength", "missing or not a non-negative integer");
      }
      const json* uri = Member(b, "uri");
      if (uri != nullptr && !uri->is_string()) return Err(field + ".uri", "not a string");
      if (uri == nullptr) {
        if (glb_ == nullptr) return Err(field, "uri is missing (only allowed in a .glb)");
        if (length > glb_->bin_size) {
          return Err(field, absl::StrCat("byteLength (", length, ") exceeds the GLB BIN chunk (",
                                         glb_->bin_size, " bytes)"));
        }
      } else {
        const std::string u = uri->get<std::string>();
        size_t payload = 0;
        if (u.rfind("data:", 0) == 0) {
          if (!IsTinygltfDataUri(u, &payload)) {
            return Err(field + ".uri", "only base64 data: URIs of buffer/image types are supported");
          }
          if (length > payload / 4 * 3 + 3) {
            return Err(field, absl::StrCat("byteLength (", length,
                                           ") exceeds the size of its data: URI"));
          }
        } else {
          absl::StatusOr<std::string> key = Resolve(field + ".uri", u);
          if (!key.ok()) return key.status();
          const size_t have = src_.files.at(*key).size();
          if (have != length) {
            return Err(field, absl::StrCat("byteLength (", length, ") does not match the size of '",
                                           Quote(*key), "' (", have, " bytes)"));
          }
        }
      }
      lengths->push_back(length);
    }
    return absl::OkStatus();
  }

  // tinygltf hands image bufferViews to the image loader without a range check.
  absl::Status ScanBufferViews(const json& j, const std::vector<uint64_t>& lengths) {
    const json* views = Member(j, "bufferViews");
    if (views == nullptr || !views->is_array()) return absl::OkStatus();
    for (size_t i = 0; i < views->size(); ++i) {
      const json& v = (*views)[i];
      const std::string field = absl::StrCat("bufferViews[", i, "]");
      uint64_t buffer = 0, offset = 0, length = 0;
      if (!JsonUint(Member(v, "buffer"), &buffer) || buffer >= lengths.size()) {
        return Err(field + ".buffer", absl::StrCat("missing or out of range (", lengths.size(),
                                                   " buffers)"));
      }
      if (Member(v, "byteOffset") && !JsonUint(Member(v, "byteOffset"), &offset)) {
        return Err(field + ".byteOffset", "not a non-negative integer");
      }
      if (!JsonUint(Member(v, "byteLength"), &length) || length == 0) {
        return Err(field + ".byteLength", "missing or not a positive integer");
      }
      const uint64_t have = lengths[buffer];
      if (offset > have || length > have - offset) {
        return Err(field, absl::StrCat("byteOffset + byteLength (",
                                       offset > UINT64_MAX - length ? std::string("overflow")
                                                                    : absl::StrCat(offset + length),
                                       ") exceeds buffers[", buffer, "].byteLength (", have, ")"));
      }
    }
    view_count_ = views->size();
    return absl::OkStatus();
  }

  // tinygltf rejects a bad indices accessor itself, but without saying where.
  absl::Status ScanMeshes(const json& j) {
    const json* accessors = Member(j, "accessors");
    const uint64_t count = accessors && accessors->is_array() ? accessors->size() : 0;
    const json* meshes = Member(j, "meshes");
    for (size_t m = 0; meshes && meshes->is_array() && m < meshes->size(); ++m) {
      const json* prims = Member((*meshes)[m], "primitives");
      for (size_t p = 0; prims && prims->is_array() && p < prims->size(); ++p) {
        uint64_t index = 0;
        const json* indices = Member((*prims)[p], "indices");
        if (indices && (!JsonUint(indices, &index) || index >= count)) {
          return Err(absl::StrCat("meshes[", m, "].primitives[", p, "].indices"),
                     absl::StrCat("accessor index ", indices->dump(), " out of range (", count,
                                  " accessors)"));
        }
      }
    }
    return absl::OkStatus();
  }

  absl::Status ScanImages(const json& j) {
    const json* images = Member(j, "images");
    const size_t count = images && images->is_array() ? images->size() : 0;
    for (size_t i = 0; i < count; ++i) {
      const json& im = (*images)[i];
      const std::string field = absl::StrCat("images[", i, "]");
      if (const json* uri = Member(im, "uri")) {
        if (!uri->is_string()) return Err(field + ".uri", "not a string");
        const std::string u = uri->get<std::string>();
        size_t payload = 0;
        if (u.rfind("data:", 0) == 0) {
          if (!IsTinygltfDataUri(u, &payload)) {
            return Err(field + ".uri", "unsupported data: URI media type");
          }
        } else if (absl::StatusOr<std::string> key = Resolve(field + ".uri", u); !key.ok()) {
          return key.status();
        }
      } else if (const json* bv = Member(im, "bufferView")) {
        uint64_t index = 0;
        if (!JsonUint(bv, &index) || index >= view_count_) {
          return Err(field + ".bufferView",
                     absl::StrCat("out of range (", view_count_, " bufferViews)"));
        }
      }
    }
    ctx_->image_needed.assign(count, false);
    if (const json* textures = Member(j, "textures"); textures && textures->is_array()) {
      for (const json& t : *textures) {
        uint64_t source = 0;
        if (JsonUint(Member(t, "source"), &source) && source < count) {
          ctx_->image_needed[source] = true;
        }
      }
    }
    return absl::OkStatus();
  }

  const GltfSource& src_;
  const GlbChunks* glb_;
  LoadContext* ctx_;
  std::vector<std::string>* warnings_;
  size_t view_count_ = 0;
};

// ---------------------------------------------------------------------------------------------
// Accessors.

struct AccessorView {
  const uint8_t* data = nullptr;
  uint64_t count = 0;
  uint64_t stride = 0;
  int component_type = 0;
  int type = 0;
  int components = 0;
  bool normalized = false;
  int index = 0;
};

float ReadComponent(const uint8_t* p, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: {
      float f;
      std::memcpy(&f, p, 4);
      return f;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return normalized ? p[0] / 255.0f : p[0];
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      const float v = static_cast<int8_t>(p[0]);
      return normalized ? std::max(v / 127.0f, -1.0f) : v;
    }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? v / 65535.0f : v;
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v;
      std::memcpy(&v, p, 2);
      return normalized ? std::max(v / 32767.0f, -1.0f) : v;
    }
    default: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return static_cast<float>(v);
    }
  }
}

glm::vec4 ReadVec(const AccessorView& a, uint64_t i) {
  glm::vec4 out(0.0f);
  const uint8_t* p = a.data + i * a.stride;
  const int size = tinygltf::GetComponentSizeInBytes(uint32_t(a.component_type));
  for (int c = 0; c < std::min(a.components, 4); ++c) {
    out[c] = ReadComponent(p + c * size, a.component_type, a.normalized);
  }
  return out;
}

uint32_t ReadIndex(const AccessorView& a, uint64_t i) {
  const uint8_t* p = a.data + i * a.stride;
  switch (a.component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return p[0];
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v;
      std::memcpy(&v, p, 2);
      return v;
    }
    default: {
      uint32_t v;
      std::memcpy(&v, p, 4);
      return v;
    }
  }
}

glm::vec3 AnyPerpendicular(const glm::vec3& n) {
  const glm::vec3 axis = std::abs(n.x) < 0.9f ? glm::vec3(1, 0, 0) : glm::vec3(0, 1, 0);
  return glm::normalize(axis - n * glm::dot(n, axis));
}

bool Finite(const glm::vec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

// Per-vertex tangents from UV derivatives (Lengyel), orthogonalized against the normal; w is
// the bitangent sign. Triangles are weighted by their area, which avoids dividing by tiny UV
// determinants.
void GenerateTangents(const std::vector<uint32_t>& tri, std::vector<Vertex>* verts) {
  std::vector<glm::vec3> tan(verts->size(), glm::vec3(0.0f)), bit(verts->size(), glm::vec3(0.0f));
  for (size_t t = 0; t + 2 < tri.size(); t += 3) {
    const Vertex &v0 = (*verts)[tri[t]], &v1 = (*verts)[tri[t + 1]], &v2 = (*verts)[tri[t + 2]];
    const glm::vec3 e1 = v1.position - v0.position, e2 = v2.position - v0.position;
    const glm::vec2 d1 = v1.uv0 - v0.uv0, d2 = v2.uv0 - v0.uv0;
    const float r = d1.x * d2.y - d2.x * d1.y;
    if (!(std::abs(r) > 1e-20f)) continue;
    const float s = r > 0.0f ? 1.0f : -1.0f;
    const glm::vec3 sdir = (e1 * d2.y - e2 * d1.y) * s, tdir = (e2 * d1.x - e1 * d2.x) * s;
    for (int k = 0; k < 3; ++k) {
      tan[tri[t + k]] += sdir;
      bit[tri[t + k]] += tdir;
    }
  }
  for (size_t i = 0; i < verts->size(); ++i) {
    Vertex& v = (*verts)[i];
    glm::vec3 t = tan[i] - v.normal * glm::dot(v.normal, tan[i]);
    const float len = glm::length(t);
    t = (len > 1e-12f && std::isfinite(len)) ? t / len : AnyPerpendicular(v.normal);
    v.tangent = glm::vec4(t, glm::dot(glm::cross(v.normal, t), bit[i]) < 0.0f ? -1.0f : 1.0f);
  }
}

// ---------------------------------------------------------------------------------------------
// Conversion of the parsed model.

class Converter {
 public:
  Converter(const std::string& file, const ImportLimits& limits, tinygltf::Model* model,
            CpuScene* scene)
      : file_(file), limits_(limits), m_(*model), s_(*scene) {
    max_vertices_ = std::min<uint64_t>(limits.max_vertices, UINT32_MAX);
    max_indices_ = std::min<uint64_t>(limits.max_indices, UINT32_MAX);
  }

  absl::Status Run();

 private:
  absl::Status Err(absl::string_view field, absl::string_view what) const {
    return absl::InvalidArgumentError(absl::StrCat(file_, ": ", field, ": ", what));
  }
  void Warn(std::string msg) {
    if (s_.warnings.size() < kMaxWarnings) s_.warnings.push_back(std::move(msg));
  }

  absl::StatusOr<AccessorView> View(int index, const std::string& use);
  absl::StatusOr<AccessorView> Attribute(const tinygltf::Primitive& p, const std::string& path,
                                         const char* name, int type, bool allow_unorm,
                                         uint64_t count, bool* present);
  absl::Status ConvertPrimitive(int mesh, int index, const tinygltf::Primitive& p,
                                std::vector<uint32_t>* out);
  absl::StatusOr<uint32_t> ConvertMesh(int mesh);
  absl::Status ConvertMaterial(int index);
  template <typename Info>
  absl::Status TextureSlot(const Info& info, bool srgb, const std::string& path, TextureRef* out);
  absl::StatusOr<int32_t> TextureFor(int texture, bool srgb);
  absl::StatusOr<glm::mat4> LocalMatrix(int node);
  absl::Status PlaceNode(int node, const glm::mat4& world);
  absl::Status CheckHierarchy();

  const std::string& file_;
  const ImportLimits& limits_;
  tinygltf::Model& m_;
  CpuScene& s_;
  uint64_t max_vertices_ = 0, max_indices_ = 0;
  int32_t default_material_ = -1;
  std::map<int, uint32_t> mesh_cache_;  // glTF mesh -> CpuScene::meshes
  std::map<std::pair<int, bool>, int32_t> texture_cache_;
  std::map<int, std::shared_ptr<const Image>> image_cache_;
};

absl::StatusOr<AccessorView> Converter::View(int index, const std::string& use) {
  if (index < 0 || size_t(index) >= m_.accessors.size()) {
    return Err(use, absl::StrCat("accessor index ", index, " out of range (", m_.accessors.size(),
                                 " accessors)"));
  }
  const tinygltf::Accessor& a = m_.accessors[index];
  const std::string field = absl::StrCat("accessors[", index, "]");
  if (a.sparse.isSparse) return Err(field, "sparse accessors are not supported");
  if (a.bufferView < 0 || size_t(a.bufferView) >= m_.bufferViews.size()) {
    return Err(field + ".bufferView", absl::StrCat("missing or out of range (",
                                                   m_.bufferViews.size(), " bufferViews)"));
  }
  const tinygltf::BufferView& bv = m_.bufferViews[a.bufferView];
  const std::string bv_field = absl::StrCat("bufferViews[", a.bufferView, "]");
  if (bv.buffer < 0 || size_t(bv.buffer) >= m_.buffers.size()) {
    return Err(bv_field + ".buffer", "out of range");
  }
  const size_t buffer_size = m_.buffers[bv.buffer].data.size();
  if (bv.byteOffset > buffer_size || bv.byteLength > buffer_size - bv.byteOffset) {
    return Err(bv_field, absl::StrCat("byteOffset + byteLength exceeds buffers[", bv.buffer,
                                      "] (", buffer_size, " bytes)"));
  }
  const int csize = tinygltf::GetComponentSizeInBytes(uint32_t(a.componentType));
  const int ncomp = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  if (csize <= 0) return Err(field + ".componentType", "invalid");
  if (ncomp <= 0) return Err(field + ".type", "invalid");
  const uint64_t elem = uint64_t(csize) * uint64_t(ncomp);
  const uint64_t stride = bv.byteStride ? bv.byteStride : elem;
  if (stride < elem) {
    return Err(bv_field + ".byteStride", absl::StrCat(stride, " is smaller than the element size ",
                                                      elem, " of ", field));
  }
  if (a.count > 0) {
    uint64_t span = 0, end = 0;
    const bool overflow = __builtin_mul_overflow(uint64_t(a.count - 1), stride, &span) ||
                          __builtin_add_overflow(span, elem, &end) ||
                          __builtin_add_overflow(end, uint64_t(a.byteOffset), &end);
    if (overflow || end > bv.byteLength) {
      return Err(field, absl::StrCat("byteOffset + count*stride (",
                                     overflow ? std::string("overflows 64 bits") : absl::StrCat(end),
                                     ") exceeds ", bv_field, ".byteLength (", bv.byteLength, ")"));
    }
  }
  AccessorView v;
  v.data = m_.buffers[bv.buffer].data.data() + bv.byteOffset + a.byteOffset;
  v.count = a.count;
  v.stride = stride;
  v.component_type = a.componentType;
  v.type = a.type;
  v.components = ncomp;
  v.normalized = a.normalized;
  v.index = index;
  return v;
}

absl::StatusOr<AccessorView> Converter::Attribute(const tinygltf::Primitive& p,
                                                  const std::string& path, const char* name,
                                                  int type, bool allow_unorm, uint64_t count,
                                                  bool* present) {
  auto it = p.attributes.find(name);
  *present = it != p.attributes.end();
  if (!*present) return AccessorView{};
  absl::StatusOr<AccessorView> v = View(it->second, absl::StrCat(path, ".attributes.", name));
  if (!v.ok()) return v.status();
  const bool unorm = v->normalized && (v->component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE ||
                                       v->component_type == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT);
  if (v->type != type || !(v->component_type == TINYGLTF_COMPONENT_TYPE_FLOAT ||
                           (allow_unorm && unorm))) {
    return Err(absl::StrCat("accessors[", v->index, "]"),
               absl::StrCat("unsupported type/componentType for ", name));
  }
  if (count != UINT64_MAX && v->count != count) {
    return Err(absl::StrCat("accessors[", v->index, "]"),
               absl::StrCat(name, " count ", v->count, " differs from POSITION count ", count));
  }
  return v;
}

absl::Status Converter::ConvertPrimitive(int mesh, int index, const tinygltf::Primitive& p,
                                         std::vector<uint32_t>* out) {
  const std::string path = absl::StrCat("meshes[", mesh, "].primitives[", index, "]");
  const int mode = p.mode < 0 ? TINYGLTF_MODE_TRIANGLES : p.mode;
  if (mode < TINYGLTF_MODE_TRIANGLES) {
    Warn(absl::StrCat(path, ": points/lines primitive (mode ", mode, ") skipped"));
    return absl::OkStatus();
  }
  if (mode > TINYGLTF_MODE_TRIANGLE_FAN) return Err(path + ".mode", absl::StrCat("invalid ", mode));
  bool has = false;
  absl::StatusOr<AccessorView> pos =
      Attribute(p, path, "POSITION", TINYGLTF_TYPE_VEC3, false, UINT64_MAX, &has);
  if (!pos.ok()) return pos.status();
  if (!has) return Err(path + ".attributes", "POSITION is required");
  const uint64_t n = pos->count;
  if (n > max_vertices_) return Err(path, absl::StrCat("vertex count ", n, " exceeds the limit"));

  std::vector<uint32_t> idx;
  if (p.indices >= 0) {
    absl::StatusOr<AccessorView> iv = View(p.indices, path + ".indices");
    if (!iv.ok()) return iv.status();
    const std::string field = absl::StrCat("accessors[", p.indices, "]");
    if (iv->type != TINYGLTF_TYPE_SCALAR || iv->component_type == TINYGLTF_COMPONENT_TYPE_FLOAT ||
        iv->component_type == TINYGLTF_COMPONENT_TYPE_BYTE ||
        iv->component_type == TINYGLTF_COMPONENT_TYPE_SHORT) {
      return Err(field, "indices must be unsigned byte/short/int scalars");
    }
    if (iv->count > max_indices_) return Err(field, "index count exceeds the limit");
    idx.resize(iv->count);
    for (uint64_t i = 0; i < iv->count; ++i) {
      idx[i] = ReadIndex(*iv, i);
      if (idx[i] >= n) {
        return Err(field, absl::StrCat("index value ", idx[i], " at position ", i,
                                       " is out of range (vertex count ", n, ")"));
      }
    }
  } else {
    if (n > max_indices_) return Err(path, "vertex count exceeds the index limit");
    idx.resize(n);
    for (uint64_t i = 0; i < n; ++i) idx[i] = uint32_t(i);
  }

  // Strips and fans become lists (glTF 2.0 spec, section 3.7.2.1 winding rules).
  std::vector<uint32_t> tri;
  if (mode == TINYGLTF_MODE_TRIANGLES) {
    if (idx.size() % 3 != 0) Warn(path + ": index count is not a multiple of 3; tail dropped");
    idx.resize(idx.size() - idx.size() % 3);
    tri = std::move(idx);
  } else if (idx.size() >= 3) {
    if ((idx.size() - 2) * 3 > max_indices_) return Err(path, "index count exceeds the limit");
    tri.reserve((idx.size() - 2) * 3);
    for (size_t i = 0; i + 2 < idx.size(); ++i) {
      if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        tri.insert(tri.end(), {idx[i], idx[i + 1 + i % 2], idx[i + 2 - i % 2]});
      } else {
        tri.insert(tri.end(), {idx[i + 1], idx[i + 2], idx[0]});
      }
    }
  }

  bool has_n = false, has_t = false, has_uv0 = false, has_uv1 = false;
  absl::StatusOr<AccessorView> nrm = Attribute(p, path, "NORMAL", TINYGLTF_TYPE_VEC3, false, n, &has_n);
  if (!nrm.ok()) return nrm.status();
  absl::StatusOr<AccessorView> tng = Attribute(p, path, "TANGENT", TINYGLTF_TYPE_VEC4, false, n, &has_t);
  if (!tng.ok()) return tng.status();
  absl::StatusOr<AccessorView> uv0 = Attribute(p, path, "TEXCOORD_0", TINYGLTF_TYPE_VEC2, true, n, &has_uv0);
  if (!uv0.ok()) return uv0.status();
  absl::StatusOr<AccessorView> uv1 = Attribute(p, path, "TEXCOORD_1", TINYGLTF_TYPE_VEC2, true, n, &has_uv1);
  if (!uv1.ok()) return uv1.status();

  const uint64_t out_vertices = has_n ? n : tri.size();  // no normals: one vertex per corner
  if (s_.vertices.size() + out_vertices > max_vertices_ ||
      s_.indices.size() + tri.size() > max_indices_) {
    return Err(path, "the scene exceeds the vertex or index limit");
  }
  std::vector<Vertex> verts(n);
  for (uint64_t i = 0; i < n; ++i) {
    Vertex& v = verts[i];
    v.position = glm::vec3(ReadVec(*pos, i));
    if (!Finite(v.position)) {
      return Err(absl::StrCat("accessors[", pos->index, "]"), "non-finite POSITION value");
    }
    if (has_n) v.normal = glm::vec3(ReadVec(*nrm, i));
    if (has_t) v.tangent = ReadVec(*tng, i);
    auto uv = [](glm::vec2 u) { return std::isfinite(u.x) && std::isfinite(u.y) ? u : glm::vec2(0); };
    if (has_uv0) v.uv0 = uv(glm::vec2(ReadVec(*uv0, i)));
    if (has_uv1) v.uv1 = uv(glm::vec2(ReadVec(*uv1, i)));
  }
  if (!has_n) {
    // Flat shading: every triangle gets its own three vertices carrying the face normal.
    std::vector<Vertex> flat(tri.size());
    for (size_t t = 0; t < tri.size(); t += 3) {
      glm::vec3 fn = glm::cross(verts[tri[t + 1]].position - verts[tri[t]].position,
                                verts[tri[t + 2]].position - verts[tri[t]].position);
      const float len = glm::length(fn);
      fn = (len > 0.0f && std::isfinite(len)) ? fn / len : glm::vec3(0, 0, 1);
      for (int k = 0; k < 3; ++k) {
        flat[t + k] = verts[tri[t + k]];
        flat[t + k].normal = fn;
        tri[t + k] = uint32_t(t + k);
      }
    }
    verts = std::move(flat);
  }
  for (Vertex& v : verts) {
    const float len = glm::length(v.normal);
    v.normal = (len > 1e-20f && std::isfinite(len)) ? v.normal / len : glm::vec3(0, 0, 1);
    if (has_t) {
      glm::vec3 t(v.tangent);
      const float tl = glm::length(t);
      t = (tl > 1e-20f && std::isfinite(tl)) ? t / tl : AnyPerpendicular(v.normal);
      v.tangent = glm::vec4(t, v.tangent.w < 0.0f ? -1.0f : 1.0f);
    }
  }
  if (!has_t) GenerateTangents(tri, &verts);

  Primitive prim;
  prim.first_index = uint32_t(s_.indices.size());
  prim.index_count = uint32_t(tri.size());
  prim.first_vertex = uint32_t(s_.vertices.size());
  prim.vertex_count = uint32_t(verts.size());
  for (const Vertex& v : verts) prim.bounds.extend(v.position);
  if (p.material >= 0) {
    if (size_t(p.material) >= m_.materials.size()) {
      return Err(path + ".material", absl::StrCat("material index ", p.material,
                                                  " out of range (", m_.materials.size(), ")"));
    }
    prim.material = uint32_t(p.material);
  } else {
    if (default_material_ < 0) {
      default_material_ = int32_t(s_.materials.size());
      Material def;
      def.name = "default";
      s_.materials.push_back(def);
    }
    prim.material = uint32_t(default_material_);
  }
  s_.vertices.insert(s_.vertices.end(), verts.begin(), verts.end());
  s_.indices.insert(s_.indices.end(), tri.begin(), tri.end());
  out->push_back(uint32_t(s_.primitives.size()));
  s_.primitives.push_back(prim);
  return absl::OkStatus();
}

absl::StatusOr<uint32_t> Converter::ConvertMesh(int mesh) {
  if (auto it = mesh_cache_.find(mesh); it != mesh_cache_.end()) return it->second;
  const tinygltf::Mesh& gm = m_.meshes[mesh];
  Mesh out;
  out.name = gm.name;
  for (size_t i = 0; i < gm.primitives.size(); ++i) {
    if (absl::Status st = ConvertPrimitive(mesh, int(i), gm.primitives[i], &out.primitives);
        !st.ok()) {
      return st;
    }
  }
  const uint32_t index = uint32_t(s_.meshes.size());
  s_.meshes.push_back(std::move(out));
  mesh_cache_[mesh] = index;
  return index;
}

absl::StatusOr<int32_t> Converter::TextureFor(int texture, bool srgb) {
  if (auto it = texture_cache_.find({texture, srgb}); it != texture_cache_.end()) return it->second;
  const tinygltf::Texture& gt = m_.textures[texture];
  const std::string field = absl::StrCat("textures[", texture, "]");
  int32_t result = -1;
  if (gt.source < 0) {
    Warn(field + ": no image source (extension-only sources are not supported); slot left empty");
  } else if (size_t(gt.source) >= m_.images.size()) {
    return Err(field + ".source", absl::StrCat("image index ", gt.source, " out of range (",
                                               m_.images.size(), " images)"));
  } else if (gt.sampler >= 0 && size_t(gt.sampler) >= m_.samplers.size()) {
    return Err(field + ".sampler", absl::StrCat("sampler index ", gt.sampler, " out of range"));
  } else {
    std::shared_ptr<const Image>& image = image_cache_[gt.source];
    if (image == nullptr) {
      tinygltf::Image& gi = m_.images[gt.source];
      if (gi.width > 0 && gi.height > 0 && gi.component == 4 && gi.bits == 8 &&
          gi.image.size() == size_t(gi.width) * size_t(gi.height) * 4) {
        auto img = std::make_shared<Image>();
        img->name = gi.name.empty() ? gi.uri : gi.name;
        if (img->name.empty()) img->name = absl::StrCat("images[", gt.source, "]");
        img->width = uint32_t(gi.width);
        img->height = uint32_t(gi.height);
        img->rgba8 = std::move(gi.image);
        image = std::move(img);
      }
    }
    if (image == nullptr) {
      Warn(absl::StrCat(field, ": images[", gt.source, "] has no pixels; slot left empty"));
    } else {
      Texture t;
      t.image = image;
      t.srgb = srgb;
      if (gt.sampler >= 0) {
        const tinygltf::Sampler& sm = m_.samplers[gt.sampler];
        auto wrap = [&](int w) {
          if (w == TINYGLTF_TEXTURE_WRAP_CLAMP_TO_EDGE) return WrapMode::kClampToEdge;
          if (w == TINYGLTF_TEXTURE_WRAP_MIRRORED_REPEAT) return WrapMode::kMirroredRepeat;
          if (w != TINYGLTF_TEXTURE_WRAP_REPEAT) {
            Warn(absl::StrCat("samplers[", gt.sampler, "]: unknown wrap mode ", w));
          }
          return WrapMode::kRepeat;
        };
        t.wrap_s = wrap(sm.wrapS);
        t.wrap_t = wrap(sm.wrapT);
      }
      result = int32_t(s_.textures.size());
      s_.textures.push_back(std::move(t));
    }
  }
  texture_cache_[{texture, srgb}] = result;
  return result;
}

double NumberOr(const tinygltf::Value& obj, const char* key, double fallback) {
  if (!obj.IsObject() || !obj.Has(key) || !obj.Get(key).IsNumber()) return fallback;
  return obj.Get(key).GetNumberAsDouble();
}

bool Numbers(const tinygltf::Value& obj, const char* key, int n, float* out) {
  if (!obj.IsObject() || !obj.Has(key)) return false;
  const tinygltf::Value& a = obj.Get(key);
  if (!a.IsArray() || a.ArrayLen() != size_t(n)) return false;
  for (int i = 0; i < n; ++i) {
    if (!a.Get(i).IsNumber()) return false;
  }
  for (int i = 0; i < n; ++i) out[i] = ToFloat(a.Get(i).GetNumberAsDouble());
  return true;
}

template <typename Info>
absl::Status Converter::TextureSlot(const Info& info, bool srgb, const std::string& path,
                                    TextureRef* out) {
  if (info.index < 0) return absl::OkStatus();
  if (size_t(info.index) >= m_.textures.size()) {
    return Err(path + ".index", absl::StrCat("texture index ", info.index, " out of range (",
                                             m_.textures.size(), " textures)"));
  }
  auto texcoord = [&](double tc) -> uint32_t {
    if (tc == 0.0 || tc == 1.0) return uint32_t(tc);
    Warn(absl::StrCat(path, ": texCoord ", tc, " is not supported; using 0"));
    return 0;
  };
  out->texcoord = texcoord(info.texCoord);
  if (auto it = info.extensions.find("KHR_texture_transform"); it != info.extensions.end()) {
    const tinygltf::Value& x = it->second;
    Numbers(x, "offset", 2, &out->offset.x);
    Numbers(x, "scale", 2, &out->scale.x);
    out->rotation = ToFloat(NumberOr(x, "rotation", 0.0));
    if (x.IsObject() && x.Has("texCoord")) out->texcoord = texcoord(NumberOr(x, "texCoord", 0.0));
  }
  absl::StatusOr<int32_t> t = TextureFor(info.index, srgb);
  if (!t.ok()) return t.status();
  out->texture = *t;
  return absl::OkStatus();
}

absl::Status Converter::ConvertMaterial(int index) {
  const tinygltf::Material& gm = m_.materials[index];
  const std::string path = absl::StrCat("materials[", index, "]");
  const tinygltf::PbrMetallicRoughness& pbr = gm.pbrMetallicRoughness;
  Material m;
  m.name = gm.name;
  if (pbr.baseColorFactor.size() == 4) {
    for (int i = 0; i < 4; ++i) m.base_color_factor[i] = ToFloat(pbr.baseColorFactor[i]);
  }
  m.metallic_factor = std::clamp(ToFloat(pbr.metallicFactor), 0.0f, 1.0f);
  m.roughness_factor = std::clamp(ToFloat(pbr.roughnessFactor), 0.0f, 1.0f);
  if (gm.emissiveFactor.size() == 3) {
    for (int i = 0; i < 3; ++i) m.emissive_factor[i] = ToFloat(gm.emissiveFactor[i]);
  }
  if (auto it = gm.extensions.find("KHR_materials_emissive_strength"); it != gm.extensions.end()) {
    m.emissive_strength = std::max(0.0f, ToFloat(NumberOr(it->second, "emissiveStrength", 1.0)));
  }
  m.normal_scale = ToFloat(gm.normalTexture.scale);
  m.occlusion_strength = std::clamp(ToFloat(gm.occlusionTexture.strength), 0.0f, 1.0f);
  if (gm.alphaMode == "MASK") {
    m.alpha_mode = AlphaMode::kMask;
  } else if (gm.alphaMode == "BLEND") {
    m.alpha_mode = AlphaMode::kBlend;
  } else if (gm.alphaMode != "OPAQUE") {
    Warn(absl::StrCat(path, ".alphaMode: unknown '", Quote(gm.alphaMode), "'; using OPAQUE"));
  }
  m.alpha_cutoff = std::max(0.0f, ToFloat(gm.alphaCutoff));
  m.double_sided = gm.doubleSided;
  absl::Status st = TextureSlot(pbr.baseColorTexture, true,
                                path + ".pbrMetallicRoughness.baseColorTexture", &m.base_color);
  if (st.ok()) {
    st = TextureSlot(pbr.metallicRoughnessTexture, false,
                     path + ".pbrMetallicRoughness.metallicRoughnessTexture", &m.metallic_roughness);
  }
  if (st.ok()) st = TextureSlot(gm.normalTexture, false, path + ".normalTexture", &m.normal);
  if (st.ok()) st = TextureSlot(gm.occlusionTexture, false, path + ".occlusionTexture", &m.occlusion);
  if (st.ok()) st = TextureSlot(gm.emissiveTexture, true, path + ".emissiveTexture", &m.emissive);
  if (!st.ok()) return st;
  s_.materials.push_back(std::move(m));
  return absl::OkStatus();
}

absl::StatusOr<glm::mat4> Converter::LocalMatrix(int index) {
  const tinygltf::Node& n = m_.nodes[index];
  const std::string path = absl::StrCat("nodes[", index, "]");
  glm::mat4 local(1.0f);
  if (!n.matrix.empty()) {
    if (n.matrix.size() != 16) return Err(path + ".matrix", "expected 16 numbers");
    for (int i = 0; i < 16; ++i) glm::value_ptr(local)[i] = ToFloat(n.matrix[i]);
    return local;
  }
  if (!n.translation.empty() && n.translation.size() != 3) {
    return Err(path + ".translation", "expected 3 numbers");
  }
  if (!n.rotation.empty() && n.rotation.size() != 4) return Err(path + ".rotation", "expected 4 numbers");
  if (!n.scale.empty() && n.scale.size() != 3) return Err(path + ".scale", "expected 3 numbers");
  glm::vec3 t(0.0f), sc(1.0f);
  glm::quat q(1.0f, 0.0f, 0.0f, 0.0f);
  for (size_t i = 0; i < n.translation.size(); ++i) t[int(i)] = ToFloat(n.translation[i]);
  for (size_t i = 0; i < n.scale.size(); ++i) sc[int(i)] = ToFloat(n.scale[i]);
  if (n.rotation.size() == 4) {
    glm::quat r(ToFloat(n.rotation[3]), ToFloat(n.rotation[0]), ToFloat(n.rotation[1]),
                ToFloat(n.rotation[2]));
    const float len = glm::length(r);
    if (len > 1e-12f && std::isfinite(len)) q = r / len;
  }
  return glm::translate(glm::mat4(1.0f), t) * glm::mat4_cast(q) * glm::scale(glm::mat4(1.0f), sc);
}

// glTF requires disjoint strict trees; anything else could loop or explode combinatorially.
absl::Status Converter::CheckHierarchy() {
  const size_t count = m_.nodes.size();
  std::vector<int> parent(count, -1);
  for (size_t i = 0; i < count; ++i) {
    for (int c : m_.nodes[i].children) {
      if (c < 0 || size_t(c) >= count) {
        return Err(absl::StrCat("nodes[", i, "].children"),
                   absl::StrCat("node index ", c, " out of range (", count, " nodes)"));
      }
      if (size_t(c) == i) return Err(absl::StrCat("nodes[", i, "]"), "node hierarchy cycle (node is its own child)");
      if (parent[c] >= 0) {
        return Err(absl::StrCat("nodes[", c, "]"), absl::StrCat("node has more than one parent (nodes[",
                                                               parent[c], "] and nodes[", i, "])"));
      }
      parent[c] = int(i);
    }
  }
  // With one parent each, a node is in a cycle exactly when its parent chain never ends.
  std::vector<uint8_t> state(count, 0);  // 0 unknown, 1 on the current walk, 2 reaches a root
  std::vector<int> walk;
  for (size_t i = 0; i < count; ++i) {
    walk.clear();
    int n = int(i);
    while (n >= 0 && state[n] == 0) {
      state[n] = 1;
      walk.push_back(n);
      n = parent[n];
    }
    if (n >= 0 && state[n] == 1) {
      return Err(absl::StrCat("nodes[", n, "]"), "node hierarchy contains a cycle");
    }
    for (int w : walk) state[w] = 2;
  }
  return absl::OkStatus();
}

absl::Status Converter::PlaceNode(int index, const glm::mat4& world) {
  const tinygltf::Node& n = m_.nodes[index];
  const std::string path = absl::StrCat("nodes[", index, "]");
  for (int c = 0; c < 4; ++c) {
    if (!Finite(glm::vec3(world[c])) || !std::isfinite(world[c][3])) {
      return Err(path, "world transform is not finite");
    }
  }
  if (n.mesh >= 0) {
    if (size_t(n.mesh) >= m_.meshes.size()) {
      return Err(path + ".mesh", absl::StrCat("mesh index ", n.mesh, " out of range (",
                                              m_.meshes.size(), " meshes)"));
    }
    absl::StatusOr<uint32_t> mesh = ConvertMesh(n.mesh);
    if (!mesh.ok()) return mesh.status();
    for (uint32_t prim : s_.meshes[*mesh].primitives) {
      if (s_.drawables.size() >= limits_.max_drawables) {
        return Err(path, absl::StrCat("more than ", limits_.max_drawables, " drawables"));
      }
      Drawable d;
      d.world = world;
      d.primitive = prim;
      d.mesh = *mesh;
      d.node = uint32_t(index);
      d.world_bounds = s_.primitives[prim].bounds.transformed(world);
      s_.bounds.extend(d.world_bounds);
      s_.counts.triangles += s_.primitives[prim].index_count / 3;
      s_.drawables.push_back(d);
    }
  }
  if (n.camera >= 0) {
    if (size_t(n.camera) >= m_.cameras.size()) return Err(path + ".camera", "camera index out of range");
    const tinygltf::Camera& gc = m_.cameras[n.camera];
    if (gc.type == "perspective") {
      const tinygltf::PerspectiveCamera& p = gc.perspective;
      SceneCamera cam;
      cam.name = gc.name;
      cam.world = world;
      if (p.yfov > 0.0 && p.yfov < 3.14159) cam.yfov = ToFloat(p.yfov);
      if (p.aspectRatio > 0.0) cam.aspect = ToFloat(p.aspectRatio);
      if (p.znear > 0.0) cam.znear = ToFloat(p.znear);
      if (p.zfar > p.znear) cam.zfar = ToFloat(p.zfar);
      s_.cameras.push_back(cam);
    } else {
      Warn(absl::StrCat(path, ": camera type '", Quote(gc.type), "' is not supported; skipped"));
    }
  }
  if (auto it = n.extensions.find("KHR_lights_punctual"); it != n.extensions.end()) {
    const double li = NumberOr(it->second, "light", -1.0);
    if (!(li >= 0.0 && li < double(m_.lights.size()))) {
      return Err(path + ".extensions.KHR_lights_punctual.light",
                 absl::StrCat("light index out of range (", m_.lights.size(), " lights)"));
    }
    const tinygltf::Light& gl = m_.lights[size_t(li)];
    Light l;
    l.name = gl.name;
    if (gl.type == "directional") {
      l.type = LightType::kDirectional;
    } else if (gl.type == "spot") {
      l.type = LightType::kSpot;
    } else if (gl.type != "point") {
      Warn(absl::StrCat(path, ": light type '", Quote(gl.type), "' is not supported; skipped"));
      return absl::OkStatus();
    }
    if (gl.color.size() == 3) l.color = glm::vec3(ToFloat(gl.color[0]), ToFloat(gl.color[1]), ToFloat(gl.color[2]));
    l.intensity = std::max(0.0f, ToFloat(gl.intensity));
    l.range = std::max(0.0f, ToFloat(gl.range));
    l.inner_cone_angle = std::max(0.0f, ToFloat(gl.spot.innerConeAngle));
    l.outer_cone_angle = std::max(l.inner_cone_angle, ToFloat(gl.spot.outerConeAngle));
    l.position = glm::vec3(world[3]);
    const glm::vec3 dir = glm::mat3(world) * glm::vec3(0, 0, -1);
    const float len = glm::length(dir);
    l.direction = (len > 1e-20f && std::isfinite(len)) ? dir / len : glm::vec3(0, 0, -1);
    s_.lights.push_back(l);
  }
  return absl::OkStatus();
}

absl::Status Converter::Run() {
  s_.counts.nodes = uint32_t(m_.nodes.size());
  s_.counts.meshes = uint32_t(m_.meshes.size());
  for (const tinygltf::Mesh& mesh : m_.meshes) s_.counts.primitives += uint32_t(mesh.primitives.size());
  s_.counts.materials = uint32_t(m_.materials.size());
  s_.counts.textures = uint32_t(m_.textures.size());
  s_.counts.images = uint32_t(m_.images.size());
  for (size_t i = 0; i < m_.materials.size(); ++i) {
    if (absl::Status st = ConvertMaterial(int(i)); !st.ok()) return st;
  }
  if (absl::Status st = CheckHierarchy(); !st.ok()) return st;

  std::vector<int> roots;
  if (m_.defaultScene >= 0 && size_t(m_.defaultScene) >= m_.scenes.size()) {
    return Err("scene", absl::StrCat("scene index ", m_.defaultScene, " out of range (",
                                     m_.scenes.size(), " scenes)"));
  }
  if (!m_.scenes.empty()) {
    const int scene = m_.defaultScene >= 0 ? m_.defaultScene : 0;
    roots = m_.scenes[scene].nodes;
    for (int r : roots) {
      if (r < 0 || size_t(r) >= m_.nodes.size()) {
        return Err(absl::StrCat("scenes[", scene, "].nodes"),
                   absl::StrCat("node index ", r, " out of range (", m_.nodes.size(), " nodes)"));
      }
    }
  } else {
    std::vector<bool> is_child(m_.nodes.size(), false);
    for (const tinygltf::Node& n : m_.nodes) {
      for (int c : n.children) is_child[c] = true;  // range-checked by CheckHierarchy
    }
    for (size_t i = 0; i < m_.nodes.size(); ++i) {
      if (!is_child[i]) roots.push_back(int(i));
    }
  }
  // Iterative traversal: the hierarchy is acyclic (checked), and depth cannot blow the stack.
  std::vector<std::pair<int, glm::mat4>> stack;
  for (auto r = roots.rbegin(); r != roots.rend(); ++r) stack.emplace_back(*r, glm::mat4(1.0f));
  while (!stack.empty()) {
    auto [node, parent_world] = stack.back();
    stack.pop_back();
    absl::StatusOr<glm::mat4> local = LocalMatrix(node);
    if (!local.ok()) return local.status();
    const glm::mat4 world = parent_world * *local;
    if (absl::Status st = PlaceNode(node, world); !st.ok()) return st;
    const std::vector<int>& children = m_.nodes[node].children;
    for (auto c = children.rbegin(); c != children.rend(); ++c) stack.emplace_back(*c, world);
  }
  s_.counts.lights = uint32_t(s_.lights.size());
  s_.counts.cameras = uint32_t(s_.cameras.size());
  return absl::OkStatus();
}

void AddTinygltfWarnings(const std::string& text, std::vector<std::string>* warnings) {
  size_t start = 0;
  while (start < text.size() && warnings->size() < kMaxWarnings) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    if (end > start) warnings->push_back(absl::StrCat("tinygltf: ", Quote(text.substr(start, end - start))));
    start = end + 1;
  }
}

}  // namespace

absl::StatusOr<CpuScene> ImportGltf(const GltfSource& source, const ImportLimits& limits) {
  const std::string& file = source.main_file;
  auto main = source.files.find(file);
  if (main == source.files.end()) {
    return absl::InvalidArgumentError(absl::StrCat(Quote(file), ": main file is not in the file set"));
  }
  const std::vector<uint8_t>& bytes = main->second;
  if (bytes.empty()) return absl::InvalidArgumentError(absl::StrCat(file, ": file is empty"));
  const bool is_glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  GlbChunks glb;
  absl::string_view text;
  if (is_glb) {
    if (absl::Status st = ParseGlb(file, bytes, &glb); !st.ok()) return st;
    text = glb.json;
  } else {
    if (bytes.size() > std::numeric_limits<uint32_t>::max()) {
      return absl::InvalidArgumentError(absl::StrCat(file, ": file is 4 GiB or larger"));
    }
    text = absl::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  }
  if (JsonTooDeep(text)) {
    return absl::InvalidArgumentError(
        absl::StrCat(file, ": JSON: nesting deeper than ", kMaxJsonDepth, " levels"));
  }
  CpuScene scene;
  scene.name = file;
  LoadContext ctx;
  ctx.source = &source;
  ctx.limits = &limits;
  try {
    const json j = json::parse(text.begin(), text.end());
    PreScanner scanner(source, is_glb ? &glb : nullptr, &ctx, &scene.warnings);
    if (absl::Status st = scanner.Run(j); !st.ok()) return st;
  } catch (const std::exception& e) {
    return absl::InvalidArgumentError(absl::StrCat(file, ": JSON: ", Quote(e.what())));
  }

  tinygltf::TinyGLTF loader;
  loader.SetFsCallbacks({&FsFileExists, &FsExpandFilePath, &FsReadWholeFile, &FsWriteWholeFile, &ctx});
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
  if (!ctx.error.empty()) return absl::InvalidArgumentError(ctx.error);
  if (!ok) {
    std::string what = err.empty() ? "cannot parse" : err;
    while (!what.empty() && what.back() == '\n') what.pop_back();
    return absl::InvalidArgumentError(absl::StrCat(file, ": tinygltf: ", Quote(what)));
  }
  AddTinygltfWarnings(warn, &scene.warnings);
  try {
    Converter converter(file, limits, &model, &scene);
    if (absl::Status st = converter.Run(); !st.ok()) return st;
  } catch (const std::bad_alloc&) {
    return absl::InvalidArgumentError(absl::StrCat(file, ": too large to import (out of memory)"));
  }
  if (scene.warnings.size() >= kMaxWarnings) scene.warnings.push_back("further warnings omitted");
  return scene;
}

}  // namespace tessera

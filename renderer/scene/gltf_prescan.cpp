// Pre-scan of a glTF asset before tinygltf sees it (see gltf_prescan.h): the input comes from
// the network, so the GLB container, the JSON nesting depth, URIs, buffer and bufferView ranges
// and required extensions are checked here, and the file-set aliases tinygltf will ask for and
// the images that need decoding are worked out.
#include "renderer/scene/gltf_prescan.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "common/status_macros.h"

namespace tessera::gltf_internal {
namespace {

using nlohmann::json;

constexpr size_t kMaxQuoted = 120;  // longest string quoted in a message

bool IsSupportedExtension(const std::string& name) {
  const std::vector<std::string_view>& all = SupportedGltfExtensions();
  return std::find(all.begin(), all.end(), name) != all.end();
}

int HexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

// RFC 3986 %-decoding, the way keys of GltfSource::files are written. With `like_tinygltf`
// it decodes the way tinygltf does before calling the file callbacks ('+' is a space, bad hex
// digits count as 0), so that spelling can be mapped back to the real key.
std::string PercentDecode(absl::string_view s, bool like_tinygltf = false) {
  std::string out;
  for (size_t i = 0; i < s.size(); ++i) {
    const bool hex = i + 2 < s.size() && HexValue(s[i + 1]) >= 0 && HexValue(s[i + 2]) >= 0;
    if (like_tinygltf && s[i] == '+') {
      out += ' ';
    } else if (s[i] == '%' && (hex || (like_tinygltf && i + 2 < s.size()))) {
      out +=
          static_cast<char>(std::max(HexValue(s[i + 1]), 0) * 16 + std::max(HexValue(s[i + 2]), 0));
      i += 2;
    } else {
      out += s[i];
    }
  }
  return out;
}

// The data: URI media types tinygltf 2.7 decodes; anything else it would treat as a file name.
bool IsTinygltfDataUri(absl::string_view uri, size_t* payload) {
  for (absl::string_view p :
       {"data:application/octet-stream;base64,", "data:application/gltf-buffer;base64,",
        "data:image/jpeg;base64,", "data:image/png;base64,", "data:image/bmp;base64,",
        "data:image/gif;base64,", "data:text/plain;base64,"}) {
    if (uri.substr(0, p.size()) == p) {
      *payload = uri.size() - p.size();
      return true;
    }
  }
  return false;
}

uint32_t ReadU32(const uint8_t* p) {
  return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24;
}

struct GlbChunks {
  absl::string_view json;
  const uint8_t* bin = nullptr;
  size_t bin_size = 0;
};

// Checks the GLB container ourselves: tinygltf only says "Invalid glTF binary".
absl::Status ParseGlb(const std::string& file, const std::vector<uint8_t>& d, GlbChunks* out) {
  if (d.size() < 20) return Invalid(file, "GLB", "file is truncated (", d.size(), " bytes)");
  if (d.size() > std::numeric_limits<uint32_t>::max()) return Invalid(file, "GLB", "4 GiB+");
  const uint32_t version = ReadU32(&d[4]), length = ReadU32(&d[8]);
  if (version != 2) return Invalid(file, "GLB", "version ", version, " is not supported");
  if (length > d.size()) {
    return Invalid(file, "GLB", "file is truncated: header declares ", length,
                   " bytes but the file has ", d.size());
  }
  const uint64_t json_len = ReadU32(&d[12]);
  if (ReadU32(&d[16]) != 0x4E4F534Au) return Invalid(file, "GLB", "first chunk is not JSON");
  if (20 + json_len > length) {
    return Invalid(file, "GLB", "file is truncated: JSON chunk of ", json_len,
                   " bytes exceeds the length ", length);
  }
  out->json = absl::string_view(reinterpret_cast<const char*>(&d[20]), json_len);
  const uint64_t bin_at = 20 + json_len;
  if (bin_at + 8 <= length && ReadU32(&d[bin_at + 4]) == 0x004E4942u) {
    const uint64_t bin_len = ReadU32(&d[bin_at]);
    if (bin_at + 8 + bin_len > length) {
      return Invalid(file, "GLB", "file is truncated: BIN chunk of ", bin_len,
                     " bytes exceeds the length ", length);
    }
    out->bin = &d[bin_at + 8];
    out->bin_size = bin_len;
  }
  return absl::OkStatus();
}

// One pass over the JSON text before any parser: how deep it nests (tinygltf recurses over
// arrays and objects in extras, so a deep document would overflow the stack) and about how many
// values it holds (every value but the first follows a ',' or opens an array or object), which
// bounds what nlohmann and tinygltf build from it.
struct JsonShape {
  uint32_t depth = 0;
  uint64_t values = 0;
};
JsonShape ScanJson(absl::string_view text, uint32_t max_depth) {
  JsonShape shape;
  uint32_t depth = 0;
  bool in_string = false;
  for (size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (in_string) {
      if (c == '\\') ++i;
      if (c == '"') in_string = false;
    } else if (c == '"') {
      in_string = true;
    } else if (c == '[' || c == '{') {
      ++shape.values;
      shape.depth = std::max(shape.depth, ++depth);
      if (depth > max_depth) return shape;  // refused anyway; stop counting
    } else if (c == ',') {
      ++shape.values;
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return shape;
}

// ---------------------------------------------------------------------------------------------
// Pre-scan of the JSON for what tinygltf would otherwise trust or resolve by itself.

const json* Member(const json& o, const char* key) {
  if (!o.is_object()) return nullptr;
  const auto it = o.find(key);
  return it == o.end() ? nullptr : &*it;
}

const json* Member(const json* o, const char* key) { return o ? Member(*o, key) : nullptr; }

size_t ArraySize(const json& o, const char* key) {
  const json* a = Member(o, key);
  return a != nullptr && a->is_array() ? a->size() : 0;
}

// A float that is an integer a double holds exactly (|x| <= 2^53): 0.0, 5126.0, 1e15.
bool WholeNumber(double x) { return std::floor(x) == x && std::abs(x) <= 9007199254740992.0; }

bool JsonUint(const json* v, uint64_t* out) {
  if (v == nullptr || !v->is_number_integer()) return false;  // is_number_integer: any sign
  if (v->is_number_unsigned()) {
    *out = v->get<uint64_t>();
    return true;
  }
  *out = uint64_t(v->get<int64_t>());
  return v->get<int64_t>() >= 0;
}

class PreScan {
 public:
  PreScan(const GltfSource& src, const GlbChunks* glb, const ImportLimits& limits,
          PreScanResult* result)
      : file_(src.main_file),
        src_(src),
        glb_(glb),
        limits_(limits),
        result_(result),
        file_set_bytes_(FileSetBytes(src)) {}

  absl::Status Run(json& j) {
    if (!j.is_object()) return Invalid(file_, "JSON", "the top level is not an object");
    RETURN_IF_ERROR(Asset(j));
    RETURN_IF_ERROR(Counts(j));
    RETURN_IF_ERROR(IntegerFields(j));
    RETURN_IF_ERROR(Accessors(j));
    RETURN_IF_ERROR(ValueRanges(j));
    for (const char* list : {"extensionsRequired", "extensionsUsed"}) {
      const json* exts = Member(j, list);
      for (size_t i = 0; exts && exts->is_array() && i < exts->size(); ++i) {
        const std::string name = (*exts)[i].is_string() ? (*exts)[i].get<std::string>() : "?";
        if (IsSupportedExtension(name)) continue;
        if (std::strcmp(list, "extensionsRequired") == 0) {
          return Invalid(file_, list, "unsupported required extension ", Quote(name));
        }
        result_->warnings.push_back(absl::StrCat("extension ", Quote(name), " is not supported"));
      }
    }
    RETURN_IF_ERROR(DeclaredExtensions(j, j, ""));
    RETURN_IF_ERROR(Instancing(j));
    RETURN_IF_ERROR(Structure(j));
    meshopt_ = Lists(j, "extensionsUsed", "EXT_meshopt_compression");
    if (Lists(j, "extensionsUsed", "KHR_draco_mesh_compression")) DracoIndices(j);
    RETURN_IF_ERROR(Buffers(j));
    RETURN_IF_ERROR(BufferViews(j));
    RETURN_IF_ERROR(Images(j));
    // tinygltf rejects a bad indices accessor itself, but without saying where.
    const size_t accessors = ArraySize(j, "accessors");
    for (size_t m = 0; m < ArraySize(j, "meshes"); ++m) {
      const json* prims = Member(j["meshes"][m], "primitives");
      for (size_t p = 0; prims && prims->is_array() && p < prims->size(); ++p) {
        uint64_t index = 0;
        const json* indices = Member((*prims)[p], "indices");
        if (indices && (!JsonUint(indices, &index) || index >= accessors)) {
          return Invalid(file_, absl::StrCat("meshes[", m, "].primitives[", p, "].indices"),
                         "accessor index ", Quote(indices->dump()), " out of range (", accessors,
                         " accessors)");
        }
      }
    }
    return absl::OkStatus();
  }

 private:
  // The counts tinygltf would allocate for, before it parses anything.
  absl::Status Counts(const json& j) {
    auto check = [&](const char* field, uint64_t count, const char* what, const char* limit,
                     uint64_t max) {
      if (count <= max) return absl::OkStatus();
      return OverLimit(file_, field, count, " ", what, " exceed the ", limit, " limit (", max, ")");
    };
    RETURN_IF_ERROR(check("nodes", ArraySize(j, "nodes"), "nodes", "max_nodes", limits_.max_nodes));
    RETURN_IF_ERROR(
        check("meshes", ArraySize(j, "meshes"), "meshes", "max_meshes", limits_.max_meshes));
    RETURN_IF_ERROR(check("textures", ArraySize(j, "textures"), "textures", "max_textures",
                          limits_.max_textures));
    RETURN_IF_ERROR(check("materials", ArraySize(j, "materials"), "materials", "max_materials",
                          limits_.max_materials));
    uint64_t primitives = 0;
    for (size_t m = 0; m < ArraySize(j, "meshes"); ++m)
      primitives += ArraySize(j["meshes"][m], "primitives");
    RETURN_IF_ERROR(check("meshes[].primitives", primitives, "primitives", "max_primitives",
                          limits_.max_primitives));
    const json* ext = Member(j, "extensions");
    const json* lights = ext ? Member(*ext, "KHR_lights_punctual") : nullptr;
    RETURN_IF_ERROR(check("extensions.KHR_lights_punctual.lights",
                          lights ? ArraySize(*lights, "lights") : 0, "lights", "max_lights",
                          limits_.max_lights));
    return absl::OkStatus();
  }

  // ---- value ranges of what the importer reads (the glTF 2.0 schema's and the extensions'):
  // a file the spec forbids is refused, naming the value, rather than clamped into shape.

  // `v` (when present) is a number in [lo, hi]; `open_lo`/`open_hi` exclude that end.
  // `also` names what else the field allows, before the range ("0 or ").
  absl::Status Number(const json* v, const std::string& field, double lo, double hi,
                      bool open_lo = false, bool open_hi = false, absl::string_view also = "") {
    if (v == nullptr) return absl::OkStatus();
    if (!v->is_number()) return Invalid(file_, field, "not a number");
    const double x = v->get<double>();
    const bool below = open_lo ? x <= lo : x < lo;
    const bool above = open_hi ? x >= hi : x > hi;
    if (below || above) {
      return Invalid(file_, field, x, " is out of range ", also, open_lo ? "(" : "[", lo, ", ",
                     hi == kUnbounded ? std::string("inf") : absl::StrCat(hi),
                     open_hi || hi == kUnbounded ? ")" : "]");
    }
    return absl::OkStatus();
  }
  // `v` (when present) is an array of `n` numbers in [lo, hi].
  absl::Status Numbers(const json* v, const std::string& field, size_t n, double lo, double hi) {
    if (v == nullptr) return absl::OkStatus();
    if (!v->is_array() || v->size() != n)
      return Invalid(file_, field, "wants an array of ", n, " numbers");
    for (size_t i = 0; i < n; ++i)
      RETURN_IF_ERROR(Number(&(*v)[i], absl::StrCat(field, "[", i, "]"), lo, hi));
    return absl::OkStatus();
  }
  static constexpr double kUnbounded = std::numeric_limits<double>::infinity();
  static constexpr double kHalfPi = 1.5707963267948966;

  // ---- the integers tinygltf reads into a C int: it casts any JSON integer (4294967296 reads as
  // 0, 4294967297 as 1), and takes a reference that is no integer (0.5, "0") or is -1 as absent.
  // Either would load a file other than the one sent, so each is refused here, naming it. A
  // float that is an integer (1.0, 5126.0) is that integer, as the validator reads it: it is
  // written as one for tinygltf, which would take it as no value (result_->integers_rewritten).
  // (The references' ranges are checked where they are used; an extension's integers are
  // widened.)
  // kSize: a byte length, offset, stride or element count, which tinygltf reads as a size_t (any
  // non-negative integer; it took a negative or fractional one as 0 where it is optional).
  enum class IntKind { kIndex, kEnum, kCount, kOffset, kSize };

  // `v` (when present) is a non-negative integer (every glTF enumeration is positive, and
  // tinygltf takes a negative mode or filter as none), at least 1 for a count, and one an int
  // holds for all but sizes.
  absl::Status Integer(json* v, const std::string& field, IntKind kind) {
    if (v == nullptr) return absl::OkStatus();
    const uint64_t hi = kind == IntKind::kSize ? std::numeric_limits<uint64_t>::max()
                                               : uint64_t(std::numeric_limits<int32_t>::max());
    const uint64_t lo = kind == IntKind::kCount ? 1 : 0;
    uint64_t n = 0;
    bool integer = false;
    if (v->is_number_unsigned()) {
      n = v->get<uint64_t>();
      integer = true;
    } else if (v->is_number_integer()) {
      integer = v->get<int64_t>() >= 0;
      n = integer ? uint64_t(v->get<int64_t>()) : 0;
    } else if (v->is_number_float()) {
      const double x = v->get<double>();
      integer = WholeNumber(x) && x >= 0.0;
      n = integer ? uint64_t(x) : 0;
    }
    if (integer && n >= lo && n <= hi) {
      if (v->is_number_float()) {
        *v = n;
        result_->integers_rewritten = true;
      }
      return absl::OkStatus();
    }
    const char* what =
        kind == IntKind::kIndex    ? " is not an index (an integer in [0, 2147483647])"
        : kind == IntKind::kCount  ? " is not a count (an integer in [1, 2147483647])"
        : kind == IntKind::kOffset ? " is not a byte offset (an integer in [0, 2147483647])"
        : kind == IntKind::kSize   ? " is not a size (a non-negative integer)"
                                   : " is not an enumerated value (an integer in [0, 2147483647])";
    return Invalid(file_, field, Quote(v->dump()), what);
  }
  // The members `keys` of `o`, when it is an object, each of `kind`.
  absl::Status Integers(json* o, const std::string& path, std::initializer_list<const char*> keys,
                        IntKind kind = IntKind::kIndex) {
    if (o == nullptr || !o->is_object()) return absl::OkStatus();
    for (const char* key : keys) RETURN_IF_ERROR(Integer(At(o, key), path + "." + key, kind));
    return absl::OkStatus();
  }
  // Member, of a JSON value this may change.
  static json* At(json* o, const char* key) { return const_cast<json*>(Member(o, key)); }
  // `v` (when present) is an array of indices.
  absl::Status IndexArray(json* v, const std::string& field) {
    if (v == nullptr) return absl::OkStatus();
    if (!v->is_array()) return Invalid(file_, field, "not an array of indices");
    for (size_t i = 0; i < v->size(); ++i)
      RETURN_IF_ERROR(Integer(&(*v)[i], absl::StrCat(field, "[", i, "]"), IntKind::kIndex));
    return absl::OkStatus();
  }
  // `v` (when present) is an object of attribute names to accessor indices.
  absl::Status IndexMap(json* v, const std::string& field) {
    if (v == nullptr) return absl::OkStatus();
    if (!v->is_object()) return Invalid(file_, field, "not an object of accessor indices");
    for (auto it = v->begin(); it != v->end(); ++it)
      RETURN_IF_ERROR(Integer(&it.value(), absl::StrCat(field, ".", it.key()), IntKind::kIndex));
    return absl::OkStatus();
  }

  // Every integer of the core schema that tinygltf reads as an int or a size_t.
  absl::Status IntegerFields(json& j) {
    auto each =
        [&](json* o, const char* key, const std::string& path,
            const std::function<absl::Status(json&, const std::string&)>& check) -> absl::Status {
      json* a = At(o, key);
      for (size_t i = 0; a && a->is_array() && i < a->size(); ++i)
        RETURN_IF_ERROR(check((*a)[i], absl::StrCat(path, key, "[", i, "]")));
      return absl::OkStatus();
    };
    constexpr IntKind kEnum = IntKind::kEnum;
    RETURN_IF_ERROR(Integer(At(&j, "scene"), "scene", IntKind::kIndex));
    RETURN_IF_ERROR(each(&j, "buffers", "", [&](json& b, const std::string& f) -> absl::Status {
      return Integers(&b, f, {"byteLength"}, IntKind::kSize);
    }));
    RETURN_IF_ERROR(each(&j, "scenes", "", [&](json& s, const std::string& f) -> absl::Status {
      return IndexArray(At(&s, "nodes"), f + ".nodes");
    }));
    RETURN_IF_ERROR(each(&j, "nodes", "", [&](json& n, const std::string& f) -> absl::Status {
      RETURN_IF_ERROR(Integers(&n, f, {"camera", "skin", "mesh"}));
      return IndexArray(At(&n, "children"), f + ".children");
    }));
    RETURN_IF_ERROR(each(&j, "meshes", "", [&](json& m, const std::string& f) -> absl::Status {
      return each(&m, "primitives", f + ".", [&](json& p, const std::string& pf) -> absl::Status {
        RETURN_IF_ERROR(Integers(&p, pf, {"indices", "material"}));
        RETURN_IF_ERROR(Integers(&p, pf, {"mode"}, kEnum));
        RETURN_IF_ERROR(IndexMap(At(&p, "attributes"), pf + ".attributes"));
        return each(&p, "targets", pf + ".", [&](json& t, const std::string& tf) -> absl::Status {
          return IndexMap(&t, tf);
        });
      });
    }));
    RETURN_IF_ERROR(each(&j, "materials", "", [&](json& m, const std::string& f) -> absl::Status {
      json* pbr = At(&m, "pbrMetallicRoughness");
      for (const char* slot : {"baseColorTexture", "metallicRoughnessTexture"}) {
        RETURN_IF_ERROR(Integers(At(pbr, slot), absl::StrCat(f, ".pbrMetallicRoughness.", slot),
                                 {"index", "texCoord"}));
      }
      for (const char* slot : {"normalTexture", "occlusionTexture", "emissiveTexture"})
        RETURN_IF_ERROR(Integers(At(&m, slot), absl::StrCat(f, ".", slot), {"index", "texCoord"}));
      return absl::OkStatus();
    }));
    RETURN_IF_ERROR(each(&j, "textures", "", [&](json& t, const std::string& f) -> absl::Status {
      return Integers(&t, f, {"sampler", "source"});
    }));
    RETURN_IF_ERROR(each(&j, "images", "", [&](json& i, const std::string& f) -> absl::Status {
      return Integers(&i, f, {"bufferView"});
    }));
    RETURN_IF_ERROR(each(&j, "samplers", "", [&](json& s, const std::string& f) -> absl::Status {
      return Integers(&s, f, {"magFilter", "minFilter", "wrapS", "wrapT"}, kEnum);
    }));
    RETURN_IF_ERROR(each(&j, "accessors", "", [&](json& a, const std::string& f) -> absl::Status {
      RETURN_IF_ERROR(Integers(&a, f, {"bufferView"}));
      RETURN_IF_ERROR(Integers(&a, f, {"componentType"}, kEnum));
      RETURN_IF_ERROR(Integers(&a, f, {"byteOffset", "count"}, IntKind::kSize));
      // tinygltf reads a sparse block's count and offsets as ints too.
      json* sparse = At(&a, "sparse");
      const std::string sf = f + ".sparse";
      RETURN_IF_ERROR(Integers(sparse, sf, {"count"}, IntKind::kCount));
      for (const char* part : {"indices", "values"}) {
        const std::string pf = absl::StrCat(sf, ".", part);
        RETURN_IF_ERROR(Integers(At(sparse, part), pf, {"bufferView"}));
        RETURN_IF_ERROR(Integers(At(sparse, part), pf, {"byteOffset"}, IntKind::kOffset));
        RETURN_IF_ERROR(Integers(At(sparse, part), pf, {"componentType"}, kEnum));
      }
      return absl::OkStatus();
    }));
    RETURN_IF_ERROR(each(&j, "bufferViews", "", [&](json& b, const std::string& f) -> absl::Status {
      RETURN_IF_ERROR(Integers(&b, f, {"buffer"}));
      RETURN_IF_ERROR(Integers(&b, f, {"byteOffset", "byteLength", "byteStride"}, IntKind::kSize));
      return Integers(&b, f, {"target"}, kEnum);
    }));
    RETURN_IF_ERROR(each(&j, "skins", "", [&](json& s, const std::string& f) -> absl::Status {
      RETURN_IF_ERROR(Integers(&s, f, {"inverseBindMatrices", "skeleton"}));
      return IndexArray(At(&s, "joints"), f + ".joints");
    }));
    return each(&j, "animations", "", [&](json& a, const std::string& f) -> absl::Status {
      RETURN_IF_ERROR(
          each(&a, "channels", f + ".", [&](json& c, const std::string& cf) -> absl::Status {
            RETURN_IF_ERROR(Integers(&c, cf, {"sampler"}));
            return Integers(At(&c, "target"), cf + ".target", {"node"});
          }));
      return each(&a, "samplers", f + ".", [&](json& s, const std::string& sf) -> absl::Status {
        return Integers(&s, sf, {"input", "output"});
      });
    });
  }

  absl::Status TextureInfo(const json* info, const std::string& field) {
    if (info == nullptr) return absl::OkStatus();
    const json* exts = Member(*info, "extensions");
    const json* tt = exts ? Member(*exts, "KHR_texture_transform") : nullptr;
    if (tt == nullptr) return absl::OkStatus();
    const std::string f = field + ".extensions.KHR_texture_transform";
    RETURN_IF_ERROR(Numbers(Member(*tt, "offset"), f + ".offset", 2, -kUnbounded, kUnbounded));
    RETURN_IF_ERROR(Numbers(Member(*tt, "scale"), f + ".scale", 2, -kUnbounded, kUnbounded));
    return Number(Member(*tt, "rotation"), f + ".rotation", -kUnbounded, kUnbounded);
  }

  // A textureInfo inside an extension, which tinygltf keeps as plain values without checking:
  // an object whose index names a texture and whose texCoord, if given, is a non-negative
  // integer; `index` and `texcoord` get them (the texCoord at most 2^20: more is no set).
  absl::Status ExtensionTextureInfo(const json& j, const json* info, const std::string& field,
                                    int32_t* index, uint32_t* texcoord) {
    if (info == nullptr) return absl::OkStatus();
    if (!info->is_object()) return Invalid(file_, field, "not an object");
    uint64_t n = 0;
    if (!JsonUint(Member(*info, "index"), &n))
      return Invalid(file_, field + ".index", "wants a non-negative integer");
    const size_t textures = ArraySize(j, "textures");
    if (n >= textures)
      return Invalid(file_, field + ".index", "texture index ", n, " out of range (", textures,
                     " textures)");
    *index = int32_t(n);
    if (const json* tc = Member(*info, "texCoord"); tc != nullptr) {
      if (!JsonUint(tc, &n))
        return Invalid(file_, field + ".texCoord", "wants a non-negative integer");
      *texcoord = uint32_t(std::min<uint64_t>(n, 1u << 20));
    }
    return TextureInfo(info, field);
  }

  // KHR_materials_ior's and KHR_materials_specular's values (their schemas' ranges), kept for
  // the importer in result_->reflectance.
  absl::Status Reflectance(const json& j, size_t material, const json* exts, const std::string& f) {
    const json* ior = exts ? Member(*exts, "KHR_materials_ior") : nullptr;
    const json* sp = exts ? Member(*exts, "KHR_materials_specular") : nullptr;
    if (ior == nullptr && sp == nullptr) return absl::OkStatus();
    PreScanResult::Reflectance& r = result_->reflectance[uint32_t(material)];
    if (ior != nullptr) {
      const std::string field = f + ".extensions.KHR_materials_ior";
      if (!ior->is_object()) return Invalid(file_, field, "not an object");
      // 0 (F0 1: the specular colour alone sets the reflectance), or at least 1.
      const json* v = Member(*ior, "ior");
      if (v != nullptr && (!v->is_number() || v->get<double>() != 0.0))
        RETURN_IF_ERROR(Number(v, field + ".ior", 1, kUnbounded, false, false, "0 or "));
      if (v != nullptr) r.ior = v->get<double>();
    }
    if (sp != nullptr) {
      const std::string field = f + ".extensions.KHR_materials_specular";
      if (!sp->is_object()) return Invalid(file_, field, "not an object");
      const json* factor = Member(*sp, "specularFactor");
      RETURN_IF_ERROR(Number(factor, field + ".specularFactor", 0, 1));
      if (factor != nullptr) r.specular_factor = factor->get<double>();
      const json* color = Member(*sp, "specularColorFactor");
      RETURN_IF_ERROR(Numbers(color, field + ".specularColorFactor", 3, 0, kUnbounded));
      for (size_t c = 0; color != nullptr && c < 3; ++c) r.specular_color[c] = (*color)[c];
      RETURN_IF_ERROR(ExtensionTextureInfo(j, Member(*sp, "specularTexture"),
                                           field + ".specularTexture", &r.specular_texture,
                                           &r.specular_texcoord));
      RETURN_IF_ERROR(ExtensionTextureInfo(j, Member(*sp, "specularColorTexture"),
                                           field + ".specularColorTexture",
                                           &r.specular_color_texture, &r.specular_color_texcoord));
    }
    return absl::OkStatus();
  }

  absl::Status ValueRanges(const json& j) {
    for (size_t i = 0; i < ArraySize(j, "materials"); ++i) {
      const json& m = j["materials"][i];
      const std::string f = absl::StrCat("materials[", i, "]");
      if (const json* pbr = Member(m, "pbrMetallicRoughness")) {
        const std::string p = f + ".pbrMetallicRoughness";
        RETURN_IF_ERROR(Numbers(Member(*pbr, "baseColorFactor"), p + ".baseColorFactor", 4, 0, 1));
        RETURN_IF_ERROR(Number(Member(*pbr, "metallicFactor"), p + ".metallicFactor", 0, 1));
        RETURN_IF_ERROR(Number(Member(*pbr, "roughnessFactor"), p + ".roughnessFactor", 0, 1));
        RETURN_IF_ERROR(TextureInfo(Member(*pbr, "baseColorTexture"), p + ".baseColorTexture"));
        RETURN_IF_ERROR(TextureInfo(Member(*pbr, "metallicRoughnessTexture"),
                                    p + ".metallicRoughnessTexture"));
      }
      RETURN_IF_ERROR(Numbers(Member(m, "emissiveFactor"), f + ".emissiveFactor", 3, 0, 1));
      RETURN_IF_ERROR(Number(Member(m, "alphaCutoff"), f + ".alphaCutoff", 0, kUnbounded));
      if (const json* occ = Member(m, "occlusionTexture"))
        RETURN_IF_ERROR(Number(Member(*occ, "strength"), f + ".occlusionTexture.strength", 0, 1));
      for (const char* slot : {"normalTexture", "occlusionTexture", "emissiveTexture"})
        RETURN_IF_ERROR(TextureInfo(Member(m, slot), f + "." + slot));
      const json* exts = Member(m, "extensions");
      // The extension's presence makes the material unlit; its value must be an object.
      if (const json* unlit = exts ? Member(*exts, "KHR_materials_unlit") : nullptr;
          unlit != nullptr && !unlit->is_object()) {
        return Invalid(file_, f + ".extensions.KHR_materials_unlit", "not an object");
      }
      if (const json* es = exts ? Member(*exts, "KHR_materials_emissive_strength") : nullptr) {
        RETURN_IF_ERROR(Number(Member(*es, "emissiveStrength"),
                               f + ".extensions.KHR_materials_emissive_strength.emissiveStrength",
                               0, kUnbounded));
      }
      RETURN_IF_ERROR(Reflectance(j, i, exts, f));
    }
    const json* exts = Member(j, "extensions");
    const json* lights = exts ? Member(*exts, "KHR_lights_punctual") : nullptr;
    for (size_t i = 0; lights && i < ArraySize(*lights, "lights"); ++i) {
      const json& l = (*lights)["lights"][i];
      const std::string f = absl::StrCat("extensions.KHR_lights_punctual.lights[", i, "]");
      RETURN_IF_ERROR(Numbers(Member(l, "color"), f + ".color", 3, 0, 1));
      RETURN_IF_ERROR(Number(Member(l, "intensity"), f + ".intensity", 0, kUnbounded));
      RETURN_IF_ERROR(Number(Member(l, "range"), f + ".range", 0, kUnbounded, /*open_lo=*/true));
      if (const json* spot = Member(l, "spot")) {
        const json* inner = Member(*spot, "innerConeAngle");
        const json* outer = Member(*spot, "outerConeAngle");
        RETURN_IF_ERROR(Number(inner, f + ".spot.innerConeAngle", 0, kHalfPi, false, true));
        RETURN_IF_ERROR(Number(outer, f + ".spot.outerConeAngle", 0, kHalfPi, true, false));
        const double in = inner && inner->is_number() ? inner->get<double>() : 0.0;
        const double out = outer && outer->is_number() ? outer->get<double>() : kHalfPi / 2;
        if (in >= out)
          return Invalid(file_, f + ".spot", "innerConeAngle ", in,
                         " is not less than outerConeAngle ", out);
      }
    }
    for (size_t i = 0; i < ArraySize(j, "cameras"); ++i) {
      const json& c = j["cameras"][i];
      const std::string f = absl::StrCat("cameras[", i, "]");
      if (const json* p = Member(c, "perspective")) {
        RETURN_IF_ERROR(Number(Member(*p, "yfov"), f + ".perspective.yfov", 0, kUnbounded, true));
        RETURN_IF_ERROR(Number(Member(*p, "znear"), f + ".perspective.znear", 0, kUnbounded, true));
        RETURN_IF_ERROR(
            Number(Member(*p, "aspectRatio"), f + ".perspective.aspectRatio", 0, kUnbounded, true));
        const json* zfar = Member(*p, "zfar");
        const json* znear = Member(*p, "znear");
        RETURN_IF_ERROR(Number(zfar, f + ".perspective.zfar", 0, kUnbounded, true));
        if (zfar && znear && znear->is_number() && zfar->get<double>() <= znear->get<double>())
          return Invalid(file_, f + ".perspective", "zfar ", zfar->get<double>(),
                         " is not greater than znear ", znear->get<double>());
      }
      if (const json* o = Member(c, "orthographic")) {
        for (const char* key : {"xmag", "ymag"}) {  // signed (a mirrored view), never zero
          const json* mag = Member(*o, key);
          if (mag && mag->is_number() && mag->get<double>() == 0.0)
            return Invalid(file_, absl::StrCat(f, ".orthographic.", key), "must not be zero");
        }
        RETURN_IF_ERROR(Number(Member(*o, "znear"), f + ".orthographic.znear", 0, kUnbounded));
        RETURN_IF_ERROR(Number(Member(*o, "zfar"), f + ".orthographic.zfar", 0, kUnbounded, true));
        const json* zfar = Member(*o, "zfar");
        const json* znear = Member(*o, "znear");
        if (zfar && znear && zfar->is_number() && znear->is_number() &&
            zfar->get<double>() <= znear->get<double>())
          return Invalid(file_, f + ".orthographic", "zfar ", zfar->get<double>(),
                         " is not greater than znear ", znear->get<double>());
      }
    }
    for (size_t i = 0; i < ArraySize(j, "nodes"); ++i) {
      const json& n = j["nodes"][i];
      const std::string f = absl::StrCat("nodes[", i, "]");
      if (Member(n, "matrix") &&
          (Member(n, "translation") || Member(n, "rotation") || Member(n, "scale")))
        return Invalid(file_, f + ".matrix", "given together with translation, rotation or scale");
      const json* r = Member(n, "rotation");
      RETURN_IF_ERROR(Numbers(r, f + ".rotation", 4, -1, 1));
      if (r != nullptr) {
        double len2 = 0;
        for (const json& c : *r) len2 += c.get<double>() * c.get<double>();
        // The validator's tolerance for a unit quaternion.
        if (std::abs(std::sqrt(len2) - 1.0) > 0.00005)
          return Invalid(file_, f + ".rotation", "is not a unit quaternion (length ",
                         std::sqrt(len2), ")");
      }
    }
    return absl::OkStatus();
  }

  // Accessor sizes, from count, type and componentType (malformed ones are tinygltf's and the
  // converter's to reject; only what they would allocate is bounded here).
  absl::Status Accessors(const json& j) {
    for (size_t i = 0; i < ArraySize(j, "accessors"); ++i) {
      const json& a = j["accessors"][i];
      const std::string field = absl::StrCat("accessors[", i, "]");
      uint64_t count = 0, component_type = 0;
      for (const char* key : {"count", "componentType", "type"}) {
        if (Member(a, key) == nullptr) return Invalid(file_, field + "." + key, "missing");
      }
      if (!JsonUint(Member(a, "count"), &count)) continue;
      // glTF 2.0 3.6.2.1: only byte and short components can be normalized.
      const json* normalized = Member(a, "normalized");
      if (normalized && normalized->is_boolean() && normalized->get<bool>() &&
          JsonUint(Member(a, "componentType"), &component_type) &&
          (component_type == 5125 || component_type == 5126)) {
        return Invalid(file_, field + ".normalized", "true, but only byte and short components ",
                       "can be normalized (componentType ", component_type, ")");
      }
      if (count > limits_.max_accessor_elements) {
        return OverLimit(file_, field + ".count", count,
                         " elements exceed the max_accessor_elements limit (",
                         limits_.max_accessor_elements, ")");
      }
      const json* type = Member(a, "type");
      if (!JsonUint(Member(a, "componentType"), &component_type) || type == nullptr ||
          !type->is_string()) {
        continue;
      }
      const uint64_t element =
          ComponentBytes(component_type) * TypeComponents(type->get_ref<const std::string&>());
      uint64_t bytes = 0;
      if (__builtin_mul_overflow(count, element, &bytes) || bytes > limits_.max_accessor_bytes) {
        return OverLimit(file_, field, count, " elements of ", element,
                         " bytes exceed the max_accessor_bytes limit (",
                         limits_.max_accessor_bytes, ")");
      }
    }
    return absl::OkStatus();
  }

  static uint64_t ComponentBytes(uint64_t component_type) {
    switch (component_type) {
      case 5120:  // BYTE
      case 5121:  // UNSIGNED_BYTE
        return 1;
      case 5122:  // SHORT
      case 5123:  // UNSIGNED_SHORT
        return 2;
      case 5125:  // UNSIGNED_INT
      case 5126:  // FLOAT
        return 4;
      default:
        return 0;
    }
  }

  static uint64_t TypeComponents(const std::string& type) {
    if (type == "SCALAR") return 1;
    if (type == "VEC2") return 2;
    if (type == "VEC3") return 3;
    if (type == "VEC4" || type == "MAT2") return 4;
    if (type == "MAT3") return 9;
    if (type == "MAT4") return 16;
    return 0;
  }

  // Maps an external URI to its key in the file set, or explains why it cannot be used.
  absl::StatusOr<std::string> Resolve(const std::string& field, const std::string& uri) {
    const std::string key = PercentDecode(uri);
    const bool dotdot = key == ".." || key.rfind("../", 0) == 0 ||
                        key.find("/../") != std::string::npos ||
                        (key.size() >= 3 && key.compare(key.size() - 3, 3, "/..") == 0);
    std::string why;
    if (key.empty()) {
      why = " (empty URI)";
    } else if (key.find('\\') != std::string::npos || key.find('\0') != std::string::npos) {
      why = " (backslashes and NUL are not allowed)";
    } else if (key[0] == '/') {
      why = " (absolute paths are not allowed)";
    } else if (key.find(':') != std::string::npos) {
      why = " (URI schemes other than data: are not allowed)";
    } else if (dotdot) {
      why = " (it leaves the asset directory)";
    } else if (src_.files.count(key) != 0) {
      result_->alias.emplace(PercentDecode(uri, /*like_tinygltf=*/true), key);
      return key;
    }
    return Invalid(file_, field, "'", Quote(uri), "' is not in the file set", why);
  }

  // Checks a uri; returns the size of what it names, or npos when it is a data: URI.
  absl::StatusOr<size_t> Uri(const std::string& field, const json& uri) {
    if (!uri.is_string()) return Invalid(file_, field, "not a string");
    const std::string u = uri.get<std::string>();
    size_t payload = 0;
    if (u.rfind("data:", 0) == 0) {
      if (IsTinygltfDataUri(u, &payload)) return std::string::npos;
      // (tinygltf 2.7 decodes no image/webp data: URI; it would take it for a file name.)
      if (absl::StartsWith(u, "data:image/webp"))
        return Invalid(file_, field, "a WebP image in a data: URI is not supported (put it in a ",
                       "file or a bufferView)");
      return Invalid(file_, field, "unsupported data: URI (base64 buffer and image types only)");
    }
    ASSIGN_OR_RETURN(std::string key, Resolve(field, u));
    return src_.files.at(key).size();
  }

  absl::Status Buffers(const json& j) {
    for (size_t i = 0; i < ArraySize(j, "buffers"); ++i) {
      const json& b = j["buffers"][i];
      const std::string field = absl::StrCat("buffers[", i, "]");
      uint64_t length = 0;
      if (!JsonUint(Member(b, "byteLength"), &length)) {
        return Invalid(file_, field + ".byteLength", "missing or not a non-negative integer");
      }
      ASSIGN_OR_RETURN(const bool fallback, MeshoptFallback(b, field));
      fallback_.push_back(fallback && Member(b, "uri") == nullptr);
      if (fallback_.back()) {
        // EXT_meshopt_compression: a buffer with no data that the compressed bufferViews decode
        // into. Only the part they reach is allocated (BufferViews sizes it, and bounds it by
        // max_decoded_bytes before anything is allocated); its byteLength alone costs nothing.
        result_->fallback_buffers[uint32_t(i)] = 0;
        buffer_lengths_.push_back(length);
        continue;
      }
      if (const json* uri = Member(b, "uri")) {
        if (uri->is_string() && absl::StartsWith(uri->get<std::string>(), "data:") &&
            !absl::StartsWith(uri->get<std::string>(), "data:application/octet-stream;") &&
            !absl::StartsWith(uri->get<std::string>(), "data:application/gltf-buffer;")) {
          return Invalid(file_, field + ".uri", "a data: URI of a buffer must be ",
                         "application/octet-stream or application/gltf-buffer");
        }
        absl::StatusOr<size_t> have = Uri(field + ".uri", *uri);
        if (!have.ok()) return have.status();
        // tinygltf insists on an exact match; say so before it reads anything.
        if (*have != std::string::npos && *have != length) {
          return Invalid(file_, field, "byteLength (", length, ") does not match the size of '",
                         Quote(uri->get<std::string>()), "' (", *have, " bytes)");
        }
      } else if (glb_ == nullptr) {
        return Invalid(file_, field, "uri is missing (only allowed in a .glb)");
      } else if (i != 0) {
        return Invalid(file_, field, "uri is missing (only buffers[0] may use the GLB BIN chunk)");
      } else if (length > glb_->bin_size) {
        return Invalid(file_, field, "byteLength (", length, ") exceeds the GLB BIN chunk (",
                       glb_->bin_size, " bytes)");
      }
      buffer_lengths_.push_back(length);
      // tinygltf copies every buffer: buffers naming the same file (or the BIN chunk) must not
      // multiply the memory an upload costs.
      if (__builtin_add_overflow(copied_bytes_, length, &copied_bytes_) ||
          copied_bytes_ > file_set_bytes_) {
        return Invalid(file_, "buffers", "their byteLengths add up to more than the ",
                       file_set_bytes_, " bytes of the file set");
      }
    }
    return absl::OkStatus();
  }

  // glTF 2.0 only: a 1.0 file (a different schema) must not be read as if it were 2.0. The spec
  // says a loader refuses a major version it does not know, and a minVersion above its own.
  absl::Status Asset(const json& j) {
    const json* asset = Member(j, "asset");
    if (asset == nullptr || !asset->is_object()) {
      return Invalid(file_, "asset", "missing (a glTF file names its version in asset.version)");
    }
    for (const char* key : {"version", "minVersion"}) {
      const json* v = Member(*asset, key);
      if (v == nullptr && std::strcmp(key, "minVersion") == 0) continue;
      const std::string field = absl::StrCat("asset.", key);
      if (v == nullptr || !v->is_string()) return Invalid(file_, field, "missing or not a string");
      const std::string text = v->get<std::string>();
      const std::vector<absl::string_view> parts = absl::StrSplit(text, '.');
      int major = 0, minor = 0;
      if (parts.size() != 2 || !absl::SimpleAtoi(parts[0], &major) ||
          !absl::SimpleAtoi(parts[1], &minor)) {
        return Invalid(file_, field, "'", Quote(text), "' is not a MAJOR.MINOR version");
      }
      const bool supported = std::strcmp(key, "version") == 0 ? major == 2
                                                              : major == 2 && minor == 0;
      if (!supported) {
        return Invalid(file_, field, "'", Quote(text), "' is not supported (glTF 2.0 only)");
      }
    }
    return absl::OkStatus();
  }

  // What every file of the set holds together: no asset needs to copy more than that.
  static uint64_t FileSetBytes(const GltfSource& src) {
    uint64_t total = 0;
    for (const auto& [name, data] : src.files) total += data.size();
    return total;
  }

  // tinygltf hands an image's bufferView to the image loader without any range check.
  absl::Status BufferViews(const json& j) {
    for (size_t i = 0; i < ArraySize(j, "bufferViews"); ++i) {
      const json& v = j["bufferViews"][i];
      const std::string field = absl::StrCat("bufferViews[", i, "]");
      uint64_t buffer = 0, offset = 0, length = 0, stride = 0;
      RETURN_IF_ERROR(BufferRange(v, field, &buffer, &offset, &length));
      if (const json* s = Member(v, "byteStride");
          s && (!JsonUint(s, &stride) || stride < 4 || stride > 252 || stride % 4 != 0)) {
        return Invalid(file_, field + ".byteStride", Quote(s->dump()),
                       " is not a multiple of 4 in 4..252");
      }
      const json* ext = meshopt_ ? Member(Member(v, "extensions"), "EXT_meshopt_compression")
                                 : nullptr;
      if (ext != nullptr) {
        const std::string ext_field = field + ".extensions.EXT_meshopt_compression";
        RETURN_IF_ERROR(MeshoptBufferView(*ext, ext_field, uint32_t(i), length));
        if (Member(v, "byteStride") && stride != result_->meshopt_views[uint32_t(i)].byte_stride) {
          return Invalid(file_, field + ".byteStride", stride, " is not the extension's byteStride (",
                         result_->meshopt_views[uint32_t(i)].byte_stride, ")");
        }
        if (fallback_[buffer]) {
          uint64_t& used = result_->fallback_buffers[uint32_t(buffer)];
          const uint64_t end = offset + length;  // <= the buffer's byteLength (BufferRange)
          if (end > used) {
            if (__builtin_add_overflow(decoded_bytes_, end - used, &decoded_bytes_) ||
                decoded_bytes_ > limits_.max_decoded_bytes) {
              return OverLimit(file_, field, "meshopt fallback buffers of ", decoded_bytes_,
                               " bytes exceed the max_decoded_bytes limit (",
                               limits_.max_decoded_bytes, ")");
            }
            used = end;
          }
        }
      } else if (fallback_[buffer]) {
        return Invalid(file_, field + ".buffer", "buffers[", buffer,
                       "] is a meshopt fallback buffer (no data), but this bufferView is not "
                       "compressed");
      }
    }
    return absl::OkStatus();
  }

  // KHR_draco_mesh_compression: the indices of a compressed primitive are an accessor without a
  // bufferView, which tinygltf refuses ("invalid bufferView"); they are handed to the importer
  // aside (PreScanResult::draco_indices) and removed from the JSON tinygltf reads.
  void DracoIndices(const json& j) {
    const size_t accessors = ArraySize(j, "accessors");
    for (size_t m = 0; m < ArraySize(j, "meshes"); ++m) {
      const json* prims = Member(j["meshes"][m], "primitives");
      for (size_t p = 0; prims && prims->is_array() && p < prims->size(); ++p) {
        const json& prim = (*prims)[p];
        uint64_t index = 0;
        if (Member(Member(prim, "extensions"), "KHR_draco_mesh_compression") != nullptr &&
            JsonUint(Member(prim, "indices"), &index) && index < accessors &&
            Member(j["accessors"][index], "bufferView") == nullptr) {
          result_->draco_indices[{uint32_t(m), uint32_t(p)}] = uint32_t(index);
        }
      }
    }
  }

  // The value of string `v` (e.g. a meshopt mode) among `names`, else what it wants.
  template <typename T>
  absl::StatusOr<T> Enum(const json* v, const std::string& field,
                         std::initializer_list<std::pair<const char*, T>> names) {
    std::string wants;
    size_t i = 0;
    for (const auto& [name, value] : names) {
      if (v != nullptr && v->is_string() && v->get_ref<const std::string&>() == name) return value;
      absl::StrAppend(&wants, i == 0 ? "" : i + 1 == names.size() ? " or " : ", ", name);
      ++i;
    }
    return Invalid(file_, field, v ? Quote(v->dump()) : "missing", ": wants ", wants);
  }

  // `o`'s buffer, byteOffset and byteLength (a bufferView, or the compressed range of a meshopt
  // one): an existing buffer and a non-empty range inside it.
  absl::Status BufferRange(const json& o, const std::string& field, uint64_t* buffer,
                           uint64_t* offset, uint64_t* length) {
    if (!JsonUint(Member(o, "buffer"), buffer) || *buffer >= buffer_lengths_.size()) {
      return Invalid(file_, field + ".buffer", "missing or out of range (",
                     buffer_lengths_.size(), " buffers)");
    }
    if (Member(o, "byteOffset") && !JsonUint(Member(o, "byteOffset"), offset)) {
      return Invalid(file_, field + ".byteOffset", "not a non-negative integer");
    }
    if (!JsonUint(Member(o, "byteLength"), length) || *length == 0) {
      return Invalid(file_, field + ".byteLength", "missing or not a positive integer");
    }
    const uint64_t have = buffer_lengths_[*buffer];
    if (*offset > have || *length > have - *offset) {
      return Invalid(file_, field, "byteOffset + byteLength (",
                     *offset > UINT64_MAX - *length ? "overflow" : absl::StrCat(*offset + *length),
                     ") exceeds buffers[", *buffer, "].byteLength (", have, ")");
    }
    return absl::OkStatus();
  }

  // Rules of the glTF 2.0 schema and of section 3.7.2.1 the importer relies on, each refused
  // naming the place (the Khronos validator's EMPTY_ENTITY, DUPLICATE_ELEMENTS,
  // UNSATISFIED_DEPENDENCY, MESH_PRIMITIVE_INVALID_ATTRIBUTE, ..._INDEXED_SEMANTIC_CONTINUITY,
  // ..._TOO_FEW_TEXCOORDS and NODE_MATRIX_NON_TRS).
  absl::Status Structure(const json& j) {
    // Arrays the schema gives minItems 1.
    for (const char* key : {"accessors", "animations", "buffers", "bufferViews", "cameras",
                            "extensionsUsed", "extensionsRequired", "images", "materials",
                            "meshes", "nodes", "samplers", "scenes", "skins", "textures"}) {
      const json* a = Member(j, key);
      if (a && a->is_array() && a->empty()) return Invalid(file_, key, "an empty array");
    }
    for (const char* list : {"extensionsUsed", "extensionsRequired"}) {
      const json* a = Member(j, list);
      for (size_t i = 0; a && a->is_array() && i < a->size(); ++i) {
        for (size_t k = 0; k < i; ++k) {
          if ((*a)[k] == (*a)[i]) {
            return Invalid(file_, absl::StrCat(list, "[", i, "]"), Quote((*a)[i].dump()),
                           " is listed twice");
          }
        }
        if (std::strcmp(list, "extensionsRequired") == 0 && (*a)[i].is_string() &&
            !Lists(j, "extensionsUsed", (*a)[i].get_ref<const std::string&>().c_str())) {
          return Invalid(file_, absl::StrCat(list, "[", i, "]"), Quote((*a)[i].dump()),
                         " is not in extensionsUsed");
        }
      }
    }
    for (size_t n = 0; n < ArraySize(j, "nodes"); ++n) {
      const json& node = j["nodes"][n];
      const std::string field = absl::StrCat("nodes[", n, "]");
      if (const json* c = Member(node, "children"); c && c->is_array() && c->empty())
        return Invalid(file_, field + ".children", "an empty array");
      RETURN_IF_ERROR(MatrixIsTrs(Member(node, "matrix"), field + ".matrix"));
    }
    for (size_t s = 0; s < ArraySize(j, "scenes"); ++s) {
      if (const json* c = Member(j["scenes"][s], "nodes"); c && c->is_array() && c->empty())
        return Invalid(file_, absl::StrCat("scenes[", s, "].nodes"), "an empty array");
    }
    for (size_t m = 0; m < ArraySize(j, "meshes"); ++m) {
      const json* prims = Member(j["meshes"][m], "primitives");
      const std::string mesh = absl::StrCat("meshes[", m, "]");
      if (prims && prims->is_array() && prims->empty())
        return Invalid(file_, mesh + ".primitives", "an empty array");
      for (size_t p = 0; prims && prims->is_array() && p < prims->size(); ++p) {
        RETURN_IF_ERROR(Attributes(j, (*prims)[p], absl::StrCat(mesh, ".primitives[", p, "]")));
      }
    }
    return absl::OkStatus();
  }

  // A primitive's attribute names are glTF's semantics (or application-specific, "_NAME"); an
  // indexed one (TEXCOORD_n, COLOR_n, JOINTS_n, WEIGHTS_n) comes with all below n; and its
  // material reads no texture coordinate set it lacks.
  absl::Status Attributes(const json& j, const json& prim, const std::string& path) {
    const json* attrs = Member(prim, "attributes");
    if (attrs == nullptr || !attrs->is_object()) return absl::OkStatus();
    std::map<std::string, std::vector<uint32_t>> sets;  // "TEXCOORD" -> the n present
    for (const auto& [name, value] : attrs->items()) {
      const std::string field = absl::StrCat(path, ".attributes.", Quote(name));
      if (name.empty() || name[0] == '_') continue;
      if (name == "POSITION" || name == "NORMAL" || name == "TANGENT") continue;
      const size_t us = name.rfind('_');
      const std::string base = us == std::string::npos ? name : name.substr(0, us);
      const std::string digits = us == std::string::npos ? "" : name.substr(us + 1);
      uint32_t n = 0;
      const bool indexed = base == "TEXCOORD" || base == "COLOR" || base == "JOINTS" ||
                           base == "WEIGHTS";
      if (!indexed || digits.empty() || (digits.size() > 1 && digits[0] == '0') ||
          !std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; }) ||
          !absl::SimpleAtoi(digits, &n)) {
        return Invalid(file_, field, "not a glTF attribute semantic (POSITION, NORMAL, TANGENT, ",
                       "TEXCOORD_n, COLOR_n, JOINTS_n, WEIGHTS_n, or _NAME)");
      }
      sets[base].push_back(n);
    }
    for (auto& [base, indices] : sets) {
      std::sort(indices.begin(), indices.end());
      for (size_t k = 0; k < indices.size(); ++k) {
        if (indices[k] != k) {
          return Invalid(file_, path + ".attributes", base, "_", indices[k], " without ", base,
                         "_", k);
        }
      }
    }
    uint64_t material = 0;
    if (!JsonUint(Member(prim, "material"), &material) || material >= ArraySize(j, "materials"))
      return absl::OkStatus();
    const uint32_t needed = TexCoordSets(j["materials"][material]);
    const uint32_t have = sets.count("TEXCOORD") ? uint32_t(sets["TEXCOORD"].size()) : 0;
    if (needed > have) {
      return Invalid(file_, path + ".material", "materials[", material, "] reads TEXCOORD_",
                     needed - 1, ", which the primitive lacks (", have,
                     " texture coordinate sets)");
    }
    return absl::OkStatus();
  }

  // How many texture coordinate sets a material's textures read (the highest texCoord + 1,
  // KHR_texture_transform's override included); 0 without textures.
  static uint32_t TexCoordSets(const json& material) {
    uint32_t sets = 0;
    auto info = [&](const json* t) {
      if (t == nullptr || !t->is_object()) return;
      uint64_t tc = 0;
      if (!JsonUint(Member(*t, "texCoord"), &tc)) tc = 0;
      const json* tt = Member(Member(t, "extensions"), "KHR_texture_transform");
      if (uint64_t over = 0; JsonUint(Member(tt, "texCoord"), &over)) tc = over;
      sets = std::max<uint32_t>(sets, uint32_t(std::min<uint64_t>(tc, 1u << 20)) + 1);
    };
    const json* pbr = Member(material, "pbrMetallicRoughness");
    info(Member(pbr, "baseColorTexture"));
    info(Member(pbr, "metallicRoughnessTexture"));
    for (const char* key : {"normalTexture", "occlusionTexture", "emissiveTexture"})
      info(Member(material, key));
    const json* specular = Member(Member(material, "extensions"), "KHR_materials_specular");
    info(Member(specular, "specularTexture"));
    info(Member(specular, "specularColorTexture"));
    return sets;
  }

  // A node matrix is a transform glTF can animate as TRS: the bottom row (0, 0, 0, 1) and
  // orthogonal axes (no shear), within float rounding.
  absl::Status MatrixIsTrs(const json* m, const std::string& field) {
    if (m == nullptr || !m->is_array() || m->size() != 16) return absl::OkStatus();
    double v[16];
    for (int k = 0; k < 16; ++k) {
      if (!(*m)[k].is_number()) return absl::OkStatus();  // ValueRanges names it
      v[k] = (*m)[k].get<double>();
    }
    if (v[3] != 0.0 || v[7] != 0.0 || v[11] != 0.0 || v[15] != 1.0) {
      return Invalid(file_, field, "not a TRS transform: its last row is (", v[3], ", ", v[7],
                     ", ", v[11], ", ", v[15], "), not (0, 0, 0, 1)");
    }
    for (int a = 0; a < 3; ++a) {
      for (int b = a + 1; b < 3; ++b) {
        const double* x = &v[4 * a];
        const double* y = &v[4 * b];
        const double dot = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
        const double lx = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        const double ly = std::sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
        if (lx > 0.0 && ly > 0.0 && std::abs(dot) > 1e-4 * lx * ly) {
          return Invalid(file_, field, "not a TRS transform: columns ", a, " and ", b,
                         " are not orthogonal (sheared)");
        }
      }
    }
    return absl::OkStatus();
  }

  // Every extension object in the document (outside extras) is named in extensionsUsed, as
  // glTF 2.0 3.12 requires; `path` is where `o` is, e.g. "materials[0]".
  absl::Status DeclaredExtensions(const json& root, const json& o, const std::string& path) {
    if (o.is_array()) {
      for (size_t i = 0; i < o.size(); ++i)
        RETURN_IF_ERROR(DeclaredExtensions(root, o[i], absl::StrCat(path, "[", i, "]")));
      return absl::OkStatus();
    }
    if (!o.is_object()) return absl::OkStatus();
    for (const auto& [key, value] : o.items()) {
      if (key == "extras") continue;
      const std::string at = path.empty() ? key : absl::StrCat(path, ".", key);
      if (key == "extensions" && value.is_object()) {
        for (const auto& [name, ext] : value.items()) {
          if (!Lists(root, "extensionsUsed", name.c_str())) {
            return Invalid(file_, at + "." + Quote(name), "not declared in extensionsUsed");
          }
        }
      }
      RETURN_IF_ERROR(DeclaredExtensions(root, value, at));
    }
    return absl::OkStatus();
  }

  // EXT_mesh_gpu_instancing's objects, where extensionsUsed lists it: `attributes`, an object of
  // at least one accessor index each in range (tinygltf would read an empty object as none, and
  // an index past an int's range as another accessor). Types and counts: the importer.
  absl::Status Instancing(const json& j) {
    if (!Lists(j, "extensionsUsed", "EXT_mesh_gpu_instancing")) return absl::OkStatus();
    const size_t accessors = ArraySize(j, "accessors");
    for (size_t n = 0; n < ArraySize(j, "nodes"); ++n) {
      const json* ext = Member(Member(j["nodes"][n], "extensions"), "EXT_mesh_gpu_instancing");
      if (ext == nullptr) continue;
      const std::string field = absl::StrCat("nodes[", n, "].extensions.EXT_mesh_gpu_instancing");
      if (!ext->is_object()) return Invalid(file_, field, "not an object");
      const json* attributes = Member(*ext, "attributes");
      if (attributes == nullptr) return Invalid(file_, field + ".attributes", "missing");
      if (!attributes->is_object() || attributes->empty()) {
        return Invalid(file_, field + ".attributes",
                       "not an object naming at least one accessor (TRANSLATION, ROTATION, "
                       "SCALE, or the application's own)");
      }
      auto& named = result_->instancing[uint32_t(n)];
      for (const auto& [name, index] : attributes->items()) {
        uint64_t a = 0;
        if (!JsonUint(&index, &a) || a >= accessors) {
          return Invalid(file_, absl::StrCat(field, ".attributes.", name), "out of range (",
                         accessors, " accessors)");
        }
        named.emplace_back(name, uint32_t(a));
      }
    }
    return absl::OkStatus();
  }

  // Whether `name` is in the top-level array `list`.
  static bool Lists(const json& j, const char* list, const char* name) {
    const json* a = Member(j, list);
    if (a == nullptr || !a->is_array()) return false;
    return std::any_of(a->begin(), a->end(), [&](const json& e) { return e == name; });
  }

  // buffers[i].extensions.EXT_meshopt_compression.fallback (false when absent, or when
  // EXT_meshopt_compression is not in extensionsUsed: then the extension is ignored).
  absl::StatusOr<bool> MeshoptFallback(const json& b, const std::string& field) {
    const json* ext = meshopt_ ? Member(Member(b, "extensions"), "EXT_meshopt_compression")
                               : nullptr;
    const json* fallback = ext ? Member(*ext, "fallback") : nullptr;
    if (fallback == nullptr) return false;
    if (!fallback->is_boolean()) {
      return Invalid(file_, field + ".extensions.EXT_meshopt_compression.fallback",
                     "not a boolean");
    }
    return fallback->get<bool>();
  }

  // bufferViews[view].extensions.EXT_meshopt_compression: where the compressed bytes are and
  // what they decode to (count x byteStride = the bufferView's byteLength).
  absl::Status MeshoptBufferView(const json& ext, const std::string& field, uint32_t view,
                                 uint64_t view_length) {
    MeshoptView m;
    uint64_t buffer = 0, offset = 0, length = 0, stride = 0, count = 0;
    RETURN_IF_ERROR(BufferRange(ext, field, &buffer, &offset, &length));
    if (fallback_[buffer]) {
      return Invalid(file_, field + ".buffer", "buffers[", buffer,
                     "] is a fallback buffer with no data to decode");
    }
    if (!JsonUint(Member(ext, "byteStride"), &stride) || stride == 0 || stride > 256) {
      return Invalid(file_, field + ".byteStride", "missing or not in 1..256");
    }
    if (!JsonUint(Member(ext, "count"), &count) || count == 0) {
      return Invalid(file_, field + ".count", "missing or not a positive integer");
    }
    using Mode = MeshoptView::Mode;
    using Filter = MeshoptView::Filter;
    ASSIGN_OR_RETURN(m.mode, Enum<Mode>(Member(ext, "mode"), field + ".mode",
                                        {{"ATTRIBUTES", Mode::kAttributes},
                                         {"TRIANGLES", Mode::kTriangles},
                                         {"INDICES", Mode::kIndices}}));
    if (const json* filter = Member(ext, "filter")) {
      ASSIGN_OR_RETURN(m.filter, Enum<Filter>(filter, field + ".filter",
                                              {{"NONE", Filter::kNone},
                                               {"OCTAHEDRAL", Filter::kOctahedral},
                                               {"QUATERNION", Filter::kQuaternion},
                                               {"EXPONENTIAL", Filter::kExponential}}));
    }
    m.buffer = uint32_t(buffer);
    m.byte_offset = offset;
    m.byte_length = length;
    m.byte_stride = uint32_t(stride);
    m.count = count;
    if (const std::string bad = CheckMeshoptParameters(m); !bad.empty()) {
      return Invalid(file_, field, bad);
    }
    uint64_t decoded = 0;
    if (__builtin_mul_overflow(count, stride, &decoded) || decoded != view_length) {
      return Invalid(file_, field, "count x byteStride (", count, " x ", stride,
                     ") is not the bufferView's byteLength (", view_length, ")");
    }
    // meshopt's codecs compress at most ~64x (vertex data of zeros: 2 bits per 16 bytes; index
    // data: at least a byte per triangle): more claims bytes the data cannot hold, and would let
    // a few compressed bytes ask for gigabytes.
    if (decoded > 128 * length + 65536) {
      return Invalid(file_, field, "decodes to ", decoded, " bytes from ", length,
                     " compressed bytes, more than meshopt's codecs can encode");
    }
    result_->meshopt_views[view] = m;
    return absl::OkStatus();
  }

  absl::Status Images(const json& j) {
    const size_t count = ArraySize(j, "images"), views = ArraySize(j, "bufferViews");
    for (size_t i = 0; i < count; ++i) {
      const json& im = j["images"][i];
      const std::string field = absl::StrCat("images[", i, "]");
      uint64_t view = 0;
      if (const json* uri = Member(im, "uri")) {
        absl::StatusOr<size_t> have = Uri(field + ".uri", *uri);
        if (!have.ok()) return have.status();
        // tinygltf reads an image's file once per image that names it.
        if (*have != std::string::npos &&
            (__builtin_add_overflow(copied_bytes_, uint64_t(*have), &copied_bytes_) ||
             copied_bytes_ > 2 * file_set_bytes_)) {
          return Invalid(file_, field + ".uri", "images and buffers copy more than twice the ",
                         file_set_bytes_, " bytes of the file set");
        }
      } else if (const json* bv = Member(im, "bufferView");
                 bv && (!JsonUint(bv, &view) || view >= views)) {
        return Invalid(file_, field + ".bufferView", "out of range (", views, " bufferViews)");
      } else if (bv && Member(im, "mimeType") == nullptr) {
        return Invalid(file_, field + ".bufferView",
                       "needs a mimeType (image/png, image/jpeg, or image/webp with "
                       "EXT_texture_webp)");
      } else if (bv && result_->meshopt_views.count(uint32_t(view))) {
        // tinygltf reads image bytes straight from the buffer, before anything is decoded.
        return Invalid(file_, field + ".bufferView", "bufferViews[", view,
                       "] is meshopt-compressed; images cannot be");
      }
    }
    result_->image_needed.assign(count, false);
    result_->image_webp.assign(count, false);
    const bool webp = Lists(j, "extensionsUsed", "EXT_texture_webp");
    for (size_t t = 0; t < ArraySize(j, "textures"); ++t) {
      const json& texture = j["textures"][t];
      // EXT_texture_webp: the texture samples its WebP source; its core source (optional) is a
      // PNG or JPEG fallback for viewers without the extension, not decoded here.
      // Without a source the extension names no image: the core source is the texture's.
      const json* ext = webp ? Member(Member(texture, "extensions"), "EXT_texture_webp") : nullptr;
      if (ext && !ext->is_object()) {
        return Invalid(file_, absl::StrCat("textures[", t, "].extensions.EXT_texture_webp"),
                       "not an object");
      }
      if (const json* s = ext ? Member(*ext, "source") : nullptr) {
        const std::string field = absl::StrCat("textures[", t, "].extensions.EXT_texture_webp");
        uint64_t source = 0;
        if (!JsonUint(s, &source) || source >= count) {
          return Invalid(file_, field + ".source", "out of range (", count, " images)");
        }
        result_->image_needed[source] = true;
        result_->image_webp[source] = true;
        result_->webp_sources[uint32_t(t)] = uint32_t(source);
        continue;
      }
      uint64_t source = 0;
      if (JsonUint(Member(texture, "source"), &source) && source < count) {
        result_->image_needed[source] = true;
      }
    }
    return absl::OkStatus();
  }

  const std::string& file_;
  const GltfSource& src_;
  const GlbChunks* glb_;
  const ImportLimits& limits_;
  PreScanResult* result_;
  std::vector<uint64_t> buffer_lengths_;
  std::vector<bool> fallback_;  // per buffer: a meshopt fallback buffer without data
  bool meshopt_ = false;        // EXT_meshopt_compression is in extensionsUsed
  uint64_t decoded_bytes_ = 0;  // what the fallback buffers hold together
  const uint64_t file_set_bytes_;
  uint64_t copied_bytes_ = 0;  // what tinygltf will copy out of the file set
};

// Calls `change` on every number inside an "extensions" object (outside `extras`, an
// application's, which the importer reads none of); says whether it changed one. (The
// pre-scan's limit on the JSON's depth bounds the recursion.)
template <typename Change>
bool ChangeExtensionNumbers(json& v, const Change& change, bool in_extensions = false) {
  bool changed = false;
  if (v.is_object()) {
    for (auto& [key, value] : v.items()) {
      if (key == "extras") continue;
      changed |= ChangeExtensionNumbers(value, change, in_extensions || key == "extensions");
    }
  } else if (v.is_array()) {
    for (json& e : v) changed |= ChangeExtensionNumbers(e, change, in_extensions);
  } else if (in_extensions && v.is_number()) {
    changed |= change(v);
  }
  return changed;
}

// Makes each float inside an "extensions" object that is an integer (0.0, 2.0; up to 2^53) an
// integer: the validator reads them as integers, and so do the pre-scan's checks of an
// extension's indices after this. (A number field is read the same either way: files write
// integers there too, "emissiveStrength": 5.)
bool ExtensionFloatsToIntegers(json& j) {
  return ChangeExtensionNumbers(j, [](json& v) {
    if (!v.is_number_float()) return false;
    const double x = v.get<double>();
    if (!WholeNumber(x)) return false;
    v = int64_t(x);
    return true;
  });
}

// Makes each integer beyond 32 bits inside an "extensions" object a floating-point number:
// tinygltf keeps an extension's values as plain values, with an integer cast to int, so
// 4294967296 would read as 0 (a light index as light 0, an emissive strength as 0); as a double
// it reads as itself, and an index that large is refused where it is checked.
bool WidenExtensionIntegers(json& j) {
  return ChangeExtensionNumbers(j, [](json& v) {
    if (!v.is_number_integer()) return false;
    constexpr int64_t kMax = std::numeric_limits<int32_t>::max();
    constexpr int64_t kMin = std::numeric_limits<int32_t>::min();
    const bool wide = v.is_number_unsigned() ? v.get<uint64_t>() > uint64_t(kMax)
                                             : v.get<int64_t>() > kMax || v.get<int64_t>() < kMin;
    if (wide) v = v.get<double>();
    return wide;
  });
}

// What tinygltf 2.7 cannot read of the compression extensions, taken out of the JSON it reads:
//  - a buffer without a uri it refuses in a .gltf and hands the BIN chunk in a .glb; neither
//    fits a meshopt fallback buffer, which has no data. Each gets a 1-byte data: URI instead; the
//    importer sizes them (PreScanResult::fallback_buffers) and decodes into them.
//  - a Draco primitive's indices (an accessor without a bufferView) it refuses; they are removed
//    and the importer puts them back (PreScanResult::draco_indices).
// And integers beyond 32 bits in extensions become doubles (WidenExtensionIntegers), and core
// integer fields written as floats (1.0) are integers already (PreScan::Integer).
// A .glb is rebuilt around the new JSON chunk with its BIN chunk as it was.
absl::Status RewriteForTinygltf(const std::string& file, const std::vector<uint8_t>& bytes,
                                const GlbChunks& glb, const ImportLimits& limits, json* j,
                                PreScanResult* result) {
  for (const auto& [index, length] : result->fallback_buffers) {
    json& b = (*j)["buffers"][index];
    b["uri"] = "data:application/octet-stream;base64,AA==";
    b["byteLength"] = 1;
  }
  for (const auto& [primitive, accessor] : result->draco_indices) {
    (*j)["meshes"][primitive.first]["primitives"][primitive.second].erase("indices");
  }
  std::string text = j->dump();
  // Re-written numbers may take more room than the file's: the limits hold for this text too.
  if (text.size() > limits.max_json_bytes) {
    return OverLimit(file, "JSON", "re-written for tinygltf, ", text.size(),
                     " bytes exceed the max_json_bytes limit (", limits.max_json_bytes, ")");
  }
  std::vector<uint8_t>& out = result->rewritten;
  if (!result->is_glb) {
    out.assign(text.begin(), text.end());
    result->text = absl::string_view(reinterpret_cast<const char*>(out.data()), out.size());
    return absl::OkStatus();
  }
  text.resize((text.size() + 3) & ~size_t(3), ' ');
  const size_t length = ReadU32(&bytes[8]);
  const size_t rest_at = 20 + glb.json.size();  // the BIN chunk's header, if any
  const size_t rest = length > rest_at ? length - rest_at : 0;
  if (20 + text.size() + rest > std::numeric_limits<uint32_t>::max()) {
    return Invalid(file, "GLB", "re-written for tinygltf, 4 GiB or larger");
  }
  out.resize(20 + text.size() + rest);
  auto put32 = [&](size_t at, uint32_t v) {
    for (int k = 0; k < 4; ++k) out[at + k] = uint8_t(v >> (8 * k));
  };
  std::memcpy(out.data(), bytes.data(), 8);  // magic, version
  put32(8, uint32_t(out.size()));
  put32(12, uint32_t(text.size()));
  put32(16, 0x4E4F534Au);
  std::memcpy(out.data() + 20, text.data(), text.size());
  if (rest > 0) std::memcpy(out.data() + 20 + text.size(), bytes.data() + rest_at, rest);
  result->text = absl::string_view(reinterpret_cast<const char*>(out.data() + 20), text.size());
  return absl::OkStatus();
}

}  // namespace

// Cuts long strings (base64 URIs, tinygltf dumps) so messages stay readable.
std::string Quote(absl::string_view s) {
  return s.size() <= kMaxQuoted ? std::string(s) : absl::StrCat(s.substr(0, kMaxQuoted), "...");
}

absl::StatusOr<PreScanResult> PreScanGltf(const GltfSource& source, const ImportLimits& limits) {
  const std::string& file = source.main_file;
  const auto main = source.files.find(file);
  if (main == source.files.end()) return Invalid(Quote(file), "main file", "not in the file set");
  const std::vector<uint8_t>& bytes = main->second;
  if (bytes.empty()) return Invalid(file, "file", "the file is empty");
  const bool is_glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  if (!is_glb && absl::EndsWithIgnoreCase(file, ".glb")) {
    // A .glb that is not one (a renamed .gltf, a text or HTML error page): say so, instead of
    // a JSON error from whatever the file holds.
    std::string head;
    for (size_t i = 0; i < std::min<size_t>(bytes.size(), 4); ++i)
      absl::StrAppend(&head, i ? " " : "", absl::Hex(bytes[i], absl::kZeroPad2));
    return Invalid(file, "file",
                   absl::StrCat("not a GLB container: it starts with bytes ", head,
                                ", not the magic 'glTF' (67 6c 54 46); a JSON glTF file is "
                                "named .gltf"));
  }
  GlbChunks glb;
  absl::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  if (is_glb) {
    RETURN_IF_ERROR(ParseGlb(file, bytes, &glb));
    text = glb.json;
  } else if (bytes.size() > std::numeric_limits<uint32_t>::max()) {
    return Invalid(file, "file", "4 GiB or larger");
  }
  if (text.size() > limits.max_json_bytes) {
    return OverLimit(file, "JSON", text.size(), " bytes exceed the max_json_bytes limit (",
                     limits.max_json_bytes, ")");
  }
  const JsonShape shape = ScanJson(text, limits.max_json_depth);
  if (shape.depth > limits.max_json_depth) {
    return OverLimit(file, "JSON", "nested deeper than the max_json_depth limit (",
                     limits.max_json_depth, ")");
  }
  if (shape.values > limits.max_json_values) {
    return OverLimit(file, "JSON", "about ", shape.values,
                     " values exceed the max_json_values limit (", limits.max_json_values, ")");
  }
  PreScanResult result{.is_glb = is_glb, .bytes = &bytes, .text = text};
  try {
    json j = json::parse(text.begin(), text.end());
    if (ExtensionFloatsToIntegers(j)) result.integers_rewritten = true;
    RETURN_IF_ERROR(PreScan(source, is_glb ? &glb : nullptr, limits, &result).Run(j));
    const bool widened = WidenExtensionIntegers(j);
    if (widened || result.integers_rewritten || !result.fallback_buffers.empty() ||
        !result.draco_indices.empty()) {
      RETURN_IF_ERROR(RewriteForTinygltf(file, bytes, glb, limits, &j, &result));
    }
  } catch (const std::exception& e) {  // nlohmann reports parse and type errors by throwing
    return Invalid(file, "JSON", Quote(e.what()));
  }
  return result;
}

}  // namespace tessera::gltf_internal

#include "renderer/scene/import_limits.h"

#include <limits>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"

namespace tessera {

const std::vector<ImportLimitField>& ImportLimitFields() {
  using L = ImportLimits;
  auto u32 = [](const char* name, uint32_t L::*m) { return ImportLimitField{name, false, m, nullptr}; };
  auto u64 = [](const char* name, uint64_t L::*m) { return ImportLimitField{name, true, nullptr, m}; };
  static const std::vector<ImportLimitField> fields = {
      u64("max_json_bytes", &L::max_json_bytes),
      u32("max_json_depth", &L::max_json_depth),
      u64("max_json_values", &L::max_json_values),
      u32("max_nodes", &L::max_nodes),
      u32("max_node_depth", &L::max_node_depth),
      u32("max_meshes", &L::max_meshes),
      u32("max_primitives", &L::max_primitives),
      u64("max_accessor_elements", &L::max_accessor_elements),
      u64("max_accessor_bytes", &L::max_accessor_bytes),
      u64("max_vertices", &L::max_vertices),
      u64("max_indices", &L::max_indices),
      u32("max_image_dimension", &L::max_image_dimension),
      u64("max_image_bytes", &L::max_image_bytes),
      u64("max_total_image_bytes", &L::max_total_image_bytes),
      u32("max_textures", &L::max_textures),
      u32("max_materials", &L::max_materials),
      u32("max_lights", &L::max_lights),
      u32("max_drawables", &L::max_drawables),
      u64("max_decoded_bytes", &L::max_decoded_bytes),
      u64("max_animation_keys", &L::max_animation_keys),
      u32("max_skin_joints", &L::max_skin_joints),
      u32("max_morph_targets", &L::max_morph_targets),
  };
  return fields;
}

std::string ParseImportLimits(std::string_view spec, ImportLimits* limits) {
  ImportLimits out = *limits;
  for (absl::string_view item :
       absl::StrSplit(absl::string_view(spec.data(), spec.size()), ',', absl::SkipWhitespace())) {
    item = absl::StripAsciiWhitespace(item);
    const size_t eq = item.find('=');
    if (eq == absl::string_view::npos) return absl::StrCat("'", item, "' is not name=value");
    const absl::string_view name = absl::StripAsciiWhitespace(item.substr(0, eq));
    const absl::string_view text = absl::StripAsciiWhitespace(item.substr(eq + 1));
    const ImportLimitField* field = nullptr;
    for (const ImportLimitField& f : ImportLimitFields())
      if (name == f.name) field = &f;
    if (field == nullptr) return absl::StrCat("unknown limit '", name, "'");
    uint64_t value = 0;
    if (!absl::SimpleAtoi(text, &value))
      return absl::StrCat(name, ": '", text, "' is not a non-negative integer");
    if (field->is_64bit) {
      out.*(field->u64) = value;
    } else if (value > std::numeric_limits<uint32_t>::max()) {
      return absl::StrCat(name, ": ", value, " is larger than ", std::numeric_limits<uint32_t>::max());
    } else {
      out.*(field->u32) = uint32_t(value);
    }
  }
  *limits = out;
  return "";
}

}  // namespace tessera

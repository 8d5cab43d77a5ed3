#include "server/settings_wire.h"

#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/status_macros.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/message.h"

namespace tessera::server {
namespace {

namespace pb = google::protobuf;

// Each row of the table with its RenderSettings field (nullptr where the proto has none: the
// unit test catches that; here the row is skipped, never a crash).
using RowField = std::pair<const SettingRow*, const pb::FieldDescriptor*>;

const std::vector<RowField>& RowFields() {
  static const std::vector<RowField> fields = [] {
    std::vector<RowField> out;
    const pb::Descriptor* d = v1::RenderSettings::descriptor();
    for (const SettingRow& row : SettingsTable())
      out.emplace_back(&row, d->FindFieldByName(std::string(row.name)));
    return out;
  }();
  return fields;
}

// The field's value as the table's double (enums: the wire value, not yet shifted).
double GetWire(const pb::Message& m, const pb::FieldDescriptor* f) {
  const pb::Reflection* r = m.GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_BOOL: return r->GetBool(m, f) ? 1.0 : 0.0;
    case pb::FieldDescriptor::CPPTYPE_UINT32: return r->GetUInt32(m, f);
    case pb::FieldDescriptor::CPPTYPE_FLOAT: return r->GetFloat(m, f);
    case pb::FieldDescriptor::CPPTYPE_ENUM: return r->GetEnumValue(m, f);
    default: return 0.0;
  }
}

void SetWire(pb::Message* m, const pb::FieldDescriptor* f, double v) {
  const pb::Reflection* r = m->GetReflection();
  switch (f->cpp_type()) {
    case pb::FieldDescriptor::CPPTYPE_BOOL: r->SetBool(m, f, v != 0.0); break;
    case pb::FieldDescriptor::CPPTYPE_UINT32: r->SetUInt32(m, f, static_cast<uint32_t>(v)); break;
    case pb::FieldDescriptor::CPPTYPE_FLOAT: r->SetFloat(m, f, static_cast<float>(v)); break;
    case pb::FieldDescriptor::CPPTYPE_ENUM: r->SetEnumValue(m, f, static_cast<int>(v)); break;
    default: break;
  }
}

// The renderer's value of a set field; enums shift by one and must name a value.
absl::StatusOr<double> FromWire(const SettingRow& row, double wire) {
  if (row.type != SettingType::kEnum) return wire;
  const double v = wire - 1.0;
  if (!row.Valid(v))
    return absl::InvalidArgumentError(
        absl::StrCat("settings.", std::string(row.name), ": unknown value ", static_cast<int64_t>(wire)));
  return v;
}

double ToWire(const SettingRow& row, double v) {
  return row.type == SettingType::kEnum ? v + 1.0 : v;
}

}  // namespace

absl::StatusOr<Settings> MergeSettings(const Settings& base, const v1::RenderSettings& u) {
  Settings s = base;
  const pb::Reflection* r = u.GetReflection();
  for (const auto& [row, field] : RowFields()) {
    // Optional scalars: set or not; proto3 enums: not UNSPECIFIED (0).
    if (field == nullptr || !r->HasField(u, field)) continue;
    ASSIGN_OR_RETURN(const double v, FromWire(*row, GetWire(u, field)));
    row->set(s, v);
  }
  // The one text setting, outside the table: unset or empty leaves it as it was.
  if (u.has_animation() && !u.animation().empty()) s.animation = u.animation();
  RETURN_IF_ERROR(ValidateSettings(s));
  return s;
}

void ToProto(const Settings& s, v1::RenderSettings* out) {
  ToProto(s, SettingMask().set(), out);
}

void ToProto(const Settings& s, const SettingMask& fields, v1::RenderSettings* out) {
  size_t i = 0;
  for (const auto& [row, field] : RowFields()) {
    if (field != nullptr && fields.test(i)) SetWire(out, field, ToWire(*row, row->get(s)));
    ++i;
  }
  if (!s.animation.empty()) out->set_animation(s.animation);
}

void FillChoices(uint32_t sample_counts, v1::SettingChoices* o) {
  // The lists of SettingChoices by row name: enum names, and the uints with a fixed set.
  const pb::Descriptor* d = o->GetDescriptor();
  const pb::Reflection* r = o->GetReflection();
  for (const SettingRow& row : SettingsTable()) {
    const pb::FieldDescriptor* list = d->FindFieldByName(std::string(row.name));
    if (list == nullptr || !list->is_repeated()) continue;
    if (row.type == SettingType::kEnum &&
        list->cpp_type() == pb::FieldDescriptor::CPPTYPE_STRING) {
      for (std::string_view name : row.choices) r->AddString(o, list, std::string(name));
    } else if (list->cpp_type() == pb::FieldDescriptor::CPPTYPE_UINT32) {
      for (double v : row.allowed) {
        const auto n = static_cast<uint32_t>(v);
        // Samples: what the device has too (a GPU may offer 16 or more, the table stops at 8).
        if (row.name == "samples" && (sample_counts & n) == 0) continue;
        r->AddUInt32(o, list, n);
      }
    }
  }
  for (const SettingRow& row : SettingsTable()) {
    v1::SettingSpec* spec = o->add_settings();
    spec->set_name(std::string(row.name));
    spec->set_type(std::string(ToString(row.type)));
    spec->set_min(row.min);
    spec->set_max(row.max);
    for (std::string_view name : row.choices) spec->add_choices(std::string(name));
    for (double v : row.allowed) spec->add_allowed(v);
    spec->set_power_of_two(row.power_of_two);
    spec->set_range(row.RangeText());
    spec->set_default_value(row.Format(row.default_value));
    spec->set_label(std::string(row.label));
    spec->set_doc(std::string(row.doc));
  }
}

}  // namespace tessera::server

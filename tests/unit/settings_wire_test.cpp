// The settings table against the wire: every row has its RenderSettings field and every field
// its row, every field round-trips through ToProto/MergeSettings, unknown enum values and
// out-of-range values name the field, and the `tessera` CLI sends exactly the fields its flags
// name.
#include "server/settings_wire.h"

#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <set>
#include <string>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/message.h"

namespace tessera::server {
namespace {

namespace pb = google::protobuf;

const pb::FieldDescriptor* ProtoField(const SettingRow& row) {
  return v1::RenderSettings::descriptor()->FindFieldByName(std::string(row.name));
}

std::string Upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

// A valid value of the row that differs from its default.
double OtherValue(const SettingRow& row) {
  switch (row.type) {
    case SettingType::kBool: return 1.0 - row.default_value;
    case SettingType::kEnum:
      return static_cast<double>((static_cast<size_t>(row.default_value) + 1) % row.choices.size());
    case SettingType::kUint:
      if (!row.allowed.empty())
        return row.allowed.front() == row.default_value ? row.allowed.back() : row.allowed.front();
      return row.default_value == row.max ? row.min : row.max;
    case SettingType::kFloat: {
      const double v = row.default_value == 0.5 ? 0.25 : 0.5;
      return v >= row.min && v <= row.max ? v : row.max;
    }
  }
  return 0.0;
}

// Every field differs from Settings{} (and the whole is valid).
Settings EveryFieldChanged() {
  Settings s;
  for (const SettingRow& row : SettingsTable()) row.set(s, OtherValue(row));
  return s;
}

void ExpectSame(const Settings& a, const Settings& b, const std::string& what) {
  for (const SettingRow& row : SettingsTable())
    EXPECT_EQ(row.get(a), row.get(b)) << what << ": " << row.name;
}

TEST(SettingsWireTest, EveryRowHasItsProtoFieldAndEveryFieldItsRow) {
  std::set<std::string> rows;
  for (const SettingRow& row : SettingsTable()) {
    rows.insert(std::string(row.name));
    const pb::FieldDescriptor* f = ProtoField(row);
    ASSERT_NE(f, nullptr) << "settings.proto has no RenderSettings." << row.name;
    EXPECT_FALSE(f->is_repeated()) << row.name;
    pb::FieldDescriptor::CppType want = pb::FieldDescriptor::CPPTYPE_BOOL;
    switch (row.type) {
      case SettingType::kBool: want = pb::FieldDescriptor::CPPTYPE_BOOL; break;
      case SettingType::kUint: want = pb::FieldDescriptor::CPPTYPE_UINT32; break;
      case SettingType::kFloat: want = pb::FieldDescriptor::CPPTYPE_FLOAT; break;
      case SettingType::kEnum: want = pb::FieldDescriptor::CPPTYPE_ENUM; break;
    }
    EXPECT_EQ(f->cpp_type(), want) << row.name << " is " << ToString(row.type) << " in the table, "
                                   << f->cpp_type_name() << " in the proto";
    // Unset must be distinguishable from a value: optional scalars, enums with UNSPECIFIED = 0.
    if (row.type == SettingType::kEnum) {
      EXPECT_EQ(f->enum_type()->value(0)->number(), 0) << row.name;
    } else {
      EXPECT_TRUE(f->has_presence()) << row.name << " must be `optional` in settings.proto";
    }
  }
  const pb::Descriptor* d = v1::RenderSettings::descriptor();
  for (int i = 0; i < d->field_count(); ++i) {
    if (d->field(i)->name() == "animation") continue;  // the one text setting (settings.h)
    EXPECT_EQ(rows.count(d->field(i)->name()), 1u)
        << "RenderSettings." << d->field(i)->name() << " has no row in the settings table";
  }
}

TEST(SettingsWireTest, EnumNamesAreTheProtoValueNames) {
  for (const SettingRow& row : SettingsTable()) {
    if (row.type != SettingType::kEnum) continue;
    const pb::EnumDescriptor* e = ProtoField(row)->enum_type();
    ASSERT_EQ(static_cast<size_t>(e->value_count()), row.choices.size() + 1) << row.name;
    for (size_t i = 0; i < row.choices.size(); ++i) {
      const pb::EnumValueDescriptor* v = e->FindValueByNumber(static_cast<int>(i) + 1);
      ASSERT_NE(v, nullptr) << row.name << " " << i;
      EXPECT_TRUE(absl::EndsWith(v->name(), "_" + Upper(row.choices[i])))
          << row.name << ": " << v->name() << " vs " << row.choices[i];
    }
  }
}

TEST(SettingsWireTest, EveryFieldRoundTrips) {
  const Settings changed = EveryFieldChanged();
  ASSERT_TRUE(ValidateSettings(changed).ok()) << ValidateSettings(changed);
  for (const auto& [from, base] : {std::pair{changed, Settings{}}, std::pair{Settings{}, changed}}) {
    v1::RenderSettings wire;
    ToProto(from, &wire);
    absl::StatusOr<Settings> back = MergeSettings(base, wire);
    ASSERT_TRUE(back.ok()) << back.status();
    ExpectSame(*back, from, wire.ShortDebugString());
  }
  // One field at a time, every enum value and every other row's non-default value.
  for (const SettingRow& row : SettingsTable()) {
    std::vector<double> values = {OtherValue(row)};
    for (size_t i = 0; i < row.choices.size(); ++i) values.push_back(static_cast<double>(i));
    for (double v : values) {
      Settings s;
      row.set(s, v);
      v1::RenderSettings wire;
      ToProto(s, SettingMask().set(SettingIndex(row)), &wire);
      absl::StatusOr<Settings> back = MergeSettings(changed, wire);
      ASSERT_TRUE(back.ok()) << row.name << ": " << back.status();
      EXPECT_EQ(row.get(*back), v) << row.name;
      for (const SettingRow& other : SettingsTable()) {
        if (&other != &row) {
          EXPECT_EQ(other.get(*back), other.get(changed)) << other.name;
        }
      }
    }
  }
}

TEST(SettingsWireTest, MaskedToProtoSetsOnlyTheNamedFields) {
  const Settings changed = EveryFieldChanged();
  for (const SettingRow& row : SettingsTable()) {
    v1::RenderSettings wire;
    ToProto(changed, SettingMask().set(SettingIndex(row)), &wire);
    std::vector<const pb::FieldDescriptor*> set;
    wire.GetReflection()->ListFields(wire, &set);
    ASSERT_EQ(set.size(), 1u) << row.name << ": " << wire.ShortDebugString();
    EXPECT_EQ(set[0]->name(), row.name);
  }
  v1::RenderSettings none;
  ToProto(changed, SettingMask(), &none);
  EXPECT_EQ(none.ByteSizeLong(), 0u);
}

TEST(SettingsWireTest, UnknownEnumValuesNameTheField) {
  for (const SettingRow& row : SettingsTable()) {
    if (row.type != SettingType::kEnum) continue;
    const pb::FieldDescriptor* f = ProtoField(row);
    for (int wire : {static_cast<int>(row.choices.size()) + 1, -1, 1000}) {
      v1::RenderSettings u;
      u.GetReflection()->SetEnumValue(&u, f, wire);
      const absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
      ASSERT_FALSE(s.ok()) << row.name << " " << wire;
      EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
      EXPECT_EQ(std::string(s.status().message()),
                absl::StrCat("settings.", std::string(row.name), ": unknown value ", wire));
    }
    // UNSPECIFIED keeps the base.
    v1::RenderSettings u;
    const Settings changed = EveryFieldChanged();
    const absl::StatusOr<Settings> s = MergeSettings(changed, u);
    ASSERT_TRUE(s.ok());
    EXPECT_EQ(row.get(*s), row.get(changed)) << row.name;
  }
}

TEST(SettingsWireTest, OutOfRangeValuesNameTheField) {
  int checked = 0;
  for (const SettingRow& row : SettingsTable()) {
    if (row.type != SettingType::kUint && row.type != SettingType::kFloat) continue;
    std::vector<double> bad;
    if (row.type == SettingType::kFloat) {
      bad = {std::nextafter(static_cast<float>(row.min), -INFINITY),
             std::nextafter(static_cast<float>(row.max), INFINITY), NAN};
    } else {
      if (row.min > 0) bad.push_back(row.min - 1);
      if (row.max < 4294967295.0) bad.push_back(row.max + 1);
    }
    for (double v : bad) {
      v1::RenderSettings u;
      const pb::FieldDescriptor* f = ProtoField(row);
      if (row.type == SettingType::kFloat) {
        u.GetReflection()->SetFloat(&u, f, static_cast<float>(v));
      } else {
        u.GetReflection()->SetUInt32(&u, f, static_cast<uint32_t>(v));
      }
      const absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
      ASSERT_FALSE(s.ok()) << row.name << " = " << v;
      EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument);
      EXPECT_TRUE(absl::StartsWith(s.status().message(), absl::StrCat("settings.", std::string(row.name), ": ")))
          << s.status();
      ++checked;
    }
  }
  EXPECT_GE(checked, 20);
}

TEST(SettingsWireTest, ChoicesDescribeEveryRow) {
  v1::SettingChoices choices;
  FillChoices(/*sample_counts=*/0b101, &choices);  // 1x and 4x, like lavapipe
  EXPECT_EQ(std::vector<uint32_t>(choices.samples().begin(), choices.samples().end()),
            (std::vector<uint32_t>{1, 4}));
  EXPECT_EQ(std::vector<uint32_t>(choices.tile_size().begin(), choices.tile_size().end()),
            (std::vector<uint32_t>{8, 16, 32}));
  ASSERT_EQ(static_cast<size_t>(choices.settings_size()), SettingsTable().size());
  for (size_t i = 0; i < SettingsTable().size(); ++i) {
    const SettingRow& row = SettingsTable()[i];
    const v1::SettingSpec& spec = choices.settings(static_cast<int>(i));
    EXPECT_EQ(spec.name(), row.name);
    EXPECT_EQ(spec.type(), ToString(row.type));
    EXPECT_EQ(spec.min(), row.min) << row.name;
    EXPECT_EQ(spec.max(), row.max) << row.name;
    EXPECT_EQ(spec.default_value(), row.Format(row.default_value)) << row.name;
    EXPECT_EQ(spec.label(), row.label);
    EXPECT_EQ(spec.doc(), row.doc);
    EXPECT_FALSE(spec.range().empty()) << row.name;
    ASSERT_EQ(static_cast<size_t>(spec.choices_size()), row.choices.size()) << row.name;
    EXPECT_EQ(static_cast<size_t>(spec.allowed_size()), row.allowed.size()) << row.name;
    if (row.type == SettingType::kEnum) {
      // The enum lists of SettingChoices hold the same names.
      const pb::FieldDescriptor* list = choices.GetDescriptor()->FindFieldByName(spec.name());
      ASSERT_NE(list, nullptr) << "SettingChoices has no list for " << row.name;
      const pb::Reflection* r = choices.GetReflection();
      ASSERT_EQ(static_cast<size_t>(r->FieldSize(choices, list)), row.choices.size());
      for (size_t c = 0; c < row.choices.size(); ++c) {
        EXPECT_EQ(r->GetRepeatedString(choices, list, static_cast<int>(c)), row.choices[c]);
        EXPECT_EQ(spec.choices(static_cast<int>(c)), row.choices[c]);
      }
    }
  }
  const v1::SettingSpec& bloom = choices.settings(static_cast<int>(SettingIndex(*FindSetting("bloom_strength"))));
  EXPECT_EQ(bloom.default_value(), "0.05");
  EXPECT_EQ(bloom.max(), 1.0);
}

// What `tessera render|stream|bench|job` does with its settings flags (RenderFlags): parse with
// the table, then send only the named fields.
v1::RenderSettings CliRequest(const std::vector<std::vector<std::string>>& flags) {
  Settings parsed;
  SettingMask named;
  for (const std::vector<std::string>& f : flags) {
    size_t next = 1;
    const absl::StatusOr<bool> r = ParseSettingFlag(
        f[0], [&] { return next < f.size() ? f[next++] : std::string(); }, &parsed, &named);
    EXPECT_TRUE(r.ok() && *r) << f[0];
  }
  v1::RenderSettings out;
  ToProto(parsed, named, &out);
  return out;
}

TEST(SettingsWireTest, CliSendsOnlyTheFieldsItsFlagsName) {
  EXPECT_EQ(CliRequest({}).ByteSizeLong(), 0u);
  EXPECT_EQ(CliRequest({{"--aa", "msaa"}, {"--samples", "2"}}).ShortDebugString(),
            "aa: AA_MSAA samples: 2");
  EXPECT_EQ(CliRequest({{"--exposure", "1.5"}}).ShortDebugString(),
            "exposure_mode: EXPOSURE_FIXED exposure_ev: 1.5");
  EXPECT_EQ(CliRequest({{"--auto-exposure"}, {"--exposure", "-1"}}).ShortDebugString(),
            "exposure_mode: EXPOSURE_AUTO exposure_ev: -1");
  EXPECT_EQ(CliRequest({{"--light-radius", "0.5,2"}}).ShortDebugString(),
            "light_radius_min: 0.5 light_radius_max: 2");
  EXPECT_EQ(CliRequest({{"--no-shadows"}, {"--chroma", "444"}}).ShortDebugString(),
            "shadows: false jpeg_444: true");
  EXPECT_EQ(CliRequest({{"--lights", "64"}, {"--debug", "cascades"}, {"--quality", "70"}})
                .ShortDebugString(),
            "synthetic_lights: 64 debug_view: DEBUG_CASCADES jpeg_quality: 70");
  EXPECT_EQ(CliRequest({{"--shadow-atlas", "1024"}, {"--animate-lights"}, {"--ssao-full-res"}})
                .ShortDebugString(),
            "lights_animated: true shadow_atlas_size: 1024 ssao_half_res: false");
  // A value the server rejects still goes out as given (the server names the field).
  EXPECT_EQ(CliRequest({{"--samples", "3"}}).ShortDebugString(), "samples: 3");
  // Every flag of the table sends its own field(s).
  for (const SettingRow& row : SettingsTable()) {
    for (const SettingFlag& f : row.flags) {
      std::vector<std::string> args = {absl::StrCat("--", std::string(f.flag))};
      if (f.form == SettingFlag::Form::kValue) args.push_back(row.Format(OtherValue(row)));
      if (f.form == SettingFlag::Form::kWord) args.push_back(std::string(f.words.back().first));
      if (f.form == SettingFlag::Form::kPair) args.push_back("1,2");
      const v1::RenderSettings wire = CliRequest({args});
      EXPECT_TRUE(wire.GetReflection()->HasField(wire, ProtoField(row))) << args[0];
    }
  }
}

}  // namespace
}  // namespace tessera::server

// The settings table: every row is consistent with Settings, ValidateSettings enforces every
// row's range at both ends, every enum value has its name, and every command-line form parses.
#include "renderer/settings_table.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace tessera {
namespace {

std::string Message(const absl::Status& status) { return std::string(status.message()); }

// --- rows -------------------------------------------------------------------------------------

TEST(SettingsTableTest, RowsAreUniqueAndDescribed) {
  std::set<std::string_view> names, flags;
  ASSERT_LE(SettingsTable().size(), kMaxSettings);
  for (const SettingRow& row : SettingsTable()) {
    EXPECT_TRUE(names.insert(row.name).second) << "duplicate row " << row.name;
    EXPECT_FALSE(row.label.empty()) << row.name;
    EXPECT_FALSE(row.doc.empty()) << row.name;
    EXPECT_EQ(FindSetting(row.name), &row);
    EXPECT_EQ(&SettingsTable()[SettingIndex(row)], &row);
    // The default is Settings{}'s and is valid.
    EXPECT_EQ(row.default_value, row.get(Settings{})) << row.name;
    EXPECT_TRUE(row.Valid(row.default_value)) << row.name;
    EXPECT_FALSE(row.RangeText().empty()) << row.name;
    for (const SettingFlag& f : row.flags) {
      EXPECT_TRUE(flags.insert(f.flag).second) << "flag --" << f.flag << " used twice";
      if (f.form == SettingFlag::Form::kToggle) {
        EXPECT_EQ(row.type, SettingType::kBool);
      }
      if (f.form == SettingFlag::Form::kPair) {
        EXPECT_NE(FindSetting(f.second), nullptr);
      }
      if (!f.also.empty()) {
        EXPECT_NE(FindSetting(f.also), nullptr) << f.flag;
      }
    }
  }
  EXPECT_EQ(FindSetting("no_such_setting"), nullptr);
}

TEST(SettingsTableTest, GetAndSetReachTheirOwnFieldOnly) {
  for (const SettingRow& row : SettingsTable()) {
    Settings s;
    const double other = row.type == SettingType::kBool ? 1.0 - row.default_value
                         : row.default_value == row.max ? row.min
                                                         : row.max;
    row.set(s, other);
    EXPECT_EQ(row.get(s), other) << row.name;
    for (const SettingRow& r : SettingsTable()) {
      if (&r != &row) {
        EXPECT_EQ(r.get(s), r.default_value) << row.name << " changed " << r.name;
      }
    }
  }
}

// --- validation -------------------------------------------------------------------------------

// Values just outside a row's range: one below min and one above max (the next float for floats;
// skipped where the type cannot hold them).
std::vector<double> JustOutside(const SettingRow& row) {
  std::vector<double> out;
  if (row.type == SettingType::kFloat) {
    out.push_back(std::nextafter(static_cast<float>(row.min), -INFINITY));
    out.push_back(std::nextafter(static_cast<float>(row.max), INFINITY));
    out.push_back(std::numeric_limits<float>::quiet_NaN());
    out.push_back(INFINITY);
  } else if (row.type == SettingType::kUint) {
    if (row.min > 0) out.push_back(row.min - 1);
    if (row.max < 4294967295.0) out.push_back(row.max + 1);
  } else if (row.type == SettingType::kEnum) {
    out.push_back(static_cast<double>(row.choices.size()));
  }
  return out;
}

TEST(SettingsTableTest, ValidateRejectsOnePastEachEndOfEveryRange) {
  int checked = 0;
  for (const SettingRow& row : SettingsTable()) {
    if (row.type == SettingType::kBool) continue;
    // Both ends are valid.
    for (double v : {row.min, row.max}) {
      Settings s;
      row.set(s, v);
      EXPECT_TRUE(ValidateSettings(s).ok()) << row.name << " = " << v << ": " << ValidateSettings(s);
    }
    for (double v : JustOutside(row)) {
      Settings s;
      row.set(s, v);
      const absl::Status st = ValidateSettings(s);
      EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument) << row.name << " = " << v;
      EXPECT_EQ(Message(st).rfind(std::string("settings.") + std::string(row.name) + ": ", 0), 0u)
          << st;
      EXPECT_NE(Message(st).find(" is out of range (" + row.RangeText() + ")"), std::string::npos)
          << st;
      ++checked;
    }
  }
  EXPECT_GE(checked, 20);
}

TEST(SettingsTableTest, ValidateKeepsAllowedSetsAndPowersOfTwo) {
  for (const SettingRow& row : SettingsTable()) {
    for (double v : row.allowed) {
      Settings s;
      row.set(s, v);
      EXPECT_TRUE(ValidateSettings(s).ok()) << row.name << " = " << v;
      if (v + 1 < row.max && std::find(row.allowed.begin(), row.allowed.end(), v + 1) ==
                                 row.allowed.end()) {
        row.set(s, v + 1);
        EXPECT_FALSE(ValidateSettings(s).ok()) << row.name << " = " << v + 1;
      }
    }
    if (row.power_of_two) {
      Settings s;
      row.set(s, row.min * 2);
      EXPECT_TRUE(ValidateSettings(s).ok()) << row.name;
      row.set(s, row.min + 1);
      EXPECT_FALSE(ValidateSettings(s).ok()) << row.name;
    }
  }
}

TEST(SettingsTableTest, CrossFieldRuleStays) {
  Settings s;
  s.light_radius_min = 2.0f;
  s.light_radius_max = 1.0f;
  EXPECT_EQ(Message(ValidateSettings(s)),
            "settings.light_radius_max: 1 is out of range (>= light_radius_min)");
  s.light_radius_max = 0.0f;  // auto
  EXPECT_TRUE(ValidateSettings(s).ok());
}

TEST(SettingsTableTest, MessagesKeepTheirForm) {
  Settings s;
  s.width = 0;
  EXPECT_EQ(Message(ValidateSettings(s)), "settings.width: 0 is out of range (1..16384)");
  s = Settings{};
  s.exposure_ev = 21.0f;
  EXPECT_EQ(Message(ValidateSettings(s)), "settings.exposure_ev: 21 is out of range (-20..20 stops)");
  s = Settings{};
  s.samples = 3;
  EXPECT_EQ(Message(ValidateSettings(s)), "settings.samples: 3 is out of range (1, 2, 4 or 8)");
}

// --- enums ------------------------------------------------------------------------------------

// The typed name of an enum row's value (settings.h's ToString); a new enum row needs a line here
// (EveryEnumValueOfEveryRowRoundTrips fails until it has one).
std::optional<std::string> TypedName(std::string_view row, const Settings& s) {
  if (row == "aa") return std::string(ToString(s.aa));
  if (row == "culling") return std::string(ToString(s.culling));
  if (row == "exposure_mode") return std::string(ToString(s.exposure_mode));
  if (row == "tonemapper") return std::string(ToString(s.tonemapper));
  if (row == "debug_view") return std::string(ToString(s.debug_view));
  if (row == "pipeline") return std::string(ToString(s.pipeline));
  if (row == "post_stage") return std::string(ToString(s.post_stage));
  if (row == "light_binning") return std::string(ToString(s.light_binning));
  if (row == "vis_mlaa_coverage") return std::string(ToString(s.vis_mlaa_coverage));
  return std::nullopt;
}

TEST(SettingsTableTest, EveryEnumValueOfEveryRowRoundTrips) {
  int enums = 0;
  for (const SettingRow& row : SettingsTable()) {
    if (row.type != SettingType::kEnum) continue;
    ++enums;
    ASSERT_GE(row.choices.size(), 2u) << row.name;
    std::set<std::string_view> seen;
    for (size_t i = 0; i < row.choices.size(); ++i) {
      EXPECT_TRUE(seen.insert(row.choices[i]).second) << row.name << ": " << row.choices[i];
      Settings s;
      row.set(s, static_cast<double>(i));
      EXPECT_EQ(row.Format(row.get(s)), row.choices[i]);
      const std::optional<std::string> typed = TypedName(row.name, s);
      ASSERT_TRUE(typed.has_value()) << "no typed ToString for enum row " << row.name;
      EXPECT_EQ(*typed, row.choices[i]);
      EXPECT_TRUE(ValidateSettings(s).ok()) << row.name << " " << row.choices[i];
    }
    // One past the last value is rejected, named by its number.
    Settings s;
    row.set(s, static_cast<double>(row.choices.size()));
    EXPECT_EQ(Message(ValidateSettings(s)),
              absl::StrCat("settings.", std::string(row.name), ": ", row.choices.size(),
                           " is out of range (", row.RangeText(), ")"));
  }
  EXPECT_EQ(enums, 9);
}

// --- command line -----------------------------------------------------------------------------

struct Parsed {
  absl::StatusOr<bool> result;
  Settings settings;
  SettingMask set;
};

// Parses `args` (a flag and its value, if any) as one settings flag, like both tools do.
Parsed ParseArgs(std::vector<std::string> args, Settings base = {}, SettingMask set = {}) {
  Parsed p{false, base, set};
  size_t next = 1;
  p.result = ParseSettingFlag(
      args[0],
      [&]() -> std::string {
        EXPECT_LT(next, args.size()) << args[0] << " asked for a value it has not";
        return next < args.size() ? args[next++] : "";
      },
      &p.settings, &p.set);
  if (p.result.ok() && *p.result) {
    EXPECT_EQ(next, args.size()) << args[0] << " left its value";
  }
  return p;
}

// A valid value of the row other than its default, as the command line spells it.
std::string OtherValueText(const SettingRow& row, double* value) {
  if (row.type == SettingType::kEnum) {
    const size_t i = (static_cast<size_t>(row.default_value) + 1) % row.choices.size();
    *value = static_cast<double>(i);
    return std::string(row.choices[i]);
  }
  if (!row.allowed.empty()) {
    *value = row.allowed.front() == row.default_value ? row.allowed.back() : row.allowed.front();
  } else if (row.power_of_two) {
    *value = row.min == row.default_value ? row.max : row.min;
  } else if (row.type == SettingType::kFloat) {
    *value = row.default_value == 0.5 ? 0.25 : 0.5;
    if (*value < row.min || *value > row.max) *value = row.max;
  } else {
    *value = row.default_value == row.max ? row.min : row.max;
  }
  return row.Format(*value);
}

TEST(ParseSettingFlagTest, EveryFlagFormOfEveryRow) {
  int flags = 0;
  for (const SettingRow& row : SettingsTable()) {
    for (const SettingFlag& f : row.flags) {
      ++flags;
      const std::string flag = absl::StrCat("--", std::string(f.flag));
      std::vector<std::pair<std::vector<std::string>, double>> cases;  // args, the row's value
      switch (f.form) {
        case SettingFlag::Form::kValue: {
          double v = 0;
          const std::string text = OtherValueText(row, &v);
          cases.push_back({{flag, text}, v});
          break;
        }
        case SettingFlag::Form::kToggle:
          cases.push_back({{flag}, 1.0});
          cases.push_back({{absl::StrCat("--no-", std::string(f.flag))}, 0.0});
          break;
        case SettingFlag::Form::kConstant:
          cases.push_back({{flag}, f.constant});
          break;
        case SettingFlag::Form::kWord:
          for (const auto& [word, v] : f.words) cases.push_back({{flag, std::string(word)}, v});
          break;
        case SettingFlag::Form::kPair:
          cases.push_back({{flag, "0.5,2"}, 0.5});
          break;
      }
      for (const auto& [args, want] : cases) {
        const Parsed p = ParseArgs(args);
        ASSERT_TRUE(p.result.ok()) << args[0] << ": " << p.result.status();
        EXPECT_TRUE(*p.result) << args[0];
        EXPECT_EQ(row.get(p.settings), want) << args[0];
        EXPECT_TRUE(p.set.test(SettingIndex(row))) << args[0];
        if (f.form == SettingFlag::Form::kPair) {
          const SettingRow* second = FindSetting(f.second);
          EXPECT_EQ(second->get(p.settings), 2.0);
          EXPECT_TRUE(p.set.test(SettingIndex(*second)));
        }
        // Nothing else changed or was marked, but the rows the flag names.
        for (const SettingRow& r : SettingsTable()) {
          const bool named = &r == &row || r.name == f.second || r.name == f.also;
          if (!named) {
            EXPECT_EQ(r.get(p.settings), r.default_value) << args[0] << " changed " << r.name;
            EXPECT_FALSE(p.set.test(SettingIndex(r))) << args[0] << " marked " << r.name;
          }
        }
      }
    }
  }
  EXPECT_GE(flags, 30);
}

TEST(ParseSettingFlagTest, TheFlagsUsersKnow) {
  Parsed p = ParseArgs({"--lights", "5000"});
  EXPECT_EQ(p.settings.synthetic_lights, 5000u);
  p = ParseArgs({"--debug", "ssao"});
  EXPECT_EQ(p.settings.debug_view, DebugView::kSsao);
  p = ParseArgs({"--debug", "bloom"});
  EXPECT_EQ(p.settings.debug_view, DebugView::kBloom);
  p = ParseArgs({"--quality", "50"});
  EXPECT_EQ(p.settings.jpeg_quality, 50u);
  p = ParseArgs({"--shadow-atlas", "2048"});
  EXPECT_EQ(p.settings.shadow_atlas_size, 2048u);
  p = ParseArgs({"--animate-lights"});
  EXPECT_TRUE(p.settings.lights_animated);
  p = ParseArgs({"--ssao-full-res"});
  EXPECT_FALSE(p.settings.ssao_half_res);
  p = ParseArgs({"--auto-exposure"});
  EXPECT_EQ(p.settings.exposure_mode, ExposureMode::kAuto);
  p = ParseArgs({"--chroma", "444"});
  EXPECT_TRUE(p.settings.jpeg_444);
  p = ParseArgs({"--chroma", "420"}, p.settings);
  EXPECT_FALSE(p.settings.jpeg_444);
  p = ParseArgs({"--light-radius", "0.25,3"});
  EXPECT_EQ(p.settings.light_radius_min, 0.25f);
  EXPECT_EQ(p.settings.light_radius_max, 3.0f);
  p = ParseArgs({"--no-scene-lights"});
  EXPECT_FALSE(p.settings.scene_lights);
  p = ParseArgs({"--exposure", "1e300"});  // beyond float: infinite, which validation refuses
  ASSERT_TRUE(p.result.ok());
  EXPECT_TRUE(std::isinf(p.settings.exposure_ev));
  EXPECT_FALSE(ValidateSettings(p.settings).ok());
  p = ParseArgs({"--width", "0"});  // ranges are the server's (or ValidateSettings') business
  EXPECT_TRUE(p.result.ok());
  EXPECT_EQ(p.settings.width, 0u);
}

TEST(ParseSettingFlagTest, ExposureIsFixedUnlessAutoWasGiven) {
  const SettingRow& mode = *FindSetting("exposure_mode");
  Parsed p = ParseArgs({"--exposure", "1.5"});
  EXPECT_EQ(p.settings.exposure_ev, 1.5f);
  EXPECT_EQ(p.settings.exposure_mode, ExposureMode::kFixed);
  EXPECT_TRUE(p.set.test(SettingIndex(mode)));  // sent, so a session's auto turns fixed
  // --auto-exposure first: --exposure compensates and leaves the mode auto.
  p = ParseArgs({"--auto-exposure"});
  p = ParseArgs({"--exposure", "-2"}, p.settings, p.set);
  EXPECT_EQ(p.settings.exposure_mode, ExposureMode::kAuto);
  EXPECT_EQ(p.settings.exposure_ev, -2.0f);
  // --auto-exposure after --exposure wins too.
  p = ParseArgs({"--exposure", "1"});
  p = ParseArgs({"--auto-exposure"}, p.settings, p.set);
  EXPECT_EQ(p.settings.exposure_mode, ExposureMode::kAuto);
}

TEST(ParseSettingFlagTest, BadValuesNameTheFlag) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"--width", "x"}, "--width: not a non-negative integer: 'x'"},
      {{"--lights", "-1"}, "--lights: not a non-negative integer: '-1'"},
      {{"--exposure", "nan"}, "--exposure: not a number: 'nan'"},
      {{"--ssao-radius", "big"}, "--ssao-radius: not a number: 'big'"},
      {{"--aa", "bogus"}, "--aa: 'bogus' is not one of none|msaa|fxaa|taa|vis_mlaa"},
      {{"--debug", "x"},
       "--debug: 'x' is not one of none|normals|depth|base_color|light_heatmap|culling_overlay|"
       "aa_mask|shadow_atlas|cascades|ssao|bloom"},
      {{"--chroma", "422"}, "--chroma wants 420 or 444"},
      {{"--light-radius", "1"}, "--light-radius wants MIN,MAX, got '1'"},
      {{"--light-radius", "1,x"}, "--light-radius: not a number: 'x'"},
  };
  for (const auto& [args, want] : cases) {
    const Parsed p = ParseArgs(args);
    ASSERT_FALSE(p.result.ok()) << args[0] << " " << args[1];
    EXPECT_EQ(p.result.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_EQ(Message(p.result.status()), want);
    EXPECT_TRUE(p.set.none()) << args[0];
  }
}

TEST(ParseSettingFlagTest, OtherFlagsAreNotTaken) {
  for (const char* flag : {"--scene", "--out", "--camera", "--frames", "--json", "width",
                           "--no-width", "--no-lights", "-aa", "--shadows-x", "--no-"}) {
    const Parsed p = ParseArgs({flag});
    ASSERT_TRUE(p.result.ok()) << flag;
    EXPECT_FALSE(*p.result) << flag;
    EXPECT_TRUE(p.set.none()) << flag;
  }
}

TEST(ParseSettingFlagTest, UsageListsEveryFlag) {
  const std::string usage = SettingsFlagsUsage();
  for (const SettingRow& row : SettingsTable()) {
    for (const SettingFlag& f : row.flags) {
      const std::string spelled = f.form == SettingFlag::Form::kToggle
                                      ? absl::StrCat("--[no-]", std::string(f.flag), " ")
                                      : absl::StrCat("--", std::string(f.flag), " ");
      EXPECT_NE(usage.find(spelled), std::string::npos) << spelled << "\n" << usage;
    }
  }
  EXPECT_NE(usage.find("--width N"), std::string::npos);
  EXPECT_NE(usage.find("(default 1280)"), std::string::npos) << usage;
  EXPECT_NE(usage.find("none|msaa|fxaa|taa|vis_mlaa"), std::string::npos) << usage;
  for (absl::string_view line : absl::StrSplit(usage, '\n')) EXPECT_LE(line.size(), 100u) << line;
}

}  // namespace
}  // namespace tessera

#pragma once
// The settings table: the one place a render setting's name, type, range, default, doc and
// command-line spelling are written. Everything else is driven by it:
//   - ValidateSettings (renderer/settings.cpp) checks every row's range, then the few rules
//     between fields (light_radius_max >= light_radius_min);
//   - the proto conversion (server/settings_wire.cpp) maps each row to the RenderSettings field
//     of the same name through protobuf reflection (MergeSettings, ToProto), and fills
//     ServerInfo.choices (the enum names, and one SettingSpec per row with range, default, doc
//     and label for clients such as the web page);
//   - ParseSettingFlag parses the settings flags of both `tessera render|stream|bench|job` and
//     tessera-render, and SettingsFlagsUsage writes their usage lines.
//
// A row: `name` (the Settings member and the proto field, snake_case); `type` (bool, uint,
// float, enum: taken from the member's C++ type); for numbers the inclusive range min..max, plus
// optionally a set of allowed values or "power of two only"; for enums the value names
// (EnumNames in settings.h); the default (read from a default-constructed Settings, never written
// twice); a label and a one-line doc; get/set (through the member pointer); and the command-line
// forms (SettingFlag), which are data too: `--width N`, toggles `--shadows/--no-shadows`, a
// constant (`--auto-exposure` sets exposure_mode=auto), a word (`--chroma 420|444`), a pair
// (`--light-radius MIN,MAX` sets two rows), and "also sets another row unless given"
// (`--exposure EV` makes exposure_mode fixed unless --auto-exposure was given).
//
// Adding a setting: a row in settings_table.cpp, the member in Settings (settings.h), the field
// in proto/tessera/v1/settings.proto, and the shader or pass that uses it. Unit tests fail when
// the table and the proto disagree (a row without its field or a field without its row).
//
// No proto or gRPC here: tessera-render links this without the wire format.
#include <bitset>
#include <cstddef>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/functional/function_ref.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "renderer/settings.h"

namespace tessera {

enum class SettingType { kBool, kUint, kFloat, kEnum };
// "bool", "uint", "float", "enum".
std::string_view ToString(SettingType type);

// One command-line spelling of a setting. Flags are written without the leading "--".
struct SettingFlag {
  enum class Form {
    kValue,     // --flag VALUE: a number of the row's type, or an enum name
    kToggle,    // --flag sets the bool row, --no-flag clears it
    kConstant,  // --flag (no value) sets the row to `constant`
    kWord,      // --flag WORD: one of `words`, each standing for a value of the row
    kPair,      // --flag A,B: the row gets A, the row named `second` gets B (numbers)
  };
  std::string_view flag;
  Form form = Form::kValue;
  std::string_view arg;  // the value in usage text: "N", "MODE", "MIN,MAX" (kValue, kWord, kPair)
  double constant = 0.0;                                     // kConstant
  std::vector<std::pair<std::string_view, double>> words;   // kWord
  std::string_view second;                                   // kPair
  // Also sets the row named `also` to `also_value`, unless the same command line set that row.
  std::string_view also;
  double also_value = 0.0;
  std::string_view usage;  // the usage text when not the row's doc
};

// Every value travels as a double: bools are 0/1, enums their value, uints and floats exactly.
struct SettingRow {
  std::string_view name;   // the Settings member and the RenderSettings field
  SettingType type = SettingType::kUint;
  double min = 0.0, max = 0.0;  // kUint, kFloat: the valid range, inclusive; finite
  std::vector<double> allowed;  // kUint: when not empty, only these values
  bool power_of_two = false;    // kUint: only powers of two
  std::string_view range;       // the range in messages and usage ("1..16384", "0..4")
  std::vector<std::string_view> choices;  // kEnum: the names, indexed by value
  double default_value = 0.0;             // Settings{}'s
  std::string_view label;                 // a short title for a settings panel
  std::string_view doc;                   // one line
  std::vector<SettingFlag> flags;
  double (*get)(const Settings&) = nullptr;
  void (*set)(Settings&, double) = nullptr;

  // Whether `value` is in the row's range (enums: a named value; bools: always).
  bool Valid(double value) const;
  // OK, or INVALID_ARGUMENT "settings.<name>: <value> is out of range (<range>)".
  absl::Status Validate(const Settings& settings) const;
  // The value as a person or a client reads it: "1280", "0.05", "msaa", "true".
  std::string Format(double value) const;
  // The range as text for usage and clients: `range`, or the enum names joined by '|'.
  std::string RangeText() const;
  // Whether value 0 is "auto", the renderer choosing per device (pipeline, post_stage,
  // light_binning, vis_mlaa_coverage): an enum row whose first name is "auto".
  bool Chooses() const {
    return type == SettingType::kEnum && !choices.empty() && choices[0] == "auto";
  }
};

// Every row, in Settings' member order.
const std::vector<SettingRow>& SettingsTable();
// The row named `name`, or nullptr.
const SettingRow* FindSetting(std::string_view name);
// The row's position in SettingsTable() (for SettingMask); `row` must be one of its rows.
size_t SettingIndex(const SettingRow& row);

// Which rows a command line set: bit i is SettingsTable()[i].
inline constexpr size_t kMaxSettings = 64;
using SettingMask = std::bitset<kMaxSettings>;

// Parses one settings flag. `flag` is the flag as given without any "=value" part ("--aa");
// `value()` yields its value and is called only for flags that take one. Returns false when
// `flag` is no settings flag; true when it set rows of `settings` (marked in `set`);
// INVALID_ARGUMENT "<flag>: ..." when the value cannot be read. Ranges are not checked here
// (ValidateSettings, or the server, does that and names the field).
absl::StatusOr<bool> ParseSettingFlag(std::string_view flag,
                                      absl::FunctionRef<std::string()> value, Settings* settings,
                                      SettingMask* set);

// The usage lines of every settings flag, two-space indented, one row per line (wrapped at
// about 100 columns).
std::string SettingsFlagsUsage();

}  // namespace tessera

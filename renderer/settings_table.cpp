#include "renderer/settings_table.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/status_macros.h"

namespace tessera {
namespace {

using Form = SettingFlag::Form;

// absl::StrCat for std::string_view arguments too (this abseil's string_view is its own type).
inline absl::string_view Arg(std::string_view s) { return {s.data(), s.size()}; }
inline absl::string_view Arg(const std::string& s) { return s; }
inline absl::string_view Arg(const char* s) { return s; }
template <typename T>
const T& Arg(const T& v) {
  return v;
}
template <typename... Args>
std::string Cat(const Args&... args) {
  return absl::StrCat(Arg(args)...);
}

// The names joined by `separator`.
std::string Join(const std::vector<std::string_view>& names, std::string_view separator) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) {
    if (i > 0) out.append(separator);
    out.append(names[i]);
  }
  return out;
}

// A row for member M: its type, choices, get/set and default come from the member itself.
template <auto M>
SettingRow Row(std::string_view name, std::string_view label, std::string_view doc) {
  using T = std::remove_cvref_t<decltype(std::declval<Settings&>().*M)>;
  SettingRow r;
  r.name = name;
  r.label = label;
  r.doc = doc;
  r.get = [](const Settings& s) -> double {
    if constexpr (std::is_enum_v<T>) {
      return static_cast<double>(static_cast<std::underlying_type_t<T>>(s.*M));
    } else {
      return static_cast<double>(s.*M);
    }
  };
  r.set = [](Settings& s, double v) {
    if constexpr (std::is_same_v<T, bool>) {
      s.*M = v != 0.0;
    } else if constexpr (std::is_enum_v<T>) {
      s.*M = static_cast<T>(static_cast<std::underlying_type_t<T>>(v));
    } else {
      s.*M = static_cast<T>(v);
    }
  };
  if constexpr (std::is_same_v<T, bool>) {
    r.type = SettingType::kBool;
    r.max = 1.0;
  } else if constexpr (std::is_same_v<T, uint32_t>) {
    r.type = SettingType::kUint;
    r.max = 4294967295.0;
  } else if constexpr (std::is_same_v<T, float>) {
    r.type = SettingType::kFloat;
  } else {
    static_assert(std::is_enum_v<T>, "a setting is a bool, uint32_t, float or enum");
    r.type = SettingType::kEnum;
    r.choices = EnumNames<T>();
    r.max = static_cast<double>(r.choices.size() - 1);
  }
  r.default_value = r.get(Settings{});
  return r;
}

// The range and flags of a row, written after it.
SettingRow&& Range(SettingRow&& r, double min, double max, std::string_view text) {
  r.min = min;
  r.max = max;
  r.range = text;
  return std::move(r);
}
SettingRow&& Allowed(SettingRow&& r, std::vector<double> values, std::string_view text) {
  r.min = values.front();
  r.max = values.back();
  r.allowed = std::move(values);
  r.range = text;
  return std::move(r);
}
SettingRow&& Flags(SettingRow&& r, std::vector<SettingFlag> flags) {
  r.flags = std::move(flags);
  return std::move(r);
}

SettingFlag Value(std::string_view flag, std::string_view arg, std::string_view usage = {}) {
  SettingFlag f;
  f.flag = flag;
  f.arg = arg;
  f.usage = usage;
  return f;
}
SettingFlag Toggle(std::string_view flag, std::string_view usage = {}) {
  SettingFlag f;
  f.flag = flag;
  f.form = Form::kToggle;
  f.usage = usage;
  return f;
}
SettingFlag Constant(std::string_view flag, double value, std::string_view usage) {
  SettingFlag f;
  f.flag = flag;
  f.form = Form::kConstant;
  f.constant = value;
  f.usage = usage;
  return f;
}

std::vector<SettingRow> BuildTable() {
  using S = Settings;
  std::vector<SettingRow> t;
  t.push_back(Flags(Range(Row<&S::width>("width", "Width", "frame width in pixels"), 1, 16384,
                          "1..16384"),
                    {Value("width", "N")}));
  t.push_back(Flags(Range(Row<&S::height>("height", "Height", "frame height in pixels"), 1,
                          16384, "1..16384"),
                    {Value("height", "N")}));
  t.push_back(Flags(Row<&S::aa>("aa", "Anti-aliasing", "anti-aliasing mode"),
                    {Value("aa", "MODE")}));
  t.push_back(Flags(Allowed(Row<&S::samples>("samples", "Samples",
                                             "MSAA / vis_mlaa samples (the nearest the device has)"),
                            {1, 2, 4, 8}, "1, 2, 4 or 8"),
                    {Value("samples", "N")}));
  t.push_back(Flags(Row<&S::culling>("culling", "Culling", "what is skipped before drawing"),
                    {Value("culling", "MODE")}));
  t.push_back(Flags(Row<&S::scene_lights>("scene_lights", "Scene's lights",
                                          "light with the file's KHR_lights_punctual lights"),
                    {Toggle("scene-lights")}));
  t.push_back(Flags(Range(Row<&S::synthetic_lights>("synthetic_lights", "Synthetic lights",
                                                    "random point lights in the scene bounds"),
                          0, 65536, "0..65536"),
                    {Value("lights", "N")}));
  t.push_back(Flags(Range(Row<&S::light_seed>("light_seed", "Light seed",
                                              "seed of the synthetic lights"),
                          0, 4294967295.0, "0..4294967295"),
                    {Value("light-seed", "N")}));
  t.push_back(Flags(Allowed(Row<&S::tile_size>("tile_size", "Tile size (px)",
                                               "light-culling tile in pixels"),
                            {8, 16, 32}, "8, 16 or 32"),
                    {Value("tile-size", "N")}));
  {
    SettingFlag radius = Value("light-radius", "MIN,MAX",
                               "smallest and largest synthetic light range (0: 1% and 4% of the "
                               "scene)");
    radius.form = Form::kPair;
    radius.second = "light_radius_max";
    t.push_back(Flags(
        Range(Row<&S::light_radius_min>("light_radius_min", "Light radius min",
                                        "smallest synthetic light range (0: 1% of the scene)"),
              0, 1e6, "0..1e6 world units, 0 = auto"),
        {radius}));
  }
  t.push_back(Range(Row<&S::light_radius_max>("light_radius_max", "Light radius max",
                                               "largest synthetic light range (0: 4% of the scene)"),
                    0, 1e6, "0..1e6 world units, 0 = auto"));
  t.push_back(Flags(Row<&S::lights_animated>("lights_animated", "Animate lights",
                                             "synthetic lights circle around their place"),
                    {Toggle("animate-lights")}));
  t.push_back(Flags(Range(Row<&S::light_time>("light_time", "Light time (s)",
                                              "where animated lights are"),
                          -1e6, 1e6, "-1e6..1e6 seconds"),
                    {Value("light-time", "SECONDS")}));
  t.push_back(Flags(Row<&S::light_culling>("light_culling", "Light culling (forward+)",
                                           "forward+ tile light lists (off: every light at "
                                           "every pixel)"),
                    {Toggle("light-culling")}));
  t.push_back(Flags(Row<&S::tile_depth_mask>("tile_depth_mask", "Tile depth mask",
                                             "2.5D depth mask per tile (off: depth bounds only)"),
                    {Toggle("tile-depth-mask")}));
  t.push_back(Flags(Row<&S::light_binning>("light_binning", "Light binning",
                                           "where the lights are projected into tiles and "
                                           "binned by tile row: cpu, gpu, or auto (the faster "
                                           "on the device)"),
                    {Value("light-binning", "WHERE")}));
  t.push_back(Flags(Row<&S::shadows>("shadows", "Shadows", "sun cascades + point/spot shadows"),
                    {Toggle("shadows")}));
  {
    SettingRow atlas = Range(Row<&S::shadow_atlas_size>("shadow_atlas_size", "Shadow atlas (texels)",
                                                        "shadow atlas side (clamped to the device)"),
                             512, 8192, "a power of two, 512..8192");
    atlas.power_of_two = true;
    t.push_back(Flags(std::move(atlas), {Value("shadow-atlas", "N")}));
  }
  t.push_back(Flags(Range(Row<&S::shadow_lights>("shadow_lights", "Shadowed lights",
                                                 "point/spot lights with shadows besides the sun"),
                          0, 32, "0..32"),
                    {Value("shadow-lights", "N")}));
  t.push_back(Flags(Row<&S::shadow_cache>("shadow_cache", "Shadow cache",
                                          "keep shadow maps whose view did not change"),
                    {Toggle("shadow-cache")}));
  t.push_back(Flags(Row<&S::ssao>("ssao", "SSAO", "screen-space ambient obscurance"),
                    {Toggle("ssao")}));
  t.push_back(Flags(Range(Row<&S::ssao_radius>("ssao_radius", "SSAO radius",
                                               "SSAO radius (0: 1.5% of the scene diagonal)"),
                          0, 1e6, "0..1e6 world units, 0 = auto"),
                    {Value("ssao-radius", "R")}));
  t.push_back(Flags(Range(Row<&S::ssao_strength>("ssao_strength", "SSAO strength",
                                                 "how dark SSAO makes occluded places"),
                          0, 4, "0..4"),
                    {Value("ssao-strength", "S")}));
  t.push_back(Flags(Row<&S::ssao_half_res>("ssao_half_res", "SSAO at half resolution",
                                           "compute SSAO at half resolution"),
                    {Constant("ssao-full-res", 0, "SSAO at full resolution (for comparison)")}));
  t.push_back(Flags(Row<&S::bloom>("bloom", "Bloom", "what is brighter than white glows"),
                    {Toggle("bloom")}));
  t.push_back(Flags(Range(Row<&S::bloom_strength>("bloom_strength", "Bloom strength",
                                                  "how much of the glow is added"),
                          0, 1, "0..1"),
                    {Value("bloom-strength", "S")}));
  t.push_back(Flags(Row<&S::ibl>("ibl", "IBL",
                                 "image-based ambient light from a procedural sky (also the "
                                 "background)"),
                    {Toggle("ibl")}));
  t.push_back(Flags(Row<&S::exposure_mode>("exposure_mode", "Exposure",
                                           "fixed (exposure_ev stops) or adapted to the frame"),
                    {Constant("auto-exposure", double(ExposureMode::kAuto),
                              "adapt to the frame's average luma (--exposure then compensates)")}));
  {
    SettingFlag ev = Value("exposure", "EV", "exposure in stops (with auto exposure: compensation)");
    ev.also = "exposure_mode";
    ev.also_value = double(ExposureMode::kFixed);
    t.push_back(Flags(Range(Row<&S::exposure_ev>("exposure_ev", "Exposure (EV)", "exposure in stops"),
                            -20, 20, "-20..20 stops"),
                      {ev}));
  }
  t.push_back(Flags(Row<&S::tonemapper>("tonemapper", "Tonemapper",
                                        "the curve from exposed HDR to the display"),
                    {Value("tonemapper", "T")}));
  t.push_back(Flags(Row<&S::pipeline>("pipeline", "Pipeline",
                                      "opaque shading with aa none/fxaa/taa: visibility buffer "
                                      "(each pixel shaded once), forward, or auto (the faster "
                                      "on the device)"),
                    {Value("pipeline", "P")}));
  t.push_back(Flags(Row<&S::post_stage>("post_stage", "Post passes",
                                        "where TAA, geometric AA, SSAO, bloom, the tonemap and "
                                        "FXAA run: fragment, compute, or auto (the faster on "
                                        "the device)"),
                    {Value("post-stage", "S")}));
  t.push_back(Flags(Row<&S::vis_mlaa_coverage>("vis_mlaa_coverage", "Visibility AA coverage",
                                               "how vis_mlaa finds each sample's triangle: "
                                               "raster (a multisampled visibility buffer), "
                                               "analytic (one sample rasterized, the others "
                                               "tested against the triangles nearby pixels "
                                               "show), or auto (analytic on GPUs, raster on "
                                               "CPU devices)"),
                    {Value("vis-mlaa-coverage", "HOW")}));
  t.push_back(Flags(Row<&S::debug_view>("debug_view", "Debug view",
                                        "what the picture shows instead of the lit scene"),
                    {Value("debug", "VIEW")}));
  t.push_back(Flags(Row<&S::pass_timing>("pass_timing", "Per-pass timing",
                                         "time each pass on its own (CPU devices then submit "
                                         "and wait for each pass alone; off: one submission, "
                                         "the passes as the device's timestamps say)"),
                    {Toggle("pass-timing")}));
  t.push_back(Flags(Range(Row<&S::jpeg_quality>("jpeg_quality", "JPEG quality", "JPEG quality"),
                          1, 100, "1..100"),
                    {Value("quality", "Q")}));
  {
    SettingFlag chroma = Value("chroma", "420|444", "JPEG chroma subsampling");
    chroma.form = Form::kWord;
    chroma.words = {{"420", 0.0}, {"444", 1.0}};
    t.push_back(Flags(Row<&S::jpeg_444>("jpeg_444", "JPEG 4:4:4 chroma",
                                        "JPEG chroma 4:4:4 instead of 4:2:0"),
                      {chroma}));
  }
  t.push_back(Flags(Range(Row<&S::scene_time>("scene_time", "Scene time (s)",
                                              "the animation's time (with play: where it starts)"),
                          -1e6, 1e6, "-1e6..1e6 seconds"),
                    {Value("time", "SECONDS")}));
  t.push_back(Flags(Row<&S::loop>("loop", "Loop",
                                  "the animation wraps at its end (off: it holds its last pose)"),
                    {Toggle("loop")}));
  t.push_back(Flags(Row<&S::play>("play", "Play",
                                  "a stream's scene time advances with the wall clock"),
                    {Toggle("play")}));
  return t;
}

bool IsPowerOfTwo(double v) {
  const auto u = static_cast<uint64_t>(v);
  return static_cast<double>(u) == v && u != 0 && (u & (u - 1)) == 0;
}

// --- command line -----------------------------------------------------------------------------

absl::Status FlagError(std::string_view flag, std::string_view what) {
  return absl::InvalidArgumentError(Cat(flag, what));
}

// A number of the row's type from `text` ("--width: not a non-negative integer: 'x'").
absl::StatusOr<double> ParseNumber(const SettingRow& row, std::string_view flag,
                                   std::string_view text) {
  if (row.type == SettingType::kUint) {
    uint32_t u = 0;
    if (!absl::SimpleAtoi(Arg(text), &u))
      return FlagError(flag, Cat(": not a non-negative integer: '", text, "'"));
    return static_cast<double>(u);
  }
  double d = 0.0;
  if (!absl::SimpleAtod(Arg(text), &d) || !std::isfinite(d))
    return FlagError(flag, Cat(": not a number: '", text, "'"));
  // Beyond float's range is infinite (which validation refuses), not undefined behaviour.
  if (std::abs(d) > std::numeric_limits<float>::max()) return d > 0 ? INFINITY : -INFINITY;
  return static_cast<double>(static_cast<float>(d));
}

// The row's value from a flag's VALUE: a number, or an enum name.
absl::StatusOr<double> ParseValue(const SettingRow& row, std::string_view flag,
                                  std::string_view text) {
  if (row.type != SettingType::kEnum) return ParseNumber(row, flag, text);
  for (size_t i = 0; i < row.choices.size(); ++i)
    if (row.choices[i] == text) return static_cast<double>(i);
  return FlagError(flag, Cat(": '", text, "' is not one of ", row.RangeText()));
}

// "a, b or c".
std::string OrList(const std::vector<std::string_view>& words) {
  if (words.size() < 2) return Join(words, "");
  return Cat(Join({words.begin(), words.end() - 1}, ", "), " or ", words.back());
}

// The values one flag gives: (row, value) pairs, in order.
using Assignments = std::vector<std::pair<const SettingRow*, double>>;

absl::StatusOr<Assignments> ParseFlagValue(const SettingRow& row, const SettingFlag& f,
                                           std::string_view flag, bool negated,
                                           absl::FunctionRef<std::string()> value) {
  switch (f.form) {
    case Form::kToggle:
      return Assignments{{&row, negated ? 0.0 : 1.0}};
    case Form::kConstant:
      return Assignments{{&row, f.constant}};
    case Form::kValue: {
      ASSIGN_OR_RETURN(const double v, ParseValue(row, flag, value()));
      return Assignments{{&row, v}};
    }
    case Form::kWord: {
      const std::string text = value();
      std::vector<std::string_view> names;
      for (const auto& [word, v] : f.words) {
        if (word == text) return Assignments{{&row, v}};
        names.push_back(word);
      }
      return FlagError(flag, Cat(" wants ", OrList(names)));
    }
    case Form::kPair: {
      const std::string text = value();
      const std::vector<std::string> parts = absl::StrSplit(text, ',');
      if (parts.size() != 2)
        return FlagError(flag, Cat(" wants ", f.arg, ", got '", text, "'"));
      const SettingRow* second = FindSetting(f.second);
      ASSIGN_OR_RETURN(const double a, ParseNumber(row, flag, parts[0]));
      ASSIGN_OR_RETURN(const double b, ParseNumber(*second, flag, parts[1]));
      return Assignments{{&row, a}, {second, b}};
    }
  }
  return Assignments{};
}

// --- usage ------------------------------------------------------------------------------------

constexpr size_t kUsageColumn = 26;
constexpr size_t kUsageWidth = 100;

// "  --flag ARG" padded to the text column, then `text`, wrapped under that column at spaces
// and, inside long lists such as "none|normals|...", after a '|'.
void AppendUsageLine(std::string_view spelling, const std::string& text, std::string* out) {
  std::string line = Cat("  ", spelling);
  if (line.size() + 1 > kUsageColumn) {
    line += ' ';
  } else {
    line.resize(kUsageColumn, ' ');
  }
  bool line_empty = true;
  for (absl::string_view word : absl::StrSplit(text, ' ', absl::SkipEmpty())) {
    // Pieces of the word that may start a new line: the word, or each "name|" of a list.
    std::vector<absl::string_view> pieces;
    if (kUsageColumn + word.size() > kUsageWidth) {
      pieces = absl::StrSplit(word, absl::ByAnyChar("|"));
      for (size_t i = 0; i + 1 < pieces.size(); ++i)
        pieces[i] = absl::string_view(pieces[i].data(), pieces[i].size() + 1);  // keep the '|'
    } else {
      pieces.push_back(word);
    }
    for (size_t i = 0; i < pieces.size(); ++i) {
      const bool glued = i > 0;  // continues the word: no space before it
      const size_t needed = pieces[i].size() + (glued || line_empty ? 0 : 1);
      if (!line_empty && line.size() + needed > kUsageWidth) {
        out->append(line).append("\n");
        line = std::string(kUsageColumn, ' ');
        line_empty = true;
      }
      if (!line_empty && !glued) line += ' ';
      line.append(pieces[i].data(), pieces[i].size());
      line_empty = false;
    }
  }
  out->append(line).append("\n");
}

}  // namespace

std::string_view ToString(SettingType type) {
  switch (type) {
    case SettingType::kBool: return "bool";
    case SettingType::kUint: return "uint";
    case SettingType::kFloat: return "float";
    case SettingType::kEnum: return "enum";
  }
  return "invalid";
}

bool SettingRow::Valid(double v) const {
  switch (type) {
    case SettingType::kBool:
      return v == 0.0 || v == 1.0;
    case SettingType::kEnum:
      return v >= 0.0 && v < static_cast<double>(choices.size()) && v == std::floor(v);
    case SettingType::kUint:
    case SettingType::kFloat:
      break;
  }
  if (!std::isfinite(v) || v < min || v > max) return false;
  if (power_of_two && !IsPowerOfTwo(v)) return false;
  if (!allowed.empty()) {
    for (double a : allowed)
      if (a == v) return true;
    return false;
  }
  return true;
}

absl::Status SettingRow::Validate(const Settings& settings) const {
  const double v = get(settings);
  if (Valid(v)) return absl::OkStatus();
  return absl::InvalidArgumentError(
      Cat("settings.", name, ": ", Format(v), " is out of range (", RangeText(), ")"));
}

std::string SettingRow::Format(double v) const {
  switch (type) {
    case SettingType::kBool:
      return v != 0.0 ? "true" : "false";
    case SettingType::kEnum:
      if (Valid(v)) return std::string(choices[static_cast<size_t>(v)]);
      return Cat(static_cast<int64_t>(v));
    case SettingType::kUint:
      return Cat(static_cast<uint64_t>(v));
    case SettingType::kFloat:
      return Cat(static_cast<float>(v));
  }
  return "";
}

std::string SettingRow::RangeText() const {
  if (type == SettingType::kEnum) return Join(choices, "|");
  if (type == SettingType::kBool) return "true|false";
  return std::string(range);
}

const std::vector<SettingRow>& SettingsTable() {
  static const std::vector<SettingRow> table = BuildTable();
  return table;
}

const SettingRow* FindSetting(std::string_view name) {
  for (const SettingRow& row : SettingsTable())
    if (row.name == name) return &row;
  return nullptr;
}

size_t SettingIndex(const SettingRow& row) {
  return static_cast<size_t>(&row - SettingsTable().data());
}

absl::StatusOr<bool> ParseSettingFlag(std::string_view flag,
                                      absl::FunctionRef<std::string()> value, Settings* settings,
                                      SettingMask* set) {
  if (flag.substr(0, 2) != "--") return false;
  flag.remove_prefix(2);
  const std::string given = Cat("--", flag);
  if (flag == "animation") {  // the one text setting, outside the table (settings.h)
    settings->animation = value();
    if (settings->animation.empty()) return FlagError(given, ": needs a name, an index or none");
    return true;
  }
  for (const SettingRow& row : SettingsTable()) {
    for (const SettingFlag& f : row.flags) {
      const bool negated =
          f.form == Form::kToggle && flag.substr(0, 3) == "no-" && flag.substr(3) == f.flag;
      if (flag != f.flag && !negated) continue;
      ASSIGN_OR_RETURN(const Assignments values, ParseFlagValue(row, f, given, negated, value));
      for (const auto& [target, v] : values) {
        target->set(*settings, v);
        set->set(SettingIndex(*target));
      }
      if (!f.also.empty()) {
        const SettingRow* also = FindSetting(f.also);
        if (!set->test(SettingIndex(*also))) {
          also->set(*settings, f.also_value);
          set->set(SettingIndex(*also));
        }
      }
      return true;
    }
  }
  return false;
}

std::string SettingsFlagsUsage() {
  std::string out;
  AppendUsageLine("--animation NAME|INDEX|none",
                  "the glTF animation to pose the scene with (default none)", &out);
  for (const SettingRow& row : SettingsTable()) {
    for (const SettingFlag& f : row.flags) {
      const std::string text(f.usage.empty() ? row.doc : f.usage);
      switch (f.form) {
        case Form::kValue:
          AppendUsageLine(Cat("--", f.flag, " ", f.arg),
                          Cat(text, ": ", row.RangeText(), " (default ",
                                       row.Format(row.default_value), ")"),
                          &out);
          break;
        case Form::kToggle:
          AppendUsageLine(Cat("--[no-]", f.flag),
                          Cat(text, " (default ", row.default_value != 0.0 ? "on" : "off",
                                       ")"),
                          &out);
          break;
        case Form::kConstant:
          AppendUsageLine(Cat("--", f.flag), text, &out);
          break;
        case Form::kWord: {
          std::string_view current;
          for (const auto& [word, v] : f.words)
            if (v == row.default_value) current = word;
          AppendUsageLine(Cat("--", f.flag, " ", f.arg),
                          Cat(text, " (default ", current, ")"), &out);
          break;
        }
        case Form::kPair:
          AppendUsageLine(Cat("--", f.flag, " ", f.arg),
                          Cat(text, ": ", row.RangeText()), &out);
          break;
      }
    }
  }
  return out;
}

}  // namespace tessera

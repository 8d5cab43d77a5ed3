#include "common/job_spec.h"

#include <algorithm>
#include <cmath>
#include <glm/glm.hpp>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "common/proto_vec.h"
#include "common/status_macros.h"

namespace tessera::jobs {
namespace {

// Smallest sine of the angle between up and the view direction that a key may have, and below
// which an interpolated up is replaced. Relative, so it does not depend on the scene's scale,
// and far above float rounding, so a camera that passes it also passes the renderer's absolute
// 1e-6 check after the conversions.
constexpr double kMinUpSine = 1e-4;
// As renderer/camera.cpp's ValidateCamera: eye and target closer than this are "equal".
constexpr float kMinViewDistance = 1e-6f;

absl::Status Invalid(absl::string_view field, absl::string_view why) {
  return absl::InvalidArgumentError(absl::StrCat(field, ": ", why));
}

// A client string quoted for an error message: escaped and cut, so that neither control
// characters nor a megabyte of text reach logs.
std::string Quote(const std::string& s) {
  return absl::StrCat("\"", absl::CHexEscape(s.substr(0, 200)), s.size() > 200 ? "..." : "", "\"");
}

uint64_t Step(const v1::FrameRange& r) { return r.step() == 0 ? 1 : r.step(); }

// In 64 bits: 0..UINT32_MAX has 2^32 frames.
uint64_t FrameCount64(const v1::FrameRange& r) {
  if (r.last() < r.first()) return 0;
  return (static_cast<uint64_t>(r.last()) - r.first()) / Step(r) + 1;
}


// LookAt.up defaults to +Y; proto3 cannot tell an unset Vec3's zeros from sent zeros, and a
// zero up is never meaningful, so both mean the default.
glm::vec3 UpOf(const v1::LookAt& l) {
  const glm::vec3 up = Vec(l.up());
  return up == glm::vec3(0.0f) ? glm::vec3(0.0f, 1.0f, 0.0f) : up;
}

// True when `up` is zero, non-finite or within kMinUpSine of `dir` (either way round).
bool UpParallel(const glm::vec3& dir, const glm::vec3& up) {
  const glm::dvec3 d(dir), u(up);
  const double cross = glm::length(glm::cross(d, u));
  return !(cross > kMinUpSine * glm::length(d) * glm::length(u));
}

// True when target - eye is usable as a view direction in float: not (nearly) zero, and its
// length does not overflow (coordinates near FLT_MAX).
bool ViewOk(const glm::vec3& eye, const glm::vec3& target) {
  const float len = glm::length(target - eye);
  return std::isfinite(len) && len >= kMinViewDistance;
}

absl::Status ValidateFinite(const std::string& field, const v1::Vec3& v) {
  if (!Finite(v)) return Invalid(field, "non-finite coordinate");
  return absl::OkStatus();
}

absl::Status ValidateOptionalFinite(const std::string& field, bool has, float v) {
  if (has && !std::isfinite(v)) return Invalid(field, "non-finite");
  return absl::OkStatus();
}

absl::Status ValidatePath(const v1::CameraPath& path, const JobLimits& limits) {
  if (!v1::Interpolation_IsValid(path.interpolation()))
    return Invalid("spec.path.interpolation", absl::StrCat("unknown value ", path.interpolation()));
  if (path.keyframes().empty())
    return Invalid("spec.path.keyframes", "is empty (a path needs at least one key)");
  if (static_cast<uint64_t>(path.keyframes_size()) > limits.max_keyframes)
    return absl::ResourceExhaustedError(absl::StrCat("spec.path.keyframes: ", path.keyframes_size(),
                                                     " keys, more than the keyframe limit (",
                                                     limits.max_keyframes, ")"));
  float znear = kDefaultZnear;
  if (path.has_znear()) {
    if (!std::isfinite(path.znear()) || path.znear() <= 0.0f)
      return Invalid("spec.path.znear", absl::StrCat(path.znear(), " must be finite and > 0"));
    znear = path.znear();
  }
  if (path.has_zfar() &&
      (!std::isfinite(path.zfar()) || (path.zfar() != 0.0f && path.zfar() <= znear)))
    return Invalid("spec.path.zfar",
                   absl::StrCat(path.zfar(), " must be 0 (infinite) or > znear (", znear, ")"));
  for (int i = 0; i < path.keyframes_size(); ++i) {
    const v1::CameraKeyframe& k = path.keyframes(i);
    const std::string key = absl::StrCat("spec.path.keyframes[", i, "]");
    if (i > 0 && k.frame() <= path.keyframes(i - 1).frame())
      return Invalid(absl::StrCat(key, ".frame"),
                     absl::StrCat(k.frame(), " is not after keyframes[", i - 1, "].frame (",
                                  path.keyframes(i - 1).frame(), ")"));
    if (!k.has_look_at()) return Invalid(absl::StrCat(key, ".look_at"), "is required");
    const v1::LookAt& l = k.look_at();
    RETURN_IF_ERROR(ValidateFinite(absl::StrCat(key, ".look_at.eye"), l.eye()));
    RETURN_IF_ERROR(ValidateFinite(absl::StrCat(key, ".look_at.target"), l.target()));
    RETURN_IF_ERROR(ValidateFinite(absl::StrCat(key, ".look_at.up"), l.up()));
    const glm::vec3 eye = Vec(l.eye()), target = Vec(l.target());
    if (!ViewOk(eye, target))
      return Invalid(absl::StrCat(key, ".look_at.target"),
                     std::isfinite(glm::length(target - eye))
                         ? "equals eye"
                         : "is too far from eye (the distance overflows a float)");
    if (UpParallel(target - eye, UpOf(l)))
      return Invalid(absl::StrCat(key, ".look_at.up"), "is parallel to target - eye");
    if (k.has_yfov() && !(std::isfinite(k.yfov()) && k.yfov() > 0.0f && k.yfov() < kMaxYfov))
      return Invalid(absl::StrCat(key, ".yfov"),
                     absl::StrCat(k.yfov(), " must be in (0, ", kMaxYfov, ") radians"));
  }
  return absl::OkStatus();
}

absl::Status ValidateList(const v1::CameraList& list, const v1::FrameRange& frames) {
  // The range passed ValidateFrameRange, so its count is at most max_frames and fits an int.
  const uint64_t count = FrameCount64(frames);
  if (static_cast<uint64_t>(list.cameras_size()) != count)
    return Invalid("spec.list.cameras",
                   absl::StrCat(list.cameras_size(), " cameras for the ", count,
                                " frames of spec.frames (one camera per frame)"));
  for (int i = 0; i < list.cameras_size(); ++i) {
    const v1::Camera& c = list.cameras(i);
    const std::string cam = absl::StrCat("spec.list.cameras[", i, "]");
    switch (c.placement_case()) {
      case v1::Camera::kLookAt: {
        const v1::LookAt& l = c.look_at();
        for (const auto& [name, v] : {std::pair<const char*, const v1::Vec3*>{"eye", &l.eye()},
                                      {"target", &l.target()},
                                      {"up", &l.up()}}) {
          RETURN_IF_ERROR(ValidateFinite(absl::StrCat(cam, ".look_at.", name), *v));
        }
        break;
      }
      case v1::Camera::kViewMatrix: {
        const auto& m = c.view_matrix().m();
        if (m.size() != 16)
          return Invalid(absl::StrCat(cam, ".view_matrix.m"),
                         absl::StrCat("needs 16 values, got ", m.size()));
        for (float v : m)
          if (!std::isfinite(v))
            return Invalid(absl::StrCat(cam, ".view_matrix.m"), "non-finite value");
        break;
      }
      case v1::Camera::kFrame:
        RETURN_IF_ERROR(
            ValidateFinite(absl::StrCat(cam, ".frame.direction"), c.frame().direction()));
        break;
      case v1::Camera::kSceneCamera:  // an index: checked against the scene at render time
      case v1::Camera::PLACEMENT_NOT_SET:
        break;
    }
    RETURN_IF_ERROR(ValidateOptionalFinite(absl::StrCat(cam, ".yfov"), c.has_yfov(), c.yfov()));
    RETURN_IF_ERROR(ValidateOptionalFinite(absl::StrCat(cam, ".znear"), c.has_znear(), c.znear()));
    RETURN_IF_ERROR(ValidateOptionalFinite(absl::StrCat(cam, ".zfar"), c.has_zfar(), c.zfar()));
  }
  return absl::OkStatus();
}

// A keyframe in double precision, with its up normalised so that keys whose ups differ only
// in length weigh the same in the interpolation.
struct Key {
  glm::dvec3 eye, target, up;
  double yfov;
};

Key KeyOf(const v1::CameraKeyframe& k) {
  const glm::dvec3 up(UpOf(k.look_at()));
  const double len = glm::length(up);
  return {glm::dvec3(Vec(k.look_at().eye())), glm::dvec3(Vec(k.look_at().target())),
          len > 0.0 ? up / len : glm::dvec3(0.0, 1.0, 0.0),
          k.has_yfov() ? static_cast<double>(k.yfov()) : static_cast<double>(kDefaultYfov)};
}

Key Lerp(const Key& a, const Key& b, double t) {
  return {a.eye + t * (b.eye - a.eye), a.target + t * (b.target - a.target),
          a.up + t * (b.up - a.up), a.yfov + t * (b.yfov - a.yfov)};
}

// Uniform Catmull-Rom between p1 (t = 0) and p2 (t = 1); exactly p1 at t = 0 and p2 at t = 1.
template <typename T>
T CatmullRom(const T& p0, const T& p1, const T& p2, const T& p3, double t) {
  const double t2 = t * t, t3 = t2 * t;
  return 0.5 * ((2.0 * p1) + (p2 - p0) * t + (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3) * t2 +
                (3.0 * p1 - p0 - 3.0 * p2 + p3) * t3);
}

Key CatmullRomKey(const Key& p0, const Key& p1, const Key& p2, const Key& p3, double t) {
  Key k{CatmullRom(p0.eye, p1.eye, p2.eye, p3.eye, t),
        CatmullRom(p0.target, p1.target, p2.target, p3.target, t),
        CatmullRom(p0.up, p1.up, p2.up, p3.up, t),
        CatmullRom(p0.yfov, p1.yfov, p2.yfov, p3.yfov, t)};
  // The spline overshoots where the keys turn; keep yfov between the values it is built from,
  // all of which are valid, so the result stays a valid field of view.
  k.yfov = std::clamp(k.yfov, std::min({p0.yfov, p1.yfov, p2.yfov, p3.yfov}),
                      std::max({p0.yfov, p1.yfov, p2.yfov, p3.yfov}));
  return k;
}

glm::vec3 PerpendicularTo(const glm::vec3& dir) {
  // Crossed with the axis least aligned with dir: never parallel, never zero.
  const glm::vec3 a = glm::abs(dir);
  const glm::vec3 axis = a.x <= a.y && a.x <= a.z ? glm::vec3(1, 0, 0)
                         : a.y <= a.z             ? glm::vec3(0, 1, 0)
                                                  : glm::vec3(0, 0, 1);
  return glm::normalize(glm::cross(dir, axis));
}

// Turns an interpolated key into a camera the renderer accepts. `prev` and `next` are the
// keys around it (valid: they passed ValidateJobSpec), tried in that order when the
// interpolation collapsed the view direction or turned up parallel to it.
v1::Camera Settle(const Key& k, const v1::CameraKeyframe& prev, const v1::CameraKeyframe& next) {
  glm::vec3 eye(k.eye), target(k.target);
  const glm::vec3 prev_eye = Vec(prev.look_at().eye()), prev_target = Vec(prev.look_at().target());
  if (!ViewOk(eye, target)) {
    // E.g. eye and target swapping places between two keys: look the previous key's way.
    target = eye + (prev_target - prev_eye);
    if (!ViewOk(eye, target)) {
      eye = prev_eye;
      target = prev_target;
    }
  }
  const glm::vec3 dir = target - eye;
  glm::vec3 up(0.0f);
  const double up_len = glm::length(k.up);
  if (up_len > 0.0 && std::isfinite(up_len)) up = glm::vec3(k.up / up_len);
  for (const glm::vec3& candidate : {UpOf(prev.look_at()), UpOf(next.look_at())}) {
    if (!UpParallel(dir, up)) break;
    up = glm::normalize(candidate);
  }
  if (UpParallel(dir, up)) up = PerpendicularTo(dir);

  v1::Camera camera;
  v1::LookAt* l = camera.mutable_look_at();
  SetVec(eye, l->mutable_eye());
  SetVec(target, l->mutable_target());
  SetVec(up, l->mutable_up());
  camera.set_yfov(static_cast<float>(k.yfov));
  return camera;
}

v1::Camera PathCamera(const v1::CameraPath& path, uint32_t frame) {
  const auto& keys = path.keyframes();
  const int n = keys.size();
  // The segment [i, i + 1] holding the frame and the parameter t in it; t = 0 at key i.
  int i = 0;
  double t = 0.0;
  if (frame <= keys[0].frame()) {
    i = 0;
  } else if (frame >= keys[n - 1].frame()) {
    i = n - 1;
  } else {
    auto it =
        std::upper_bound(keys.begin(), keys.end(), frame,
                         [](uint32_t f, const v1::CameraKeyframe& k) { return f < k.frame(); });
    // Clamped so that unordered keys (a spec that skipped validation) cannot index out of range.
    i = std::clamp(static_cast<int>(it - keys.begin()) - 1, 0, n - 2);
    const uint32_t f0 = keys[i].frame(), f1 = keys[i + 1].frame();
    if (f1 > f0 && frame >= f0)
      t = std::min(1.0, static_cast<double>(frame - f0) / static_cast<double>(f1 - f0));
  }
  const int j = std::min(i + 1, n - 1);
  const Key k0 = KeyOf(keys[i]);
  Key k = k0;
  if (t > 0.0) {
    switch (path.interpolation()) {
      case v1::INTERPOLATION_STEP:
        break;
      case v1::INTERPOLATION_CATMULL_ROM:
        // The end keys duplicated (p0 = p1 on the first segment, p3 = p2 on the last).
        k = CatmullRomKey(KeyOf(keys[std::max(i - 1, 0)]), k0, KeyOf(keys[j]),
                          KeyOf(keys[std::min(i + 2, n - 1)]), t);
        break;
      default:  // LINEAR, UNSPECIFIED
        k = Lerp(k0, KeyOf(keys[j]), t);
        break;
    }
  }
  v1::Camera camera = Settle(k, keys[i], keys[j]);
  if (path.has_znear()) camera.set_znear(path.znear());
  if (path.has_zfar()) camera.set_zfar(path.zfar());
  return camera;
}

// A parsed name pattern: the literal text around the one conversion ("%%" already turned into
// '%') and the conversion's zero-padded width (0 for "%d").
struct NamePattern {
  std::string before, after;
  int width = 0;
};

absl::StatusOr<NamePattern> ParseNamePattern(const std::string& pattern) {
  auto bad = [&](absl::string_view why) {
    return Invalid("spec.name_pattern", absl::StrCat(Quote(pattern), " ", why));
  };
  if (pattern.empty()) return bad("is empty");
  if (pattern.size() > kMaxNamePatternBytes)
    return bad(absl::StrCat("is longer than ", kMaxNamePatternBytes, " bytes"));
  NamePattern out;
  bool have_conversion = false;
  for (size_t i = 0; i < pattern.size(); ++i) {
    const unsigned char c = pattern[i];
    if (c < 0x20 || c == 0x7f) return bad("contains a control character");
    if (c == '/') return bad("contains '/' (a name pattern names files; see output_dir)");
    if (c == '\\') return bad("contains a backslash");
    std::string& text = have_conversion ? out.after : out.before;
    if (c != '%') {
      text.push_back(static_cast<char>(c));
      continue;
    }
    // "%%", "%d" or "%0Nd"; anything else is refused rather than guessed at.
    const absl::string_view rest = absl::string_view(pattern).substr(i + 1);
    int width = -1;
    size_t len = 0;  // bytes after the '%'
    if (!rest.empty() && rest[0] == '%') {
      text.push_back('%');
      ++i;
      continue;
    } else if (!rest.empty() && rest[0] == 'd') {
      width = 0;
      len = 1;
    } else if (rest.size() >= 3 && rest[0] == '0' && rest[1] >= '1' && rest[1] <= '9' &&
               rest[2] == 'd') {
      width = rest[1] - '0';
      len = 3;
    } else {
      return bad(absl::StrCat("has an unsupported conversion at byte ", i,
                              " (only %d, %0Nd with N 1..9, and %% are allowed)"));
    }
    if (have_conversion) return bad("has more than one %d conversion (one frame number per name)");
    have_conversion = true;
    out.width = width;
    i += len;
  }
  if (!have_conversion) return bad("has no %d or %0Nd for the frame number");
  // The conversion always yields at least one digit, so a name is never "" , "." or "..".
  return out;
}

std::string Expand(const NamePattern& p, uint32_t frame) {
  std::string digits = absl::StrCat(frame);
  if (digits.size() < static_cast<size_t>(p.width))
    digits.insert(0, static_cast<size_t>(p.width) - digits.size(), '0');
  return absl::StrCat(p.before, digits, p.after);
}

}  // namespace

uint32_t FrameCount(const v1::FrameRange& range) {
  return static_cast<uint32_t>(std::min<uint64_t>(FrameCount64(range), UINT32_MAX));
}

absl::Status ValidateFrameRange(const v1::FrameRange& range, uint32_t max_frames) {
  if (range.last() < range.first())
    return Invalid("spec.frames.last", absl::StrCat(range.last(), " is before spec.frames.first (",
                                                    range.first(), ")"));
  const uint64_t count = FrameCount64(range);
  if (count > max_frames)
    return absl::ResourceExhaustedError(absl::StrCat(
        "spec.frames: ", count, " frames, more than the max_job_frames limit (", max_frames, ")"));
  return absl::OkStatus();
}

absl::StatusOr<std::vector<uint32_t>> FrameNumbers(const v1::FrameRange& range,
                                                   uint32_t max_frames) {
  RETURN_IF_ERROR(ValidateFrameRange(range, max_frames));
  const uint64_t count = FrameCount64(range), step = Step(range);
  std::vector<uint32_t> frames;
  frames.reserve(count);
  // In 64 bits: first + i * step <= last for every i < count, so the cast is exact.
  for (uint64_t i = 0; i < count; ++i)
    frames.push_back(static_cast<uint32_t>(range.first() + i * step));
  return frames;
}

std::optional<uint32_t> FrameIndex(const v1::FrameRange& range, uint32_t frame) {
  if (range.last() < range.first() || frame < range.first() || frame > range.last())
    return std::nullopt;
  const uint64_t offset = static_cast<uint64_t>(frame) - range.first();
  if (offset % Step(range) != 0) return std::nullopt;
  return static_cast<uint32_t>(offset / Step(range));
}

absl::Status ValidateJobSpec(const v1::JobSpec& spec, const JobLimits& limits) {
  if (spec.name().size() > kMaxNameBytes)
    return Invalid("spec.name",
                   absl::StrCat(spec.name().size(), " bytes, more than ", kMaxNameBytes));
  RETURN_IF_ERROR(ValidateFrameRange(spec.frames(), limits.max_frames));
  if (!v1::ImageEncoding_IsValid(spec.encoding()))
    return Invalid("spec.encoding", absl::StrCat("unknown value ", spec.encoding()));
  if (spec.encoding() == v1::VIDEO_H264)
    return Invalid("spec.encoding",
                   "VIDEO_H264 is for Stream sessions; a job writes one image per frame: "
                   "IMAGE_JPEG or IMAGE_PNG");
  if (!v1::JobOutput_IsValid(spec.output()))
    return Invalid("spec.output", absl::StrCat("unknown value ", spec.output()));
  // Checked whatever the output: a spec is journalled and may be resubmitted with another.
  RETURN_IF_ERROR(ValidateOutputDir(spec.output_dir()));
  if (!spec.name_pattern().empty()) {
    RETURN_IF_ERROR(ValidateNamePattern(spec.name_pattern()));
  }
  if (!(spec.fps() == 0.0 || (spec.fps() >= kMinFps && spec.fps() <= kMaxFps)))  // NaN fails
    return Invalid("spec.fps", absl::StrCat(spec.fps(), " is out of range (0, or ", kMinFps, "..",
                                            kMaxFps, " frames per second; 0: the time stands still)"));
  // Every frame's scene time within the setting's range (the last frame's is the largest).
  if (spec.fps() > 0.0) {
    const double last = SceneTimeSeconds(spec, spec.frames().last());
    if (!(std::abs(last) <= kMaxSceneTime))
      return Invalid("spec.fps", absl::StrCat("frame ", spec.frames().last(), " would be at ",
                                              last, " s, past the scene_time range (-1e6..1e6)"));
  }
  if (spec.taa_frames() > kMaxTaaFrames)
    return Invalid("spec.taa_frames",
                   absl::StrCat(spec.taa_frames(), " is more than ", kMaxTaaFrames));
  switch (spec.cameras_case()) {
    case v1::JobSpec::kPath:
      return ValidatePath(spec.path(), limits);
    case v1::JobSpec::kList:
      return ValidateList(spec.list(), spec.frames());
    case v1::JobSpec::CAMERAS_NOT_SET:
      break;
  }
  return absl::OkStatus();
}

absl::StatusOr<v1::Camera> CameraAtFrame(const v1::JobSpec& spec, uint32_t frame) {
  const v1::FrameRange& r = spec.frames();
  const std::optional<uint32_t> index = FrameIndex(r, frame);
  if (!index)
    return Invalid("frame", absl::StrCat(frame, " is not a frame of spec.frames (", r.first(),
                                         " to ", r.last(), " step ", Step(r), ")"));
  switch (spec.cameras_case()) {
    case v1::JobSpec::kPath:
      if (spec.path().keyframes().empty())
        return Invalid("spec.path.keyframes", "is empty (a path needs at least one key)");
      for (int i = 0; i < spec.path().keyframes_size(); ++i)
        if (!spec.path().keyframes(i).has_look_at())
          return Invalid(absl::StrCat("spec.path.keyframes[", i, "].look_at"), "is required");
      return PathCamera(spec.path(), frame);
    case v1::JobSpec::kList:
      if (*index >= static_cast<uint32_t>(spec.list().cameras_size()))
        return Invalid("spec.list.cameras",
                       absl::StrCat(spec.list().cameras_size(), " cameras, frame ", frame,
                                    " is at index ", *index));
      return spec.list().cameras(static_cast<int>(*index));
    case v1::JobSpec::CAMERAS_NOT_SET:
      break;
  }
  return v1::Camera();
}

absl::Status ValidateNamePattern(const std::string& pattern) {
  return ParseNamePattern(pattern).status();
}

absl::Status ValidateOutputDir(const std::string& dir) {
  if (dir.empty()) return absl::OkStatus();  // the output root itself
  auto bad = [&](absl::string_view why) {
    return Invalid("spec.output_dir", absl::StrCat(Quote(dir), " ", why));
  };
  if (dir.size() > kMaxOutputDirBytes)
    return bad(absl::StrCat("is longer than ", kMaxOutputDirBytes, " bytes"));
  for (unsigned char c : dir) {
    if (c < 0x20 || c == 0x7f) return bad("contains a control character");
    if (c == '\\') return bad("contains a backslash (use '/')");
  }
  if (dir.front() == '/') return bad("is absolute (it is relative to the server's output root)");
  for (absl::string_view seg : absl::StrSplit(dir, '/')) {
    if (seg.empty()) return bad("has an empty path segment");
    if (seg == "." || seg == "..") return bad("has a '.' or '..' segment");
  }
  return absl::OkStatus();
}

const char* Extension(v1::ImageEncoding encoding) {
  return encoding == v1::IMAGE_PNG ? ".png" : ".jpg";
}

std::string FrameFileName(const v1::JobSpec& spec, uint32_t frame) {
  if (!spec.name_pattern().empty()) {
    absl::StatusOr<NamePattern> p = ParseNamePattern(spec.name_pattern());
    if (p.ok()) return Expand(*p, frame);
    // Unreachable for a validated spec; the default name beats a client-controlled one.
  }
  return Expand(NamePattern{"frame_", Extension(spec.encoding()), 5}, frame);
}

double SceneTimeSeconds(const v1::JobSpec& spec, uint32_t frame) {
  const double start = spec.settings().scene_time();  // 0 when unset
  return spec.fps() > 0.0 ? start + double(frame) / spec.fps() : start;
}

float SceneTimeAtFrame(const v1::JobSpec& spec, uint32_t frame) {
  return static_cast<float>(SceneTimeSeconds(spec, frame));
}

uint32_t TaaFrames(const v1::JobSpec& spec) {
  return spec.taa_frames() == 0 ? kDefaultTaaFrames : spec.taa_frames();
}

}  // namespace tessera::jobs

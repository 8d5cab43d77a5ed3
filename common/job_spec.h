#pragma once
// Render-job specs (tessera/v1/job.proto) without the scene or the server's state: validation
// at submit time, the frame numbers of a range, the camera of each frame (keyframe
// interpolation) and output file names. Pure functions over the generated protos, so the
// daemon, the journal replay and RenderJobFrame all see the same frames, cameras and names,
// and the tests need no server.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "tessera/v1/job.pb.h"

namespace tessera::jobs {

struct JobLimits {
  uint32_t max_frames = 100000;    // frames in one job (ServerOptions.max_job_frames)
  uint32_t max_keyframes = 10000;  // keys in a CameraPath (a CameraList is bound by max_frames)
};

// The server's limits, mirrored here so a spec is refused when it is submitted rather than
// failing frame after frame at render time.
inline constexpr uint32_t kMaxNameBytes = 256;
inline constexpr uint32_t kMaxTaaFrames = 64;
inline constexpr uint32_t kDefaultTaaFrames = 8;
inline constexpr double kMinFps = 1e-3;  // 0 also: the time stands still
inline constexpr double kMaxFps = 1000.0;
inline constexpr double kMaxSceneTime = 1e6;  // RenderSettings.scene_time's range
inline constexpr float kDefaultYfov = 0.8f;
// renderer/camera.cpp's ValidateCamera accepts yfov in (0, 3.1), a little short of pi.
inline constexpr float kMaxYfov = 3.1f;
inline constexpr float kDefaultZnear = 0.05f;
inline constexpr size_t kMaxNamePatternBytes = 200;
inline constexpr size_t kMaxOutputDirBytes = 1024;

// Frames in the range: (last - first) / step + 1, step 0 meaning 1. No validation: 0 when
// last < first. Computed without materialising the frames and without wrapping near UINT32_MAX
// (the count of 0..UINT32_MAX does not fit a uint32 and saturates to UINT32_MAX).
uint32_t FrameCount(const v1::FrameRange& range);

// OK when last >= first (INVALID_ARGUMENT "spec.frames.last: ...") and the range has at most
// `max_frames` frames (RESOURCE_EXHAUSTED naming max_job_frames).
absl::Status ValidateFrameRange(const v1::FrameRange& range, uint32_t max_frames);

// Frame numbers of the range, ascending: first, first + step, ... <= last. Errors as
// ValidateFrameRange, checked before anything is allocated.
absl::StatusOr<std::vector<uint32_t>> FrameNumbers(const v1::FrameRange& range,
                                                   uint32_t max_frames);

// Position (0-based) of frame number `frame` in the range; nullopt when it is not one of its
// frames (outside [first, last], off the step, or last < first).
std::optional<uint32_t> FrameIndex(const v1::FrameRange& range, uint32_t frame);

// Everything about a spec that can be checked without the scene or the server's state: name
// length, frames, encoding, output, output_dir, name_pattern, taa_frames and the cameras (path
// keys: present, finite, ordered, not degenerate; list: one camera per frame, finite numbers;
// the server's camera resolver checks the rest of a list's cameras per frame). Errors are
// INVALID_ARGUMENT naming the field path, e.g. "spec.path.keyframes[3].frame: ...", except the
// frame and keyframe limits (RESOURCE_EXHAUSTED).
absl::Status ValidateJobSpec(const v1::JobSpec& spec, const JobLimits& limits = {});

// The camera for frame number `frame` (INVALID_ARGUMENT when it is not a frame of the range).
//  path: look_at = eye/target/up interpolated between the keys around the frame (LINEAR or
//   UNSPECIFIED: linear; STEP: the last key at or before the frame; CATMULL_ROM: a uniform
//   Catmull-Rom spline through every key, end keys duplicated), yfov likewise (0.8 for a key
//   without one), znear/zfar from the path when set. Frames before the first key (after the
//   last) hold that key. The result is never degenerate: up is renormalised and falls back to
//   the previous key's up when it turns (nearly) parallel to the view direction.
//  list: cameras[FrameIndex(frame)].
//  neither: a default Camera (no placement: the server frames the scene bounds).
// Meant for specs that passed ValidateJobSpec; any other spec gives an error or some camera,
// never a crash.
absl::StatusOr<v1::Camera> CameraAtFrame(const v1::JobSpec& spec, uint32_t frame);

// INVALID_ARGUMENT ("spec.name_pattern: ...") unless `pattern` has exactly one "%d" or "%0Nd"
// (N 1..9), no other '%' except "%%", no '/', '\\' or control characters, and is 1..200 bytes.
absl::Status ValidateNamePattern(const std::string& pattern);

// INVALID_ARGUMENT ("spec.output_dir: ...") unless `dir` is "" (the output root) or a relative
// '/'-separated path without empty, "." or ".." segments, backslashes or control characters,
// at most 1024 bytes.
absl::Status ValidateOutputDir(const std::string& dir);

// ".png" for IMAGE_PNG, ".jpg" otherwise (JPEG is the default encoding).
const char* Extension(v1::ImageEncoding encoding);

// The file name of frame number `frame`: name_pattern with its conversion replaced by the
// number (zero-padded to N digits for "%0Nd", never truncated) and "%%" by '%', or
// "frame_%05d" plus Extension(spec.encoding()) when name_pattern is empty. The pattern must
// have passed ValidateNamePattern.
std::string FrameFileName(const v1::JobSpec& spec, uint32_t frame);

// The scene time of frame number `frame`: spec.settings.scene_time (0 when unset) plus
// frame / spec.fps (nothing when fps is 0), computed in double and rounded to the setting's
// float once, so every daemon poses a frame alike.
float SceneTimeAtFrame(const v1::JobSpec& spec, uint32_t frame);
// The same before the rounding to float (what validation holds to the setting's range).
double SceneTimeSeconds(const v1::JobSpec& spec, uint32_t frame);

// spec.taa_frames, or 8 when 0.
uint32_t TaaFrames(const v1::JobSpec& spec);

}  // namespace tessera::jobs

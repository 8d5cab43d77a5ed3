// Render-job specs without a server: frame ranges (steps, the limit, ranges that end at
// UINT32_MAX), submit-time validation (every error names the field a person has to fix),
// keyframe interpolation (linear, step, Catmull-Rom through the keys, holding outside them,
// never a degenerate camera), camera lists and output file names.
#include "common/job_spec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "tests/unit/status_matchers.h"

namespace tessera::jobs {
namespace {

using test::IsError;

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr uint32_t kMax = std::numeric_limits<uint32_t>::max();

v1::FrameRange Range(uint32_t first, uint32_t last, uint32_t step = 0) {
  v1::FrameRange r;
  r.set_first(first);
  r.set_last(last);
  r.set_step(step);
  return r;
}

void Set(const glm::vec3& v, v1::Vec3* out) {
  out->set_x(v.x);
  out->set_y(v.y);
  out->set_z(v.z);
}

glm::vec3 V(const v1::Vec3& v) { return {v.x(), v.y(), v.z()}; }

v1::CameraKeyframe* AddKey(v1::CameraPath* path, uint32_t frame, glm::vec3 eye, glm::vec3 target,
                           glm::vec3 up = glm::vec3(0.0f), std::optional<float> yfov = {}) {
  v1::CameraKeyframe* k = path->add_keyframes();
  k->set_frame(frame);
  Set(eye, k->mutable_look_at()->mutable_eye());
  Set(target, k->mutable_look_at()->mutable_target());
  if (up != glm::vec3(0.0f)) Set(up, k->mutable_look_at()->mutable_up());
  if (yfov) k->set_yfov(*yfov);
  return k;
}

// Frames 0..100, three keys circling the origin: passes validation.
v1::JobSpec PathSpec(v1::Interpolation interpolation = v1::INTERPOLATION_LINEAR) {
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 100);
  v1::CameraPath* path = spec.mutable_path();
  path->set_interpolation(interpolation);
  AddKey(path, 0, {0, 1, 10}, {0, 0, 0});
  AddKey(path, 50, {10, 1, 0}, {0, 0, 0}, {0, 1, 0}, 0.6f);
  AddKey(path, 100, {0, 1, -10}, {0, 0, 0});
  return spec;
}

v1::Camera At(const v1::JobSpec& spec, uint32_t frame) {
  absl::StatusOr<v1::Camera> cam = CameraAtFrame(spec, frame);
  EXPECT_TRUE(cam.ok()) << "frame " << frame << ": " << cam.status();
  return cam.ok() ? *cam : v1::Camera();
}

glm::vec3 Eye(const v1::Camera& c) { return V(c.look_at().eye()); }
glm::vec3 Target(const v1::Camera& c) { return V(c.look_at().target()); }
glm::vec3 Up(const v1::Camera& c) { return V(c.look_at().up()); }

// What renderer/camera.cpp's ValidateCamera asks of a look-at camera, with margin.
::testing::AssertionResult Usable(const v1::Camera& c) {
  if (!c.has_look_at()) return ::testing::AssertionFailure() << "no look_at";
  const glm::vec3 d = Target(c) - Eye(c), up = Up(c);
  if (!(glm::length(d) >= 1e-6f)) return ::testing::AssertionFailure() << "target equals eye";
  if (!(std::abs(glm::length(up) - 1.0f) < 1e-5f))
    return ::testing::AssertionFailure() << "up has length " << glm::length(up);
  const float sine = glm::length(glm::cross(glm::normalize(d), up));
  if (!(sine > 1e-5f)) return ::testing::AssertionFailure() << "up parallel to view, sin " << sine;
  if (!(c.yfov() > 0.0f && c.yfov() < kMaxYfov))
    return ::testing::AssertionFailure() << "yfov " << c.yfov();
  return ::testing::AssertionSuccess();
}

// ---------------------------------------------------------------------------------------------
// Frame ranges

TEST(FrameRangeTest, NumbersFollowTheStep) {
  EXPECT_EQ(*FrameNumbers(Range(5, 20, 5), 100), (std::vector<uint32_t>{5, 10, 15, 20}));
  // last need not be on the step.
  EXPECT_EQ(*FrameNumbers(Range(5, 24, 5), 100), (std::vector<uint32_t>{5, 10, 15, 20}));
  EXPECT_EQ(*FrameNumbers(Range(3, 6, 0), 100), (std::vector<uint32_t>{3, 4, 5, 6}));  // 0 = 1
  EXPECT_EQ(*FrameNumbers(Range(3, 6, 1), 100), (std::vector<uint32_t>{3, 4, 5, 6}));
  EXPECT_EQ(*FrameNumbers(Range(7, 7), 100), (std::vector<uint32_t>{7}));
  EXPECT_EQ(*FrameNumbers(Range(0, 10, 100), 100), (std::vector<uint32_t>{0}));
  EXPECT_EQ(FrameCount(Range(5, 24, 5)), 4u);
  EXPECT_EQ(FrameCount(Range(0, 0)), 1u);
}

TEST(FrameRangeTest, NearUint32MaxDoesNotWrap) {
  EXPECT_EQ(*FrameNumbers(Range(kMax - 10, kMax, 4), 100),
            (std::vector<uint32_t>{kMax - 10, kMax - 6, kMax - 2}));
  EXPECT_EQ(*FrameNumbers(Range(kMax - 2, kMax), 100),
            (std::vector<uint32_t>{kMax - 2, kMax - 1, kMax}));
  EXPECT_EQ(*FrameNumbers(Range(kMax, kMax), 100), (std::vector<uint32_t>{kMax}));
  EXPECT_EQ(*FrameNumbers(Range(0, kMax, kMax), 100), (std::vector<uint32_t>{0, kMax}));
  EXPECT_EQ(*FrameNumbers(Range(1, kMax, kMax), 100), (std::vector<uint32_t>{1}));
  EXPECT_EQ(FrameCount(Range(kMax - 2, kMax)), 3u);
  // 2^32 frames do not fit the return type: saturated, and the limit names the true count.
  EXPECT_EQ(FrameCount(Range(0, kMax)), kMax);
  EXPECT_TRUE(IsError(FrameNumbers(Range(0, kMax), 100000).status(),
                      absl::StatusCode::kResourceExhausted, {"spec.frames", "4294967296"}));
}

TEST(FrameRangeTest, LimitIsCheckedBeforeMaterialising) {
  const absl::Status st = FrameNumbers(Range(0, 200000), 100000).status();
  EXPECT_TRUE(IsError(st, absl::StatusCode::kResourceExhausted, {}));
  EXPECT_EQ(st.message(),
            "spec.frames: 200001 frames, more than the max_job_frames limit (100000)");
  EXPECT_EQ(FrameNumbers(Range(0, 99999), 100000)->size(), 100000u);  // exactly at the limit
  EXPECT_EQ(FrameNumbers(Range(0, 199998, 2), 100000)->size(), 100000u);
  EXPECT_TRUE(IsError(FrameNumbers(Range(0, 200000, 2), 100000).status(),
                      absl::StatusCode::kResourceExhausted, {"100001", "max_job_frames"}));
}

TEST(FrameRangeTest, LastBeforeFirst) {
  const absl::Status st = FrameNumbers(Range(5, 3), 100).status();
  EXPECT_TRUE(IsError(st, absl::StatusCode::kInvalidArgument, {}));
  EXPECT_EQ(st.message(), "spec.frames.last: 3 is before spec.frames.first (5)");
  EXPECT_EQ(FrameCount(Range(5, 3)), 0u);
}

TEST(FrameRangeTest, FrameIndex) {
  const v1::FrameRange r = Range(10, 32, 5);  // 10 15 20 25 30
  EXPECT_EQ(FrameIndex(r, 10), 0u);
  EXPECT_EQ(FrameIndex(r, 25), 3u);
  EXPECT_EQ(FrameIndex(r, 30), 4u);
  EXPECT_EQ(FrameIndex(r, 12), std::nullopt);  // off the step
  EXPECT_EQ(FrameIndex(r, 9), std::nullopt);
  EXPECT_EQ(FrameIndex(r, 35), std::nullopt);  // on the step, past last
  EXPECT_EQ(FrameIndex(r, 0), std::nullopt);
  EXPECT_EQ(FrameIndex(Range(5, 3), 4), std::nullopt);
  EXPECT_EQ(FrameIndex(Range(0, 100), 100), 100u);  // step 0 = 1
  EXPECT_EQ(FrameIndex(Range(0, kMax, kMax), kMax), 1u);
  EXPECT_EQ(FrameIndex(Range(kMax - 10, kMax, 4), kMax - 2), 2u);
  EXPECT_EQ(FrameIndex(Range(kMax - 10, kMax, 4), kMax), std::nullopt);
  // Every frame of a range is found at its position.
  const std::vector<uint32_t> frames = *FrameNumbers(r, 100);
  for (uint32_t i = 0; i < frames.size(); ++i) EXPECT_EQ(FrameIndex(r, frames[i]), i);
}

// ---------------------------------------------------------------------------------------------
// ValidateJobSpec: the spec outside the cameras

absl::Status Validate(const v1::JobSpec& spec, const JobLimits& limits = {}) {
  return ValidateJobSpec(spec, limits);
}

::testing::AssertionResult Invalid(const absl::Status& st,
                                   std::initializer_list<std::string_view> needles) {
  return IsError(st, absl::StatusCode::kInvalidArgument, needles);
}

TEST(ValidateJobSpecTest, MinimalAndTypicalSpecsPass) {
  EXPECT_TRUE(Validate(v1::JobSpec()).ok());  // one frame (0..0), framed scene bounds
  EXPECT_TRUE(Validate(PathSpec()).ok());
  for (v1::Interpolation i :
       {v1::INTERPOLATION_UNSPECIFIED, v1::INTERPOLATION_CATMULL_ROM, v1::INTERPOLATION_STEP})
    EXPECT_TRUE(Validate(PathSpec(i)).ok());
  v1::JobSpec spec = PathSpec();
  spec.set_name(std::string(256, 'n'));
  spec.set_encoding(v1::IMAGE_PNG);
  spec.set_output(v1::JOB_OUTPUT_SERVER_DIR);
  spec.set_output_dir("shots/a1");
  spec.set_name_pattern("shot_%04d.png");
  spec.set_taa_frames(64);
  EXPECT_TRUE(Validate(spec).ok()) << Validate(spec);
}

TEST(ValidateJobSpecTest, TopLevelFieldsAreNamed) {
  v1::JobSpec spec = PathSpec();
  spec.set_name(std::string(257, 'n'));
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.name:", "257"}));

  spec = PathSpec();
  *spec.mutable_frames() = Range(5, 3);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.frames.last: 3 is before spec.frames.first (5)"}));

  spec = PathSpec();
  *spec.mutable_frames() = Range(0, 10);
  EXPECT_TRUE(IsError(Validate(spec, {.max_frames = 10}), absl::StatusCode::kResourceExhausted,
                      {"spec.frames:", "11 frames", "max_job_frames limit (10)"}));

  spec = PathSpec();
  spec.set_encoding(static_cast<v1::ImageEncoding>(7));
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.encoding:", "7"}));

  spec = PathSpec();
  spec.set_output(static_cast<v1::JobOutput>(9));
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.output:", "9"}));

  spec = PathSpec();
  spec.set_output_dir("a/../../etc");
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.output_dir:", "'..'"}));

  spec = PathSpec();
  spec.set_name_pattern("a/%d");
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.name_pattern:", "'/'"}));

  spec = PathSpec();
  spec.set_taa_frames(65);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.taa_frames:", "65", "64"}));

  for (double fps : {-1.0, 1000.5, 1e-300, double(NAN), double(INFINITY)}) {
    spec = PathSpec();
    spec.set_fps(fps);
    EXPECT_TRUE(Invalid(Validate(spec), {"spec.fps:", "0.001..1000"})) << fps;
  }
  spec = PathSpec();
  *spec.mutable_frames() = Range(0, 100000);
  spec.clear_path();
  spec.set_fps(0.05);  // frame 100000 at 2e6 s
  EXPECT_TRUE(Invalid(Validate(spec, {.max_frames = 200000}), {"spec.fps:", "frame 100000", "2e+06 s"}));
  spec.set_fps(24.0);
  EXPECT_TRUE(Validate(spec, {.max_frames = 200000}).ok());
}

TEST(JobSpecTest, SceneTimeFollowsTheFrameNumber) {
  v1::JobSpec spec;
  EXPECT_EQ(SceneTimeAtFrame(spec, 7), 0.0f) << "fps 0: the time stands still";
  spec.mutable_settings()->set_scene_time(1.5f);
  EXPECT_EQ(SceneTimeAtFrame(spec, 7), 1.5f);
  spec.set_fps(24.0);
  EXPECT_EQ(SceneTimeAtFrame(spec, 0), 1.5f);
  EXPECT_EQ(SceneTimeAtFrame(spec, 36), 3.0f);
  EXPECT_EQ(SceneTimeAtFrame(spec, 1), static_cast<float>(1.5 + 1.0 / 24.0));
  spec.set_fps(30.0);
  spec.mutable_settings()->clear_scene_time();
  EXPECT_EQ(SceneTimeAtFrame(spec, 3000000), 100000.0f);
}

// ---------------------------------------------------------------------------------------------
// ValidateJobSpec: camera paths

TEST(ValidateJobSpecTest, PathKeyCountAndOrder) {
  v1::JobSpec spec = PathSpec();
  spec.mutable_path()->clear_keyframes();
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes:", "empty"}));

  spec = PathSpec();
  EXPECT_TRUE(IsError(Validate(spec, {.max_keyframes = 2}), absl::StatusCode::kResourceExhausted,
                      {"spec.path.keyframes:", "3 keys", "(2)"}));
  EXPECT_TRUE(Validate(spec, {.max_keyframes = 3}).ok());

  spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(1)->set_frame(0);
  EXPECT_EQ(Validate(spec).message(),
            "spec.path.keyframes[1].frame: 0 is not after keyframes[0].frame (0)");

  spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(2)->set_frame(40);
  EXPECT_TRUE(Invalid(Validate(spec),
                      {"spec.path.keyframes[2].frame: 40 is not after keyframes[1].frame (50)"}));

  spec = PathSpec();
  spec.mutable_path()->set_interpolation(static_cast<v1::Interpolation>(9));
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.interpolation:", "9"}));

  // Keys outside the range are fine: frames before (after) them hold the key.
  spec = PathSpec();
  *spec.mutable_frames() = Range(20, 30);
  EXPECT_TRUE(Validate(spec).ok());
}

TEST(ValidateJobSpecTest, PathKeyPlacement) {
  v1::JobSpec spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(2)->clear_look_at();
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[2].look_at:", "required"}));

  spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_eye()->set_y(kNan);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[1].look_at.eye:", "non-finite"}));

  spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(0)->mutable_look_at()->mutable_target()->set_x(kInf);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[0].look_at.target:"}));

  spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_up()->set_z(-kInf);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[1].look_at.up:"}));

  spec = PathSpec();
  Set({3, 4, 5}, spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_eye());
  Set({3, 4, 5}, spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_target());
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[1].look_at.target:", "equals eye"}));

  // Up along the view direction (key 1 looks along (-10, -1, 0)), either way round and
  // whatever its length.
  for (const glm::vec3& up : {glm::vec3(-30, -3, 0), glm::vec3(20, 2, 0)}) {
    spec = PathSpec();
    Set(up, spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_up());
    EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[1].look_at.up:", "parallel"}));
  }

  // An unset (zero) up is +Y, which is parallel to a camera looking straight down.
  spec = PathSpec();
  Set({0, 10, 0}, spec.mutable_path()->mutable_keyframes(2)->mutable_look_at()->mutable_eye());
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[2].look_at.up:"}));
  Set({0, 0, 1}, spec.mutable_path()->mutable_keyframes(2)->mutable_look_at()->mutable_up());
  EXPECT_TRUE(Validate(spec).ok());

  // The parallel check is relative: a large scene far from the origin is fine, and so is a
  // tiny one...
  spec = PathSpec();
  Set({1e7f, 1e7f, 1e7f + 1000},
      spec.mutable_path()->mutable_keyframes(0)->mutable_look_at()->mutable_eye());
  Set({1e7f, 1e7f, 1e7f},
      spec.mutable_path()->mutable_keyframes(0)->mutable_look_at()->mutable_target());
  Set({1e-3f, 2e-3f, 0},
      spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_eye());
  Set({0, 0, 0}, spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_target());
  Set({0, 1e-4f, 0}, spec.mutable_path()->mutable_keyframes(1)->mutable_look_at()->mutable_up());
  EXPECT_TRUE(Validate(spec).ok()) << Validate(spec);
  // ...but up within 1e-4 radians of the view direction (key 0 looks down -Z) is parallel,
  // however far the camera is from the origin; 1e-3 radians is not.
  v1::LookAt* far = spec.mutable_path()->mutable_keyframes(0)->mutable_look_at();
  Set({0, 0, 1}, far->mutable_up());
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[0].look_at.up:"}));
  Set({1e-5f, 0, 1}, far->mutable_up());
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[0].look_at.up:"}));
  Set({1e-3f, 0, 1}, far->mutable_up());
  EXPECT_TRUE(Validate(spec).ok()) << Validate(spec);
}

TEST(ValidateJobSpecTest, PathLens) {
  for (float bad : {0.0f, -0.5f, kMaxYfov, 3.2f, kNan, kInf}) {
    v1::JobSpec spec = PathSpec();
    spec.mutable_path()->mutable_keyframes(2)->set_yfov(bad);
    EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.keyframes[2].yfov:"})) << bad;
  }
  v1::JobSpec spec = PathSpec();
  spec.mutable_path()->mutable_keyframes(2)->set_yfov(3.0f);
  EXPECT_TRUE(Validate(spec).ok());

  for (float bad : {0.0f, -1.0f, kNan, kInf}) {
    spec = PathSpec();
    spec.mutable_path()->set_znear(bad);
    EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.znear:"})) << bad;
  }
  spec = PathSpec();
  spec.mutable_path()->set_znear(1.0f);
  spec.mutable_path()->set_zfar(0.5f);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.zfar:", "znear (1)"}));
  spec.mutable_path()->set_zfar(1.0f);  // equal is not after
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.zfar:"}));
  spec.mutable_path()->set_zfar(kNan);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.zfar:"}));
  spec.mutable_path()->set_zfar(0.0f);  // infinite
  EXPECT_TRUE(Validate(spec).ok());
  spec.mutable_path()->set_zfar(1000.0f);
  EXPECT_TRUE(Validate(spec).ok());
  // Without znear the far plane is compared with the renderer's default near plane (0.05).
  spec.mutable_path()->clear_znear();
  spec.mutable_path()->set_zfar(0.01f);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.path.zfar:", "0.05"}));
}

// ---------------------------------------------------------------------------------------------
// ValidateJobSpec: camera lists

v1::JobSpec ListSpec(const v1::FrameRange& frames, int cameras) {
  v1::JobSpec spec;
  *spec.mutable_frames() = frames;
  spec.mutable_list();  // set the oneof even with no cameras
  for (int i = 0; i < cameras; ++i) {
    v1::Camera* c = spec.mutable_list()->add_cameras();
    Set({0, 0, 5.0f + i}, c->mutable_look_at()->mutable_eye());
    c->set_yfov(0.5f + 0.1f * i);
  }
  return spec;
}

TEST(ValidateJobSpecTest, ListHasOneCameraPerFrame) {
  EXPECT_TRUE(Validate(ListSpec(Range(10, 20, 5), 3)).ok());
  EXPECT_TRUE(Invalid(Validate(ListSpec(Range(10, 20, 5), 4)),
                      {"spec.list.cameras:", "4 cameras", "3 frames"}));
  EXPECT_TRUE(Invalid(Validate(ListSpec(Range(10, 20, 5), 2)),
                      {"spec.list.cameras:", "2 cameras", "3 frames"}));
  EXPECT_TRUE(Invalid(Validate(ListSpec(Range(0, 0), 0)), {"spec.list.cameras:", "0 cameras"}));
  // The frame limit comes first, so a huge range is not compared camera by camera.
  EXPECT_TRUE(IsError(Validate(ListSpec(Range(0, 9), 10), {.max_frames = 5}),
                      absl::StatusCode::kResourceExhausted, {"spec.frames:"}));
}

TEST(ValidateJobSpecTest, ListCameraNumbersAreFinite) {
  v1::JobSpec spec = ListSpec(Range(0, 3), 4);
  spec.mutable_list()->mutable_cameras(1)->mutable_look_at()->mutable_up()->set_x(kNan);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[1].look_at.up:"}));

  spec = ListSpec(Range(0, 3), 4);
  spec.mutable_list()->mutable_cameras(2)->mutable_look_at()->mutable_target()->set_z(kInf);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[2].look_at.target:"}));

  spec = ListSpec(Range(0, 3), 4);
  v1::Mat4* m = spec.mutable_list()->mutable_cameras(3)->mutable_view_matrix();
  for (int i = 0; i < 16; ++i) m->add_m(i % 5 == 0 ? 1.0f : 0.0f);
  EXPECT_TRUE(Validate(spec).ok());
  m->set_m(7, kNan);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[3].view_matrix.m:", "non-finite"}));
  m->mutable_m()->RemoveLast();
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[3].view_matrix.m:", "16", "15"}));

  spec = ListSpec(Range(0, 3), 4);
  spec.mutable_list()->mutable_cameras(0)->set_yfov(kInf);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[0].yfov:"}));
  spec = ListSpec(Range(0, 3), 4);
  spec.mutable_list()->mutable_cameras(0)->set_znear(kNan);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[0].znear:"}));
  spec = ListSpec(Range(0, 3), 4);
  spec.mutable_list()->mutable_cameras(3)->set_zfar(-kInf);
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[3].zfar:"}));
  spec = ListSpec(Range(0, 3), 4);
  Set({kNan, 0, 1}, spec.mutable_list()->mutable_cameras(2)->mutable_frame()->mutable_direction());
  EXPECT_TRUE(Invalid(Validate(spec), {"spec.list.cameras[2].frame.direction:"}));

  // Deeper checks (eye == target, a scene camera index) are the resolver's, per frame.
  spec = ListSpec(Range(0, 3), 4);
  spec.mutable_list()->mutable_cameras(1)->set_scene_camera(99);
  spec.mutable_list()->mutable_cameras(2)->mutable_look_at()->Clear();
  EXPECT_TRUE(Validate(spec).ok());
}

// ---------------------------------------------------------------------------------------------
// CameraAtFrame: paths

TEST(CameraAtFrameTest, LinearMidpointIsExact) {
  for (v1::Interpolation interp : {v1::INTERPOLATION_LINEAR, v1::INTERPOLATION_UNSPECIFIED}) {
    v1::JobSpec spec;
    *spec.mutable_frames() = Range(0, 10);
    spec.mutable_path()->set_interpolation(interp);
    AddKey(spec.mutable_path(), 0, {0, 0, 10}, {0, 0, 0}, {0, 1, 0}, 0.5f);
    AddKey(spec.mutable_path(), 10, {2, 4, 16}, {2, 2, 2}, {0, 3, 0}, 1.0f);
    ASSERT_TRUE(Validate(spec).ok());
    const v1::Camera mid = At(spec, 5);
    EXPECT_EQ(Eye(mid), glm::vec3(1, 2, 13));
    EXPECT_EQ(Target(mid), glm::vec3(1, 1, 1));
    EXPECT_EQ(Up(mid), glm::vec3(0, 1, 0));  // renormalised
    EXPECT_EQ(mid.yfov(), 0.75f);
    const v1::Camera quarter = At(spec, 2);  // t = 0.2
    EXPECT_NEAR(Eye(quarter).y, 0.8f, 1e-6f);
    EXPECT_NEAR(quarter.yfov(), 0.6f, 1e-6f);
    // At the keys: the keys.
    EXPECT_EQ(Eye(At(spec, 0)), glm::vec3(0, 0, 10));
    EXPECT_EQ(Eye(At(spec, 10)), glm::vec3(2, 4, 16));
    EXPECT_EQ(At(spec, 10).yfov(), 1.0f);
    for (uint32_t f = 0; f <= 10; ++f) EXPECT_TRUE(Usable(At(spec, f))) << f;
  }
}

TEST(CameraAtFrameTest, DefaultsAndPlanes) {
  v1::JobSpec spec = PathSpec();
  const v1::Camera first = At(spec, 0);
  EXPECT_EQ(first.yfov(), kDefaultYfov);     // key 0 has none
  EXPECT_EQ(Up(first), glm::vec3(0, 1, 0));  // nor an up
  EXPECT_FALSE(first.has_znear());
  EXPECT_FALSE(first.has_zfar());
  EXPECT_EQ(At(spec, 50).yfov(), 0.6f);
  EXPECT_NEAR(At(spec, 25).yfov(), 0.7f, 1e-6f);  // between the default 0.8 and 0.6
  spec.mutable_path()->set_znear(0.25f);
  spec.mutable_path()->set_zfar(500.0f);
  for (uint32_t f : {0u, 33u, 100u}) {
    const v1::Camera c = At(spec, f);
    EXPECT_EQ(c.znear(), 0.25f);
    EXPECT_EQ(c.zfar(), 500.0f);
    EXPECT_TRUE(c.has_look_at());
  }
}

TEST(CameraAtFrameTest, StepHoldsEachKeyUntilTheNext) {
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 10);
  spec.mutable_path()->set_interpolation(v1::INTERPOLATION_STEP);
  AddKey(spec.mutable_path(), 0, {0, 0, 1}, {0, 0, 0});
  AddKey(spec.mutable_path(), 4, {0, 0, 2}, {0, 0, 0}, {}, 0.4f);
  AddKey(spec.mutable_path(), 8, {0, 0, 3}, {0, 0, 0});
  ASSERT_TRUE(Validate(spec).ok());
  const float want_z[] = {1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3};
  for (uint32_t f = 0; f <= 10; ++f) EXPECT_EQ(Eye(At(spec, f)).z, want_z[f]) << f;
  EXPECT_EQ(At(spec, 7).yfov(), 0.4f);
  EXPECT_EQ(At(spec, 8).yfov(), kDefaultYfov);
}

TEST(CameraAtFrameTest, HoldsBeforeTheFirstKeyAndAfterTheLast) {
  for (v1::Interpolation interp :
       {v1::INTERPOLATION_LINEAR, v1::INTERPOLATION_CATMULL_ROM, v1::INTERPOLATION_STEP}) {
    v1::JobSpec spec;
    *spec.mutable_frames() = Range(0, 30);
    spec.mutable_path()->set_interpolation(interp);
    AddKey(spec.mutable_path(), 10, {1, 2, 3}, {0, 0, 0}, {}, 0.5f);
    AddKey(spec.mutable_path(), 20, {4, 5, 6}, {1, 1, 1}, {}, 0.9f);
    ASSERT_TRUE(Validate(spec).ok());
    for (uint32_t f : {0u, 5u, 10u}) {
      EXPECT_EQ(Eye(At(spec, f)), glm::vec3(1, 2, 3)) << interp << " frame " << f;
      EXPECT_EQ(At(spec, f).yfov(), 0.5f);
    }
    for (uint32_t f : {20u, 25u, 30u}) {
      EXPECT_EQ(Eye(At(spec, f)), glm::vec3(4, 5, 6)) << interp << " frame " << f;
      EXPECT_EQ(Target(At(spec, f)), glm::vec3(1, 1, 1));
      EXPECT_EQ(At(spec, f).yfov(), 0.9f);
    }
  }
  // A single key is every frame's camera.
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 5);
  AddKey(spec.mutable_path(), 3, {1, 2, 3}, {0, 0, 0});
  for (uint32_t f = 0; f <= 5; ++f) EXPECT_EQ(Eye(At(spec, f)), glm::vec3(1, 2, 3));
}

v1::JobSpec CurvySpec(v1::Interpolation interp, uint32_t spacing) {
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 4 * spacing);
  spec.mutable_path()->set_interpolation(interp);
  const float xs[] = {0, 5, 1, 7, 2};
  const float fovs[] = {0.5f, 0.9f, 0.6f, 1.2f, 0.7f};
  for (uint32_t i = 0; i < 5; ++i)
    AddKey(spec.mutable_path(), i * spacing, {xs[i], 1.0f + i, 20}, {xs[i] * 0.5f, 0, 0},
           glm::normalize(glm::vec3(0.1f * i, 1, 0)), fovs[i]);
  return spec;
}

TEST(CameraAtFrameTest, CatmullRomPassesThroughEveryKey) {
  const v1::JobSpec spec = CurvySpec(v1::INTERPOLATION_CATMULL_ROM, 10);
  ASSERT_TRUE(Validate(spec).ok());
  for (const v1::CameraKeyframe& k : spec.path().keyframes()) {
    const v1::Camera c = At(spec, k.frame());
    EXPECT_EQ(Eye(c), V(k.look_at().eye())) << k.frame();
    EXPECT_EQ(Target(c), V(k.look_at().target())) << k.frame();
    const glm::vec3 up = V(k.look_at().up());
    EXPECT_NEAR(Up(c).x, up.x, 1e-6f);
    EXPECT_NEAR(Up(c).y, up.y, 1e-6f);
    EXPECT_EQ(c.yfov(), k.yfov()) << k.frame();
  }
  for (uint32_t f = 0; f <= 40; ++f) EXPECT_TRUE(Usable(At(spec, f))) << f;
}

TEST(CameraAtFrameTest, CatmullRomOnAStraightEvenlySpacedLineIsTheLine) {
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 30);
  spec.mutable_path()->set_interpolation(v1::INTERPOLATION_CATMULL_ROM);
  for (uint32_t i = 0; i < 4; ++i)
    AddKey(spec.mutable_path(), 10 * i, {1.0f * i, 2.0f * i, 10}, {1.0f * i, 2.0f * i, 0});
  ASSERT_TRUE(Validate(spec).ok());
  // Between the inner keys the spline reproduces the line exactly (up to rounding).
  for (uint32_t f = 10; f <= 20; ++f) {
    const v1::Camera c = At(spec, f);
    EXPECT_NEAR(Eye(c).x, f / 10.0f, 1e-6f) << f;
    EXPECT_NEAR(Eye(c).y, f / 5.0f, 1e-6f) << f;
    EXPECT_NEAR(Target(c).x, f / 10.0f, 1e-6f) << f;
    EXPECT_EQ(Eye(c).z, 10.0f);
  }
  // The end keys are duplicated, so the outer segments ease in and out rather than follow the
  // line: 0.5 * (t + 2t^2 - t^3) at t = 0.5 on the first.
  EXPECT_NEAR(Eye(At(spec, 5)).x, 0.4375f, 1e-6f);
  EXPECT_NEAR(Eye(At(spec, 25)).x, 3.0f - 0.4375f, 1e-6f);
}

TEST(CameraAtFrameTest, CatmullRomIsSmoothAtTheKeysWhereLinearHasKinks) {
  // Slopes either side of the inner keys, one frame apart with keys 1000 frames apart: the
  // spline's differ by its second derivative's jump (~3e-5 here), linear's by ~0.01.
  auto kinks = [](v1::Interpolation interp) {
    const v1::JobSpec spec = CurvySpec(interp, 1000);
    float worst = 0.0f;
    for (uint32_t key : {1000u, 2000u, 3000u}) {
      const float left = Eye(At(spec, key)).x - Eye(At(spec, key - 1)).x;
      const float right = Eye(At(spec, key + 1)).x - Eye(At(spec, key)).x;
      worst = std::max(worst, std::abs(right - left));
    }
    return worst;
  };
  EXPECT_LT(kinks(v1::INTERPOLATION_CATMULL_ROM), 2e-4f);
  EXPECT_GT(kinks(v1::INTERPOLATION_LINEAR), 5e-3f);
  // The tangent at an inner key is half the difference of its neighbours (per segment).
  const v1::JobSpec spec = CurvySpec(v1::INTERPOLATION_CATMULL_ROM, 1000);
  const float slope = (Eye(At(spec, 2001)).x - Eye(At(spec, 1999)).x) / 2.0f;
  EXPECT_NEAR(slope, (7.0f - 5.0f) / 2.0f / 1000.0f, 2e-5f);
}

TEST(CameraAtFrameTest, CatmullRomKeepsYfovInRange) {
  // 0.1, 3.0, 3.0: the spline overshoots above 3.0 between the last two keys (past 3.1, the
  // renderer's limit, unclamped).
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 20);
  spec.mutable_path()->set_interpolation(v1::INTERPOLATION_CATMULL_ROM);
  AddKey(spec.mutable_path(), 0, {0, 0, 5}, {0, 0, 0}, {}, 0.1f);
  AddKey(spec.mutable_path(), 10, {0, 0, 6}, {0, 0, 0}, {}, 3.0f);
  AddKey(spec.mutable_path(), 20, {0, 0, 7}, {0, 0, 0}, {}, 3.0f);
  ASSERT_TRUE(Validate(spec).ok());
  for (uint32_t f = 0; f <= 20; ++f) {
    EXPECT_LE(At(spec, f).yfov(), 3.0f) << f;
    EXPECT_GE(At(spec, f).yfov(), 0.1f) << f;
  }
}

TEST(CameraAtFrameTest, UpFallsBackToThePreviousKeyWhenInterpolatedParallel) {
  // Looking down -Z, then along (0, 2, 1): halfway the view is straight along +Y, and the ups
  // (1, 1, 0) and (-1, 1, 0) average to +Y as well.
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 10);
  AddKey(spec.mutable_path(), 0, {0, 0, 0}, {0, 0, -1}, {1, 1, 0});
  AddKey(spec.mutable_path(), 10, {0, 0, 0}, {0, 2, 1}, {-1, 1, 0});
  ASSERT_TRUE(Validate(spec).ok());
  const v1::Camera mid = At(spec, 5);
  EXPECT_EQ(Target(mid), glm::vec3(0, 1, 0));
  EXPECT_NEAR(Up(mid).x, std::sqrt(0.5f), 1e-6f);
  EXPECT_NEAR(Up(mid).y, std::sqrt(0.5f), 1e-6f);
  EXPECT_TRUE(Usable(mid));

  // Opposite ups cancel to zero halfway: the previous key's up again.
  spec.mutable_path()->clear_keyframes();
  AddKey(spec.mutable_path(), 0, {0, 0, 0}, {0, 0, -1}, {0, 1, 0});
  AddKey(spec.mutable_path(), 10, {0, 0, 0}, {1, 0, 0}, {0, -1, 0});
  ASSERT_TRUE(Validate(spec).ok());
  EXPECT_EQ(Up(At(spec, 5)), glm::vec3(0, 1, 0));
  // Either side of the zero the interpolated up is used, renormalised: it flips.
  EXPECT_EQ(Up(At(spec, 4)), glm::vec3(0, 1, 0));
  EXPECT_EQ(Up(At(spec, 6)), glm::vec3(0, -1, 0));
  EXPECT_EQ(Up(At(spec, 10)), glm::vec3(0, -1, 0));
}

TEST(CameraAtFrameTest, NeverDegenerate) {
  // Both keys' ups are +Y and the view passes through +Y: no key's up will do, so any up
  // perpendicular to the view is taken.
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 10);
  AddKey(spec.mutable_path(), 0, {0, 0, 0}, {0, 0, -1});
  AddKey(spec.mutable_path(), 10, {0, 0, 0}, {0, 2, 1});
  ASSERT_TRUE(Validate(spec).ok());
  const v1::Camera mid = At(spec, 5);
  EXPECT_EQ(Target(mid) - Eye(mid), glm::vec3(0, 1, 0));
  EXPECT_TRUE(Usable(mid));

  // Eye and target swap places: halfway they meet, and the camera looks the previous key's way.
  spec.mutable_path()->clear_keyframes();
  AddKey(spec.mutable_path(), 0, {0, 0, 0}, {1, 0, 0});
  AddKey(spec.mutable_path(), 10, {1, 0, 0}, {0, 0, 0});
  ASSERT_TRUE(Validate(spec).ok());
  EXPECT_EQ(Eye(At(spec, 5)), glm::vec3(0.5f, 0, 0));
  EXPECT_EQ(Target(At(spec, 5)), glm::vec3(1.5f, 0, 0));

  // Every frame of awkward paths, in every interpolation, is a camera the renderer accepts.
  for (v1::Interpolation interp :
       {v1::INTERPOLATION_LINEAR, v1::INTERPOLATION_CATMULL_ROM, v1::INTERPOLATION_STEP}) {
    v1::JobSpec s;
    *s.mutable_frames() = Range(0, 60);
    s.mutable_path()->set_interpolation(interp);
    AddKey(s.mutable_path(), 0, {0, 0, 0}, {1, 0, 0}, {0, 1, 0});
    AddKey(s.mutable_path(), 10, {1, 0, 0}, {0, 0, 0}, {0, -1, 0});
    AddKey(s.mutable_path(), 20, {0, 0, 0}, {0, 0, -1}, {0, 1, 0}, 3.0f);
    AddKey(s.mutable_path(), 30, {0, 0, 0}, {0, 2, 1}, {0, 1, 0}, 0.01f);
    AddKey(s.mutable_path(), 40, {0, 5, 0}, {0, 0, 0}, {0, 0, 1});
    AddKey(s.mutable_path(), 50, {0, -5, 0}, {0, 0, 0}, {0, 0, -1});
    ASSERT_TRUE(Validate(s).ok()) << Validate(s);
    for (uint32_t f = 0; f <= 60; ++f) EXPECT_TRUE(Usable(At(s, f))) << interp << " frame " << f;
  }
}

// ---------------------------------------------------------------------------------------------
// CameraAtFrame: lists, defaults, frames outside the range

TEST(CameraAtFrameTest, ListPicksTheCameraByIndex) {
  const v1::JobSpec spec = ListSpec(Range(10, 20, 5), 3);  // frames 10, 15, 20
  ASSERT_TRUE(Validate(spec).ok());
  EXPECT_EQ(At(spec, 10).yfov(), 0.5f);
  EXPECT_EQ(At(spec, 15).yfov(), spec.list().cameras(1).yfov());
  EXPECT_EQ(Eye(At(spec, 15)), glm::vec3(0, 0, 6));
  EXPECT_EQ(Eye(At(spec, 20)), glm::vec3(0, 0, 7));
  EXPECT_TRUE(Invalid(CameraAtFrame(spec, 12).status(), {"frame:", "12"}));
  EXPECT_TRUE(Invalid(CameraAtFrame(spec, 25).status(), {"frame:", "25"}));
  // A list that is short (never validated) is an error, not a crash.
  v1::JobSpec short_list = ListSpec(Range(10, 20, 5), 2);
  EXPECT_TRUE(Invalid(CameraAtFrame(short_list, 20).status(), {"spec.list.cameras"}));
}

TEST(CameraAtFrameTest, NoCamerasMeansFrameTheScene) {
  v1::JobSpec spec;
  *spec.mutable_frames() = Range(0, 3);
  const v1::Camera c = At(spec, 2);
  EXPECT_EQ(c.placement_case(), v1::Camera::PLACEMENT_NOT_SET);
  EXPECT_FALSE(c.has_yfov());
  EXPECT_TRUE(Invalid(CameraAtFrame(spec, 4).status(), {"frame:", "4"}));
}

TEST(CameraAtFrameTest, PathOffTheRangeOrWithoutKeysIsAnError) {
  v1::JobSpec spec = PathSpec();
  *spec.mutable_frames() = Range(0, 100, 10);
  EXPECT_TRUE(Invalid(CameraAtFrame(spec, 55).status(), {"frame:", "55"}));
  EXPECT_TRUE(CameraAtFrame(spec, 60).ok());
  spec.mutable_path()->clear_keyframes();
  EXPECT_TRUE(Invalid(CameraAtFrame(spec, 60).status(), {"spec.path.keyframes"}));
}

// ---------------------------------------------------------------------------------------------
// File names

TEST(FileNameTest, PatternExpansion) {
  v1::JobSpec spec;
  spec.set_name_pattern("shot_%04d.png");
  EXPECT_EQ(FrameFileName(spec, 7), "shot_0007.png");
  EXPECT_EQ(FrameFileName(spec, 12345), "shot_12345.png");  // wider than N: not cut
  spec.set_name_pattern("%d");
  EXPECT_EQ(FrameFileName(spec, 123), "123");
  EXPECT_EQ(FrameFileName(spec, 0), "0");
  EXPECT_EQ(FrameFileName(spec, kMax), "4294967295");
  spec.set_name_pattern("100%%_%d%%.jpg");
  EXPECT_EQ(FrameFileName(spec, 5), "100%_5%.jpg");
  spec.set_name_pattern("%09d");
  EXPECT_EQ(FrameFileName(spec, 42), "000000042");
  spec.set_name_pattern("a%01db");
  EXPECT_EQ(FrameFileName(spec, 3), "a3b");
}

TEST(FileNameTest, DefaultNames) {
  v1::JobSpec spec;
  EXPECT_EQ(FrameFileName(spec, 7), "frame_00007.jpg");
  EXPECT_EQ(FrameFileName(spec, 123456), "frame_123456.jpg");
  spec.set_encoding(v1::IMAGE_JPEG);
  EXPECT_EQ(FrameFileName(spec, 0), "frame_00000.jpg");
  spec.set_encoding(v1::IMAGE_PNG);
  EXPECT_EQ(FrameFileName(spec, 42), "frame_00042.png");
  EXPECT_STREQ(Extension(v1::IMAGE_PNG), ".png");
  EXPECT_STREQ(Extension(v1::IMAGE_JPEG), ".jpg");
  EXPECT_STREQ(Extension(v1::IMAGE_ENCODING_UNSPECIFIED), ".jpg");
  // A pattern that would not pass validation never reaches the file system.
  spec.set_name_pattern("../%s");
  EXPECT_EQ(FrameFileName(spec, 42), "frame_00042.png");
}

TEST(FileNameTest, PatternRejections) {
  for (const std::string& bad : std::vector<std::string>{"a/%d",
                                                         "%s",
                                                         "%d%d",
                                                         "%d_%04d",
                                                         "no_number",
                                                         "%010d",
                                                         "%00d",
                                                         "%0d",
                                                         "%5d",
                                                         "%",
                                                         "x%",
                                                         "%0",
                                                         "%04",
                                                         "a\\%d",
                                                         std::string("a\n%d"),
                                                         std::string("a\x7f%d"),
                                                         "",
                                                         "%ld",
                                                         "%%d",
                                                         std::string(199, 'x') + "%d"}) {
    EXPECT_TRUE(Invalid(ValidateNamePattern(bad), {"spec.name_pattern:"})) << "\"" << bad << "\"";
  }
  for (const std::string& good :
       std::vector<std::string>{"%d", "%01d", "%09d", "shot_%04d.png", "%%%d%%", "%%%%_%d", ".%d",
                                std::string(198, 'x') + "%d"}) {
    EXPECT_TRUE(ValidateNamePattern(good).ok())
        << "\"" << good << "\" " << ValidateNamePattern(good);
  }
  EXPECT_TRUE(Invalid(ValidateNamePattern("%d%d"), {"more than one"}));
  EXPECT_TRUE(Invalid(ValidateNamePattern("no_number"), {"no %d"}));
  EXPECT_TRUE(Invalid(ValidateNamePattern("a/%d"), {"'/'"}));
}

TEST(FileNameTest, OutputDir) {
  for (const std::string& good :
       std::vector<std::string>{"", "a", "a/b", "shots/2024-01-01/take 3", "..a/b..", ".x"})
    EXPECT_TRUE(ValidateOutputDir(good).ok()) << "\"" << good << "\"";
  for (const std::string& bad :
       std::vector<std::string>{"/abs", "a//b", "a/", "./a", "a/.", "..", "a/../b", "a\\b",
                                std::string("a\tb"), std::string(1025, 'a')})
    EXPECT_TRUE(Invalid(ValidateOutputDir(bad), {"spec.output_dir:"})) << "\"" << bad << "\"";
  EXPECT_TRUE(ValidateOutputDir(std::string(1024, 'a')).ok());
}

TEST(JobSpecTest, TaaFrames) {
  v1::JobSpec spec;
  EXPECT_EQ(TaaFrames(spec), 8u);
  spec.set_taa_frames(1);
  EXPECT_EQ(TaaFrames(spec), 1u);
  spec.set_taa_frames(64);
  EXPECT_EQ(TaaFrames(spec), 64u);
}

}  // namespace
}  // namespace tessera::jobs

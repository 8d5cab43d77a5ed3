#pragma once
// Translation between the wire (tessera.v1 messages) and the renderer's structs. Everything a
// client sends passes through here first: enum values, ranges and non-finite numbers are
// checked and errors name the proto field ("settings.width", "camera.look_at.eye").
#include <cstdint>
#include <string>

#include "absl/status/statusor.h"
#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/settings.h"
#include "server/settings_wire.h"  // MergeSettings, ToProto(Settings), FillChoices
#include "tessera/v1/render_service.pb.h"

namespace tessera::server {

// Idle refinement of one session (v1::InteractiveProfile with its defaults applied).
struct InteractiveProfile {
  bool enabled = false;
  float render_scale = 0.5f;
  uint32_t jpeg_quality = 60;
  uint32_t rest_ms = 250;
};

// `base` with the set fields of `update`; INVALID_ARGUMENT naming `field`.render_scale etc.
absl::StatusOr<InteractiveProfile> MergeProfile(const InteractiveProfile& base,
                                                const v1::InteractiveProfile& update,
                                                const std::string& field);

// How a session's frames are coded (v1::VideoSettings with its defaults applied).
struct VideoSettings {
  bool h264 = false;  // false: JPEG frames
  v1::VideoEncoderKind encoder = v1::VIDEO_ENCODER_AUTO;
  uint32_t crf = 23;
  uint32_t interactive_crf = 29;
  uint32_t max_bitrate_kbps = 0;
  uint32_t keyframe_interval = 0;
  std::string preset = "superfast";
  bool operator==(const VideoSettings&) const = default;
  // What a running encoder cannot change: a change of these starts a new video (a keyframe).
  bool SameStream(const VideoSettings& o) const {
    return h264 == o.h264 && encoder == o.encoder && max_bitrate_kbps == o.max_bitrate_kbps &&
           keyframe_interval == o.keyframe_interval && preset == o.preset;
  }
};

// `base` with the set fields of `update`; INVALID_ARGUMENT naming `field`.crf etc.
absl::StatusOr<VideoSettings> MergeVideo(const VideoSettings& base,
                                         const v1::VideoSettings& update,
                                         const std::string& field);
// `video` against the session's `settings` (h264 sizes, naming `prefix`settings.width/height)
// and this server (a hardware encoder, naming `prefix`video.encoder). `prefix`: "open." or "".
absl::Status CheckVideo(const VideoSettings& video, const Settings& settings,
                        const std::string& prefix);

// The concrete camera for `camera` in a scene (framing uses the scene bounds and the frame's
// aspect ratio). INVALID_ARGUMENT naming the field.
absl::StatusOr<Camera> ResolveCamera(const v1::Camera& camera, const SceneInfo& scene,
                                     float aspect);

void ToProto(const SceneInfo& info, v1::SceneInfo* out);  // scene_id etc. left to the caller
void ToProto(const Aabb& box, v1::Aabb* out);
// Eye/target/up of any camera (a view matrix is decomposed).
void CameraToProto(const Camera& camera, v1::Frame* out);
// Everything of `frame` except sequence, event_id, scene_id, data, encoding and queue wait.
void FrameToProto(const Frame& frame, v1::Frame* out);

// Every limit of `limits` into the proto field of the same name.
void ImportLimitsToProto(const ImportLimits& limits, v1::ImportLimits* out);

// The wire's Frame of a frame from the render loop (render_loop.h): everything but the
// encoded bytes (jobs write those to files), and the whole frame.
struct EncodedFrame;
void FrameMetaToProto(const EncodedFrame& frame, v1::Frame* out);
void ToProto(const EncodedFrame& frame, v1::Frame* out);

// The wire's SceneInfo of a scene in the store (scene_store.h).
struct SceneListing;
void ToProto(const SceneListing& scene, v1::SceneInfo* out);

}  // namespace tessera::server

// libFuzzer target: the server's validation of what clients send, decoded from protobuf bytes
// as gRPC would decode them. The first byte picks the request, the rest is its encoding:
//   0: an UploadScene stream: UploadRequest messages, each preceded by its varint length
//      (manifest and chunks through UploadAssembler, then the glTF import of what it built)
//   1: a RenderRequest (settings merged over the defaults and resolved against a device,
//      the camera resolved against a scene)
//   2: a Stream ClientEvent (settings, camera, interactive profile, video settings)
//   3: a SubmitJobRequest (the job spec, its frame numbers, cameras and file names)
//   4: a RenderJobFrameRequest (the spec and one frame)
// Errors are expected; crashes, hangs, leaks, and an accepted request the renderer could not
// use (non-finite camera, out-of-range settings) are the bugs.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "google/protobuf/io/coded_stream.h"
#include "renderer/scene/gltf_import.h"
#include "server/convert.h"
#include "common/job_spec.h"
#include "server/upload.h"
#include "tests/fuzz/file_set.h"
#include "tessera/v1/job.pb.h"
#include "tessera/v1/render_service.pb.h"

namespace {

using namespace tessera;

// A device like lavapipe's (1x/4x MSAA) and a scene with bounds and a camera.
constexpr DeviceCaps kCaps{.max_samples = 4, .sample_counts = 0b101};

SceneInfo TestScene() {
  SceneInfo info;
  info.name = "fuzz";
  info.bounds.extend(glm::vec3(-1.0f, -2.0f, -3.0f));
  info.bounds.extend(glm::vec3(4.0f, 5.0f, 6.0f));
  info.cameras.push_back(SceneCamera{.name = "file camera"});
  return info;
}

void CheckCamera(const absl::StatusOr<Camera>& camera) {
  if (!camera.ok()) return;
  if (!ValidateCamera(*camera).ok()) __builtin_trap();  // accepted but unusable
}

void Settings_(const v1::RenderSettings& update) {
  absl::StatusOr<Settings> merged = server::MergeSettings(Settings{}, update);
  if (!merged.ok()) return;
  if (!ValidateSettings(*merged).ok()) __builtin_trap();
  absl::StatusOr<ResolvedSettings> resolved = ResolveSettings(*merged, kCaps);
  if (!resolved.ok()) __builtin_trap();  // valid settings always resolve
}

void Camera_(const v1::Camera& camera, uint32_t width, uint32_t height) {
  static const SceneInfo scene = TestScene();
  const float aspect = width > 0 && height > 0 ? float(width) / float(height) : 1.0f;
  CheckCamera(server::ResolveCamera(camera, scene, aspect));
}

void Upload(const uint8_t* data, size_t size) {
  google::protobuf::io::CodedInputStream in(data, int(size));
  server::UploadAssembler assembler({.max_bytes = 1u << 20, .max_files = 16,
                                     .max_chunk_bytes = 64u << 10});
  v1::UploadRequest request;
  uint32_t length = 0;
  bool first = true;
  while (in.ReadVarint32(&length) && length <= (1u << 20)) {
    const auto limit = in.PushLimit(int(length));
    const bool parsed = request.ParseFromCodedStream(&in) && in.ConsumedEntireMessage();
    in.PopLimit(limit);
    if (!parsed) return;
    absl::Status st = first && request.has_manifest() ? assembler.Begin(request.manifest())
                      : request.has_chunk()           ? assembler.Add(request.mutable_chunk())
                                                      : absl::InvalidArgumentError("order");
    if (!st.ok()) return;
    first = false;
  }
  std::string scene_id;
  absl::StatusOr<GltfSource> source = assembler.Finish(&scene_id);
  if (!source.ok()) return;
  if (scene_id.size() != 64 || source->files.count(source->main_file) == 0) __builtin_trap();
  (void)ImportGltf(*source, fuzz::FuzzImportLimits());
}

void Job(const v1::JobSpec& spec, const uint32_t* only_frame) {
  constexpr jobs::JobLimits kLimits{.max_frames = 4096, .max_keyframes = 1024};
  if (!jobs::ValidateJobSpec(spec, kLimits).ok()) return;
  absl::StatusOr<std::vector<uint32_t>> frames =
      jobs::FrameNumbers(spec.frames(), kLimits.max_frames);
  if (!frames.ok() || frames->empty()) __builtin_trap();  // a valid spec has frames
  Settings_(spec.settings());
  auto one = [&](uint32_t frame) {
    absl::StatusOr<v1::Camera> camera = jobs::CameraAtFrame(spec, frame);
    if (!camera.ok()) __builtin_trap();  // validated: every frame has a camera
    Camera_(*camera, spec.settings().width(), spec.settings().height());
    if (jobs::FrameFileName(spec, frame).empty()) __builtin_trap();
  };
  if (only_frame != nullptr) {
    if (jobs::FrameIndex(spec.frames(), *only_frame)) one(*only_frame);
    return;
  }
  // The first, last and a few frames between: the path's ends and its interpolation.
  for (size_t i = 0; i < frames->size(); i += std::max<size_t>(1, frames->size() / 8))
    one((*frames)[i]);
  one(frames->back());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0 || size > (1u << 20)) return 0;
  const uint8_t which = data[0] % 5;
  ++data;
  --size;
  switch (which) {
    case 0:
      Upload(data, size);
      break;
    case 1: {
      v1::RenderRequest r;
      if (!r.ParseFromArray(data, int(size))) break;
      Settings_(r.settings());
      Camera_(r.camera(), r.settings().width(), r.settings().height());
      break;
    }
    case 2: {
      v1::ClientEvent e;
      if (!e.ParseFromArray(data, int(size))) break;
      if (e.has_open()) {
        Settings_(e.open().settings());
        Camera_(e.open().camera(), e.open().settings().width(), e.open().settings().height());
        (void)server::MergeProfile(server::InteractiveProfile{}, e.open().interactive(),
                                   "open.interactive");
        (void)server::MergeVideo(server::VideoSettings{}, e.open().video(), "open.video");
      }
      Settings_(e.settings());
      Camera_(e.camera(), e.settings().width(), e.settings().height());
      (void)server::MergeProfile(server::InteractiveProfile{}, e.interactive(), "interactive");
      (void)server::MergeVideo(server::VideoSettings{}, e.video(), "video");
      break;
    }
    case 3: {
      v1::SubmitJobRequest r;
      if (r.ParseFromArray(data, int(size))) Job(r.spec(), nullptr);
      break;
    }
    case 4: {
      v1::RenderJobFrameRequest r;
      if (r.ParseFromArray(data, int(size))) {
        const uint32_t frame = r.frame();
        Job(r.spec(), &frame);
      }
      break;
    }
  }
  return 0;
}

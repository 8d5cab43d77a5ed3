#include "server/convert.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/type_ptr.hpp>

#include "absl/strings/escaping.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/video.h"
#include "common/proto_vec.h"
#include "common/status_macros.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/message.h"
#include "server/render_loop.h"
#include "server/scene_store.h"

namespace tessera::server {
namespace {

absl::Status Bad(const std::string& field, const std::string& why) {
  return absl::InvalidArgumentError(absl::StrCat("camera.", field, ": ", why));
}

}  // namespace

absl::StatusOr<Camera> ResolveCamera(const v1::Camera& c, const SceneInfo& scene, float aspect) {
  Camera cam;
  // Lens first: a scene camera brings its own, which explicit fields override.
  switch (c.placement_case()) {
    case v1::Camera::kLookAt: {
      const v1::LookAt& l = c.look_at();
      if (!Finite(l.eye())) return Bad("look_at.eye", "non-finite");
      if (!Finite(l.target())) return Bad("look_at.target", "non-finite");
      if (!Finite(l.up())) return Bad("look_at.up", "non-finite");
      cam.eye = Vec(l.eye());
      cam.target = Vec(l.target());
      if (l.has_up()) cam.up = Vec(l.up());
      if (glm::length(cam.target - cam.eye) < 1e-6f) return Bad("look_at.target", "equals eye");
      if (glm::length(glm::cross(glm::normalize(cam.target - cam.eye), cam.up)) < 1e-6f)
        return Bad("look_at.up", "is zero or parallel to the view direction");
      break;
    }
    case v1::Camera::kViewMatrix: {
      const auto& m = c.view_matrix().m();
      if (m.size() != 16)
        return Bad("view_matrix.m", absl::StrCat("needs 16 values, got ", m.size()));
      for (float v : m)
        if (!std::isfinite(v)) return Bad("view_matrix.m", "non-finite value");
      cam.view = glm::make_mat4(m.data());
      if (std::abs(glm::determinant(*cam.view)) < 1e-12f)
        return Bad("view_matrix.m", "matrix is singular");
      break;
    }
    case v1::Camera::kSceneCamera: {
      if (c.scene_camera() >= scene.cameras.size())
        return Bad("scene_camera",
                   absl::StrCat(c.scene_camera(), " is out of range: the scene has ",
                                scene.cameras.size(), " cameras"));
      cam = FromSceneCamera(scene.cameras[c.scene_camera()], int32_t(c.scene_camera()));
      break;
    }
    case v1::Camera::kFrame:
    case v1::Camera::PLACEMENT_NOT_SET: {
      glm::vec3 dir(0.55f, 0.45f, 0.70f);
      if (c.has_frame() && c.frame().has_direction()) {
        if (!Finite(c.frame().direction())) return Bad("frame.direction", "non-finite");
        dir = Vec(c.frame().direction());
        if (glm::length(dir) < 1e-6f) return Bad("frame.direction", "is zero");
      }
      const float yfov = c.has_yfov() ? c.yfov() : cam.yfov;
      if (!std::isfinite(yfov) || yfov <= 0.0f || yfov >= 3.1f)
        return Bad("yfov", "must be in (0, 3.1) radians");
      if (scene.bounds.empty()) {
        cam.eye = glm::vec3(0.0f, 0.0f, 5.0f);  // nothing to frame
      } else {
        cam = FrameBounds(scene.bounds, yfov, aspect, dir);
      }
      break;
    }
  }
  if (c.has_yfov()) cam.yfov = c.yfov();
  if (c.has_znear()) cam.znear = c.znear();
  if (c.has_zfar()) cam.zfar = c.zfar();
  RETURN_IF_ERROR(ValidateCamera(cam));
  return cam;
}

void ToProto(const Aabb& box, v1::Aabb* out) {
  if (box.empty()) return;  // an empty scene has no bounds
  SetVec(box.min, out->mutable_min());
  SetVec(box.max, out->mutable_max());
}

void ToProto(const SceneInfo& info, v1::SceneInfo* o) {
  o->set_name(info.name);
  v1::SceneCounts* c = o->mutable_counts();
  c->set_nodes(info.counts.nodes);
  c->set_meshes(info.counts.meshes);
  c->set_primitives(info.counts.primitives);
  c->set_triangles(info.counts.triangles);
  c->set_materials(info.counts.materials);
  c->set_textures(info.counts.textures);
  c->set_images(info.counts.images);
  c->set_lights(info.counts.lights);
  c->set_cameras(info.counts.cameras);
  ToProto(info.bounds, o->mutable_bounds());
  for (const SceneCamera& cam : info.cameras) {
    v1::SceneCamera* pc = o->add_cameras();
    pc->set_name(cam.name);
    const float* m = glm::value_ptr(cam.world);
    for (int i = 0; i < 16; ++i) pc->mutable_world()->add_m(m[i]);
    pc->set_yfov(cam.yfov);
    pc->set_aspect(cam.aspect);
    pc->set_znear(cam.znear);
    pc->set_zfar(cam.zfar);
  }
  for (const std::string& w : info.warnings) o->add_warnings(w);
  o->set_device_bytes(info.device_bytes);
  for (const AnimationSummary& a : info.animations) {
    v1::AnimationInfo* pa = o->add_animations();
    pa->set_name(a.name);
    pa->set_duration_s(a.duration_s);
    pa->set_channels(a.channels);
  }
}

void CameraToProto(const Camera& camera, v1::Frame* out) {
  v1::LookAt* l = out->mutable_camera();
  if (camera.view) {
    const glm::mat4 inv = glm::inverse(*camera.view);
    const glm::vec3 eye(inv[3]);
    SetVec(eye, l->mutable_eye());
    SetVec(eye - glm::vec3(inv[2]), l->mutable_target());
    SetVec(glm::vec3(inv[1]), l->mutable_up());
  } else {
    SetVec(camera.eye, l->mutable_eye());
    SetVec(camera.target, l->mutable_target());
    SetVec(camera.up, l->mutable_up());
  }
  out->set_yfov(camera.yfov);
  out->set_znear(camera.znear);
  out->set_zfar(camera.zfar);
}

void FrameToProto(const Frame& f, v1::Frame* o) {
  o->set_width(f.image.width);
  o->set_height(f.image.height);
  ToProto(f.settings.effective, o->mutable_settings());
  for (const SettingNote& n : f.settings.notes) {
    v1::SettingNote* pn = o->add_notes();
    pn->set_field(n.field);
    pn->set_message(n.message);
  }
  for (const PassTiming& p : f.passes) {
    v1::PassTiming* pp = o->add_passes();
    pp->set_pass(p.pass);
    pp->set_gpu_ms(p.gpu_ms);
    pp->set_timestamp_ms(p.timestamp_ms);
  }
  switch (f.timing) {
    case TimingSource::kGpuTimestamps:
      o->set_timing_source(v1::TIMING_GPU_TIMESTAMPS);
      break;
    case TimingSource::kPassWallClock:
      o->set_timing_source(v1::TIMING_PASS_WALL_CLOCK);
      break;
    case TimingSource::kFrameWallClock:
      o->set_timing_source(v1::TIMING_FRAME_WALL_CLOCK);
      break;
  }
  o->set_gpu_total_ms(f.gpu_total_ms);
  v1::CpuTimings* cpu = o->mutable_cpu();
  cpu->set_record_ms(f.cpu.record_ms);
  cpu->set_gpu_ms(f.cpu.submit_wait_ms);
  cpu->set_submissions(f.cpu.submissions);
  cpu->set_readback_ms(f.cpu.readback_ms);
  cpu->set_encode_ms(f.cpu.encode_ms);
  v1::FrameStats* st = o->mutable_stats();
  st->set_drawables(f.stats.drawables);
  st->set_drawables_culled(f.stats.drawables_culled);
  st->set_draws(f.stats.draws);
  st->set_triangles_submitted(f.stats.triangles_submitted);
  st->set_lights(f.stats.lights);
  st->set_local_lights(f.stats.local_lights);
  st->set_tile_lights_avg(f.stats.tile_lights_avg);
  st->set_tile_lights_p50(f.stats.tile_lights_p50);
  st->set_tile_lights_p95(f.stats.tile_lights_p95);
  st->set_tile_lights_max(f.stats.tile_lights_max);
  st->set_tile_overflows(f.stats.tile_overflows);
  st->set_drawables_in_frustum(f.stats.drawables_in_frustum);
  st->set_drawables_drawn(f.stats.drawables_drawn);
  st->set_drawables_late(f.stats.drawables_late);
  st->set_drawables_stale(f.stats.drawables_stale);
  st->set_indirect_draws(f.stats.indirect_draws);
  st->set_pipeline_statistics(f.stats.pipeline_statistics);
  st->set_primitives_in(f.stats.primitives_in);
  st->set_primitives_clipped(f.stats.primitives_clipped);
  st->set_fragment_invocations(f.stats.fragment_invocations);
  st->set_shadowed_lights(f.stats.shadowed_lights);
  st->set_shadow_views(f.stats.shadow_views);
  st->set_shadow_faces_rendered(f.stats.shadow_faces_rendered);
  st->set_shadow_draws(f.stats.shadow_draws);
  st->set_shadow_evictions(f.stats.shadow_evictions);
  st->set_shaded_pixels(f.stats.shaded_pixels);
  st->set_shading_invocations(f.stats.shading_invocations);
  st->set_shading_dispatches(f.stats.shading_dispatches);
  st->set_edge_pixels(f.stats.edge_pixels);
  st->set_runner_up_pixels(f.stats.runner_up_pixels);
  st->set_blend_pixels(f.stats.blend_pixels);
  st->set_animated_drawables(f.stats.animated_drawables);
  st->set_deformed_vertices(f.stats.deformed_vertices);
}

absl::StatusOr<InteractiveProfile> MergeProfile(const InteractiveProfile& base,
                                                const v1::InteractiveProfile& u,
                                                const std::string& field) {
  InteractiveProfile p = base;
  if (u.has_enabled()) p.enabled = u.enabled();
  if (u.has_render_scale()) {
    const float s = u.render_scale();
    if (!std::isfinite(s) || s < 0.25f || s > 1.0f)
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".render_scale: ", s, " is out of range (0.25..1)"));
    p.render_scale = s;
  }
  if (u.has_jpeg_quality()) {
    if (u.jpeg_quality() < 1 || u.jpeg_quality() > 100)
      return absl::InvalidArgumentError(absl::StrCat(field, ".jpeg_quality: ", u.jpeg_quality(),
                                                     " is out of range (1..100)"));
    p.jpeg_quality = u.jpeg_quality();
  }
  if (u.has_rest_ms()) {
    if (u.rest_ms() > 60000)
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".rest_ms: ", u.rest_ms(), " is out of range (0..60000)"));
    p.rest_ms = u.rest_ms();
  }
  return p;
}

absl::StatusOr<VideoSettings> MergeVideo(const VideoSettings& base, const v1::VideoSettings& u,
                                         const std::string& field) {
  VideoSettings v = base;
  switch (u.codec()) {
    case v1::VIDEO_CODEC_UNSPECIFIED:
      break;
    case v1::VIDEO_CODEC_JPEG:
      v.h264 = false;
      break;
    case v1::VIDEO_CODEC_H264:
      v.h264 = true;
      break;
    default:
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".codec: ", static_cast<int>(u.codec()), " is not a VideoCodec"));
  }
  if (!v1::VideoEncoderKind_IsValid(u.encoder()))
    return absl::InvalidArgumentError(absl::StrCat(
        field, ".encoder: ", static_cast<int>(u.encoder()), " is not a VideoEncoderKind"));
  if (u.encoder() != v1::VIDEO_ENCODER_UNSPECIFIED) v.encoder = u.encoder();
  auto range = [&](bool has, uint32_t value, uint32_t lo, uint32_t hi, const char* name,
                   uint32_t* out) -> absl::Status {
    if (!has) return absl::OkStatus();
    if (value < lo || value > hi)
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".", name, ": ", value, " is out of range (", lo, "..", hi, ")"));
    *out = value;
    return absl::OkStatus();
  };
  // 0 would be lossless, in a profile (High 4:4:4 Predictive) browsers do not decode.
  RETURN_IF_ERROR(range(u.has_crf(), u.crf(), 1, 51, "crf", &v.crf));
  RETURN_IF_ERROR(
      range(u.has_interactive_crf(), u.interactive_crf(), 1, 51, "interactive_crf", &v.interactive_crf));
  RETURN_IF_ERROR(range(u.has_keyframe_interval(), u.keyframe_interval(), 0, 600,
                        "keyframe_interval", &v.keyframe_interval));
  if (u.has_max_bitrate_kbps()) {
    const uint32_t kbps = u.max_bitrate_kbps();
    if (kbps != 0 && (kbps < 100 || kbps > 500000))
      return absl::InvalidArgumentError(absl::StrCat(
          field, ".max_bitrate_kbps: ", kbps, " is out of range (0 for no cap, or 100..500000)"));
    v.max_bitrate_kbps = kbps;
  }
  if (u.has_preset()) {
    const std::vector<std::string>& presets = video::Presets();
    if (std::find(presets.begin(), presets.end(), u.preset()) == presets.end())
      return absl::InvalidArgumentError(
          absl::StrCat(field, ".preset: \"", absl::CEscape(u.preset().substr(0, 64)),
                       "\" is not one of ", absl::StrJoin(presets, ", ")));
    v.preset = u.preset();
  }
  return v;
}

absl::Status CheckVideo(const VideoSettings& video, const Settings& settings,
                        const std::string& prefix) {
  if (!video.h264) return absl::OkStatus();
  for (auto [name, v] : {std::pair{"width", settings.width}, std::pair{"height", settings.height}})
    if (!video::VideoSideOk(v))
      return absl::InvalidArgumentError(absl::StrCat(
          prefix, "settings.", name, ": ", v,
          " does not suit an h264 session (H.264 needs an even size of 16..", video::kMaxVideoSide,
          ")"));
  if (absl::Status st = video::CheckVideoSize(settings.width, settings.height); !st.ok())
    return absl::InvalidArgumentError(absl::StrCat(prefix, "settings.width: ", st.message()));
  if (video.encoder == v1::VIDEO_ENCODER_HARDWARE && !video::HardwareEncoderAvailable())
    return absl::FailedPreconditionError(
        absl::StrCat(prefix, "video.encoder: this server has no hardware H.264 encoder "
                             "(h264_nvenc does not open); use VIDEO_ENCODER_AUTO or SOFTWARE"));
  return absl::OkStatus();
}

void ImportLimitsToProto(const ImportLimits& limits, v1::ImportLimits* out) {
  // By name, so a limit added to ImportLimitFields() without its proto field shows up in the
  // unit test (a missing field is skipped here, never a crash).
  const google::protobuf::Descriptor* d = out->GetDescriptor();
  const google::protobuf::Reflection* r = out->GetReflection();
  for (const ImportLimitField& f : ImportLimitFields()) {
    const google::protobuf::FieldDescriptor* field = d->FindFieldByName(f.name);
    if (field == nullptr) continue;
    if (field->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_UINT64) {
      r->SetUInt64(out, field, f.Get(limits));
    } else if (field->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_UINT32) {
      r->SetUInt32(out, field, uint32_t(f.Get(limits)));
    }
  }
}

void FrameMetaToProto(const EncodedFrame& f, v1::Frame* o) {
  FrameToProto(f.frame, o);
  CameraToProto(f.camera, o);
  o->set_render_width(f.render_width);
  o->set_render_height(f.render_height);
  o->set_sequence(f.sequence);
  o->set_event_id(f.event_id);
  o->set_scene_id(f.scene_id);
  o->set_profile(f.profile);
  // Unencoded (video) frames get VIDEO_H264 when the session encodes them.
  o->set_encoding(f.format == ImageFormat::kPng ? v1::IMAGE_PNG : v1::IMAGE_JPEG);
  v1::CpuTimings* cpu = o->mutable_cpu();
  cpu->set_queue_wait_ms(f.queue_wait_ms);
  cpu->set_total_ms(f.total_ms);
}

void ToProto(const EncodedFrame& f, v1::Frame* o) {
  FrameMetaToProto(f, o);
  o->set_data(f.data.data(), f.data.size());
}

void ToProto(const SceneListing& s, v1::SceneInfo* o) {
  ToProto(s.info.scene, o);
  o->set_scene_id(s.id);
  o->set_upload_bytes(s.info.upload_bytes);
  o->set_load_ms(s.info.load_ms);
  o->set_sessions(s.sessions);
  o->set_deleted(s.deleted);
}

}  // namespace tessera::server

#include "clients/cli/cli_format.h"

#include <cmath>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "clients/cli/cli_common.h"

namespace tessera::cli {

namespace {

template <typename E>
std::string Name(E value, const google::protobuf::EnumDescriptor* type) {
  const google::protobuf::EnumValueDescriptor* v = type->FindValueByNumber(value);
  return v ? EnumShortName(v) : absl::StrCat(static_cast<int>(value));
}

const char* OnOff(bool b) { return b ? "on" : "off"; }

}  // namespace

std::string FormatVec3(const v1::Vec3& v) {
  return absl::StrFormat("(%.4g, %.4g, %.4g)", v.x(), v.y(), v.z());
}

std::string SettingsSummary(const v1::RenderSettings& s) {
  std::vector<std::string> parts;
  if (s.has_width() || s.has_height()) {
    parts.push_back(absl::StrCat(s.has_width() ? absl::StrCat(s.width()) : "default", "x",
                                 s.has_height() ? absl::StrCat(s.height()) : "default"));
  }
  if (s.aa() != v1::AA_MODE_UNSPECIFIED) {
    std::string aa = absl::StrCat("aa ", Name(s.aa(), v1::AaMode_descriptor()));
    if (s.has_samples() && (s.aa() == v1::AA_MSAA || s.aa() == v1::AA_VIS_MLAA)) {
      absl::StrAppend(&aa, " x", s.samples());
    }
    if (s.aa() == v1::AA_VIS_MLAA && s.vis_mlaa_coverage() != v1::VIS_MLAA_COVERAGE_UNSPECIFIED) {
      absl::StrAppend(&aa, " (", Name(s.vis_mlaa_coverage(), v1::VisMlaaCoverage_descriptor()),
                      " coverage)");
    }
    parts.push_back(aa);
  }
  // How the frame runs: in a frame's settings what auto chose on the server's device; in the
  // server's defaults or a bench configuration, as given (e.g. "auto").
  if (s.pipeline() != v1::PIPELINE_UNSPECIFIED)
    parts.push_back(absl::StrCat("pipeline ", Name(s.pipeline(), v1::Pipeline_descriptor())));
  if (s.post_stage() != v1::POST_STAGE_UNSPECIFIED)
    parts.push_back(absl::StrCat("post passes ", Name(s.post_stage(), v1::PostStage_descriptor())));
  if (s.light_binning() != v1::LIGHT_BINNING_UNSPECIFIED) {
    parts.push_back(
        absl::StrCat("light binning ", Name(s.light_binning(), v1::LightBinning_descriptor())));
  }
  if (s.culling() != v1::CULLING_MODE_UNSPECIFIED) {
    parts.push_back(absl::StrCat("culling ", Name(s.culling(), v1::CullingMode_descriptor())));
  }
  if (s.has_scene_lights()) parts.push_back(absl::StrCat("scene lights ", OnOff(s.scene_lights())));
  if (s.has_synthetic_lights()) {
    parts.push_back(
        absl::StrCat(s.synthetic_lights(), " synthetic lights",
                     s.has_light_seed() ? absl::StrCat(" (seed ", s.light_seed(), ")") : ""));
  }
  if (s.has_tile_size()) parts.push_back(absl::StrCat("tile ", s.tile_size()));
  if (s.has_shadows()) parts.push_back(absl::StrCat("shadows ", OnOff(s.shadows())));
  if (s.has_ssao()) parts.push_back(absl::StrCat("ssao ", OnOff(s.ssao())));
  if (s.has_bloom()) parts.push_back(absl::StrCat("bloom ", OnOff(s.bloom())));
  if (s.has_ibl()) parts.push_back(absl::StrCat("ibl ", OnOff(s.ibl())));
  if (s.exposure_mode() == v1::EXPOSURE_AUTO) {
    parts.push_back(s.exposure_ev() != 0.0f ? absl::StrFormat("exposure auto %+g EV", s.exposure_ev())
                                             : std::string("exposure auto"));
  } else if (s.exposure_mode() == v1::EXPOSURE_FIXED || s.has_exposure_ev()) {
    parts.push_back(absl::StrFormat("exposure %g EV", s.exposure_ev()));
  }
  if (s.tonemapper() != v1::TONEMAPPER_UNSPECIFIED) {
    parts.push_back(absl::StrCat("tonemapper ", Name(s.tonemapper(), v1::Tonemapper_descriptor())));
  }
  if (s.debug_view() != v1::DEBUG_VIEW_UNSPECIFIED) {
    parts.push_back(absl::StrCat("debug ", Name(s.debug_view(), v1::DebugView_descriptor())));
  }
  if (s.has_jpeg_quality() || s.has_jpeg_444()) {
    std::string q = "jpeg";
    if (s.has_jpeg_quality()) absl::StrAppend(&q, " q", s.jpeg_quality());
    if (s.has_jpeg_444()) absl::StrAppend(&q, s.jpeg_444() ? " 4:4:4" : " 4:2:0");
    parts.push_back(q);
  }
  if (s.has_pass_timing() && !s.pass_timing()) parts.push_back("pass timing off");
  if (!s.animation().empty() && s.animation() != "none") {
    parts.push_back(absl::StrFormat("animation %s at %g s%s%s", s.animation(), s.scene_time(),
                                    s.has_loop() && !s.loop() ? " (held at its end)" : "",
                                    s.play() ? " (playing)" : ""));
  }
  return parts.empty() ? "server defaults" : absl::StrJoin(parts, ", ");
}

std::string WrapList(const std::string& text, size_t indent) {
  constexpr size_t kWidth = 100;
  std::string out;
  size_t column = indent;
  for (absl::string_view item : absl::StrSplit(text, ", ")) {
    if (!out.empty()) {
      if (column + 2 + item.size() > kWidth) {
        absl::StrAppend(&out, ",\n", std::string(indent, ' '));
        column = indent;
      } else {
        out += ", ";
        column += 2;
      }
    }
    absl::StrAppend(&out, item);
    column += item.size();
  }
  return out;
}

std::string CameraSummary(const v1::Frame& frame) {
  const v1::LookAt& c = frame.camera();
  return absl::StrFormat("eye %s target %s up %s, fov %.1f deg, near %g, far %s",
                         FormatVec3(c.eye()), FormatVec3(c.target()), FormatVec3(c.up()),
                         frame.yfov() * 180.0 / M_PI, frame.znear(),
                         frame.zfar() == 0 ? "inf" : absl::StrFormat("%g", frame.zfar()));
}

void PrintSceneInfo(FILE* out, const v1::SceneInfo& info) {
  const v1::SceneCounts& c = info.counts();
  absl::FPrintF(out, "  id        %s\n", info.scene_id());
  absl::FPrintF(out,
                "  counts    %u nodes, %u meshes, %u primitives, %u triangles\n"
                "            %u materials, %u textures, %u images, %u lights, %u cameras\n",
                c.nodes(), c.meshes(), c.primitives(), c.triangles(), c.materials(), c.textures(),
                c.images(), c.lights(), c.cameras());
  if (info.has_bounds()) {
    absl::FPrintF(out, "  bounds    %s .. %s\n", FormatVec3(info.bounds().min()),
                  FormatVec3(info.bounds().max()));
  }
  absl::FPrintF(out, "  memory    %s uploaded, %s on the device, loaded in %.1f ms\n",
                HumanBytes(info.upload_bytes()), HumanBytes(info.device_bytes()), info.load_ms());
  for (int i = 0; i < info.cameras_size(); ++i) {
    const v1::SceneCamera& cam = info.cameras(i);
    absl::FPrintF(out, "  camera %d  %s (fov %.1f deg)\n", i,
                  cam.name().empty() ? "(unnamed)" : cam.name(), cam.yfov() * 180.0 / M_PI);
  }
  for (int i = 0; i < info.animations_size(); ++i) {
    const v1::AnimationInfo& a = info.animations(i);
    absl::FPrintF(out, "  animation %d  %s (%.2f s, %u channel%s; --animation %s --time S)\n", i,
                  a.name().empty() ? "(unnamed)" : a.name(), a.duration_s(), a.channels(),
                  a.channels() == 1 ? "" : "s", a.name().empty() ? absl::StrCat(i) : a.name());
  }
  for (const std::string& w : info.warnings()) absl::FPrintF(out, "  warning: %s\n", w);
}

void PrintFrameTimings(const v1::Frame& frame) {
  absl::PrintF("%-20s %10s%s\n", "pass", "gpu ms",
               frame.timing_source() == v1::TIMING_PASS_WALL_CLOCK
                   ? "   (CPU device: each pass submitted alone, timed by the wall clock)"
               : frame.timing_source() == v1::TIMING_FRAME_WALL_CLOCK
                   ? "   (CPU device, one submission: the passes as its timestamps say, the "
                     "total by the wall clock)"
                   : "");
  for (const v1::PassTiming& p : frame.passes())
    absl::PrintF("%-20s %10.3f\n", p.pass(), p.gpu_ms());
  absl::PrintF("%-20s %10.3f\n\n", "total", frame.gpu_total_ms());

  const v1::CpuTimings& cpu = frame.cpu();
  absl::PrintF("%-20s %10s\n", "cpu stage", "ms");
  const std::pair<const char*, double> stages[] = {
      {"queue wait", cpu.queue_wait_ms()}, {"record", cpu.record_ms()},
      {"submit->fence", cpu.gpu_ms()},     {"readback", cpu.readback_ms()},
      {"encode", cpu.encode_ms()},         {"total", cpu.total_ms()},
  };
  for (const auto& [name, ms] : stages) absl::PrintF("%-20s %10.3f\n", name, ms);

  const v1::FrameStats& st = frame.stats();
  absl::PrintF("\ndraws %u (%u indirect), triangles submitted %u, lights %u\n", st.draws(),
               st.indirect_draws(), st.triangles_submitted(), st.lights());
  absl::PrintF("drawables %u: %u in the frustum, %u drawn (%u culled)\n", st.drawables(),
               st.drawables_in_frustum(), st.drawables_drawn(), st.drawables_culled());
  if (st.animated_drawables() > 0)
    absl::PrintF("animated %u drawables, %u vertices skinned or morphed this frame\n",
                 st.animated_drawables(), st.deformed_vertices());
  if (st.pipeline_statistics())
    absl::PrintF("device counted %u primitives in, %u rasterized, %u fragment invocations\n",
                 st.primitives_in(), st.primitives_clipped(), st.fragment_invocations());
  for (const v1::SettingNote& n : frame.notes())
    absl::PrintF("note: %s: %s\n", n.field(), n.message());
}

Json FrameJson(const v1::Frame& frame) {
  Json j = ToJson(frame);
  j["bytes"] = frame.data().size();
  return j;
}

}  // namespace tessera::cli

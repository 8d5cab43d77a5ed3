// tessera render: one frame to a file (Render), with its per-pass timings.
#include <cerrno>
#include <cstdio>
#include <filesystem>
#include <string>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "clients/cli/cli_render_flags.h"

namespace tessera::cli {
namespace {

struct RenderOptions {
  std::string scene = "demo";
  std::string out = "tessera.jpg";
  v1::ImageEncoding encoding = v1::IMAGE_JPEG;
  double timeout_s = 600;
  RenderFlags flags;
};

RenderOptions ParseRenderOptions(const Invocation& inv) {
  RenderOptions o;
  ArgReader args(inv);
  while (args.Next()) {
    if (args.Is("--scene")) {
      o.scene = args.Value();
    } else if (args.Is("-o") || args.Is("--out")) {
      o.out = args.Value();
    } else if (args.Is("--timeout")) {
      o.timeout_s = args.Double();
    } else if (!o.flags.Parse(args)) {
      args.Unknown();
    }
  }
  o.flags.Finish(args);
  const std::string lower = absl::AsciiStrToLower(o.out);
  if (absl::EndsWith(lower, ".png")) {
    o.encoding = v1::IMAGE_PNG;
  } else if (!absl::EndsWith(lower, ".jpg") && !absl::EndsWith(lower, ".jpeg")) {
    args.Fail(absl::StrCat("-o ", o.out, ": the name must end in .jpg, .jpeg or .png"));
  }
  return o;
}

// The status names the file and the system's reason (its code from errno). The file's directory
// is made if missing (-o renders/shot.jpg).
absl::Status WriteFile(const std::string& path, const std::string& bytes) {
  if (const std::filesystem::path dir = std::filesystem::path(path).parent_path(); !dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(dir, ec);
    if (ec)
      return absl::Status(absl::StatusCode::kFailedPrecondition,
                          absl::StrCat(path, ": cannot create its directory: ", ec.message()));
  }
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return absl::ErrnoToStatus(errno, absl::StrCat(path, ": cannot create"));
  const bool ok = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  if (std::fclose(f) != 0 || !ok)
    return absl::ErrnoToStatus(errno, absl::StrCat(path, ": write failed"));
  return absl::OkStatus();
}

int RunRender(const Invocation& inv) {
  const RenderOptions o = ParseRenderOptions(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;

  v1::RenderRequest request;
  request.set_scene_id(o.scene);
  if (o.flags.has_placement() || o.flags.has_look_at() || o.flags.camera().has_yfov() ||
      o.flags.camera().has_znear() || o.flags.camera().has_zfar()) {
    *request.mutable_camera() = o.flags.camera();
  }
  *request.mutable_settings() = o.flags.settings();
  request.set_encoding(o.encoding);

  grpc::ClientContext context;
  SetDeadline(&context, o.timeout_s);
  v1::Frame frame;
  grpc::Status status = stub->Render(&context, request, &frame);
  if (!status.ok()) return ReportRpcError(inv, status);

  if (absl::Status st = WriteFile(o.out, frame.data()); !st.ok()) return ReportError(inv, st);

  if (inv.global.json) {
    PrintJson({{"output", o.out}, {"frame", FrameJson(frame)}});
    return 0;
  }
  absl::PrintF("scene    %s\n", frame.scene_id());
  absl::PrintF("camera   %s\n", CameraSummary(frame));
  absl::PrintF("settings %s\n", WrapList(SettingsSummary(frame.settings()), 9));
  absl::PrintF("output   %s (%ux%u %s, %s)\n\n", o.out, frame.width(), frame.height(),
               frame.encoding() == v1::IMAGE_PNG ? "png" : "jpeg", HumanBytes(frame.data().size()));
  PrintFrameTimings(frame);
  return 0;
}

}  // namespace

const Command kRenderCommand = {
    "render", "render one frame to a .jpg or .png file",
    R"(usage: tessera render [--scene ID] [camera flags] [settings flags] [-o FILE]
Renders one frame on the server (Render) and writes it to FILE; prints the camera, the
effective settings, the GPU time of every pass, the CPU stages and any setting notes.
--json: the output path and the Frame (without the image; its size as "bytes"); on failure
{"error": {"code", "message"}}.
  --scene ID          a scene id (or a unique prefix of 8+ characters) or "demo" (the default)
  -o, --out FILE      output image, .jpg/.jpeg (JPEG) or .png (PNG) (default: tessera.jpg)
  --timeout SEC       give up after SEC seconds (default 600)
)",
    /*render_flags=*/true, RunRender};

}  // namespace tessera::cli

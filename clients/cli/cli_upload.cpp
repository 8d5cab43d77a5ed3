// tessera upload: glTF files (with their buffers and images) to the server's scene store.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "clients/cli/cli_progress.h"
#include "renderer/scene/gltf_import.h"
#include "common/scene_id.h"

namespace tessera::cli {
namespace {

using Clock = std::chrono::steady_clock;

constexpr uint32_t kChunkBytes = 1u << 20;  // the proto's upper bound for one chunk

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// A glTF file set read from disk, hashed as the server will hash it.
struct LocalScene {
  GltfSource source;
  std::map<std::string, std::string> sha256;  // file name -> hex
  std::string scene_id;
  uint64_t total_bytes = 0;
};

absl::StatusOr<LocalScene> ReadLocalScene(const std::string& path) {
  absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
  if (!source.ok()) return source.status();
  LocalScene scene;
  scene.source = std::move(*source);
  for (const auto& [name, data] : scene.source.files) {
    scene.sha256[name] = Sha256Hex(data.data(), data.size());
    scene.total_bytes += data.size();
  }
  scene.scene_id = SceneId(scene.sha256, scene.source.main_file);
  return scene;
}

// What happened to one file on the command line.
struct UploadResult {
  std::string path;
  std::string scene_id;
  bool uploaded = false;  // false: the server had it already
  double seconds = 0;     // sending + server-side loading
  v1::SceneInfo info;
};

// Sends the manifest, then every file in chunks of at most `chunk_bytes`.
void SendFiles(grpc::ClientWriter<v1::UploadRequest>* writer, const LocalScene& scene,
               uint32_t chunk_bytes, ProgressBar* bar) {
  v1::UploadRequest request;
  v1::UploadManifest* manifest = request.mutable_manifest();
  manifest->set_main_file(scene.source.main_file);
  for (const auto& [name, data] : scene.source.files) {
    v1::UploadFile* f = manifest->add_files();
    f->set_name(name);
    f->set_size(data.size());
    f->set_sha256(scene.sha256.at(name));
  }
  // A failed write means the server ended the call early; Finish() says why.
  if (!writer->Write(request)) return;

  uint64_t sent = 0;
  uint32_t file_index = 0;
  for (const auto& [name, data] : scene.source.files) {
    for (size_t offset = 0; offset < data.size(); offset += chunk_bytes) {
      const size_t n = std::min<size_t>(chunk_bytes, data.size() - offset);
      v1::UploadRequest chunk_request;
      v1::UploadChunk* chunk = chunk_request.mutable_chunk();
      chunk->set_file_index(file_index);
      chunk->set_offset(offset);
      chunk->set_data(data.data() + offset, n);
      if (!writer->Write(chunk_request)) return;
      sent += n;
      bar->Update(sent);
    }
    ++file_index;
  }
  bar->Update(sent, /*force=*/true);
}

grpc::Status Upload(v1::RenderService::Stub* stub, const LocalScene& scene,
                    const std::string& label, uint32_t chunk_bytes, v1::SceneInfo* info) {
  ProgressBar bar(std::filesystem::path(label).filename().string(), scene.total_bytes,
                  ProgressBar::Unit::kBytes);
  // No deadline: a large upload on a slow link takes as long as it takes (Ctrl-C stops it).
  grpc::ClientContext context;
  std::unique_ptr<grpc::ClientWriter<v1::UploadRequest>> writer = stub->UploadScene(&context, info);
  SendFiles(writer.get(), scene, chunk_bytes, &bar);
  writer->WritesDone();
  bar.Say("sent; the server is loading the scene...");
  return writer->Finish();
}

// The server's message about the file at `path`, named by that path once: the server names the
// main file in its import errors ("Box.gltf: meshes[0]..."), which becomes "dir/Box.gltf:
// meshes[0]...".
std::string NamedByPath(const std::string& path, const std::string& message) {
  const std::string name = std::filesystem::path(path).filename().string() + ": ";
  const bool named = message.compare(0, name.size(), name) == 0;
  return absl::StrCat(path, ": ", named ? message.substr(name.size()) : message);
}

// The server's limits as they apply to this upload: the chunk size, or an error naming the
// limit before any byte is sent.
grpc::Status CheckLimits(const v1::Limits& limits, const LocalScene& scene, uint32_t* chunk_bytes) {
  *chunk_bytes = kChunkBytes;
  if (limits.max_chunk_bytes() > 0) *chunk_bytes = std::min(kChunkBytes, limits.max_chunk_bytes());
  if (limits.max_upload_files() > 0 && scene.source.files.size() > limits.max_upload_files()) {
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        absl::StrCat(scene.source.files.size(), " files; the server takes at most ",
                                     limits.max_upload_files(), " (max_upload_files)"));
  }
  if (limits.max_upload_bytes() > 0 && scene.total_bytes > limits.max_upload_bytes()) {
    return grpc::Status(grpc::StatusCode::RESOURCE_EXHAUSTED,
                        absl::StrCat(scene.total_bytes, " bytes; the server takes at most ",
                                     limits.max_upload_bytes(), " (max_upload_bytes)"));
  }
  return grpc::Status::OK;
}

class Uploader {
 public:
  Uploader(const Invocation& inv, v1::RenderService::Stub* stub) : inv_(inv), stub_(stub) {}

  // Uploads one file set unless the server has it. Errors are reported on stderr (and in
  // `error` for --json); returns false then.
  bool Run(const std::string& path, UploadResult* result, Json* error) {
    result->path = path;
    absl::StatusOr<LocalScene> scene = ReadLocalScene(path);
    if (!scene.ok()) {
      *error = ErrorJson(absl::StatusCodeToString(scene.status().code()), scene.status().message());
      ReportError(inv_, scene.status());
      return false;
    }
    result->scene_id = scene->scene_id;
    std::string resolved;
    bool present = false;
    grpc::Status status =
        ResolveSceneId(stub_, scene->scene_id, &resolved, &result->info, &present);
    if (status.ok() && present) return true;  // the server has it: nothing to send

    uint32_t chunk_bytes = 0;
    if (status.ok()) status = FetchLimits();
    if (status.ok()) status = CheckLimits(limits_, *scene, &chunk_bytes);
    if (status.ok()) {
      const Clock::time_point start = Clock::now();
      status = Upload(stub_, *scene, path, chunk_bytes, &result->info);
      result->seconds = SecondsSince(start);
      result->uploaded = true;
    }
    if (!status.ok()) {
      const grpc::Status named(status.error_code(), NamedByPath(path, status.error_message()));
      *error = ErrorJson(named);
      ReportRpcError(inv_, named);
      return false;
    }
    if (result->info.scene_id() != scene->scene_id) {
      // Should never happen: both sides hash per scene_id.h. Trust the server's id.
      std::fprintf(stderr, "tessera: upload: %s: server id %s differs from the local id %s\n",
                   path.c_str(), result->info.scene_id().c_str(), scene->scene_id.c_str());
      result->scene_id = result->info.scene_id();
    }
    return true;
  }

 private:
  grpc::Status FetchLimits() {
    if (have_limits_) return grpc::Status::OK;
    grpc::ClientContext context;
    SetDeadline(&context, kShortCallSeconds);
    v1::ServerInfo info;
    grpc::Status status = stub_->GetServerInfo(&context, v1::GetServerInfoRequest(), &info);
    if (!status.ok()) return status;
    limits_ = info.limits();
    have_limits_ = true;
    return status;
  }

  const Invocation& inv_;
  v1::RenderService::Stub* stub_;
  bool have_limits_ = false;
  v1::Limits limits_;
};

void PrintResult(const UploadResult& r) {
  if (r.uploaded) {
    const double mib = r.info.upload_bytes() / (1024.0 * 1024.0);
    absl::FPrintF(stderr, "%s: uploaded %s in %.2f s (%.1f MiB/s, incl. loading)\n", r.path,
                  HumanBytes(r.info.upload_bytes()), r.seconds,
                  r.seconds > 0 ? mib / r.seconds : 0.0);
  } else {
    absl::FPrintF(stderr, "%s: already on the server\n", r.path);
  }
  PrintSceneInfo(stderr, r.info);
  // The id alone on stdout: `id=$(tessera upload scene.glb)` captures exactly it.
  absl::PrintF("%s\n", r.scene_id);
  std::fflush(stdout);
}

Json ResultJson(const UploadResult& r) {
  return {{"file", r.path},
          {"scene_id", r.scene_id},
          {"uploaded", r.uploaded},
          {"seconds", r.seconds},
          {"info", ToJson(r.info)}};
}

}  // namespace

bool UploadSceneFile(const Invocation& inv, v1::RenderService::Stub* stub,
                     const std::string& path, std::string* scene_id) {
  Uploader uploader(inv, stub);
  UploadResult result;
  Json error;
  if (!uploader.Run(path, &result, &error)) return false;
  *scene_id = result.scene_id;
  return true;
}

namespace {

int RunUpload(const Invocation& inv) {
  std::vector<std::string> paths;
  ArgReader args(inv);
  while (args.Next()) {
    if (!args.IsPositional()) args.Unknown();
    paths.push_back(args.current());
  }
  if (paths.empty()) args.Fail("which files? give one or more .gltf or .glb files");
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;

  Uploader uploader(inv, stub.get());
  Json out = Json::array();
  int rc = 0;
  // Every file is tried, so one bad file does not hide what happened to the others.
  for (const std::string& path : paths) {
    UploadResult result;
    Json error;
    if (!uploader.Run(path, &result, &error)) {
      rc = kExitError;
      if (inv.global.json) out.push_back({{"file", path}, {"error", error}});
      continue;
    }
    if (inv.global.json) {
      out.push_back(ResultJson(result));
    } else {
      PrintResult(result);
    }
  }
  if (inv.global.json) PrintJson(out);
  return rc;
}

}  // namespace

const Command kUploadCommand = {"upload", "upload .gltf/.glb scenes (skipped when already there)",
                                R"(usage: tessera upload FILE...
Uploads each FILE (a .glb, or a .gltf with the .bin and image files it names; a directory
means the one .gltf or .glb in it) to the server.
The scene id is the content hash, computed locally first: a scene the server already has is
not sent again. A progress bar shows on stderr when it is a terminal.

Output: the details of each scene on stderr, and its id alone on stdout, one line per FILE,
so `id=$(tessera upload scene.glb)` captures it. Every FILE is tried; the exit status is 1
if any of them failed. --json: a JSON array with one object per FILE (file, scene_id,
uploaded, seconds, info: the SceneInfo; or file and error: {"code", "message"}).
)",
                                false, RunUpload};

}  // namespace tessera::cli

#pragma once
// What the streaming benchmarks (tessera-stream-bench, tessera-viewers-bench) share: the camera
// orbit their clients move along, how a --scenes key becomes a glTF file set and its scene id,
// and the upload of that file set through UploadScene.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <glm/glm.hpp>
#include <map>
#include <memory>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "renderer/camera.h"
#include "renderer/scene/gltf_import.h"
#include "common/scene_id.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::bench {

using Clock = std::chrono::steady_clock;

inline constexpr uint32_t kChunkBytes = 1u << 20;  // the proto's (and the server's default) limit
inline constexpr float kOrbitStepRadians = 0.02f;  // camera movement per event
// When a client finds the server with nothing left to render for it, it sends two events; the
// second waits this long so the server has taken the first (two events that arrive together
// are merged into one frame: latest wins).
inline constexpr auto kRestartGap = std::chrono::milliseconds(1);

inline double MsBetween(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

// Cameras on a circle around the scene centre, at the distance, height and near plane of the
// server's default framing; `phase` puts a client elsewhere on it.
struct Orbit {
  glm::vec3 center{0.0f};
  glm::vec3 offset{0.0f, 0.0f, 5.0f};  // eye - center at step 0
  float znear = 0.05f;
  uint64_t phase = 0;  // steps

  v1::Camera At(uint64_t step) const {
    const float a = kOrbitStepRadians * static_cast<float>((step + phase) % 100000);
    const glm::vec3 o(offset.x * std::cos(a) + offset.z * std::sin(a), offset.y,
                      -offset.x * std::sin(a) + offset.z * std::cos(a));
    v1::Camera c;
    v1::LookAt* l = c.mutable_look_at();
    l->mutable_eye()->set_x(center.x + o.x);
    l->mutable_eye()->set_y(center.y + o.y);
    l->mutable_eye()->set_z(center.z + o.z);
    l->mutable_target()->set_x(center.x);
    l->mutable_target()->set_y(center.y);
    l->mutable_target()->set_z(center.z);
    c.set_znear(znear);
    return c;
  }
};

inline Orbit MakeOrbit(const Aabb& bounds, float aspect) {
  const Camera framed = FrameBounds(bounds, Camera{}.yfov, aspect);
  Orbit orbit;
  orbit.center = framed.target;
  orbit.offset = framed.eye - framed.target;
  orbit.znear = framed.znear;
  return orbit;
}

// The same from the bounds the server reports (SceneInfo.bounds).
inline Orbit MakeOrbit(const v1::Aabb& bounds, float aspect) {
  Aabb box;
  box.min = glm::vec3(bounds.min().x(), bounds.min().y(), bounds.min().z());
  box.max = glm::vec3(bounds.max().x(), bounds.max().y(), bounds.max().z());
  return MakeOrbit(box, aspect);
}

// tests/CMakeLists.txt defines this for every test program; the fallback (the assets next to
// the repository, as the top-level CMakeLists.txt has them) keeps a stand-alone compile working.
#ifndef TESSERA_DEFAULT_ASSETS_DIR
#define TESSERA_DEFAULT_ASSETS_DIR "../shared/assets"
#endif

// The assets folder: TESSERA_ASSETS_DIR, else the build's default.
inline std::string AssetsDir() {
  if (const char* env = std::getenv("TESSERA_ASSETS_DIR"); env && *env) return env;
  return TESSERA_DEFAULT_ASSETS_DIR;
}

// Whether `flag` is among the arguments.
inline bool HasFlag(int argc, char** argv, const std::string& flag) {
  for (int i = 1; i < argc; ++i)
    if (flag == argv[i]) return true;
  return false;
}

// The file set a --scenes key other than "demo" names: "sponza" (in `assets`) or a .gltf/.glb
// path. Errors name the key or the file.
inline absl::StatusOr<GltfSource> ReadSceneFiles(const std::string& key,
                                                 const std::string& assets) {
  std::string path;
  if (key == "sponza")
    path = assets + "/Sponza/glTF/Sponza.gltf";
  else if (absl::EndsWithIgnoreCase(key, ".gltf") || absl::EndsWithIgnoreCase(key, ".glb"))
    path = key;
  else
    return absl::InvalidArgumentError(
        absl::StrCat("unknown scene \"", key, "\" (demo, sponza, or a path to a .gltf/.glb)"));
  absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
  if (!source.ok())
    return absl::Status(source.status().code(),
                        path + ": " + std::string(source.status().message()));
  return source;
}

// The scene id the server must answer for an upload of `src`.
inline std::string LocalSceneId(const GltfSource& src) {
  std::map<std::string, std::string> sha256;
  for (const auto& [name, data] : src.files) sha256[name] = Sha256Hex(data.data(), data.size());
  return SceneId(sha256, src.main_file);
}

// Uploads `src` through UploadScene (manifest with checksums, then kChunkBytes chunks) within
// ten minutes; `info` is what the server answered.
inline grpc::Status UploadFileSet(v1::RenderService::Stub* stub, const GltfSource& src,
                                  v1::SceneInfo* info) {
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::minutes(10));
  std::unique_ptr<grpc::ClientWriter<v1::UploadRequest>> writer = stub->UploadScene(&ctx, info);
  v1::UploadRequest request;
  v1::UploadManifest* manifest = request.mutable_manifest();
  manifest->set_main_file(src.main_file);
  for (const auto& [name, data] : src.files) {
    v1::UploadFile* f = manifest->add_files();
    f->set_name(name);
    f->set_size(data.size());
    f->set_sha256(Sha256Hex(data.data(), data.size()));
  }
  bool ok = writer->Write(request);
  uint32_t file_index = 0;
  for (const auto& [name, data] : src.files) {
    for (size_t offset = 0; ok && offset < data.size(); offset += kChunkBytes) {
      const size_t n = std::min<size_t>(kChunkBytes, data.size() - offset);
      v1::UploadRequest chunk_request;
      v1::UploadChunk* chunk = chunk_request.mutable_chunk();
      chunk->set_file_index(file_index);
      chunk->set_offset(offset);
      chunk->set_data(data.data() + offset, n);
      ok = writer->Write(chunk_request);
    }
    ++file_index;
  }
  if (ok) writer->WritesDone();
  return writer->Finish();
}

}  // namespace tessera::bench

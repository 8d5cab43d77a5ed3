// tessera-import-check FILE...: imports each glTF/GLB file (LoadGltfSourceFromDisk + ImportGltf,
// the same path as tessera-render and an upload's files) and prints one JSON line per file:
//   {"file": F, "ok": true, "triangles": N}  or  {"file": F, "ok": false, "code": C, "message": M}
// For tests/gltf/agreement.mjs, which compares these with the Khronos glTF-Validator's reports.
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>

#include "absl/status/status.h"
#include "renderer/scene/gltf_import.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: tessera-import-check FILE...\n");
    return 2;
  }
  for (int i = 1; i < argc; ++i) {
    nlohmann::json line = {{"file", argv[i]}};
    absl::StatusOr<tessera::GltfSource> src = tessera::LoadGltfSourceFromDisk(argv[i]);
    absl::StatusOr<tessera::CpuScene> scene =
        src.ok() ? tessera::ImportGltf(*src) : absl::StatusOr<tessera::CpuScene>(src.status());
    line["ok"] = scene.ok();
    if (scene.ok()) {
      line["triangles"] = scene->indices.size() / 3;
    } else {
      line["code"] = std::string(absl::StatusCodeToString(scene.status().code()));
      line["message"] = std::string(scene.status().message());
    }
    std::printf("%s\n", line.dump().c_str());
  }
  return 0;
}

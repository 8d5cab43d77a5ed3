#pragma once
// The scene a renderer benchmark runs on: a glTF file from disk, or the built-in demo scene when
// the path is empty. Exits through Fail() with the importer's message on error.
#include <string>

#include "bench_util.h"
#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"

namespace tessera::bench {

inline SceneHandle LoadSceneOrDemo(Renderer& renderer, const std::string& path) {
  absl::StatusOr<SceneHandle> scene;
  if (path.empty()) {
    scene = renderer.LoadScene(BuildDemoScene());
  } else {
    absl::StatusOr<GltfSource> source = LoadGltfSourceFromDisk(path);
    if (!source.ok()) Fail(std::string(source.status().message()));
    scene = renderer.LoadScene(*source);
  }
  if (!scene.ok()) Fail(std::string(scene.status().message()));
  return *scene;
}

}  // namespace tessera::bench

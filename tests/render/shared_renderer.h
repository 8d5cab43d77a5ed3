#pragma once
// One Vulkan device (with validation) and one uploaded demo scene per test binary: creating the
// device is the slow part on lavapipe.
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>

#include "renderer/renderer.h"
#include "renderer/scene/demo_scene.h"

namespace tessera {

inline Renderer& SharedRenderer() {
  static std::unique_ptr<Renderer> renderer = [] {
    absl::StatusOr<std::unique_ptr<Renderer>> r = Renderer::Create({.validation = true});
    if (!r.ok()) {
      ADD_FAILURE() << "no Vulkan device: " << r.status();
      std::abort();
    }
    return std::move(*r);
  }();
  return *renderer;
}

inline const SceneHandle& SharedDemoScene() {
  static SceneHandle scene = [] {
    absl::StatusOr<SceneHandle> s = SharedRenderer().LoadScene(BuildDemoScene());
    if (!s.ok()) {
      ADD_FAILURE() << "demo scene: " << s.status();
      std::abort();
    }
    return *s;
  }();
  return scene;
}

}  // namespace tessera

#pragma once
// One Vulkan device (with validation) and one uploaded demo scene per test binary: creating the
// device is the slow part on lavapipe.
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <string_view>

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

// vis_mlaa and the visibility pipeline need the visibility buffer (DeviceInfo::visibility_buffer:
// standard sample locations, and gl_PrimitiveID or pulled vertices); a device without it renders
// those requests as msaa and forward, with a note (the settings and fallback tests check that).
// Tests of the visibility paths themselves skip.
#define TESSERA_SKIP_WITHOUT_VISIBILITY_BUFFER(renderer)                             \
  if (!(renderer).device_info().visibility_buffer)                                  \
  GTEST_SKIP() << (renderer).device_info().name << " cannot draw the visibility buffer"

// Whether the frame's settings carry a note on `field` (a request the device changed).
inline bool HasNote(const Frame& f, std::string_view field) {
  for (const SettingNote& n : f.settings.notes)
    if (n.field == field) return true;
  return false;
}

// Whether the device lists a fallback whose missing feature starts with `missing`.
inline bool HasFallback(const DeviceInfo& info, std::string_view missing) {
  for (const DeviceFallback& f : info.fallbacks)
    if (std::string_view(f.missing).substr(0, missing.size()) == missing) return true;
  return false;
}

// Every validation message a renderer's device reported, as test failures.
inline void ExpectNoValidationMessages(const Renderer& r) {
  EXPECT_EQ(r.validation_message_count(), 0u);
  for (const std::string& m : r.validation_messages()) ADD_FAILURE() << "validation: " << m;
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

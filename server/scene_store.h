#pragma once
// Content-addressed scenes on the device, shared by every request and session that names them.
// A deleted scene leaves the index at once (new requests get NOT_FOUND) and is freed when the
// last session holding it ends. Thread-safe.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/renderer.h"
#include "tessera/v1/scene.pb.h"

namespace tessera::server {

inline constexpr char kDemoSceneId[] = "demo";

struct StoredScene {
  std::string id;
  SceneHandle scene;
  v1::SceneInfo info;  // sessions/deleted are filled in when listed
  std::atomic<uint32_t> sessions{0};
  std::atomic<bool> deleted{false};
};

// Held by a streaming session: counts it as a user of the scene for as long as it lives.
class SceneLease {
 public:
  explicit SceneLease(std::shared_ptr<StoredScene> s) : scene_(std::move(s)) { ++scene_->sessions; }
  ~SceneLease() { --scene_->sessions; }
  SceneLease(const SceneLease&) = delete;
  SceneLease& operator=(const SceneLease&) = delete;
  const StoredScene& get() const { return *scene_; }

 private:
  std::shared_ptr<StoredScene> scene_;
};

class SceneStore {
 public:
  explicit SceneStore(uint32_t max_scenes) : max_scenes_(max_scenes) {}

  // The built-in scene (not counted against max_scenes, cannot be deleted).
  void AddDemo(SceneHandle scene, v1::SceneInfo info);

  // OK when another uploaded scene fits: RESOURCE_EXHAUSTED naming max_scenes otherwise.
  // Checked before an upload is parsed; Add checks again.
  absl::Status CheckRoom() const;

  // Inserts a scene, or returns the one already stored under `id` (same content).
  absl::StatusOr<std::shared_ptr<StoredScene>> Add(const std::string& id, SceneHandle scene,
                                                   v1::SceneInfo info);

  // By full id or a unique prefix of at least 8 characters. NOT_FOUND naming the id.
  absl::StatusOr<std::shared_ptr<StoredScene>> Find(const std::string& id_or_prefix) const;
  std::shared_ptr<StoredScene> FindExact(const std::string& id) const;

  // Demo first, then in load order; sessions and deleted filled in.
  std::vector<v1::SceneInfo> List() const;

  // Returns how many sessions still use it. NOT_FOUND, or FAILED_PRECONDITION for the demo.
  absl::StatusOr<uint32_t> Delete(const std::string& id_or_prefix);

  // Scenes in memory: indexed ones plus deleted ones still held by sessions.
  uint32_t count() const;

  static void FillLiveFields(const StoredScene& s, v1::SceneInfo* out);

 private:
  size_t UploadedLocked() const;  // indexed + deleted-but-in-use uploaded scenes
  const uint32_t max_scenes_;
  mutable std::mutex mu_;
  std::shared_ptr<StoredScene> demo_;
  std::map<std::string, std::shared_ptr<StoredScene>> scenes_;  // uploaded, by id
  std::vector<std::string> order_;                              // load order of scenes_
  mutable std::vector<std::weak_ptr<StoredScene>> deleted_;     // until their sessions end
};

}  // namespace tessera::server

#pragma once
// Content-addressed scenes on the device, shared by every request and session that names them.
// A deleted scene leaves the index at once (new requests get NOT_FOUND) and is freed when the
// last session holding it ends. Thread-safe.
//
// Two limits bound the uploaded scenes: a count (max_scenes) and the device memory they hold
// (memory_budget, 0 = unlimited). When a new scene would exceed either, scenes no session
// uses are evicted, least recently used first (a later request for one gets NOT_FOUND, and a
// client re-uploads it: HasScene tells). Only when that is not enough is the upload refused.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/renderer.h"

namespace tessera::server {

// The shortest id prefix that names a scene or a job (ids are 64 and 16 hex digits; `tessera
// scenes` and `job list` show them shortened).
inline constexpr size_t kMinIdPrefix = 8;

inline constexpr char kDemoSceneId[] = "demo";

// What the store keeps of a scene beside its handle; handlers make the wire's SceneInfo of it.
struct StoredSceneInfo {
  SceneInfo scene;            // the renderer's; its name is the main file's (or "demo")
  uint64_t upload_bytes = 0;  // bytes of the uploaded files
  double load_ms = 0.0;       // import + device upload time when it was loaded
};

struct StoredScene {
  std::string id;
  SceneHandle scene;
  StoredSceneInfo info;
  std::atomic<uint32_t> sessions{0};
  std::atomic<bool> deleted{false};
  mutable std::atomic<int64_t> last_used{0};  // steady-clock ticks of the last Find
  uint64_t device_bytes = 0;
};

// A scene as listed: what the store keeps of it, and its users at that moment.
struct SceneListing {
  std::string id;
  StoredSceneInfo info;
  uint32_t sessions = 0;  // streaming sessions using it
  bool deleted = false;   // deleted, kept until the sessions using it end
};

// Held by a streaming session: counts it as a user of the scene for as long as it lives.
class SceneLease {
 public:
  explicit SceneLease(std::shared_ptr<StoredScene> s) : scene_(std::move(s)) { ++scene_->sessions; }
  ~SceneLease() {
    // A scene watched until now counts as just used (LRU eviction).
    scene_->last_used = std::chrono::steady_clock::now().time_since_epoch().count();
    --scene_->sessions;
  }
  SceneLease(const SceneLease&) = delete;
  SceneLease& operator=(const SceneLease&) = delete;
  const StoredScene& get() const { return *scene_; }

 private:
  std::shared_ptr<StoredScene> scene_;
};

class SceneStore {
 public:
  explicit SceneStore(uint32_t max_scenes, uint64_t memory_budget = 0)
      : max_scenes_(max_scenes), memory_budget_(memory_budget) {}

  // Called (under the store's lock: keep it short) for every scene evicted to make room.
  void set_eviction_listener(std::function<void(const StoredScene&)> f) { on_evict_ = std::move(f); }

  // The built-in scene (not counted against max_scenes, cannot be deleted).
  void AddDemo(SceneHandle scene, StoredSceneInfo info);

  // OK when another uploaded scene fits, counting scenes that could be evicted as room:
  // RESOURCE_EXHAUSTED naming max_scenes otherwise. Checked before an upload is parsed; Add
  // checks again (and checks the memory budget, which needs the scene's size).
  absl::Status CheckRoom() const;

  // Inserts a scene, evicting unused ones if needed, or returns the one already stored under
  // `id` (same content). RESOURCE_EXHAUSTED naming the limit when it cannot make room.
  absl::StatusOr<std::shared_ptr<StoredScene>> Add(const std::string& id, SceneHandle scene,
                                                   StoredSceneInfo info);

  // By full id or a unique prefix of at least 8 characters. NOT_FOUND naming the id.
  absl::StatusOr<std::shared_ptr<StoredScene>> Find(const std::string& id_or_prefix) const;
  std::shared_ptr<StoredScene> FindExact(const std::string& id) const;

  // Demo first, then in load order, then deleted scenes still in use.
  std::vector<SceneListing> List() const;

  // Returns how many sessions still use it. NOT_FOUND, or FAILED_PRECONDITION for the demo.
  absl::StatusOr<uint32_t> Delete(const std::string& id_or_prefix);

  // Scenes in memory: indexed ones plus deleted ones still held by sessions.
  uint32_t count() const;
  // Device memory of the scenes in memory (the demo included).
  uint64_t device_bytes() const;
  uint64_t memory_budget() const { return memory_budget_; }
  uint64_t evictions() const { return evictions_; }

  // `s` as listed now (its sessions and whether it is deleted).
  static SceneListing Describe(const StoredScene& s);

 private:
  size_t UploadedLocked() const;  // indexed + deleted-but-in-use uploaded scenes
  uint64_t UploadedBytesLocked() const;
  // Evicts the least recently used scene no session holds; false when there is none.
  bool EvictOneLocked();
  const uint32_t max_scenes_;
  const uint64_t memory_budget_;
  std::function<void(const StoredScene&)> on_evict_;
  uint64_t evictions_ = 0;
  mutable std::mutex mu_;
  std::shared_ptr<StoredScene> demo_;
  std::map<std::string, std::shared_ptr<StoredScene>> scenes_;  // uploaded, by id
  std::vector<std::string> order_;                              // load order of scenes_
  mutable std::vector<std::weak_ptr<StoredScene>> deleted_;     // until their sessions end
};

}  // namespace tessera::server

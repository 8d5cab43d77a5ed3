#include "server/scene_store.h"

#include <algorithm>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"

namespace tessera::server {
namespace {

void Touch(const StoredScene& s) {
  s.last_used = std::chrono::steady_clock::now().time_since_epoch().count();
}

// Nobody but the store holds it: no session (leases), no handler between Find and its lease,
// no queued Render (which holds the scene handle).
bool Evictable(const std::shared_ptr<StoredScene>& s) {
  return s->sessions.load() == 0 && s.use_count() == 1 && s->scene.use_count() <= 1;
}

}  // namespace

void SceneStore::AddDemo(SceneHandle scene, StoredSceneInfo info) {
  auto s = std::make_shared<StoredScene>();
  s->device_bytes = info.scene.device_bytes;
  s->id = kDemoSceneId;
  s->scene = std::move(scene);
  s->info = std::move(info);
  std::lock_guard lock(mu_);
  demo_ = std::move(s);
}

size_t SceneStore::UploadedLocked() const {
  std::erase_if(deleted_, [](const auto& w) { return w.expired(); });
  return scenes_.size() + deleted_.size();  // deleted scenes in use still hold device memory
}

uint64_t SceneStore::UploadedBytesLocked() const {
  uint64_t bytes = 0;
  for (const auto& [id, s] : scenes_) bytes += s->device_bytes;
  for (const auto& w : deleted_)
    if (auto s = w.lock()) bytes += s->device_bytes;
  return bytes;
}

bool SceneStore::EvictOneLocked() {
  auto victim = scenes_.end();
  for (auto it = scenes_.begin(); it != scenes_.end(); ++it)
    if (Evictable(it->second) &&
        (victim == scenes_.end() || it->second->last_used < victim->second->last_used))
      victim = it;
  if (victim == scenes_.end()) return false;
  if (on_evict_) on_evict_(*victim->second);
  order_.erase(std::remove(order_.begin(), order_.end(), victim->first), order_.end());
  scenes_.erase(victim);  // freed now unless a queued Render still holds its handle
  ++evictions_;
  return true;
}

absl::Status SceneStore::CheckRoom() const {
  std::lock_guard lock(mu_);
  // Lenient on purpose: a scene only briefly held (a request between Find and its lease) will
  // be evictable by the time this upload is parsed; Add decides for real.
  const bool any_evictable = std::any_of(scenes_.begin(), scenes_.end(),
                                         [](const auto& kv) { return kv.second->sessions == 0; });
  if (UploadedLocked() >= max_scenes_ && !any_evictable)
    return absl::ResourceExhaustedError(absl::StrCat(
        "scenes: ", UploadedLocked(), " uploaded scenes in memory reach the max_scenes limit (",
        max_scenes_, "); delete one with DeleteScene"));
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<StoredScene>> SceneStore::Add(const std::string& id,
                                                             SceneHandle scene,
                                                             StoredSceneInfo info) {
  std::lock_guard lock(mu_);
  if (auto it = scenes_.find(id); it != scenes_.end()) {
    Touch(*it->second);
    return it->second;  // same content
  }
  const uint64_t bytes = info.scene.device_bytes;
  if (memory_budget_ != 0 && bytes > memory_budget_)
    return absl::ResourceExhaustedError(absl::StrCat(
        "scene_memory_budget: the scene needs ", bytes, " bytes of device memory, more than the "
        "whole budget (", memory_budget_, " bytes)"));
  while (UploadedLocked() >= max_scenes_ ||
         (memory_budget_ != 0 && UploadedBytesLocked() + bytes > memory_budget_)) {
    if (EvictOneLocked()) continue;
    if (UploadedLocked() >= max_scenes_)
      return absl::ResourceExhaustedError(absl::StrCat(
          "scenes: ", UploadedLocked(), " uploaded scenes in memory reach the max_scenes limit (",
          max_scenes_, ") and all are in use by sessions; delete one with DeleteScene"));
    return absl::ResourceExhaustedError(absl::StrCat(
        "scene_memory_budget: ", UploadedBytesLocked(), " bytes held by scenes in use + ", bytes,
        " for this one exceed the budget (", memory_budget_, " bytes)"));
  }
  auto s = std::make_shared<StoredScene>();
  s->device_bytes = bytes;
  Touch(*s);
  s->id = id;
  s->scene = std::move(scene);
  s->info = std::move(info);
  scenes_.emplace(id, s);
  order_.push_back(id);
  return s;
}

std::shared_ptr<StoredScene> SceneStore::FindExact(const std::string& id) const {
  std::lock_guard lock(mu_);
  if (id == kDemoSceneId) return demo_;
  auto it = scenes_.find(id);
  if (it == scenes_.end()) return nullptr;
  Touch(*it->second);
  return it->second;
}

absl::StatusOr<std::shared_ptr<StoredScene>> SceneStore::Find(const std::string& id) const {
  if (id.empty()) return absl::InvalidArgumentError("scene_id: is empty");
  if (auto s = FindExact(id)) return s;
  std::lock_guard lock(mu_);
  if (id.size() >= kMinIdPrefix) {
    // A unique prefix, as people copy ids from `tessera scenes`.
    auto it = scenes_.lower_bound(id);
    if (it != scenes_.end() && absl::StartsWith(it->first, id)) {
      auto next = std::next(it);
      if (next == scenes_.end() || !absl::StartsWith(next->first, id)) {
        Touch(*it->second);
        return it->second;
      }
      return absl::InvalidArgumentError(
          absl::StrCat("scene_id: prefix \"", id, "\" matches more than one scene"));
    }
  }
  return absl::NotFoundError(absl::StrCat(
      "scene_id: no scene \"", id.substr(0, 80), "\"",
      id.size() < kMinIdPrefix ? absl::StrCat(" (a prefix needs at least ", kMinIdPrefix,
                                              " characters; ListScenes shows the ids)")
                               : " (ListScenes shows what is loaded)"));
}

SceneListing SceneStore::Describe(const StoredScene& s) {
  return SceneListing{s.id, s.info, s.sessions.load(), s.deleted.load()};
}

std::vector<SceneListing> SceneStore::List() const {
  std::lock_guard lock(mu_);
  std::vector<SceneListing> out;
  auto add = [&out](const StoredScene& s) { out.push_back(Describe(s)); };
  if (demo_) add(*demo_);
  for (const std::string& id : order_) add(*scenes_.at(id));
  for (const auto& w : deleted_)
    if (auto s = w.lock()) add(*s);
  return out;
}

absl::StatusOr<uint32_t> SceneStore::Delete(const std::string& id) {
  ASSIGN_OR_RETURN(std::shared_ptr<StoredScene> s, Find(id));
  if (s->id == kDemoSceneId)
    return absl::FailedPreconditionError("scene_id: the built-in \"demo\" scene cannot be deleted");
  std::lock_guard lock(mu_);
  if (scenes_.erase(s->id) == 0)  // deleted concurrently
    return absl::NotFoundError(absl::StrCat("scene_id: no scene \"", id, "\""));
  order_.erase(std::remove(order_.begin(), order_.end(), s->id), order_.end());
  s->deleted = true;
  std::erase_if(deleted_, [](const auto& w) { return w.expired(); });
  deleted_.push_back(s);
  return s->sessions.load();
}

uint64_t SceneStore::device_bytes() const {
  std::lock_guard lock(mu_);
  return UploadedBytesLocked() + (demo_ ? demo_->device_bytes : 0);
}

uint32_t SceneStore::count() const {
  std::lock_guard lock(mu_);
  std::erase_if(deleted_, [](const auto& w) { return w.expired(); });
  return static_cast<uint32_t>(scenes_.size() + deleted_.size() + (demo_ ? 1 : 0));
}

}  // namespace tessera::server

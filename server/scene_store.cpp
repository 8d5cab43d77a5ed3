#include "server/scene_store.h"

#include <algorithm>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"

namespace tessera::server {

void SceneStore::AddDemo(SceneHandle scene, v1::SceneInfo info) {
  auto s = std::make_shared<StoredScene>();
  s->id = kDemoSceneId;
  s->scene = std::move(scene);
  info.set_scene_id(kDemoSceneId);
  s->info = std::move(info);
  std::lock_guard lock(mu_);
  demo_ = std::move(s);
}

size_t SceneStore::UploadedLocked() const {
  std::erase_if(deleted_, [](const auto& w) { return w.expired(); });
  return scenes_.size() + deleted_.size();  // deleted scenes in use still hold device memory
}

absl::Status SceneStore::CheckRoom() const {
  std::lock_guard lock(mu_);
  if (UploadedLocked() >= max_scenes_)
    return absl::ResourceExhaustedError(absl::StrCat(
        "scenes: ", UploadedLocked(), " uploaded scenes in memory reach the max_scenes limit (",
        max_scenes_, "); delete one with DeleteScene"));
  return absl::OkStatus();
}

absl::StatusOr<std::shared_ptr<StoredScene>> SceneStore::Add(const std::string& id,
                                                             SceneHandle scene,
                                                             v1::SceneInfo info) {
  std::lock_guard lock(mu_);
  if (auto it = scenes_.find(id); it != scenes_.end()) return it->second;  // same content
  if (UploadedLocked() >= max_scenes_)
    return absl::ResourceExhaustedError(absl::StrCat(
        "scenes: ", UploadedLocked(), " uploaded scenes in memory reach the max_scenes limit (",
        max_scenes_, "); delete one with DeleteScene"));
  auto s = std::make_shared<StoredScene>();
  s->id = id;
  s->scene = std::move(scene);
  info.set_scene_id(id);
  s->info = std::move(info);
  scenes_.emplace(id, s);
  order_.push_back(id);
  return s;
}

std::shared_ptr<StoredScene> SceneStore::FindExact(const std::string& id) const {
  std::lock_guard lock(mu_);
  if (id == kDemoSceneId) return demo_;
  auto it = scenes_.find(id);
  return it == scenes_.end() ? nullptr : it->second;
}

absl::StatusOr<std::shared_ptr<StoredScene>> SceneStore::Find(const std::string& id) const {
  if (id.empty()) return absl::InvalidArgumentError("scene_id: is empty");
  if (auto s = FindExact(id)) return s;
  std::lock_guard lock(mu_);
  if (id.size() >= 8) {
    // A unique prefix, as people copy ids from `tessera scenes`.
    auto it = scenes_.lower_bound(id);
    if (it != scenes_.end() && absl::StartsWith(it->first, id)) {
      auto next = std::next(it);
      if (next == scenes_.end() || !absl::StartsWith(next->first, id)) return it->second;
      return absl::InvalidArgumentError(
          absl::StrCat("scene_id: prefix \"", id, "\" matches more than one scene"));
    }
  }
  return absl::NotFoundError(absl::StrCat("scene_id: no scene \"", id.substr(0, 80),
                                          "\" (ListScenes shows what is loaded)"));
}

void SceneStore::FillLiveFields(const StoredScene& s, v1::SceneInfo* out) {
  out->set_sessions(s.sessions.load());
  out->set_deleted(s.deleted.load());
}

std::vector<v1::SceneInfo> SceneStore::List() const {
  std::lock_guard lock(mu_);
  std::vector<v1::SceneInfo> out;
  auto add = [&out](const StoredScene& s) {
    out.push_back(s.info);
    FillLiveFields(s, &out.back());
  };
  if (demo_) add(*demo_);
  for (const std::string& id : order_) add(*scenes_.at(id));
  for (const auto& w : deleted_)
    if (auto s = w.lock()) add(*s);
  return out;
}

absl::StatusOr<uint32_t> SceneStore::Delete(const std::string& id) {
  absl::StatusOr<std::shared_ptr<StoredScene>> found = Find(id);
  if (!found.ok()) return found.status();
  std::shared_ptr<StoredScene> s = *std::move(found);
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

uint32_t SceneStore::count() const {
  std::lock_guard lock(mu_);
  std::erase_if(deleted_, [](const auto& w) { return w.expired(); });
  return static_cast<uint32_t>(scenes_.size() + deleted_.size() + (demo_ ? 1 : 0));
}

}  // namespace tessera::server

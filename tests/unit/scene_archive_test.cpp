// SceneArchive as the --scene_store_dir store uses it: several archives (replicas) on one
// directory, ids checked on load, LRU eviction under a size limit that never takes a scene
// being loaded, and a crash mid-write that never yields a partial scene.
#include "server/scene_archive.h"

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fcntl.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "tests/unit/status_matchers.h"

namespace tessera::server {
namespace {

namespace fs = std::filesystem;
using test::IsError;

GltfSource MakeScene(uint8_t seed, size_t bytes = 1000, int files = 1) {
  GltfSource source;
  source.main_file = "scene.gltf";
  source.files["scene.gltf"] = {'{', '}'};
  for (int f = 0; f < files; ++f) {
    std::vector<uint8_t> data(bytes);
    for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<uint8_t>(i * 7 + seed + f);
    source.files["buffers/b" + std::to_string(f) + ".bin"] = std::move(data);
  }
  return source;
}

uint64_t BytesOf(const GltfSource& source) {
  uint64_t total = 0;
  for (const auto& [name, data] : source.files) total += data.size();
  return total;
}

class SceneArchiveTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "tessera_scene_archive_XXXXXX").string();
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr);
    root_ = tmpl;
    dir_ = root_ + "/store";
  }
  void TearDown() override { fs::remove_all(root_); }

  std::unique_ptr<SceneArchive> Open(uint64_t max_bytes = 0,
                                     std::chrono::seconds stale = std::chrono::hours(1)) {
    absl::StatusOr<std::unique_ptr<SceneArchive>> a =
        SceneArchive::Open(dir_, {max_bytes, stale}, "scene_store_dir");
    EXPECT_TRUE(a.ok()) << a.status();
    return a.ok() ? *std::move(a) : nullptr;
  }

  // Sets a scene's "last used" time (its directory's mtime) `age` into the past.
  void Age(const std::string& id, std::chrono::seconds age) {
    const std::string path = dir_ + "/" + id;
    fs::last_write_time(path, fs::file_time_type::clock::now() - age);
  }

  std::vector<std::string> Names() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir_)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }

  std::string root_, dir_;
};

TEST_F(SceneArchiveTest, ASceneSavedByOneReplicaLoadsInAnother) {
  std::unique_ptr<SceneArchive> a = Open(), b = Open();
  const GltfSource scene = MakeScene(1);
  const std::string id = SceneIdOf(scene);
  EXPECT_FALSE(b->Has(id));
  EXPECT_TRUE(IsError(b->Load(id, 1 << 20).status(), absl::StatusCode::kNotFound, {id}));
  ASSERT_TRUE(a->Save(id, scene).ok());
  EXPECT_TRUE(b->Has(id));
  absl::StatusOr<GltfSource> loaded = b->Load(id, 1 << 20);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->files, scene.files);
  EXPECT_EQ(b->List(), std::vector<std::string>{id});
  EXPECT_EQ(b->TotalBytes(), BytesOf(scene));
  // Both save the same scene: one archive, no leftovers.
  ASSERT_TRUE(b->Save(id, scene).ok());
  EXPECT_EQ(Names(), std::vector<std::string>{id});
}

TEST_F(SceneArchiveTest, FilesThatDoNotHashToTheIdAreDataLossNotAScene) {
  std::unique_ptr<SceneArchive> a = Open();
  const GltfSource scene = MakeScene(2);
  const std::string id = SceneIdOf(scene);
  ASSERT_TRUE(a->Save(id, scene).ok());
  {
    std::fstream f(dir_ + "/" + id + "/files/buffers/b0.bin",
                   std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(10);
    f.put('\x55');  // one byte changed on disk
  }
  EXPECT_TRUE(IsError(a->Load(id, 1 << 20).status(), absl::StatusCode::kDataLoss,
                      {id, "do not hash to its id"}));
  // A scene saved under another scene's id is refused on load too.
  const GltfSource other = MakeScene(3);
  const std::string wrong = std::string(64, 'e');
  ASSERT_TRUE(a->Save(wrong, other).ok());
  EXPECT_TRUE(IsError(a->Load(wrong, 1 << 20).status(), absl::StatusCode::kDataLoss, {wrong}));
}

TEST_F(SceneArchiveTest, TheSizeLimitEvictsTheLeastRecentlyUsedScene) {
  const GltfSource s1 = MakeScene(1, 4000), s2 = MakeScene(2, 4000), s3 = MakeScene(3, 4000);
  const uint64_t one = BytesOf(s1);
  std::unique_ptr<SceneArchive> a = Open(2 * one + one / 2);  // room for two
  ASSERT_TRUE(a->Save(SceneIdOf(s1), s1).ok());
  ASSERT_TRUE(a->Save(SceneIdOf(s2), s2).ok());
  Age(SceneIdOf(s1), std::chrono::hours(2));
  Age(SceneIdOf(s2), std::chrono::hours(3));
  ASSERT_TRUE(a->Load(SceneIdOf(s2), 1 << 20).ok());  // s2 used now: s1 is the oldest
  ASSERT_TRUE(a->Save(SceneIdOf(s3), s3).ok());
  EXPECT_FALSE(a->Has(SceneIdOf(s1)));
  EXPECT_TRUE(a->Has(SceneIdOf(s2)));
  EXPECT_TRUE(a->Has(SceneIdOf(s3)));
  EXPECT_EQ(a->evictions(), 1u);
  EXPECT_LE(a->TotalBytes(), 2 * one + one / 2);
  // A scene larger than the whole store is refused, naming the limit.
  const GltfSource huge = MakeScene(4, 3 * one);
  EXPECT_TRUE(IsError(a->Save(SceneIdOf(huge), huge), absl::StatusCode::kResourceExhausted,
                      {SceneIdOf(huge), std::to_string(2 * one + one / 2)}));
  EXPECT_EQ(a->List().size(), 2u);
}

TEST_F(SceneArchiveTest, ASceneBeingLoadedIsNeverEvicted) {
  const GltfSource s1 = MakeScene(1, 4000), s2 = MakeScene(2, 4000);
  const uint64_t one = BytesOf(s1);
  std::unique_ptr<SceneArchive> a = Open(one + one / 2);  // room for one
  ASSERT_TRUE(a->Save(SceneIdOf(s1), s1).ok());
  // Another replica is loading s1: it holds the shared lock Load takes.
  const std::string main = dir_ + "/" + SceneIdOf(s1) + "/main";
  const int fd = open(main.c_str(), O_RDONLY | O_CLOEXEC);
  ASSERT_GE(fd, 0);
  ASSERT_EQ(flock(fd, LOCK_SH), 0);
  EXPECT_TRUE(IsError(a->Save(SceneIdOf(s2), s2), absl::StatusCode::kResourceExhausted,
                      {"being loaded"}));
  EXPECT_TRUE(a->Has(SceneIdOf(s1)));
  EXPECT_FALSE(a->Has(SceneIdOf(s2)));
  close(fd);  // the load is done: now s1 can go
  ASSERT_TRUE(a->Save(SceneIdOf(s2), s2).ok());
  EXPECT_FALSE(a->Has(SceneIdOf(s1)));
  EXPECT_TRUE(a->Has(SceneIdOf(s2)));
}

TEST_F(SceneArchiveTest, ACrashMidWriteNeverLeavesAPartialScene) {
  // A child process saves a large scene (64 files of 1 MiB, an fsync each) and is killed
  // with SIGKILL as soon as its temporary directory has files.
  const GltfSource big = MakeScene(9, 1 << 20, 64);
  const std::string id = SceneIdOf(big);
  ASSERT_NE(Open(), nullptr);
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    absl::StatusOr<std::unique_ptr<SceneArchive>> a =
        SceneArchive::Open(dir_, {0, std::chrono::hours(1)}, "scene_store_dir");
    _exit(a.ok() && (*a)->Save(id, big).ok() ? 0 : 1);
  }
  bool writing = false;
  for (int i = 0; i < 2000 && !writing; ++i) {
    for (const auto& e : fs::directory_iterator(dir_)) {
      std::error_code ec;
      if (e.path().filename().string().rfind(".tmp-new-", 0) == 0 &&
          fs::exists(e.path() / "files" / "buffers" / "b1.bin", ec))
        writing = true;
    }
    if (!writing) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  kill(child, SIGKILL);
  int status = 0;
  waitpid(child, &status, 0);
  ASSERT_TRUE(writing) << "the child never started writing";
  ASSERT_TRUE(WIFSIGNALED(status)) << "the child finished before it was killed";
  // Another replica sees no scene, only the crashed write's temporary name ...
  std::unique_ptr<SceneArchive> b = Open();
  EXPECT_FALSE(b->Has(id));
  EXPECT_TRUE(b->List().empty());
  EXPECT_TRUE(IsError(b->Load(id, 1 << 30).status(), absl::StatusCode::kNotFound, {id}));
  ASSERT_EQ(Names().size(), 1u);
  // ... which a replica starting within the hour leaves alone (it could be a live write),
  // and one starting later removes.
  const std::string tmp = dir_ + "/" + Names()[0];
  fs::last_write_time(tmp, fs::file_time_type::clock::now() - std::chrono::hours(2));
  ASSERT_NE(Open(), nullptr);
  EXPECT_TRUE(Names().empty());
  // Saving it again works and loads whole.
  ASSERT_TRUE(b->Save(id, big).ok());
  absl::StatusOr<GltfSource> loaded = b->Load(id, 1 << 30);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->files.size(), big.files.size());
}

}  // namespace
}  // namespace tessera::server

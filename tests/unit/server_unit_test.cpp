// Pure logic of the server, no gRPC calls and no Vulkan device: assembling an UploadScene
// stream (limits, ordering, names, hashes), the content hash that names a scene, translating
// wire settings and cameras into the renderer's structs, and the scene store's index, limits
// and deferred deletion. Every error check asserts the status code and that the message names
// the field, file or limit a person has to fix.
#include <gtest/gtest.h>
#include "tests/unit/status_matchers.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <initializer_list>
#include <limits>
#include <map>
#include <optional>
#include <thread>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "renderer/camera.h"
#include "renderer/renderer.h"
#include "renderer/settings.h"
#include "absl/strings/str_cat.h"
#include "google/protobuf/descriptor.h"
#include "google/protobuf/message.h"
#include "server/convert.h"
#include "server/render_loop.h"
#include "server/scene_store.h"
#include "server/upload.h"
#include "common/scene_id.h"

namespace tessera::server {
namespace {

constexpr float kNan = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

using test::IsError;

std::vector<uint8_t> Bytes(std::string_view s) { return std::vector<uint8_t>(s.begin(), s.end()); }

std::string Sha(std::string_view s) { return Sha256Hex(s.data(), s.size()); }

// ---------------------------------------------------------------------------------------------
// Sha256 / SceneId

TEST(Sha256Test, KnownVectors) {
  EXPECT_EQ(Sha(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(Sha("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(Sha("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
}

TEST(Sha256Test, IncrementalEqualsOneShot) {
  std::string data(1000, '\0');
  for (size_t i = 0; i < data.size(); ++i) data[i] = static_cast<char>((i * 131 + 7) & 0xff);
  const std::string one_shot = Sha(data);
  for (size_t split :
       {size_t{0}, size_t{1}, size_t{63}, size_t{64}, size_t{65}, size_t{999}, size_t{1000}}) {
    Sha256 h;
    h.Update(data.data(), split);
    h.Update(data.data() + split, data.size() - split);
    EXPECT_EQ(h.FinishHex(), one_shot) << "split at " << split;
  }
  // Many tiny updates, including empty ones.
  Sha256 h;
  for (size_t i = 0; i < data.size(); i += 3) {
    h.Update(data.data() + i, std::min<size_t>(3, data.size() - i));
    h.Update(data.data(), 0);
  }
  EXPECT_EQ(h.FinishHex(), one_shot);
}

TEST(Sha256Test, IsSha256Hex) {
  EXPECT_TRUE(IsSha256Hex(Sha("x")));
  EXPECT_FALSE(IsSha256Hex(""));
  EXPECT_FALSE(IsSha256Hex(std::string(63, 'a')));
  EXPECT_FALSE(IsSha256Hex(std::string(65, 'a')));
  EXPECT_FALSE(IsSha256Hex(std::string(64, 'A')));  // lowercase only
  EXPECT_FALSE(IsSha256Hex(std::string(63, 'a') + "g"));
}

TEST(SceneIdTest, IsTheHashOfTheDocumentedText) {
  const std::string gltf = "{\"asset\":{\"version\":\"2.0\"}}";
  const std::string bin = "binary";
  const std::string text =
      "a/mesh.bin\n" + Sha(bin) + "\nscene.gltf\n" + Sha(gltf) + "\nmain scene.gltf\n";
  EXPECT_EQ(SceneId({{"scene.gltf", Sha(gltf)}, {"a/mesh.bin", Sha(bin)}}, "scene.gltf"),
            Sha(text));
}

// ---------------------------------------------------------------------------------------------
// UploadAssembler

struct TestFile {
  std::string name;
  std::string content;
};

v1::UploadManifest Manifest(const std::vector<std::pair<std::string, uint64_t>>& files,
                            const std::string& main_file = "") {
  v1::UploadManifest m;
  for (const auto& [name, size] : files) {
    v1::UploadFile* f = m.add_files();
    f->set_name(name);
    f->set_size(size);
  }
  m.set_main_file(main_file);
  return m;
}

v1::UploadManifest Manifest(const std::vector<TestFile>& files, const std::string& main_file = "") {
  std::vector<std::pair<std::string, uint64_t>> sized;
  for (const TestFile& f : files) sized.emplace_back(f.name, f.content.size());
  return Manifest(sized, main_file);
}

v1::UploadChunk Chunk(uint32_t file_index, uint64_t offset, std::string_view data) {
  v1::UploadChunk c;
  c.set_file_index(file_index);
  c.set_offset(offset);
  c.set_data(std::string(data));
  return c;
}

absl::Status AddChunk(UploadAssembler& a, uint32_t file_index, uint64_t offset,
                      std::string_view data) {
  v1::UploadChunk c = Chunk(file_index, offset, data);
  return a.Add(&c);
}

// Sends every file in chunks of `chunk` bytes, interleaving the files round-robin.
absl::Status SendAll(UploadAssembler& a, const std::vector<TestFile>& files, size_t chunk) {
  std::vector<size_t> sent(files.size(), 0);
  for (bool more = true; more;) {
    more = false;
    for (size_t i = 0; i < files.size(); ++i) {
      const std::string& c = files[i].content;
      if (sent[i] >= c.size()) continue;
      const size_t n = std::min(chunk, c.size() - sent[i]);
      if (absl::Status st = AddChunk(a, static_cast<uint32_t>(i), sent[i],
                                     std::string_view(c).substr(sent[i], n));
          !st.ok())
        return st;
      sent[i] += n;
      more = true;
    }
  }
  return absl::OkStatus();
}

const std::vector<TestFile>& BoxFiles() {
  static constexpr char kBinary[] = "\x00\x01\x02\xff\x00 binary \x7f tail";  // NULs inside
  static const std::vector<TestFile> files = {
      {"scene.gltf",
       "{\"asset\":{\"version\":\"2.0\"},\"buffers\":[{\"uri\":\"buffers/box.bin\"}]}"},
      {"buffers/box.bin", std::string(kBinary, sizeof(kBinary) - 1)},
      {"textures/wall.png", std::string(300, 'p')},
  };
  return files;
}

TEST(UploadAssemblerTest, AssemblesFilesAndComputesTheSceneId) {
  const std::vector<TestFile>& files = BoxFiles();
  v1::UploadManifest manifest = Manifest(files);
  // A correct sha256 for one file is checked and accepted.
  manifest.mutable_files(1)->set_sha256(Sha(files[1].content));
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(manifest).ok());
  EXPECT_TRUE(a.begun());
  EXPECT_EQ(a.main_file(), "scene.gltf");
  uint64_t total = 0;
  for (const TestFile& f : files) total += f.content.size();
  EXPECT_EQ(a.declared_bytes(), total);
  ASSERT_TRUE(SendAll(a, files, 7).ok());
  EXPECT_EQ(a.received_bytes(), total);

  std::string scene_id;
  absl::StatusOr<GltfSource> source = a.Finish(&scene_id);
  ASSERT_TRUE(source.ok()) << source.status();
  EXPECT_EQ(source->main_file, "scene.gltf");
  ASSERT_EQ(source->files.size(), files.size());
  std::map<std::string, std::string> hashes;
  for (const TestFile& f : files) {
    ASSERT_EQ(source->files.count(f.name), 1u) << f.name;
    EXPECT_EQ(source->files.at(f.name), Bytes(f.content)) << f.name;
    hashes[f.name] = Sha(f.content);
  }
  EXPECT_EQ(scene_id, SceneId(hashes, "scene.gltf"));
  // The same id spelled out from the documented text, without SceneId.
  const std::string text = "buffers/box.bin\n" + Sha(files[1].content) + "\nscene.gltf\n" +
                           Sha(files[0].content) + "\ntextures/wall.png\n" + Sha(files[2].content) +
                           "\nmain scene.gltf\n";
  EXPECT_EQ(scene_id, Sha(text));
}

TEST(UploadAssemblerTest, SceneIdIgnoresManifestOrderAndChunking) {
  std::vector<TestFile> files = BoxFiles();
  std::string id_a, id_b;
  {
    UploadAssembler a(UploadLimits{});
    ASSERT_TRUE(a.Begin(Manifest(files)).ok());
    ASSERT_TRUE(SendAll(a, files, 1000).ok());
    ASSERT_TRUE(a.Finish(&id_a).ok());
  }
  std::reverse(files.begin(), files.end());
  {
    UploadAssembler a(UploadLimits{});
    ASSERT_TRUE(a.Begin(Manifest(files)).ok());
    ASSERT_TRUE(SendAll(a, files, 3).ok());
    ASSERT_TRUE(a.Finish(&id_b).ok());
  }
  EXPECT_TRUE(IsSha256Hex(id_a)) << id_a;
  EXPECT_EQ(id_a, id_b);
}

TEST(UploadAssemblerTest, SceneIdDependsOnContentAndMainFile) {
  const std::vector<TestFile> files = {{"a.gltf", "{}"}, {"b.gltf", "{ }"}};
  auto id_of = [](const std::vector<TestFile>& fs, const std::string& main) {
    UploadAssembler a(UploadLimits{});
    EXPECT_TRUE(a.Begin(Manifest(fs, main)).ok());
    EXPECT_TRUE(SendAll(a, fs, 64).ok());
    std::string id;
    EXPECT_TRUE(a.Finish(&id).ok());
    return id;
  };
  const std::string main_a = id_of(files, "a.gltf");
  EXPECT_NE(main_a, id_of(files, "b.gltf"));
  EXPECT_NE(main_a, id_of({{"a.gltf", "{}"}, {"b.gltf", "{  }"}}, "a.gltf"));
  EXPECT_EQ(main_a, id_of(files, "a.gltf"));
}

TEST(UploadAssemblerTest, ChunkDataIsMovedOut) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"s.glb", 4}})).ok());
  v1::UploadChunk c = Chunk(0, 0, "glTF");
  ASSERT_TRUE(a.Add(&c).ok());
  EXPECT_TRUE(c.data().empty());
}

TEST(UploadAssemblerTest, EmptyFileNeedsNoChunks) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"s.gltf", 2}, {"empty.bin", 0}})).ok());
  ASSERT_TRUE(AddChunk(a, 0, 0, "{}").ok());
  std::string id;
  absl::StatusOr<GltfSource> source = a.Finish(&id);
  ASSERT_TRUE(source.ok()) << source.status();
  EXPECT_TRUE(source->files.at("empty.bin").empty());
}

TEST(UploadAssemblerTest, ChunkOffsetsMustFollowOn) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"scene.gltf", 10}, {"data.bin", 10}})).ok());
  EXPECT_TRUE(IsError(AddChunk(a, 0, 1, "abc"), absl::StatusCode::kInvalidArgument,
                      {"chunk.offset", "scene.gltf"}));
  ASSERT_TRUE(AddChunk(a, 0, 0, "abc").ok());
  // An overlap and a gap are both refused; the file's own offset counts, not other files'.
  EXPECT_TRUE(IsError(AddChunk(a, 0, 2, "def"), absl::StatusCode::kInvalidArgument,
                      {"chunk.offset", "scene.gltf"}));
  EXPECT_TRUE(IsError(AddChunk(a, 0, 4, "def"), absl::StatusCode::kInvalidArgument,
                      {"chunk.offset", "scene.gltf"}));
  EXPECT_TRUE(IsError(AddChunk(a, 1, 3, "xyz"), absl::StatusCode::kInvalidArgument,
                      {"chunk.offset", "data.bin"}));
  EXPECT_TRUE(AddChunk(a, 1, 0, "xyz").ok());
  EXPECT_TRUE(AddChunk(a, 0, 3, "def").ok());
  EXPECT_EQ(a.received_bytes(), 9u);  // refused chunks are not counted
}

TEST(UploadAssemblerTest, UnknownFileIndex) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"scene.gltf", 10}, {"data.bin", 10}})).ok());
  EXPECT_TRUE(IsError(AddChunk(a, 2, 0, "abc"), absl::StatusCode::kInvalidArgument,
                      {"chunk.file_index", "2"}));
  EXPECT_TRUE(IsError(AddChunk(a, 0xffffffffu, 0, "abc"), absl::StatusCode::kInvalidArgument,
                      {"chunk.file_index"}));
}

TEST(UploadAssemblerTest, DataPastTheDeclaredSize) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"scene.gltf", 2}, {"data.bin", 4}})).ok());
  EXPECT_TRUE(IsError(AddChunk(a, 1, 0, "12345"), absl::StatusCode::kInvalidArgument,
                      {"chunk.data", "data.bin"}));
  ASSERT_TRUE(AddChunk(a, 1, 0, "123").ok());
  EXPECT_TRUE(IsError(AddChunk(a, 1, 3, "45"), absl::StatusCode::kInvalidArgument,
                      {"chunk.data", "data.bin"}));
  EXPECT_TRUE(AddChunk(a, 1, 3, "4").ok());
  EXPECT_TRUE(IsError(AddChunk(a, 1, 4, "5"), absl::StatusCode::kInvalidArgument,
                      {"chunk.data", "data.bin"}));
}

TEST(UploadAssemblerTest, EmptyChunk) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"scene.gltf", 2}, {"data.bin", 4}})).ok());
  EXPECT_TRUE(IsError(AddChunk(a, 1, 0, ""), absl::StatusCode::kInvalidArgument,
                      {"chunk.data", "empty", "data.bin"}));
}

TEST(UploadAssemblerTest, ChunkOverMaxChunkBytes) {
  UploadLimits limits;
  limits.max_chunk_bytes = 8;
  UploadAssembler a(limits);
  ASSERT_TRUE(a.Begin(Manifest({{"scene.gltf", 100}})).ok());
  EXPECT_TRUE(IsError(AddChunk(a, 0, 0, "123456789"), absl::StatusCode::kResourceExhausted,
                      {"chunk.data", "max_chunk_bytes", "8"}));
  EXPECT_TRUE(AddChunk(a, 0, 0, "12345678").ok());  // the limit itself is allowed
}

TEST(UploadAssemblerTest, TooManyFiles) {
  UploadLimits limits;
  limits.max_files = 2;
  UploadAssembler a(limits);
  EXPECT_TRUE(IsError(a.Begin(Manifest({{"s.gltf", 1}, {"a.bin", 1}, {"b.bin", 1}})),
                      absl::StatusCode::kResourceExhausted, {"max_upload_files", "2"}));
  EXPECT_FALSE(a.begun());
  EXPECT_TRUE(a.Begin(Manifest({{"s.gltf", 1}, {"a.bin", 1}})).ok());
}

TEST(UploadAssemblerTest, TooManyBytes) {
  UploadLimits limits;
  limits.max_bytes = 10;
  {
    UploadAssembler a(limits);
    EXPECT_TRUE(IsError(a.Begin(Manifest({{"s.gltf", 6}, {"big.bin", 5}})),
                        absl::StatusCode::kResourceExhausted,
                        {"max_upload_bytes", "10", "big.bin"}));
  }
  {
    // One file alone past the limit, with a size that would overflow a naive sum.
    UploadAssembler a(limits);
    EXPECT_TRUE(IsError(
        a.Begin(Manifest({{"s.gltf", 6}, {"huge.bin", std::numeric_limits<uint64_t>::max()}})),
        absl::StatusCode::kResourceExhausted, {"max_upload_bytes", "huge.bin"}));
  }
  UploadAssembler a(limits);
  EXPECT_TRUE(a.Begin(Manifest({{"s.gltf", 6}, {"a.bin", 4}})).ok());  // exactly the limit
}

TEST(UploadAssemblerTest, DuplicateNames) {
  UploadAssembler a(UploadLimits{});
  EXPECT_TRUE(IsError(a.Begin(Manifest({{"s.gltf", 1}, {"a.bin", 1}, {"a.bin", 2}})),
                      absl::StatusCode::kInvalidArgument,
                      {"manifest.files[2]", "duplicate", "a.bin"}));
}

TEST(UploadAssemblerTest, BadNamesInTheManifest) {
  const std::vector<std::string> names = {"../secret.bin",      "/etc/passwd", "textures\\wall.png",
                                          "textures//wall.png", "a\nb.bin",    ""};
  for (const std::string& name : names) {
    UploadAssembler a(UploadLimits{});
    EXPECT_TRUE(IsError(a.Begin(Manifest({{"s.gltf", 1}, {name, 1}})),
                        absl::StatusCode::kInvalidArgument, {"manifest.files[1]", "file name"}))
        << "name \"" << name << "\"";
    EXPECT_FALSE(a.begun());
  }
}

TEST(UploadAssemblerTest, EmptyManifest) {
  UploadAssembler a(UploadLimits{});
  EXPECT_TRUE(IsError(a.Begin(Manifest(std::vector<TestFile>{})),
                      absl::StatusCode::kInvalidArgument, {"manifest.files"}));
}

TEST(UploadAssemblerTest, BadSha256Text) {
  UploadAssembler a(UploadLimits{});
  v1::UploadManifest m = Manifest({{"s.gltf", 1}});
  m.mutable_files(0)->set_sha256(std::string(64, 'A'));
  EXPECT_TRUE(
      IsError(a.Begin(m), absl::StatusCode::kInvalidArgument, {"manifest.files[0].sha256"}));
}

TEST(UploadAssemblerTest, MainFileMustBeKnown) {
  {
    UploadAssembler a(UploadLimits{});
    EXPECT_TRUE(IsError(a.Begin(Manifest({{"a.bin", 1}, {"b.png", 1}})),
                        absl::StatusCode::kInvalidArgument, {"manifest.main_file", "0 files"}));
  }
  {
    UploadAssembler a(UploadLimits{});
    EXPECT_TRUE(IsError(a.Begin(Manifest({{"a.gltf", 1}, {"b.glb", 1}})),
                        absl::StatusCode::kInvalidArgument, {"manifest.main_file", "2 files"}));
  }
  {
    UploadAssembler a(UploadLimits{});
    EXPECT_TRUE(IsError(a.Begin(Manifest({{"a.gltf", 1}}, "other.gltf")),
                        absl::StatusCode::kInvalidArgument, {"manifest.main_file", "other.gltf"}));
  }
  {
    UploadAssembler a(UploadLimits{});
    EXPECT_TRUE(IsError(a.Begin(Manifest({{"a.gltf", 1}, {"a.bin", 1}}, "a.bin")),
                        absl::StatusCode::kInvalidArgument, {"manifest.main_file", "a.bin"}));
  }
  {
    // Two glTF files are fine once main_file names one.
    UploadAssembler a(UploadLimits{});
    ASSERT_TRUE(a.Begin(Manifest({{"a.gltf", 1}, {"b.GLB", 1}}, "b.GLB")).ok());
    EXPECT_EQ(a.main_file(), "b.GLB");
  }
}

TEST(UploadAssemblerTest, ShortFileAtFinish) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"s.gltf", 2}, {"data.bin", 4}, {"never.png", 3}})).ok());
  ASSERT_TRUE(AddChunk(a, 0, 0, "{}").ok());
  ASSERT_TRUE(AddChunk(a, 1, 0, "12").ok());
  std::string id = "unchanged";
  absl::StatusOr<GltfSource> source = a.Finish(&id);
  EXPECT_TRUE(IsError(source.status(), absl::StatusCode::kInvalidArgument, {"data.bin", "2", "4"}));
  EXPECT_EQ(id, "unchanged");
}

TEST(UploadAssemblerTest, FileWithNoChunksAtFinish) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"s.gltf", 2}, {"never.png", 3}})).ok());
  ASSERT_TRUE(AddChunk(a, 0, 0, "{}").ok());
  std::string id;
  EXPECT_TRUE(IsError(a.Finish(&id).status(), absl::StatusCode::kInvalidArgument, {"never.png"}));
}

TEST(UploadAssemblerTest, Sha256Mismatch) {
  UploadAssembler a(UploadLimits{});
  v1::UploadManifest m = Manifest({{"s.gltf", 2}, {"data.bin", 4}});
  m.mutable_files(1)->set_sha256(Sha("1235"));
  ASSERT_TRUE(a.Begin(m).ok());
  ASSERT_TRUE(AddChunk(a, 0, 0, "{}").ok());
  ASSERT_TRUE(AddChunk(a, 1, 0, "1234").ok());
  std::string id;
  EXPECT_TRUE(IsError(a.Finish(&id).status(), absl::StatusCode::kDataLoss,
                      {"data.bin", "sha256", Sha("1234"), Sha("1235")}));
}

TEST(UploadAssemblerTest, ManifestTwice) {
  UploadAssembler a(UploadLimits{});
  ASSERT_TRUE(a.Begin(Manifest({{"s.gltf", 2}})).ok());
  EXPECT_TRUE(IsError(a.Begin(Manifest({{"t.gltf", 2}})), absl::StatusCode::kInvalidArgument,
                      {"manifest"}));
  EXPECT_EQ(a.main_file(), "s.gltf");  // the first manifest stays
}

TEST(UploadAssemblerTest, ChunkOrFinishBeforeManifest) {
  UploadAssembler a(UploadLimits{});
  EXPECT_TRUE(
      IsError(AddChunk(a, 0, 0, "{}"), absl::StatusCode::kInvalidArgument, {"chunk", "manifest"}));
  std::string id;
  EXPECT_TRUE(IsError(a.Finish(&id).status(), absl::StatusCode::kInvalidArgument, {"manifest"}));
}

// ---------------------------------------------------------------------------------------------
// ValidateUploadName

TEST(ValidateUploadNameTest, AcceptsRelativeNames) {
  const std::vector<std::string> names = {"Box0.bin",
                                          "textures/wall.png",
                                          "a b/c d.png",
                                          "..a",
                                          "a..",
                                          ".hidden/x.png",
                                          "deep/er/still/deeper/file.bin",
                                          "\xc3\xa9t\xc3\xa9.png",
                                          std::string(1024, 'n')};
  for (const std::string& name : names) {
    EXPECT_TRUE(ValidateUploadName(name).ok())
        << "\"" << name << "\": " << ValidateUploadName(name);
  }
}

TEST(ValidateUploadNameTest, RejectsEscapesAndOddNames) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "empty"},
      {"..", "'..'"},
      {"../x.bin", "'..'"},
      {"a/../../x.bin", "'..'"},
      {"./x.bin", "'.'"},
      {"a/./x.bin", "'.'"},
      {"/abs.bin", "absolute"},
      {"/", "absolute"},
      {"a\\b.bin", "backslash"},
      {"..\\x.bin", "backslash"},
      {"a//b.bin", "empty path segment"},
      {"a/", "empty path segment"},
      {std::string("a\0b", 3), "control character"},
      {"a\tb", "control character"},
      {"a\x1f", "control character"},
      {"a\x7f", "control character"},
      {std::string(1025, 'n'), "longer than 1024"},
  };
  for (const auto& [name, why] : cases) {
    EXPECT_TRUE(
        IsError(ValidateUploadName(name), absl::StatusCode::kInvalidArgument, {"file name", why}))
        << "name of " << name.size() << " bytes";
  }
}

// ---------------------------------------------------------------------------------------------
// MergeSettings / ToProto(Settings)

// Every field differs from Settings{} and is valid.
Settings NonDefaultSettings() {
  Settings s;
  s.width = 640;
  s.height = 480;
  s.aa = AaMode::kMsaa;
  s.samples = 2;
  s.culling = CullingMode::kGpuOcclusion;
  s.scene_lights = false;
  s.synthetic_lights = 123;
  s.light_seed = 7;
  s.tile_size = 32;
  s.shadows = true;
  s.ssao = true;
  s.bloom = true;
  s.ibl = true;
  s.exposure_mode = ExposureMode::kAuto;
  s.exposure_ev = -1.5f;
  s.tonemapper = Tonemapper::kPhotographic;
  s.debug_view = DebugView::kLightHeatmap;
  s.jpeg_quality = 75;
  s.jpeg_444 = true;
  return s;
}

void ExpectSameSettings(const Settings& a, const Settings& b) {
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(ToString(a.aa), ToString(b.aa));
  EXPECT_EQ(a.samples, b.samples);
  EXPECT_EQ(ToString(a.culling), ToString(b.culling));
  EXPECT_EQ(a.scene_lights, b.scene_lights);
  EXPECT_EQ(a.synthetic_lights, b.synthetic_lights);
  EXPECT_EQ(a.light_seed, b.light_seed);
  EXPECT_EQ(a.tile_size, b.tile_size);
  EXPECT_EQ(a.shadows, b.shadows);
  EXPECT_EQ(a.ssao, b.ssao);
  EXPECT_EQ(a.bloom, b.bloom);
  EXPECT_EQ(a.ibl, b.ibl);
  EXPECT_EQ(ToString(a.exposure_mode), ToString(b.exposure_mode));
  EXPECT_EQ(a.exposure_ev, b.exposure_ev);
  EXPECT_EQ(ToString(a.tonemapper), ToString(b.tonemapper));
  EXPECT_EQ(ToString(a.debug_view), ToString(b.debug_view));
  EXPECT_EQ(a.jpeg_quality, b.jpeg_quality);
  EXPECT_EQ(a.jpeg_444, b.jpeg_444);
}

TEST(MergeSettingsTest, UnsetFieldsKeepTheBase) {
  const Settings base = NonDefaultSettings();
  absl::StatusOr<Settings> merged = MergeSettings(base, v1::RenderSettings{});
  ASSERT_TRUE(merged.ok()) << merged.status();
  ExpectSameSettings(*merged, base);
}

TEST(MergeSettingsTest, SetFieldsReplaceOnlyThemselves) {
  const Settings base = NonDefaultSettings();
  v1::RenderSettings u;
  u.set_width(320);
  u.set_aa(v1::AA_NONE);
  u.set_shadows(false);     // explicit false replaces true
  u.set_exposure_ev(0.0f);  // explicit zero replaces -1.5
  u.set_jpeg_quality(10);
  absl::StatusOr<Settings> merged = MergeSettings(base, u);
  ASSERT_TRUE(merged.ok()) << merged.status();
  Settings want = base;
  want.width = 320;
  want.aa = AaMode::kNone;
  want.shadows = false;
  want.exposure_ev = 0.0f;
  want.jpeg_quality = 10;
  ExpectSameSettings(*merged, want);
}

TEST(MergeSettingsTest, WireEnumsMapToTheRendererEnums) {
  const std::vector<std::pair<v1::AaMode, AaMode>> aa = {{v1::AA_NONE, AaMode::kNone},
                                                         {v1::AA_MSAA, AaMode::kMsaa},
                                                         {v1::AA_FXAA, AaMode::kFxaa},
                                                         {v1::AA_TAA, AaMode::kTaa},
                                                         {v1::AA_VIS_MLAA, AaMode::kVisMlaa}};
  for (const auto& [wire, want] : aa) {
    v1::RenderSettings u;
    u.set_aa(wire);
    absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(ToString(s->aa), ToString(want)) << v1::AaMode_Name(wire);
  }
  const std::vector<std::pair<v1::CullingMode, CullingMode>> culling = {
      {v1::CULLING_NONE, CullingMode::kNone},
      {v1::CULLING_CPU_FRUSTUM, CullingMode::kCpuFrustum},
      {v1::CULLING_GPU_FRUSTUM, CullingMode::kGpuFrustum},
      {v1::CULLING_GPU_OCCLUSION, CullingMode::kGpuOcclusion}};
  for (const auto& [wire, want] : culling) {
    v1::RenderSettings u;
    u.set_culling(wire);
    absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(ToString(s->culling), ToString(want)) << v1::CullingMode_Name(wire);
  }
  const std::vector<std::pair<v1::ExposureMode, ExposureMode>> exposure = {
      {v1::EXPOSURE_FIXED, ExposureMode::kFixed}, {v1::EXPOSURE_AUTO, ExposureMode::kAuto}};
  for (const auto& [wire, want] : exposure) {
    v1::RenderSettings u;
    u.set_exposure_mode(wire);
    absl::StatusOr<Settings> s = MergeSettings(NonDefaultSettings(), u);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(ToString(s->exposure_mode), ToString(want)) << v1::ExposureMode_Name(wire);
  }
  for (const auto& [wire, want] :
       std::vector<std::pair<v1::Tonemapper, Tonemapper>>{
           {v1::TONEMAPPER_PBR_NEUTRAL, Tonemapper::kPbrNeutral},
           {v1::TONEMAPPER_PHOTOGRAPHIC, Tonemapper::kPhotographic}}) {
    v1::RenderSettings u;
    u.set_tonemapper(wire);
    absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(ToString(s->tonemapper), ToString(want)) << v1::Tonemapper_Name(wire);
  }
  {
    v1::RenderSettings u;
    u.set_tonemapper(static_cast<v1::Tonemapper>(9));
    absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
    ASSERT_FALSE(s.ok());
    EXPECT_NE(std::string(s.status().message()).find("settings.tonemapper"), std::string::npos);
  }
  const std::vector<std::pair<v1::DebugView, DebugView>> debug = {
      {v1::DEBUG_NONE, DebugView::kNone},
      {v1::DEBUG_NORMALS, DebugView::kNormals},
      {v1::DEBUG_DEPTH, DebugView::kDepth},
      {v1::DEBUG_BASE_COLOR, DebugView::kBaseColor},
      {v1::DEBUG_LIGHT_HEATMAP, DebugView::kLightHeatmap},
      {v1::DEBUG_CULLING_OVERLAY, DebugView::kCullingOverlay},
      {v1::DEBUG_AA_MASK, DebugView::kAaMask}};
  for (const auto& [wire, want] : debug) {
    v1::RenderSettings u;
    u.set_debug_view(wire);
    absl::StatusOr<Settings> s = MergeSettings(Settings{}, u);
    ASSERT_TRUE(s.ok()) << s.status();
    EXPECT_EQ(ToString(s->debug_view), ToString(want)) << v1::DebugView_Name(wire);
  }
}

TEST(MergeSettingsTest, UnknownEnumValuesNameTheField) {
  {
    v1::RenderSettings u;
    u.set_aa(static_cast<v1::AaMode>(42));
    EXPECT_TRUE(IsError(MergeSettings(Settings{}, u).status(), absl::StatusCode::kInvalidArgument,
                        {"settings.aa", "42"}));
  }
  {
    v1::RenderSettings u;
    u.set_aa(static_cast<v1::AaMode>(-1));
    EXPECT_TRUE(IsError(MergeSettings(Settings{}, u).status(), absl::StatusCode::kInvalidArgument,
                        {"settings.aa"}));
  }
  {
    v1::RenderSettings u;
    u.set_culling(static_cast<v1::CullingMode>(42));
    EXPECT_TRUE(IsError(MergeSettings(Settings{}, u).status(), absl::StatusCode::kInvalidArgument,
                        {"settings.culling"}));
  }
  {
    v1::RenderSettings u;
    u.set_exposure_mode(static_cast<v1::ExposureMode>(42));
    EXPECT_TRUE(IsError(MergeSettings(Settings{}, u).status(), absl::StatusCode::kInvalidArgument,
                        {"settings.exposure_mode"}));
  }
  {
    v1::RenderSettings u;
    u.set_debug_view(static_cast<v1::DebugView>(42));
    EXPECT_TRUE(IsError(MergeSettings(Settings{}, u).status(), absl::StatusCode::kInvalidArgument,
                        {"settings.debug_view"}));
  }
}

TEST(MergeSettingsTest, OutOfRangeValuesNameTheField) {
  struct Case {
    const char* field;
    void (*set)(v1::RenderSettings*);
  };
  const Case cases[] = {
      {"settings.width", [](v1::RenderSettings* u) { u->set_width(0); }},
      {"settings.width", [](v1::RenderSettings* u) { u->set_width(100000); }},
      {"settings.height", [](v1::RenderSettings* u) { u->set_height(0); }},
      {"settings.height", [](v1::RenderSettings* u) { u->set_height(16385); }},
      {"settings.samples", [](v1::RenderSettings* u) { u->set_samples(3); }},
      {"settings.synthetic_lights", [](v1::RenderSettings* u) { u->set_synthetic_lights(65537); }},
      {"settings.tile_size", [](v1::RenderSettings* u) { u->set_tile_size(12); }},
      {"settings.exposure_ev", [](v1::RenderSettings* u) { u->set_exposure_ev(20.5f); }},
      {"settings.exposure_ev", [](v1::RenderSettings* u) { u->set_exposure_ev(kNan); }},
      {"settings.jpeg_quality", [](v1::RenderSettings* u) { u->set_jpeg_quality(0); }},
      {"settings.jpeg_quality", [](v1::RenderSettings* u) { u->set_jpeg_quality(101); }},
  };
  for (const Case& c : cases) {
    v1::RenderSettings u;
    c.set(&u);
    EXPECT_TRUE(IsError(MergeSettings(Settings{}, u).status(), absl::StatusCode::kInvalidArgument,
                        {c.field}))
        << u.ShortDebugString();
  }
}

TEST(MergeSettingsTest, ToProtoRoundTripsEveryField) {
  for (const Settings& s : {Settings{}, NonDefaultSettings()}) {
    v1::RenderSettings wire;
    ToProto(s, &wire);
    absl::StatusOr<Settings> back = MergeSettings(Settings{}, wire);
    ASSERT_TRUE(back.ok()) << back.status();
    ExpectSameSettings(*back, s);
    // Merged into a base that differs everywhere, every field must still come from `wire`.
    absl::StatusOr<Settings> over = MergeSettings(NonDefaultSettings(), wire);
    ASSERT_TRUE(over.ok()) << over.status();
    ExpectSameSettings(*over, s);
  }
  // Every enum value survives the trip (the wire values are shifted by one).
  for (size_t i = 0; i < EnumNames<AaMode>().size(); ++i) {
    const auto v = static_cast<AaMode>(i);
    Settings s;
    s.aa = v;
    v1::RenderSettings wire;
    ToProto(s, &wire);
    absl::StatusOr<Settings> back = MergeSettings(NonDefaultSettings(), wire);
    ASSERT_TRUE(back.ok()) << back.status();
    EXPECT_EQ(ToString(back->aa), ToString(v));
  }
  for (size_t i = 0; i < EnumNames<DebugView>().size(); ++i) {
    const auto v = static_cast<DebugView>(i);
    Settings s;
    s.debug_view = v;
    v1::RenderSettings wire;
    ToProto(s, &wire);
    absl::StatusOr<Settings> back = MergeSettings(NonDefaultSettings(), wire);
    ASSERT_TRUE(back.ok()) << back.status();
    EXPECT_EQ(ToString(back->debug_view), ToString(v));
  }
}

// ---------------------------------------------------------------------------------------------
// ResolveCamera

SceneInfo TestScene() {
  SceneInfo info;
  info.name = "test";
  info.bounds = Aabb{glm::vec3(-1.0f, -2.0f, -3.0f), glm::vec3(3.0f, 2.0f, 1.0f)};
  SceneCamera cam;
  cam.name = "file camera";
  cam.world = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 1.0f, 5.0f));
  cam.yfov = 0.6f;
  cam.znear = 0.1f;
  cam.zfar = 50.0f;
  info.cameras.push_back(cam);
  return info;
}

void SetVec(v1::Vec3* v, float x, float y, float z) {
  v->set_x(x);
  v->set_y(y);
  v->set_z(z);
}

v1::Camera LookAt(glm::vec3 eye, glm::vec3 target) {
  v1::Camera c;
  SetVec(c.mutable_look_at()->mutable_eye(), eye.x, eye.y, eye.z);
  SetVec(c.mutable_look_at()->mutable_target(), target.x, target.y, target.z);
  return c;
}

bool Inside(const Aabb& box, glm::vec3 p) {
  return glm::all(glm::greaterThanEqual(p, box.min)) && glm::all(glm::lessThanEqual(p, box.max));
}

void ExpectNear(glm::vec3 a, glm::vec3 b, float eps = 1e-4f) {
  EXPECT_NEAR(a.x, b.x, eps);
  EXPECT_NEAR(a.y, b.y, eps);
  EXPECT_NEAR(a.z, b.z, eps);
}

TEST(ResolveCameraTest, LookAt) {
  absl::StatusOr<Camera> cam =
      ResolveCamera(LookAt({1.0f, 2.0f, 3.0f}, {0.0f, 0.5f, 0.0f}), TestScene(), 1.0f);
  ASSERT_TRUE(cam.ok()) << cam.status();
  EXPECT_FALSE(cam->view.has_value());
  ExpectNear(cam->eye, {1.0f, 2.0f, 3.0f});
  ExpectNear(cam->target, {0.0f, 0.5f, 0.0f});
  ExpectNear(cam->up, {0.0f, 1.0f, 0.0f});  // unset up: +Y
  EXPECT_FLOAT_EQ(cam->yfov, Camera{}.yfov);
  EXPECT_FLOAT_EQ(cam->znear, Camera{}.znear);
  EXPECT_FLOAT_EQ(cam->zfar, Camera{}.zfar);
}

TEST(ResolveCameraTest, LookAtErrorsNameTheField) {
  const SceneInfo scene = TestScene();
  EXPECT_TRUE(IsError(ResolveCamera(LookAt({kNan, 0.0f, 1.0f}, {0, 0, 0}), scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.look_at.eye"}));
  EXPECT_TRUE(IsError(ResolveCamera(LookAt({0, 0, 1}, {0.0f, kInf, 0.0f}), scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.look_at.target"}));
  EXPECT_TRUE(IsError(ResolveCamera(LookAt({1, 2, 3}, {1, 2, 3}), scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.look_at.target", "eye"}));
  v1::Camera parallel = LookAt({0, 0, 0}, {0, 5, 0});  // looking straight up with +Y up
  EXPECT_TRUE(IsError(ResolveCamera(parallel, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.look_at.up"}));
  v1::Camera zero_up = LookAt({0, 0, 5}, {0, 0, 0});
  SetVec(zero_up.mutable_look_at()->mutable_up(), 0, 0, 0);
  EXPECT_TRUE(IsError(ResolveCamera(zero_up, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.look_at.up"}));
  v1::Camera nan_up = LookAt({0, 0, 5}, {0, 0, 0});
  SetVec(nan_up.mutable_look_at()->mutable_up(), 0, kNan, 0);
  EXPECT_TRUE(IsError(ResolveCamera(nan_up, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.look_at.up"}));
}

TEST(ResolveCameraTest, ViewMatrix) {
  const glm::mat4 view = glm::lookAtRH(glm::vec3(4, 3, 2), glm::vec3(0), glm::vec3(0, 1, 0));
  v1::Camera c;
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row) c.mutable_view_matrix()->add_m(view[col][row]);
  absl::StatusOr<Camera> cam = ResolveCamera(c, TestScene(), 1.0f);
  ASSERT_TRUE(cam.ok()) << cam.status();
  ASSERT_TRUE(cam->view.has_value());
  for (int col = 0; col < 4; ++col)
    for (int row = 0; row < 4; ++row)
      EXPECT_FLOAT_EQ((*cam->view)[col][row], view[col][row]) << col << "," << row;
  ExpectNear(CameraPosition(*cam), {4, 3, 2});
}

TEST(ResolveCameraTest, ViewMatrixErrorsNameTheField) {
  const SceneInfo scene = TestScene();
  v1::Camera fifteen;
  for (int i = 0; i < 15; ++i) fifteen.mutable_view_matrix()->add_m(i % 5 == 0 ? 1.0f : 0.0f);
  EXPECT_TRUE(IsError(ResolveCamera(fifteen, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.view_matrix.m", "15"}));
  v1::Camera empty;
  empty.mutable_view_matrix();
  EXPECT_TRUE(IsError(ResolveCamera(empty, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.view_matrix.m", "0"}));
  v1::Camera singular;
  for (int i = 0; i < 16; ++i) singular.mutable_view_matrix()->add_m(0.0f);
  EXPECT_TRUE(IsError(ResolveCamera(singular, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.view_matrix.m", "singular"}));
  v1::Camera nan;
  for (int i = 0; i < 16; ++i) nan.mutable_view_matrix()->add_m(i % 5 == 0 ? 1.0f : 0.0f);
  nan.mutable_view_matrix()->set_m(12, kNan);
  EXPECT_TRUE(IsError(ResolveCamera(nan, scene, 1.0f).status(), absl::StatusCode::kInvalidArgument,
                      {"camera.view_matrix.m"}));
}

TEST(ResolveCameraTest, SceneCamera) {
  const SceneInfo scene = TestScene();
  v1::Camera c;
  c.set_scene_camera(0);
  absl::StatusOr<Camera> cam = ResolveCamera(c, scene, 1.0f);
  ASSERT_TRUE(cam.ok()) << cam.status();
  ASSERT_TRUE(cam->view.has_value());
  ExpectNear(CameraPosition(*cam), {0.0f, 1.0f, 5.0f});
  EXPECT_FLOAT_EQ(cam->yfov, 0.6f);  // the file's lens
  EXPECT_FLOAT_EQ(cam->znear, 0.1f);
  EXPECT_FLOAT_EQ(cam->zfar, 50.0f);

  c.set_yfov(1.0f);  // an explicit field overrides the file's
  cam = ResolveCamera(c, scene, 1.0f);
  ASSERT_TRUE(cam.ok()) << cam.status();
  EXPECT_FLOAT_EQ(cam->yfov, 1.0f);
  EXPECT_FLOAT_EQ(cam->znear, 0.1f);
}

TEST(ResolveCameraTest, SceneCameraOutOfRange) {
  v1::Camera c;
  c.set_scene_camera(1);
  EXPECT_TRUE(IsError(ResolveCamera(c, TestScene(), 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.scene_camera", "1"}));
  c.set_scene_camera(0);
  SceneInfo no_cameras = TestScene();
  no_cameras.cameras.clear();
  EXPECT_TRUE(IsError(ResolveCamera(c, no_cameras, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.scene_camera"}));
}

TEST(ResolveCameraTest, UnsetPlacementFramesTheBounds) {
  const SceneInfo scene = TestScene();
  const float aspect = 16.0f / 9.0f;
  absl::StatusOr<Camera> cam = ResolveCamera(v1::Camera{}, scene, aspect);
  ASSERT_TRUE(cam.ok()) << cam.status();
  EXPECT_FALSE(cam->view.has_value());
  ExpectNear(cam->target, scene.bounds.center());
  EXPECT_FALSE(Inside(scene.bounds, cam->eye));
  // From the documented default direction.
  ExpectNear(glm::normalize(cam->eye - cam->target),
             glm::normalize(glm::vec3(0.55f, 0.45f, 0.70f)));
  // Every corner of the box is in front of the camera and inside the picture.
  const glm::mat4 view_proj = ProjectionMatrix(*cam, aspect) * ViewMatrix(*cam);
  for (int i = 0; i < 8; ++i) {
    const glm::vec3 corner(i & 1 ? scene.bounds.max.x : scene.bounds.min.x,
                           i & 2 ? scene.bounds.max.y : scene.bounds.min.y,
                           i & 4 ? scene.bounds.max.z : scene.bounds.min.z);
    const glm::vec4 clip = view_proj * glm::vec4(corner, 1.0f);
    ASSERT_GT(clip.w, 0.0f) << "corner " << i;
    EXPECT_LE(std::abs(clip.x / clip.w), 1.0f + 1e-4f) << "corner " << i;
    EXPECT_LE(std::abs(clip.y / clip.w), 1.0f + 1e-4f) << "corner " << i;
    EXPECT_LE(clip.z / clip.w, 1.0f) << "corner " << i << " is in front of the near plane";
  }
}

TEST(ResolveCameraTest, FrameDirection) {
  const SceneInfo scene = TestScene();
  v1::Camera c;
  SetVec(c.mutable_frame()->mutable_direction(), 0.0f, 0.0f, 2.0f);
  absl::StatusOr<Camera> cam = ResolveCamera(c, scene, 1.0f);
  ASSERT_TRUE(cam.ok()) << cam.status();
  const glm::vec3 center = scene.bounds.center();
  EXPECT_NEAR(cam->eye.x, center.x, 1e-4f);
  EXPECT_NEAR(cam->eye.y, center.y, 1e-4f);
  EXPECT_GT(cam->eye.z, scene.bounds.max.z);

  SetVec(c.mutable_frame()->mutable_direction(), 0.0f, 0.0f, 0.0f);
  EXPECT_TRUE(IsError(ResolveCamera(c, scene, 1.0f).status(), absl::StatusCode::kInvalidArgument,
                      {"camera.frame.direction"}));
  SetVec(c.mutable_frame()->mutable_direction(), kNan, 0.0f, 1.0f);
  EXPECT_TRUE(IsError(ResolveCamera(c, scene, 1.0f).status(), absl::StatusCode::kInvalidArgument,
                      {"camera.frame.direction"}));
}

TEST(ResolveCameraTest, ExplicitLensOverrides) {
  const SceneInfo scene = TestScene();
  v1::Camera c = LookAt({0, 0, 10}, {0, 0, 0});
  c.set_yfov(0.5f);
  c.set_znear(0.25f);
  c.set_zfar(100.0f);
  absl::StatusOr<Camera> cam = ResolveCamera(c, scene, 1.0f);
  ASSERT_TRUE(cam.ok()) << cam.status();
  EXPECT_FLOAT_EQ(cam->yfov, 0.5f);
  EXPECT_FLOAT_EQ(cam->znear, 0.25f);
  EXPECT_FLOAT_EQ(cam->zfar, 100.0f);

  // Framing uses the explicit field of view: narrower means farther away.
  absl::StatusOr<Camera> wide = ResolveCamera(v1::Camera{}, scene, 1.0f);
  v1::Camera narrow_request;
  narrow_request.set_yfov(0.4f);
  narrow_request.set_znear(0.3f);
  narrow_request.set_zfar(1000.0f);
  absl::StatusOr<Camera> narrow = ResolveCamera(narrow_request, scene, 1.0f);
  ASSERT_TRUE(wide.ok()) << wide.status();
  ASSERT_TRUE(narrow.ok()) << narrow.status();
  EXPECT_FLOAT_EQ(narrow->yfov, 0.4f);
  EXPECT_FLOAT_EQ(narrow->znear, 0.3f);
  EXPECT_FLOAT_EQ(narrow->zfar, 1000.0f);
  EXPECT_GT(glm::length(narrow->eye - narrow->target), glm::length(wide->eye - wide->target));
}

TEST(ResolveCameraTest, LensErrorsNameTheField) {
  const SceneInfo scene = TestScene();
  v1::Camera c = LookAt({0, 0, 10}, {0, 0, 0});
  c.set_yfov(3.2f);
  EXPECT_TRUE(IsError(ResolveCamera(c, scene, 1.0f).status(), absl::StatusCode::kInvalidArgument,
                      {"camera.yfov"}));
  v1::Camera framed;
  framed.set_yfov(kNan);
  EXPECT_TRUE(IsError(ResolveCamera(framed, scene, 1.0f).status(),
                      absl::StatusCode::kInvalidArgument, {"camera.yfov"}));
  c = LookAt({0, 0, 10}, {0, 0, 0});
  c.set_znear(0.0f);
  EXPECT_TRUE(IsError(ResolveCamera(c, scene, 1.0f).status(), absl::StatusCode::kInvalidArgument,
                      {"camera.znear"}));
  c = LookAt({0, 0, 10}, {0, 0, 0});
  c.set_znear(1.0f);
  c.set_zfar(0.5f);
  EXPECT_TRUE(IsError(ResolveCamera(c, scene, 1.0f).status(), absl::StatusCode::kInvalidArgument,
                      {"camera.zfar"}));
}

// ---------------------------------------------------------------------------------------------
// SceneStore. Handles are null: the store only keeps them, it never looks inside.

std::string IdOf(const std::string& prefix, char fill) {
  return prefix + std::string(64 - prefix.size(), fill);
}

StoredSceneInfo Info(const std::string& name) {
  StoredSceneInfo info;
  info.scene.name = name;
  return info;
}

TEST(SceneStoreTest, FindByIdAndUniquePrefix) {
  SceneStore store(8);
  store.AddDemo(nullptr, Info("demo"));
  const std::string a = IdOf("abcdef01", '0');
  const std::string b = IdOf("abcdef01", '1');
  const std::string c = IdOf("12345678", 'f');
  absl::StatusOr<std::shared_ptr<StoredScene>> added = store.Add(a, nullptr, Info("a.gltf"));
  ASSERT_TRUE(added.ok()) << added.status();
  EXPECT_EQ((*added)->id, a);
  EXPECT_EQ((*added)->id, a);
  EXPECT_EQ((*added)->info.scene.name, "a.gltf");
  ASSERT_TRUE(store.Add(b, nullptr, Info("b.gltf")).ok());
  ASSERT_TRUE(store.Add(c, nullptr, Info("c.gltf")).ok());

  absl::StatusOr<std::shared_ptr<StoredScene>> found = store.Find(a);
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ(*found, *added);
  found = store.Find("12345678");  // a unique 8-character prefix
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ((*found)->id, c);
  found = store.Find("abcdef011");  // a longer prefix tells a from b
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ((*found)->id, b);
  found = store.Find("demo");
  ASSERT_TRUE(found.ok()) << found.status();
  EXPECT_EQ((*found)->id, "demo");
  EXPECT_EQ((*found)->id, "demo");
  EXPECT_EQ(store.FindExact(c)->id, c);
  EXPECT_EQ(store.FindExact("12345678"), nullptr);  // exact means exact
}

TEST(SceneStoreTest, AmbiguousShortUnknownAndEmptyIds) {
  SceneStore store(8);
  ASSERT_TRUE(store.Add(IdOf("abcdef01", '0'), nullptr, Info("a")).ok());
  ASSERT_TRUE(store.Add(IdOf("abcdef01", '1'), nullptr, Info("b")).ok());
  ASSERT_TRUE(store.Add(IdOf("12345678", 'f'), nullptr, Info("c")).ok());
  EXPECT_TRUE(IsError(store.Find("abcdef01").status(), absl::StatusCode::kInvalidArgument,
                      {"scene_id", "abcdef01", "more than one"}));
  // Shorter than 8 characters: not a prefix, even when unique.
  EXPECT_TRUE(IsError(store.Find("1234567").status(), absl::StatusCode::kNotFound,
                      {"scene_id", "1234567", "at least 8 characters"}));
  EXPECT_TRUE(IsError(store.Find(IdOf("ffff", 'f')).status(), absl::StatusCode::kNotFound,
                      {"scene_id", "ffff"}));
  EXPECT_TRUE(IsError(store.Find("123456789").status(), absl::StatusCode::kNotFound, {"scene_id"}));
  EXPECT_TRUE(IsError(store.Find("").status(), absl::StatusCode::kInvalidArgument, {"scene_id"}));
  EXPECT_TRUE(IsError(store.Find("demo").status(), absl::StatusCode::kNotFound, {"demo"}));
}

TEST(SceneStoreTest, AddingTheSameIdReturnsTheStoredEntry) {
  SceneStore store(1);
  const std::string id = IdOf("", 'a');
  absl::StatusOr<std::shared_ptr<StoredScene>> first = store.Add(id, nullptr, Info("first"));
  ASSERT_TRUE(first.ok()) << first.status();
  EXPECT_EQ(store.count(), 1u);
  // Even at the limit: same content is no new scene.
  absl::StatusOr<std::shared_ptr<StoredScene>> second = store.Add(id, nullptr, Info("second"));
  ASSERT_TRUE(second.ok()) << second.status();
  EXPECT_EQ(*second, *first);
  EXPECT_EQ((*second)->info.scene.name, "first");
  EXPECT_EQ(store.count(), 1u);
  EXPECT_EQ(store.List().size(), 1u);
}

TEST(SceneStoreTest, MaxScenesEvictsTheLeastRecentlyUsedUnusedScene) {
  SceneStore store(2);
  std::vector<std::string> evicted;
  store.set_eviction_listener([&](const StoredScene& s) { evicted.push_back(s.id); });
  store.AddDemo(nullptr, Info("demo"));  // not counted against the limit, never evicted
  ASSERT_TRUE(store.CheckRoom().ok());
  ASSERT_TRUE(store.Add(IdOf("", '1'), nullptr, Info("1")).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  ASSERT_TRUE(store.Add(IdOf("", '2'), nullptr, Info("2")).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  ASSERT_TRUE(store.Find(IdOf("", '1')).ok());  // 1 is now the more recently used
  EXPECT_TRUE(store.CheckRoom().ok());           // 2 could be evicted
  ASSERT_TRUE(store.Add(IdOf("", '3'), nullptr, Info("3")).ok());
  EXPECT_EQ(evicted, std::vector<std::string>{IdOf("", '2')});
  EXPECT_EQ(store.evictions(), 1u);
  EXPECT_EQ(store.Find(IdOf("", '2')).status().code(), absl::StatusCode::kNotFound);
  EXPECT_TRUE(store.Find(IdOf("", '1')).ok());
  EXPECT_EQ(store.count(), 3u);  // demo, 1, 3
}

TEST(SceneStoreTest, MaxScenesRefusesWhenEverySceneIsInUse) {
  SceneStore store(2);
  store.AddDemo(nullptr, Info("demo"));
  auto one = store.Add(IdOf("", '1'), nullptr, Info("1"));
  auto two = store.Add(IdOf("", '2'), nullptr, Info("2"));
  ASSERT_TRUE(one.ok() && two.ok());
  {
    SceneLease l1(*one), l2(*two);
    EXPECT_TRUE(
        IsError(store.CheckRoom(), absl::StatusCode::kResourceExhausted, {"max_scenes", "2"}));
    EXPECT_TRUE(IsError(store.Add(IdOf("", '3'), nullptr, Info("3")).status(),
                        absl::StatusCode::kResourceExhausted, {"max_scenes", "2", "in use"}));
    EXPECT_EQ(store.count(), 3u);
    EXPECT_EQ(store.Find(IdOf("", '3')).status().code(), absl::StatusCode::kNotFound);
    // Deleting one makes room again (it is freed when its lease ends).
    absl::StatusOr<uint32_t> deleted = store.Delete(IdOf("", '1'));
    ASSERT_TRUE(deleted.ok()) << deleted.status();
    EXPECT_EQ(*deleted, 1u);
  }
  one->reset();  // the deleted scene's last holder: now it is freed
  two->reset();
  EXPECT_TRUE(store.CheckRoom().ok());
  EXPECT_TRUE(store.Add(IdOf("", '3'), nullptr, Info("3")).ok());
  EXPECT_EQ(store.evictions(), 0u);
}

StoredSceneInfo Sized(const std::string& name, uint64_t bytes) {
  StoredSceneInfo info = Info(name);
  info.scene.device_bytes = bytes;
  return info;
}

TEST(SceneStoreTest, MemoryBudgetEvictsUnusedScenesLeastRecentlyUsedFirst) {
  SceneStore store(16, /*memory_budget=*/1000);
  store.AddDemo(nullptr, Sized("demo", 50));  // outside the budget
  auto a = store.Add(IdOf("", 'a'), nullptr, Sized("a", 400));
  std::this_thread::sleep_for(std::chrono::milliseconds(2));
  auto b = store.Add(IdOf("", 'b'), nullptr, Sized("b", 400));
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(store.device_bytes(), 850u);
  std::optional<SceneLease> hold_a(std::in_place, *a);  // a is in use: b must go instead
  a->reset();
  // Held by someone between a Find and its lease: not evictable either.
  EXPECT_TRUE(IsError(store.Add(IdOf("", 'x'), nullptr, Sized("x", 500)).status(),
                      absl::StatusCode::kResourceExhausted, {"scene_memory_budget"}));
  b->reset();
  auto c = store.Add(IdOf("", 'c'), nullptr, Sized("c", 500));
  ASSERT_TRUE(c.ok()) << c.status();
  EXPECT_EQ(store.Find(IdOf("", 'b')).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store.device_bytes(), 950u);
  // a (in use) + c (in use) leave no room for 300 more.
  std::optional<SceneLease> hold_c(std::in_place, *c);
  c->reset();
  EXPECT_TRUE(IsError(store.Add(IdOf("", 'd'), nullptr, Sized("d", 300)).status(),
                      absl::StatusCode::kResourceExhausted, {"scene_memory_budget", "1000"}));
  // Larger than the whole budget: refused without evicting anything.
  hold_c.reset();
  EXPECT_TRUE(IsError(store.Add(IdOf("", 'e'), nullptr, Sized("e", 1001)).status(),
                      absl::StatusCode::kResourceExhausted, {"scene_memory_budget", "1001"}));
  EXPECT_TRUE(store.Find(IdOf("", 'c')).ok());
  // With c released, d fits after evicting c.
  ASSERT_TRUE(store.Add(IdOf("", 'd'), nullptr, Sized("d", 300)).ok());
  EXPECT_EQ(store.Find(IdOf("", 'c')).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store.evictions(), 2u);
}

TEST(SceneStoreTest, ListIsDemoThenLoadOrder) {
  SceneStore store(8);
  store.AddDemo(nullptr, Info("demo"));
  ASSERT_TRUE(store.Add(IdOf("", 'f'), nullptr, Info("f")).ok());
  ASSERT_TRUE(store.Add(IdOf("", '0'), nullptr, Info("0")).ok());
  ASSERT_TRUE(store.Add(IdOf("", '8'), nullptr, Info("8")).ok());
  const std::vector<SceneListing> list = store.List();
  ASSERT_EQ(list.size(), 4u);
  EXPECT_EQ(list[0].id, "demo");
  EXPECT_EQ(list[1].info.scene.name, "f");
  EXPECT_EQ(list[2].info.scene.name, "0");
  EXPECT_EQ(list[3].info.scene.name, "8");
  for (const SceneListing& info : list) {
    EXPECT_EQ(info.sessions, 0u);
    EXPECT_FALSE(info.deleted);
  }
}

TEST(SceneStoreTest, DemoCannotBeDeleted) {
  SceneStore store(8);
  store.AddDemo(nullptr, Info("demo"));
  EXPECT_TRUE(IsError(store.Delete("demo").status(), absl::StatusCode::kFailedPrecondition,
                      {"scene_id", "demo"}));
  EXPECT_TRUE(store.Find("demo").ok());
  EXPECT_TRUE(
      IsError(store.Delete(IdOf("", 'a')).status(), absl::StatusCode::kNotFound, {"scene_id"}));
}

TEST(SceneStoreTest, DeleteWithoutSessionsFreesAtOnce) {
  SceneStore store(8);
  store.AddDemo(nullptr, Info("demo"));
  const std::string id = IdOf("0123abcd", '5');
  std::weak_ptr<StoredScene> weak;
  {
    absl::StatusOr<std::shared_ptr<StoredScene>> added = store.Add(id, nullptr, Info("x"));
    ASSERT_TRUE(added.ok()) << added.status();
    weak = *added;
  }
  EXPECT_EQ(store.count(), 2u);
  absl::StatusOr<uint32_t> users = store.Delete("0123abcd");  // by prefix
  ASSERT_TRUE(users.ok()) << users.status();
  EXPECT_EQ(*users, 0u);
  EXPECT_TRUE(weak.expired());
  EXPECT_EQ(store.count(), 1u);
  EXPECT_EQ(store.List().size(), 1u);
  EXPECT_TRUE(IsError(store.Find(id).status(), absl::StatusCode::kNotFound, {"scene_id"}));
  EXPECT_TRUE(IsError(store.Delete(id).status(), absl::StatusCode::kNotFound, {"scene_id"}));
}

TEST(SceneStoreTest, DeleteWhileLeasedKeepsTheSceneUntilTheLeaseEnds) {
  SceneStore store(8);
  store.AddDemo(nullptr, Info("demo"));
  const std::string id = IdOf("0123abcd", '5');
  ASSERT_TRUE(store.Add(id, nullptr, Info("x")).ok());
  std::unique_ptr<SceneLease> lease;
  {
    absl::StatusOr<std::shared_ptr<StoredScene>> found = store.Find(id);
    ASSERT_TRUE(found.ok()) << found.status();
    lease = std::make_unique<SceneLease>(*found);
  }
  EXPECT_EQ(lease->get().sessions.load(), 1u);
  {
    const SceneListing live = SceneStore::Describe(lease->get());
    EXPECT_EQ(live.sessions, 1u);
    EXPECT_FALSE(live.deleted);
  }

  absl::StatusOr<uint32_t> users = store.Delete(id);
  ASSERT_TRUE(users.ok()) << users.status();
  EXPECT_EQ(*users, 1u);
  EXPECT_TRUE(lease->get().deleted.load());
  // New requests cannot name it...
  EXPECT_TRUE(IsError(store.Find(id).status(), absl::StatusCode::kNotFound, {"scene_id"}));
  EXPECT_TRUE(IsError(store.Find("0123abcd").status(), absl::StatusCode::kNotFound, {"scene_id"}));
  EXPECT_EQ(store.FindExact(id), nullptr);
  // ...but it is still in memory, listed as deleted with its session.
  EXPECT_EQ(store.count(), 2u);
  std::vector<SceneListing> list = store.List();
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[1].id, id);
  EXPECT_TRUE(list[1].deleted);
  EXPECT_EQ(list[1].sessions, 1u);

  // Uploading the same content again makes a new, separate entry.
  absl::StatusOr<std::shared_ptr<StoredScene>> again = store.Add(id, nullptr, Info("again"));
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_NE(again->get(), &lease->get());
  EXPECT_FALSE((*again)->deleted.load());
  EXPECT_EQ(store.count(), 3u);
  ASSERT_TRUE(store.Delete(id).ok());
  again = absl::NotFoundError("released");
  EXPECT_EQ(store.count(), 2u);

  lease.reset();  // the last session ends
  EXPECT_EQ(store.count(), 1u);
  list = store.List();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].id, "demo");
}

}  // namespace
}  // namespace tessera::server

namespace tessera::server {
namespace {

// GetServerInfo reports every import limit: each ImportLimitField has a proto field of the
// same name that carries its value.
TEST(ImportLimitsProto, EveryLimitHasItsFieldAndValue) {
  ImportLimits limits;
  uint64_t next = 1000;
  for (const ImportLimitField& f : ImportLimitFields()) {
    ASSERT_EQ(ParseImportLimits(absl::StrCat(f.name, "=", ++next), &limits), "") << f.name;
  }
  v1::ImportLimits proto;
  ImportLimitsToProto(limits, &proto);
  const google::protobuf::Descriptor* d = proto.GetDescriptor();
  const google::protobuf::Reflection* r = proto.GetReflection();
  EXPECT_EQ(size_t(d->field_count()), ImportLimitFields().size());
  for (const ImportLimitField& f : ImportLimitFields()) {
    const google::protobuf::FieldDescriptor* field = d->FindFieldByName(f.name);
    ASSERT_NE(field, nullptr) << f.name << " is missing from tessera.v1.ImportLimits";
    EXPECT_EQ(field->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_UINT64, f.is_64bit)
        << f.name << ": the proto field and the limit differ in width";
    const uint64_t value = field->cpp_type() == google::protobuf::FieldDescriptor::CPPTYPE_UINT64
                               ? r->GetUInt64(proto, field)
                               : r->GetUInt32(proto, field);
    EXPECT_EQ(value, f.Get(limits)) << f.name;
  }
}

// The render loop's frame and the store's scenes are plain structs; the handlers make the wire's
// messages of them, every field where the client finds it.
TEST(WireConversion, EncodedFrameBecomesTheWireFrame) {
  EncodedFrame f;
  f.frame.image.width = 64;  // the encoded size: the pixels are gone
  f.frame.image.height = 48;
  f.frame.passes = {{"depth_prepass", 1.5, 1.25}, {"forward", 2.5, 2.0}};
  f.frame.gpu_total_ms = 4.0;
  f.frame.cpu.encode_ms = 3.0;
  f.frame.cpu.submissions = 1;  // the frame in one submission, on a CPU device (pass_timing off)
  f.frame.timing = TimingSource::kFrameWallClock;
  f.frame.stats.draws = 11;
  // The visibility shading's counts, and which way it ran.
  f.frame.stats.shaded_pixels = 1500;
  f.frame.stats.shading_invocations = 1536;
  f.frame.stats.shading_dispatches = 2;
  f.frame.stats.edge_pixels = 40;
  f.frame.stats.blend_pixels = 30;
  f.frame.stats.runner_up_pixels = 20;
  f.data = {1, 2, 3};
  f.format = ImageFormat::kPng;
  f.render_width = 32;
  f.render_height = 24;
  f.camera.eye = {1.0f, 2.0f, 3.0f};
  f.sequence = 7;
  f.event_id = 5;
  f.scene_id = "demo";
  f.profile = "interactive";
  f.queue_wait_ms = 0.5;
  f.total_ms = 9.0;
  v1::Frame wire;
  ToProto(f, &wire);
  EXPECT_EQ(wire.width(), 64u);
  EXPECT_EQ(wire.height(), 48u);
  EXPECT_EQ(wire.render_width(), 32u);
  EXPECT_EQ(wire.render_height(), 24u);
  ASSERT_EQ(wire.passes_size(), 2);
  EXPECT_EQ(wire.passes(1).pass(), "forward");
  EXPECT_EQ(wire.passes(1).gpu_ms(), 2.5);
  EXPECT_EQ(wire.gpu_total_ms(), 4.0);
  EXPECT_EQ(wire.cpu().encode_ms(), 3.0);
  EXPECT_EQ(wire.cpu().queue_wait_ms(), 0.5);
  EXPECT_EQ(wire.cpu().total_ms(), 9.0);
  EXPECT_EQ(wire.cpu().submissions(), 1u);
  EXPECT_EQ(wire.timing_source(), v1::TIMING_FRAME_WALL_CLOCK);
  EXPECT_EQ(wire.stats().draws(), 11u);
  EXPECT_EQ(wire.stats().shaded_pixels(), 1500u);
  EXPECT_EQ(wire.stats().shading_invocations(), 1536u);
  EXPECT_EQ(wire.stats().shading_dispatches(), 2u);
  EXPECT_EQ(wire.stats().edge_pixels(), 40u);
  EXPECT_EQ(wire.stats().blend_pixels(), 30u);
  EXPECT_EQ(wire.stats().runner_up_pixels(), 20u);
  EXPECT_EQ(wire.camera().eye().y(), 2.0f);
  EXPECT_EQ(wire.sequence(), 7u);
  EXPECT_EQ(wire.event_id(), 5u);
  EXPECT_EQ(wire.scene_id(), "demo");
  EXPECT_EQ(wire.profile(), "interactive");
  EXPECT_EQ(wire.encoding(), v1::IMAGE_PNG);
  EXPECT_EQ(wire.data(), std::string("\x01\x02\x03", 3));
  // Jobs take the metadata and write the bytes to files.
  v1::Frame meta;
  FrameMetaToProto(f, &meta);
  EXPECT_TRUE(meta.data().empty());
  meta.set_data(wire.data());
  EXPECT_EQ(meta.SerializeAsString(), wire.SerializeAsString());
}

TEST(WireConversion, StoredSceneBecomesTheWireSceneInfo) {
  SceneListing scene;
  scene.id = std::string(64, 'a');
  scene.info.scene.name = "box.gltf";
  scene.info.scene.counts.triangles = 12;
  scene.info.scene.warnings = {"no lights"};
  scene.info.scene.device_bytes = 4096;
  scene.info.upload_bytes = 1000;
  scene.info.load_ms = 12.5;
  scene.sessions = 2;
  scene.deleted = true;
  v1::SceneInfo wire;
  ToProto(scene, &wire);
  EXPECT_EQ(wire.scene_id(), scene.id);
  EXPECT_EQ(wire.name(), "box.gltf");
  EXPECT_EQ(wire.counts().triangles(), 12u);
  ASSERT_EQ(wire.warnings_size(), 1);
  EXPECT_EQ(wire.warnings(0), "no lights");
  EXPECT_EQ(wire.device_bytes(), 4096u);
  EXPECT_EQ(wire.upload_bytes(), 1000u);
  EXPECT_EQ(wire.load_ms(), 12.5);
  EXPECT_EQ(wire.sessions(), 2u);
  EXPECT_TRUE(wire.deleted());
}

}  // namespace
}  // namespace tessera::server

// tessera-soak: one tesserad under mixed clients for a long time, watched for growth and for
// errors a healthy server should not give (issue 11, "Soak"). Not part of CI.
//
// It starts one tesserad (--tesserad) on 127.0.0.1:0 with small limits, then --clients worker
// threads, each on a connection of its own (made anew now and then), drawing actions from an RNG
// seeded with --seed until --duration is up:
//   upload_valid      Box (.gltf + .bin), BoxTextured.glb, OrientationTest.glb, 1 in 20
//                     DamagedHelmet.glb (3.7 MB): parsed the first time, "already loaded" after;
//   upload_malformed  a truncated GLB, JSON garbage, a .gltf without its buffer, a chunk for a
//                     file not in the manifest (INVALID_ARGUMENT), a PNG texture claiming
//                     100000x100000 (that or RESOURCE_EXHAUSTED), a wrong sha256 (DATA_LOSS), a
//                     manifest with too many files or bytes (RESOURCE_EXHAUSTED);
//   scene_lifecycle   a .gltf never seen before (Box or BoxTextured with a counter in its root
//                     "extras"): uploaded, rendered once, deleted, so scene memory comes and goes;
//   render            Render of demo or an uploaded model at 160x120..320x240, aa, samples and
//                     culling from GetServerInfo's choices, JPEG or PNG; 1 in 10 of an unknown
//                     scene (NOT_FOUND);
//   stream            a session that reads 1..10 frames with a camera event after each (half of
//                     them with a settings change too: size, aa, culling, JPEG quality), then
//                     half-closes (OK), cancels (CANCELLED; the server parks the session),
//                     cancels and resumes by token (stream_resume), or vanishes: the call is
//                     destroyed without Finish;
//   info              GetServerInfo or ListScenes.
// Each call has a deadline, and its end is counted under its action as ok, an expected error
// (what its bad input should get, or RESOURCE_EXHAUSTED naming a load limit — uploads at once,
// the render queue — the server shedding load as designed) or an unexpected one: any other code,
// DEADLINE_EXCEEDED and UNAVAILABLE included, OK for a bad input, or a wrong answer (BAD_ANSWER).
//
// The main thread samples the daemon every --sample-every seconds: VmRSS and Threads from
// /proc/PID/status, the entries of /proc/PID/fd, GetServerInfo's device memory (all the daemon
// holds, and the scenes' share) and sessions. Samples before --warmup are the warm-up. At the end
// the workers stop, a last sample is taken, tesserad gets SIGTERM and must exit with status 0.
//
// Verdict: flat when, from just after the warm-up to the end, RSS grew by at most 5 %, device
// memory by at most 5 % or 16 MiB, and FDs and threads by at most 2; pass when flat (not needed
// with --smoke), without unexpected errors, and with a clean exit. Prints one JSON document on
// stdout (also to --out), a line per sample and a one-line summary on stderr. Exit status 0 for
// a pass, 1 for a failed verdict, 2 for bad flags or a soak that could not start.
//
//   ./build/default/tests/tessera-soak --tesserad ./build/default/server/tesserad
//   ./build/default/tests/tessera-soak --tesserad ./build/default/server/tesserad --smoke

#include <errno.h>  // program_invocation_short_name
#include <grpcpp/grpcpp.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <random>
#include <stop_token>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "bench_stream.h"
#include "bench_util.h"
#include "process_util.h"
#include "renderer/scene/gltf_import.h"
#include "common/scene_id.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace {

using nlohmann::json;
using namespace tessera::bench;  // bench_util.h, bench_stream.h, process_util.h

namespace v1 = tessera::v1;
namespace fs = std::filesystem;
using tessera::GltfSource;
using Code = grpc::StatusCode;
using StreamRW = grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>;

// Far beyond what a call takes on lavapipe under this load: DEADLINE_EXCEEDED means a hung call.
constexpr auto kUnaryDeadline = std::chrono::seconds(30);
constexpr auto kLongDeadline = std::chrono::seconds(60);  // uploads (a parse), streams

constexpr double kMaxGrowthPct = 5.0;    // RSS and device memory
constexpr double kDeviceSlackMb = 16.0;  // device memory: parked sessions' targets come and go
constexpr double kCountSlack = 2.0;      // FDs and threads
// "After the warm-up" is the median of the first kEdgeSamples samples from --warmup on, "the
// end" the median of the last kEdgeSamples: a momentary peak at either edge (a scene being
// parsed, a burst of sessions) does not decide the verdict.
constexpr size_t kEdgeSamples = 3;
constexpr size_t kExamplesKept = 10;

// The daemon's upload limits here: small, so the malformed manifests stay small too.
constexpr uint64_t kMaxUploadBytes = 64ull << 20;
constexpr uint32_t kMaxUploadFiles = 64;
const std::string kUnknownScene(64, '0');  // a content hash no upload has

constexpr char kUsage[] =
    "usage: tessera-soak --tesserad PATH [--duration S] [--warmup S] [--sample-every S]\n"
    "         [--clients N] [--seed N] [--assets DIR] [--device NAME] [--out FILE] [--smoke]\n"
    "         [--aa MODE]   (every render and stream uses this AA mode instead of a random one)\n";

[[noreturn]] void UsageError(const std::string& msg) {
  std::fprintf(stderr, "%s: %s\n%s", program_invocation_short_name, msg.c_str(), kUsage);
  std::exit(2);
}

std::chrono::system_clock::time_point DeadlineIn(std::chrono::seconds s) {
  return std::chrono::system_clock::now() + s;
}

double Mib(uint64_t bytes) { return double(bytes) / double(1 << 20); }

std::shared_ptr<grpc::Channel> NewChannel(const std::string& address) {
  grpc::ChannelArguments args;
  args.SetMaxReceiveMessageSize(64 << 20);
  // A connection of its own: channels to one address would otherwise share one.
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel(address, grpc::InsecureChannelCredentials(), args);
}

struct Options {
  std::string tesserad, assets, device, out;
  std::string aa;  // empty: each render and settings change picks an AA mode at random
  double duration_s = 600.0;
  double warmup_s = 60.0;
  double sample_every_s = 5.0;
  uint32_t clients = 6;
  uint64_t seed = 1;
  bool smoke = false;
};

// --- outcomes ------------------------------------------------------------------------------

// clang-format off
enum class Action { kUploadValid, kUploadMalformed, kSceneLifecycle, kRender, kStream,
                    kStreamResume, kInfo, kSample /* the sampler's GetServerInfo */ };
constexpr std::array<const char*, 8> kActionNames = {"upload_valid", "upload_malformed",
    "scene_lifecycle", "render", "stream", "stream_resume", "info", "sample"};
// clang-format on

std::string CodeName(Code code) {
  return absl::StatusCodeToString(static_cast<absl::StatusCode>(code));
}

// RESOURCE_EXHAUSTED for a load limit, not for the request: the server shedding load.
bool LoadShed(const grpc::Status& st) {
  return st.error_code() == Code::RESOURCE_EXHAUSTED &&
         (absl::StrContains(st.error_message(), "max_concurrent_uploads") ||
          absl::StrContains(st.error_message(), "render queue"));
}

// How every call ended, per action; shared by the workers and the sampler.
class Tally {
 public:
  // A call that should end with `success` (or be shed); anything else is unexpected.
  void Judge(Action a, const std::string& what, const grpc::Status& st, Code success = Code::OK) {
    if (st.error_code() == success) return Ok(a);
    if (LoadShed(st)) return Expected(a, st.error_code());
    Unexpected(a, CodeName(st.error_code()), absl::StrCat(what, ": ", st.error_message()));
  }
  // A bad input, which should be refused with one of `codes` (or shed); OK is unexpected.
  void JudgeRefusal(Action a, const std::string& what, const grpc::Status& st,
                    std::initializer_list<Code> codes) {
    if (std::find(codes.begin(), codes.end(), st.error_code()) != codes.end() || LoadShed(st))
      return Expected(a, st.error_code());
    Unexpected(a, CodeName(st.error_code()),
               absl::StrCat(what, ": ", st.ok() ? "accepted" : st.error_message()));
  }
  void Ok(Action a) {
    std::lock_guard lock(mu_);
    ++calls_;
    ++counts_[size_t(a)].ok;
  }
  void Expected(Action a, Code code) {
    std::lock_guard lock(mu_);
    ++calls_;
    ++counts_[size_t(a)].expected[CodeName(code)];
  }
  void Unexpected(Action a, const std::string& code, const std::string& message) {
    std::lock_guard lock(mu_);
    ++calls_;
    ++unexpected_;
    ++counts_[size_t(a)].unexpected[code];
    if (examples_.size() < kExamplesKept)
      examples_.push_back(absl::StrCat(kActionNames[size_t(a)], ": ", code, ": ", message));
  }

  uint64_t calls() const {
    std::lock_guard lock(mu_);
    return calls_;
  }
  uint64_t unexpected() const {
    std::lock_guard lock(mu_);
    return unexpected_;
  }
  std::vector<std::string> examples() const {
    std::lock_guard lock(mu_);
    return examples_;
  }
  json Json() const {
    std::lock_guard lock(mu_);
    json out = json::object();
    for (size_t i = 0; i < counts_.size(); ++i)
      out[kActionNames[i]] = {{"ok", counts_[i].ok},
                              {"expected_errors", counts_[i].expected},
                              {"unexpected_errors", counts_[i].unexpected}};
    return out;
  }

 private:
  struct Counts {
    uint64_t ok = 0;
    std::map<std::string, uint64_t> expected, unexpected;  // by code name
  };
  mutable std::mutex mu_;
  std::array<Counts, kActionNames.size()> counts_;
  uint64_t calls_ = 0, unexpected_ = 0;
  std::vector<std::string> examples_;  // the first kExamplesKept unexpected errors
};

// --- what the workers send -----------------------------------------------------------------

// The files the workers upload, read before the run.
struct Inputs {
  std::vector<GltfSource> models;  // upload_valid's; the last one is the big one
  GltfSource box;                  // Box.gltf + Box0.bin
  GltfSource textured;             // BoxTextured.gltf + .bin + .png
  GltfSource textured_glb;         // what upload_malformed truncates
};

absl::StatusOr<Inputs> ReadInputs(const std::string& assets) {
  std::vector<GltfSource> read;
  for (const char* rel :
       {"Box/glTF/Box.gltf", "BoxTextured/glTF-Binary/BoxTextured.glb",
        "OrientationTest/glTF-Binary/OrientationTest.glb",
        "DamagedHelmet/glTF-Binary/DamagedHelmet.glb", "BoxTextured/glTF/BoxTextured.gltf"}) {
    absl::StatusOr<GltfSource> src = tessera::LoadGltfSourceFromDisk(assets + "/" + rel);
    if (!src.ok())
      return absl::Status(src.status().code(), absl::StrCat(assets, "/", rel, ": ",
                                                            src.status().message(), " (--assets)"));
    read.push_back(*std::move(src));
  }
  Inputs in;
  in.box = read[0];
  in.textured_glb = read[1];
  in.textured = read[4];
  in.models.assign(read.begin(), read.begin() + 4);
  return in;
}

uint32_t Crc32(const uint8_t* p, size_t n) {  // PNG's, bit by bit: a few bytes only
  uint32_t crc = 0xffffffffu;
  for (size_t i = 0; i < n; ++i) {
    crc ^= p[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xedb88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

// A PNG of a signature, an IHDR claiming `w` x `h` RGBA8 and an IEND: a decoder that trusted
// the header would allocate w * h * 4 bytes (40 GB for 100000 x 100000).
std::vector<uint8_t> PngHeaderOnly(uint32_t w, uint32_t h) {
  auto put32 = [](std::vector<uint8_t>* out, uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) out->push_back(uint8_t(v >> shift));
  };
  std::vector<uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  auto chunk = [&](const char* type, const std::vector<uint8_t>& data) {
    std::vector<uint8_t> body(type, type + 4);  // what the CRC covers: type and data
    body.insert(body.end(), data.begin(), data.end());
    put32(&png, uint32_t(data.size()));
    png.insert(png.end(), body.begin(), body.end());
    put32(&png, Crc32(body.data(), body.size()));
  };
  std::vector<uint8_t> ihdr;
  put32(&ihdr, w);
  put32(&ihdr, h);
  ihdr.insert(ihdr.end(), {8, 6, 0, 0, 0});  // 8 bits, RGBA, deflate, no filter, no interlace
  chunk("IHDR", ihdr);
  chunk("IEND", {});
  return png;
}

v1::UploadManifest ManifestOf(const GltfSource& src) {
  v1::UploadManifest m;
  m.set_main_file(src.main_file);
  for (const auto& [name, data] : src.files) {
    v1::UploadFile* f = m.add_files();
    f->set_name(name);
    f->set_size(data.size());
    f->set_sha256(tessera::Sha256Hex(data.data(), data.size()));
  }
  return m;
}

std::vector<v1::UploadChunk> ChunksOf(const GltfSource& src) {
  std::vector<v1::UploadChunk> chunks;
  uint32_t index = 0;  // in the manifest's order (the map's)
  for (const auto& [name, data] : src.files) {
    for (size_t offset = 0; offset < data.size(); offset += kChunkBytes) {
      v1::UploadChunk& c = chunks.emplace_back();
      c.set_file_index(index);
      c.set_offset(offset);
      c.set_data(data.data() + offset, std::min<size_t>(kChunkBytes, data.size() - offset));
    }
    ++index;
  }
  return chunks;
}

// One UploadScene call: the manifest, the chunks, the half-close. A server that refuses early
// ends the call; the writes then fail and Finish says why.
grpc::Status SendUpload(v1::RenderService::Stub* stub, const v1::UploadManifest& manifest,
                        const std::vector<v1::UploadChunk>& chunks, v1::SceneInfo* info) {
  grpc::ClientContext ctx;
  ctx.set_deadline(DeadlineIn(kLongDeadline));
  std::unique_ptr<grpc::ClientWriter<v1::UploadRequest>> writer = stub->UploadScene(&ctx, info);
  v1::UploadRequest request;
  *request.mutable_manifest() = manifest;
  bool ok = writer->Write(request);
  for (size_t i = 0; ok && i < chunks.size(); ++i) {
    *request.mutable_chunk() = chunks[i];
    ok = writer->Write(request);
  }
  if (ok) writer->WritesDone();
  return writer->Finish();
}

// The setting values GetServerInfo offers, as enums.
struct Choices {
  std::vector<v1::AaMode> aa;
  std::vector<uint32_t> samples;
  std::vector<v1::CullingMode> culling;
};

absl::StatusOr<Choices> ChoicesFrom(const v1::SettingChoices& c) {
  Choices out;
  // Names are the enum values' in lower case without the prefix: "msaa" is AA_MSAA.
  for (const std::string& name : c.aa())
    if (v1::AaMode m; v1::AaMode_Parse("AA_" + absl::AsciiStrToUpper(name), &m))
      out.aa.push_back(m);
  for (const std::string& name : c.culling())
    if (v1::CullingMode m; v1::CullingMode_Parse("CULLING_" + absl::AsciiStrToUpper(name), &m))
      out.culling.push_back(m);
  out.samples.assign(c.samples().begin(), c.samples().end());
  if (out.aa.empty() || out.culling.empty() || out.samples.empty())
    return absl::InternalError("GetServerInfo.choices: no aa, culling or samples value known");
  return out;
}

// The scenes the workers render and stream: demo and the models uploaded so far. None is ever
// deleted or evicted (max_scenes leaves room for them and every lifecycle scene), so NOT_FOUND
// for one is an unexpected error.
class SceneBoard {
 public:
  void Add(const std::string& id) {
    std::lock_guard lock(mu_);
    if (std::find(ids_.begin(), ids_.end(), id) == ids_.end()) ids_.push_back(id);
  }
  std::string Pick(std::mt19937_64& rng) const {
    std::lock_guard lock(mu_);
    return ids_[std::uniform_int_distribution<size_t>(0, ids_.size() - 1)(rng)];
  }

 private:
  mutable std::mutex mu_;
  std::vector<std::string> ids_ = {"demo"};
};

// What the workers share: set before they start, then read-only but for what locks itself.
struct Shared {
  std::string address;
  Inputs inputs;
  Choices choices;
  v1::Limits limits;
  Clock::time_point end;
  std::atomic<uint64_t> next_variant{0};  // scene_lifecycle's counter
  SceneBoard scenes;
  Tally tally;
};

// --- the workers ---------------------------------------------------------------------------

class Worker {
 public:
  Worker(Shared& shared, uint32_t index, uint64_t seed)
      : s_(shared), in_(shared.inputs), tally_(shared.tally) {
    std::seed_seq seq{uint32_t(seed), uint32_t(seed >> 32), index};
    rng_.seed(seq);
    Reconnect();
  }

  void Run(std::stop_token stop) {
    using Step = void (Worker::*)();
    static constexpr Step kSteps[] = {&Worker::UploadValid,    &Worker::UploadMalformed,
                                      &Worker::SceneLifecycle, &Worker::Render,
                                      &Worker::Stream,         &Worker::Info};
    std::discrete_distribution<size_t> pick({15, 15, 5, 25, 30, 10});  // kSteps' weights
    while (!stop.stop_requested() && Clock::now() < s_.end) {
      if (Chance(0.1)) Reconnect();  // connections come and go too
      (this->*kSteps[pick(rng_)])();
    }
  }

 private:
  int Uniform(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  bool Chance(double p) { return std::bernoulli_distribution(p)(rng_); }
  template <typename T>
  T Pick(const std::vector<T>& v) {
    return v[size_t(Uniform(0, int(v.size()) - 1))];
  }

  void Reconnect() { stub_ = v1::RenderService::NewStub(NewChannel(s_.address)); }

  grpc::Status Upload(const GltfSource& src, v1::SceneInfo* info) {
    return SendUpload(stub_.get(), ManifestOf(src), ChunksOf(src), info);
  }

  void UploadValid() {
    // The big one 1 in 20: its first upload decodes five 2048x2048 textures.
    const std::vector<GltfSource>& models = in_.models;
    const GltfSource& m =
        Chance(0.05) ? models.back() : models[size_t(Uniform(0, int(models.size()) - 2))];
    v1::SceneInfo info;
    const grpc::Status st = Upload(m, &info);
    if (st.ok() && info.scene_id() != LocalSceneId(m))
      return tally_.Unexpected(Action::kUploadValid, "BAD_ANSWER",
                               m.main_file + ": scene id " + info.scene_id());
    if (st.ok()) s_.scenes.Add(info.scene_id());
    tally_.Judge(Action::kUploadValid, m.main_file, st);
  }

  void UploadMalformed() {
    const Action a = Action::kUploadMalformed;
    v1::SceneInfo info;
    GltfSource src = in_.box;  // what most cases break
    switch (Uniform(0, 7)) {
      case 0: {
        src = in_.textured_glb;
        std::vector<uint8_t>& glb = src.files[src.main_file];
        glb.resize(size_t(Uniform(1, int(glb.size()) - 1)));
        return tally_.JudgeRefusal(a, absl::StrCat("a GLB cut to ", glb.size(), " bytes"),
                                   Upload(src, &info), {Code::INVALID_ARGUMENT});
      }
      case 1: {  // Box's JSON cut short, or bytes at random
        std::vector<uint8_t> text = src.files[src.main_file];
        text.resize(size_t(Uniform(1, int(text.size()) / 2)));
        if (Chance(0.5))
          for (uint8_t& c : text) c = uint8_t(Uniform(0, 255));
        src.files = {{"garbage.gltf", text}};
        src.main_file = "garbage.gltf";
        return tally_.JudgeRefusal(a, "JSON garbage", Upload(src, &info), {Code::INVALID_ARGUMENT});
      }
      case 2:
        src.files.erase("Box0.bin");
        return tally_.JudgeRefusal(a, "a .gltf without its buffer", Upload(src, &info),
                                   {Code::INVALID_ARGUMENT});
      case 3:
        src = in_.textured;
        for (auto& [name, data] : src.files)
          if (absl::EndsWith(name, ".png")) data = PngHeaderOnly(100000, 100000);
        // Refused as a bad image or as over a limit (the image or the scene's device memory).
        return tally_.JudgeRefusal(a, "a 100000x100000 PNG texture", Upload(src, &info),
                                   {Code::INVALID_ARGUMENT, Code::RESOURCE_EXHAUSTED});
      case 4: {
        std::vector<v1::UploadChunk> chunks = ChunksOf(src);
        chunks.emplace_back().set_file_index(uint32_t(src.files.size()));  // past the manifest
        chunks.back().set_data("x");
        return tally_.JudgeRefusal(a, "a chunk for a file not in the manifest",
                                   SendUpload(stub_.get(), ManifestOf(src), chunks, &info),
                                   {Code::INVALID_ARGUMENT});
      }
      case 5: {
        v1::UploadManifest m = ManifestOf(src);
        m.mutable_files(0)->set_sha256(tessera::Sha256Hex("soak", 4));
        return tally_.JudgeRefusal(a, "a wrong sha256",
                                   SendUpload(stub_.get(), m, ChunksOf(src), &info),
                                   {Code::DATA_LOSS});
      }
      case 6: {
        v1::UploadManifest m;
        m.add_files()->set_name("scene.gltf");
        for (uint32_t i = 0; i < s_.limits.max_upload_files(); ++i)
          m.add_files()->set_name(absl::StrCat("buffer", i, ".bin"));
        for (v1::UploadFile& f : *m.mutable_files()) f.set_size(1);
        return tally_.JudgeRefusal(a, "max_upload_files + 1 files",
                                   SendUpload(stub_.get(), m, {}, &info),
                                   {Code::RESOURCE_EXHAUSTED});
      }
      default: {
        v1::UploadManifest m;
        m.add_files()->set_name("big.glb");
        m.mutable_files(0)->set_size(s_.limits.max_upload_bytes() + 1);
        return tally_.JudgeRefusal(a, "max_upload_bytes + 1 bytes",
                                   SendUpload(stub_.get(), m, {}, &info),
                                   {Code::RESOURCE_EXHAUSTED});
      }
    }
  }

  // A scene never uploaded before: loaded, rendered once, deleted. The delete is tried whatever
  // the render did, so no lifecycle scene stays behind.
  void SceneLifecycle() {
    const Action a = Action::kSceneLifecycle;
    const uint64_t n = s_.next_variant.fetch_add(1);
    GltfSource src = n % 2 ? in_.textured : in_.box;
    std::vector<uint8_t>& text = src.files[src.main_file];
    const std::string extras = absl::StrCat("\"extras\": {\"tessera_soak\": ", n, "}, ");
    text.insert(std::find(text.begin(), text.end(), '{') + 1, extras.begin(), extras.end());
    const std::string what = absl::StrCat(src.main_file, " variant ", n);
    v1::SceneInfo info;
    const grpc::Status uploaded = Upload(src, &info);
    tally_.Judge(a, what + ": upload", uploaded);
    if (!uploaded.ok()) return;
    v1::RenderRequest request;
    request.set_scene_id(info.scene_id());
    request.mutable_settings()->set_width(160);
    request.mutable_settings()->set_height(120);
    v1::Frame frame;
    grpc::ClientContext render_ctx;
    render_ctx.set_deadline(DeadlineIn(kUnaryDeadline));
    tally_.Judge(a, what + ": render", stub_->Render(&render_ctx, request, &frame));
    v1::DeleteSceneRequest del;
    del.set_scene_id(info.scene_id());
    v1::DeleteSceneResponse deleted;
    grpc::ClientContext delete_ctx;
    delete_ctx.set_deadline(DeadlineIn(kUnaryDeadline));
    tally_.Judge(a, what + ": delete", stub_->DeleteScene(&delete_ctx, del, &deleted));
  }

  // Size, aa (and samples for MSAA), culling and JPEG quality, at random from the choices.
  void RandomSettings(v1::RenderSettings* s) {
    s->set_width(uint32_t(Uniform(160, 320)));
    s->set_height(uint32_t(Uniform(120, 240)));
    s->set_aa(Pick(s_.choices.aa));
    if (s->aa() == v1::AA_MSAA) s->set_samples(Pick(s_.choices.samples));
    s->set_culling(Pick(s_.choices.culling));
    s->set_jpeg_quality(uint32_t(Uniform(40, 95)));
  }

  void Render() {
    const bool unknown = Chance(0.1);
    v1::RenderRequest request;
    request.set_scene_id(unknown ? kUnknownScene : s_.scenes.Pick(rng_));
    RandomSettings(request.mutable_settings());
    request.set_encoding(Chance(0.25) ? v1::IMAGE_PNG : v1::IMAGE_JPEG);
    const v1::RenderSettings& s = request.settings();
    const std::string what = absl::StrCat("render of ", request.scene_id().substr(0, 12), " at ",
                                          s.width(), "x", s.height(), " ", v1::AaMode_Name(s.aa()),
                                          " ", v1::CullingMode_Name(s.culling()));
    grpc::ClientContext ctx;
    ctx.set_deadline(DeadlineIn(kUnaryDeadline));
    v1::Frame frame;
    const grpc::Status st = stub_->Render(&ctx, request, &frame);
    if (unknown) return tally_.JudgeRefusal(Action::kRender, what, st, {Code::NOT_FOUND});
    if (st.ok() &&
        (frame.width() != s.width() || frame.height() != s.height() || frame.data().empty()))
      return tally_.Unexpected(Action::kRender, "BAD_ANSWER",
                               absl::StrCat(what, ": a ", frame.width(), "x", frame.height(),
                                            " frame of ", frame.data().size(), " bytes"));
    tally_.Judge(Action::kRender, what, st);
  }

  // The scene framed from a random side.
  v1::Camera RandomCamera() {
    const double angle = double(Uniform(0, 628)) / 100.0;
    v1::Camera c;
    v1::Vec3* dir = c.mutable_frame()->mutable_direction();
    dir->set_x(float(std::cos(angle)));
    dir->set_y(0.45f);
    dir->set_z(float(std::sin(angle)));
    return c;
  }

  // A session's next event: a new camera (a change, so a session rendering on events only sends
  // the next frame) and, when thrashing, part of new settings.
  v1::ClientEvent NextEvent(uint64_t id, bool thrash) {
    v1::ClientEvent e;
    e.set_event_id(id);
    *e.mutable_camera() = RandomCamera();
    if (!thrash) return e;
    v1::RenderSettings all;
    RandomSettings(&all);
    v1::RenderSettings* s = e.mutable_settings();
    if (Chance(0.5)) {
      s->set_width(all.width());
      s->set_height(all.height());
    }
    if (Chance(0.5)) {
      s->set_aa(all.aa());
      if (all.has_samples()) s->set_samples(all.samples());
    }
    if (Chance(0.5)) s->set_culling(all.culling());
    if (Chance(0.5)) s->set_jpeg_quality(all.jpeg_quality());
    return e;
  }

  void Stream() {
    const std::string scene = s_.scenes.Pick(rng_);
    const int frames = Uniform(1, 10);
    const bool thrash = Chance(0.5);
    enum End { kClose, kCancel, kResume, kAbandon };
    static constexpr const char* kEndNames[] = {"close", "cancel", "cancel+resume", "abandon"};
    const int roll = Uniform(0, 99);
    const End end = roll < 45 ? kClose : roll < 70 ? kCancel : roll < 85 ? kResume : kAbandon;
    const std::string what = absl::StrCat("stream on ", scene.substr(0, 12), " (", frames,
                                          " frames, ", kEndNames[end], thrash ? ", thrash)" : ")");
    grpc::ClientContext ctx;  // before the stream, which must go first (kAbandon)
    ctx.set_deadline(DeadlineIn(kLongDeadline));
    std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
    v1::ClientEvent open;
    open.set_event_id(1);
    v1::OpenSession* o = open.mutable_open();
    o->set_scene_id(scene);
    *o->mutable_camera() = RandomCamera();
    RandomSettings(o->mutable_settings());
    if (Chance(0.3)) o->set_target_fps(float(Uniform(5, 30)));  // else frames on events only
    bool alive = rw->Write(open);
    v1::Frame frame;
    for (int i = 0; alive && i < frames; ++i) {
      alive = rw->Read(&frame);
      if (alive && i + 1 < frames) alive = rw->Write(NextEvent(uint64_t(i) + 2, thrash));
    }
    const std::string token = frame.session_token();  // the last frame's
    if (!alive) {  // the server ended the stream before its frames: Finish says why
      const grpc::Status st = rw->Finish();
      if (st.ok()) return tally_.Unexpected(Action::kStream, "OK", what + ": ended early");
      return tally_.Judge(Action::kStream, what, st);
    }
    if (end == kAbandon) return tally_.Ok(Action::kStream);  // ~rw, ~ctx: gRPC cancels the call
    if (end == kClose) {
      rw->WritesDone();
    } else {
      ctx.TryCancel();
    }
    while (rw->Read(&frame)) {
    }
    tally_.Judge(Action::kStream, what, rw->Finish(), end == kClose ? Code::OK : Code::CANCELLED);
    if (end == kResume) Resume(token, what);
  }

  // Takes a cancelled (parked) session back by its token: its frame comes without an event;
  // then a proper close.
  void Resume(const std::string& token, const std::string& what) {
    grpc::ClientContext ctx;
    ctx.set_deadline(DeadlineIn(kLongDeadline));
    std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
    v1::ClientEvent resume;
    resume.mutable_open()->set_resume_token(token);
    v1::Frame frame;
    if (rw->Write(resume) && rw->Read(&frame)) {
      rw->WritesDone();
      while (rw->Read(&frame)) {
      }
    }
    tally_.Judge(Action::kStreamResume, "resume of " + what, rw->Finish());
  }

  void Info() {
    grpc::ClientContext ctx;
    ctx.set_deadline(DeadlineIn(kUnaryDeadline));
    v1::ServerInfo info;
    v1::ListScenesResponse list;
    if (Chance(0.5))
      return tally_.Judge(Action::kInfo, "GetServerInfo",
                          stub_->GetServerInfo(&ctx, v1::GetServerInfoRequest{}, &info));
    tally_.Judge(Action::kInfo, "ListScenes",
                 stub_->ListScenes(&ctx, v1::ListScenesRequest{}, &list));
  }

  Shared& s_;
  const Inputs& in_;
  Tally& tally_;
  std::mt19937_64 rng_;
  std::unique_ptr<v1::RenderService::Stub> stub_;  // owns its channel: a new one reconnects
};

// --- samples and verdict -------------------------------------------------------------------

struct Sample {
  double t_s = 0.0;  // since the workers started
  uint64_t rss_kb = 0;
  uint32_t threads = 0, fds = 0;
  // From GetServerInfo; nullopt when it failed (an unexpected error of its own).
  std::optional<uint64_t> device_bytes, scene_device_bytes;
  uint32_t sessions = 0, parked_sessions = 0;
  uint64_t ops = 0, unexpected = 0;  // calls so far

  json Json() const {
    auto mb = [](std::optional<uint64_t> b) { return b ? json(Mib(*b)) : json(nullptr); };
    return {{"t_s", t_s},
            {"rss_mb", double(rss_kb) / 1024.0},
            {"threads", threads},
            {"fds", fds},
            {"device_mb", mb(device_bytes)},
            {"scene_device_mb", mb(scene_device_bytes)},
            {"sessions", sessions},
            {"parked_sessions", parked_sessions},
            {"ops", ops},
            {"unexpected", unexpected}};
  }
};

// The daemon's /proc figures and GetServerInfo's; nullopt once the daemon has ended (a zombie
// has no VmRSS) or its /proc cannot be read.
std::optional<Sample> TakeSample(pid_t pid, v1::RenderService::Stub* stub, Tally* tally,
                                 Clock::time_point start) {
  Sample s;
  s.t_s = Seconds(Clock::now() - start);
  std::ifstream status(absl::StrCat("/proc/", pid, "/status"));
  bool has_rss = false, has_threads = false;
  for (std::string line; std::getline(status, line);) {
    has_rss = has_rss || std::sscanf(line.c_str(), "VmRSS: %" SCNu64, &s.rss_kb) == 1;
    has_threads = has_threads || std::sscanf(line.c_str(), "Threads: %" SCNu32, &s.threads) == 1;
  }
  std::error_code ec;
  for (fs::directory_iterator it(absl::StrCat("/proc/", pid, "/fd"), ec), end; !ec && it != end;
       it.increment(ec))
    ++s.fds;
  if (!has_rss || !has_threads || ec) return std::nullopt;
  grpc::ClientContext ctx;
  ctx.set_deadline(DeadlineIn(kUnaryDeadline));
  v1::ServerInfo info;
  const grpc::Status st = stub->GetServerInfo(&ctx, v1::GetServerInfoRequest{}, &info);
  tally->Judge(Action::kSample, "GetServerInfo", st);
  if (st.ok()) {
    s.device_bytes = info.device_memory_bytes();
    s.scene_device_bytes = info.scene_device_bytes();
    s.sessions = info.active_sessions();
    s.parked_sessions = info.parked_sessions();
  }
  s.ops = tally->calls();
  s.unexpected = tally->unexpected();
  std::fprintf(stderr,
               "[soak] t=%5.0f s  rss %7.1f MiB  fds %3u  threads %3u  device %7.1f MiB  "
               "sessions %2u (+%u parked)  calls %" PRIu64 "  unexpected %" PRIu64 "\n",
               s.t_s, double(s.rss_kb) / 1024.0, s.fds, s.threads, Mib(s.device_bytes.value_or(0)),
               s.sessions, s.parked_sessions, s.ops, s.unexpected);
  return s;
}

// One figure after the warm-up: the medians at its two edges (kEdgeSamples each, fewer when
// there are not twice as many samples), its maximum, its growth.
struct Trend {
  size_t samples = 0;
  double after_warmup = 0.0, end = 0.0, max = 0.0, growth_pct = 0.0;

  explicit Trend(const std::vector<double>& v) : samples(v.size()) {
    if (v.empty()) return;
    const size_t k = std::min(kEdgeSamples, std::max<size_t>(1, v.size() / 2));
    after_warmup = Median(std::vector<double>(v.begin(), v.begin() + k));
    end = Median(std::vector<double>(v.end() - k, v.end()));
    max = *std::max_element(v.begin(), v.end());
    growth_pct = after_warmup > 0.0 ? 100.0 * (end - after_warmup) / after_warmup : 0.0;
  }
  json Json() const {
    return {{"after_warmup", after_warmup},
            {"end", end},
            {"max", max},
            {"growth_pct", growth_pct},
            {"samples", samples}};
  }
};

// The flatness checks over the samples after the warm-up, each with its reason in `why`.
bool Flat(const std::vector<Sample>& samples, double warmup_s, json* summary,
          std::vector<std::string>* why) {
  std::vector<double> rss, fds, threads, device;
  for (const Sample& s : samples) {
    if (s.t_s < warmup_s) continue;
    rss.push_back(double(s.rss_kb) / 1024.0);
    fds.push_back(s.fds);
    threads.push_back(s.threads);
    if (s.device_bytes) device.push_back(Mib(*s.device_bytes));
  }
  const Trend r(rss), f(fds), t(threads), d(device);
  *summary = {
      {"rss_mb", r.Json()}, {"fds", f.Json()}, {"threads", t.Json()}, {"device_mb", d.Json()}};
  auto check = [&](bool ok, const std::string& text) {
    why->push_back(absl::StrCat(ok ? "ok: " : "FAIL: ", text));
    return ok;
  };
  if (rss.size() < 2)
    return check(false, absl::StrCat(rss.size(),
                                     " sample(s) after the warm-up, 2 needed (see "
                                     "--duration, --warmup, --sample-every)"));
  const double device_allowed = std::max(kDeviceSlackMb, d.after_warmup * kMaxGrowthPct / 100.0);
  // Each check is made (and explained) even after one has failed.
  bool flat = check(r.growth_pct <= kMaxGrowthPct,
                    absl::StrFormat("RSS %.1f MiB after the warm-up, %.1f MiB at the end: %+.1f %% "
                                    "(at most +%.0f %%)",
                                    r.after_warmup, r.end, r.growth_pct, kMaxGrowthPct));
  flat &= check(f.end <= f.after_warmup + kCountSlack,
                absl::StrFormat("open FDs %g after the warm-up, %g at the end (at most +%g)",
                                f.after_warmup, f.end, kCountSlack));
  flat &= check(t.end <= t.after_warmup + kCountSlack,
                absl::StrFormat("threads %g after the warm-up, %g at the end (at most +%g)",
                                t.after_warmup, t.end, kCountSlack));
  if (device.size() >= 2)
    flat &= check(
        d.end - d.after_warmup <= device_allowed,
        absl::StrFormat("device memory %.1f MiB after the warm-up, %.1f MiB at the end "
                        "(at most +%.1f MiB: %.0f %% or %.0f MiB)",
                        d.after_warmup, d.end, device_allowed, kMaxGrowthPct, kDeviceSlackMb));
  return flat;
}

// --- flags and main ------------------------------------------------------------------------

Options ParseFlags(int argc, char** argv) {
  Options o;
  o.assets = AssetsDir();
  // --smoke sets small defaults first, so later flags can still change them.
  if (HasFlag(argc, argv, "--smoke")) {
    o.smoke = true;
    o.duration_s = 8.0;
    o.warmup_s = 2.0;
    o.sample_every_s = 1.0;
  }
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) UsageError(arg + " needs a value");
      return argv[++i];
    };
    auto seconds = [&](double* out, double min, double max) {
      if (!absl::SimpleAtod(value(), out) || !(*out >= min) || *out > max)
        UsageError(absl::StrCat(arg, " wants seconds in ", min, "..", max));
    };
    if (arg == "--smoke") {
      continue;
    } else if (arg == "--help" || arg == "-h") {
      std::fputs(kUsage, stdout);
      std::exit(0);
    } else if (arg == "--tesserad") {
      o.tesserad = value();
    } else if (arg == "--duration") {
      seconds(&o.duration_s, 1.0, 7 * 86400.0);
    } else if (arg == "--warmup") {
      seconds(&o.warmup_s, 0.0, 7 * 86400.0);
    } else if (arg == "--sample-every") {
      seconds(&o.sample_every_s, 0.1, 3600.0);
    } else if (arg == "--clients") {
      if (!absl::SimpleAtoi(value(), &o.clients) || o.clients < 1 || o.clients > 64)
        UsageError("--clients wants a number in 1..64");
    } else if (arg == "--seed") {
      if (!absl::SimpleAtoi(value(), &o.seed)) UsageError("--seed wants a number");
    } else if (arg == "--assets") {
      o.assets = value();
    } else if (arg == "--device") {
      o.device = value();
    } else if (arg == "--out") {
      o.out = value();
    } else if (arg == "--aa") {
      o.aa = value();
    } else {
      UsageError("unknown option " + arg);
    }
  }
  if (o.tesserad.empty()) UsageError("--tesserad PATH is required");
  if (access(o.tesserad.c_str(), X_OK) != 0)
    UsageError(absl::StrCat(o.tesserad, ": not an executable (", std::strerror(errno), ")"));
  if (o.warmup_s >= o.duration_s) UsageError("--warmup must be shorter than --duration");
  if (o.sample_every_s > o.duration_s) UsageError("--sample-every is longer than --duration");
  return o;
}

// Everything after the flags; returns the exit status.
int RunSoak(const Options& o) {
  auto cannot_start = [](const std::string& why) {
    std::fprintf(stderr, "%s: %s\n", program_invocation_short_name, why.c_str());
    return 2;
  };
  std::fprintf(stderr, "[soak] seed %" PRIu64 ", %.0f s (warm-up %.0f s), %u clients\n", o.seed,
               o.duration_s, o.warmup_s, o.clients);
  absl::StatusOr<Inputs> inputs = ReadInputs(o.assets);
  if (!inputs.ok()) return cannot_start(std::string(inputs.status().message()));
  TempDir tmp("tessera-soak");  // before the daemon, which is stopped before its directory goes
  if (tmp.path().empty()) return cannot_start(absl::StrCat("mkdtemp: ", std::strerror(errno)));
  // max_scenes: every model plus two lifecycle scenes per worker (its current one, and the one
  // it deleted last, which a finishing Render may hold a moment longer): the store never fills,
  // so nothing the workers rely on is evicted.
  const std::vector<std::string> daemon_args = {
      absl::StrCat("--max_scenes=", inputs->models.size() + 2 * o.clients),
      absl::StrCat("--max_upload_bytes=", kMaxUploadBytes),
      absl::StrCat("--max_upload_files=", kMaxUploadFiles)};
  DaemonSet daemons;
  if (absl::Status st = daemons.Start(o.tesserad, o.device, 1, tmp.path(), daemon_args); !st.ok())
    return cannot_start(std::string(st.message()));
  const Daemon daemon = daemons.daemons().front();

  Shared shared;
  shared.address = daemon.address();
  shared.inputs = *std::move(inputs);
  std::unique_ptr<v1::RenderService::Stub> stub =  // the sampler's connection
      v1::RenderService::NewStub(NewChannel(shared.address));
  v1::ServerInfo info;
  {
    grpc::ClientContext ctx;
    ctx.set_deadline(DeadlineIn(kUnaryDeadline));
    if (grpc::Status st = stub->GetServerInfo(&ctx, v1::GetServerInfoRequest{}, &info); !st.ok())
      return cannot_start("GetServerInfo: " + st.error_message());
  }
  absl::StatusOr<Choices> choices = ChoicesFrom(info.choices());
  if (!choices.ok()) return cannot_start(std::string(choices.status().message()));
  shared.choices = *std::move(choices);
  if (!o.aa.empty()) {
    v1::AaMode mode;
    if (!v1::AaMode_Parse("AA_" + absl::AsciiStrToUpper(o.aa), &mode) ||
        std::find(shared.choices.aa.begin(), shared.choices.aa.end(), mode) ==
            shared.choices.aa.end())
      return cannot_start(absl::StrCat("--aa ", o.aa, ": not one of the server's AA modes"));
    shared.choices.aa = {mode};
  }
  shared.limits = info.limits();

  // The run: the workers, and this thread sampling on schedule until the end.
  std::vector<Sample> samples;
  std::string early_end;  // why the run ended before --duration
  const Clock::time_point start = Clock::now();
  shared.end = start + std::chrono::duration_cast<Clock::duration>(
                           std::chrono::duration<double>(o.duration_s));
  {
    std::vector<std::jthread> workers;  // asked to stop and joined when the block ends
    for (uint32_t i = 0; i < o.clients; ++i)
      workers.emplace_back(
          [&shared, i, &o](std::stop_token stop) { Worker(shared, i, o.seed).Run(stop); });
    const auto every = std::chrono::duration<double>(o.sample_every_s);
    for (uint64_t k = 0;; ++k) {
      const Clock::time_point at = start + std::chrono::duration_cast<Clock::duration>(k * every);
      if (at >= shared.end) break;
      std::this_thread::sleep_until(at);
      std::optional<Sample> s = TakeSample(daemon.pid, stub.get(), &shared.tally, start);
      if (!s) {
        early_end = "tesserad ended during the run";
        break;
      }
      samples.push_back(*s);
    }
    if (early_end.empty()) std::this_thread::sleep_until(shared.end);
    for (std::jthread& w : workers) w.request_stop();  // all at once, then the joins
  }
  if (early_end.empty()) {
    if (std::optional<Sample> s = TakeSample(daemon.pid, stub.get(), &shared.tally, start))
      samples.push_back(*s);
    else
      early_end = "tesserad ended as the workers stopped";
  }
  const absl::Status stopped = daemons.Stop();
  const std::string daemon_exit =
      stopped.ok() ? "exit status 0 after SIGTERM" : std::string(stopped.message());

  // The verdict.
  json summary;
  std::vector<std::string> why;
  const bool flat = Flat(samples, o.warmup_s, &summary, &why);
  auto check = [&](bool ok, const std::string& text) {
    why.push_back(absl::StrCat(ok ? "ok: " : "FAIL: ", text));
    return ok;
  };
  const uint64_t unexpected = shared.tally.unexpected();
  const std::vector<std::string> examples = shared.tally.examples();
  const bool no_unexpected =
      check(unexpected == 0,
            absl::StrCat(unexpected, " unexpected errors in ", shared.tally.calls(), " calls",
                         examples.empty() ? "" : "; the first: " + examples.front()));
  const bool clean_exit = check(stopped.ok(), "tesserad: " + daemon_exit);
  const bool full_run =
      check(early_end.empty(), early_end.empty() ? "ran for --duration" : early_end);
  if (o.smoke) why.push_back("note: --smoke: flatness is reported, not required");
  const bool pass = (flat || o.smoke) && no_unexpected && clean_exit && full_run;

  json series = json::array();
  for (const Sample& s : samples) series.push_back(s.Json());
  const json out = {
      {"seed", o.seed},
      {"aa", o.aa.empty() ? "random" : o.aa},
      {"duration_s", o.duration_s},
      {"warmup_s", o.warmup_s},
      {"sample_every_s", o.sample_every_s},
      {"clients", o.clients},
      {"smoke", o.smoke},
      {"device", info.device().name()},
      {"server_version", info.version()},
      {"daemon_args", daemon_args},
      {"samples", series},
      {"summary", summary},
      {"ops", shared.tally.Json()},
      {"unexpected_examples", examples},
      {"daemon_exit", daemon_exit},
      {"verdict",
       {{"flat", flat}, {"no_unexpected_errors", no_unexpected}, {"pass", pass}, {"why", why}}}};
  const std::string text = out.dump(2);
  std::printf("%s\n", text.c_str());
  std::fflush(stdout);
  const json& r = summary["rss_mb"];
  std::fprintf(stderr,
               "%s: %s (seed %" PRIu64 ", %.0f s, %u clients): %" PRIu64 " calls, %" PRIu64
               " unexpected; RSS %.1f -> %.1f MiB (%+.1f %%); tesserad %s\n",
               program_invocation_short_name, pass ? "PASS" : "FAIL", o.seed, o.duration_s,
               o.clients, shared.tally.calls(), unexpected, r["after_warmup"].get<double>(),
               r["end"].get<double>(), r["growth_pct"].get<double>(), daemon_exit.c_str());
  if (!o.out.empty()) {
    std::ofstream f(o.out);
    f << text << "\n";
    if (!f.flush()) return cannot_start(o.out + ": cannot write (--out)");
  }
  return pass ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) { return RunSoak(ParseFlags(argc, argv)); }

// tessera job: render-farm jobs. `submit` hands a job to one daemon (SubmitJob, then WatchJob
// and FetchJobFrames), or with --servers spreads its frames over several daemons itself
// (RenderJobFrame through gRPC's round_robin load balancing, retrying a failed frame on
// another daemon, writing every frame exactly once). `watch`, `cancel`, `list`, `fetch` and
// `rm` work on the jobs of one daemon.
#include <arpa/inet.h>
#include <netdb.h>
#include <sys/socket.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "clients/cli/cli_commands.h"
#include "clients/cli/cli_format.h"
#include "clients/cli/cli_progress.h"
#include "clients/cli/cli_render_flags.h"
#include "clients/cli/cli_stream_parts.h"
#include "common/job_spec.h"
#include "common/scene_id.h"
#include "common/status_macros.h"

namespace tessera::cli {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// "312 ms/frame" for a progress bar's note; "" before the first frame.
std::string MsPerFrame(double ms) {
  return ms > 0 ? absl::StrFormat("%.0f ms/frame", ms) : std::string();
}

// "0..119", "0..119:2", "7".
bool ParseFrameRange(const std::string& text, v1::FrameRange* out) {
  std::string body = text;
  uint32_t step = 1;
  if (size_t colon = text.find(':'); colon != std::string::npos) {
    if (!absl::SimpleAtoi(text.substr(colon + 1), &step) || step == 0) return false;
    body = text.substr(0, colon);
  }
  uint32_t first = 0, last = 0;
  if (size_t dots = body.find(".."); dots != std::string::npos) {
    if (!absl::SimpleAtoi(body.substr(0, dots), &first) ||
        !absl::SimpleAtoi(body.substr(dots + 2), &last))
      return false;
  } else {
    if (!absl::SimpleAtoi(body, &first)) return false;
    last = first;
  }
  out->set_first(first);
  out->set_last(last);
  out->set_step(step);
  return true;
}

// A keyframe file: {"interpolation": "catmull_rom", "znear": 0.05, "keyframes": [{"frame": 0,
// "eye": [x,y,z], "target": [x,y,z], "up": [0,1,0], "yfov": 0.8}, ...]}
absl::StatusOr<v1::CameraPath> ReadKeyframes(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("--keyframes: cannot read '", path, "'"));
  Json j = Json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object())
    return absl::InvalidArgumentError(
        absl::StrCat("--keyframes: '", path, "' is not a JSON object"));
  v1::CameraPath out;
  const std::string interp = j.value("interpolation", "linear");
  if (interp == "linear") {
    out.set_interpolation(v1::INTERPOLATION_LINEAR);
  } else if (interp == "catmull_rom") {
    out.set_interpolation(v1::INTERPOLATION_CATMULL_ROM);
  } else if (interp == "step") {
    out.set_interpolation(v1::INTERPOLATION_STEP);
  } else {
    return absl::InvalidArgumentError(absl::StrCat(
        "--keyframes: interpolation '", interp, "': use linear, catmull_rom or step"));
  }
  if (j.contains("znear") && j["znear"].is_number()) out.set_znear(j["znear"].get<float>());
  if (j.contains("zfar") && j["zfar"].is_number()) out.set_zfar(j["zfar"].get<float>());
  if (!j.contains("keyframes") || !j["keyframes"].is_array())
    return absl::InvalidArgumentError("--keyframes: needs a \"keyframes\" array");
  size_t i = 0;
  for (const Json& k : j["keyframes"]) {
    const std::string where = absl::StrCat("--keyframes: keyframes[", i++, "]");
    if (!k.is_object() || !k.contains("frame") || !k["frame"].is_number_unsigned())
      return absl::InvalidArgumentError(absl::StrCat(where, ": needs \"frame\" (a frame number)"));
    v1::CameraKeyframe* key = out.add_keyframes();
    key->set_frame(k["frame"].get<uint32_t>());
    auto vec = [&](const char* name, v1::Vec3* v, bool required) -> absl::Status {
      if (!k.contains(name)) {
        return required ? absl::InvalidArgumentError(absl::StrCat(where, ": needs \"", name,
                                                                  "\" ([x, y, z])"))
                        : absl::OkStatus();
      }
      const Json& a = k[name];
      if (!a.is_array() || a.size() != 3 || !a[0].is_number() || !a[1].is_number() ||
          !a[2].is_number())
        return absl::InvalidArgumentError(absl::StrCat(where, ".", name, ": not [x, y, z]"));
      v->set_x(a[0].get<float>());
      v->set_y(a[1].get<float>());
      v->set_z(a[2].get<float>());
      return absl::OkStatus();
    };
    v1::LookAt* la = key->mutable_look_at();
    RETURN_IF_ERROR(vec("eye", la->mutable_eye(), true));
    RETURN_IF_ERROR(vec("target", la->mutable_target(), true));
    RETURN_IF_ERROR(vec("up", la->mutable_up(), false));
    if (k.contains("yfov") && k["yfov"].is_number()) key->set_yfov(k["yfov"].get<float>());
  }
  return out;
}

struct SubmitOptions {
  std::string scene = "demo";
  std::string scene_file;  // --scene-file: uploaded first (to every server)
  std::string name;
  std::string frames = "0..0";
  std::string keyframes_file;
  bool orbit = false;
  bool png = false;
  uint32_t taa_frames = 0;
  double fps = 0.0;        // animated scenes: frame n at --time + n / fps
  std::string out;         // local directory for the frames
  std::string server_dir;  // SERVER_DIR output on the daemon
  std::string pattern;
  std::string servers;     // several daemons: spread the frames
  bool detach = false;
  uint32_t retries = 5;
  uint32_t parallel = 0;   // frames in flight with --servers (0: 2 per address)
  double frame_timeout_s = 600;
  RenderFlags flags;
};

// The orbit as an explicit camera list: one turn over the frames, around the scene bounds.
absl::Status OrbitCameras(v1::RenderService::Stub* stub, const SubmitOptions& o,
                          const std::string& scene_id, uint32_t frames, v1::CameraList* out) {
  v1::SceneInfo info;
  std::string resolved;
  bool found = false;
  grpc::Status st = ResolveSceneId(stub, scene_id, &resolved, &info, &found);
  if (!st.ok()) return absl::Status(absl::StatusCode(st.error_code()), st.error_message());
  if (!found || !info.has_bounds())
    return absl::NotFoundError(absl::StrCat("--orbit: scene ", scene_id, " has no bounds here"));
  const v1::RenderSettings& s = o.flags.settings();
  const float width = s.has_width() ? s.width() : 1280.0f;
  const float height = s.has_height() ? s.height() : 720.0f;
  const v1::Camera& c = o.flags.camera();
  const Orbit orbit = Orbit::FromBounds(info.bounds(), c.has_yfov() ? c.yfov() : 0.8f,
                                        width / std::max(1.0f, height));
  for (uint32_t i = 0; i < frames; ++i) *out->add_cameras() = orbit.CameraAt(i, frames, c);
  return absl::OkStatus();
}

SubmitOptions ParseSubmit(const Invocation& inv) {
  SubmitOptions o;
  Invocation sub = inv;
  sub.args.erase(sub.args.begin());
  ArgReader args(sub);
  while (args.Next()) {
    if (args.Is("--scene")) {
      o.scene = args.Value();
    } else if (args.Is("--scene-file")) {
      o.scene_file = args.Value();
    } else if (args.Is("--name")) {
      o.name = args.Value();
    } else if (args.Is("--frames")) {
      o.frames = args.Value();
    } else if (args.Is("--keyframes")) {
      o.keyframes_file = args.Value();
    } else if (args.Is("--orbit")) {
      o.orbit = true;
    } else if (args.Is("--png")) {
      o.png = true;
    } else if (args.Is("--taa-frames")) {
      o.taa_frames = args.Uint();
    } else if (args.Is("--fps")) {
      o.fps = args.Double();
    } else if (args.Is("--out") || args.Is("-o")) {
      o.out = args.Value();
    } else if (args.Is("--server-dir")) {
      o.server_dir = args.Value();
    } else if (args.Is("--pattern")) {
      o.pattern = args.Value();
    } else if (args.Is("--servers")) {
      o.servers = args.Value();
    } else if (args.Is("--detach")) {
      o.detach = true;
    } else if (args.Is("--retries")) {
      o.retries = args.Uint();
    } else if (args.Is("--parallel")) {
      o.parallel = args.Uint();
    } else if (args.Is("--frame-timeout")) {
      o.frame_timeout_s = args.Double();
    } else if (!o.flags.Parse(args)) {
      args.Unknown();
    }
  }
  o.flags.Finish(args);
  v1::FrameRange range;
  if (!ParseFrameRange(o.frames, &range))
    args.Fail(absl::StrCat("--frames '", o.frames, "': use FIRST..LAST[:STEP] or one number"));
  if (int(o.orbit) + int(!o.keyframes_file.empty()) + int(o.flags.has_placement()) > 1)
    args.Fail("--orbit, --keyframes and --camera/--frame each place the camera: pick one");
  if (!o.servers.empty() && o.out.empty())
    args.Fail("--servers writes the frames here: give --out DIR");
  if (!o.servers.empty() && (!o.server_dir.empty() || o.detach))
    args.Fail("--servers renders through this client: --server-dir and --detach do not apply");
  if (!o.server_dir.empty() && !o.out.empty())
    args.Fail("--server-dir keeps the frames on the server; --out fetches them here: pick one");
  if (!o.scene_file.empty() && o.scene != "demo")
    args.Fail("--scene and --scene-file name the scene twice: pick one");
  return o;
}

// The spec from the options; the scene id already resolved.
absl::StatusOr<v1::JobSpec> BuildSpec(v1::RenderService::Stub* stub, const SubmitOptions& o,
                                      const std::string& scene_id) {
  v1::JobSpec spec;
  spec.set_name(o.name.empty() ? absl::StrCat("frames ", o.frames) : o.name);
  spec.set_scene_id(scene_id);
  *spec.mutable_settings() = o.flags.settings();
  ParseFrameRange(o.frames, spec.mutable_frames());
  spec.set_encoding(o.png ? v1::IMAGE_PNG : v1::IMAGE_JPEG);
  spec.set_taa_frames(o.taa_frames);
  spec.set_fps(o.fps);
  if (!o.server_dir.empty()) {
    spec.set_output(v1::JOB_OUTPUT_SERVER_DIR);
    spec.set_output_dir(o.server_dir == "." ? "" : o.server_dir);
  } else {
    spec.set_output(v1::JOB_OUTPUT_RETURN);
  }
  if (!o.pattern.empty()) spec.set_name_pattern(o.pattern);
  const v1::Camera& c = o.flags.camera();
  if (!o.keyframes_file.empty()) {
    absl::StatusOr<v1::CameraPath> path = ReadKeyframes(o.keyframes_file);
    if (!path.ok()) return path.status();
    *spec.mutable_path() = *std::move(path);
  } else if (o.orbit) {
    RETURN_IF_ERROR(
        OrbitCameras(stub, o, scene_id, jobs::FrameCount(spec.frames()), spec.mutable_list()));
  } else if (c.has_look_at()) {
    // One camera for every frame: a path with one key holds it.
    v1::CameraPath* path = spec.mutable_path();
    v1::CameraKeyframe* key = path->add_keyframes();
    key->set_frame(spec.frames().first());
    *key->mutable_look_at() = c.look_at();
    if (c.has_yfov()) key->set_yfov(c.yfov());
    if (c.has_znear()) path->set_znear(c.znear());
    if (c.has_zfar()) path->set_zfar(c.zfar());
  } else if (o.flags.has_placement() || c.has_yfov() || c.has_znear() || c.has_zfar()) {
    // A scene camera or a framing for every frame (only a look-at can be a path key).
    const uint32_t n = jobs::FrameCount(spec.frames());
    if (n > 100000) return absl::InvalidArgumentError("--frames: too many frames for one camera");
    for (uint32_t i = 0; i < n; ++i) *spec.mutable_list()->add_cameras() = c;
  }
  RETURN_IF_ERROR(jobs::ValidateJobSpec(spec));
  return spec;
}

Json FrameEventJson(const v1::JobFrameEvent& e) {
  Json j = ToJson(e);
  return j;
}

// Writes `data` to dir/name through a temporary file, so a reader never sees half a frame.
bool WriteFrameFile(const std::string& dir, const std::string& name, const std::string& data,
                    std::string* error) {
  const std::string path = (std::filesystem::path(dir) / name).string();
  const std::string tmp = path + ".part";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    if (!f) {
      *error = absl::StrCat(tmp, ": cannot create");
      return false;
    }
    f.write(data.data(), std::streamsize(data.size()));
    if (!f.good()) {
      *error = absl::StrCat(tmp, ": write failed");
      return false;
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) {
    *error = absl::StrCat(path, ": ", ec.message());
    return false;
  }
  return true;
}

bool MakeOutDir(const Invocation& inv, const std::string& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    ReportError(inv, absl::StrCat("--out ", dir, ": cannot create the directory: ", ec.message()),
                ErrnoCodeName(ec.value()));
    return false;
  }
  return true;
}

// Watches a job to its end with a progress bar. Frame events go to `frames` (JSON).
grpc::Status Watch(v1::RenderService::Stub* stub, const std::string& job_id, v1::Job* final_job,
                   Json* frames) {
  grpc::ClientContext context;
  v1::WatchJobRequest request;
  request.set_job_id(job_id);
  std::unique_ptr<grpc::ClientReader<v1::JobProgress>> reader = stub->WatchJob(&context, request);
  ProgressBar bar(absl::StrCat("job ", job_id.substr(0, 8)), 0);
  v1::JobProgress p;
  while (reader->Read(&p)) {
    *final_job = p.job();
    if (p.has_frame() && frames) frames->push_back(FrameEventJson(p.frame()));
    bar.set_total(p.job().frames_total());
    bar.set_eta(p.job().eta_s());  // the server's: it knows about restored frames and the queue
    bar.set_note(MsPerFrame(p.job().mean_frame_ms()));
    bar.Update(p.job().frames_done(), /*force=*/!p.has_frame());
  }
  bar.Clear();
  return reader->Finish();
}

// Fetches frames of a job into `dir`, named as the job names them. Returns the files written.
grpc::Status Fetch(const Invocation& inv, v1::RenderService::Stub* stub, const v1::Job& job,
                   const std::vector<uint32_t>& wanted, const std::string& dir, Json* files) {
  grpc::ClientContext context;
  v1::FetchJobFramesRequest request;
  request.set_job_id(job.job_id());
  for (uint32_t f : wanted) request.add_frames(f);
  std::unique_ptr<grpc::ClientReader<v1::JobFrame>> reader =
      stub->FetchJobFrames(&context, request);
  ProgressBar bar("fetch", wanted.empty() ? job.frames_done() : wanted.size());
  v1::JobFrame frame;
  uint32_t n = 0;
  while (reader->Read(&frame)) {
    if (Sha256Hex(frame.data().data(), frame.data().size()) != frame.sha256()) {
      context.TryCancel();
      reader->Finish();
      return grpc::Status(grpc::StatusCode::DATA_LOSS,
                          absl::StrCat("frame ", frame.frame(), ": sha256 mismatch in transit"));
    }
    const std::string name = jobs::FrameFileName(job.spec(), frame.frame());
    std::string error;
    if (!WriteFrameFile(dir, name, frame.data(), &error)) {
      context.TryCancel();
      reader->Finish();
      return grpc::Status(grpc::StatusCode::INTERNAL, error);
    }
    if (files) files->push_back((std::filesystem::path(dir) / name).string());
    bar.Update(++n);
  }
  bar.Clear();
  (void)inv;
  return reader->Finish();
}

const char* StateName(v1::JobState s) {
  switch (s) {
    case v1::JOB_QUEUED: return "queued";
    case v1::JOB_RUNNING: return "running";
    case v1::JOB_SUCCEEDED: return "succeeded";
    case v1::JOB_FAILED: return "failed";
    case v1::JOB_CANCELLED: return "cancelled";
    default: return "unknown";
  }
}

void PrintJobLine(const v1::Job& j) {
  absl::FPrintF(stderr, "job %s (%s): %s, %u/%u frames%s%s%s\n", j.job_id(), j.spec().name(),
                StateName(j.state()), j.frames_done(), j.frames_total(),
                j.frames_restored() ? absl::StrCat(" (", j.frames_restored(), " restored)") : "",
                j.mean_frame_ms() > 0 ? absl::StrFormat(", %.0f ms/frame", j.mean_frame_ms())
                                      : std::string(),
                j.error().empty() ? "" : absl::StrCat(": ", j.error()));
}

// ---------------------------------------------------------------------------------------------
// --servers: the frames spread over several daemons by this client.

// Worth trying again, on another daemon: it failed, was killed, was busy, or (a daemon that
// came back, or a new one behind a DNS name) does not have the scene.
bool Retryable(const grpc::Status& st) {
  if (st.error_code() == grpc::StatusCode::NOT_FOUND)
    return st.error_message().find("scene_id") != std::string::npos;
  switch (st.error_code()) {
    case grpc::StatusCode::UNAVAILABLE:
    case grpc::StatusCode::DEADLINE_EXCEEDED:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
    case grpc::StatusCode::ABORTED:
    case grpc::StatusCode::INTERNAL:
    case grpc::StatusCode::UNKNOWN:
    case grpc::StatusCode::CANCELLED:
      return true;
    default:
      return false;  // the spec or the scene is wrong: every daemon would say the same
  }
}

// How often a farm tries the daemons of --servers that did not answer.
constexpr double kFarmProbeSeconds = 2.0;

int RunFarm(const Invocation& inv, const SubmitOptions& o) {
  std::string lb_target;
  std::vector<std::string> addresses;
  if (absl::Status st = ResolveServers(o.servers, &lb_target, &addresses); !st.ok())
    return ReportError(inv, st);
  // The scene on every daemon that answers (content-addressed: a daemon that has it is
  // skipped). One that does not answer is left out and probed while the job runs: when it
  // answers it gets the scene, and round_robin gives it frames.
  std::string scene_id = o.scene;
  std::unique_ptr<v1::RenderService::Stub> first_stub;
  std::vector<std::string> down, down_why;
  absl::Status down_status;
  for (const std::string& address : addresses) {
    Invocation one = inv;
    one.global.server = address;
    absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = TryConnect(one);
    if (!channel.ok()) {
      if (absl::IsInvalidArgument(channel.status())) return kExitError;  // TLS files: said
      down.push_back(address);
      down_status = channel.status();
      down_why.push_back(absl::IsDeadlineExceeded(channel.status())
                             ? absl::StrFormat("nothing within %g s", inv.global.connect_timeout_s)
                             : std::string("connection failed"));
      continue;
    }
    auto stub = v1::RenderService::NewStub(*channel);
    if (!o.scene_file.empty()) {
      if (!UploadSceneFile(one, stub.get(), o.scene_file, &scene_id)) return kExitError;
    } else {
      std::string resolved;
      bool found = false;
      grpc::Status st = ResolveSceneId(stub.get(), o.scene, &resolved, nullptr, &found);
      if (!st.ok()) return ReportRpcError(one, st);
      if (!found)
        return ReportError(one,
                           absl::StrCat("scene ", o.scene, " is not on ", address,
                                        " (give --scene-file to upload it everywhere)"),
                           "NOT_FOUND");
      scene_id = resolved;
    }
    if (!first_stub) first_stub = std::move(stub);
  }
  if (!first_stub) {
    return ReportError(inv, absl::Status(down_status.code(),
                                         absl::StrCat("no daemon of --servers answers (",
                                                      absl::StrJoin(addresses, ", "),
                                                      "): is tesserad running there?")));
  }
  for (size_t i = 0; i < down.size(); ++i)
    absl::FPrintF(stderr, "tessera: job: tesserad at %s does not answer (%s); starting without "
                  "it, and trying it again every %g s\n", down[i], down_why[i],
                  kFarmProbeSeconds);
  absl::StatusOr<v1::JobSpec> spec = BuildSpec(first_stub.get(), o, scene_id);
  if (!spec.ok()) return ReportError(inv, spec.status());
  absl::StatusOr<std::vector<uint32_t>> frames = jobs::FrameNumbers(spec->frames(), 100000);
  if (!frames.ok()) return ReportError(inv, frames.status());
  if (!MakeOutDir(inv, o.out)) return kExitError;

  std::shared_ptr<grpc::Channel> channel = MakeChannel(inv, lb_target, /*round_robin=*/true);
  if (!channel) return kExitError;
  auto stub = v1::RenderService::NewStub(channel);

  struct Pending {
    uint32_t frame;
    uint32_t attempts;
    Clock::time_point not_before{};  // retries wait out their backoff
  };
  std::mutex mu;
  std::condition_variable cv;
  std::deque<Pending> queue;
  for (uint32_t f : *frames) queue.push_back({f, 0, {}});
  std::set<uint32_t> written;
  std::map<std::string, uint32_t> by_server;
  std::vector<double> frame_ms;
  uint32_t retried = 0;
  uint32_t busy = 0;
  std::string fatal;
  grpc::StatusCode fatal_code = grpc::StatusCode::OK;
  const Clock::time_point start = Clock::now();
  ProgressBar bar(absl::StrCat("farm x", addresses.size()), frames->size());
  const uint32_t parallel =
      o.parallel ? o.parallel : std::max<uint32_t>(2, 2 * uint32_t(addresses.size()));

  auto worker = [&] {
    std::unique_lock lock(mu);
    for (;;) {
      cv.wait(lock, [&] { return !fatal.empty() || !queue.empty() || busy == 0; });
      if (!fatal.empty() || queue.empty()) return;
      Pending p = queue.front();
      queue.pop_front();
      ++busy;
      lock.unlock();
      std::this_thread::sleep_until(p.not_before);
      v1::RenderJobFrameRequest request;
      *request.mutable_spec() = *spec;
      request.set_frame(p.frame);
      grpc::ClientContext context;
      SetDeadline(&context, o.frame_timeout_s);
      context.set_wait_for_ready(true);  // a daemon coming back is waited for, not failed
      v1::Frame frame;
      const Clock::time_point t0 = Clock::now();
      grpc::Status st = stub->RenderJobFrame(&context, request, &frame);
      const double ms = SecondsSince(t0) * 1000.0;
      std::string error;
      if (st.ok() &&
          !WriteFrameFile(o.out, jobs::FrameFileName(*spec, p.frame), frame.data(), &error))
        st = grpc::Status(grpc::StatusCode::INTERNAL, error);
      lock.lock();
      --busy;
      if (st.ok()) {
        written.insert(p.frame);
        ++by_server[context.peer()];
        frame_ms.push_back(ms);
      } else if (Retryable(st) && p.attempts + 1 < std::max(1u, o.retries) && error.empty()) {
        ++retried;
        // Back off (100 ms doubling, up to 3.2 s, with jitter) so a daemon that fails fast
        // while shutting down cannot use up a frame's tries before round_robin moves on.
        const int backoff_ms = (100 << std::min(p.attempts, 5u)) * (75 + std::rand() % 50) / 100;
        queue.push_back({p.frame, p.attempts + 1,
                         Clock::now() + std::chrono::milliseconds(backoff_ms)});
        bar.Clear();
        absl::FPrintF(stderr, "tessera: job: frame %u failed on %s (%s: %s); retrying\n",
                      p.frame, context.peer(), StatusCodeName(st.error_code()),
                      st.error_message());
      } else if (fatal.empty()) {
        fatal_code = st.error_code();
        fatal = absl::StrCat("frame ", p.frame, ": ", StatusCodeName(st.error_code()), ": ",
                             st.error_message());
      }
      std::string note = MsPerFrame(Median(frame_ms));
      if (retried) absl::StrAppend(&note, "  ", retried, " retried");
      bar.set_note(std::move(note));
      bar.Update(written.size());
      cv.notify_all();
    }
  };
  // The daemons that did not answer at the start, tried again until the job ends. One that
  // answers gets the scene (when the job uploads it); frames reach it through round_robin,
  // and a frame that lands there before its scene does is retried (NOT_FOUND scene_id).
  bool finished = false;
  std::thread prober([&] {
    std::unique_lock lock(mu);
    while (!down.empty()) {
      if (cv.wait_for(lock, std::chrono::duration<double>(kFarmProbeSeconds),
                      [&] { return finished; }))
        return;
      const std::vector<std::string> candidates = down;
      lock.unlock();
      std::vector<std::string> back;
      for (const std::string& address : candidates) {
        Invocation one = inv;
        one.global.server = address;
        one.global.connect_timeout_s = std::min(one.global.connect_timeout_s, kFarmProbeSeconds);
        absl::StatusOr<std::shared_ptr<grpc::Channel>> channel = TryConnect(one);
        if (!channel.ok()) continue;
        auto probe_stub = v1::RenderService::NewStub(*channel);
        std::string id;
        if (!o.scene_file.empty() && !UploadSceneFile(one, probe_stub.get(), o.scene_file, &id))
          continue;  // tried again at the next probe
        back.push_back(address);
      }
      lock.lock();
      for (const std::string& address : back) {
        down.erase(std::find(down.begin(), down.end(), address));
        bar.Clear();
        absl::FPrintF(stderr, "tessera: job: tesserad at %s answers now; it takes frames too\n",
                      address);
      }
    }
  });
  std::vector<std::thread> threads;
  for (uint32_t i = 0; i < parallel; ++i) threads.emplace_back(worker);
  for (std::thread& t : threads) t.join();
  {
    std::lock_guard lock(mu);
    finished = true;
  }
  cv.notify_all();
  prober.join();
  bar.Clear();
  const double seconds = SecondsSince(start);
  if (!fatal.empty()) return ReportError(inv, fatal, StatusCodeName(fatal_code));

  if (inv.global.json) {
    Json servers = Json::object();
    for (const auto& [peer, n] : by_server) servers[peer] = n;
    PrintJson({{"frames", written.size()},
               {"out", o.out},
               {"seconds", seconds},
               {"frame_ms_median", Median(frame_ms)},
               {"retried", retried},
               {"servers", servers},
               {"servers_down", down}});
  } else {
    absl::FPrintF(stderr, "%u frames to %s in %s (%.0f ms/frame median per call), %u retried\n",
                  written.size(), o.out, HumanDuration(seconds), Median(frame_ms), retried);
    for (const auto& [peer, n] : by_server) absl::FPrintF(stderr, "  %-28s %u frames\n", peer, n);
    for (const std::string& address : down)
      absl::FPrintF(stderr, "  %-28s did not answer\n", address);
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------

int RunSubmit(const Invocation& inv) {
  const SubmitOptions o = ParseSubmit(inv);
  if (!o.servers.empty()) return RunFarm(inv, o);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  std::string scene_id = o.scene;
  if (!o.scene_file.empty()) {
    if (!UploadSceneFile(inv, stub.get(), o.scene_file, &scene_id)) return kExitError;
  } else if (grpc::Status st = ResolveSceneId(stub.get(), o.scene, &scene_id); !st.ok()) {
    return ReportRpcError(inv, st);
  }
  absl::StatusOr<v1::JobSpec> spec = BuildSpec(stub.get(), o, scene_id);
  if (!spec.ok()) return ReportError(inv, spec.status());
  if (!o.out.empty() && !MakeOutDir(inv, o.out)) return kExitError;

  v1::Job job;
  {
    grpc::ClientContext context;
    SetDeadline(&context, kShortCallSeconds * 4);  // validates every frame's camera
    v1::SubmitJobRequest request;
    *request.mutable_spec() = *spec;
    if (grpc::Status st = stub->SubmitJob(&context, request, &job); !st.ok())
      return ReportRpcError(inv, st);
  }
  if (!inv.global.json) PrintJobLine(job);
  if (o.detach) {
    if (inv.global.json) {
      PrintJson({{"job", ToJson(job)}});
    } else {
      absl::PrintF("%s\n", job.job_id());
    }
    return 0;
  }
  Json frames = Json::array();
  v1::Job final_job = job;
  if (grpc::Status st = Watch(stub.get(), job.job_id(), &final_job, &frames); !st.ok())
    return ReportRpcError(inv, st);
  Json files = Json::array();
  if (!o.out.empty() && final_job.frames_done() > 0) {
    if (grpc::Status st = Fetch(inv, stub.get(), final_job, {}, o.out, &files); !st.ok())
      return ReportRpcError(inv, st);
  }
  if (inv.global.json) {
    PrintJson({{"job", ToJson(final_job)}, {"frames", frames}, {"files", files}});
  } else {
    PrintJobLine(final_job);
    if (!files.empty()) absl::FPrintF(stderr, "%u frames written to %s\n", files.size(), o.out);
    if (!final_job.output_path().empty())
      absl::FPrintF(stderr, "frames are on the server in %s\n", final_job.output_path());
    absl::PrintF("%s\n", final_job.job_id());
  }
  return final_job.state() == v1::JOB_SUCCEEDED ? 0 : kExitJobFailed;
}

// The job id argument of watch/cancel/fetch/rm.
std::string JobIdArg(ArgReader& args, std::string* id) {
  if (!args.IsPositional()) args.Unknown();
  if (!id->empty()) args.Fail("one job id at a time");
  *id = args.current();
  return *id;
}

Invocation SubInvocation(const Invocation& inv) {
  Invocation sub = inv;
  sub.args.erase(sub.args.begin());
  return sub;
}

// watch, cancel, rm: just the job id.
std::string OnlyJobId(const Invocation& inv) {
  Invocation sub = SubInvocation(inv);
  ArgReader args(sub);
  std::string id;
  while (args.Next()) JobIdArg(args, &id);
  if (id.empty()) args.Fail("which job? give its id (tessera job list)");
  return id;
}

int RunWatch(const Invocation& inv) {
  const std::string id = OnlyJobId(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  v1::Job job;
  Json frames = Json::array();
  if (grpc::Status st = Watch(stub.get(), id, &job, &frames); !st.ok())
    return ReportRpcError(inv, st);
  if (inv.global.json) {
    PrintJson({{"job", ToJson(job)}, {"frames", frames}});
  } else {
    PrintJobLine(job);
  }
  return job.state() == v1::JOB_SUCCEEDED ? 0 : kExitJobFailed;
}

int RunCancel(const Invocation& inv) {
  const std::string id = OnlyJobId(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  grpc::ClientContext context;
  SetDeadline(&context, kShortCallSeconds);
  v1::CancelJobRequest request;
  request.set_job_id(id);
  v1::Job job;
  if (grpc::Status st = stub->CancelJob(&context, request, &job); !st.ok())
    return ReportRpcError(inv, st);
  if (inv.global.json) {
    PrintJson({{"job", ToJson(job)}});
  } else {
    PrintJobLine(job);
  }
  return 0;
}

int RunRm(const Invocation& inv) {
  const std::string id = OnlyJobId(inv);
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  grpc::ClientContext context;
  SetDeadline(&context, kShortCallSeconds);
  v1::DeleteJobRequest request;
  request.set_job_id(id);
  v1::DeleteJobResponse response;
  if (grpc::Status st = stub->DeleteJob(&context, request, &response); !st.ok())
    return ReportRpcError(inv, st);
  if (inv.global.json) {
    PrintJson({{"deleted", id}});
  } else {
    absl::FPrintF(stderr, "job %s deleted\n", id);
  }
  return 0;
}

grpc::Status ListAll(v1::RenderService::Stub* stub, v1::ListJobsResponse* out) {
  grpc::ClientContext context;
  SetDeadline(&context, kShortCallSeconds);
  return stub->ListJobs(&context, v1::ListJobsRequest(), out);
}

int RunList(const Invocation& inv) {
  Invocation sub = SubInvocation(inv);
  ArgReader args(sub);
  while (args.Next()) args.Unknown();
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  v1::ListJobsResponse list;
  if (grpc::Status st = ListAll(stub.get(), &list); !st.ok()) return ReportRpcError(inv, st);
  if (inv.global.json) {
    Json jobs = Json::array();
    for (const v1::Job& j : list.jobs()) jobs.push_back(ToJson(j));
    PrintJson(jobs);
    return 0;
  }
  if (list.jobs().empty()) {
    absl::PrintF("no jobs\n");
    return 0;
  }
  absl::PrintF("%-16s  %-10s  %11s  %9s  %-12s  %s\n", "job", "state", "frames", "ms/frame",
               "scene", "name");
  for (const v1::Job& j : list.jobs()) {
    absl::PrintF("%-16s  %-10s  %5u/%-5u  %9.0f  %-12s  %s%s\n", j.job_id(), StateName(j.state()),
                 j.frames_done(), j.frames_total(), j.mean_frame_ms(), j.scene_id().substr(0, 12),
                 j.spec().name(), j.error().empty() ? "" : absl::StrCat("  (", j.error(), ")"));
  }
  return 0;
}

int RunFetch(const Invocation& inv) {
  Invocation sub = SubInvocation(inv);
  ArgReader args(sub);
  std::string id, out, frames_text;
  while (args.Next()) {
    if (args.Is("--out") || args.Is("-o")) {
      out = args.Value();
    } else if (args.Is("--frames")) {
      frames_text = args.Value();
    } else {
      JobIdArg(args, &id);
    }
  }
  if (id.empty()) args.Fail("which job? give its id (tessera job list)");
  if (out.empty()) args.Fail("where to? give --out DIR");
  std::vector<uint32_t> wanted;
  if (!frames_text.empty()) {
    v1::FrameRange range;
    if (!ParseFrameRange(frames_text, &range))
      args.Fail(absl::StrCat("--frames '", frames_text, "': use FIRST..LAST[:STEP]"));
    absl::StatusOr<std::vector<uint32_t>> f = jobs::FrameNumbers(range, 100000);
    if (!f.ok()) args.Fail(f.status().message());
    wanted = *f;
  }
  auto stub = ConnectStub(inv);
  if (!stub) return kExitError;
  v1::ListJobsResponse list;
  if (grpc::Status st = ListAll(stub.get(), &list); !st.ok()) return ReportRpcError(inv, st);
  auto it = std::find_if(list.jobs().begin(), list.jobs().end(),
                         [&](const v1::Job& j) { return j.job_id() == id; });
  if (it == list.jobs().end())
    return ReportRpcError(inv, grpc::Status(grpc::StatusCode::NOT_FOUND,
                                            absl::StrCat("job_id: no job \"", id, "\"")));
  if (!MakeOutDir(inv, out)) return kExitError;
  Json files = Json::array();
  if (grpc::Status st = Fetch(inv, stub.get(), *it, wanted, out, &files); !st.ok())
    return ReportRpcError(inv, st);
  if (inv.global.json) {
    PrintJson({{"job", ToJson(*it)}, {"files", files}});
  } else {
    absl::FPrintF(stderr, "%u frames written to %s\n", files.size(), out);
  }
  return 0;
}

int RunJob(const Invocation& inv) {
  if (inv.args.empty())
    UsageError("job", "which? submit, watch, cancel, list, fetch or rm (tessera job --help)");
  const std::string& verb = inv.args[0];
  if (verb == "submit") return RunSubmit(inv);
  if (verb == "watch") return RunWatch(inv);
  if (verb == "cancel") return RunCancel(inv);
  if (verb == "list") return RunList(inv);
  if (verb == "fetch") return RunFetch(inv);
  if (verb == "rm") return RunRm(inv);
  UsageError("job", absl::StrCat("unknown job command '", verb,
                                 "': submit, watch, cancel, list, fetch or rm"));
}

}  // namespace

const Command kJobCommand = {"job", "render-farm jobs: submit, watch, cancel, list, fetch, rm",
                             R"(usage: tessera job submit [options] [camera and settings flags]
       tessera job watch JOB | cancel JOB | rm JOB | list
       tessera job fetch JOB --out DIR [--frames FIRST..LAST[:STEP]]

submit: renders a frame range to files. With one server the job runs on it (SubmitJob) at
background priority, next to live viewers; the command shows a progress bar with an ETA
until the job ends and, with --out, fetches the frames. With --servers the frames are spread
over several daemons by gRPC's round_robin load balancing; a frame that fails on one daemon
(killed, shutting down) is retried on another, and every frame is written exactly once.
Frames are deterministic: the same job gives the same pixels on any daemon with the same device.
  --scene ID          a scene on the server(s) (default demo; 8+ character id prefixes work)
  --scene-file FILE   upload FILE (.glb/.gltf) first, to every server
  --frames A..B[:S]   frame numbers A to B inclusive, every S-th (default 0..0)
  --orbit             one turn around the scene over the frames
  --keyframes FILE    a camera path (JSON): {"interpolation": "linear|catmull_rom|step",
                      "keyframes": [{"frame": 0, "eye": [x,y,z], "target": [x,y,z],
                      "up": [0,1,0], "yfov": 0.8}, ...]}
                      (--eye/--target/--camera N give every frame one camera)
  --png               lossless PNG frames (default JPEG)
  --taa-frames N      with --aa taa: frames accumulated per output frame (1..64, default 8)
  --fps F             animated scenes (--animation): frame n shows the scene at --time + n / F
                      seconds (0..1000; default 0: every frame at --time)
  --out DIR           write the frames here (created), named by the pattern
  --pattern P         file names, e.g. shot_%04d.png (default frame_%05d.jpg/.png)
  --server-dir DIR    keep the frames on the server, under its --job_output_root/DIR
  --name TEXT         a label for `tessera job list`
  --detach            print the job id and return at once (watch it with `tessera job watch`)
  --servers LIST      several daemons: "host:port,host:port,..." or "dns:///name:port" (every
                      address the name resolves to, e.g. a Kubernetes headless Service)
  --parallel N        with --servers: frames in flight (default 2 per daemon)
  --retries N         with --servers: tries per frame (default 5)
  --frame-timeout SEC with --servers: deadline of one frame (default 600)
watch: a progress bar with an ETA on stderr (a terminal) until the job ends.
Exit status of submit and watch: 0 when every frame is done, 3 when the job ended failed or
cancelled (its Job, with the error, is still printed), 1 when the server could not be asked.
--json (one document on stdout, also on failure: {"error": {"code", "message"}}):
  submit, watch   {"job": Job, "frames": [per-frame events], "files": [...]} (submit --detach
                  and cancel: {"job": Job}); submit --servers: {"frames", "out", "seconds",
                  "frame_ms_median", "retried", "servers": {peer: frames}}
  list            [Job, ...]            fetch   {"job": Job, "files": [...]}
  rm              {"deleted": JOB}
)",
                             true, RunJob};

}  // namespace tessera::cli

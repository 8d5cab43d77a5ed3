#pragma once
// One live session (Stream) from the open event to Finish, as `tessera stream` and `tessera
// bench` run it: the events it sends, the frames it receives (kept without their images) and
// the figures of a run (medians, latency percentiles).
#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "clients/cli/cli_common.h"
#include "clients/cli/cli_render_flags.h"
#include "clients/cli/cli_stream_parts.h"
#include "tessera/v1/render_service.grpc.pb.h"

namespace tessera::cli {

// How the CLI asks for frames.
enum class Pacing {
  kPerFrame,    // one event (camera move or refresh) per received frame
  kSteadyRate,  // --orbit --fps F: a camera move every 1/F s, whatever the frames do
  kServerRate,  // --fps F alone: the session renders continuously at F fps
};

// What a session asks for.
struct SessionOptions {
  std::string scene = "demo";
  uint32_t frames = 10;  // frames to receive; with orbit, one turn takes this many moves
  bool orbit = false;
  float fps = 0;
  float interactive_scale = 0;  // > 0: enable the session's interactive profile at this scale
  int rest_ms = -1;             // the profile's rest time; -1: the server's default
  v1::VideoSettings video;      // --codec, --crf, ... (unset: JPEG frames)
  RenderFlags flags;

  Pacing pacing() const {
    // --play alone: the server renders the playing animation at its own rate.
    if (fps <= 0) return flags.settings().play() && !orbit ? Pacing::kServerRate : Pacing::kPerFrame;
    return orbit ? Pacing::kSteadyRate : Pacing::kServerRate;
  }
};

// One received frame, without its image.
struct FrameRecord {
  v1::Frame frame;
  uint64_t bytes = 0;                // of the encoded image (not kept)
  double received_ms = 0;            // since the open event was sent
  std::optional<double> latency_ms;  // of the newest event this frame answered first
};

// The video flags of `tessera stream` and `tessera bench` (--codec, --crf, --interactive-crf,
// --preset, --keyframe-interval, --max-bitrate, --encoder): true when the current argument was
// one of them. The server checks the ranges and names the field.
bool ParseVideoFlag(ArgReader& args, v1::VideoSettings* video);
// Their usage lines (a literal, so the commands' usage texts can include it).
#define TESSERA_VIDEO_FLAGS_USAGE                                                                 \
  "  --codec C           jpeg (default) or h264: an H.264 video stream (even sizes only)\n"       \
  "  --crf N             h264: constant quality 0..51 (server default 23; lower: better, bigger)\n" \
  "  --interactive-crf N h264 with --interactive: the quality while the camera moves (default 29)\n" \
  "  --preset P          h264: ultrafast, superfast (default), veryfast, faster, fast, medium\n"  \
  "  --keyframe-interval N  h264: a keyframe every N frames (default 0: only when needed)\n"     \
  "  --max-bitrate KBPS  h264: cap the bitrate (1 s buffer; default 0: no cap)\n"                 \
  "  --encoder E         h264: auto (hardware where the server has it; the default), software,\n" \
  "                      hardware\n"

// The orbit path when `o.orbit` is set: around the scene bounds (HasScene), or through the
// explicit --eye/--target. nullopt when the scene could not be described (the first frame's
// camera is used then). Also resolves a scene id prefix into `scene_id`.
grpc::Status PlanOrbit(v1::RenderService::Stub* stub, const SessionOptions& o,
                       std::string* scene_id, std::optional<Orbit>* orbit);

// The session from open to Finish.
class Session {
 public:
  // Called on the reading thread for every counted frame, in order, `index` from 1, with the
  // image still in record.frame.data() (it is dropped afterwards).
  using FrameHandler = std::function<void(const FrameRecord& record, uint32_t index)>;

  Session(const SessionOptions& o, FrameHandler on_frame) : o_(o), on_frame_(std::move(on_frame)) {}

  // Runs the session until o.frames frames arrived or the call ended; the call's status.
  // Called again (on another server, after this one was lost), the session goes on: a new
  // Stream opened with the next event id and orbit step, frames counted on, one clock.
  grpc::Status Run(v1::RenderService::Stub* stub, const std::string& scene_id,
                   std::optional<Orbit> orbit);
  double ElapsedMs() const;  // since the first Run's open event

  const std::vector<FrameRecord>& records() const { return records_; }
  // (event id, ms from sending it to the first frame reflecting it), in id order.
  const std::vector<std::pair<uint64_t, double>>& latencies() const { return latencies_; }
  uint32_t extra_frames() const { return extra_frames_; }

 private:
  class Events;
  void ReadFrames(grpc::ClientReaderWriter<v1::ClientEvent, v1::Frame>* stream, EventWriter* writer,
                  Events* events);

  const SessionOptions& o_;
  FrameHandler on_frame_;
  LatencyTracker latency_;
  Clock::time_point start_;
  std::vector<FrameRecord> records_;
  std::vector<std::pair<uint64_t, double>> latencies_;
  uint32_t extra_frames_ = 0;
  // Carried from one Run to the next.
  uint32_t runs_ = 0;
  uint64_t next_event_id_ = 1;
  uint64_t step_ = 0;
  std::optional<Orbit> orbit_;
};

// The figures of a run, computed once from its records.
struct Summary {
  uint32_t frames = 0;
  uint32_t extra_frames = 0;  // arrived after the half-close, not counted
  double seconds = 0;         // open event sent -> last frame received
  double fps = 0;             // between the first and the last frame
  uint64_t dropped = 0;       // sequence numbers never received
  std::optional<double> first_frame_ms;
  std::vector<double> latencies_ms;                            // events after the open event
  std::vector<std::pair<std::string, double>> pass_median_ms;  // in pass order
  std::vector<std::pair<double, double>> pass_p10_p90_ms;      // the same passes' spread
  double gpu_total_median_ms = 0;
  double gpu_total_p10_ms = 0, gpu_total_p90_ms = 0;  // the spread: one slow frame shows here
  double cpu_total_median_ms = 0;
  double bytes_median = 0;
  uint64_t bytes_total = 0;
  // Payload bits per second between the first and the last frame (the first frame's bytes
  // excluded: they arrived at the start of the span); 0 with fewer than 2 frames.
  double bitrate_kbps = 0;
  uint32_t keyframes = 0;  // video frames that were keyframes
  std::string codec;       // "jpeg", "png" or the video codec string of the last frame
};

// The figures of `records` (received in order). `latencies` as Session::latencies(); the
// open event's (id 1) is first_frame_ms, not a latency sample.
Summary Summarize(const std::vector<FrameRecord>& records,
                  const std::vector<std::pair<uint64_t, double>>& latencies);

// {"median", "p95", "events", "samples"} of a run's latencies (ms), for --json.
Json LatencyJson(const Summary& s);
// [{"pass", "median_ms", "p10_ms", "p90_ms"}, ...] in pass order, for --json.
Json PassMediansJson(const Summary& s);

}  // namespace tessera::cli

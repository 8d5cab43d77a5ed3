#pragma once
// Video coding for Stream sessions and their clients, through FFmpeg's libraries (Debian's
// libavcodec with libx264 and NVENC, libswscale, libavformat). FFmpeg's headers stay in
// video.cpp.
//
//  - Encoder: RGBA frames in, one H.264 access unit (Annex B) out per frame, at once: no
//    B-frames, no lookahead, no frame held back (tune zerolatency). libx264 on the CPU, or NVENC
//    where the machine has it. Keyframes (IDR with SPS/PPS) on request and every
//    keyframe_interval frames; the constant-quality factor may change from frame to frame.
//  - Decoder: the same stream back to RGBA (tests, benchmarks, the CLI's checks).
//  - VideoFileWriter: a session's packets into an .h264 (Annex B) or .mp4 file (tessera stream
//    --save), with each frame's arrival time as its presentation time.
//
// RGB <-> YUV uses BT.709 coefficients, limited range, and the stream says so (with the sRGB
// transfer function), so a browser's decoder turns it back into the same colours.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace tessera::video {

enum class EncoderKind { kAuto, kSoftware, kHardware };

// The presets sessions may ask for (libx264's names, fastest first).
const std::vector<std::string>& Presets();

// The largest frame a session may stream: H.264 level 5.2's 36864 macroblocks (4096x2304), at
// most 4096 on a side (NVENC's limit too); browsers refuse larger streams.
inline constexpr uint32_t kMaxVideoSide = 4096;
inline constexpr uint32_t kMaxVideoMacroblocks = 36864;
// Whether one side can be a video frame's: even, 16..kMaxVideoSide.
bool VideoSideOk(uint32_t side);
// INVALID_ARGUMENT when w x h cannot be a video frame (a side not VideoSideOk, or more
// macroblocks than kMaxVideoMacroblocks).
absl::Status CheckVideoSize(uint32_t width, uint32_t height);

struct EncoderOptions {
  uint32_t width = 0;  // CheckVideoSize
  uint32_t height = 0;
  EncoderKind kind = EncoderKind::kAuto;
  uint32_t crf = 23;                 // 1..51: constant quality (rate factor; NVENC: its cq)
  // 0: no cap; else a VBV cap with a buffer of the same size. The rate control counts frames at
  // a nominal 30 per second (sessions render at a varying rate), so the cap is per 30 frames.
  uint32_t max_bitrate_kbps = 0;
  uint32_t keyframe_interval = 0;    // frames; 0: keyframes only when asked for
  std::string preset = "superfast";  // one of Presets()
  // Encoder threads (libx264 slices). 0: one per 1280x720 pixels, at most the cores.
  uint32_t threads = 0;
};

struct Packet {
  std::vector<uint8_t> data;  // one access unit, Annex B
  bool keyframe = false;
};

class Encoder {
 public:
  // FAILED_PRECONDITION when kHardware is asked for and the machine has no hardware encoder;
  // INVALID_ARGUMENT for odd or tiny sizes or an unknown preset.
  static absl::StatusOr<std::unique_ptr<Encoder>> Create(const EncoderOptions& options);
  ~Encoder();

  // Encodes one frame of width x height RGBA8 pixels, rows `stride` bytes apart. `crf`: this
  // frame's quality factor (nullopt: the options'); libx264 only (NVENC keeps the cq it was
  // opened with: see per_frame_crf()).
  absl::StatusOr<Packet> Encode(const uint8_t* rgba, size_t stride, bool keyframe,
                                std::optional<uint32_t> crf = std::nullopt);

  // "libx264" or "h264_nvenc".
  const char* name() const;
  // Whether Encode's `crf` applies (libx264); otherwise a new quality needs a new encoder.
  bool per_frame_crf() const;
  uint32_t crf() const;  // the factor it opened with
  // The RFC 6381 codec string of the stream ("avc1.PPCCLL" from its SPS); empty before the
  // first keyframe.
  const std::string& codec_string() const;
  uint32_t width() const;
  uint32_t height() const;
  uint64_t frames() const;  // encoded so far

  struct Impl;

 private:
  explicit Encoder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Whether a hardware H.264 encoder (NVENC) opens on this machine; probed once.
bool HardwareEncoderAvailable();
// The encoders EncoderKind::kAuto tries, in its order: "h264_nvenc" where it opens, "libx264".
std::vector<std::string> EncoderNames();

// The RFC 6381 codec string ("avc1.64001f") of the first SPS in an Annex B stream; empty
// without one.
std::string CodecStringFromAnnexB(const uint8_t* data, size_t size);

struct DecodedFrame {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> rgba;  // width * height * 4
};

class Decoder {
 public:
  static absl::StatusOr<std::unique_ptr<Decoder>> Create();
  ~Decoder();
  // One access unit in, its picture out (the encoder's streams have no reordering delay).
  // An error for data that does not decode, for a delta frame before the first keyframe, and
  // for a gap in the stream: a frame whose frame_num does not follow the previous reference
  // frame's (libavcodec itself would conceal the gap with copies and report nothing).
  absl::StatusOr<DecodedFrame> Decode(const uint8_t* data, size_t size);

  struct Impl;

 private:
  explicit Decoder(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// Writes H.264 packets to `path`: ".mp4" through libavformat's MP4 muxer (the first packet
// must be a keyframe: its SPS/PPS become the track's configuration), anything else as a raw
// Annex B stream. A size change needs a new file (the CLI starts one).
class VideoFileWriter {
 public:
  static absl::StatusOr<std::unique_ptr<VideoFileWriter>> Open(const std::string& path,
                                                               uint32_t width, uint32_t height);
  ~VideoFileWriter();  // Close() if not closed
  // `time_ms`: the frame's presentation time from the stream's start.
  absl::Status Write(const uint8_t* data, size_t size, bool keyframe, double time_ms);
  absl::Status Close();
  uint64_t frames() const;

  struct Impl;

 private:
  explicit VideoFileWriter(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace tessera::video

#include "common/video.h"

#include <algorithm>
#include <cstdio>
#include <mutex>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}

namespace tessera::video {
namespace {

std::string AvError(int err) {
  char buf[AV_ERROR_MAX_STRING_SIZE] = {};
  av_strerror(err, buf, sizeof(buf));
  return buf;
}

struct CodecCtxFree {
  void operator()(AVCodecContext* c) const { avcodec_free_context(&c); }
};
struct FrameFree {
  void operator()(AVFrame* f) const { av_frame_free(&f); }
};
struct PacketFree {
  void operator()(AVPacket* p) const { av_packet_free(&p); }
};
struct SwsFree {
  void operator()(SwsContext* s) const { sws_freeContext(s); }
};
using CodecCtx = std::unique_ptr<AVCodecContext, CodecCtxFree>;
using FramePtr = std::unique_ptr<AVFrame, FrameFree>;
using PacketPtr = std::unique_ptr<AVPacket, PacketFree>;
using SwsPtr = std::unique_ptr<SwsContext, SwsFree>;

// FFmpeg logs to stderr by default: the encoders' chatter goes, and so do the errors, which
// come back as statuses (the NVENC probe's "Cannot load libcuda.so.1" on a machine without one).
void QuietFfmpeg() {
  static std::once_flag once;
  std::call_once(once, [] { av_log_set_level(AV_LOG_FATAL); });
}

// BT.709 limited range, sRGB transfer: what the encoder writes into the stream's VUI and what
// RGB <-> YUV conversion uses in both directions.
void SetColour(AVCodecContext* c) {
  c->colorspace = AVCOL_SPC_BT709;
  c->color_primaries = AVCOL_PRI_BT709;
  c->color_trc = AVCOL_TRC_IEC61966_2_1;
  c->color_range = AVCOL_RANGE_MPEG;
}

SwsContext* RgbaToYuv(uint32_t w, uint32_t h) {
  SwsContext* s = sws_getContext(static_cast<int>(w), static_cast<int>(h), AV_PIX_FMT_RGBA,
                                 static_cast<int>(w), static_cast<int>(h), AV_PIX_FMT_YUV420P,
                                 SWS_BILINEAR | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INP, nullptr, nullptr, nullptr);
  if (s) {
    const int* bt709 = sws_getCoefficients(SWS_CS_ITU709);
    sws_setColorspaceDetails(s, bt709, /*srcRange=*/1, bt709, /*dstRange=*/0, 0, 1 << 16,
                             1 << 16);
  }
  return s;
}

const char* NvencPreset(const std::string& preset) {
  const std::vector<std::string>& all = Presets();
  static const char* kNv[] = {"p1", "p2", "p3", "p4", "p5", "p6"};
  const size_t i = std::find(all.begin(), all.end(), preset) - all.begin();
  return kNv[std::min<size_t>(i, 5)];
}

uint32_t DefaultThreads(uint32_t w, uint32_t h) {
  const uint64_t pixels = uint64_t{w} * h;
  const uint32_t want = static_cast<uint32_t>((pixels + 1280 * 720 - 1) / (1280 * 720));
  return std::clamp(want, 1u, std::max(1u, std::thread::hardware_concurrency()));
}

absl::StatusOr<CodecCtx> OpenEncoder(const EncoderOptions& o, bool hardware) {
  const char* name = hardware ? "h264_nvenc" : "libx264";
  const AVCodec* codec = avcodec_find_encoder_by_name(name);
  if (!codec) return absl::UnavailableError(absl::StrCat(name, " is not in this libavcodec"));
  CodecCtx c(avcodec_alloc_context3(codec));
  if (!c) return absl::ResourceExhaustedError("avcodec_alloc_context3 failed");
  c->width = static_cast<int>(o.width);
  c->height = static_cast<int>(o.height);
  c->pix_fmt = AV_PIX_FMT_YUV420P;
  c->time_base = AVRational{1, 30};
  c->framerate = AVRational{30, 1};
  c->max_b_frames = 0;
  // 0: keyframes only when asked for (a reliable transport never loses a reference).
  c->gop_size = o.keyframe_interval > 0 ? static_cast<int>(o.keyframe_interval)
                                        : (hardware ? -1 : (1 << 30));
  SetColour(c.get());
  if (o.max_bitrate_kbps > 0) {
    c->rc_max_rate = int64_t{o.max_bitrate_kbps} * 1000;
    c->rc_buffer_size = static_cast<int>(std::min<int64_t>(c->rc_max_rate, INT32_MAX));
  }
  AVDictionary* opts = nullptr;
  if (hardware) {
    av_dict_set(&opts, "preset", NvencPreset(o.preset), 0);
    av_dict_set(&opts, "tune", "ull", 0);
    av_dict_set(&opts, "zerolatency", "1", 0);
    av_dict_set(&opts, "delay", "0", 0);
    av_dict_set(&opts, "rc", "vbr", 0);
    av_dict_set_int(&opts, "cq", std::max(1u, o.crf), 0);
    av_dict_set(&opts, "forced-idr", "1", 0);
  } else {
    c->thread_count = static_cast<int>(o.threads ? o.threads : DefaultThreads(o.width, o.height));
    av_dict_set(&opts, "preset", o.preset.c_str(), 0);
    av_dict_set(&opts, "tune", "zerolatency", 0);
    av_dict_set(&opts, "crf", std::to_string(o.crf).c_str(), 0);
    av_dict_set(&opts, "forced-idr", "1", 0);
  }
  const int err = avcodec_open2(c.get(), codec, &opts);
  av_dict_free(&opts);
  if (err < 0) return absl::UnavailableError(absl::StrCat(name, ": ", AvError(err)));
  return c;
}

// Reads the bits of one NAL unit's payload (emulation-prevention bytes removed).
class BitReader {
 public:
  BitReader(const uint8_t* p, size_t n) {
    for (size_t i = 0; i < n; ++i) {
      if (i >= 2 && p[i] == 3 && p[i - 1] == 0 && p[i - 2] == 0 && rbsp_.size() >= 2 &&
          rbsp_[rbsp_.size() - 1] == 0 && rbsp_[rbsp_.size() - 2] == 0)
        continue;
      rbsp_.push_back(p[i]);
    }
  }
  uint32_t U(int n) {
    uint32_t v = 0;
    for (int i = 0; i < n; ++i) {
      if (bit_ >= rbsp_.size() * 8) {
        ok_ = false;
        return 0;
      }
      v = (v << 1) | ((rbsp_[bit_ / 8] >> (7 - bit_ % 8)) & 1u);
      ++bit_;
    }
    return v;
  }
  uint32_t Ue() {  // Exp-Golomb
    int zeros = 0;
    while (ok_ && U(1) == 0) {
      if (++zeros > 31) ok_ = false;
    }
    return ok_ ? (1u << zeros) - 1 + U(zeros) : 0;
  }
  bool ok() const { return ok_; }

 private:
  std::vector<uint8_t> rbsp_;
  size_t bit_ = 0;
  bool ok_ = true;
};

// The NAL units of an Annex B access unit: (header byte offset, size) pairs.
std::vector<std::pair<size_t, size_t>> NalUnits(const uint8_t* d, size_t n) {
  std::vector<std::pair<size_t, size_t>> out;
  size_t i = 0, start = SIZE_MAX;
  while (i + 2 < n) {
    if (d[i] == 0 && d[i + 1] == 0 && d[i + 2] == 1) {
      if (start != SIZE_MAX) {
        size_t end = i;
        while (end > start && d[end - 1] == 0) --end;  // trailing zeros of a 4-byte start code
        out.emplace_back(start, end - start);
      }
      i += 3;
      start = i;
    } else {
      ++i;
    }
  }
  if (start != SIZE_MAX && start < n) out.emplace_back(start, n - start);
  return out;
}

}  // namespace

bool VideoSideOk(uint32_t side) { return side >= 16 && side % 2 == 0 && side <= kMaxVideoSide; }

std::vector<std::string> EncoderNames() {
  if (HardwareEncoderAvailable()) return {"h264_nvenc", "libx264"};
  return {"libx264"};
}

absl::Status CheckVideoSize(uint32_t w, uint32_t h) {
  const uint64_t mbs = uint64_t{(w + 15) / 16} * ((h + 15) / 16);
  if (!VideoSideOk(w) || !VideoSideOk(h) || mbs > kMaxVideoMacroblocks)
    return absl::InvalidArgumentError(absl::StrCat(
        w, "x", h, " cannot be an H.264 frame here: even sizes of 16..", kMaxVideoSide,
        " with at most ", kMaxVideoMacroblocks, " macroblocks (level 5.2, e.g. 4096x2304)"));
  return absl::OkStatus();
}

const std::vector<std::string>& Presets() {
  static const std::vector<std::string> kPresets = {"ultrafast", "superfast", "veryfast",
                                                    "faster",    "fast",      "medium"};
  return kPresets;
}

std::string CodecStringFromAnnexB(const uint8_t* data, size_t size) {
  for (const auto& [at, len] : NalUnits(data, size)) {
    if ((data[at] & 0x1f) != 7 || len < 4) continue;  // the SPS: profile, constraints, level
    char buf[16];
    std::snprintf(buf, sizeof(buf), "avc1.%02x%02x%02x", data[at + 1], data[at + 2], data[at + 3]);
    return buf;
  }
  return "";
}

// ---------------------------------------------------------------------------------------------
// Encoder

struct Encoder::Impl {
  EncoderOptions options;
  bool hardware = false;
  CodecCtx ctx;
  FramePtr frame;
  PacketPtr packet;
  SwsPtr sws;
  std::string codec_string;
  uint64_t frames = 0;
  uint32_t crf = 0;  // the factor libx264 runs at now
};

bool HardwareEncoderAvailable() {
  static const bool available = [] {
    QuietFfmpeg();
    EncoderOptions o;
    o.width = 256;
    o.height = 256;
    return OpenEncoder(o, /*hardware=*/true).ok();
  }();
  return available;
}

absl::StatusOr<std::unique_ptr<Encoder>> Encoder::Create(const EncoderOptions& o) {
  QuietFfmpeg();
  if (absl::Status st = CheckVideoSize(o.width, o.height); !st.ok()) return st;
  if (std::find(Presets().begin(), Presets().end(), o.preset) == Presets().end())
    return absl::InvalidArgumentError(absl::StrCat("preset \"", o.preset, "\" is not one of ",
                                                   absl::StrJoin(Presets(), ", ")));
  // crf 0 would be lossless, in the High 4:4:4 Predictive profile browsers do not decode.
  if (o.crf < 1 || o.crf > 51)
    return absl::InvalidArgumentError(absl::StrCat("crf ", o.crf, " is not in 1..51"));
  auto impl = std::make_unique<Impl>();
  impl->options = o;
  absl::StatusOr<CodecCtx> ctx = absl::UnavailableError("");
  if (o.kind != EncoderKind::kSoftware && HardwareEncoderAvailable()) {
    ctx = OpenEncoder(o, /*hardware=*/true);
    impl->hardware = ctx.ok();
  }
  if (o.kind == EncoderKind::kHardware && !ctx.ok())
    return absl::FailedPreconditionError(
        absl::StrCat("no hardware H.264 encoder opens on this server (h264_nvenc",
                     ctx.status().message().empty() ? "" : ": ", ctx.status().message(), ")"));
  if (!ctx.ok()) ctx = OpenEncoder(o, /*hardware=*/false);
  if (!ctx.ok()) return ctx.status();
  impl->ctx = *std::move(ctx);
  impl->crf = o.crf;
  impl->frame.reset(av_frame_alloc());
  impl->packet.reset(av_packet_alloc());
  if (!impl->frame || !impl->packet) return absl::ResourceExhaustedError("av_frame_alloc failed");
  impl->frame->format = AV_PIX_FMT_YUV420P;
  impl->frame->width = static_cast<int>(o.width);
  impl->frame->height = static_cast<int>(o.height);
  impl->frame->colorspace = AVCOL_SPC_BT709;
  impl->frame->color_range = AVCOL_RANGE_MPEG;
  if (int err = av_frame_get_buffer(impl->frame.get(), 0); err < 0)
    return absl::ResourceExhaustedError(absl::StrCat("av_frame_get_buffer: ", AvError(err)));
  impl->sws.reset(RgbaToYuv(o.width, o.height));
  if (!impl->sws) return absl::InternalError("sws_getContext failed for RGBA -> YUV420P");
  return std::unique_ptr<Encoder>(new Encoder(std::move(impl)));
}

Encoder::Encoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Encoder::~Encoder() = default;

const char* Encoder::name() const { return impl_->hardware ? "h264_nvenc" : "libx264"; }
bool Encoder::per_frame_crf() const { return !impl_->hardware; }
uint32_t Encoder::crf() const { return impl_->options.crf; }
const std::string& Encoder::codec_string() const { return impl_->codec_string; }
uint32_t Encoder::width() const { return impl_->options.width; }
uint32_t Encoder::height() const { return impl_->options.height; }
uint64_t Encoder::frames() const { return impl_->frames; }

absl::StatusOr<Packet> Encoder::Encode(const uint8_t* rgba, size_t stride, bool keyframe,
                                       std::optional<uint32_t> crf) {
  Impl& m = *impl_;
  AVFrame* f = m.frame.get();
  if (int err = av_frame_make_writable(f); err < 0)
    return absl::ResourceExhaustedError(absl::StrCat("av_frame_make_writable: ", AvError(err)));
  const uint8_t* src[1] = {rgba};
  const int src_stride[1] = {static_cast<int>(stride)};
  sws_scale(m.sws.get(), src, src_stride, 0, static_cast<int>(m.options.height), f->data,
            f->linesize);
  const uint32_t want_crf = std::clamp(crf.value_or(m.options.crf), 1u, 51u);
  if (!m.hardware && want_crf != m.crf) {
    // libx264 reconfigures its rate factor before the next frame when the option changed.
    av_opt_set_double(m.ctx->priv_data, "crf", want_crf, 0);
    m.crf = want_crf;
  }
  f->pts = static_cast<int64_t>(m.frames);
  f->pict_type = keyframe || m.frames == 0 ? AV_PICTURE_TYPE_I : AV_PICTURE_TYPE_NONE;
  if (int err = avcodec_send_frame(m.ctx.get(), f); err < 0)
    return absl::InternalError(absl::StrCat(name(), " rejected a frame: ", AvError(err)));
  AVPacket* p = m.packet.get();
  const int err = avcodec_receive_packet(m.ctx.get(), p);
  if (err == AVERROR(EAGAIN))
    return absl::InternalError(absl::StrCat(name(), " held a frame back (expected none)"));
  if (err < 0) return absl::InternalError(absl::StrCat(name(), ": ", AvError(err)));
  Packet out;
  out.data.assign(p->data, p->data + p->size);
  out.keyframe = (p->flags & AV_PKT_FLAG_KEY) != 0;
  av_packet_unref(p);
  if (out.keyframe && m.codec_string.empty())
    m.codec_string = CodecStringFromAnnexB(out.data.data(), out.data.size());
  ++m.frames;
  return out;
}

// ---------------------------------------------------------------------------------------------
// Decoder

struct Decoder::Impl {
  CodecCtx ctx;
  FramePtr frame;
  PacketPtr packet;
  SwsPtr sws;
  int sws_w = 0, sws_h = 0, sws_fmt = -1;
  // frame_num bookkeeping (CheckFrameNum).
  int log2_max_frame_num = 0;  // from the SPS; 0: unknown (no check)
  bool separate_colour_plane = false;
  bool have_reference = false;
  uint32_t prev_ref_frame_num = 0;

  // libavcodec conceals a missing reference frame with a copy and says nothing: the frame_num
  // of every picture after an IDR must be one more than the previous reference picture's.
  absl::Status CheckFrameNum(const uint8_t* d, size_t n);
};

absl::Status Decoder::Impl::CheckFrameNum(const uint8_t* d, size_t n) {
  for (const auto& [at, len] : NalUnits(d, n)) {
    if (len < 2) continue;
    const int type = d[at] & 0x1f;
    const int ref_idc = (d[at] >> 5) & 3;
    BitReader r(d + at + 1, len - 1);
    if (type == 7) {  // SPS
      const uint32_t profile = r.U(8);
      r.U(16);  // constraint flags, level
      r.Ue();   // seq_parameter_set_id
      separate_colour_plane = false;
      bool scaling = false;
      for (uint32_t hp : {100u, 110u, 122u, 244u, 44u, 83u, 86u, 118u, 128u, 138u, 139u, 134u, 135u}) {
        if (profile != hp) continue;
        if (r.Ue() == 3) separate_colour_plane = r.U(1) != 0;  // chroma_format_idc
        r.Ue();                                               // bit depths
        r.Ue();
        r.U(1);                    // qpprime_y_zero_transform_bypass
        scaling = r.U(1) != 0;     // seq_scaling_matrix_present: lists follow (not parsed)
      }
      log2_max_frame_num = scaling || !r.ok() ? 0 : static_cast<int>(r.Ue()) + 4;
      if (!r.ok() || log2_max_frame_num > 16) log2_max_frame_num = 0;
    } else if (type == 1 || type == 5) {  // a slice
      if (r.Ue() != 0) continue;           // first_mb_in_slice: the picture's first slice only
      r.Ue();                              // slice_type
      r.Ue();                              // pic_parameter_set_id
      if (separate_colour_plane) r.U(2);
      if (log2_max_frame_num == 0) continue;
      const uint32_t frame_num = r.U(log2_max_frame_num);
      if (!r.ok()) continue;
      if (type == 5) {
        have_reference = true;
      } else if (!have_reference) {
        return absl::InvalidArgumentError("h264 decode: a delta frame before any keyframe");
      } else {
        const uint32_t due = (prev_ref_frame_num + 1) & ((1u << log2_max_frame_num) - 1);
        if (frame_num != due)
          return absl::InvalidArgumentError(absl::StrCat(
              "h264 decode: frame_num ", frame_num, " where ", due,
              " was due: a frame of the stream is missing"));
      }
      if (ref_idc != 0) prev_ref_frame_num = frame_num;
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Decoder>> Decoder::Create() {
  QuietFfmpeg();
  const AVCodec* codec = avcodec_find_decoder(AV_CODEC_ID_H264);
  if (!codec) return absl::UnavailableError("no H.264 decoder in this libavcodec");
  auto impl = std::make_unique<Impl>();
  impl->ctx.reset(avcodec_alloc_context3(codec));
  impl->frame.reset(av_frame_alloc());
  impl->packet.reset(av_packet_alloc());
  if (!impl->ctx || !impl->frame || !impl->packet)
    return absl::ResourceExhaustedError("allocating the H.264 decoder failed");
  impl->ctx->thread_count = 1;  // no frame threading: one picture out per packet in
  impl->ctx->flags |= AV_CODEC_FLAG_LOW_DELAY;
  if (int err = avcodec_open2(impl->ctx.get(), codec, nullptr); err < 0)
    return absl::InternalError(absl::StrCat("h264 decoder: ", AvError(err)));
  return std::unique_ptr<Decoder>(new Decoder(std::move(impl)));
}

Decoder::Decoder(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Decoder::~Decoder() = default;

absl::StatusOr<DecodedFrame> Decoder::Decode(const uint8_t* data, size_t size) {
  Impl& m = *impl_;
  if (absl::Status st = m.CheckFrameNum(data, size); !st.ok()) return st;
  AVPacket* p = m.packet.get();
  if (int err = av_new_packet(p, static_cast<int>(size)); err < 0)
    return absl::ResourceExhaustedError(AvError(err));
  std::copy(data, data + size, p->data);
  int err = avcodec_send_packet(m.ctx.get(), p);
  av_packet_unref(p);
  if (err < 0) return absl::InvalidArgumentError(absl::StrCat("h264 decode: ", AvError(err)));
  AVFrame* f = m.frame.get();
  err = avcodec_receive_frame(m.ctx.get(), f);
  if (err == AVERROR(EAGAIN))
    return absl::InvalidArgumentError("h264 decode: the packet gave no picture");
  if (err < 0) return absl::InvalidArgumentError(absl::StrCat("h264 decode: ", AvError(err)));
  if (f->decode_error_flags != 0 || (f->flags & AV_FRAME_FLAG_CORRUPT))
    return absl::InvalidArgumentError("h264 decode: the picture is corrupt (missing references)");
  if (!m.sws || m.sws_w != f->width || m.sws_h != f->height || m.sws_fmt != f->format) {
    m.sws.reset(sws_getContext(f->width, f->height, static_cast<AVPixelFormat>(f->format),
                               f->width, f->height, AV_PIX_FMT_RGBA,
                               SWS_BILINEAR | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT, nullptr,
                               nullptr, nullptr));
    if (!m.sws) return absl::InternalError("sws_getContext failed for YUV -> RGBA");
    const int* bt709 = sws_getCoefficients(SWS_CS_ITU709);
    sws_setColorspaceDetails(m.sws.get(), bt709, /*srcRange=*/0, bt709, /*dstRange=*/1, 0,
                             1 << 16, 1 << 16);
    m.sws_w = f->width;
    m.sws_h = f->height;
    m.sws_fmt = f->format;
  }
  DecodedFrame out;
  out.width = static_cast<uint32_t>(f->width);
  out.height = static_cast<uint32_t>(f->height);
  out.rgba.resize(size_t{out.width} * out.height * 4);
  uint8_t* dst[1] = {out.rgba.data()};
  const int dst_stride[1] = {static_cast<int>(out.width * 4)};
  sws_scale(m.sws.get(), f->data, f->linesize, 0, f->height, dst, dst_stride);
  av_frame_unref(f);
  return out;
}

// ---------------------------------------------------------------------------------------------
// VideoFileWriter

struct VideoFileWriter::Impl {
  std::string path;
  bool mp4 = false;
  uint32_t width = 0, height = 0;
  FILE* raw = nullptr;
  AVFormatContext* fmt = nullptr;
  AVStream* stream = nullptr;
  bool header_written = false;
  bool closed = false;
  uint64_t frames = 0;
  int64_t last_pts = -1;
};

absl::StatusOr<std::unique_ptr<VideoFileWriter>> VideoFileWriter::Open(const std::string& path,
                                                                       uint32_t width,
                                                                       uint32_t height) {
  QuietFfmpeg();
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->width = width;
  impl->height = height;
  impl->mp4 = path.size() > 4 && path.compare(path.size() - 4, 4, ".mp4") == 0;
  if (!impl->mp4) {
    impl->raw = std::fopen(path.c_str(), "wb");
    if (!impl->raw) return absl::NotFoundError(absl::StrCat(path, ": cannot create the file"));
  } else {
    if (int err = avformat_alloc_output_context2(&impl->fmt, nullptr, "mp4", path.c_str());
        err < 0)
      return absl::InternalError(absl::StrCat(path, ": ", AvError(err)));
    if (int err = avio_open(&impl->fmt->pb, path.c_str(), AVIO_FLAG_WRITE); err < 0) {
      avformat_free_context(impl->fmt);
      impl->fmt = nullptr;
      return absl::NotFoundError(absl::StrCat(path, ": ", AvError(err)));
    }
    impl->stream = avformat_new_stream(impl->fmt, nullptr);
    if (!impl->stream) {
      avio_closep(&impl->fmt->pb);
      avformat_free_context(impl->fmt);
      impl->fmt = nullptr;
      return absl::ResourceExhaustedError("avformat_new_stream failed");
    }
    AVCodecParameters* par = impl->stream->codecpar;
    par->codec_type = AVMEDIA_TYPE_VIDEO;
    par->codec_id = AV_CODEC_ID_H264;
    par->width = static_cast<int>(width);
    par->height = static_cast<int>(height);
    par->color_space = AVCOL_SPC_BT709;
    par->color_primaries = AVCOL_PRI_BT709;
    par->color_trc = AVCOL_TRC_IEC61966_2_1;
    par->color_range = AVCOL_RANGE_MPEG;
    impl->stream->time_base = AVRational{1, 1000};
  }
  return std::unique_ptr<VideoFileWriter>(new VideoFileWriter(std::move(impl)));
}

VideoFileWriter::VideoFileWriter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

VideoFileWriter::~VideoFileWriter() { (void)Close(); }

uint64_t VideoFileWriter::frames() const { return impl_->frames; }

absl::Status VideoFileWriter::Write(const uint8_t* data, size_t size, bool keyframe,
                                    double time_ms) {
  Impl& m = *impl_;
  if (m.closed) return absl::FailedPreconditionError(absl::StrCat(m.path, ": already closed"));
  if (!m.mp4) {
    if (std::fwrite(data, 1, size, m.raw) != size)
      return absl::DataLossError(absl::StrCat(m.path, ": write failed"));
    ++m.frames;
    return absl::OkStatus();
  }
  if (!m.header_written) {
    if (!keyframe)
      return absl::FailedPreconditionError(
          absl::StrCat(m.path, ": an MP4 track must start with a keyframe"));
    // The keyframe's SPS and PPS (Annex B) become the track's configuration; the MP4 muxer
    // turns them into an avcC box and the packets into length-prefixed NAL units.
    size_t end = 0;  // where the first slice NAL unit's start code begins
    for (const auto& [at, len] : NalUnits(data, size)) {
      const int type = data[at] & 0x1f;
      if (type != 1 && type != 5) continue;
      end = at - 3;
      if (end > 0 && data[end - 1] == 0) --end;  // a 4-byte start code
      break;
    }
    AVCodecParameters* par = m.stream->codecpar;
    av_freep(&par->extradata);  // a failed header write before: start again
    par->extradata = static_cast<uint8_t*>(av_mallocz(end + AV_INPUT_BUFFER_PADDING_SIZE));
    if (!par->extradata) return absl::ResourceExhaustedError("av_mallocz failed");
    std::copy(data, data + end, par->extradata);
    par->extradata_size = static_cast<int>(end);
    if (int err = avformat_write_header(m.fmt, nullptr); err < 0)
      return absl::InternalError(absl::StrCat(m.path, ": ", AvError(err)));
    m.header_written = true;
  }
  PacketPtr p(av_packet_alloc());
  if (!p || av_new_packet(p.get(), static_cast<int>(size)) < 0)
    return absl::ResourceExhaustedError("av_new_packet failed");
  std::copy(data, data + size, p->data);
  // Milliseconds, strictly increasing (frames can arrive within one millisecond).
  int64_t pts = std::max<int64_t>(static_cast<int64_t>(time_ms), m.last_pts + 1);
  m.last_pts = pts;
  p->pts = p->dts = av_rescale_q(pts, AVRational{1, 1000}, m.stream->time_base);
  p->stream_index = m.stream->index;
  if (keyframe) p->flags |= AV_PKT_FLAG_KEY;
  if (int err = av_interleaved_write_frame(m.fmt, p.get()); err < 0)
    return absl::InternalError(absl::StrCat(m.path, ": ", AvError(err)));
  ++m.frames;
  return absl::OkStatus();
}

absl::Status VideoFileWriter::Close() {
  Impl& m = *impl_;
  if (m.closed) return absl::OkStatus();
  m.closed = true;
  absl::Status st;
  if (m.raw) {
    if (std::fclose(m.raw) != 0) st = absl::DataLossError(absl::StrCat(m.path, ": close failed"));
    m.raw = nullptr;
  }
  if (m.fmt) {
    if (m.header_written) {
      if (int err = av_write_trailer(m.fmt); err < 0)
        st = absl::InternalError(absl::StrCat(m.path, ": ", AvError(err)));
    }
    avio_closep(&m.fmt->pb);
    avformat_free_context(m.fmt);
    m.fmt = nullptr;
  }
  return st;
}

}  // namespace tessera::video

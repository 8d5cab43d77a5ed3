// H.264 video streams: the encoder library on its own (common/video.h) and Stream sessions
// with video.codec = VIDEO_CODEC_H264 against an in-process server. Every picture is decoded
// with libavcodec here and compared with a lossless Render of the same camera; keyframes come
// where the protocol promises them, and only there.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

extern "C" {
#include <libavformat/avformat.h>
}

#include "common/video.h"
#include "renderer/image_io.h"
#include "tests/integration/client_helpers.h"

namespace tessera {
namespace {

namespace fs = std::filesystem;
using namespace test_client;  // client_helpers.h

// --- the encoder library -------------------------------------------------------------------

// A test picture: a smooth gradient and a square that moves with `t`.
RgbaImage Picture(uint32_t w, uint32_t h, int t) {
  RgbaImage im{w, h, std::vector<uint8_t>(size_t{w} * h * 4)};
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      uint8_t* p = &im.pixels[(size_t{y} * w + x) * 4];
      const bool square = x >= uint32_t(10 + 3 * t) && x < uint32_t(40 + 3 * t) && y >= 20 && y < 50;
      p[0] = square ? 230 : uint8_t(x * 255 / w);
      p[1] = square ? 40 : uint8_t(y * 255 / h);
      p[2] = square ? 60 : uint8_t(128 + 60 * std::sin(0.1 * (x + y)));
      p[3] = 255;
    }
  return im;
}

RgbaImage FromDecoded(const video::DecodedFrame& d) { return {d.width, d.height, d.rgba}; }

// What Tessera's default JPEG (quality 90, 4:2:0) keeps of `im`: the bar video is held to.
double JpegPsnr(const RgbaImage& im) {
  absl::StatusOr<std::vector<uint8_t>> jpg = EncodeJpeg(im, 90, ChromaSubsampling::k420);
  EXPECT_TRUE(jpg.ok());
  absl::StatusOr<RgbaImage> back = DecodeJpeg(*jpg);
  EXPECT_TRUE(back.ok());
  return *Psnr(*back, im);
}

TEST(VideoEncoder, FramesDecodeToTheirPicturesAndOnlyTheFirstIsAKeyframe) {
  video::EncoderOptions o;
  o.width = 128;
  o.height = 96;
  o.kind = video::EncoderKind::kSoftware;
  o.crf = 18;
  absl::StatusOr<std::unique_ptr<video::Encoder>> enc = video::Encoder::Create(o);
  ASSERT_TRUE(enc.ok()) << enc.status();
  EXPECT_STREQ((*enc)->name(), "libx264");
  absl::StatusOr<std::unique_ptr<video::Decoder>> dec = video::Decoder::Create();
  ASSERT_TRUE(dec.ok()) << dec.status();
  for (int t = 0; t < 8; ++t) {
    const RgbaImage pic = Picture(128, 96, t);
    absl::StatusOr<video::Packet> p = (*enc)->Encode(pic.pixels.data(), 128 * 4, t == 5);
    ASSERT_TRUE(p.ok()) << p.status();
    EXPECT_EQ(p->keyframe, t == 0 || t == 5) << "frame " << t;
    absl::StatusOr<video::DecodedFrame> d = (*dec)->Decode(p->data.data(), p->data.size());
    ASSERT_TRUE(d.ok()) << "frame " << t << ": " << d.status();
    ASSERT_EQ(d->width, 128u);
    ASSERT_EQ(d->height, 96u);
    absl::StatusOr<double> psnr = Psnr(FromDecoded(*d), pic);
    ASSERT_TRUE(psnr.ok());
    // The saturated square's edges lose the same chroma in both (4:2:0).
    EXPECT_GT(*psnr, JpegPsnr(pic) - 3.5) << "frame " << t;
    EXPECT_GT(*psnr, 30.0) << "frame " << t;
  }
  // High profile (libx264's default for 4:2:0 8-bit): avc1.64xxxx.
  EXPECT_EQ((*enc)->codec_string().substr(0, 7), "avc1.64") << (*enc)->codec_string();
  EXPECT_EQ((*enc)->frames(), 8u);
}

// `n` frames of the moving test picture at w x h (software encoder); frame `key` a keyframe too.
std::vector<video::Packet> EncodeSequence(uint32_t w, uint32_t h, int n, int key = -1) {
  video::EncoderOptions o;
  o.width = w;
  o.height = h;
  o.kind = video::EncoderKind::kSoftware;
  auto enc = video::Encoder::Create(o);
  EXPECT_TRUE(enc.ok()) << enc.status();
  std::vector<video::Packet> packets;
  for (int t = 0; enc.ok() && t < n; ++t) {
    const RgbaImage pic = Picture(w, h, t);
    absl::StatusOr<video::Packet> p = (*enc)->Encode(pic.pixels.data(), size_t{w} * 4, t == key);
    EXPECT_TRUE(p.ok()) << p.status();
    if (p.ok()) packets.push_back(*std::move(p));
  }
  return packets;
}

TEST(VideoEncoder, AKeyframeDecodesAloneADeltaFrameDoesNot) {
  const std::vector<video::Packet> packets = EncodeSequence(64, 64, 4, /*key=*/3);
  ASSERT_EQ(packets.size(), 4u);
  auto fresh = video::Decoder::Create();
  EXPECT_FALSE((*fresh)->Decode(packets[1].data.data(), packets[1].data.size()).ok())
      << "a delta frame without its keyframe must not pass as a picture";
  auto fresh2 = video::Decoder::Create();
  EXPECT_TRUE((*fresh2)->Decode(packets[3].data.data(), packets[3].data.size()).ok());
}

// A frame missing from the middle of a stream is an error, not a silently concealed picture
// (what the stream tests rely on to prove that no encoded frame is ever dropped).
TEST(VideoDecoder, AFrameMissingMidStreamIsAnError) {
  const std::vector<video::Packet> packets = EncodeSequence(64, 48, 6);
  ASSERT_EQ(packets.size(), 6u);
  auto all = video::Decoder::Create();
  for (const video::Packet& p : packets)
    EXPECT_TRUE((*all)->Decode(p.data.data(), p.data.size()).ok());
  auto gap = video::Decoder::Create();
  for (int t : {0, 1, 2}) ASSERT_TRUE((*gap)->Decode(packets[t].data.data(), packets[t].data.size()).ok());
  absl::StatusOr<video::DecodedFrame> d = (*gap)->Decode(packets[4].data.data(), packets[4].data.size());
  EXPECT_FALSE(d.ok()) << "frame 3 was skipped";
  EXPECT_NE(d.status().message().find("missing"), std::string::npos) << d.status();
}

TEST(VideoEncoder, TheQualityFactorChangesPerFrame) {
  video::EncoderOptions o;
  o.width = 128;
  o.height = 96;
  o.kind = video::EncoderKind::kSoftware;
  auto enc = video::Encoder::Create(o);
  ASSERT_TRUE(enc.ok());
  // Keyframes of one picture at two factors: the coarser is much smaller.
  const RgbaImage pic = Picture(128, 96, 1);
  auto fine = (*enc)->Encode(pic.pixels.data(), 128 * 4, true, 12);
  auto coarse = (*enc)->Encode(pic.pixels.data(), 128 * 4, true, 40);
  ASSERT_TRUE(fine.ok() && coarse.ok());
  EXPECT_LT(coarse->data.size() * 2, fine->data.size())
      << coarse->data.size() << " vs " << fine->data.size();
}

TEST(VideoEncoder, BadOptionsAreRefused) {
  video::EncoderOptions o;
  o.width = 101;
  o.height = 64;
  EXPECT_EQ(video::Encoder::Create(o).status().code(), absl::StatusCode::kInvalidArgument);
  o.width = 100;
  o.preset = "placebo-ish";
  absl::Status st = video::Encoder::Create(o).status();
  EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("superfast"), std::string::npos) << st;
  o.preset = "superfast";
  o.kind = video::EncoderKind::kHardware;
  if (!video::HardwareEncoderAvailable()) {
    st = video::Encoder::Create(o).status();
    EXPECT_EQ(st.code(), absl::StatusCode::kFailedPrecondition) << st;
    // Auto falls back to the software encoder.
    o.kind = video::EncoderKind::kAuto;
    auto enc = video::Encoder::Create(o);
    ASSERT_TRUE(enc.ok()) << enc.status();
    EXPECT_STREQ((*enc)->name(), "libx264");
  }
}

TEST(VideoEncoder, CodecStringComesFromTheSps) {
  const uint8_t sps[] = {0, 0, 0, 1, 0x67, 0x64, 0x00, 0x1f, 0xac};
  EXPECT_EQ(video::CodecStringFromAnnexB(sps, sizeof(sps)), "avc1.64001f");
  const uint8_t none[] = {0, 0, 0, 1, 0x65, 0x88, 0x84};
  EXPECT_EQ(video::CodecStringFromAnnexB(none, sizeof(none)), "");
}

// The .mp4 a CLI session saves: libavformat reads it back with every frame, at its times.
TEST(VideoFileWriter, Mp4HoldsEveryFrameAtItsTime) {
  const fs::path dir = fs::temp_directory_path() / ("tessera-video-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string mp4 = (dir / "out.mp4").string();
  const std::string raw = (dir / "out.h264").string();
  video::EncoderOptions o;
  o.width = 64;
  o.height = 48;
  o.kind = video::EncoderKind::kSoftware;
  auto enc = video::Encoder::Create(o);
  ASSERT_TRUE(enc.ok());
  auto w = video::VideoFileWriter::Open(mp4, 64, 48);
  auto wr = video::VideoFileWriter::Open(raw, 64, 48);
  ASSERT_TRUE(w.ok() && wr.ok()) << w.status() << wr.status();
  size_t raw_bytes = 0;
  for (int t = 0; t < 6; ++t) {
    const RgbaImage pic = Picture(64, 48, t);
    auto p = (*enc)->Encode(pic.pixels.data(), 64 * 4, false);
    ASSERT_TRUE(p.ok());
    ASSERT_TRUE((*w)->Write(p->data.data(), p->data.size(), p->keyframe, 100.0 * t).ok());
    ASSERT_TRUE((*wr)->Write(p->data.data(), p->data.size(), p->keyframe, 100.0 * t).ok());
    raw_bytes += p->data.size();
  }
  ASSERT_TRUE((*w)->Close().ok());
  ASSERT_TRUE((*wr)->Close().ok());
  EXPECT_EQ(fs::file_size(raw), raw_bytes);

  AVFormatContext* fmt = nullptr;
  ASSERT_EQ(avformat_open_input(&fmt, mp4.c_str(), nullptr, nullptr), 0);
  ASSERT_GE(avformat_find_stream_info(fmt, nullptr), 0);
  ASSERT_EQ(fmt->nb_streams, 1u);
  EXPECT_EQ(fmt->streams[0]->codecpar->codec_id, AV_CODEC_ID_H264);
  EXPECT_EQ(fmt->streams[0]->codecpar->width, 64);
  AVPacket* pkt = av_packet_alloc();
  std::vector<double> times;
  auto dec = video::Decoder::Create();
  // MP4 stores length-prefixed NAL units; the decoder here reads Annex B, so only count and
  // time the packets.
  while (av_read_frame(fmt, pkt) >= 0) {
    times.push_back(double(pkt->pts) * av_q2d(fmt->streams[0]->time_base) * 1000.0);
    av_packet_unref(pkt);
  }
  av_packet_free(&pkt);
  avformat_close_input(&fmt);
  ASSERT_EQ(times.size(), 6u);
  for (int t = 0; t < 6; ++t) EXPECT_NEAR(times[t], 100.0 * t, 1.0);
  fs::remove_all(dir);

  // An MP4 must start with a keyframe.
  auto w2 = video::VideoFileWriter::Open((dir.string() + "-2.mp4"), 64, 48);
  ASSERT_TRUE(w2.ok());
  const uint8_t delta[] = {0, 0, 0, 1, 0x41, 0x9a};
  EXPECT_EQ((*w2)->Write(delta, sizeof(delta), false, 0).code(),
            absl::StatusCode::kFailedPrecondition);
  (void)(*w2)->Close();
  fs::remove(dir.string() + "-2.mp4");
}

// --- Stream sessions -----------------------------------------------------------------------

class VideoStreamTest : public SharedServerTest<VideoStreamTest> {
 protected:
  static void SetUpTestSuite() {
    server::ServerOptions o;
    o.listen = "127.0.0.1:0";
    o.validation = std::getenv("TESSERA_VALIDATION") != nullptr;
    o.resume_grace_s = 30;
    absl::StatusOr<std::unique_ptr<server::Server>> s = server::Server::Start(o);
    ASSERT_TRUE(s.ok()) << s.status();
    server_ = s->release();
  }

  // Every test's streams are over: nothing is held for them any more (encoded or unencoded).
  void TearDown() override {
    server::ServerStats s;
    for (int i = 0; i < 500; ++i) {
      s = server_->stats();
      if (s.sessions == 0 && s.pending_frame_bytes == 0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    EXPECT_EQ(s.sessions, 0u);
    EXPECT_EQ(s.pending_frame_bytes, 0u);
  }

  // A lossless Render of what `f` shows (its camera and size).
  RgbaImage Reference(const v1::Frame& f) {
    v1::RenderRequest req = DemoRequest(f.width(), f.height());
    v1::LookAt* l = req.mutable_camera()->mutable_look_at();
    *l = f.camera();
    req.mutable_camera()->set_yfov(f.yfov());
    req.set_encoding(v1::IMAGE_PNG);
    grpc::ClientContext ctx;
    v1::Frame out;
    grpc::Status st = stub_->Render(&ctx, req, &out);
    EXPECT_TRUE(st.ok()) << st.error_message();
    absl::StatusOr<RgbaImage> im = DecodePng(
        std::span(reinterpret_cast<const uint8_t*>(out.data().data()), out.data().size()));
    EXPECT_TRUE(im.ok()) << im.status();
    return im.ok() ? *im : RgbaImage{};
  }
};

v1::ClientEvent H264Open(uint32_t w, uint32_t h) {
  v1::ClientEvent e = OpenEvent("demo", w, h);
  e.mutable_open()->mutable_video()->set_codec(v1::VIDEO_CODEC_H264);
  return e;
}

TEST_F(VideoStreamTest, FramesDecodeToTheRenderOfTheirCamera) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(H264Open(320, 192)));
  auto dec = video::Decoder::Create();
  ASSERT_TRUE(dec.ok());
  v1::Frame f;
  std::vector<v1::Frame> frames;
  std::vector<RgbaImage> pictures;
  for (uint64_t k = 1; k <= 6; ++k) {  // ping-pong: each frame, then the next camera
    ASSERT_TRUE(rw->Read(&f));
    ASSERT_EQ(f.encoding(), v1::VIDEO_H264);
    auto d = (*dec)->Decode(reinterpret_cast<const uint8_t*>(f.data().data()), f.data().size());
    ASSERT_TRUE(d.ok()) << "frame " << f.sequence() << ": " << d.status();
    pictures.push_back(FromDecoded(*d));
    frames.push_back(f);
    ASSERT_TRUE(rw->Write(CameraEvent(k)));
  }
  EXPECT_TRUE(CloseStream(rw.get()).ok());
  for (size_t i = 0; i < frames.size(); ++i) {
    const v1::Frame& fr = frames[i];
    EXPECT_EQ(fr.keyframe(), i == 0) << "frame " << i << ": only the session's first";
    EXPECT_EQ(fr.codec().substr(0, 5), "avc1.");
    EXPECT_EQ(fr.encoder(), video::HardwareEncoderAvailable() ? "h264_nvenc" : "libx264");
    EXPECT_GT(fr.cpu().encode_ms(), 0.0);
    EXPECT_EQ(fr.width(), 320u);
    const RgbaImage reference = Reference(fr);
    absl::StatusOr<double> psnr = Psnr(pictures[i], reference);
    ASSERT_TRUE(psnr.ok()) << psnr.status();
    const double jpeg = JpegPsnr(reference);
    // The picture of the camera before: what a frame shown late or out of order would score.
    const double wrong = i > 0 ? *Psnr(pictures[i], Reference(frames[i - 1])) : 0.0;
    std::printf("h264 frame %zu: %zu bytes, %.2f dB (JPEG q90: %.2f dB, previous camera: %.2f dB)\n",
                i, fr.data().size(), *psnr, jpeg, wrong);
    // crf 23 on a small picture that moves a lot between frames: under JPEG q90 (benchmarks
    // compare them at equal quality), and far above the wrong picture.
    EXPECT_GT(*psnr, 26.0) << "frame " << i;
    EXPECT_GT(*psnr, wrong + 6.0) << "frame " << i;
  }
  // Delta frames of a small camera step cost less than the keyframe.
  EXPECT_LT(frames[3].data().size(), frames[0].data().size());
}

// Reads frames until one reflects `event_id`; returns it.
v1::Frame ReadUntilEvent(StreamRW* rw, uint64_t event_id, video::Decoder* dec) {
  v1::Frame f;
  while (rw->Read(&f)) {
    auto d = dec->Decode(reinterpret_cast<const uint8_t*>(f.data().data()), f.data().size());
    EXPECT_TRUE(d.ok()) << "frame " << f.sequence() << ": " << d.status();
    if (f.event_id() >= event_id) return f;
  }
  ADD_FAILURE() << "the stream ended before event " << event_id;
  return f;
}

TEST_F(VideoStreamTest, KeyframesAtResizeRequestAndNewEncoderOnly) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(H264Open(96, 64)));
  auto dec = video::Decoder::Create();
  v1::Frame f = ReadUntilEvent(rw.get(), 0, dec->get());
  EXPECT_TRUE(f.keyframe());

  // Sends event `id`, filled in by `fill`; the first frame that reflects it.
  auto step = [&](uint64_t id, auto fill) {
    v1::ClientEvent e;
    e.set_event_id(id);
    fill(e);
    rw->Write(e);
    return ReadUntilEvent(rw.get(), id, dec->get());
  };
  f = step(1, [](v1::ClientEvent& e) { OrbitEye(1, e.mutable_camera()); });
  EXPECT_FALSE(f.keyframe()) << "a camera move is a delta frame";
  f = step(2, [](v1::ClientEvent& e) { e.mutable_settings()->set_width(128); });
  EXPECT_TRUE(f.keyframe()) << "a resize starts a new video";
  EXPECT_EQ(f.width(), 128u);
  f = step(3, [](v1::ClientEvent& e) { e.set_keyframe(true); });
  EXPECT_TRUE(f.keyframe()) << "a keyframe was asked for";
  f = step(4, [](v1::ClientEvent& e) { e.mutable_video()->set_crf(30); });
  EXPECT_FALSE(f.keyframe()) << "the quality factor changes within the video";
  f = step(5, [](v1::ClientEvent& e) { e.mutable_video()->set_preset("ultrafast"); });
  EXPECT_TRUE(f.keyframe()) << "a new preset is a new encoder";

  EXPECT_TRUE(CloseStream(rw.get()).ok());
}

TEST_F(VideoStreamTest, SwitchingCodecsMidSession) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  ASSERT_TRUE(rw->Write(OpenEvent("demo", 96, 64)));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.encoding(), v1::IMAGE_JPEG);
  EXPECT_FALSE(f.keyframe());
  v1::ClientEvent e;
  e.set_event_id(1);
  e.mutable_video()->set_codec(v1::VIDEO_CODEC_H264);
  rw->Write(e);
  do {
    ASSERT_TRUE(rw->Read(&f));
  } while (f.event_id() < 1);
  EXPECT_EQ(f.encoding(), v1::VIDEO_H264);
  EXPECT_TRUE(f.keyframe());
  e.set_event_id(2);
  e.mutable_video()->set_codec(v1::VIDEO_CODEC_JPEG);
  rw->Write(e);
  do {
    ASSERT_TRUE(rw->Read(&f));
  } while (f.event_id() < 2);
  EXPECT_EQ(f.encoding(), v1::IMAGE_JPEG);
  EXPECT_TRUE(DecodeJpeg(std::span(reinterpret_cast<const uint8_t*>(f.data().data()),
                                   f.data().size()))
                  .ok());
  EXPECT_TRUE(CloseStream(rw.get()).ok());
}

TEST_F(VideoStreamTest, AResumedSessionStartsWithAKeyframe) {
  std::string token;
  {
    grpc::ClientContext ctx;
    std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
    ASSERT_TRUE(rw->Write(H264Open(96, 64)));
    v1::Frame f;
    ASSERT_TRUE(rw->Read(&f));
    rw->Write(CameraEvent(1));
    ASSERT_TRUE(rw->Read(&f));
    EXPECT_FALSE(f.keyframe());
    token = f.session_token();
    ctx.TryCancel();  // the client vanishes: the session is parked
    rw->Finish();
  }
  ASSERT_FALSE(token.empty());
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  v1::ClientEvent e;
  e.set_event_id(2);
  e.mutable_open()->set_resume_token(token);
  ASSERT_TRUE(rw->Write(e));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  EXPECT_EQ(f.encoding(), v1::VIDEO_H264);
  EXPECT_TRUE(f.keyframe()) << "a new stream's decoder needs a keyframe";
  auto dec = video::Decoder::Create();
  EXPECT_TRUE((*dec)->Decode(reinterpret_cast<const uint8_t*>(f.data().data()), f.data().size()).ok());
  EXPECT_TRUE(CloseStream(rw.get()).ok());
}

// Idle refinement: frames while the camera moves are coded coarser (interactive_crf), one
// full-quality frame follows once it rests, and then the stream sends nothing.
TEST_F(VideoStreamTest, ARestingCameraSendsNothingAfterItsRefinementFrame) {
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  v1::ClientEvent open = H264Open(128, 96);
  open.mutable_open()->mutable_interactive()->set_enabled(true);
  open.mutable_open()->mutable_interactive()->set_render_scale(1.0f);
  open.mutable_open()->mutable_interactive()->set_rest_ms(150);
  open.mutable_open()->mutable_video()->set_crf(20);
  open.mutable_open()->mutable_video()->set_interactive_crf(40);
  ASSERT_TRUE(rw->Write(open));
  std::vector<v1::Frame> frames;  // the reader's until it is joined
  std::vector<std::chrono::steady_clock::time_point> at;
  std::thread reader([&] {
    v1::Frame f;
    while (rw->Read(&f)) {
      frames.push_back(f);
      at.push_back(std::chrono::steady_clock::now());
    }
  });
  for (uint64_t k = 1; k <= 6; ++k) {
    rw->Write(CameraEvent(k));
    std::this_thread::sleep_for(std::chrono::milliseconds(40));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(2000));
  const auto t_close = std::chrono::steady_clock::now();
  rw->WritesDone();
  reader.join();
  EXPECT_TRUE(rw->Finish().ok());
  ASSERT_GE(frames.size(), 3u);
  EXPECT_LT(at.back(), t_close) << "a frame came after the half-close";
  // The last frame is the full-quality one, well before the end of the rest.
  const v1::Frame& last = frames.back();
  EXPECT_EQ(last.profile(), "full");
  EXPECT_EQ(last.event_id(), 6u);
  EXPECT_GT(t_close - at.back(), std::chrono::milliseconds(1000))
      << "frames kept coming after the refinement frame";
  size_t interactive = 0, interactive_bytes = 0;
  for (const v1::Frame& f : frames)
    if (f.profile() == "interactive") ++interactive, interactive_bytes += f.data().size();
  ASSERT_GE(interactive, 1u);
  EXPECT_LT(interactive_bytes / interactive, last.data().size())
      << "interactive frames are coded coarser than the refinement frame";
}

TEST_F(VideoStreamTest, ServerInfoListsTheEncoders) {
  grpc::ClientContext ctx;
  v1::ServerInfo info;
  ASSERT_TRUE(stub_->GetServerInfo(&ctx, {}, &info).ok());
  ASSERT_FALSE(info.video_encoders().empty());
  EXPECT_EQ(info.video_encoders(info.video_encoders_size() - 1), "libx264");
  EXPECT_EQ(info.video_encoders(0) == "h264_nvenc", video::HardwareEncoderAvailable());
}

TEST_F(VideoStreamTest, BadVideoSettingsAreInvalidArgumentNamingTheField) {
  auto refused = [&](v1::ClientEvent open) {
    grpc::ClientContext ctx;
    std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
    rw->Write(open);
    v1::Frame f;
    while (rw->Read(&f)) {
    }
    return rw->Finish();
  };
  v1::ClientEvent e = H264Open(96, 64);
  e.mutable_open()->mutable_video()->set_crf(60);
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.video.crf");
  e = H264Open(96, 64);
  e.mutable_open()->mutable_video()->set_preset("slowest");
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.video.preset");
  e = H264Open(96, 64);
  e.mutable_open()->mutable_video()->set_max_bitrate_kbps(5);
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.video.max_bitrate_kbps");
  e = H264Open(96, 64);
  e.mutable_open()->mutable_video()->set_keyframe_interval(601);
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.video.keyframe_interval");
  e = H264Open(96, 64);
  e.mutable_open()->mutable_video()->set_codec(static_cast<v1::VideoCodec>(9));
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.video.codec");
  e = H264Open(97, 64);
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.settings.width");
  e = H264Open(4098, 64);  // over H.264 level 5.2's side
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.settings.width: 4098");
  e = H264Open(4096, 4096);  // 65536 macroblocks, over level 5.2's 36864
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.settings.width: 4096x4096");
  e = H264Open(96, 64);
  e.mutable_open()->mutable_video()->set_crf(0);  // lossless: a profile browsers do not decode
  EXPECT_CODE(refused(e), INVALID_ARGUMENT, "open.video.crf: 0");
  if (!video::HardwareEncoderAvailable()) {
    e = H264Open(96, 64);
    e.mutable_open()->mutable_video()->set_encoder(v1::VIDEO_ENCODER_HARDWARE);
    EXPECT_CODE(refused(e), FAILED_PRECONDITION, "open.video.encoder");
  }
  // An update: an odd width in an h264 session ends it naming the field.
  grpc::ClientContext ctx;
  std::unique_ptr<StreamRW> rw = stub_->Stream(&ctx);
  rw->Write(H264Open(96, 64));
  v1::Frame f;
  ASSERT_TRUE(rw->Read(&f));
  v1::ClientEvent bad;
  bad.set_event_id(1);
  bad.mutable_settings()->set_width(99);
  rw->Write(bad);
  while (rw->Read(&f)) {
  }
  EXPECT_CODE(rw->Finish(), INVALID_ARGUMENT, "settings.width");
  // A Render is one image.
  v1::RenderRequest req = DemoRequest(32, 32);
  req.set_encoding(v1::VIDEO_H264);
  grpc::ClientContext rctx;
  v1::Frame out;
  EXPECT_CODE(stub_->Render(&rctx, req, &out), INVALID_ARGUMENT, "encoding");
}

}  // namespace
}  // namespace tessera

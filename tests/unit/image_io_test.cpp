#include "renderer/image_io.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <png.h>

#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace tessera {
namespace {

// A smooth image: what JPEG compresses well, so PSNR thresholds are stable.
RgbaImage Gradient(uint32_t w, uint32_t h) {
  RgbaImage img;
  img.width = w;
  img.height = h;
  img.pixels.resize(size_t{w} * h * 4);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      uint8_t* p = &img.pixels[(size_t{y} * w + x) * 4];
      p[0] = static_cast<uint8_t>(255 * x / (w - 1));
      p[1] = static_cast<uint8_t>(255 * y / (h - 1));
      p[2] = static_cast<uint8_t>(128 + 64 * std::sin(0.05 * (x + y)));
      p[3] = 255;
    }
  }
  return img;
}

// Every byte distinct-ish, alpha varying: a lossless codec must reproduce it exactly.
RgbaImage Noise(uint32_t w, uint32_t h) {
  RgbaImage img;
  img.width = w;
  img.height = h;
  img.pixels.resize(size_t{w} * h * 4);
  uint32_t state = 12345;
  for (uint8_t& b : img.pixels) {
    state = state * 1664525u + 1013904223u;
    b = static_cast<uint8_t>(state >> 24);
  }
  return img;
}

// ---- Writing non-RGBA PNGs with libpng directly, so DecodePng's conversions are tested
// against files EncodePng can never produce.

struct RawPngWriter {
  std::vector<uint8_t> out;
};

void RawWrite(png_structp png, png_bytep data, png_size_t len) {
  auto* w = static_cast<RawPngWriter*>(png_get_io_ptr(png));
  w->out.insert(w->out.end(), data, data + len);
}
void RawFlush(png_structp) {}

struct RawPngSpec {
  uint32_t width = 0;
  uint32_t height = 0;
  int bit_depth = 8;
  int color_type = PNG_COLOR_TYPE_GRAY;
  std::vector<png_color> palette;
  std::vector<png_byte> trns;  // palette alpha entries
  std::vector<uint8_t> data;   // packed rows in the file's own format (big-endian 16-bit)
};

bool WriteRawPngImpl(const RawPngSpec& spec, RawPngWriter* w, std::vector<png_bytep>* rows) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, w, RawWrite, RawFlush);
  png_set_IHDR(png, info, spec.width, spec.height, spec.bit_depth, spec.color_type,
               PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (!spec.palette.empty()) {
    png_set_PLTE(png, info, spec.palette.data(), static_cast<int>(spec.palette.size()));
  }
  if (!spec.trns.empty()) {
    png_set_tRNS(png, info, spec.trns.data(), static_cast<int>(spec.trns.size()), nullptr);
  }
  png_write_info(png, info);
  png_write_image(png, rows->data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

std::vector<uint8_t> WriteRawPng(const RawPngSpec& spec) {
  const size_t row_bytes = spec.data.size() / spec.height;
  std::vector<png_bytep> rows(spec.height);
  for (uint32_t y = 0; y < spec.height; ++y) {
    rows[y] = const_cast<png_bytep>(spec.data.data() + y * row_bytes);
  }
  RawPngWriter w;
  EXPECT_TRUE(WriteRawPngImpl(spec, &w, &rows));
  return w.out;
}

// PNG chunk CRC (IEEE, reflected), bitwise: only used on a 17-byte chunk.
uint32_t Crc32(const uint8_t* data, size_t n) {
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) {
    crc ^= data[i];
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

const uint8_t* PixelAt(const RgbaImage& img, uint32_t x, uint32_t y) {
  return &img.pixels[(size_t{y} * img.width + x) * 4];
}

// ---- JPEG ----------------------------------------------------------------------------------

TEST(ImageIo, JpegRoundTripHighQuality) {
  const RgbaImage src = Gradient(128, 96);
  auto jpeg = EncodeJpeg(src, 95, ChromaSubsampling::k420);
  ASSERT_TRUE(jpeg.ok()) << jpeg.status();
  ASSERT_GT(jpeg->size(), 2u);
  EXPECT_EQ((*jpeg)[0], 0xFF);
  EXPECT_EQ((*jpeg)[1], 0xD8);
  auto decoded = DecodeJpeg(*jpeg);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  EXPECT_EQ(decoded->width, src.width);
  EXPECT_EQ(decoded->height, src.height);
  ASSERT_EQ(decoded->pixels.size(), src.pixels.size());
  for (size_t i = 3; i < decoded->pixels.size(); i += 4) ASSERT_EQ(decoded->pixels[i], 255);
  auto psnr = Psnr(src, *decoded);
  ASSERT_TRUE(psnr.ok()) << psnr.status();
  EXPECT_GT(*psnr, 35.0);
}

TEST(ImageIo, JpegLowQualityIsWorse) {
  const RgbaImage src = Gradient(128, 96);
  auto hi = EncodeJpeg(src, 95, ChromaSubsampling::k420);
  auto lo = EncodeJpeg(src, 10, ChromaSubsampling::k420);
  ASSERT_TRUE(hi.ok() && lo.ok());
  EXPECT_LT(lo->size(), hi->size());
  auto hi_img = DecodeJpeg(*hi);
  auto lo_img = DecodeJpeg(*lo);
  ASSERT_TRUE(hi_img.ok() && lo_img.ok());
  auto hi_psnr = Psnr(src, *hi_img);
  auto lo_psnr = Psnr(src, *lo_img);
  ASSERT_TRUE(hi_psnr.ok() && lo_psnr.ok());
  EXPECT_LT(*lo_psnr, *hi_psnr);
}

TEST(ImageIo, JpegSubsamplingModesDecodeToSize) {
  // Odd sizes exercise the partial MCU blocks at the right and bottom edges.
  const RgbaImage src = Gradient(77, 53);
  for (ChromaSubsampling s : {ChromaSubsampling::k420, ChromaSubsampling::k444}) {
    auto jpeg = EncodeJpeg(src, 90, s);
    ASSERT_TRUE(jpeg.ok()) << jpeg.status();
    auto img = DecodeJpeg(*jpeg);
    ASSERT_TRUE(img.ok()) << img.status();
    EXPECT_EQ(img->width, 77u);
    EXPECT_EQ(img->height, 53u);
    EXPECT_EQ(img->pixels.size(), 77u * 53u * 4u);
    auto psnr = Psnr(src, *img);
    ASSERT_TRUE(psnr.ok());
    EXPECT_GT(*psnr, 30.0);
  }
}

// A gradient with deterministic noise: every DCT coefficient band in use.
RgbaImage Textured(uint32_t w, uint32_t h) {
  RgbaImage img = Gradient(w, h);
  uint32_t state = 12345;
  for (size_t i = 0; i < img.pixels.size(); ++i) {
    if (i % 4 == 3) continue;
    state = state * 1664525u + 1013904223u;
    img.pixels[i] = uint8_t((img.pixels[i] + (state >> 27)) & 0xFF);
  }
  return img;
}

// The markers of a baseline JPEG after its scan header: how many RSTn, in order.
int CountRestarts(const std::vector<uint8_t>& jpeg, bool* in_order) {
  int n = 0;
  *in_order = true;
  for (size_t i = 0; i + 1 < jpeg.size(); ++i) {
    if (jpeg[i] != 0xFF || jpeg[i + 1] < 0xD0 || jpeg[i + 1] > 0xD7) continue;
    *in_order = *in_order && jpeg[i + 1] == 0xD0 + n % 8;
    ++n;
  }
  return n;
}

// Strips encoded on several threads and spliced with restart markers decode to exactly the
// pixels of the one-strip encode (strips are cut at MCU rows; a restart only resets the DC
// prediction), for both subsamplings, sizes that are not multiples of an MCU, and more strips
// than MCU rows.
TEST(ImageIo, JpegStripsDecodeToTheOneStripPixels) {
  const RgbaImage src = Textured(301, 203);
  for (ChromaSubsampling s : {ChromaSubsampling::k420, ChromaSubsampling::k444}) {
    auto one = EncodeJpeg(src, 85, s, 1);
    ASSERT_TRUE(one.ok()) << one.status();
    auto one_img = DecodeJpeg(*one);
    ASSERT_TRUE(one_img.ok()) << one_img.status();
    bool in_order = false;
    EXPECT_EQ(CountRestarts(*one, &in_order), 0);
    for (uint32_t strips : {2u, 3u, 5u, 8u, 100u}) {
      auto split = EncodeJpeg(src, 85, s, strips);
      ASSERT_TRUE(split.ok()) << split.status();
      auto img = DecodeJpeg(*split);
      ASSERT_TRUE(img.ok()) << img.status() << " strips " << strips;
      EXPECT_EQ(img->width, src.width);
      EXPECT_EQ(img->height, src.height);
      EXPECT_EQ(img->pixels, one_img->pixels) << "strips " << strips;
      const uint32_t mcu_rows = (src.height + (s == ChromaSubsampling::k444 ? 7 : 15)) /
                                (s == ChromaSubsampling::k444 ? 8 : 16);
      const uint32_t expected = std::min({strips, mcu_rows, kMaxJpegStrips});
      // Rows are split evenly in whole MCU rows: the strip count can come out one lower.
      const int restarts = CountRestarts(*split, &in_order);
      EXPECT_GE(restarts + 1, int(expected) - 1) << "strips " << strips;
      EXPECT_LE(restarts + 1, int(expected)) << "strips " << strips;
      EXPECT_TRUE(in_order);
    }
  }
}

// A restart interval is 16 bits of MCUs: a wide image gets more, shorter strips than asked,
// still on the asked number of threads.
TEST(ImageIo, JpegStripsOfAWideImageFitTheRestartInterval) {
  const RgbaImage src = Gradient(16384, 512);  // 4:4:4: 2048 MCUs a row, 31 rows a strip
  auto one = EncodeJpeg(src, 75, ChromaSubsampling::k444, 1);
  auto split = EncodeJpeg(src, 75, ChromaSubsampling::k444, 2);
  ASSERT_TRUE(one.ok() && split.ok());
  bool in_order = false;
  EXPECT_EQ(CountRestarts(*split, &in_order), 2);  // 64 MCU rows: strips of 31, 31, 2
  EXPECT_TRUE(in_order);
  auto a = DecodeJpeg(*one);
  auto b = DecodeJpeg(*split);
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->pixels, b->pixels);
}

// Strips are spliced only when they share strip 0's tables: with TurboJPEG's TJ_OPTIMIZE each
// strip gets its own Huffman tables, and the encode falls back to one strip (a valid JPEG, not a
// corrupt one).
TEST(ImageIo, JpegStripsWithTheirOwnTablesFallBackToOneStrip) {
  const RgbaImage src = Textured(301, 203);
  ASSERT_EQ(setenv("TJ_OPTIMIZE", "1", 1), 0);
  auto split = EncodeJpeg(src, 85, ChromaSubsampling::k420, 4);
  auto one = EncodeJpeg(src, 85, ChromaSubsampling::k420, 1);
  unsetenv("TJ_OPTIMIZE");
  ASSERT_TRUE(split.ok() && one.ok());
  bool in_order = false;
  EXPECT_EQ(CountRestarts(*split, &in_order), 0);
  EXPECT_EQ(*split, *one);
  auto img = DecodeJpeg(*split);
  ASSERT_TRUE(img.ok()) << img.status();
  EXPECT_EQ(img->width, src.width);
}

TEST(ImageIo, JpegRejectsBadQuality) {
  const RgbaImage src = Gradient(16, 16);
  for (int q : {0, 101, -5}) {
    auto r = EncodeJpeg(src, q, ChromaSubsampling::k420);
    EXPECT_EQ(r.status().code(), absl::StatusCode::kInvalidArgument) << "quality " << q;
  }
  EXPECT_TRUE(EncodeJpeg(src, 1, ChromaSubsampling::k420).ok());
  EXPECT_TRUE(EncodeJpeg(src, 100, ChromaSubsampling::k444).ok());
}

TEST(ImageIo, EncodersRejectBadImages) {
  RgbaImage empty;
  EXPECT_EQ(EncodeJpeg(empty, 90, ChromaSubsampling::k420).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodePng(empty).status().code(), absl::StatusCode::kInvalidArgument);

  RgbaImage zero_height = Gradient(8, 8);
  zero_height.height = 0;
  EXPECT_FALSE(EncodeJpeg(zero_height, 90, ChromaSubsampling::k420).ok());
  EXPECT_FALSE(EncodePng(zero_height).ok());

  RgbaImage short_pixels = Gradient(8, 8);
  short_pixels.pixels.resize(8 * 8 * 4 - 1);
  EXPECT_EQ(EncodeJpeg(short_pixels, 90, ChromaSubsampling::k420).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(EncodePng(short_pixels).status().code(), absl::StatusCode::kInvalidArgument);

  RgbaImage long_pixels = Gradient(8, 8);
  long_pixels.pixels.push_back(0);
  EXPECT_FALSE(EncodeJpeg(long_pixels, 90, ChromaSubsampling::k420).ok());
  EXPECT_FALSE(EncodePng(long_pixels).ok());
}

TEST(ImageIo, JpegDecodeRejectsBadInput) {
  EXPECT_EQ(DecodeJpeg({}).status().code(), absl::StatusCode::kInvalidArgument);
  const std::vector<uint8_t> garbage = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  EXPECT_FALSE(DecodeJpeg(garbage).ok());
  const std::vector<uint8_t> soi_only = {0xFF, 0xD8};
  EXPECT_FALSE(DecodeJpeg(soi_only).ok());

  auto jpeg = EncodeJpeg(Gradient(64, 64), 90, ChromaSubsampling::k420);
  ASSERT_TRUE(jpeg.ok());
  for (size_t keep : {size_t{4}, size_t{100}, jpeg->size() / 2, jpeg->size() - 10}) {
    std::span<const uint8_t> truncated(jpeg->data(), keep);
    EXPECT_FALSE(DecodeJpeg(truncated).ok()) << "kept " << keep << " of " << jpeg->size();
  }
  // A PNG is not a JPEG.
  auto png = EncodePng(Gradient(8, 8));
  ASSERT_TRUE(png.ok());
  EXPECT_FALSE(DecodeJpeg(*png).ok());
}

// ---- WebP (EXT_texture_webp textures) -------------------------------------------------------

// Lossless WebP keeps every channel where alpha is not 0 (libwebp may change the colour of
// fully transparent pixels unless told not to): noise with alpha 1..255 round-trips exactly.
TEST(ImageIo, WebpLosslessRoundTripIsExact) {
  RgbaImage src = Noise(37, 23);
  for (size_t i = 3; i < src.pixels.size(); i += 4)
    src.pixels[i] = std::max<uint8_t>(src.pixels[i], 1);
  auto webp = EncodeWebpLossless(src);
  ASSERT_TRUE(webp.ok()) << webp.status();
  EXPECT_TRUE(IsWebp(*webp));
  uint32_t w = 0, h = 0;
  ASSERT_TRUE(ReadWebpSize(*webp, &w, &h));
  EXPECT_EQ(w, 37u);
  EXPECT_EQ(h, 23u);
  auto img = DecodeWebp(*webp);
  ASSERT_TRUE(img.ok()) << img.status();
  EXPECT_EQ(img->width, src.width);
  EXPECT_EQ(img->height, src.height);
  EXPECT_EQ(img->pixels, src.pixels);
}

TEST(ImageIo, WebpDecodeRejectsBadInput) {
  EXPECT_EQ(DecodeWebp({}).status().code(), absl::StatusCode::kInvalidArgument);
  auto png = EncodePng(Gradient(8, 8));
  ASSERT_TRUE(png.ok());
  EXPECT_FALSE(IsWebp(*png));
  uint32_t w = 0, h = 0;
  EXPECT_FALSE(ReadWebpSize(*png, &w, &h));
  absl::StatusOr<RgbaImage> not_webp = DecodeWebp(*png);
  ASSERT_FALSE(not_webp.ok());
  EXPECT_NE(not_webp.status().message().find("bad header"), std::string::npos) << not_webp.status();
  auto webp = EncodeWebpLossless(Gradient(64, 64));
  ASSERT_TRUE(webp.ok()) << webp.status();
  // Cut anywhere: the header's own check or the decode fails, never a half image.
  for (size_t keep : {size_t{11}, size_t{30}, webp->size() / 2, webp->size() - 1}) {
    std::span<const uint8_t> truncated(webp->data(), keep);
    EXPECT_FALSE(DecodeWebp(truncated).ok()) << "kept " << keep << " of " << webp->size();
  }
  // An animated WebP (a VP8X header with the animation flag, then its ANIM chunk): refused by
  // name, not decoded as its first frame.
  const std::vector<uint8_t> animated = {
      'R', 'I', 'F', 'F', 30, 0, 0, 0, 'W',  'E', 'B', 'P',  // RIFF, the size after this word
      'V', 'P', '8', 'X', 10, 0, 0, 0, 0x02, 0,   0,   0,    // VP8X: flags (animation), reserved
      7,   0,   0,   3,   0,  0,                             // canvas 8x4 (each less one)
      'A', 'N', 'I', 'M', 6,  0, 0, 0, 0,    0,   0,   0,   0, 0};  // background colour, loop count
  absl::StatusOr<RgbaImage> anim = DecodeWebp(animated);
  ASSERT_FALSE(anim.ok());
  EXPECT_NE(anim.status().message().find("animated"), std::string::npos) << anim.status();
  // The size is checked against max_pixels before anything is decoded.
  absl::StatusOr<RgbaImage> over = DecodeWebp(*webp, 64 * 64 - 1);
  ASSERT_FALSE(over.ok());
  EXPECT_NE(over.status().message().find("64x64"), std::string::npos) << over.status();
}

// ---- PNG -----------------------------------------------------------------------------------

TEST(ImageIo, PngRoundTripIsExact) {
  const RgbaImage src = Noise(37, 23);
  auto png = EncodePng(src);
  ASSERT_TRUE(png.ok()) << png.status();
  auto img = DecodePng(*png);
  ASSERT_TRUE(img.ok()) << img.status();
  EXPECT_EQ(img->width, src.width);
  EXPECT_EQ(img->height, src.height);
  EXPECT_EQ(img->pixels, src.pixels);  // alpha included
}

// The strips splice into one zlib stream: every strip count decodes to the image (noise, which
// deflate barely shrinks, and a gradient with long runs), for heights that leave short last
// strips and widths down to one pixel; the bytes depend on the strip count alone (equal on
// every call; the threads that encode them vary with the machine), strips past kMaxPngStrips or
// the rows are clamped, and a libpng decode checks each chunk's CRC and the stream's Adler-32.
TEST(ImageIo, PngStripsDecodeToTheImage) {
  for (const auto& [w, h] : {std::pair{1u, 1u}, std::pair{3u, 2u}, std::pair{1u, 200u},
                             std::pair{7u, 64u}, std::pair{33u, 65u}, std::pair{97u, 301u},
                             std::pair{256u, 129u}}) {
    std::vector<RgbaImage> images = {Noise(w, h)};
    if (w > 1 && h > 1) images.push_back(Gradient(w, h));  // which needs two of each
    for (const RgbaImage& src : images) {
      std::vector<uint8_t> one_strip, eight_strips;
      for (uint32_t strips : {1u, 2u, 3u, 8u, 0u, 1000u}) {
        SCOPED_TRACE(testing::Message() << w << "x" << h << ", " << strips << " strips");
        auto png = EncodePng(src, strips);
        ASSERT_TRUE(png.ok()) << png.status();
        auto again = EncodePng(src, strips);
        ASSERT_TRUE(again.ok());
        EXPECT_EQ(*again, *png);
        if (strips == 1u) one_strip = *png;
        if (strips == 8u) eight_strips = *png;
        if (strips == 1000u) EXPECT_EQ(*png, eight_strips) << "clamped to kMaxPngStrips";
        if (h == 1u) EXPECT_EQ(*png, one_strip) << "one row is one strip";
        auto img = DecodePng(*png);
        ASSERT_TRUE(img.ok()) << img.status();
        EXPECT_EQ(img->width, src.width);
        EXPECT_EQ(img->height, src.height);
        EXPECT_EQ(img->pixels, src.pixels);
      }
    }
  }
  EXPECT_EQ(AutoPngStrips(Noise(4, 63)), 1u);
  EXPECT_EQ(AutoPngStrips(Noise(4, 128)), 2u);
  EXPECT_EQ(AutoPngStrips(Noise(4, 2160)), kMaxPngStrips);
}

TEST(ImageIo, DecodesGrayPng) {
  RawPngSpec spec;
  spec.width = 5;
  spec.height = 3;
  spec.color_type = PNG_COLOR_TYPE_GRAY;
  for (uint32_t i = 0; i < 15; ++i) spec.data.push_back(static_cast<uint8_t>(i * 17));
  auto img = DecodePng(WriteRawPng(spec));
  ASSERT_TRUE(img.ok()) << img.status();
  ASSERT_EQ(img->width, 5u);
  ASSERT_EQ(img->height, 3u);
  for (uint32_t y = 0; y < 3; ++y) {
    for (uint32_t x = 0; x < 5; ++x) {
      const uint8_t g = static_cast<uint8_t>((y * 5 + x) * 17);
      const uint8_t* p = PixelAt(*img, x, y);
      EXPECT_EQ(p[0], g);
      EXPECT_EQ(p[1], g);
      EXPECT_EQ(p[2], g);
      EXPECT_EQ(p[3], 255);
    }
  }
}

TEST(ImageIo, DecodesPalettePngWithTransparency) {
  RawPngSpec spec;
  spec.width = 4;
  spec.height = 2;
  spec.color_type = PNG_COLOR_TYPE_PALETTE;
  spec.palette = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {10, 20, 30}};
  spec.trns = {255, 128, 0};  // entry 3 has no tRNS entry: opaque
  spec.data = {0, 1, 2, 3, 3, 2, 1, 0};
  auto img = DecodePng(WriteRawPng(spec));
  ASSERT_TRUE(img.ok()) << img.status();
  ASSERT_EQ(img->width, 4u);
  ASSERT_EQ(img->height, 2u);
  const uint8_t expected[4][4] = {
      {255, 0, 0, 255}, {0, 255, 0, 128}, {0, 0, 255, 0}, {10, 20, 30, 255}};
  for (uint32_t y = 0; y < 2; ++y) {
    for (uint32_t x = 0; x < 4; ++x) {
      const uint8_t* e = expected[spec.data[y * 4 + x]];
      const uint8_t* p = PixelAt(*img, x, y);
      for (int c = 0; c < 4; ++c) EXPECT_EQ(p[c], e[c]) << x << "," << y << " c" << c;
    }
  }
}

TEST(ImageIo, DecodesSixteenBitGrayAlphaPng) {
  RawPngSpec spec;
  spec.width = 2;
  spec.height = 1;
  spec.bit_depth = 16;
  spec.color_type = PNG_COLOR_TYPE_GRAY_ALPHA;
  // Big-endian 16-bit samples: gray 0xABCD alpha 0x8000, gray 0x0102 alpha 0xFFFF.
  spec.data = {0xAB, 0xCD, 0x80, 0x00, 0x01, 0x02, 0xFF, 0xFF};
  auto img = DecodePng(WriteRawPng(spec));
  ASSERT_TRUE(img.ok()) << img.status();
  ASSERT_EQ(img->pixels.size(), 8u);
  // Stripping keeps the high byte.
  EXPECT_EQ(img->pixels, (std::vector<uint8_t>{0xAB, 0xAB, 0xAB, 0x80, 0x01, 0x01, 0x01, 0xFF}));
}

TEST(ImageIo, DecodesLowBitDepthGrayPng) {
  RawPngSpec spec;
  spec.width = 8;
  spec.height = 1;
  spec.bit_depth = 1;
  spec.color_type = PNG_COLOR_TYPE_GRAY;
  spec.data = {0b10100101};
  auto img = DecodePng(WriteRawPng(spec));
  ASSERT_TRUE(img.ok()) << img.status();
  const int bits[8] = {1, 0, 1, 0, 0, 1, 0, 1};
  for (uint32_t x = 0; x < 8; ++x) {
    EXPECT_EQ(PixelAt(*img, x, 0)[0], bits[x] ? 255 : 0) << x;
    EXPECT_EQ(PixelAt(*img, x, 0)[3], 255);
  }
}

TEST(ImageIo, PngDecodeRejectsBadInput) {
  EXPECT_EQ(DecodePng({}).status().code(), absl::StatusCode::kInvalidArgument);
  const std::vector<uint8_t> garbage = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  EXPECT_EQ(DecodePng(garbage).status().code(), absl::StatusCode::kInvalidArgument);

  auto png = EncodePng(Noise(32, 32));
  ASSERT_TRUE(png.ok());
  for (size_t keep : {size_t{4}, size_t{8}, size_t{20}, png->size() / 2, png->size() - 1}) {
    std::span<const uint8_t> truncated(png->data(), keep);
    EXPECT_EQ(DecodePng(truncated).status().code(), absl::StatusCode::kInvalidArgument)
        << "kept " << keep << " of " << png->size();
  }
  // A corrupted pixel stream must fail the CRC or zlib checks, not crash.
  std::vector<uint8_t> corrupt = *png;
  for (size_t i = 60; i < corrupt.size() - 20; i += 7) corrupt[i] ^= 0x5A;
  EXPECT_FALSE(DecodePng(corrupt).ok());
  // A JPEG is not a PNG.
  auto jpeg = EncodeJpeg(Gradient(8, 8), 90, ChromaSubsampling::k420);
  ASSERT_TRUE(jpeg.ok());
  EXPECT_FALSE(DecodePng(*jpeg).ok());
}

TEST(ImageIo, PngRejectsAbsurdDimensions) {
  // A valid 1x1 PNG whose header is then rewritten to claim 100000 x 100000 pixels: the
  // decoder must refuse before allocating 40 GB. The IHDR CRC is fixed up so the size check,
  // not the CRC check, is what rejects it.
  auto png = EncodePng(Noise(1, 1));
  ASSERT_TRUE(png.ok());
  std::vector<uint8_t> bytes = *png;
  // Signature (8) + length (4) + "IHDR" (4), then width, height big-endian.
  auto put32 = [&](size_t at, uint32_t v) {
    bytes[at] = v >> 24;
    bytes[at + 1] = (v >> 16) & 0xFF;
    bytes[at + 2] = (v >> 8) & 0xFF;
    bytes[at + 3] = v & 0xFF;
  };
  put32(16, 100000);
  put32(20, 100000);
  const uint32_t crc = Crc32(bytes.data() + 12, 17);
  put32(29, crc);
  auto img = DecodePng(bytes);
  EXPECT_EQ(img.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(img.status().message().find("CRC"), std::string::npos) << img.status();
}

// A chunk that declares more bytes than the file holds is refused before libpng sees it (libpng
// allocates the declared length first), also when the file ends inside the chunk's header.
TEST(ImageIo, PngChunkLongerThanTheFileIsRefused) {
  auto png = EncodePng(Noise(4, 4));
  ASSERT_TRUE(png.ok());
  const std::vector<uint8_t> good = *png;
  const size_t after_ihdr = 8 + 12 + 13;  // signature, IHDR chunk
  for (const size_t keep : {size_t{8}, size_t{10}, size_t{40}}) {
    std::vector<uint8_t> bytes(good.begin(), good.begin() + after_ihdr);
    const std::vector<uint8_t> ztxt = {0x40, 0x00, 0x00, 0x00, 'z', 'T', 'X', 't'};  // 1 GiB
    bytes.insert(bytes.end(), ztxt.begin(), ztxt.end());
    bytes.resize(after_ihdr + keep, 'x');
    SCOPED_TRACE(keep);
    auto img = DecodePng(bytes);
    ASSERT_FALSE(img.ok());
    EXPECT_EQ(img.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(img.status().message().find("past the end of the file"), std::string::npos)
        << img.status();
  }
  EXPECT_TRUE(DecodePng(good).ok());
}

// The pixel bound is checked from the header, before the pixels are allocated.
TEST(ImageIo, DecodersHonourMaxPixels) {
  const RgbaImage image = Noise(64, 32);
  auto png = EncodePng(image);
  auto jpeg = EncodeJpeg(image, 90, ChromaSubsampling::k444);
  ASSERT_TRUE(png.ok() && jpeg.ok());
  EXPECT_TRUE(DecodePng(*png, 64 * 32).ok());
  EXPECT_TRUE(DecodeJpeg(*jpeg, 64 * 32).ok());
  EXPECT_EQ(DecodePng(*png, 64 * 32 - 1).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(DecodeJpeg(*jpeg, 64 * 32 - 1).status().code(), absl::StatusCode::kInvalidArgument);
}

// ---- Metrics -------------------------------------------------------------------------------

TEST(ImageIo, PsnrIdenticalIsInfinite) {
  const RgbaImage a = Noise(16, 8);
  auto psnr = Psnr(a, a);
  ASSERT_TRUE(psnr.ok());
  EXPECT_TRUE(std::isinf(*psnr));
  EXPECT_GT(*psnr, 0.0);
}

TEST(ImageIo, PsnrIgnoresAlpha) {
  RgbaImage a = Noise(16, 8);
  RgbaImage b = a;
  for (size_t i = 3; i < b.pixels.size(); i += 4) b.pixels[i] ^= 0xFF;
  auto psnr = Psnr(a, b);
  ASSERT_TRUE(psnr.ok());
  EXPECT_TRUE(std::isinf(*psnr));
}

TEST(ImageIo, PsnrSinglePixelDifference) {
  RgbaImage a = Gradient(4, 4);
  RgbaImage b = a;
  // One channel of one pixel off by 10 (pick a value that cannot wrap).
  uint8_t& g = b.pixels[(1 * 4 + 2) * 4 + 1];
  g = static_cast<uint8_t>(g >= 128 ? g - 10 : g + 10);
  // MSE over 16 pixels x 3 channels: 10^2 / 48.
  const double mse = 100.0 / 48.0;
  const double expected = 10.0 * std::log10(255.0 * 255.0 / mse);  // ~ 44.9 dB
  auto psnr = Psnr(a, b);
  ASSERT_TRUE(psnr.ok());
  EXPECT_NEAR(*psnr, expected, 1e-9);
  auto reverse = Psnr(b, a);
  ASSERT_TRUE(reverse.ok());
  EXPECT_DOUBLE_EQ(*psnr, *reverse);
}

TEST(ImageIo, PsnrRejectsSizeMismatch) {
  EXPECT_EQ(Psnr(Noise(16, 8), Noise(8, 16)).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(Psnr(Noise(16, 8), Noise(16, 9)).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_FALSE(Psnr(RgbaImage{}, RgbaImage{}).ok());
  RgbaImage broken = Noise(4, 4);
  broken.pixels.pop_back();
  EXPECT_FALSE(Psnr(broken, Noise(4, 4)).ok());
}

TEST(ImageIo, DiffImageAmplifiesDifferences) {
  RgbaImage a = Noise(4, 4);
  for (size_t i = 0; i < a.pixels.size(); i += 4) {
    a.pixels[i] = 100;
    a.pixels[i + 1] = 100;
    a.pixels[i + 2] = 100;
  }
  RgbaImage b = a;
  b.pixels[0] = 103;  // |d| = 3 -> 24 at gain 8
  b.pixels[1] = 40;   // |d| = 60 -> clamped to 255
  auto diff = DiffImage(a, b);
  ASSERT_TRUE(diff.ok()) << diff.status();
  ASSERT_EQ(diff->width, 4u);
  EXPECT_EQ(diff->pixels[0], 24);
  EXPECT_EQ(diff->pixels[1], 255);
  EXPECT_EQ(diff->pixels[2], 0);
  for (size_t i = 3; i < diff->pixels.size(); i += 4) EXPECT_EQ(diff->pixels[i], 255);
  for (size_t i = 4; i < diff->pixels.size(); ++i) {
    if (i % 4 != 3) {
      EXPECT_EQ(diff->pixels[i], 0);
    }
  }
  EXPECT_FALSE(DiffImage(Noise(4, 4), Noise(5, 4)).ok());
}

// ---- Files ---------------------------------------------------------------------------------

TEST(ImageIo, FileRoundTrip) {
  const std::string path = testing::TempDir() + "/tessera_image_io_test.bin";
  const std::vector<uint8_t> bytes = Noise(100, 100).pixels;
  ASSERT_TRUE(WriteFileBytes(path, bytes).ok());
  auto read = ReadFileBytes(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(*read, bytes);

  ASSERT_TRUE(WriteFileBytes(path, {}).ok());
  read = ReadFileBytes(path);
  ASSERT_TRUE(read.ok());
  EXPECT_TRUE(read->empty());
  std::remove(path.c_str());
}

TEST(ImageIo, FileErrorsNameThePath) {
  const std::string missing = testing::TempDir() + "/no/such/dir/tessera_missing.png";
  auto read = ReadFileBytes(missing);
  ASSERT_FALSE(read.ok());
  EXPECT_EQ(read.status().code(), absl::StatusCode::kNotFound);
  EXPECT_NE(read.status().message().find(missing), std::string::npos) << read.status();

  const std::vector<uint8_t> bytes = {1, 2, 3};
  absl::Status write = WriteFileBytes(missing, bytes);
  ASSERT_FALSE(write.ok());
  EXPECT_NE(write.message().find(missing), std::string::npos) << write;
}

}  // namespace
}  // namespace tessera

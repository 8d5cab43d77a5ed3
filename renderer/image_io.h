#pragma once
// Image encoding/decoding for frames and golden-image tests: JPEG through TurboJPEG, PNG
// through libpng, and the comparison metrics the render tests use. CPU only.
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace tessera {

// Tightly packed 8-bit RGBA pixels, top row first.
struct RgbaImage {
  uint32_t width = 0;
  uint32_t height = 0;
  std::vector<uint8_t> pixels;  // width * height * 4
};

// Pixels someone else holds, in the same layout: an RgbaImage's, or a frame's left in the mapped
// memory the device copied them into (LentPixels, renderer.h). What the encoders read.
struct RgbaView {
  uint32_t width = 0;
  uint32_t height = 0;
  std::span<const uint8_t> pixels;  // width * height * 4

  RgbaView() = default;
  RgbaView(uint32_t w, uint32_t h, std::span<const uint8_t> p) : width(w), height(h), pixels(p) {}
  RgbaView(const RgbaImage& image)  // NOLINT(google-explicit-constructor): a view of it
      : width(image.width), height(image.height), pixels(image.pixels) {}
};

enum class ChromaSubsampling { k420, k444 };

// Encodes RGBA8 (alpha ignored) as baseline JPEG. quality 1..100; INVALID_ARGUMENT otherwise.
absl::StatusOr<std::vector<uint8_t>> EncodeJpeg(RgbaView image, int quality,
                                                ChromaSubsampling subsampling);
// The same, as `strips` horizontal strips (at most kMaxJpegStrips, and one per MCU row) encoded on
// up to one thread per hardware thread and spliced into one JPEG with restart markers between
// them; the decoded pixels equal the one-strip encode's, and the bytes do not depend on the
// machine (a render-farm frame is byte-identical on every daemon). strips 0: AutoJpegStrips.
absl::StatusOr<std::vector<uint8_t>> EncodeJpeg(RgbaView image, int quality,
                                                ChromaSubsampling subsampling, uint32_t strips);
inline constexpr uint32_t kMaxJpegStrips = 8;
// One strip below 1920x1080 pixels (the encoder pool already spreads sessions over the cores),
// else kMaxJpegStrips, whatever the machine.
uint32_t AutoJpegStrips(RgbaView image);
// Larger than any frame we render; also stops a tiny file from declaring gigapixels.
inline constexpr uint32_t kMaxImageSide = 16384;

// Decodes a JPEG to RGBA8 (alpha 255). The header's size is checked (each side at most
// kMaxImageSide, at most `max_pixels` in all) before the pixels are allocated.
absl::StatusOr<RgbaImage> DecodeJpeg(std::span<const uint8_t> jpeg,
                                     uint64_t max_pixels = uint64_t{kMaxImageSide} * kMaxImageSide);

// Encodes RGBA8 as a lossless 8-bit RGBA PNG: every row Paeth-filtered, the rows deflated with
// zlib's run-length strategy in at most `strips` horizontal strips (at most kMaxPngStrips, as
// many rows each, the last shorter) on up to one thread per hardware thread, each strip's deflate
// stream ended with a sync flush and spliced into the one zlib stream (pigz's way). The bytes
// depend on the image, `strips` and the zlib build, not on the threads or the CPU.
// strips 0: AutoPngStrips. (Sponza at 1280x720 on the 2-core development
// machine: libpng's defaults, adaptive filters at zlib level 6, took 634 ms and 1.61 MB; this
// 85 ms on one thread, 43 ms in 8 strips on two, and 1.60 MB. README, "The CPU side of a large
// frame".)
absl::StatusOr<std::vector<uint8_t>> EncodePng(RgbaView image, uint32_t strips = 0);
inline constexpr uint32_t kMaxPngStrips = 8;
// A strip per 64 rows, at most kMaxPngStrips, whatever the machine.
uint32_t AutoPngStrips(RgbaView image);
// Decodes any PNG (gray, palette, 16-bit, with/without alpha) to RGBA8; sizes as DecodeJpeg.
absl::StatusOr<RgbaImage> DecodePng(std::span<const uint8_t> png,
                                    uint64_t max_pixels = uint64_t{kMaxImageSide} * kMaxImageSide);
// Decodes a WebP image (lossy or lossless, with or without alpha; not animated) to RGBA8 with
// libwebp; sizes as DecodeJpeg. Lossy WebP without alpha decodes with alpha 255.
absl::StatusOr<RgbaImage> DecodeWebp(std::span<const uint8_t> webp,
                                     uint64_t max_pixels = uint64_t{kMaxImageSide} * kMaxImageSide);
// Whether `data` starts as a WebP file does ("RIFF", a size, "WEBP").
bool IsWebp(std::span<const uint8_t> data);
// A WebP image's width and height from its headers (libwebp's WebPGetInfo), nothing decoded;
// false when they are cut short or not WebP.
bool ReadWebpSize(std::span<const uint8_t> webp, uint32_t* width, uint32_t* height);
// Encodes RGBA8 as lossless WebP (libwebp; tests make WebP textures with it).
absl::StatusOr<std::vector<uint8_t>> EncodeWebpLossless(RgbaView image);
// INVALID_ARGUMENT naming `what` when the image is empty, larger than kMaxImageSide on a side,
// or its pixel buffer does not hold width x height RGBA.
absl::Status ValidateImage(RgbaView image, const char* what);

// Reads/writes a whole file. Errors name the path.
absl::StatusOr<std::vector<uint8_t>> ReadFileBytes(const std::string& path);
absl::Status WriteFileBytes(const std::string& path, std::span<const uint8_t> bytes);

// PSNR in dB over the RGB channels of two images of the same size (alpha ignored);
// +infinity when identical. INVALID_ARGUMENT when sizes differ.
absl::StatusOr<double> Psnr(const RgbaImage& a, const RgbaImage& b);

// A visual diff: |a - b| per channel, amplified by `gain` and clamped, alpha 255.
absl::StatusOr<RgbaImage> DiffImage(const RgbaImage& a, const RgbaImage& b, float gain = 8.0f);

}  // namespace tessera

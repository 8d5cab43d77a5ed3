#pragma once
// Golden-image comparison shared by the render tests: tests/render/golden/<name>.png within a
// bound that holds across drivers (GoldenBound), the actual image and an amplified diff written
// on failure;
// TESSERA_UPDATE_GOLDENS=1 rewrites the golden instead (look at it before committing).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "renderer/image_io.h"
#include "absl/strings/str_format.h"
#include "renderer/image_metrics.h"
#include "tests/render/shared_renderer.h"

namespace tessera {

// An environment variable, or `fallback` when unset.
inline std::string Env(const char* name, const char* fallback = "") {
  const char* v = std::getenv(name);
  return v ? v : fallback;
}

// How far a golden comparison may go. Goldens are rendered on lavapipe. Measured by
// GoldenCheckTest and the golden tests themselves (each prints its figures):
//  - SwiftShader against lavapipe's goldens: plain PSNR 40.9-56.1 dB, neighbourhood PSNR
//    48.9-64.5 dB, at most 0.021 % of pixels more than 16 levels out.
//  - Planted bugs (a flipped normal map on the helmet, each of the demo's lights missing, a
//    texture shifted by 1/32 or 1/64), on either CPU device: plain 38.0 dB and less,
//    neighbourhood 42.8 dB and less, 0.195 % out and more.
//  - An NVIDIA H200 (tests/render/golden/h200/) filters textures and chooses LODs a little
//    differently: plain 29.1-34.8 dB, all along the checkerboards' edges; neighbourhood
//    41.4-45.5 dB, 0.06-0.30 % out.
// CPU devices get a bound between the first two, with about 3 dB of margin each side. GPUs get a
// looser one that accepts the H200 and still fails every missing light and shifted texture, but
// not the helmet's flipped normal map (42.8 dB): on a GPU that bug would pass.
struct GoldenBound {
  double min_plain_psnr = 0.0;  // PSNR of the pixels
  double min_psnr = 0.0;        // of the excess over the 3x3 neighbourhood ranges
  double max_outliers = 1.0;    // fraction of pixels more than 16 levels outside them
};
// PSNR in dB of two captured HDR colours (FrameCapture::hdr, RGBA), RGB clamped to 1 (the peak):
// how far TAA's frame is from a reference in the colours the tonemapper mostly shows.
inline double HdrPsnr(const std::vector<float>& a, const std::vector<float>& b) {
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    if (i % 4 == 3) continue;
    const double d = std::min(a[i], 1.0f) - std::min(b[i], 1.0f);
    sum += d * d;
  }
  return 10.0 * std::log10(1.0 / (sum / double(a.size() / 4 * 3)));
}

inline constexpr GoldenBound kCpuGoldenBound{39.0, 46.0, 0.001};
inline constexpr GoldenBound kGpuGoldenBound{0.0, 40.0, 0.005};

inline GoldenBound GoldenBoundFor(const DeviceInfo& device) {
  return device.type == "cpu" ? kCpuGoldenBound : kGpuGoldenBound;
}

struct GoldenError {
  double plain_psnr = 0.0;
  NeighbourhoodError neighbourhood;
};

inline absl::StatusOr<GoldenError> MeasureGoldenError(const RgbaImage& image,
                                                      const RgbaImage& golden) {
  absl::StatusOr<double> plain = Psnr(image, golden);
  if (!plain.ok()) return plain.status();
  absl::StatusOr<NeighbourhoodError> n = CompareNeighbourhood(image, golden);
  if (!n.ok()) return n.status();
  return GoldenError{*plain, *n};
}

inline bool WithinBound(const GoldenError& e, const GoldenBound& bound) {
  return e.plain_psnr >= bound.min_plain_psnr && e.neighbourhood.psnr >= bound.min_psnr &&
         e.neighbourhood.outlier_fraction <= bound.max_outliers;
}

inline std::string Describe(const GoldenError& e) {
  return absl::StrFormat("plain %.2f dB, neighbourhood %.2f dB, %.3f %% out, largest %d",
                         e.plain_psnr, e.neighbourhood.psnr,
                         100.0 * e.neighbourhood.outlier_fraction, e.neighbourhood.max_excess);
}

inline std::string GoldenPath(const std::string& name) {
  return Env("TESSERA_GOLDEN_DIR", TESSERA_DEFAULT_GOLDEN_DIR) + "/" + name + ".png";
}

// tests/render/golden/<name>.png, decoded.
inline absl::StatusOr<RgbaImage> ReadGolden(const std::string& name) {
  absl::StatusOr<std::vector<uint8_t>> bytes = ReadFileBytes(GoldenPath(name));
  if (!bytes.ok()) return bytes.status();
  return DecodePng(*bytes);
}

// Compares with tests/render/golden/<name>.png within the shared renderer's device's bound (or
// writes it when updating goldens).
inline void CompareWithGolden(const std::string& name, const RgbaImage& image) {
  const std::string golden_path = GoldenPath(name);
  if (Env("TESSERA_UPDATE_GOLDENS") == "1") {
    absl::StatusOr<std::vector<uint8_t>> png = EncodePng(image);
    ASSERT_TRUE(png.ok()) << png.status();
    ASSERT_TRUE(WriteFileBytes(golden_path, *png).ok());
    GTEST_SKIP() << "wrote " << golden_path;
  }
  absl::StatusOr<RgbaImage> golden = ReadGolden(name);
  ASSERT_TRUE(golden.ok()) << golden.status() << " (run with TESSERA_UPDATE_GOLDENS=1)";
  absl::StatusOr<GoldenError> e = MeasureGoldenError(image, *golden);
  ASSERT_TRUE(e.ok()) << e.status();
  const GoldenBound bound = GoldenBoundFor(SharedRenderer().device_info());
  std::printf("golden %s: %s\n", name.c_str(), Describe(*e).c_str());
  if (!WithinBound(*e, bound)) {
    const std::filesystem::path out_dir =
        Env("TESSERA_TEST_OUTPUT_DIR", TESSERA_DEFAULT_OUTPUT_DIR);
    std::filesystem::create_directories(out_dir);
    const std::string actual = (out_dir / (name + ".actual.png")).string();
    const std::string diff = (out_dir / (name + ".diff.png")).string();
    if (auto png = EncodePng(image); png.ok()) (void)WriteFileBytes(actual, *png);
    if (auto d = DiffImage(image, *golden); d.ok())
      if (auto png = EncodePng(*d); png.ok()) (void)WriteFileBytes(diff, *png);
    ADD_FAILURE() << name << ": " << Describe(*e) << "; bound: plain >= " << bound.min_plain_psnr
                  << " dB, neighbourhood >= " << bound.min_psnr << " dB and <= "
                  << 100.0 * bound.max_outliers << " % out; wrote " << actual << " and " << diff;
  }
}

}  // namespace tessera

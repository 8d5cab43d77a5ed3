#pragma once
// Golden-image comparison shared by the render tests: tests/render/golden/<name>.png, PSNR
// against a bound, the actual image and an amplified diff written on failure;
// TESSERA_UPDATE_GOLDENS=1 rewrites the golden instead (look at it before committing).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "renderer/image_io.h"

namespace tessera {

// An environment variable, or `fallback` when unset.
inline std::string Env(const char* name, const char* fallback = "") {
  const char* v = std::getenv(name);
  return v ? v : fallback;
}

// Compares with tests/render/golden/<name>.png (or writes it when updating goldens).
inline void CompareWithGolden(const std::string& name, const RgbaImage& image, double min_psnr) {
  const std::string golden_path =
      Env("TESSERA_GOLDEN_DIR", TESSERA_DEFAULT_GOLDEN_DIR) + "/" + name + ".png";
  if (Env("TESSERA_UPDATE_GOLDENS") == "1") {
    absl::StatusOr<std::vector<uint8_t>> png = EncodePng(image);
    ASSERT_TRUE(png.ok()) << png.status();
    ASSERT_TRUE(WriteFileBytes(golden_path, *png).ok());
    GTEST_SKIP() << "wrote " << golden_path;
  }
  absl::StatusOr<std::vector<uint8_t>> bytes = ReadFileBytes(golden_path);
  ASSERT_TRUE(bytes.ok()) << bytes.status() << " (run with TESSERA_UPDATE_GOLDENS=1)";
  absl::StatusOr<RgbaImage> golden = DecodePng(*bytes);
  ASSERT_TRUE(golden.ok()) << golden.status();
  absl::StatusOr<double> psnr = Psnr(image, *golden);
  ASSERT_TRUE(psnr.ok()) << psnr.status();
  if (*psnr < min_psnr) {
    const std::filesystem::path out_dir =
        Env("TESSERA_TEST_OUTPUT_DIR", TESSERA_DEFAULT_OUTPUT_DIR);
    std::filesystem::create_directories(out_dir);
    const std::string actual = (out_dir / (name + ".actual.png")).string();
    const std::string diff = (out_dir / (name + ".diff.png")).string();
    if (auto png = EncodePng(image); png.ok()) (void)WriteFileBytes(actual, *png);
    if (auto d = DiffImage(image, *golden); d.ok())
      if (auto png = EncodePng(*d); png.ok()) (void)WriteFileBytes(diff, *png);
    ADD_FAILURE() << name << ": PSNR " << *psnr << " dB < " << min_psnr << " dB; wrote " << actual
                  << " and " << diff;
  }
}

}  // namespace tessera

#include "renderer/image_metrics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "renderer/image_io.h"

namespace tessera {
namespace {

RgbaImage Solid(uint32_t w, uint32_t h, uint8_t r, uint8_t g, uint8_t b) {
  RgbaImage img;
  img.width = w;
  img.height = h;
  img.pixels.resize(size_t{w} * h * 4);
  for (size_t i = 0; i < img.pixels.size(); i += 4) {
    img.pixels[i + 0] = r;
    img.pixels[i + 1] = g;
    img.pixels[i + 2] = b;
    img.pixels[i + 3] = 255;
  }
  return img;
}

uint8_t* Px(RgbaImage& img, uint32_t x, uint32_t y) {
  return &img.pixels[(size_t{y} * img.width + x) * 4];
}
const uint8_t* Px(const RgbaImage& img, uint32_t x, uint32_t y) {
  return &img.pixels[(size_t{y} * img.width + x) * 4];
}

void SetRgb(RgbaImage& img, uint32_t x, uint32_t y, uint8_t r, uint8_t g, uint8_t b) {
  uint8_t* p = Px(img, x, y);
  p[0] = r;
  p[1] = g;
  p[2] = b;
}

// Structure at every scale: sines plus deterministic noise, values well inside 0..255.
RgbaImage Texture(uint32_t w, uint32_t h) {
  RgbaImage img = Solid(w, h, 0, 0, 0);
  uint32_t state = 777;
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      state = state * 1664525u + 1013904223u;
      const double n = static_cast<double>(state >> 24) / 255.0 - 0.5;
      const double v = 128 + 60 * std::sin(0.4 * x) * std::cos(0.3 * y) + 60 * n;
      const auto b = static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L));
      // Luma follows b (0.54 b + 54): SSIM sees the structure. R + G = 255 never looks like
      // the contact sheet's grey background.
      SetRgb(img, x, y, static_cast<uint8_t>(255 - b), b, static_cast<uint8_t>(b / 2));
    }
  }
  return img;
}

// Adds deterministic noise of up to +-amplitude to every RGB channel.
RgbaImage AddNoise(const RgbaImage& src, int amplitude, uint32_t seed) {
  RgbaImage img = src;
  uint32_t state = seed;
  for (size_t i = 0; i < img.pixels.size(); ++i) {
    if (i % 4 == 3) continue;
    state = state * 1664525u + 1013904223u;
    const int d = static_cast<int>(state >> 24) % (2 * amplitude + 1) - amplitude;
    img.pixels[i] = static_cast<uint8_t>(std::clamp(int{img.pixels[i]} + d, 0, 255));
  }
  return img;
}

// ---- sRGB ------------------------------------------------------------------------------------

TEST(SrgbTest, KnownValues) {
  EXPECT_FLOAT_EQ(SrgbToLinear(0.0f), 0.0f);
  EXPECT_FLOAT_EQ(SrgbToLinear(1.0f), 1.0f);
  EXPECT_NEAR(SrgbToLinear(0.5f), 0.2140f, 1e-4);
  // The linear segment below the knee.
  EXPECT_NEAR(SrgbToLinear(0.02f), 0.02f / 12.92f, 1e-7);
  EXPECT_NEAR(LinearToSrgb(0.5f), 0.7354f, 1e-4);
  EXPECT_NEAR(LinearToSrgb(0.0031308f), 0.04045f, 1e-5);
  EXPECT_FLOAT_EQ(LinearToSrgb(1.0f), 1.0f);
}

TEST(SrgbTest, RoundTripsAndIsMonotonic) {
  float previous = -1.0f;
  for (int i = 0; i <= 1000; ++i) {
    const float v = static_cast<float>(i) / 1000.0f;
    EXPECT_NEAR(LinearToSrgb(SrgbToLinear(v)), v, 1e-5) << v;
    EXPECT_NEAR(SrgbToLinear(LinearToSrgb(v)), v, 1e-5) << v;
    const float lin = SrgbToLinear(v);
    EXPECT_GT(lin, previous) << v;
    previous = lin;
  }
}

// ---- DownsampleBox --------------------------------------------------------------------------

TEST(DownsampleBoxTest, CheckerBlockAveragesInLinearLight) {
  // Two 2x2 blocks: a black/white checker (linear mean 0.5 -> sRGB 188, not the 128 a naive
  // average of the encoded values gives) and a uniform block.
  RgbaImage img = Solid(4, 2, 0, 0, 0);
  SetRgb(img, 0, 0, 255, 255, 255);
  SetRgb(img, 1, 1, 255, 255, 255);
  for (uint32_t y = 0; y < 2; ++y) {
    for (uint32_t x = 2; x < 4; ++x) SetRgb(img, x, y, 77, 140, 9);
  }
  Px(img, 0, 0)[3] = 0;  // alpha is ignored and the output is opaque
  absl::StatusOr<RgbaImage> out = DownsampleBox(img, 2);
  ASSERT_TRUE(out.ok()) << out.status();
  ASSERT_EQ(out->width, 2u);
  ASSERT_EQ(out->height, 1u);
  ASSERT_EQ(out->pixels.size(), 8u);
  for (int c = 0; c < 3; ++c) EXPECT_EQ(Px(*out, 0, 0)[c], 188) << c;
  EXPECT_EQ(Px(*out, 0, 0)[3], 255);
  EXPECT_EQ(Px(*out, 1, 0)[0], 77);
  EXPECT_EQ(Px(*out, 1, 0)[1], 140);
  EXPECT_EQ(Px(*out, 1, 0)[2], 9);
  EXPECT_EQ(Px(*out, 1, 0)[3], 255);
}

TEST(DownsampleBoxTest, SixteenSamplesPerPixel) {
  // One white sample in a 4x4 block: linear 1/16 -> sRGB round(0.2773 * 255) = 71.
  RgbaImage img = Solid(8, 4, 0, 0, 0);
  SetRgb(img, 5, 2, 255, 255, 255);
  absl::StatusOr<RgbaImage> out = DownsampleBox(img, 4);
  ASSERT_TRUE(out.ok()) << out.status();
  ASSERT_EQ(out->width, 2u);
  ASSERT_EQ(out->height, 1u);
  EXPECT_EQ(Px(*out, 0, 0)[0], 0);
  const int expected = static_cast<int>(std::lround(LinearToSrgb(1.0f / 16.0f) * 255.0f));
  EXPECT_EQ(expected, 71);
  EXPECT_EQ(Px(*out, 1, 0)[0], expected);
}

TEST(DownsampleBoxTest, FactorOneIsIdentityForEveryValue) {
  RgbaImage img = Solid(256, 1, 0, 0, 0);
  for (uint32_t x = 0; x < 256; ++x) {
    SetRgb(img, x, 0, static_cast<uint8_t>(x), static_cast<uint8_t>(255 - x),
           static_cast<uint8_t>(x));
  }
  absl::StatusOr<RgbaImage> out = DownsampleBox(img, 1);
  ASSERT_TRUE(out.ok()) << out.status();
  EXPECT_EQ(out->pixels, img.pixels);
}

TEST(DownsampleBoxTest, RejectsBadFactor) {
  absl::StatusOr<RgbaImage> bad = DownsampleBox(Solid(1281, 720, 1, 2, 3), 4);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("1281x720"), std::string::npos) << bad.status();
  EXPECT_EQ(DownsampleBox(Solid(8, 6, 0, 0, 0), 4).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(DownsampleBox(Solid(8, 8, 0, 0, 0), 0).status().code(),
            absl::StatusCode::kInvalidArgument);
  RgbaImage broken = Solid(4, 4, 0, 0, 0);
  broken.pixels.pop_back();
  EXPECT_EQ(DownsampleBox(broken, 2).status().code(), absl::StatusCode::kInvalidArgument);
}

// ---- Masks ----------------------------------------------------------------------------------

TEST(DifferenceMaskTest, ThresholdIsExclusive) {
  RgbaImage a = Solid(5, 1, 100, 100, 100);
  RgbaImage b = a;
  Px(b, 0, 0)[0] = 102;  // differs by exactly 2: not selected
  Px(b, 1, 0)[0] = 103;  // 3: selected
  Px(b, 2, 0)[1] = 97;   // 3 the other way, in green
  Px(b, 3, 0)[2] = 98;   // 2 in blue: not selected
  Px(b, 4, 0)[3] = 0;    // alpha only: ignored
  absl::StatusOr<std::vector<uint8_t>> mask = DifferenceMask(a, b);
  ASSERT_TRUE(mask.ok()) << mask.status();
  EXPECT_EQ(*mask, (std::vector<uint8_t>{0, 1, 1, 0, 0}));

  absl::StatusOr<std::vector<uint8_t>> strict = DifferenceMask(a, b, 0);
  ASSERT_TRUE(strict.ok());
  EXPECT_EQ(*strict, (std::vector<uint8_t>{1, 1, 1, 1, 0}));
}

TEST(DifferenceMaskTest, RejectsBadInput) {
  EXPECT_EQ(DifferenceMask(Solid(4, 4, 0, 0, 0), Solid(4, 5, 0, 0, 0)).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(DifferenceMask(Solid(4, 4, 0, 0, 0), Solid(4, 4, 0, 0, 0), -1).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(MaskTest, InvertAndCount) {
  const std::vector<uint8_t> mask = {0, 1, 7, 0, 255};
  EXPECT_EQ(MaskCount(mask), 3u);
  EXPECT_EQ(InvertMask(mask), (std::vector<uint8_t>{1, 0, 0, 1, 0}));
  EXPECT_EQ(MaskCount(InvertMask(mask)), 2u);
  EXPECT_EQ(MaskCount({}), 0u);
}

// ---- PSNR -----------------------------------------------------------------------------------

TEST(PsnrMaskedTest, IdenticalIsInfinite) {
  RgbaImage a = Texture(20, 10);
  absl::StatusOr<double> p = PsnrMasked(a, a);
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_TRUE(std::isinf(*p) && *p > 0) << *p;
}

TEST(PsnrMaskedTest, KnownMse) {
  // Every channel off by 10: MSE 100, PSNR 10 log10(255^2 / 100) = 28.1308 dB.
  absl::StatusOr<double> p = PsnrMasked(Solid(8, 8, 100, 100, 100), Solid(8, 8, 110, 90, 110));
  ASSERT_TRUE(p.ok()) << p.status();
  EXPECT_NEAR(*p, 28.1308, 1e-3);
  // An empty mask means every pixel: the same as the unmasked Psnr.
  RgbaImage a = Texture(16, 16);
  RgbaImage b = AddNoise(a, 5, 3);
  absl::StatusOr<double> full = Psnr(a, b);
  absl::StatusOr<double> masked = PsnrMasked(a, b);
  ASSERT_TRUE(full.ok() && masked.ok());
  EXPECT_DOUBLE_EQ(*full, *masked);
}

TEST(PsnrMaskedTest, MaskRestrictsThePixels) {
  RgbaImage a = Solid(4, 1, 50, 50, 50);
  RgbaImage b = a;
  Px(b, 0, 0)[0] = 60;   // pixel 0: one channel off by 10
  Px(b, 3, 0)[1] = 250;  // pixel 3: a huge error
  // Pixels 1 and 2 only: identical there.
  absl::StatusOr<double> clean = PsnrMasked(a, b, {0, 1, 1, 0});
  ASSERT_TRUE(clean.ok());
  EXPECT_TRUE(std::isinf(*clean));
  // Pixels 0 and 1: MSE = 100 / 6.
  absl::StatusOr<double> p01 = PsnrMasked(a, b, {1, 1, 0, 0});
  ASSERT_TRUE(p01.ok());
  EXPECT_NEAR(*p01, 10.0 * std::log10(255.0 * 255.0 / (100.0 / 6.0)), 1e-9);
  // Adding pixel 3 makes it much worse.
  absl::StatusOr<double> p013 = PsnrMasked(a, b, {1, 1, 0, 1});
  ASSERT_TRUE(p013.ok());
  EXPECT_NEAR(*p013, 10.0 * std::log10(255.0 * 255.0 / ((100.0 + 200.0 * 200.0) / 9.0)), 1e-9);
  // Nothing selected: NaN.
  absl::StatusOr<double> none = PsnrMasked(a, b, {0, 0, 0, 0});
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(std::isnan(*none));
}

TEST(PsnrMaskedTest, RejectsBadInput) {
  RgbaImage a = Solid(4, 4, 0, 0, 0);
  EXPECT_EQ(PsnrMasked(a, a, std::vector<uint8_t>(15, 1)).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(PsnrMasked(a, Solid(4, 3, 0, 0, 0)).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// ---- SSIM -----------------------------------------------------------------------------------

// The textbook definition, one full 11x11 window per pixel, to check the separable version.
double ReferenceSsim(const RgbaImage& a, const RgbaImage& b, const std::vector<uint8_t>& mask) {
  std::array<double, 11> w{};
  double sum = 0;
  for (int k = -5; k <= 5; ++k) sum += w[k + 5] = std::exp(-(k * k) / (2.0 * 1.5 * 1.5));
  for (double& v : w) v /= sum;
  auto luma = [](const RgbaImage& img, int x, int y) {
    const uint8_t* p = Px(img, static_cast<uint32_t>(x), static_cast<uint32_t>(y));
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
  };
  const double c1 = 6.5025, c2 = 58.5225;
  const int width = static_cast<int>(a.width), height = static_cast<int>(a.height);
  double total = 0;
  int n = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (!mask.empty() && mask[static_cast<size_t>(y) * width + x] == 0) continue;
      double ma = 0, mb = 0, aa = 0, bb = 0, ab = 0;
      for (int j = -5; j <= 5; ++j) {
        for (int i = -5; i <= 5; ++i) {
          const int sx = std::clamp(x + i, 0, width - 1), sy = std::clamp(y + j, 0, height - 1);
          const double wt = w[i + 5] * w[j + 5];
          const double va = luma(a, sx, sy), vb = luma(b, sx, sy);
          ma += wt * va;
          mb += wt * vb;
          aa += wt * va * va;
          bb += wt * vb * vb;
          ab += wt * va * vb;
        }
      }
      const double va = aa - ma * ma, vb = bb - mb * mb, cov = ab - ma * mb;
      total += ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
      ++n;
    }
  }
  return total / n;
}

TEST(SsimMaskedTest, IdenticalIsOne) {
  RgbaImage a = Texture(40, 30);
  absl::StatusOr<double> s = SsimMasked(a, a);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_NEAR(*s, 1.0, 1e-12);
}

TEST(SsimMaskedTest, NoiseLowersItAndInversionRuinsIt) {
  RgbaImage a = Texture(48, 40);
  absl::StatusOr<double> noisy = SsimMasked(a, AddNoise(a, 20, 99));
  ASSERT_TRUE(noisy.ok()) << noisy.status();
  EXPECT_LT(*noisy, 0.99);
  EXPECT_GT(*noisy, 0.3);
  RgbaImage inverted = a;
  for (size_t i = 0; i < inverted.pixels.size(); ++i) {
    if (i % 4 != 3) inverted.pixels[i] = static_cast<uint8_t>(255 - inverted.pixels[i]);
  }
  absl::StatusOr<double> inv = SsimMasked(a, inverted);
  ASSERT_TRUE(inv.ok());
  // Anti-correlated structure: negative, far below the noisy copy.
  EXPECT_LT(*inv, 0.0);
  EXPECT_LT(*inv, *noisy - 0.5);
}

TEST(SsimMaskedTest, MatchesDirectWindowIncludingBorders) {
  // Smaller than the window in one direction, so clamping is exercised on both sides.
  RgbaImage a = Texture(23, 9);
  RgbaImage b = AddNoise(a, 25, 5);
  for (uint32_t x = 0; x < 23; x += 3) SetRgb(b, x, 4, 255, 0, 255);
  absl::StatusOr<double> s = SsimMasked(a, b);
  ASSERT_TRUE(s.ok()) << s.status();
  EXPECT_NEAR(*s, ReferenceSsim(a, b, {}), 1e-9);
  std::vector<uint8_t> mask(23 * 9, 0);
  for (size_t i = 0; i < mask.size(); i += 4) mask[i] = 1;
  absl::StatusOr<double> sm = SsimMasked(a, b, mask);
  ASSERT_TRUE(sm.ok()) << sm.status();
  EXPECT_NEAR(*sm, ReferenceSsim(a, b, mask), 1e-9);
  EXPECT_NE(*sm, *s);
}

TEST(SsimMaskedTest, MaskSelectsTheRegion) {
  // The right half differs; pixels far enough left (window radius 5) still see identical windows.
  RgbaImage a = Texture(64, 16);
  RgbaImage b = a;
  for (uint32_t y = 0; y < 16; ++y) {
    for (uint32_t x = 32; x < 64; ++x) SetRgb(b, x, y, 0, 0, 0);
  }
  std::vector<uint8_t> left(64 * 16, 0), right(64 * 16, 0);
  for (uint32_t y = 0; y < 16; ++y) {
    for (uint32_t x = 0; x < 20; ++x) left[y * 64 + x] = 1;
    for (uint32_t x = 40; x < 64; ++x) right[y * 64 + x] = 1;
  }
  absl::StatusOr<double> sl = SsimMasked(a, b, left);
  absl::StatusOr<double> sr = SsimMasked(a, b, right);
  ASSERT_TRUE(sl.ok() && sr.ok());
  EXPECT_NEAR(*sl, 1.0, 1e-12);
  EXPECT_LT(*sr, 0.5);
  absl::StatusOr<double> none = SsimMasked(a, b, std::vector<uint8_t>(64 * 16, 0));
  ASSERT_TRUE(none.ok());
  EXPECT_TRUE(std::isnan(*none));
  EXPECT_EQ(SsimMasked(a, b, std::vector<uint8_t>(10, 1)).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(SsimMasked(a, Solid(64, 15, 0, 0, 0)).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// ---- Coverage -------------------------------------------------------------------------------

TEST(MeasureCoverageTest, SyntheticImage) {
  RgbaImage img = Solid(6, 1, 0, 0, 0);
  std::vector<float> coverage(6, 0.0f);
  // 0: black, coverage 0            -> error 0, not an edge
  // 1: white, coverage 1            -> error 0, not an edge
  SetRgb(img, 1, 0, 255, 255, 255);
  coverage[1] = 1.0f;
  // 2: white where coverage is 0.5  -> error 0.5, edge (analytic)
  SetRgb(img, 2, 0, 255, 255, 255);
  coverage[2] = 0.5f;
  // 3: grey 188 (linear ~0.5029) where coverage is 0 -> edge (estimate)
  SetRgb(img, 3, 0, 188, 188, 188);
  // 4: pure red: luminance is the Rec. 709 red weight, 0.2126 -> error 0, edge
  SetRgb(img, 4, 0, 255, 0, 0);
  coverage[4] = 0.2126f;
  // 5: coverage within float noise of 1, rendered white -> not an edge
  SetRgb(img, 5, 0, 255, 255, 255);
  coverage[5] = 1.0f - 1e-7f;

  absl::StatusOr<CoverageError> err = MeasureCoverage(img, coverage);
  ASSERT_TRUE(err.ok()) << err.status();
  const double grey = SrgbToLinear(188.0f / 255.0f);
  EXPECT_NEAR(grey, 0.5029, 1e-4);
  EXPECT_EQ(err->edge_pixels, 3u);
  EXPECT_NEAR(err->edge_mae, (0.5 + grey + 0.0) / 3.0, 1e-5);
  EXPECT_NEAR(err->all_mae, (0.5 + grey) / 6.0, 1e-5);
}

TEST(MeasureCoverageTest, NoEdgesAndBadInput) {
  RgbaImage img = Solid(2, 2, 255, 255, 255);
  absl::StatusOr<CoverageError> err = MeasureCoverage(img, {1, 1, 1, 0});
  ASSERT_TRUE(err.ok()) << err.status();
  EXPECT_EQ(err->edge_pixels, 0u);
  EXPECT_TRUE(std::isnan(err->edge_mae));
  EXPECT_NEAR(err->all_mae, 0.25, 1e-9);
  EXPECT_EQ(MeasureCoverage(img, {1, 1, 1}).status().code(), absl::StatusCode::kInvalidArgument);
}

// ---- Contact sheet --------------------------------------------------------------------------

// Layout constants the tests rely on (see ContactSheet in image_metrics.cpp).
constexpr uint32_t kGutter = 2;
constexpr uint32_t kBand = 12;

bool IsBackground(const RgbaImage& img, uint32_t x, uint32_t y) {
  const uint8_t* p = Px(img, x, y);
  return p[0] == 32 && p[1] == 32 && p[2] == 32 && p[3] == 255;
}

TEST(ContactSheetTest, SizeAndMagnifiedPixels) {
  RgbaImage a = Texture(16, 16), b = Texture(16, 16);
  SetRgb(a, 3, 4, 250, 1, 2);  // inside crop 0, one pixel right and down of its corner
  SetRgb(b, 3, 4, 3, 250, 4);
  const std::vector<Crop> crops = {{2, 3, 4, 5}, {0, 0, 8, 8}};
  absl::StatusOr<RgbaImage> sheet = ContactSheet({{"noaa", &a}, {"ref", &b}}, crops, 3);
  ASSERT_TRUE(sheet.ok()) << sheet.status();
  const uint32_t col_w = 8 * 3;
  EXPECT_EQ(sheet->width, kGutter + 2 * (col_w + kGutter));
  EXPECT_EQ(sheet->height, kBand + kGutter + 5 * 3 + kGutter + 8 * 3 + kGutter);
  ASSERT_EQ(sheet->pixels.size(), size_t{sheet->width} * sheet->height * 4);

  const uint32_t row0 = kBand + kGutter;
  for (uint32_t col = 0; col < 2; ++col) {
    const RgbaImage& src = col == 0 ? a : b;
    const uint32_t cx = kGutter + col * (col_w + kGutter);
    for (uint32_t dy = 0; dy < 3; ++dy) {
      for (uint32_t dx = 0; dx < 3; ++dx) {
        const uint8_t* p = Px(*sheet, cx + 1 * 3 + dx, row0 + 1 * 3 + dy);
        EXPECT_EQ(p[0], Px(src, 3, 4)[0]) << col << " " << dx << "," << dy;
        EXPECT_EQ(p[1], Px(src, 3, 4)[1]) << col << " " << dx << "," << dy;
        EXPECT_EQ(p[2], Px(src, 3, 4)[2]) << col << " " << dx << "," << dy;
      }
    }
    // Crop 0 is 4 px wide (12 zoomed) in a 24 px column: the rest of its row is background.
    EXPECT_TRUE(IsBackground(*sheet, cx + 12, row0));
    EXPECT_TRUE(IsBackground(*sheet, cx + col_w - 1, row0 + 14));
    // The gutter between the rows, and row 1's top-left pixel is the image's (0, 0).
    EXPECT_TRUE(IsBackground(*sheet, cx, row0 + 15));
    const uint32_t row1 = row0 + 15 + kGutter;
    EXPECT_EQ(Px(*sheet, cx, row1)[0], Px(src, 0, 0)[0]);
    EXPECT_EQ(Px(*sheet, cx + col_w - 1, row1 + 23)[1], Px(src, 7, 7)[1]);
  }
  // The gutter between the columns.
  EXPECT_TRUE(IsBackground(*sheet, kGutter + col_w, row0 + 5));
  EXPECT_TRUE(IsBackground(*sheet, 0, row0 + 5));
}

uint32_t WhiteInBand(const RgbaImage& sheet, uint32_t x0, uint32_t x1) {
  uint32_t n = 0;
  for (uint32_t y = 0; y < kBand; ++y) {
    for (uint32_t x = x0; x < x1; ++x) {
      const uint8_t* p = Px(sheet, x, y);
      if (p[0] == 255 && p[1] == 255 && p[2] == 255) ++n;
    }
  }
  return n;
}

TEST(ContactSheetTest, LabelsAreDrawnAndTruncated) {
  RgbaImage img = Solid(8, 8, 0, 0, 0);
  // Column width 4 * 6 = 24 px: room for 4 glyphs.
  absl::StatusOr<RgbaImage> sheet = ContactSheet(
      {{"WWWWWWWWWWWWWWWWWWWW", &img}, {"", &img}, {"e", &img}, {"E", &img}, {"??", &img}},
      {{0, 0, 4, 4}}, 6);
  ASSERT_TRUE(sheet.ok()) << sheet.status();
  const uint32_t col_w = 24;
  auto col_x = [&](uint32_t c) { return kGutter + c * (col_w + kGutter); };
  // The long label fills its column but stops there: the gutter and the next (unlabelled)
  // column's band stay dark.
  const uint32_t w_pixels = WhiteInBand(*sheet, col_x(0), col_x(0) + col_w);
  EXPECT_GT(w_pixels, 4u * 10u);
  EXPECT_EQ(WhiteInBand(*sheet, col_x(0) + col_w, col_x(2)), 0u);
  // Four 'W's exactly: the same count as a four-letter label would give.
  absl::StatusOr<RgbaImage> four = ContactSheet({{"WWWW", &img}}, {{0, 0, 4, 4}}, 6);
  ASSERT_TRUE(four.ok());
  EXPECT_EQ(WhiteInBand(*four, 0, four->width), w_pixels);
  // Lowercase draws as uppercase; unknown characters are blanks.
  const uint32_t e_lower = WhiteInBand(*sheet, col_x(2), col_x(2) + col_w);
  EXPECT_GT(e_lower, 0u);
  EXPECT_EQ(e_lower, WhiteInBand(*sheet, col_x(3), col_x(3) + col_w));
  EXPECT_EQ(WhiteInBand(*sheet, col_x(4), col_x(4) + col_w), 0u);
  // Distinct glyphs differ.
  absl::StatusOr<RgbaImage> one = ContactSheet({{"1", &img}}, {{0, 0, 4, 4}}, 6);
  absl::StatusOr<RgbaImage> eight = ContactSheet({{"8", &img}}, {{0, 0, 4, 4}}, 6);
  ASSERT_TRUE(one.ok() && eight.ok());
  EXPECT_NE(one->pixels, eight->pixels);
}

TEST(ContactSheetTest, CropsClampToTheImage) {
  RgbaImage img = Texture(16, 16);
  // Starts inside but runs 6 px past the corner: 2x2 remain.
  absl::StatusOr<RgbaImage> sheet = ContactSheet({{"a", &img}}, {{14, 14, 8, 8}}, 2);
  ASSERT_TRUE(sheet.ok()) << sheet.status();
  EXPECT_EQ(sheet->width, kGutter + 4 + kGutter);
  EXPECT_EQ(sheet->height, kBand + kGutter + 4 + kGutter);
  EXPECT_EQ(Px(*sheet, kGutter + 3, kBand + kGutter + 3)[0], Px(img, 15, 15)[0]);
}

TEST(ContactSheetTest, RejectsBadInput) {
  RgbaImage a = Solid(16, 16, 0, 0, 0), b = Solid(16, 8, 0, 0, 0);
  EXPECT_EQ(ContactSheet({{"a", &a}, {"b", &b}}, {{0, 0, 4, 4}}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ContactSheet({{"a", &a}, {"null", nullptr}}, {{0, 0, 4, 4}}).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ContactSheet({}, {{0, 0, 4, 4}}).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ContactSheet({{"a", &a}}, {{0, 0, 4, 4}}, 0).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ContactSheet({{"a", &a}}, {{0, 0, 0, 4}}).status().code(),
            absl::StatusCode::kInvalidArgument);
  // 16 px at zoom 2000 would be 32000 px wide.
  EXPECT_EQ(ContactSheet({{"a", &a}}, {{0, 0, 16, 16}}, 2000).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// ---- Busiest crops --------------------------------------------------------------------------

bool Contains(const Crop& c, uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1) {
  return c.x <= x0 && c.y <= y0 && x1 <= c.x + c.width && y1 <= c.y + c.height;
}

bool Overlap(const Crop& a, const Crop& b) {
  return a.x < b.x + b.width && b.x < a.x + a.width && a.y < b.y + b.height && b.y < a.y + a.height;
}

TEST(BusiestCropsTest, FindsPlantedClusters) {
  const uint32_t w = 64, h = 64;
  std::vector<uint8_t> mask(w * h, 0);
  auto plant = [&](uint32_t x0, uint32_t y0, uint32_t x1, uint32_t y1) {
    for (uint32_t y = y0; y < y1; ++y) {
      for (uint32_t x = x0; x < x1; ++x) mask[y * w + x] = 1;
    }
  };
  plant(40, 20, 48, 28);  // 64 pixels
  plant(5, 50, 8, 53);    // 9 pixels
  const std::vector<Crop> crops = BusiestCrops(mask, w, h, 16, 5);
  // Every other window overlaps the first pick or is empty.
  ASSERT_EQ(crops.size(), 2u);
  for (const Crop& c : crops) {
    EXPECT_EQ(c.width, 16u);
    EXPECT_EQ(c.height, 16u);
    EXPECT_LE(c.x + c.width, w);
    EXPECT_LE(c.y + c.height, h);
  }
  EXPECT_TRUE(Contains(crops[0], 40, 20, 48, 28)) << crops[0].x << "," << crops[0].y;
  EXPECT_TRUE(Contains(crops[1], 5, 50, 8, 53)) << crops[1].x << "," << crops[1].y;
  EXPECT_FALSE(Overlap(crops[0], crops[1]));

  EXPECT_EQ(BusiestCrops(mask, w, h, 16, 1).size(), 1u);
  EXPECT_TRUE(BusiestCrops(std::vector<uint8_t>(w * h, 0), w, h, 16, 3).empty());
  EXPECT_TRUE(BusiestCrops(mask, w, h + 1, 16, 3).empty());  // wrong mask size
}

TEST(BusiestCropsTest, ReachesTheRightAndBottomEdges) {
  // 70 is not a multiple of the stride (4): the cluster in the last columns and rows must still
  // be covered by a whole window.
  const uint32_t w = 70, h = 70;
  std::vector<uint8_t> mask(w * h, 0);
  for (uint32_t y = 66; y < 70; ++y) {
    for (uint32_t x = 66; x < 70; ++x) mask[y * w + x] = 1;
  }
  mask[0] = 1;
  const std::vector<Crop> crops = BusiestCrops(mask, w, h, 16, 4);
  ASSERT_EQ(crops.size(), 2u);
  EXPECT_TRUE(Contains(crops[0], 66, 66, 70, 70)) << crops[0].x << "," << crops[0].y;
  EXPECT_TRUE(Contains(crops[1], 0, 0, 1, 1));
}

// An edge a pixel sharper, softer or shifted stays within the other image's neighbourhood; a
// change of level does not, and it is measured by how far it leaves the range.
TEST(CompareNeighbourhoodTest, ToleratesEdgeShiftsNotLevelChanges) {
  auto edge = [](uint32_t at, uint8_t mid) {
    RgbaImage img = Solid(16, 8, 20, 20, 20);
    for (uint32_t y = 0; y < 8; ++y) {
      for (uint32_t x = at; x < 16; ++x) {
        uint8_t* p = &img.pixels[(size_t{y} * 16 + x) * 4];
        p[0] = p[1] = p[2] = x == at ? mid : 220;
      }
    }
    return img;
  };
  const RgbaImage golden = edge(8, 220);
  for (const RgbaImage& other : {edge(8, 120), edge(7, 220), edge(9, 220), edge(7, 60)}) {
    absl::StatusOr<NeighbourhoodError> e = CompareNeighbourhood(other, golden);
    ASSERT_TRUE(e.ok()) << e.status();
    EXPECT_EQ(e->max_excess, 0);
    EXPECT_TRUE(std::isinf(e->psnr));
    EXPECT_EQ(e->outlier_fraction, 0.0);
  }
  // Two pixels off is outside a 3x3 neighbourhood: column 9 of the shifted edge is 200 below
  // its golden neighbours, and column 8 of the golden 200 above the shifted edge's.
  absl::StatusOr<NeighbourhoodError> far = CompareNeighbourhood(edge(10, 220), golden);
  ASSERT_TRUE(far.ok());
  EXPECT_EQ(far->max_excess, 200);
  EXPECT_DOUBLE_EQ(far->outlier_fraction, 16.0 / 128.0);  // two columns of 16
  // Brighter by 10 everywhere: every pixel 10 out (not an outlier at 16), 28.13 dB.
  RgbaImage brighter = golden;
  for (size_t i = 0; i < brighter.pixels.size(); ++i)
    if (i % 4 != 3) brighter.pixels[i] = uint8_t(brighter.pixels[i] + 10);
  absl::StatusOr<NeighbourhoodError> b = CompareNeighbourhood(brighter, golden);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->max_excess, 10);
  EXPECT_EQ(b->outlier_fraction, 0.0);
  EXPECT_NEAR(b->psnr, 10.0 * std::log10(255.0 * 255.0 / 100.0), 1e-9);
  EXPECT_EQ(CompareNeighbourhood(Solid(4, 4, 0, 0, 0), golden).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace tessera

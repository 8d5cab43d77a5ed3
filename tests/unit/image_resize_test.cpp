#include "renderer/image_resize.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <numbers>
#include <numeric>
#include <vector>

#include "absl/status/status.h"
#include "renderer/image_io.h"

namespace tessera {
namespace {

RgbaImage Solid(uint32_t w, uint32_t h, uint8_t r, uint8_t g, uint8_t b, uint8_t a) {
  RgbaImage img;
  img.width = w;
  img.height = h;
  img.pixels.resize(size_t{w} * h * 4);
  for (size_t i = 0; i < img.pixels.size(); i += 4) {
    img.pixels[i + 0] = r;
    img.pixels[i + 1] = g;
    img.pixels[i + 2] = b;
    img.pixels[i + 3] = a;
  }
  return img;
}

uint8_t* Px(RgbaImage& img, uint32_t x, uint32_t y) {
  return &img.pixels[(size_t{y} * img.width + x) * 4];
}
const uint8_t* Px(const RgbaImage& img, uint32_t x, uint32_t y) {
  return &img.pixels[(size_t{y} * img.width + x) * 4];
}

uint8_t ToByte(double v) { return static_cast<uint8_t>(std::clamp(std::lround(v), 0L, 255L)); }

// Full-range noise in every channel, alpha included: hard edges everywhere, so the filter
// overshoots and the clamping and edge handling are exercised.
RgbaImage Noise(uint32_t w, uint32_t h, uint32_t seed) {
  RgbaImage img = Solid(w, h, 0, 0, 0, 0);
  uint32_t state = seed;
  for (uint8_t& v : img.pixels) {
    state = state * 1664525u + 1013904223u;
    v = static_cast<uint8_t>(state >> 24);
  }
  return img;
}

// Low-frequency sines (periods of 23..51 pixels), different per channel, within 33..223.
RgbaImage Smooth(uint32_t w, uint32_t h) {
  RgbaImage img = Solid(w, h, 0, 0, 0, 255);
  constexpr double kTau = 2.0 * std::numbers::pi;
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      uint8_t* p = Px(img, x, y);
      for (int c = 0; c < 3; ++c) {
        p[c] = ToByte(128 + 40 * std::sin(kTau * x / 37.0 + c) +
                      30 * std::cos(kTau * y / 23.0 + 2 * c) +
                      25 * std::sin(kTau * (x + y) / 51.0 - c));
      }
    }
  }
  return img;
}

// Each 2x2 block averaged: the frame a half-resolution render would have produced.
RgbaImage BoxHalve(const RgbaImage& img) {
  RgbaImage out = Solid(img.width / 2, img.height / 2, 0, 0, 0, 0);
  for (uint32_t y = 0; y < out.height; ++y) {
    for (uint32_t x = 0; x < out.width; ++x) {
      for (int c = 0; c < 4; ++c) {
        const int sum = Px(img, 2 * x, 2 * y)[c] + Px(img, 2 * x + 1, 2 * y)[c] +
                        Px(img, 2 * x, 2 * y + 1)[c] + Px(img, 2 * x + 1, 2 * y + 1)[c];
        Px(out, x, y)[c] = static_cast<uint8_t>((sum + 2) / 4);
      }
    }
  }
  return out;
}

// Source coordinate of an output pixel centre, with the same alignment as ResizeBicubic.
double SourceCoord(uint32_t out, uint32_t src_size, uint32_t dst_size) {
  return (out + 0.5) * src_size / dst_size - 0.5;
}

RgbaImage NearestResize(const RgbaImage& img, uint32_t w, uint32_t h) {
  RgbaImage out = Solid(w, h, 0, 0, 0, 0);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      const auto sx = static_cast<uint32_t>(std::clamp<long>(
          std::lround(SourceCoord(x, img.width, w)), 0L, static_cast<long>(img.width) - 1));
      const auto sy = static_cast<uint32_t>(std::clamp<long>(
          std::lround(SourceCoord(y, img.height, h)), 0L, static_cast<long>(img.height) - 1));
      std::copy_n(Px(img, sx, sy), 4, Px(out, x, y));
    }
  }
  return out;
}

RgbaImage BilinearResize(const RgbaImage& img, uint32_t w, uint32_t h) {
  RgbaImage out = Solid(w, h, 0, 0, 0, 0);
  for (uint32_t y = 0; y < h; ++y) {
    const double fy = std::clamp(SourceCoord(y, img.height, h), 0.0, img.height - 1.0);
    const auto y0 = static_cast<uint32_t>(fy);
    const uint32_t y1 = std::min(y0 + 1, img.height - 1);
    const double ty = fy - y0;
    for (uint32_t x = 0; x < w; ++x) {
      const double fx = std::clamp(SourceCoord(x, img.width, w), 0.0, img.width - 1.0);
      const auto x0 = static_cast<uint32_t>(fx);
      const uint32_t x1 = std::min(x0 + 1, img.width - 1);
      const double tx = fx - x0;
      for (int c = 0; c < 4; ++c) {
        const double top = Px(img, x0, y0)[c] * (1 - tx) + Px(img, x1, y0)[c] * tx;
        const double bottom = Px(img, x0, y1)[c] * (1 - tx) + Px(img, x1, y1)[c] * tx;
        Px(out, x, y)[c] = ToByte(top * (1 - ty) + bottom * ty);
      }
    }
  }
  return out;
}

RgbaImage MirrorX(const RgbaImage& img) {
  RgbaImage out = img;
  for (uint32_t y = 0; y < img.height; ++y) {
    for (uint32_t x = 0; x < img.width; ++x) {
      std::copy_n(Px(img, img.width - 1 - x, y), 4, Px(out, x, y));
    }
  }
  return out;
}

RgbaImage FlipY(const RgbaImage& img) {
  RgbaImage out = img;
  for (uint32_t y = 0; y < img.height; ++y) {
    std::copy_n(Px(img, 0, img.height - 1 - y), size_t{img.width} * 4, Px(out, 0, y));
  }
  return out;
}

// Equal size and pixels; on a mismatch names the first differing pixel instead of printing
// megabytes of buffer.
testing::AssertionResult SamePixels(const RgbaImage& actual, const RgbaImage& expected) {
  if (actual.width != expected.width || actual.height != expected.height ||
      actual.pixels.size() != expected.pixels.size()) {
    return testing::AssertionFailure() << "size " << actual.width << "x" << actual.height
                                       << ", expected " << expected.width << "x" << expected.height;
  }
  const auto [a, e] =
      std::mismatch(actual.pixels.begin(), actual.pixels.end(), expected.pixels.begin());
  if (a == actual.pixels.end()) return testing::AssertionSuccess();
  const auto at = static_cast<size_t>(a - actual.pixels.begin());
  const size_t count = static_cast<size_t>(
      std::inner_product(actual.pixels.begin(), actual.pixels.end(), expected.pixels.begin(),
                         size_t{0}, std::plus<>(), std::not_equal_to<>()));
  return testing::AssertionFailure()
         << count << " bytes differ; first at pixel " << (at / 4) % actual.width << ","
         << at / 4 / actual.width << " channel " << at % 4 << ": " << int{*a} << " vs " << int{*e};
}

RgbaImage Resize(const RgbaImage& img, uint32_t w, uint32_t h) {
  absl::StatusOr<RgbaImage> out = ResizeBicubic(img, w, h);
  EXPECT_TRUE(out.ok()) << out.status();
  return out.ok() ? *std::move(out) : RgbaImage{};
}

TEST(ResizeBicubic, ConstantImageStaysExactlyConstant) {
  struct Case {
    uint32_t sw, sh, dw, dh;
  };
  // 2x, the interactive profile's 0.5 render scale, a non-integer factor, a downscale, and a
  // downscale wide enough that rounding ~16000 weights per output must not drift the sum.
  for (const Case& c : {Case{64, 40, 128, 80}, Case{640, 360, 1280, 720}, Case{100, 50, 173, 91},
                        Case{173, 91, 50, 31}, Case{16384, 2, 3, 2}}) {
    SCOPED_TRACE(testing::Message() << c.sw << "x" << c.sh << " -> " << c.dw << "x" << c.dh);
    const RgbaImage out = Resize(Solid(c.sw, c.sh, 37, 140, 251, 77), c.dw, c.dh);
    EXPECT_TRUE(SamePixels(out, Solid(c.dw, c.dh, 37, 140, 251, 77)));
  }
}

TEST(ResizeBicubic, LinearRampsStayLinearInTheInterior) {
  // Red ramps up and blue down along x, green along y, steeply (8 levels a pixel): the separable
  // filter must reproduce each. Allowed: 0.5 for rounding to 8 bits plus a little fixed-point
  // error. Other cubics miss: Keys with a = -0.75 is off by up to 0.048 * slope.
  const uint32_t sw = 32, sh = 31, dw = 89, dh = 97;
  RgbaImage src = Solid(sw, sh, 0, 0, 0, 255);
  for (uint32_t y = 0; y < sh; ++y) {
    for (uint32_t x = 0; x < sw; ++x) {
      uint8_t* p = Px(src, x, y);
      p[0] = static_cast<uint8_t>(4 + 8 * x);
      p[1] = static_cast<uint8_t>(10 + 8 * y);
      p[2] = static_cast<uint8_t>(252 - 8 * x);
    }
  }
  const RgbaImage out = Resize(src, dw, dh);
  ASSERT_EQ(out.pixels.size(), size_t{dw} * dh * 4);

  int checked = 0;
  double worst = 0.0;
  for (uint32_t y = 0; y < dh; ++y) {
    const double sy = SourceCoord(y, sh, dh);
    if (sy < 2.0 || sy > sh - 3.0) continue;  // the kernel would reach a clamped border
    for (uint32_t x = 0; x < dw; ++x) {
      const double sx = SourceCoord(x, sw, dw);
      if (sx < 2.0 || sx > sw - 3.0) continue;
      const uint8_t* p = Px(out, x, y);
      worst = std::max({worst, std::abs(p[0] - (4 + 8 * sx)), std::abs(p[1] - (10 + 8 * sy)),
                        std::abs(p[2] - (252 - 8 * sx))});
      ASSERT_EQ(p[3], 255);
      ++checked;
    }
  }
  EXPECT_LE(worst, 0.6) << "largest deviation from the ramps";
  EXPECT_GT(checked, 70 * 80);
}

TEST(ResizeBicubic, SameSizeIsIdentity) {
  const RgbaImage src = Noise(33, 17, 5);
  EXPECT_TRUE(SamePixels(Resize(src, 33, 17), src));
}

TEST(ResizeBicubic, InterpolatesThroughSourceSamples) {
  // At 3x every third output centre lands exactly on a source centre, where Catmull-Rom's
  // weights are 0, 1, 0: the source value comes through unchanged, even for noise.
  const RgbaImage src = Noise(20, 15, 11);
  const RgbaImage out = Resize(src, 60, 45);
  ASSERT_EQ(out.pixels.size(), size_t{60} * 45 * 4);
  for (uint32_t y = 0; y < src.height; ++y) {
    for (uint32_t x = 0; x < src.width; ++x) {
      const uint8_t* s = Px(src, x, y);
      const uint8_t* o = Px(out, 3 * x + 1, 3 * y + 1);
      ASSERT_TRUE(std::equal(s, s + 4, o)) << "at source " << x << "," << y;
    }
  }
}

TEST(ResizeBicubic, BeatsNearestAndBilinearOnASmoothImage) {
  // A half-resolution render of smooth content brought back to full size: the cubic gets
  // closer to the full-resolution original than the cheaper filters.
  const RgbaImage original = Smooth(256, 256);
  const RgbaImage half = BoxHalve(original);
  const absl::StatusOr<double> cubic = Psnr(Resize(half, 256, 256), original);
  const absl::StatusOr<double> linear = Psnr(BilinearResize(half, 256, 256), original);
  const absl::StatusOr<double> nearest = Psnr(NearestResize(half, 256, 256), original);
  ASSERT_TRUE(cubic.ok() && linear.ok() && nearest.ok());
  EXPECT_GT(*linear, *nearest + 3.0);
  EXPECT_GT(*cubic, *linear + 2.0) << "cubic " << *cubic << " dB, bilinear " << *linear << " dB";
  EXPECT_GT(*cubic, 45.0);
}

TEST(ResizeBicubic, MirroredInputGivesMirroredOutput) {
  // Exact, not approximate: the weights of mirrored outputs are computed and rounded to the same
  // integers. The exact 3x and 2x cases have windows symmetric about their centre, where
  // equal weights must not be rounded differently.
  const RgbaImage src = Noise(39, 24, 3);
  struct Size {
    uint32_t w, h;
  };
  for (const Size& s : {Size{101, 64}, Size{78, 48}, Size{13, 8}, Size{16, 9}}) {
    SCOPED_TRACE(testing::Message() << "to " << s.w << "x" << s.h);
    const RgbaImage out = Resize(src, s.w, s.h);
    EXPECT_TRUE(SamePixels(Resize(MirrorX(src), s.w, s.h), MirrorX(out)));
    EXPECT_TRUE(SamePixels(Resize(FlipY(src), s.w, s.h), FlipY(out)));
  }
}

TEST(ResizeBicubic, RejectsBadInputs) {
  const RgbaImage good = Solid(8, 8, 1, 2, 3, 4);
  EXPECT_EQ(ResizeBicubic(RgbaImage{}, 16, 16).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ResizeBicubic(good, 0, 16).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ResizeBicubic(good, 16, 0).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ResizeBicubic(good, kMaxImageSide + 1, 16).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ResizeBicubic(good, 16, kMaxImageSide + 1).status().code(),
            absl::StatusCode::kInvalidArgument);
  RgbaImage short_buffer = good;
  short_buffer.pixels.pop_back();
  EXPECT_EQ(ResizeBicubic(short_buffer, 16, 16).status().code(),
            absl::StatusCode::kInvalidArgument);
  RgbaImage zero_height = good;
  zero_height.height = 0;
  EXPECT_EQ(ResizeBicubic(zero_height, 16, 16).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(ResizeBicubic, DownscaledCheckerboardIsMidGrey) {
  // A one-pixel checkerboard is all Nyquist frequency: the widened (low-pass) kernel averages
  // it away. At 3x every output centre lands on a source pixel, so the unwidened kernel would
  // return that pixel's black or white (aliasing); at 4x the centres fall between two pixels
  // and symmetry alone would give grey.
  RgbaImage board = Solid(48, 48, 0, 0, 0, 255);
  for (uint32_t y = 0; y < 48; ++y) {
    for (uint32_t x = 0; x < 48; ++x) {
      if ((x + y) % 2 == 1) std::fill_n(Px(board, x, y), 3, uint8_t{255});
    }
  }
  for (const uint32_t size : {12u, 16u}) {
    SCOPED_TRACE(testing::Message() << "48x48 -> " << size << "x" << size);
    const RgbaImage out = Resize(board, size, size);
    ASSERT_EQ(out.pixels.size(), size_t{size} * size * 4);
    for (uint32_t y = 0; y < size; ++y) {
      for (uint32_t x = 0; x < size; ++x) {
        const uint8_t* p = Px(out, x, y);
        for (int c = 0; c < 3; ++c) {
          ASSERT_NEAR(p[c], 127.5, 4.0) << "channel " << c << " at " << x << "," << y;
        }
        ASSERT_EQ(p[3], 255);
      }
    }
  }
}

}  // namespace
}  // namespace tessera

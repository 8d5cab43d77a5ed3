#include "renderer/image_metrics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"

namespace tessera {
namespace {


// Both images valid and of one size.
absl::Status ValidatePair(const RgbaImage& a, const RgbaImage& b, const char* fn) {
  RETURN_IF_ERROR(ValidateImage(a, absl::StrCat(fn, " (first image)").c_str()));
  RETURN_IF_ERROR(ValidateImage(b, absl::StrCat(fn, " (second image)").c_str()));
  if (a.width != b.width || a.height != b.height) {
    return absl::InvalidArgumentError(absl::StrCat(fn, ": sizes differ: ", a.width, "x", a.height,
                                                   " vs ", b.width, "x", b.height));
  }
  return absl::OkStatus();
}

absl::Status ValidateMask(const std::vector<uint8_t>& mask, const RgbaImage& image,
                          const char* fn) {
  const uint64_t pixels = uint64_t{image.width} * image.height;
  if (!mask.empty() && mask.size() != pixels) {
    return absl::InvalidArgumentError(absl::StrCat(fn, ": mask has ", mask.size(), " entries, ",
                                                   image.width, "x", image.height, " needs ",
                                                   pixels));
  }
  return absl::OkStatus();
}

bool Selected(const std::vector<uint8_t>& mask, size_t i) { return mask.empty() || mask[i] != 0; }

// Decoding is the hot loop of DownsampleBox (16 lookups per output channel at factor 4).
const std::array<float, 256>& SrgbDecodeTable() {
  static const std::array<float, 256> table = [] {
    std::array<float, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = SrgbToLinear(static_cast<float>(i) / 255.0f);
    return t;
  }();
  return table;
}

uint8_t EncodeSrgb8(double linear) {
  const float encoded = LinearToSrgb(static_cast<float>(linear));
  return static_cast<uint8_t>(std::clamp(std::lround(encoded * 255.0f), 0L, 255L));
}

// ---- SSIM ----------------------------------------------------------------------------------

constexpr int kSsimRadius = 5;  // 11 taps
constexpr int kSsimTaps = 2 * kSsimRadius + 1;
constexpr double kSsimSigma = 1.5;
constexpr double kSsimC1 = (0.01 * 255.0) * (0.01 * 255.0);
constexpr double kSsimC2 = (0.03 * 255.0) * (0.03 * 255.0);

std::array<double, kSsimTaps> GaussianWeights() {
  std::array<double, kSsimTaps> w{};
  double sum = 0.0;
  for (int k = -kSsimRadius; k <= kSsimRadius; ++k) {
    w[k + kSsimRadius] = std::exp(-(k * k) / (2.0 * kSsimSigma * kSsimSigma));
    sum += w[k + kSsimRadius];
  }
  for (double& v : w) v /= sum;
  return w;
}

double Luma(const uint8_t* p) { return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]; }

// The five window moments (E[a], E[b], E[a^2], E[b^2], E[ab]) of one image row after the
// horizontal half of the separable Gaussian; the vertical half combines 11 of these.
struct MomentRow {
  std::vector<double> m[5];
};

void HorizontalMoments(const RgbaImage& a, const RgbaImage& b, uint32_t row,
                       const std::array<double, kSsimTaps>& w, std::vector<double>* la,
                       std::vector<double>* lb, MomentRow* out) {
  const uint32_t width = a.width;
  // Padded with the edge values, so the tap loop needs no clamping.
  for (int x = -kSsimRadius; x < static_cast<int>(width) + kSsimRadius; ++x) {
    const size_t sx = static_cast<size_t>(std::clamp(x, 0, static_cast<int>(width) - 1));
    const size_t offset = (size_t{row} * width + sx) * 4;
    (*la)[x + kSsimRadius] = Luma(&a.pixels[offset]);
    (*lb)[x + kSsimRadius] = Luma(&b.pixels[offset]);
  }
  for (uint32_t x = 0; x < width; ++x) {
    double s[5] = {0, 0, 0, 0, 0};
    for (int k = 0; k < kSsimTaps; ++k) {
      const double va = (*la)[x + k], vb = (*lb)[x + k];
      s[0] += w[k] * va;
      s[1] += w[k] * vb;
      s[2] += w[k] * va * va;
      s[3] += w[k] * vb * vb;
      s[4] += w[k] * va * vb;
    }
    for (int i = 0; i < 5; ++i) out->m[i][x] = s[i];
  }
}

// ---- Contact sheet font ---------------------------------------------------------------------

constexpr int kGlyphWidth = 5;
constexpr int kGlyphHeight = 7;
constexpr int kGlyphAdvance = 6;
constexpr uint32_t kLabelBand = 12;  // label strip above the first row
constexpr uint32_t kLabelTop = 3;    // glyph top inside the strip
constexpr uint32_t kGutter = 2;
constexpr uint8_t kBackground = 32;

struct Glyph {
  char c;
  uint8_t rows[kGlyphHeight];  // top row first; bit 4 is the leftmost pixel
};

constexpr Glyph kFont[] = {
    {'A', {0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}},
    {'B', {0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E}},
    {'C', {0x0E, 0x11, 0x10, 0x10, 0x10, 0x11, 0x0E}},
    {'D', {0x1C, 0x12, 0x11, 0x11, 0x11, 0x12, 0x1C}},
    {'E', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F}},
    {'F', {0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10}},
    {'G', {0x0E, 0x11, 0x10, 0x17, 0x11, 0x11, 0x0F}},
    {'H', {0x11, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11}},
    {'I', {0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'J', {0x07, 0x02, 0x02, 0x02, 0x02, 0x12, 0x0C}},
    {'K', {0x11, 0x12, 0x14, 0x18, 0x14, 0x12, 0x11}},
    {'L', {0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F}},
    {'M', {0x11, 0x1B, 0x15, 0x15, 0x11, 0x11, 0x11}},
    {'N', {0x11, 0x11, 0x19, 0x15, 0x13, 0x11, 0x11}},
    {'O', {0x0E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}},
    {'P', {0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10}},
    {'Q', {0x0E, 0x11, 0x11, 0x11, 0x15, 0x12, 0x0D}},
    {'R', {0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11}},
    {'S', {0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E}},
    {'T', {0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04}},
    {'U', {0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E}},
    {'V', {0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04}},
    {'W', {0x11, 0x11, 0x11, 0x15, 0x15, 0x15, 0x0A}},
    {'X', {0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11}},
    {'Y', {0x11, 0x11, 0x11, 0x0A, 0x04, 0x04, 0x04}},
    {'Z', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x10, 0x1F}},
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}},
    {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}},
    {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}},
    {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}},
    {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}},
    {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'_', {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1F}},
    {'-', {0x00, 0x00, 0x00, 0x1F, 0x00, 0x00, 0x00}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}},
};

// nullptr for characters the font lacks (drawn as blanks).
const Glyph* FindGlyph(char c) {
  if (c >= 'a' && c <= 'z') c = static_cast<char>(c - 'a' + 'A');
  for (const Glyph& g : kFont) {
    if (g.c == c) return &g;
  }
  return nullptr;
}

void SetPixel(RgbaImage* img, uint32_t x, uint32_t y, const uint8_t* rgb) {
  uint8_t* p = &img->pixels[(size_t{y} * img->width + x) * 4];
  p[0] = rgb[0];
  p[1] = rgb[1];
  p[2] = rgb[2];
  p[3] = 255;
}

// Draws as many whole glyphs as fit in max_width pixels.
void DrawLabel(RgbaImage* img, uint32_t x0, uint32_t y0, uint32_t max_width,
               const std::string& text) {
  static constexpr uint8_t kWhite[3] = {255, 255, 255};
  const size_t fit = (size_t{max_width} + kGlyphAdvance - kGlyphWidth) / kGlyphAdvance;
  const size_t n = std::min(text.size(), fit);
  for (size_t i = 0; i < n; ++i) {
    const Glyph* g = FindGlyph(text[i]);
    if (g == nullptr) continue;
    const uint32_t gx = x0 + static_cast<uint32_t>(i) * kGlyphAdvance;
    for (int row = 0; row < kGlyphHeight; ++row) {
      for (int col = 0; col < kGlyphWidth; ++col) {
        if ((g->rows[row] >> (kGlyphWidth - 1 - col)) & 1) {
          SetPixel(img, gx + col, y0 + row, kWhite);
        }
      }
    }
  }
}

// A crop intersected with the image; x0 < x1 <= width, y0 < y1 <= height.
struct Rect {
  uint32_t x0, y0, x1, y1;
};

Rect ClampCrop(const Crop& c, uint32_t width, uint32_t height) {
  Rect r;
  r.x0 = std::min(c.x, width - 1);
  r.y0 = std::min(c.y, height - 1);
  r.x1 = static_cast<uint32_t>(std::min<uint64_t>(uint64_t{r.x0} + c.width, width));
  r.y1 = static_cast<uint32_t>(std::min<uint64_t>(uint64_t{r.y0} + c.height, height));
  return r;
}

}  // namespace

float SrgbToLinear(float encoded) {
  const float c = std::clamp(encoded, 0.0f, 1.0f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

float LinearToSrgb(float linear) {
  const float c = std::clamp(linear, 0.0f, 1.0f);
  return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

absl::StatusOr<RgbaImage> DownsampleBox(const RgbaImage& image, uint32_t factor) {
  RETURN_IF_ERROR(ValidateImage(image, "DownsampleBox"));
  if (factor == 0) return absl::InvalidArgumentError("DownsampleBox: factor must be at least 1");
  if (image.width % factor != 0 || image.height % factor != 0) {
    return absl::InvalidArgumentError(absl::StrCat("DownsampleBox: ", image.width, "x",
                                                   image.height, " does not divide by ", factor));
  }
  const std::array<float, 256>& decode = SrgbDecodeTable();
  RgbaImage out;
  out.width = image.width / factor;
  out.height = image.height / factor;
  out.pixels.resize(size_t{out.width} * out.height * 4);
  const double inv_samples = 1.0 / (static_cast<double>(factor) * factor);
  // One output row at a time: sum its factor source rows into `acc`, then encode.
  std::vector<double> acc(size_t{out.width} * 3);
  for (uint32_t oy = 0; oy < out.height; ++oy) {
    std::fill(acc.begin(), acc.end(), 0.0);
    for (uint32_t sy = oy * factor; sy < (oy + 1) * factor; ++sy) {
      const uint8_t* row = &image.pixels[size_t{sy} * image.width * 4];
      for (uint32_t sx = 0; sx < image.width; ++sx) {
        double* a = &acc[size_t{sx / factor} * 3];
        a[0] += decode[row[sx * 4 + 0]];
        a[1] += decode[row[sx * 4 + 1]];
        a[2] += decode[row[sx * 4 + 2]];
      }
    }
    for (uint32_t ox = 0; ox < out.width; ++ox) {
      uint8_t* p = &out.pixels[(size_t{oy} * out.width + ox) * 4];
      for (int c = 0; c < 3; ++c) p[c] = EncodeSrgb8(acc[size_t{ox} * 3 + c] * inv_samples);
      p[3] = 255;
    }
  }
  return out;
}

absl::StatusOr<std::vector<uint8_t>> DifferenceMask(const RgbaImage& a, const RgbaImage& b,
                                                    int threshold) {
  RETURN_IF_ERROR(ValidatePair(a, b, "DifferenceMask"));
  if (threshold < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("DifferenceMask: threshold ", threshold, " is negative"));
  }
  std::vector<uint8_t> mask(size_t{a.width} * a.height);
  for (size_t i = 0; i < mask.size(); ++i) {
    const uint8_t* pa = &a.pixels[i * 4];
    const uint8_t* pb = &b.pixels[i * 4];
    bool differs = false;
    for (int c = 0; c < 3; ++c) differs |= std::abs(int{pa[c]} - int{pb[c]}) > threshold;
    mask[i] = differs ? 1 : 0;
  }
  return mask;
}

std::vector<uint8_t> InvertMask(const std::vector<uint8_t>& mask) {
  std::vector<uint8_t> out(mask.size());
  for (size_t i = 0; i < mask.size(); ++i) out[i] = mask[i] == 0 ? 1 : 0;
  return out;
}

uint64_t MaskCount(const std::vector<uint8_t>& mask) {
  return static_cast<uint64_t>(
      std::count_if(mask.begin(), mask.end(), [](uint8_t v) { return v != 0; }));
}

absl::StatusOr<double> PsnrMasked(const RgbaImage& a, const RgbaImage& b,
                                  const std::vector<uint8_t>& mask) {
  RETURN_IF_ERROR(ValidatePair(a, b, "PsnrMasked"));
  RETURN_IF_ERROR(ValidateMask(mask, a, "PsnrMasked"));
  const size_t pixels = size_t{a.width} * a.height;
  uint64_t sum_sq = 0;
  uint64_t selected = 0;
  for (size_t i = 0; i < pixels; ++i) {
    if (!Selected(mask, i)) continue;
    ++selected;
    for (size_t c = 0; c < 3; ++c) {
      const int d = int{a.pixels[i * 4 + c]} - int{b.pixels[i * 4 + c]};
      sum_sq += static_cast<uint64_t>(d * d);
    }
  }
  if (selected == 0) return std::numeric_limits<double>::quiet_NaN();
  if (sum_sq == 0) return std::numeric_limits<double>::infinity();
  const double mse = static_cast<double>(sum_sq) / (static_cast<double>(selected) * 3.0);
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

namespace {

// Per pixel, the largest amount by which a channel of `a` lies outside the range of `b`'s
// channel over the (2 radius + 1)^2 neighbourhood (clamped at the borders). The range is a
// separable min/max: rows first, then columns.
std::vector<int> Excess(const RgbaImage& a, const RgbaImage& b, uint32_t radius) {
  const uint32_t w = a.width, h = a.height;
  const size_t n = size_t{w} * h;
  std::vector<int> excess(n, 0);
  std::vector<uint8_t> row_lo(n), row_hi(n);
  for (int c = 0; c < 3; ++c) {
    for (uint32_t y = 0; y < h; ++y) {
      for (uint32_t x = 0; x < w; ++x) {
        uint8_t lo = 255, hi = 0;
        const uint32_t x0 = x >= radius ? x - radius : 0, x1 = std::min(w - 1, x + radius);
        for (uint32_t xx = x0; xx <= x1; ++xx) {
          const uint8_t v = b.pixels[(size_t{y} * w + xx) * 4 + c];
          lo = std::min(lo, v);
          hi = std::max(hi, v);
        }
        row_lo[size_t{y} * w + x] = lo;
        row_hi[size_t{y} * w + x] = hi;
      }
    }
    for (uint32_t y = 0; y < h; ++y) {
      const uint32_t y0 = y >= radius ? y - radius : 0, y1 = std::min(h - 1, y + radius);
      for (uint32_t x = 0; x < w; ++x) {
        int lo = 255, hi = 0;
        for (uint32_t yy = y0; yy <= y1; ++yy) {
          lo = std::min<int>(lo, row_lo[size_t{yy} * w + x]);
          hi = std::max<int>(hi, row_hi[size_t{yy} * w + x]);
        }
        const size_t i = size_t{y} * w + x;
        const int v = a.pixels[i * 4 + c];
        excess[i] = std::max(excess[i], v < lo ? lo - v : (v > hi ? v - hi : 0));
      }
    }
  }
  return excess;
}

}  // namespace

absl::StatusOr<NeighbourhoodError> CompareNeighbourhood(const RgbaImage& actual,
                                                        const RgbaImage& expected,
                                                        uint32_t radius, int threshold) {
  RETURN_IF_ERROR(ValidatePair(actual, expected, "CompareNeighbourhood"));
  const std::vector<int> ab = Excess(actual, expected, radius);
  const std::vector<int> ba = Excess(expected, actual, radius);
  NeighbourhoodError out;
  uint64_t sum_sq = 0, outliers = 0;
  for (size_t i = 0; i < ab.size(); ++i) {
    const int e = std::max(ab[i], ba[i]);
    sum_sq += uint64_t(e) * uint64_t(e);
    outliers += e > threshold ? 1 : 0;
    out.max_excess = std::max(out.max_excess, e);
  }
  const double pixels = static_cast<double>(ab.size());
  out.outlier_fraction = pixels > 0 ? static_cast<double>(outliers) / pixels : 0.0;
  out.psnr = sum_sq == 0 ? std::numeric_limits<double>::infinity()
                         : 10.0 * std::log10(255.0 * 255.0 / (static_cast<double>(sum_sq) / pixels));
  return out;
}

absl::StatusOr<double> SsimMasked(const RgbaImage& a, const RgbaImage& b,
                                  const std::vector<uint8_t>& mask) {
  RETURN_IF_ERROR(ValidatePair(a, b, "SsimMasked"));
  RETURN_IF_ERROR(ValidateMask(mask, a, "SsimMasked"));
  const uint32_t width = a.width, height = a.height;
  const std::array<double, kSsimTaps> w = GaussianWeights();

  // Horizontally filtered rows live in a ring of 11: output row y needs source rows y-5..y+5
  // (clamped), at most 11 consecutive rows, so row r can always sit in slot r % 11. This keeps
  // the memory at 11 rows instead of five full-frame planes.
  std::array<MomentRow, kSsimTaps> ring;
  std::array<int64_t, kSsimTaps> ring_row;
  ring_row.fill(-1);
  for (MomentRow& r : ring) {
    for (std::vector<double>& m : r.m) m.resize(width);
  }
  std::vector<double> la(width + 2 * kSsimRadius), lb(width + 2 * kSsimRadius);
  auto moments = [&](uint32_t row) -> const MomentRow& {
    const size_t slot = row % kSsimTaps;
    if (ring_row[slot] != row) {
      HorizontalMoments(a, b, row, w, &la, &lb, &ring[slot]);
      ring_row[slot] = row;
    }
    return ring[slot];
  };

  double ssim_sum = 0.0;
  uint64_t selected = 0;
  std::array<const MomentRow*, kSsimTaps> taps;
  for (uint32_t y = 0; y < height; ++y) {
    const size_t row_start = size_t{y} * width;
    bool any = mask.empty();
    for (uint32_t x = 0; x < width && !any; ++x) any = mask[row_start + x] != 0;
    if (!any) continue;
    for (int k = 0; k < kSsimTaps; ++k) {
      const int sy =
          std::clamp(static_cast<int>(y) + k - kSsimRadius, 0, static_cast<int>(height) - 1);
      taps[k] = &moments(static_cast<uint32_t>(sy));
    }
    for (uint32_t x = 0; x < width; ++x) {
      if (!Selected(mask, row_start + x)) continue;
      double s[5] = {0, 0, 0, 0, 0};
      for (int k = 0; k < kSsimTaps; ++k) {
        for (int i = 0; i < 5; ++i) s[i] += w[k] * taps[k]->m[i][x];
      }
      const double mu_a = s[0], mu_b = s[1];
      const double var_a = s[2] - mu_a * mu_a;
      const double var_b = s[3] - mu_b * mu_b;
      const double cov = s[4] - mu_a * mu_b;
      ssim_sum += ((2.0 * mu_a * mu_b + kSsimC1) * (2.0 * cov + kSsimC2)) /
                  ((mu_a * mu_a + mu_b * mu_b + kSsimC1) * (var_a + var_b + kSsimC2));
      ++selected;
    }
  }
  if (selected == 0) return std::numeric_limits<double>::quiet_NaN();
  return ssim_sum / static_cast<double>(selected);
}

absl::StatusOr<CoverageError> MeasureCoverage(const RgbaImage& image,
                                              const std::vector<float>& coverage) {
  RETURN_IF_ERROR(ValidateImage(image, "MeasureCoverage"));
  const size_t pixels = size_t{image.width} * image.height;
  if (coverage.size() != pixels) {
    return absl::InvalidArgumentError(absl::StrCat("MeasureCoverage: coverage has ",
                                                   coverage.size(), " entries, ", image.width, "x",
                                                   image.height, " needs ", pixels));
  }
  // Coverage exactly 0 or 1 up to float noise from the analytic clipping is not an edge.
  constexpr double kTolerance = 1e-6;
  auto partial = [](double v) { return v > kTolerance && v < 1.0 - kTolerance; };
  const std::array<float, 256>& decode = SrgbDecodeTable();
  double edge_sum = 0.0, all_sum = 0.0;
  uint64_t edge = 0;
  for (size_t i = 0; i < pixels; ++i) {
    const double c = coverage[i];
    if (!std::isfinite(c)) {
      return absl::InvalidArgumentError(
          absl::StrCat("MeasureCoverage: coverage[", i, "] is not finite"));
    }
    const uint8_t* p = &image.pixels[i * 4];
    const double estimate =
        std::clamp(0.2126 * decode[p[0]] + 0.7152 * decode[p[1]] + 0.0722 * decode[p[2]], 0.0, 1.0);
    const double err = std::abs(estimate - c);
    all_sum += err;
    if (partial(c) || partial(estimate)) {
      edge_sum += err;
      ++edge;
    }
  }
  CoverageError out;
  out.edge_pixels = edge;
  // NaN, like the masked metrics, rather than a perfect-looking 0 when there is nothing to score.
  out.edge_mae =
      edge > 0 ? edge_sum / static_cast<double>(edge) : std::numeric_limits<double>::quiet_NaN();
  out.all_mae = all_sum / static_cast<double>(pixels);
  return out;
}

// Layout (all gutters kGutter px, background grey 32):
//   y = 0:         the label band, kLabelBand px, each column's label at its left edge
//   then per crop: a gutter, then the row of height (clamped crop height) * zoom
//   then a final gutter.
//   x: a gutter, then per image a column of width max(clamped crop width) * zoom and a gutter.
// A crop narrower or shorter than the column/row box sits at its top-left.
absl::StatusOr<RgbaImage> ContactSheet(const std::vector<LabelledImage>& images,
                                       const std::vector<Crop>& crops, uint32_t zoom) {
  if (images.empty()) return absl::InvalidArgumentError("ContactSheet: no images");
  if (crops.empty()) return absl::InvalidArgumentError("ContactSheet: no crops");
  if (zoom == 0) return absl::InvalidArgumentError("ContactSheet: zoom must be at least 1");
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string what = absl::StrCat("ContactSheet: images[", i, "] (", images[i].label, ")");
    if (images[i].image == nullptr) return absl::InvalidArgumentError(what + ": null image");
    RETURN_IF_ERROR(ValidateImage(*images[i].image, what.c_str()));
    const RgbaImage& first = *images[0].image;
    if (images[i].image->width != first.width || images[i].image->height != first.height) {
      return absl::InvalidArgumentError(
          absl::StrCat(what, ": ", images[i].image->width, "x", images[i].image->height,
                       " differs from images[0]'s ", first.width, "x", first.height));
    }
  }
  const uint32_t src_w = images[0].image->width, src_h = images[0].image->height;
  std::vector<Rect> rects;
  for (size_t i = 0; i < crops.size(); ++i) {
    if (crops[i].width == 0 || crops[i].height == 0) {
      return absl::InvalidArgumentError(absl::StrCat("ContactSheet: crops[", i, "] is empty (",
                                                     crops[i].width, "x", crops[i].height, ")"));
    }
    rects.push_back(ClampCrop(crops[i], src_w, src_h));
  }

  uint64_t col_w = 0;
  uint64_t sheet_h = kLabelBand + kGutter;
  for (const Rect& r : rects) {
    col_w = std::max<uint64_t>(col_w, uint64_t{r.x1 - r.x0} * zoom);
    sheet_h += uint64_t{r.y1 - r.y0} * zoom + kGutter;
  }
  const uint64_t sheet_w = kGutter + images.size() * (col_w + kGutter);
  if (sheet_w > kMaxImageSide || sheet_h > kMaxImageSide) {
    return absl::InvalidArgumentError(absl::StrCat("ContactSheet: sheet would be ", sheet_w, "x",
                                                   sheet_h, ", more than ", kMaxImageSide,
                                                   " on a side (fewer crops or a smaller zoom)"));
  }

  RgbaImage sheet;
  sheet.width = static_cast<uint32_t>(sheet_w);
  sheet.height = static_cast<uint32_t>(sheet_h);
  sheet.pixels.resize(size_t{sheet.width} * sheet.height * 4);
  for (size_t i = 0; i < sheet.pixels.size(); i += 4) {
    sheet.pixels[i + 0] = sheet.pixels[i + 1] = sheet.pixels[i + 2] = kBackground;
    sheet.pixels[i + 3] = 255;
  }

  for (size_t col = 0; col < images.size(); ++col) {
    const uint32_t cx = static_cast<uint32_t>(kGutter + col * (col_w + kGutter));
    DrawLabel(&sheet, cx, kLabelTop, static_cast<uint32_t>(col_w), images[col].label);
    const RgbaImage& src = *images[col].image;
    uint32_t cy = kLabelBand + kGutter;
    for (const Rect& r : rects) {
      for (uint32_t sy = r.y0; sy < r.y1; ++sy) {
        for (uint32_t sx = r.x0; sx < r.x1; ++sx) {
          const uint8_t* p = &src.pixels[(size_t{sy} * src_w + sx) * 4];
          const uint32_t ox = cx + (sx - r.x0) * zoom, oy = cy + (sy - r.y0) * zoom;
          for (uint32_t dy = 0; dy < zoom; ++dy) {
            for (uint32_t dx = 0; dx < zoom; ++dx) SetPixel(&sheet, ox + dx, oy + dy, p);
          }
        }
      }
      cy += (r.y1 - r.y0) * zoom + kGutter;
    }
  }
  return sheet;
}

// A mask of the wrong size (neither empty nor width * height) or size 0 gives no crops. Windows
// are min(size, width) x min(size, height), at a stride of size / 4 plus the last position
// flush with the right/bottom edge.
std::vector<Crop> BusiestCrops(const std::vector<uint8_t>& mask, uint32_t width, uint32_t height,
                               uint32_t size, uint32_t count) {
  if (size == 0 || count == 0 || width == 0 || height == 0) return {};
  const uint64_t pixels = uint64_t{width} * height;
  if (!mask.empty() && mask.size() != pixels) return {};
  const uint32_t win_w = std::min(size, width), win_h = std::min(size, height);
  const uint32_t stride = std::max(1u, size / 4);

  // Summed-area table with a zero first row and column: sat[(y)(width+1) + x] counts the
  // selected pixels above and left of (x, y). Not needed when every pixel is selected.
  std::vector<uint64_t> sat;
  if (!mask.empty()) {
    sat.assign((size_t{width} + 1) * (size_t{height} + 1), 0);
    const size_t pitch = size_t{width} + 1;
    for (uint32_t y = 0; y < height; ++y) {
      uint64_t row_sum = 0;
      for (uint32_t x = 0; x < width; ++x) {
        row_sum += mask[size_t{y} * width + x] != 0 ? 1 : 0;
        sat[(y + 1) * pitch + x + 1] = sat[y * pitch + x + 1] + row_sum;
      }
    }
  }
  auto window_count = [&](uint32_t x, uint32_t y) -> uint64_t {
    if (mask.empty()) return uint64_t{win_w} * win_h;
    const size_t pitch = size_t{width} + 1;
    const size_t x1 = x + win_w, y1 = y + win_h;
    return sat[y1 * pitch + x1] - sat[y * pitch + x1] - sat[y1 * pitch + x] + sat[y * pitch + x];
  };
  auto positions = [stride](uint32_t extent, uint32_t window) {
    std::vector<uint32_t> p;
    for (uint32_t v = 0; v + window <= extent; v += stride) p.push_back(v);
    if (p.back() + window < extent) p.push_back(extent - window);
    return p;
  };

  struct Candidate {
    uint64_t count;
    uint32_t x, y;
  };
  std::vector<Candidate> candidates;
  for (uint32_t y : positions(height, win_h)) {
    for (uint32_t x : positions(width, win_w)) {
      if (const uint64_t n = window_count(x, y); n > 0) candidates.push_back({n, x, y});
    }
  }
  // Best first; ties go to the top-most, then left-most window so results are reproducible.
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& l, const Candidate& r) {
    return std::tie(r.count, l.y, l.x) < std::tie(l.count, r.y, r.x);
  });

  // Greedy: walking the sorted list and keeping what does not overlap an earlier pick is the
  // same as repeatedly taking the best window that does not overlap any pick.
  std::vector<Crop> chosen;
  for (const Candidate& c : candidates) {
    if (chosen.size() >= count) break;
    const bool overlaps = std::any_of(chosen.begin(), chosen.end(), [&](const Crop& k) {
      return c.x < k.x + k.width && k.x < c.x + win_w && c.y < k.y + k.height && k.y < c.y + win_h;
    });
    if (!overlaps) chosen.push_back(Crop{c.x, c.y, win_w, win_h});
  }
  return chosen;
}

}  // namespace tessera

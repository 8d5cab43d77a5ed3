#include "renderer/image_resize.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"

namespace tessera {
namespace {

// Fixed point instead of float: integer sums do not depend on the order of the taps, which makes
// the result exactly mirror-symmetric and deterministic, and int16 x int16 -> int32 products
// vectorise on baseline x86-64 (no SSE4.1 needed).
//
// Weights carry 14 fraction bits, the intermediate (after the horizontal pass) 6 in int16.
// Range: a Catmull-Rom window's weights have a sum of magnitudes of at most 1.25 (0.125 in the
// negative lobes), so intermediate values stay within about [-0.125, 1.125] * 255 * 64. The
// vertical pass's int32 sums stay below 2^31 even for the widest kernel: at most 2^15 (the int16
// range) times (1.25 * 2^14 + one unit of rounding per tap, up to 2^14 taps).
constexpr int kWeightBits = 14;
constexpr int32_t kWeightOne = 1 << kWeightBits;
constexpr int kIntermediateBits = 6;
constexpr int kHorizontalShift = kWeightBits - kIntermediateBits;
constexpr int kVerticalShift = kWeightBits + kIntermediateBits;
constexpr int32_t kHorizontalRounding = 1 << (kHorizontalShift - 1);
constexpr int32_t kVerticalRounding = 1 << (kVerticalShift - 1);
// Intermediate values the vertical pass handles together (16 int16 = two SSE registers).
constexpr size_t kBlock = 16;

// Keys' cubic convolution kernel with a = -0.5 (Catmull-Rom), support (-2, 2).
double CatmullRom(double x) {
  x = std::abs(x);
  if (x < 1.0) return (1.5 * x - 2.5) * x * x + 1.0;
  if (x < 2.0) return ((-0.5 * x + 2.5) * x - 4.0) * x + 2.0;
  return 0.0;
}

int64_t FloorDiv(int64_t a, int64_t b) {  // b > 0
  return a >= 0 ? a / b : -((-a + b - 1) / b);
}

// Which source samples, with which weights, make each output sample along one axis. Output i
// reads the `taps` source samples from start[i], all inside the image (clamped edge taps are
// folded onto the border sample), with weights[i * taps + k] summing to kWeightOne. Every
// output has the same number of taps (zero-padded), so the passes' inner loops have one trip
// count, and the common 4-tap case a compile-time one.
struct AxisFilter {
  std::vector<int32_t> start;
  std::vector<int16_t> weights;
  size_t taps = 0;
};

// Summed from both ends inwards, so a window and its mirror image give the same double.
double SymmetricSum(const std::vector<double>& w) {
  double sum = 0.0;
  size_t a = 0;
  size_t b = w.size();
  for (; b - a >= 2; ++a, --b) sum += w[a] + w[b - 1];
  if (a < b) sum += w[a];
  return sum;
}

// Reused across the outputs of an axis.
struct Scratch {
  std::vector<double> window;
  std::vector<double> fraction;
  std::vector<size_t> order;
  std::vector<int32_t> weights;
};

// The kernel over the source samples that output i's window covers, taps outside the image
// folded onto the border sample (edge clamping). Returns the window's first source index.
//
// In units of 1 / (2 * dst) source pixels the centre of output i sits at (2i + 1) * src - dst,
// so tap j is d = 2 * dst * j - centre away: an exact integer, and exactly negated for the
// mirrored output and tap. Dividing by 2 * max(src, dst) gives the kernel argument both when
// upscaling (kernel at source spacing) and when downscaling (kernel widened by src / dst).
// Folded taps are added outermost first at either edge for the same reason: a window and its
// mirror image get the same doubles, bit for bit.
int64_t KernelWindow(int64_t i, int64_t src, int64_t dst, std::vector<double>& window) {
  const int64_t centre = (2 * i + 1) * src - dst;
  const int64_t reach = 4 * std::max(src, dst);  // |d| < reach inside the kernel's support
  const int64_t lo = FloorDiv(centre - reach, 2 * dst) + 1;
  const int64_t hi = -FloorDiv(-(centre + reach), 2 * dst) - 1;
  const auto kernel = [&](int64_t j) {
    return CatmullRom(static_cast<double>(2 * dst * j - centre) / static_cast<double>(reach / 2));
  };
  const int64_t first = std::clamp<int64_t>(lo, 0, src - 1);
  const int64_t last = std::clamp<int64_t>(hi, 0, src - 1);
  if (first == last) {  // a one-pixel source: everything folds onto it
    window.assign(1, 1.0);
    return first;
  }
  window.assign(static_cast<size_t>(last - first + 1), 0.0);
  for (int64_t j = lo; j <= first; ++j) window.front() += kernel(j);
  for (int64_t j = hi; j >= last; --j) window.back() += kernel(j);
  for (int64_t j = first + 1; j < last; ++j) window[static_cast<size_t>(j - first)] = kernel(j);
  return first;
}

// Scales the window to sum to kWeightOne and rounds it so that the sum stays exact (flat areas
// keep their value): every weight is rounded down, then the units that leaves short go to the
// weights with the largest fractions (largest-remainder rounding; plain rounding is off by
// hundreds of units when a wide downscaling kernel has thousands of taps). Equal fractions get
// a unit together or not at all, since any tie-break by position would treat a window and its
// mirror image differently; in rare exact ties that leaves the sum a unit or two short, which
// moves no 8-bit value.
void Quantise(Scratch& s) {
  const size_t n = s.window.size();
  const double scale = kWeightOne / SymmetricSum(s.window);
  s.weights.resize(n);
  s.fraction.resize(n);
  int32_t missing = kWeightOne;
  for (size_t k = 0; k < n; ++k) {
    const double x = s.window[k] * scale;
    const double down = std::floor(x);
    s.weights[k] = static_cast<int32_t>(down);
    s.fraction[k] = x - down;
    missing -= s.weights[k];
  }
  s.order.resize(n);
  for (size_t k = 0; k < n; ++k) s.order[k] = k;
  std::sort(s.order.begin(), s.order.end(),
            [&](size_t a, size_t b) { return s.fraction[a] > s.fraction[b]; });
  for (size_t a = 0; a < n && missing > 0;) {
    size_t b = a + 1;
    while (b < n && s.fraction[s.order[b]] == s.fraction[s.order[a]]) ++b;
    if (static_cast<int64_t>(b - a) <= missing) {
      for (size_t c = a; c < b; ++c) ++s.weights[s.order[c]];
      missing -= static_cast<int32_t>(b - a);
    }
    a = b;
  }
}

AxisFilter MakeAxisFilter(uint32_t src, uint32_t dst) {
  AxisFilter f;
  // The support is an open interval 4 * max(src, dst) / dst source pixels long.
  const size_t support = (size_t{4} * std::max(src, dst) + dst - 1) / dst;
  f.taps = std::min<size_t>(src, support);
  f.start.resize(dst);
  f.weights.assign(size_t{dst} * f.taps, 0);

  Scratch s;
  for (uint32_t i = 0; i < dst; ++i) {
    const int64_t first = KernelWindow(i, src, dst, s.window);
    Quantise(s);
    // Shifted left at the right edge so that the zero-padded window stays inside the image.
    const int64_t start = std::min<int64_t>(first, int64_t{src} - static_cast<int64_t>(f.taps));
    f.start[i] = static_cast<int32_t>(start);
    std::copy(s.weights.begin(), s.weights.end(),
              f.weights.begin() + static_cast<ptrdiff_t>(i * f.taps + (first - start)));
  }
  return f;
}

// With 4 taps the horizontal sums provably fit int16 after the shift (at most 1.25 * 255 * 64
// plus 4 units of weight rounding). Downscaling kernels round thousands of weights, which only
// fits in practice, so the generic path clamps; the clamp would cost the 4-tap path ~15%.
template <bool kClamp>
int16_t ToIntermediate(int32_t acc) {
  const int32_t v = (acc + kHorizontalRounding) >> kHorizontalShift;
  if constexpr (kClamp) return static_cast<int16_t>(std::clamp(v, -32768, 32767));
  return static_cast<int16_t>(v);
}

// Horizontal pass: every source row resampled to columns.start.size() RGBA samples. kTaps is
// columns.taps when known at compile time (the compiler then unrolls the tap loop), else 0.
template <size_t kTaps>
void FilterRows(RgbaView src, const AxisFilter& columns, size_t out_stride, int16_t* out) {
  const size_t taps = kTaps != 0 ? kTaps : columns.taps;
  const size_t out_width = columns.start.size();
  for (uint32_t y = 0; y < src.height; ++y) {
    const uint8_t* in = src.pixels.data() + size_t{y} * src.width * 4;
    int16_t* row = out + size_t{y} * out_stride;
    const int16_t* w = columns.weights.data();
    for (size_t x = 0; x < out_width; ++x, w += taps) {
      const uint8_t* p = in + static_cast<size_t>(columns.start[x]) * 4;
      int32_t r = 0, g = 0, b = 0, a = 0;
      for (size_t k = 0; k < taps; ++k, p += 4) {
        r += w[k] * p[0];
        g += w[k] * p[1];
        b += w[k] * p[2];
        a += w[k] * p[3];
      }
      row[x * 4 + 0] = ToIntermediate<kTaps == 0>(r);
      row[x * 4 + 1] = ToIntermediate<kTaps == 0>(g);
      row[x * 4 + 2] = ToIntermediate<kTaps == 0>(b);
      row[x * 4 + 3] = ToIntermediate<kTaps == 0>(a);
    }
    std::fill(row + out_width * 4, row + out_stride, int16_t{0});
  }
}

// Vertical pass, a block of kBlock intermediate values at a time through all of an output row's
// taps: the fixed-size inner loops keep the sums in registers and vectorise even at -O2 (GCC's
// cheap cost model only vectorises loops whose trip count is known).
template <size_t kTaps>
void FilterColumns(const int16_t* in, size_t in_stride, const AxisFilter& rows, RgbaImage& out) {
  const size_t taps = kTaps != 0 ? kTaps : rows.taps;
  const size_t row_len = size_t{out.width} * 4;
  for (size_t y = 0; y < rows.start.size(); ++y) {
    const int16_t* w = rows.weights.data() + y * taps;
    const int16_t* first_row = in + static_cast<size_t>(rows.start[y]) * in_stride;
    uint8_t* dst = out.pixels.data() + y * row_len;
    for (size_t i = 0; i < row_len; i += kBlock) {
      int32_t sum[kBlock];
      std::fill_n(sum, kBlock, kVerticalRounding);
      const int16_t* src = first_row + i;
      for (size_t k = 0; k < taps; ++k, src += in_stride) {
        const int32_t weight = w[k];
        for (size_t l = 0; l < kBlock; ++l) sum[l] += weight * src[l];
      }
      uint8_t block[kBlock];
      for (size_t l = 0; l < kBlock; ++l) {
        block[l] = static_cast<uint8_t>(std::clamp(sum[l] >> kVerticalShift, 0, 255));
      }
      if (row_len - i >= kBlock) {
        std::memcpy(dst + i, block, kBlock);
      } else {
        std::memcpy(dst + i, block, row_len - i);
      }
    }
  }
}

}  // namespace

absl::StatusOr<RgbaImage> ResizeBicubic(RgbaView src, uint32_t width, uint32_t height) {
  RETURN_IF_ERROR(ValidateImage(src, "ResizeBicubic (source)"));
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide) {
    return absl::InvalidArgumentError(absl::StrCat("ResizeBicubic: target ", width, "x", height,
                                                   " is not 1..", kMaxImageSide, " per side"));
  }
  if (width == src.width && height == src.height)
    return RgbaImage{width, height, std::vector<uint8_t>(src.pixels.begin(), src.pixels.end())};

  const AxisFilter columns = MakeAxisFilter(src.width, width);
  const AxisFilter rows = MakeAxisFilter(src.height, height);
  // Rows padded to whole blocks, so the vertical pass needs no tail loop. Not zero-filled:
  // FilterRows writes every element.
  const size_t stride = (size_t{width} * 4 + kBlock - 1) / kBlock * kBlock;
  const auto intermediate = std::make_unique_for_overwrite<int16_t[]>(stride * src.height);
  if (columns.taps == 4) {
    FilterRows<4>(src, columns, stride, intermediate.get());
  } else {
    FilterRows<0>(src, columns, stride, intermediate.get());
  }

  RgbaImage out;
  out.width = width;
  out.height = height;
  out.pixels.resize(size_t{width} * height * 4);
  if (rows.taps == 4) {
    FilterColumns<4>(intermediate.get(), stride, rows, out);
  } else {
    FilterColumns<0>(intermediate.get(), stride, rows, out);
  }
  return out;
}

}  // namespace tessera

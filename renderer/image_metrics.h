#pragma once
// Image-quality metrics for anti-aliasing measurements (tessera-aa-quality, the AA tests):
// linear-light box downsampling for the supersampled reference, PSNR and SSIM over a pixel
// mask, the edge mask, and a labelled contact sheet of zoomed crops. CPU only, no Vulkan.
//
// Conventions: images are sRGB-encoded RGBA8 (alpha ignored). A mask is one byte per pixel,
// non-zero = selected; an empty mask selects every pixel.
#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "renderer/image_io.h"

namespace tessera {

// sRGB transfer functions (IEC 61966-2-1), [0,1] <-> [0,1].
float SrgbToLinear(float encoded);
float LinearToSrgb(float linear);

// Averages each factor x factor block in linear light and re-encodes to sRGB (rounded). The
// reference of the AA measurements: a frame rendered at 4x width and height without AA, box
// filtered down (16 samples per pixel). INVALID_ARGUMENT unless both sizes divide by factor.
absl::StatusOr<RgbaImage> DownsampleBox(const RgbaImage& image, uint32_t factor);

// 1 where any RGB channel of `a` and `b` differs by more than `threshold` (8-bit steps), else 0:
// with the reference and the no-AA frame, the pixels that need anti-aliasing.
absl::StatusOr<std::vector<uint8_t>> DifferenceMask(const RgbaImage& a, const RgbaImage& b,
                                                    int threshold = 2);
// The mask with every value flipped (0 <-> 1).
std::vector<uint8_t> InvertMask(const std::vector<uint8_t>& mask);
// Selected pixels.
uint64_t MaskCount(const std::vector<uint8_t>& mask);

// PSNR in dB over the RGB channels of the selected pixels (8-bit peak 255). +infinity when
// they are identical; NaN when the mask selects nothing. INVALID_ARGUMENT on size mismatch.
absl::StatusOr<double> PsnrMasked(const RgbaImage& a, const RgbaImage& b,
                                  const std::vector<uint8_t>& mask = {});

// A golden-image comparison that holds across drivers. Each pixel of one image may take any value
// between the smallest and the largest of the other image's pixels within `radius` (per RGB
// channel); how far it lies outside that range is its excess. Both directions are checked, and a
// pixel's excess is the larger. Texture filtering and LOD selection that differ between drivers
// (an edge a pixel sharper or softer, a checkerboard filtered a little differently) stay within
// the range; a missing light, a flipped normal or a shifted texture leaves it.
struct NeighbourhoodError {
  double psnr = 0.0;              // of the excess over RGB (8-bit peak); +infinity when none
  double outlier_fraction = 0.0;  // pixels whose excess exceeds `threshold` on some channel
  int max_excess = 0;
};
absl::StatusOr<NeighbourhoodError> CompareNeighbourhood(const RgbaImage& actual,
                                                        const RgbaImage& expected,
                                                        uint32_t radius = 1, int threshold = 16);

// Mean SSIM (Wang et al. 2004: 11x11 Gaussian window, sigma 1.5, K1 0.01, K2 0.03, L 255) of
// the Rec. 709 luma of the 8-bit values, averaged over the selected pixels (each pixel's SSIM
// is that of the window centred on it; windows are clamped at the image border). NaN when the
// mask selects nothing.
absl::StatusOr<double> SsimMasked(const RgbaImage& a, const RgbaImage& b,
                                  const std::vector<uint8_t>& mask = {});

// Per-pixel coverage estimated from a white-on-black render (linear luminance of each pixel,
// clamped to [0,1]) against the analytic coverage: mean absolute error over the pixels where
// either is strictly between 0 and 1 (the edge pixels), and over all pixels.
struct CoverageError {
  double edge_mae = 0.0;
  double all_mae = 0.0;
  uint64_t edge_pixels = 0;
};
absl::StatusOr<CoverageError> MeasureCoverage(const RgbaImage& image,
                                              const std::vector<float>& coverage);

// A contact sheet: one row per crop, one column per image, each crop magnified `zoom` times with
// nearest-neighbour (pixels stay visible), separated by a 2-pixel dark gutter, with each
// column's label written above the first row in a built-in bitmap font (ASCII letters, digits,
// '_', '-', '.', 'x'; others as blanks). Crops are clamped to the image bounds. All images
// must have the same size (INVALID_ARGUMENT otherwise).
struct Crop {
  uint32_t x = 0, y = 0, width = 32, height = 32;
};
struct LabelledImage {
  std::string label;
  const RgbaImage* image = nullptr;
};
absl::StatusOr<RgbaImage> ContactSheet(const std::vector<LabelledImage>& images,
                                       const std::vector<Crop>& crops, uint32_t zoom = 4);

// Up to `count` non-overlapping size x size windows with the most selected mask pixels, best
// first (windows with none are skipped): where a contact sheet should look.
std::vector<Crop> BusiestCrops(const std::vector<uint8_t>& mask, uint32_t width, uint32_t height,
                               uint32_t size, uint32_t count);

}  // namespace tessera

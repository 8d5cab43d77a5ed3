// libFuzzer target: image decoding. The first byte picks the decoder, the rest is the file:
//   0: as the glTF importer decodes textures (DecodeTextureImage: header check, then libpng,
//      TurboJPEG or libwebp, RGBA8)
//   1: DecodePng (libpng; the CLI reads PNG frames and golden images with it)
//   2: DecodeJpeg (TurboJPEG; the CLI and tests decode JPEG frames with it)
//   3: DecodeWebp (libwebp; EXT_texture_webp textures)
// A decoded image must be as large as it says, and within the limits it was decoded under.
#include <cstddef>
#include <cstdint>
#include <span>

#include "renderer/image_io.h"
#include "renderer/scene/gltf_import.h"

// Past this a decode allocates (and zero-fills) more than a fuzzer should spend on one input.
constexpr uint64_t kMaxPixels = 1u << 22;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size == 0) return 0;
  const uint8_t which = data[0] % 4;
  const std::span<const uint8_t> file(data + 1, size - 1);
  if (which == 0) {
    tessera::ImportLimits limits;
    limits.max_image_dimension = 4096;
    limits.max_image_bytes = 16u << 20;
    absl::StatusOr<tessera::DecodedImage> image =
        tessera::DecodeTextureImage(file.data(), file.size(), limits);
    if (image.ok()) {
      if (image->width == 0 || image->height == 0 || image->width > limits.max_image_dimension ||
          image->height > limits.max_image_dimension ||
          image->rgba8.size() != size_t(image->width) * image->height * 4 ||
          image->rgba8.size() > limits.max_image_bytes)
        __builtin_trap();
    }
    return 0;
  }
  absl::StatusOr<tessera::RgbaImage> image = which == 1   ? tessera::DecodePng(file, kMaxPixels)
                                             : which == 2 ? tessera::DecodeJpeg(file, kMaxPixels)
                                                          : tessera::DecodeWebp(file, kMaxPixels);
  if (image.ok() && (!tessera::ValidateImage(*image, "fuzz").ok() ||
                     uint64_t(image->width) * image->height > kMaxPixels))
    __builtin_trap();
  return 0;
}

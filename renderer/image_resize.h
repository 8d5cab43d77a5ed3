#pragma once
// CPU image resampling for the streaming server's interactive profile: a frame rendered at
// render_scale < 1 is upscaled to the viewer's resolution on an encoder thread before JPEG
// encoding, so this has to be cheap per frame and safe to call from many threads at once.
#include <cstdint>

#include "absl/status/statusor.h"
#include "renderer/image_io.h"

namespace tessera {

// Resamples an RGBA8 image to width x height with a separable cubic filter (Keys, a = -0.5,
// i.e. Catmull-Rom: interpolating, reproduces linear ramps), pixel centres aligned
// ((x + 0.5) * src/dst - 0.5), edges clamped. When downscaling, the kernel is widened by the
// scale factor (so it is a proper low-pass). Works in the 8-bit sRGB values as stored
// (like video scalers); alpha is resampled too. Results rounded and clamped to 0..255.
// INVALID_ARGUMENT for an empty source, a zero/oversized target (over kMaxImageSide) or a
// pixel buffer whose size does not match.
//
// Same-size input returns a copy. The arithmetic is 14-bit fixed point with exactly normalised
// weights, so flat areas stay exactly flat, and the result is deterministic and exactly
// mirror-symmetric (resizing a flipped image gives the flipped result). Scratch memory:
// width x src.height x 8 bytes. 640x360 -> 1280x720 takes about 8 ms on one core (-O2).
absl::StatusOr<RgbaImage> ResizeBicubic(RgbaView src, uint32_t width, uint32_t height);

}  // namespace tessera

#include "renderer/image_io.h"

#include <png.h>
#include <turbojpeg.h>
#include <webp/decode.h>
#include <webp/encode.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <span>
#include <thread>
#include <utility>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "common/status_macros.h"

namespace tessera {
namespace {

const char* WebpStatusName(VP8StatusCode status) {
  switch (status) {
    case VP8_STATUS_OK:
      return "ok";
    case VP8_STATUS_OUT_OF_MEMORY:
      return "out of memory";
    case VP8_STATUS_INVALID_PARAM:
      return "invalid parameter";
    case VP8_STATUS_BITSTREAM_ERROR:
      return "not a WebP bitstream";
    case VP8_STATUS_UNSUPPORTED_FEATURE:
      return "unsupported feature";
    case VP8_STATUS_SUSPENDED:
      return "suspended";
    case VP8_STATUS_USER_ABORT:
      return "aborted";
    case VP8_STATUS_NOT_ENOUGH_DATA:
      return "cut short";
  }
  return "unknown status";
}

// The RGBA8 image a decoder of `who` fills, once its header's size is checked: each side
// 1..kMaxImageSide, at most `max_pixels` in all.
absl::StatusOr<RgbaImage> DecodeTarget(const char* who, int width, int height,
                                       uint64_t max_pixels) {
  if (width <= 0 || height <= 0 || static_cast<uint32_t>(width) > kMaxImageSide ||
      static_cast<uint32_t>(height) > kMaxImageSide ||
      uint64_t(width) * uint64_t(height) > max_pixels) {
    return absl::InvalidArgumentError(
        absl::StrCat(who, ": dimensions out of range (", width, "x", height, ")"));
  }
  RgbaImage image;
  image.width = static_cast<uint32_t>(width);
  image.height = static_cast<uint32_t>(height);
  image.pixels.resize(size_t{image.width} * image.height * 4);
  return image;
}

// ---- TurboJPEG ---------------------------------------------------------------------------

// Owns a tjhandle so every return path destroys it.
class TjHandle {
 public:
  explicit TjHandle(tjhandle h) : h_(h) {}
  ~TjHandle() {
    if (h_ != nullptr) tjDestroy(h_);
  }
  TjHandle(const TjHandle&) = delete;
  TjHandle& operator=(const TjHandle&) = delete;
  tjhandle get() const { return h_; }

 private:
  tjhandle h_;
};

std::string TjError(tjhandle h) { return tjGetErrorStr2(h); }

// Runs work(k) for every strip k < count on up to one thread per hardware thread (the calling
// thread among them); what each strip produces must depend on k alone.
template <typename Work>
void ForEachStrip(uint32_t count, Work work) {
  const uint32_t threads = std::clamp(std::thread::hardware_concurrency(), 1u, count);
  auto run = [&](uint32_t first) {
    for (uint32_t k = first; k < count; k += threads) work(k);
  };
  std::vector<std::jthread> pool;
  uint32_t started = 1;
  try {
    for (; started < threads; ++started) pool.emplace_back(run, started);
  } catch (const std::system_error&) {
    // No thread to be had: this thread does the strips of those not started too.
  }
  for (uint32_t t = started; t < threads; ++t) run(t);
  run(0);
}

// ---- JPEG in strips ------------------------------------------------------------------------
//
// A large frame is encoded as horizontal strips on several threads and spliced into one baseline
// JPEG: strip 0's headers (its SOF's height patched to the whole image's, and a DRI segment
// whose restart interval is one strip's MCUs), then each strip's entropy-coded data with a
// restart marker between strips. A restart only resets the DC predictors, and the strips are cut
// at MCU rows (chroma 4:2:0 is averaged over 2x2 pixels inside a strip's rows), so the decoded
// pixels are those of a one-strip encode.

// One encoded strip: the whole JPEG, and where its entropy-coded data lies.
struct EncodedStrip {
  std::vector<uint8_t> jpeg;
  size_t sof = 0;           // offset of the SOF0 marker
  size_t sos = 0;           // offset of the SOS marker
  size_t data_begin = 0;    // first byte after the SOS segment
  size_t data_end = 0;      // the EOI marker
};

// Finds the SOF0 and SOS segments and the scan data of a TurboJPEG baseline encode.
absl::Status IndexStrip(EncodedStrip& s) {
  const std::vector<uint8_t>& j = s.jpeg;
  if (j.size() < 4 || j[0] != 0xFF || j[1] != 0xD8 || j[j.size() - 2] != 0xFF ||
      j[j.size() - 1] != 0xD9) {
    return absl::InternalError("EncodeJpeg: a strip is not a complete JPEG");
  }
  size_t p = 2;
  while (p + 4 <= j.size()) {
    if (j[p] != 0xFF) return absl::InternalError("EncodeJpeg: a strip's markers are malformed");
    const uint8_t marker = j[p + 1];
    const size_t length = (size_t(j[p + 2]) << 8) | j[p + 3];
    if (marker == 0xC0) s.sof = p;
    if (marker == 0xDD || (marker >= 0xC1 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 &&
                           marker != 0xCC)) {
      return absl::InternalError("EncodeJpeg: a strip is not a plain baseline JPEG");
    }
    if (marker == 0xDA) {
      s.sos = p;
      s.data_begin = p + 2 + length;
      s.data_end = j.size() - 2;
      return s.sof != 0 && s.data_begin <= s.data_end
                 ? absl::OkStatus()
                 : absl::InternalError("EncodeJpeg: a strip has no frame header");
    }
    p += 2 + length;
  }
  return absl::InternalError("EncodeJpeg: a strip has no scan");
}

absl::StatusOr<std::vector<uint8_t>> CompressRows(RgbaView image, uint32_t y0, uint32_t rows,
                                                  int quality, int samp) {
  TjHandle tj(tjInitCompress());
  if (tj.get() == nullptr) {
    return absl::InternalError(absl::StrCat("tjInitCompress: ", TjError(nullptr)));
  }
  unsigned char* jpeg = nullptr;
  unsigned long jpeg_size = 0;
  const size_t pitch = size_t(image.width) * 4;
  const int rc = tjCompress2(tj.get(), image.pixels.data() + y0 * pitch,
                             static_cast<int>(image.width), static_cast<int>(pitch),
                             static_cast<int>(rows), TJPF_RGBA, &jpeg, &jpeg_size, samp, quality,
                             TJFLAG_ACCURATEDCT);
  if (rc != 0) {
    tjFree(jpeg);  // TurboJPEG may have allocated the buffer before failing
    return absl::InternalError(absl::StrCat("tjCompress2: ", TjError(tj.get())));
  }
  std::vector<uint8_t> out(jpeg, jpeg + jpeg_size);
  tjFree(jpeg);
  return out;
}

// ---- libpng ------------------------------------------------------------------------------
//
// libpng reports errors by longjmp. Everything that must survive the jump (buffers, the
// message) lives in these state structs, owned by the caller of the setjmp frame, so no
// object with a destructor is skipped by the jump.

struct PngErrorState {
  char message[256] = "unknown libpng error";
};

void PngErrorFn(png_structp png, png_const_charp msg) {
  auto* err = static_cast<PngErrorState*>(png_get_error_ptr(png));
  if (err != nullptr && msg != nullptr) {
    std::snprintf(err->message, sizeof(err->message), "%s", msg);
  }
  png_longjmp(png, 1);
}

void PngWarningFn(png_structp, png_const_charp) {
  // Warnings (bad ancillary chunks, gamma oddities) do not affect the pixels we return.
}

// ---- PNG encoding in strips (zlib) -----------------------------------------------------------
//
// Every row is Paeth-filtered (filter type 4; the row above is the image's, so the filtered bytes
// do not depend on the strips). The strips' filtered rows are deflated independently (raw
// deflate, zlib's run-length strategy), each ended with a sync flush but the last, so that the
// pieces concatenate into one deflate stream; the zlib header and the Adler-32 of all the
// filtered bytes (adler32_combine) wrap it, split into one IDAT chunk per strip.

uint8_t Paeth(uint8_t a, uint8_t b, uint8_t c) {  // left, above, upper left (PNG spec 9.4)
  const int p = int(a) + int(b) - int(c);
  const int pa = std::abs(p - int(a)), pb = std::abs(p - int(b)), pc = std::abs(p - int(c));
  if (pa <= pb && pa <= pc) return a;
  return pb <= pc ? b : c;
}

struct PngStrip {
  std::vector<uint8_t> deflated;
  uLong adler = 1;
  uLong filtered_bytes = 0;
  bool ok = false;
};

// Filters rows [y0, y1) and deflates them, a row at a time (the extra memory is the strip's
// deflated bytes); `last` ends the deflate stream.
PngStrip DeflateRows(RgbaView image, uint32_t y0, uint32_t y1, bool last) {
  PngStrip out;
  const size_t stride = size_t(image.width) * 4;
  std::vector<uint8_t> filtered(stride + 1);
  const std::vector<uint8_t> zeros(stride, 0);
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, -15, 8, Z_RLE) != Z_OK) return out;
  std::vector<uint8_t> buffer(256 * 1024);
  out.deflated.reserve(size_t(y1 - y0) * (stride + 1) / 2);  // rendered frames: a third or less
  for (uint32_t y = y0; y < y1; ++y) {
    const uint8_t* row = image.pixels.data() + y * stride;
    const uint8_t* above = y == 0 ? zeros.data() : row - stride;
    uint8_t* f = filtered.data();
    *f++ = 4;  // Paeth
    for (size_t i = 0; i < 4; ++i) f[i] = uint8_t(row[i] - Paeth(0, above[i], 0));
    for (size_t i = 4; i < stride; ++i)
      f[i] = uint8_t(row[i] - Paeth(row[i - 4], above[i], above[i - 4]));
    out.adler = adler32(out.adler, filtered.data(), uInt(filtered.size()));
    out.filtered_bytes += uLong(filtered.size());
    const int flush = y + 1 < y1 ? Z_NO_FLUSH : last ? Z_FINISH : Z_SYNC_FLUSH;
    z.next_in = filtered.data();
    z.avail_in = uInt(filtered.size());
    int rc = Z_OK;
    do {  // until the row is in and, at the end, everything flushed
      z.next_out = buffer.data();
      z.avail_out = uInt(buffer.size());
      rc = deflate(&z, flush);
      out.deflated.insert(out.deflated.end(), buffer.data(),
                          buffer.data() + (buffer.size() - z.avail_out));
    } while (rc != Z_STREAM_ERROR && (z.avail_out == 0 || z.avail_in != 0));
    out.ok = rc != Z_STREAM_ERROR && (flush != Z_FINISH || rc == Z_STREAM_END);
    if (!out.ok) break;
  }
  deflateEnd(&z);
  return out;
}

void PutBe32(std::vector<uint8_t>& out, uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(uint8_t(v >> shift));
}

// Appends a chunk: length, type, data (the concatenation of `parts`), CRC of type and data.
// The largest, one strip of the largest image: its filtered rows plus deflate's worst case.
static_assert(uint64_t{kMaxImageSide} * (uint64_t{kMaxImageSide} * 4 + 1) * 1001 / 1000 <
                  (uint64_t{1} << 31),
              "an IDAT chunk's length must stay below 2^31");
void PutChunk(std::vector<uint8_t>& out, const char (&type)[5],
              std::initializer_list<std::span<const uint8_t>> parts) {
  size_t length = 0;
  for (const auto& p : parts) length += p.size();
  PutBe32(out, uint32_t(length));
  const size_t crc_from = out.size();
  out.insert(out.end(), type, type + 4);
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  PutBe32(out, uint32_t(crc32(0, out.data() + crc_from, uInt(out.size() - crc_from))));
}

struct PngReadState {
  PngErrorState error;
  const uint8_t* data = nullptr;
  size_t size = 0;
  size_t pos = 0;
  bool too_large = false;
  uint64_t max_pixels = 0;
  RgbaImage image;
  std::vector<png_bytep> rows;
};

void PngReadFn(png_structp png, png_bytep out, png_size_t length) {
  auto* st = static_cast<PngReadState*>(png_get_io_ptr(png));
  if (length > st->size - st->pos) png_error(png, "truncated PNG data");
  std::memcpy(out, st->data + st->pos, length);
  st->pos += length;
}

bool DecodePngImpl(PngReadState* st) {
  png_structp png =
      png_create_read_struct(PNG_LIBPNG_VER_STRING, &st->error, PngErrorFn, PngWarningFn);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_set_read_fn(png, st, PngReadFn);
  png_set_user_limits(png, kMaxImageSide, kMaxImageSide);
  // Bounds what a compressed text or ICC chunk may inflate to, and how many ancillary chunks
  // (text, sPLT, unknown) are kept; no chunk we decode (IDAT is streamed) needs more.
  png_set_chunk_malloc_max(png, 8u << 20);
  png_set_chunk_cache_max(png, 128);
  png_read_info(png, info);

  png_uint_32 width = 0, height = 0;
  int bit_depth = 0, color_type = 0, interlace = 0;
  png_get_IHDR(png, info, &width, &height, &bit_depth, &color_type, &interlace, nullptr, nullptr);
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide ||
      uint64_t{width} * height > st->max_pixels) {
    st->too_large = true;
    png_error(png, "PNG dimensions out of range");
  }

  // Normalize every PNG flavour to 8-bit RGBA.
  const bool has_trns = png_get_valid(png, info, PNG_INFO_tRNS) != 0;
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (has_trns) png_set_tRNS_to_alpha(png);
  if (bit_depth == 16) png_set_strip_16(png);
  if (color_type == PNG_COLOR_TYPE_GRAY || color_type == PNG_COLOR_TYPE_GRAY_ALPHA) {
    png_set_gray_to_rgb(png);
  }
  if ((color_type & PNG_COLOR_MASK_ALPHA) == 0 && !has_trns) {
    png_set_add_alpha(png, 0xFF, PNG_FILLER_AFTER);
  }
  png_set_interlace_handling(png);
  png_read_update_info(png, info);

  if (png_get_rowbytes(png, info) != size_t{width} * 4) {
    png_error(png, "PNG transform did not produce RGBA8");
  }
  st->image.width = width;
  st->image.height = height;
  st->image.pixels.resize(size_t{width} * height * 4);
  st->rows.resize(height);
  for (png_uint_32 y = 0; y < height; ++y) {
    st->rows[y] = st->image.pixels.data() + size_t{y} * width * 4;
  }
  png_read_image(png, st->rows.data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

}  // namespace

absl::StatusOr<std::vector<uint8_t>> EncodeJpeg(RgbaView image, int quality,
                                                ChromaSubsampling subsampling) {
  return EncodeJpeg(image, quality, subsampling, 1);
}

uint32_t AutoJpegStrips(RgbaView image) {
  constexpr uint64_t kMinPixels = 1920 * 1080;
  return uint64_t(image.width) * image.height < kMinPixels ? 1 : kMaxJpegStrips;
}

absl::StatusOr<std::vector<uint8_t>> EncodeJpeg(RgbaView image, int quality,
                                                ChromaSubsampling subsampling, uint32_t strips) {
  if (quality < 1 || quality > 100) {
    return absl::InvalidArgumentError(
        absl::StrCat("EncodeJpeg: quality ", quality, " outside 1..100"));
  }
  RETURN_IF_ERROR(ValidateImage(image, "EncodeJpeg"));
  const bool s444 = subsampling == ChromaSubsampling::k444;
  const int samp = s444 ? TJSAMP_444 : TJSAMP_420;
  const uint32_t mcu = s444 ? 8 : 16;  // an MCU's side in pixels
  const uint32_t mcu_rows = (image.height + mcu - 1) / mcu;
  const uint32_t mcus_per_row = (image.width + mcu - 1) / mcu;
  if (strips == 0) strips = AutoJpegStrips(image);
  strips = std::clamp(strips, 1u, std::min(mcu_rows, kMaxJpegStrips));
  // Every strip but the last holds `rows` MCU rows; a restart interval (16 bits) is one strip.
  const uint32_t rows = std::min((mcu_rows + strips - 1) / strips,
                                 std::max(1u, 65535u / mcus_per_row));
  const uint32_t count = (mcu_rows + rows - 1) / rows;
  if (count == 1) return CompressRows(image, 0, image.height, quality, samp);

  std::vector<EncodedStrip> parts(count);
  std::vector<absl::Status> status(count);
  // The bytes depend on the strips alone; the threads only on the machine.
  ForEachStrip(count, [&](uint32_t k) {
    const uint32_t y0 = k * rows * mcu;
    absl::StatusOr<std::vector<uint8_t>> jpeg =
        CompressRows(image, y0, std::min(rows * mcu, image.height - y0), quality, samp);
    if (!jpeg.ok()) {
      status[k] = jpeg.status();
      return;
    }
    parts[k].jpeg = std::move(*jpeg);
    status[k] = IndexStrip(parts[k]);
  });
  for (const absl::Status& st : status) RETURN_IF_ERROR(st);
  // Every strip must carry strip 0's tables (TurboJPEG's standard Huffman tables; not so when
  // e.g. TJ_OPTIMIZE in the environment makes each strip's its own): else one strip after all.
  for (uint32_t k = 1; k < count; ++k) {
    const EncodedStrip& s = parts[k];
    const EncodedStrip& h = parts[0];
    const bool same = s.sos == h.sos && s.sof == h.sof && s.data_begin == h.data_begin &&
                      std::equal(h.jpeg.begin(), h.jpeg.begin() + h.sof + 5, s.jpeg.begin()) &&
                      std::equal(h.jpeg.begin() + h.sof + 7, h.jpeg.begin() + h.data_begin,
                                 s.jpeg.begin() + h.sof + 7);
    if (!same) return CompressRows(image, 0, image.height, quality, samp);
  }

  const EncodedStrip& head = parts[0];
  std::vector<uint8_t> out(head.jpeg.begin(), head.jpeg.begin() + head.sos);
  out[head.sof + 5] = uint8_t(image.height >> 8);  // SOF0: length, precision, height, width
  out[head.sof + 6] = uint8_t(image.height & 0xFF);
  const uint32_t interval = rows * mcus_per_row;
  const uint8_t dri[] = {0xFF, 0xDD, 0x00, 0x04, uint8_t(interval >> 8), uint8_t(interval & 0xFF)};
  out.insert(out.end(), std::begin(dri), std::end(dri));
  out.insert(out.end(), head.jpeg.begin() + head.sos, head.jpeg.begin() + head.data_begin);
  for (uint32_t k = 0; k < count; ++k) {
    const EncodedStrip& s = parts[k];
    out.insert(out.end(), s.jpeg.begin() + s.data_begin, s.jpeg.begin() + s.data_end);
    if (k + 1 < count) {
      out.push_back(0xFF);
      out.push_back(uint8_t(0xD0 + k % 8));  // RST0..RST7, in turn
    }
  }
  out.push_back(0xFF);
  out.push_back(0xD9);
  return out;
}

absl::StatusOr<RgbaImage> DecodeJpeg(std::span<const uint8_t> jpeg, uint64_t max_pixels) {
  if (jpeg.empty()) return absl::InvalidArgumentError("DecodeJpeg: empty input");
  if (jpeg.size() > std::numeric_limits<unsigned long>::max()) {
    return absl::InvalidArgumentError("DecodeJpeg: input too large");
  }
  TjHandle tj(tjInitDecompress());
  if (tj.get() == nullptr) {
    return absl::InternalError(absl::StrCat("tjInitDecompress: ", TjError(nullptr)));
  }
  int width = 0, height = 0, subsamp = 0, colorspace = 0;
  if (tjDecompressHeader3(tj.get(), jpeg.data(), static_cast<unsigned long>(jpeg.size()), &width,
                          &height, &subsamp, &colorspace) != 0) {
    return absl::InvalidArgumentError(absl::StrCat("DecodeJpeg: bad header: ", TjError(tj.get())));
  }
  ASSIGN_OR_RETURN(RgbaImage image, DecodeTarget("DecodeJpeg", width, height, max_pixels));
  // Stop on warnings: a truncated scan is only a warning to libjpeg (it pads with grey),
  // and we would rather report it than hand back a half-grey frame.
  if (tjDecompress2(tj.get(), jpeg.data(), static_cast<unsigned long>(jpeg.size()),
                    image.pixels.data(), width, width * 4, height, TJPF_RGBA,
                    TJFLAG_ACCURATEDCT | TJFLAG_STOPONWARNING) != 0) {
    return absl::InvalidArgumentError(absl::StrCat("DecodeJpeg: ", TjError(tj.get())));
  }
  return image;
}

bool IsWebp(std::span<const uint8_t> d) {
  return d.size() >= 12 && std::memcmp(d.data(), "RIFF", 4) == 0 &&
         std::memcmp(d.data() + 8, "WEBP", 4) == 0;
}

bool ReadWebpSize(std::span<const uint8_t> webp, uint32_t* width, uint32_t* height) {
  int w = 0, h = 0;
  if (!IsWebp(webp) || !WebPGetInfo(webp.data(), webp.size(), &w, &h) || w <= 0 || h <= 0)
    return false;
  *width = uint32_t(w);
  *height = uint32_t(h);
  return true;
}

absl::StatusOr<RgbaImage> DecodeWebp(std::span<const uint8_t> webp, uint64_t max_pixels) {
  if (webp.empty()) return absl::InvalidArgumentError("DecodeWebp: empty input");
  WebPBitstreamFeatures features;
  // The RIFF header and the first chunk's: the size, alpha and animation, nothing decoded.
  const VP8StatusCode header = WebPGetFeatures(webp.data(), webp.size(), &features);
  if (header != VP8_STATUS_OK) {
    return absl::InvalidArgumentError(
        absl::StrCat("DecodeWebp: bad header (", WebpStatusName(header), ")"));
  }
  if (features.has_animation) {
    return absl::InvalidArgumentError("DecodeWebp: an animated WebP (only still images decode)");
  }
  const int width = features.width, height = features.height;
  ASSIGN_OR_RETURN(RgbaImage image, DecodeTarget("DecodeWebp", width, height, max_pixels));
  // Into our buffer, at the size the header gave (libwebp refuses data of another size).
  if (WebPDecodeRGBAInto(webp.data(), webp.size(), image.pixels.data(), image.pixels.size(),
                         width * 4) == nullptr) {
    return absl::InvalidArgumentError(
        "DecodeWebp: the image data is corrupt or cut short (libwebp could not decode it)");
  }
  return image;
}

absl::StatusOr<std::vector<uint8_t>> EncodeWebpLossless(RgbaView image) {
  RETURN_IF_ERROR(ValidateImage(image, "EncodeWebpLossless"));
  uint8_t* out = nullptr;
  const size_t size = WebPEncodeLosslessRGBA(image.pixels.data(), int(image.width),
                                             int(image.height), int(image.width) * 4, &out);
  if (size == 0 || out == nullptr) {
    WebPFree(out);
    return absl::InternalError("EncodeWebpLossless: libwebp's encoder failed");
  }
  std::vector<uint8_t> bytes(out, out + size);
  WebPFree(out);
  return bytes;
}

uint32_t AutoPngStrips(RgbaView image) { return std::clamp(image.height / 64, 1u, kMaxPngStrips); }

absl::StatusOr<std::vector<uint8_t>> EncodePng(RgbaView image, uint32_t strips) {
  RETURN_IF_ERROR(ValidateImage(image, "EncodePng"));
  if (strips == 0) strips = AutoPngStrips(image);
  strips = std::clamp(strips, 1u, std::min(image.height, kMaxPngStrips));
  const uint32_t rows = (image.height + strips - 1) / strips;
  const uint32_t count = (image.height + rows - 1) / rows;
  std::vector<PngStrip> parts(count);
  ForEachStrip(count, [&](uint32_t k) {
    parts[k] = DeflateRows(image, k * rows, std::min(image.height, (k + 1) * rows),
                           k + 1 == count);
  });
  uLong adler = 1;
  size_t deflated = 0;
  for (const PngStrip& p : parts) {
    if (!p.ok) return absl::InternalError("EncodePng: zlib's deflate failed");
    adler = adler32_combine(adler, p.adler, p.filtered_bytes);
    deflated += p.deflated.size();
  }
  std::vector<uint8_t> out;
  out.reserve(deflated + 64 + 12 * count);
  const uint8_t signature[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  out.insert(out.end(), std::begin(signature), std::end(signature));
  std::vector<uint8_t> ihdr;
  PutBe32(ihdr, image.width);
  PutBe32(ihdr, image.height);
  ihdr.insert(ihdr.end(), {8, 6, 0, 0, 0});  // 8-bit RGBA, deflate, adaptive filters, no interlace
  PutChunk(out, "IHDR", {ihdr});
  const uint8_t zlib_header[] = {0x78, 0x01};  // deflate, 32 KiB window, check bits
  std::vector<uint8_t> trailer;
  PutBe32(trailer, uint32_t(adler));
  for (uint32_t k = 0; k < count; ++k) {
    const std::span<const uint8_t> head =
        k == 0 ? std::span<const uint8_t>(zlib_header) : std::span<const uint8_t>();
    const std::span<const uint8_t> tail =
        k + 1 == count ? std::span<const uint8_t>(trailer) : std::span<const uint8_t>();
    PutChunk(out, "IDAT", {head, parts[k].deflated, tail});
  }
  PutChunk(out, "IEND", {});
  return out;
}

absl::StatusOr<RgbaImage> DecodePng(std::span<const uint8_t> png, uint64_t max_pixels) {
  if (png.empty()) return absl::InvalidArgumentError("DecodePng: empty input");
  if (png.size() < 8 || png_sig_cmp(png.data(), 0, 8) != 0) {
    return absl::InvalidArgumentError("DecodePng: not a PNG (bad signature)");
  }
  // libpng allocates a chunk's declared length before reading it (png_set_chunk_malloc_max
  // does not stop that in Debian 12's 1.6.39): a 900-byte file declaring a 1 GiB chunk cost a
  // 1 GiB malloc (found by fuzzing). A chunk cannot be longer than the file that holds it.
  // (A chunk is its length, type, data and CRC: 12 bytes more than its length.)
  for (size_t at = 8; png.size() - at >= 8;) {
    const uint8_t* c = png.data() + at;
    const uint64_t length = uint64_t(c[0]) << 24 | uint64_t(c[1]) << 16 | uint64_t(c[2]) << 8 | c[3];
    if (12 + length > png.size() - at) {
      return absl::InvalidArgumentError(absl::StrCat("DecodePng: the chunk at byte ", at,
                                                     " declares ", length,
                                                     " bytes, past the end of the file"));
    }
    if (std::memcmp(c + 4, "IEND", 4) == 0) break;
    at += 12 + length;
  }
  PngReadState st;
  st.data = png.data();
  st.size = png.size();
  st.max_pixels = max_pixels;
  if (!DecodePngImpl(&st)) {
    return absl::InvalidArgumentError(absl::StrCat("DecodePng: ", st.error.message));
  }
  return std::move(st.image);
}

absl::StatusOr<std::vector<uint8_t>> ReadFileBytes(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    const int err = errno;
    return absl::ErrnoToStatus(err, absl::StrCat("cannot open ", path));
  }
  std::vector<uint8_t> bytes;
  // Chunked reads work for pipes and /proc files whose size is not known up front.
  uint8_t chunk[64 * 1024];
  size_t n = 0;
  while ((n = std::fread(chunk, 1, sizeof(chunk), f)) > 0) {
    bytes.insert(bytes.end(), chunk, chunk + n);
  }
  const bool failed = std::ferror(f) != 0;
  const int err = errno;
  std::fclose(f);
  if (failed) return absl::ErrnoToStatus(err, absl::StrCat("cannot read ", path));
  return bytes;
}

absl::Status WriteFileBytes(const std::string& path, std::span<const uint8_t> bytes) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) {
    const int err = errno;
    return absl::ErrnoToStatus(err, absl::StrCat("cannot create ", path));
  }
  const size_t written = bytes.empty() ? 0 : std::fwrite(bytes.data(), 1, bytes.size(), f);
  int err = errno;
  bool ok = written == bytes.size();
  // fclose flushes: a full disk often only shows up here.
  if (std::fclose(f) != 0) {
    if (ok) err = errno;
    ok = false;
  }
  if (!ok) return absl::ErrnoToStatus(err, absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

absl::StatusOr<double> Psnr(const RgbaImage& a, const RgbaImage& b) {
  RETURN_IF_ERROR(ValidateImage(a, "Psnr (first image)"));
  RETURN_IF_ERROR(ValidateImage(b, "Psnr (second image)"));
  if (a.width != b.width || a.height != b.height) {
    return absl::InvalidArgumentError(absl::StrCat("Psnr: sizes differ: ", a.width, "x", a.height,
                                                   " vs ", b.width, "x", b.height));
  }
  uint64_t sum_sq = 0;
  for (size_t i = 0; i < a.pixels.size(); i += 4) {
    for (size_t c = 0; c < 3; ++c) {
      const int d = int{a.pixels[i + c]} - int{b.pixels[i + c]};
      sum_sq += static_cast<uint64_t>(d * d);
    }
  }
  if (sum_sq == 0) return std::numeric_limits<double>::infinity();
  const double mse = static_cast<double>(sum_sq) / (static_cast<double>(a.width) * a.height * 3.0);
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

absl::StatusOr<RgbaImage> DiffImage(const RgbaImage& a, const RgbaImage& b, float gain) {
  RETURN_IF_ERROR(ValidateImage(a, "DiffImage (first image)"));
  RETURN_IF_ERROR(ValidateImage(b, "DiffImage (second image)"));
  if (a.width != b.width || a.height != b.height) {
    return absl::InvalidArgumentError(absl::StrCat("DiffImage: sizes differ: ", a.width, "x",
                                                   a.height, " vs ", b.width, "x", b.height));
  }
  if (!std::isfinite(gain) || gain < 0.0f) {
    return absl::InvalidArgumentError(absl::StrCat("DiffImage: bad gain ", gain));
  }
  RgbaImage out;
  out.width = a.width;
  out.height = a.height;
  out.pixels.resize(a.pixels.size());
  for (size_t i = 0; i < a.pixels.size(); i += 4) {
    for (size_t c = 0; c < 3; ++c) {
      const float d = std::abs(float(a.pixels[i + c]) - float(b.pixels[i + c])) * gain;
      out.pixels[i + c] = static_cast<uint8_t>(std::min(255.0f, std::round(d)));
    }
    out.pixels[i + 3] = 255;
  }
  return out;
}

absl::Status ValidateImage(RgbaView image, const char* what) {
  if (image.width == 0 || image.height == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": empty image (", image.width, "x", image.height, ")"));
  }
  if (image.width > kMaxImageSide || image.height > kMaxImageSide) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, ": image too large (", image.width, "x", image.height, ")"));
  }
  const uint64_t expected = uint64_t{image.width} * image.height * 4;
  if (image.pixels.size() != expected) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": pixel buffer holds ",
                                                   image.pixels.size(), " bytes, ", image.width,
                                                   "x", image.height, " RGBA needs ", expected));
  }
  return absl::OkStatus();
}

}  // namespace tessera

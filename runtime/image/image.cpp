#include "runtime/image/image.h"

#include <png.h>
#include <turbojpeg.h>

#include <algorithm>
#include <cerrno>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <memory>
#include <new>
#include <string>
#include <system_error>

namespace mocap::image {
namespace {

// Whole-file reads are capped well above any image within kMaxImageSidePx.
constexpr std::uintmax_t kMaxFileBytes = std::uintmax_t{1} << 30;

constexpr std::uint8_t kPngMagic[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
constexpr std::uint8_t kJpegMagic[3] = {0xFF, 0xD8, 0xFF};

bool starts_with(std::span<const std::uint8_t> bytes, std::span<const std::uint8_t> magic) {
  return bytes.size() >= magic.size() && std::equal(magic.begin(), magic.end(), bytes.begin());
}

bool starts_with_text(std::span<const std::uint8_t> bytes, std::size_t offset,
                      std::string_view text) {
  if (bytes.size() < offset + text.size()) return false;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (bytes[offset + i] != static_cast<std::uint8_t>(text[i])) return false;
  }
  return true;
}

// Names formats we recognise but do not decode, for a more useful error.
const char* other_image_format(std::span<const std::uint8_t> bytes) {
  if (starts_with_text(bytes, 0, "GIF87a") || starts_with_text(bytes, 0, "GIF89a")) return "GIF";
  if (starts_with_text(bytes, 0, "RIFF") && starts_with_text(bytes, 8, "WEBP")) return "WebP";
  if (starts_with_text(bytes, 0, "BM")) return "BMP";
  if (starts_with_text(bytes, 0, std::string_view("II*\0", 4)) ||
      starts_with_text(bytes, 0, std::string_view("MM\0*", 4))) {
    return "TIFF";
  }
  if (bytes.size() >= 2 && bytes[0] == 'P' && bytes[1] >= '1' && bytes[1] <= '7') return "PNM";
  return nullptr;
}

std::string hex_prefix(std::span<const std::uint8_t> bytes) {
  std::string out;
  const std::size_t n = std::min<std::size_t>(bytes.size(), 8);
  for (std::size_t i = 0; i < n; ++i) {
    char buf[4];
    std::snprintf(buf, sizeof(buf), "%02x", bytes[i]);
    if (i > 0) out += ' ';
    out += buf;
  }
  return out;
}

Error too_large(std::string_view name, long long width_px, long long height_px) {
  return Error(ErrorCode::kUnsupported, std::string(name) + ": image is " +
                                            std::to_string(width_px) + "x" +
                                            std::to_string(height_px) + " px, larger than the " +
                                            std::to_string(kMaxImageSidePx) + "x" +
                                            std::to_string(kMaxImageSidePx) + " px limit");
}

// ---------------------------------------------------------------------------------------------
// JPEG (TurboJPEG)

struct TjDestroyer {
  void operator()(void* handle) const {
    if (handle != nullptr) tjDestroy(handle);
  }
};
using TjHandle = std::unique_ptr<void, TjDestroyer>;

Result<ImageRgb8> decode_jpeg(std::span<const std::uint8_t> bytes, std::string_view name) {
  const TjHandle tj(tjInitDecompress());
  if (!tj) {
    return Error(ErrorCode::kInternal,
                 std::string(name) + ": cannot create a JPEG decoder: " + tjGetErrorStr2(nullptr));
  }
  int width_px = 0;
  int height_px = 0;
  int subsampling = 0;
  int colorspace = 0;
  if (tjDecompressHeader3(tj.get(), bytes.data(), static_cast<unsigned long>(bytes.size()),
                          &width_px, &height_px, &subsampling, &colorspace) != 0) {
    return Error(ErrorCode::kParse, std::string(name) + ": corrupt or truncated JPEG header (" +
                                        tjGetErrorStr2(tj.get()) + ")");
  }
  if (width_px <= 0 || height_px <= 0) {
    // TurboJPEG accepts a stream cut before its frame header as "tables only", size 0x0.
    return Error(ErrorCode::kParse,
                 std::string(name) + ": truncated or corrupt JPEG header (no image size found)");
  }
  if (width_px > kMaxImageSidePx || height_px > kMaxImageSidePx) {
    return too_large(name, width_px, height_px);
  }
  if (colorspace == TJCS_CMYK || colorspace == TJCS_YCCK) {
    return Error(ErrorCode::kUnsupported,
                 std::string(name) + ": CMYK JPEG images are not supported (RGB/gray only)");
  }
  ImageRgb8 image;
  image.width_px = width_px;
  image.height_px = height_px;
  image.rgb.resize(static_cast<std::size_t>(width_px) * static_cast<std::size_t>(height_px) * 3);
  // Flags 0: accurate integer IDCT and smooth upsampling, libjpeg's defaults for decoding.
  if (tjDecompress2(tj.get(), bytes.data(), static_cast<unsigned long>(bytes.size()),
                    image.rgb.data(), width_px, 0, height_px, TJPF_RGB, 0) != 0) {
    // A warning (e.g. "Premature end of JPEG file") still leaves grey filler in the output:
    // treat it as damage rather than returning a silently wrong image.
    const bool warning = tjGetErrorCode(tj.get()) == TJERR_WARNING;
    return Error(ErrorCode::kParse,
                 std::string(name) +
                     (warning ? ": truncated or corrupt JPEG data (" : ": cannot decode JPEG (") +
                     tjGetErrorStr2(tj.get()) + ")");
  }
  return image;
}

// ---------------------------------------------------------------------------------------------
// PNG (libpng). libpng reports errors through a callback that must not return; we longjmp
// back into the two small functions below, which hold only trivially destructible locals and
// keep all state in PngJob (reached through a pointer), as setjmp/longjmp requires in C++.

struct PngJob {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::size_t offset = 0;
  png_structp png = nullptr;
  png_infop info = nullptr;
  png_uint_32 width_px = 0;
  png_uint_32 height_px = 0;
  int bit_depth = 0;
  int color_type = 0;
  std::size_t row_bytes = 0;
  int channels = 0;
  char message[256] = {};
  std::jmp_buf jump;
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
  auto* job = static_cast<PngJob*>(png_get_error_ptr(png));
  std::snprintf(job->message, sizeof(job->message), "%s", message);
  std::longjmp(job->jump, 1);
}

void on_png_warning(png_structp /*png*/, png_const_charp /*message*/) {
  // Benign (e.g. "iCCP: known incorrect sRGB profile"); damage is reported as an error.
}

void read_png_bytes(png_structp png, png_bytep out, png_size_t count) {
  auto* job = static_cast<PngJob*>(png_get_io_ptr(png));
  if (job->size - job->offset < count) png_error(png, "unexpected end of file (truncated)");
  std::memcpy(out, job->data + job->offset, count);
  job->offset += count;
}

// Reads the header and sets up the conversion to 8-bit RGB. False on error (job->message).
bool png_read_header(PngJob* job) {
  if (setjmp(job->jump) != 0) return false;
  png_set_read_fn(job->png, job, read_png_bytes);
  png_read_info(job->png, job->info);
  job->width_px = png_get_image_width(job->png, job->info);
  job->height_px = png_get_image_height(job->png, job->info);
  job->bit_depth = png_get_bit_depth(job->png, job->info);
  job->color_type = png_get_color_type(job->png, job->info);
  if (job->width_px > static_cast<png_uint_32>(kMaxImageSidePx) ||
      job->height_px > static_cast<png_uint_32>(kMaxImageSidePx)) {
    return true;  // the caller reports the size before anything is allocated
  }
  if (job->color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(job->png);
  if (job->color_type == PNG_COLOR_TYPE_GRAY && job->bit_depth < 8) {
    png_set_expand_gray_1_2_4_to_8(job->png);
  }
  if (job->bit_depth == 16) png_set_scale_16(job->png);
  // Drops an alpha channel, including the one palette expansion makes from a tRNS chunk.
  png_set_strip_alpha(job->png);
  if (job->color_type == PNG_COLOR_TYPE_GRAY || job->color_type == PNG_COLOR_TYPE_GRAY_ALPHA) {
    png_set_gray_to_rgb(job->png);
  }
  png_set_interlace_handling(job->png);
  png_read_update_info(job->png, job->info);
  job->row_bytes = png_get_rowbytes(job->png, job->info);
  job->channels = png_get_channels(job->png, job->info);
  return true;
}

// Decodes all rows (interlaced or not) and checks the rest of the stream. False on error.
bool png_read_pixels(PngJob* job, png_bytepp rows) {
  if (setjmp(job->jump) != 0) return false;
  png_read_image(job->png, rows);
  png_read_end(job->png, nullptr);
  return true;
}

struct PngStructs {
  PngJob* job;
  ~PngStructs() {
    if (job->png != nullptr) png_destroy_read_struct(&job->png, &job->info, nullptr);
  }
};

Result<ImageRgb8> decode_png(std::span<const std::uint8_t> bytes, std::string_view name) {
  PngJob job;
  job.data = bytes.data();
  job.size = bytes.size();
  const PngStructs structs{&job};
  job.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &job, on_png_error, on_png_warning);
  if (job.png != nullptr) job.info = png_create_info_struct(job.png);
  if (job.png == nullptr || job.info == nullptr) {
    return Error(ErrorCode::kInternal, std::string(name) + ": cannot create a PNG decoder");
  }
  if (!png_read_header(&job)) {
    return Error(ErrorCode::kParse,
                 std::string(name) + ": corrupt or truncated PNG header (" + job.message + ")");
  }
  if (job.width_px > static_cast<png_uint_32>(kMaxImageSidePx) ||
      job.height_px > static_cast<png_uint_32>(kMaxImageSidePx)) {
    return too_large(name, job.width_px, job.height_px);
  }
  const auto width_px = static_cast<std::size_t>(job.width_px);
  const auto height_px = static_cast<std::size_t>(job.height_px);
  if (job.channels != 3 || job.row_bytes != width_px * 3) {
    return Error(ErrorCode::kInternal, std::string(name) + ": PNG conversion to 8-bit RGB gave " +
                                           std::to_string(job.channels) + " channels, " +
                                           std::to_string(job.row_bytes) + " bytes per row");
  }
  ImageRgb8 image;
  image.width_px = static_cast<int>(job.width_px);
  image.height_px = static_cast<int>(job.height_px);
  image.rgb.resize(width_px * height_px * 3);
  std::vector<png_bytep> rows(height_px);
  for (std::size_t y = 0; y < height_px; ++y) rows[y] = image.rgb.data() + y * width_px * 3;
  if (!png_read_pixels(&job, rows.data())) {
    return Error(ErrorCode::kParse,
                 std::string(name) + ": corrupt or truncated PNG data (" + job.message + ")");
  }
  return image;
}

}  // namespace

ImageFormat sniff_format(std::span<const std::uint8_t> bytes) {
  if (starts_with(bytes, kJpegMagic)) return ImageFormat::kJpeg;
  if (starts_with(bytes, kPngMagic)) return ImageFormat::kPng;
  return ImageFormat::kUnknown;
}

Result<ImageRgb8> decode_image(std::span<const std::uint8_t> bytes, std::string_view name) {
  try {
    switch (sniff_format(bytes)) {
      case ImageFormat::kJpeg:
        return decode_jpeg(bytes, name);
      case ImageFormat::kPng:
        return decode_png(bytes, name);
      case ImageFormat::kUnknown:
        break;
    }
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, std::string(name) + ": out of memory while decoding");
  }
  if (bytes.empty()) {
    return Error(ErrorCode::kParse, std::string(name) + ": empty file, expected a JPEG or PNG");
  }
  if (const char* other = other_image_format(bytes)) {
    return Error(ErrorCode::kUnsupported, std::string(name) + ": " + other +
                                              " images are not supported (JPEG and PNG only)");
  }
  return Error(ErrorCode::kParse, std::string(name) +
                                      ": not a JPEG or PNG image (starts with bytes " +
                                      hex_prefix(bytes) + ")");
}

Result<ImageRgb8> load_image(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) {
    return Error(ErrorCode::kNotFound, name + ": no such file");
  }
  if (std::filesystem::is_directory(status)) {
    return Error(ErrorCode::kIo, name + ": is a directory, expected an image file");
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) return Error(ErrorCode::kIo, name + ": cannot get the file size: " + ec.message());
  if (size > kMaxFileBytes) {
    return Error(ErrorCode::kUnsupported, name + ": file is " + std::to_string(size) +
                                              " bytes, more than the " +
                                              std::to_string(kMaxFileBytes) + " byte limit");
  }
  std::vector<std::uint8_t> bytes;
  try {
    bytes.resize(static_cast<std::size_t>(size));
  } catch (const std::bad_alloc&) {
    return Error(ErrorCode::kIo, name + ": out of memory while reading");
  }
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) {
    return Error(ErrorCode::kIo,
                 name + ": cannot open for reading: " + std::generic_category().message(errno));
  }
  const std::size_t got = std::fread(bytes.data(), 1, bytes.size(), file);
  const bool read_error = std::ferror(file) != 0;
  std::fclose(file);
  if (read_error) return Error(ErrorCode::kIo, name + ": read failed");
  bytes.resize(got);  // the file may have shrunk since file_size(); decoding then reports it
  return decode_image(bytes, name);
}

Status save_ppm(const ImageRgb8& image, const std::filesystem::path& path) {
  const std::string name = path.string();
  if (image.width_px <= 0 || image.height_px <= 0 ||
      image.rgb.size() != static_cast<std::size_t>(image.width_px) *
                              static_cast<std::size_t>(image.height_px) * 3) {
    return Error(ErrorCode::kInvalidArgument,
                 name + ": cannot save an inconsistent image (" + std::to_string(image.width_px) +
                     "x" + std::to_string(image.height_px) + " px, " +
                     std::to_string(image.rgb.size()) + " bytes of RGB)");
  }
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) {
    return Error(ErrorCode::kIo,
                 name + ": cannot open for writing: " + std::generic_category().message(errno));
  }
  const std::string header =
      "P6\n" + std::to_string(image.width_px) + " " + std::to_string(image.height_px) + "\n255\n";
  bool ok = std::fwrite(header.data(), 1, header.size(), file) == header.size();
  ok = ok && std::fwrite(image.rgb.data(), 1, image.rgb.size(), file) == image.rgb.size();
  ok = (std::fclose(file) == 0) && ok;
  if (!ok) return Error(ErrorCode::kIo, name + ": write failed");
  return Status::Ok();
}

namespace {

void png_append(png_structp png, png_bytep data, png_size_t length) {
  auto* out = static_cast<std::vector<std::uint8_t>*>(png_get_io_ptr(png));
  out->insert(out->end(), data, data + length);
}

void png_no_flush(png_structp) {}

}  // namespace

Result<std::vector<std::uint8_t>> encode_png(const ImageRgb8& image) {
  if (image.width_px <= 0 || image.height_px <= 0 || image.width_px > kMaxImageSidePx ||
      image.height_px > kMaxImageSidePx ||
      image.rgb.size() != static_cast<std::size_t>(image.width_px) *
                              static_cast<std::size_t>(image.height_px) * 3) {
    return Error(ErrorCode::kInvalidArgument, "cannot encode an inconsistent image as PNG (" +
                                                  std::to_string(image.width_px) + "x" +
                                                  std::to_string(image.height_px) + " px)");
  }
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (png == nullptr) return Error(ErrorCode::kInternal, "libpng: cannot create a writer");
  png_infop info = png_create_info_struct(png);
  std::vector<std::uint8_t> out;
  std::vector<png_bytep> rows(static_cast<std::size_t>(image.height_px));
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, info != nullptr ? &info : nullptr);
    return Error(ErrorCode::kInternal, "libpng: PNG encoding failed");
  }
  png_set_write_fn(png, &out, png_append, png_no_flush);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image.width_px),
               static_cast<png_uint_32>(image.height_px), 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  for (int y = 0; y < image.height_px; ++y) {
    rows[static_cast<std::size_t>(y)] =
        const_cast<png_bytep>(image.rgb.data() + image.pixel_offset(0, y));
  }
  png_set_rows(png, info, rows.data());
  png_write_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

Status save_png(const ImageRgb8& image, const std::filesystem::path& path) {
  auto bytes = encode_png(image);
  if (!bytes.ok()) return bytes.error().with_context(path.string());
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) {
    return Error(ErrorCode::kIo, path.string() + ": cannot open for writing: " +
                                     std::generic_category().message(errno));
  }
  bool ok = std::fwrite(bytes->data(), 1, bytes->size(), file) == bytes->size();
  ok = (std::fclose(file) == 0) && ok;
  if (!ok) return Error(ErrorCode::kIo, path.string() + ": write failed");
  return Status::Ok();
}

Result<std::vector<std::uint8_t>> encode_jpeg(const ImageRgb8& image, int quality) {
  if (image.width_px <= 0 || image.height_px <= 0 || image.width_px > kMaxImageSidePx ||
      image.height_px > kMaxImageSidePx ||
      image.rgb.size() != static_cast<std::size_t>(image.width_px) *
                              static_cast<std::size_t>(image.height_px) * 3) {
    return Error(ErrorCode::kInvalidArgument, "encode_jpeg: inconsistent image " +
                                                  std::to_string(image.width_px) + "x" +
                                                  std::to_string(image.height_px) + " with " +
                                                  std::to_string(image.rgb.size()) + " bytes");
  }
  if (quality < 1 || quality > 100) {
    return Error(ErrorCode::kInvalidArgument,
                 "encode_jpeg: quality " + std::to_string(quality) + " is outside [1, 100]");
  }
  const TjHandle tj(tjInitCompress());
  if (!tj) return Error(ErrorCode::kIo, "encode_jpeg: cannot start libturbojpeg");
  unsigned char* out = nullptr;
  unsigned long size = 0;
  if (tjCompress2(tj.get(), image.rgb.data(), image.width_px, 0, image.height_px, TJPF_RGB, &out,
                  &size, TJSAMP_420, quality, TJFLAG_FASTDCT) != 0) {
    const std::string why = tjGetErrorStr2(tj.get());
    tjFree(out);
    return Error(ErrorCode::kIo, "encode_jpeg: " + why);
  }
  std::vector<std::uint8_t> bytes(out, out + size);
  tjFree(out);
  return bytes;
}

}  // namespace mocap::image

// runtime/image: JPEG/PNG decoding to RGB8. Fixtures are encoded here with libpng and
// TurboJPEG into a temporary directory; the real photos (tools/fetch_test_photos.sh) are
// checked when present under <source>/.cache/photos.
#include "runtime/image/image.h"
#include "tests/support/data.h"
#include "tests/support/temp_dir.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <png.h>
#include <turbojpeg.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

namespace mocap::image {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using Bytes = std::vector<std::uint8_t>;

Bytes read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

// A PNG to encode: `samples` holds width*height*channels values in the PNG's own bit depth
// (palette indices for palette images), row-major.
struct PngSpec {
  int width_px = 0;
  int height_px = 0;
  int color_type = PNG_COLOR_TYPE_RGB;
  int bit_depth = 8;
  std::vector<std::uint16_t> samples{};
  std::vector<png_color> palette{};
  std::vector<png_byte> palette_alpha{};  // tRNS for palette images
  bool interlaced = false;
};

int png_channels(int color_type) {
  switch (color_type) {
    case PNG_COLOR_TYPE_GRAY:
    case PNG_COLOR_TYPE_PALETTE:
      return 1;
    case PNG_COLOR_TYPE_GRAY_ALPHA:
      return 2;
    case PNG_COLOR_TYPE_RGB:
      return 3;
    default:
      return 4;
  }
}

// Encodes with libpng's default error handling (abort on a bug in this test).
void write_png(const fs::path& path, const PngSpec& spec) {
  const int channels = png_channels(spec.color_type);
  ASSERT_EQ(spec.samples.size(),
            static_cast<std::size_t>(spec.width_px * spec.height_px * channels));
  // Rows: one byte per sample below 8 bits (png_set_packing packs them), big-endian at 16.
  const int bytes_per_sample = spec.bit_depth == 16 ? 2 : 1;
  const std::size_t row_bytes =
      static_cast<std::size_t>(spec.width_px * channels * bytes_per_sample);
  Bytes pixels(row_bytes * static_cast<std::size_t>(spec.height_px));
  for (std::size_t i = 0; i < spec.samples.size(); ++i) {
    if (bytes_per_sample == 2) {
      pixels[2 * i] = static_cast<std::uint8_t>(spec.samples[i] >> 8);
      pixels[2 * i + 1] = static_cast<std::uint8_t>(spec.samples[i] & 0xFF);
    } else {
      pixels[i] = static_cast<std::uint8_t>(spec.samples[i]);
    }
  }
  std::vector<png_bytep> rows(static_cast<std::size_t>(spec.height_px));
  for (std::size_t y = 0; y < rows.size(); ++y) rows[y] = pixels.data() + y * row_bytes;

  std::FILE* file = std::fopen(path.c_str(), "wb");
  ASSERT_NE(file, nullptr) << path;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  png_init_io(png, file);
  png_set_IHDR(png, info, static_cast<png_uint_32>(spec.width_px),
               static_cast<png_uint_32>(spec.height_px), spec.bit_depth, spec.color_type,
               spec.interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  if (!spec.palette.empty()) {
    png_set_PLTE(png, info, spec.palette.data(), static_cast<int>(spec.palette.size()));
  }
  if (!spec.palette_alpha.empty()) {
    png_set_tRNS(png, info, spec.palette_alpha.data(), static_cast<int>(spec.palette_alpha.size()),
                 nullptr);
  }
  png_write_info(png, info);
  if (spec.bit_depth < 8) png_set_packing(png);
  png_write_image(png, rows.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  ASSERT_EQ(std::fclose(file), 0);
}

// Encodes packed RGB (3 bytes/pixel) or gray (1 byte/pixel) as a JPEG.
void write_jpeg(const fs::path& path, int width_px, int height_px, const Bytes& pixels, bool gray,
                int quality, int subsampling) {
  tjhandle tj = tjInitCompress();
  ASSERT_NE(tj, nullptr);
  unsigned char* jpeg = nullptr;
  unsigned long jpeg_size = 0;
  const int rc = tjCompress2(tj, pixels.data(), width_px, 0, height_px, gray ? TJPF_GRAY : TJPF_RGB,
                             &jpeg, &jpeg_size, gray ? TJSAMP_GRAY : subsampling, quality, 0);
  ASSERT_EQ(rc, 0) << tjGetErrorStr2(tj);
  write_bytes(path, Bytes(jpeg, jpeg + jpeg_size));
  tjFree(jpeg);
  tjDestroy(tj);
}

// Smooth colour ramps: JPEG reproduces them closely.
Bytes gradient_rgb(int width_px, int height_px) {
  Bytes rgb(static_cast<std::size_t>(width_px * height_px * 3));
  for (int y = 0; y < height_px; ++y) {
    for (int x = 0; x < width_px; ++x) {
      const std::size_t i = static_cast<std::size_t>((y * width_px + x) * 3);
      rgb[i] = static_cast<std::uint8_t>(40 + 160 * x / (width_px - 1));
      rgb[i + 1] = static_cast<std::uint8_t>(200 - 150 * y / (height_px - 1));
      rgb[i + 2] = static_cast<std::uint8_t>(60 + 60 * (x + y) / (width_px + height_px - 2));
    }
  }
  return rgb;
}

// FNV-1a, 64-bit: a fingerprint of decoded pixels.
std::uint64_t fnv1a64(const Bytes& bytes) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const std::uint8_t b : bytes) {
    h ^= b;
    h *= 0x100000001b3ULL;
  }
  return h;
}

struct Diff {
  int max_abs = 0;
  double mean_abs = 0.0;
};

Diff compare(const Bytes& a, const Bytes& b) {
  Diff d;
  if (a.size() != b.size() || a.empty()) return {999, 999.0};
  double sum = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const int e = std::abs(int{a[i]} - int{b[i]});
    d.max_abs = std::max(d.max_abs, e);
    sum += e;
  }
  d.mean_abs = sum / static_cast<double>(a.size());
  return d;
}

class ImageTest : public ::testing::Test {
 protected:
  fs::path file(const std::string& name) const { return dir_ / name; }

  // Writes `spec`, decodes it and returns the image (fails the test on an error).
  ImageRgb8 png_round_trip(const PngSpec& spec, const std::string& name = "fixture.png") {
    write_png(file(name), spec);
    auto img = load_image(file(name));
    EXPECT_TRUE(img.ok()) << (img.ok() ? "" : img.error().to_string());
    if (!img.ok()) return {};
    EXPECT_EQ(img->width_px, spec.width_px);
    EXPECT_EQ(img->height_px, spec.height_px);
    EXPECT_EQ(img->rgb.size(), static_cast<std::size_t>(spec.width_px * spec.height_px * 3));
    return std::move(img).value();
  }

  ::mocap::testing::TestTempDir tmp_{"image_test"};
  const std::filesystem::path dir_ = tmp_.path();
};

TEST_F(ImageTest, SniffsFormatByMagicBytes) {
  EXPECT_EQ(sniff_format(Bytes{0xFF, 0xD8, 0xFF, 0xE0}), ImageFormat::kJpeg);
  EXPECT_EQ(sniff_format(Bytes{0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A}), ImageFormat::kPng);
  EXPECT_EQ(sniff_format(Bytes{0x89, 'P', 'N', 'G'}), ImageFormat::kUnknown);
  EXPECT_EQ(sniff_format(Bytes{0xFF, 0xD8}), ImageFormat::kUnknown);
  EXPECT_EQ(sniff_format(Bytes{}), ImageFormat::kUnknown);
}

TEST_F(ImageTest, PngRgb8IsExact) {
  PngSpec spec{.width_px = 5, .height_px = 3};
  for (int i = 0; i < 5 * 3 * 3; ++i) spec.samples.push_back(static_cast<std::uint16_t>(i * 5 + 7));
  const ImageRgb8 img = png_round_trip(spec);
  ASSERT_EQ(img.rgb.size(), spec.samples.size());
  for (std::size_t i = 0; i < img.rgb.size(); ++i) EXPECT_EQ(img.rgb[i], spec.samples[i]) << i;
  EXPECT_EQ(img.pixel_offset(4, 2), 42u);
}

TEST_F(ImageTest, PngInterlacedIsExact) {
  PngSpec spec{.width_px = 11, .height_px = 9, .interlaced = true};
  for (int i = 0; i < 11 * 9 * 3; ++i) spec.samples.push_back(static_cast<std::uint16_t>(i % 251));
  const ImageRgb8 img = png_round_trip(spec);
  ASSERT_EQ(img.rgb.size(), spec.samples.size());
  for (std::size_t i = 0; i < img.rgb.size(); ++i) EXPECT_EQ(img.rgb[i], spec.samples[i]) << i;
}

TEST_F(ImageTest, PngRgbaDropsAlpha) {
  PngSpec spec{.width_px = 4, .height_px = 2, .color_type = PNG_COLOR_TYPE_RGB_ALPHA};
  for (int p = 0; p < 8; ++p) {
    spec.samples.insert(
        spec.samples.end(),
        {static_cast<std::uint16_t>(10 * p), static_cast<std::uint16_t>(255 - 10 * p),
         static_cast<std::uint16_t>(3 * p), static_cast<std::uint16_t>(p * 30)});  // alpha
  }
  const ImageRgb8 img = png_round_trip(spec);
  ASSERT_EQ(img.rgb.size(), 8u * 3u);
  for (int p = 0; p < 8; ++p) {
    EXPECT_EQ(img.rgb[p * 3 + 0], 10 * p);
    EXPECT_EQ(img.rgb[p * 3 + 1], 255 - 10 * p);
    EXPECT_EQ(img.rgb[p * 3 + 2], 3 * p);
  }
}

TEST_F(ImageTest, PngGrayIsReplicated) {
  PngSpec spec{.width_px = 16, .height_px = 16, .color_type = PNG_COLOR_TYPE_GRAY};
  for (int i = 0; i < 256; ++i) spec.samples.push_back(static_cast<std::uint16_t>(i));
  const ImageRgb8 img = png_round_trip(spec);
  ASSERT_EQ(img.rgb.size(), 256u * 3u);
  for (int i = 0; i < 256; ++i) {
    EXPECT_EQ(img.rgb[i * 3 + 0], i);
    EXPECT_EQ(img.rgb[i * 3 + 1], i);
    EXPECT_EQ(img.rgb[i * 3 + 2], i);
  }
}

TEST_F(ImageTest, PngGrayAlphaIsReplicated) {
  PngSpec spec{.width_px = 3, .height_px = 1, .color_type = PNG_COLOR_TYPE_GRAY_ALPHA};
  spec.samples = {0, 255, 128, 0, 255, 77};
  const ImageRgb8 img = png_round_trip(spec);
  EXPECT_EQ(img.rgb, (Bytes{0, 0, 0, 128, 128, 128, 255, 255, 255}));
}

TEST_F(ImageTest, PngLowBitDepthGrayIsScaled) {
  // 1, 2 and 4 bits per sample expand to the full 0..255 range (v * 255 / (2^bits - 1)).
  for (const int bits : {1, 2, 4}) {
    SCOPED_TRACE("bit depth " + std::to_string(bits));
    const int levels = 1 << bits;
    PngSpec spec{
        .width_px = levels, .height_px = 2, .color_type = PNG_COLOR_TYPE_GRAY, .bit_depth = bits};
    for (int y = 0; y < 2; ++y) {
      for (int v = 0; v < levels; ++v) spec.samples.push_back(static_cast<std::uint16_t>(v));
    }
    const ImageRgb8 img = png_round_trip(spec, "gray" + std::to_string(bits) + ".png");
    ASSERT_EQ(img.rgb.size(), static_cast<std::size_t>(levels * 2 * 3));
    for (int v = 0; v < levels; ++v) {
      const int expected = v * 255 / (levels - 1);
      EXPECT_EQ(img.rgb[v * 3], expected) << v;
      EXPECT_EQ(img.rgb[v * 3 + 2], expected) << v;
    }
  }
}

TEST_F(ImageTest, PngPaletteIsExpandedAndTransparencyIgnored) {
  const std::vector<png_color> palette = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {12, 34, 56}};
  for (const int bits : {2, 8}) {
    for (const bool with_trns : {false, true}) {
      SCOPED_TRACE("bits " + std::to_string(bits) + (with_trns ? " with tRNS" : ""));
      PngSpec spec{.width_px = 4,
                   .height_px = 2,
                   .color_type = PNG_COLOR_TYPE_PALETTE,
                   .bit_depth = bits,
                   .samples = {3, 2, 1, 0, 0, 1, 2, 3},
                   .palette = palette};
      if (with_trns) spec.palette_alpha = {0, 128, 255, 7};
      const ImageRgb8 img = png_round_trip(spec, "palette.png");
      ASSERT_EQ(img.rgb.size(), 8u * 3u);
      for (std::size_t p = 0; p < 8; ++p) {
        const png_color c = palette[spec.samples[p]];
        EXPECT_EQ(img.rgb[p * 3 + 0], c.red) << p;
        EXPECT_EQ(img.rgb[p * 3 + 1], c.green) << p;
        EXPECT_EQ(img.rgb[p * 3 + 2], c.blue) << p;
      }
    }
  }
}

TEST_F(ImageTest, Png16BitIsRoundedTo8Bit) {
  // k * 257 maps exactly to k; other values round to the nearest 8-bit level (within 1).
  PngSpec spec{.width_px = 4, .height_px = 1, .bit_depth = 16};
  spec.samples = {0,    65535, 257 * 100, 257 * 7, 12345, 40000,
                  1000, 65000, 257 * 254, 257 * 1, 32767, 32768};
  const ImageRgb8 img = png_round_trip(spec);
  ASSERT_EQ(img.rgb.size(), 12u);
  for (std::size_t i = 0; i < 12; ++i) {
    const double exact = spec.samples[i] * 255.0 / 65535.0;
    if (spec.samples[i] % 257 == 0) {
      EXPECT_EQ(img.rgb[i], spec.samples[i] / 257) << i;
    } else {
      EXPECT_LE(std::abs(img.rgb[i] - exact), 1.0) << i;
    }
  }
}

TEST_F(ImageTest, Png16BitGrayAlpha) {
  PngSpec spec{
      .width_px = 2, .height_px = 1, .color_type = PNG_COLOR_TYPE_GRAY_ALPHA, .bit_depth = 16};
  spec.samples = {257 * 200, 0, 257 * 3, 65535};
  const ImageRgb8 img = png_round_trip(spec);
  EXPECT_EQ(img.rgb, (Bytes{200, 200, 200, 3, 3, 3}));
}

TEST_F(ImageTest, JpegRgbWithinTolerance) {
  for (const int subsampling : {TJSAMP_444, TJSAMP_420}) {
    SCOPED_TRACE("subsampling " + std::to_string(subsampling));
    const int w = 64;
    const int h = 48;
    const Bytes rgb = gradient_rgb(w, h);
    write_jpeg(file("ramp.jpg"), w, h, rgb, /*gray=*/false, 95, subsampling);
    auto img = load_image(file("ramp.jpg"));
    ASSERT_TRUE(img.ok()) << img.error().to_string();
    EXPECT_EQ(img->width_px, w);
    EXPECT_EQ(img->height_px, h);
    const Diff d = compare(img->rgb, rgb);
    EXPECT_LE(d.max_abs, 8);
    EXPECT_LE(d.mean_abs, 1.5);
  }
}

TEST_F(ImageTest, JpegGrayIsReplicated) {
  const int w = 32;
  const int h = 8;
  Bytes gray(static_cast<std::size_t>(w * h));
  for (int i = 0; i < w * h; ++i) gray[i] = static_cast<std::uint8_t>(30 + (i % w) * 6);
  write_jpeg(file("gray.jpg"), w, h, gray, /*gray=*/true, 95, TJSAMP_GRAY);
  auto img = load_image(file("gray.jpg"));
  ASSERT_TRUE(img.ok()) << img.error().to_string();
  ASSERT_EQ(img->rgb.size(), static_cast<std::size_t>(w * h * 3));
  Bytes red;
  for (std::size_t p = 0; p < gray.size(); ++p) {
    EXPECT_EQ(img->rgb[p * 3], img->rgb[p * 3 + 1]);
    EXPECT_EQ(img->rgb[p * 3], img->rgb[p * 3 + 2]);
    red.push_back(img->rgb[p * 3]);
  }
  EXPECT_LE(compare(red, gray).max_abs, 4);
}

TEST_F(ImageTest, FormatComesFromContentNotExtension) {
  PngSpec spec{.width_px = 2, .height_px = 1, .samples = {1, 2, 3, 4, 5, 6}};
  write_png(file("really_png.jpg"), spec);
  auto png = load_image(file("really_png.jpg"));
  ASSERT_TRUE(png.ok()) << png.error().to_string();
  EXPECT_EQ(png->rgb, (Bytes{1, 2, 3, 4, 5, 6}));

  write_jpeg(file("really_jpeg.png"), 16, 16, gradient_rgb(16, 16), false, 90, TJSAMP_444);
  fs::copy_file(file("really_jpeg.png"), file("no_extension"));
  for (const char* name : {"really_jpeg.png", "no_extension"}) {
    auto jpeg = load_image(file(name));
    ASSERT_TRUE(jpeg.ok()) << jpeg.error().to_string();
    EXPECT_EQ(jpeg->width_px, 16);
    EXPECT_LE(compare(jpeg->rgb, gradient_rgb(16, 16)).max_abs, 12);
  }
}

TEST_F(ImageTest, DecodesFromMemory) {
  PngSpec spec{.width_px = 1, .height_px = 1, .samples = {9, 8, 7}};
  write_png(file("one.png"), spec);
  auto img = decode_image(read_bytes(file("one.png")), "camera 3");
  ASSERT_TRUE(img.ok()) << img.error().to_string();
  EXPECT_EQ(img->rgb, (Bytes{9, 8, 7}));

  auto bad = decode_image(Bytes{1, 2, 3}, "camera 3");
  ASSERT_FALSE(bad.ok());
  EXPECT_THAT(bad.error().message(), HasSubstr("camera 3: "));
}

TEST_F(ImageTest, MissingFileIsNotFound) {
  const fs::path missing = file("does_not_exist.jpg");
  auto img = load_image(missing);
  ASSERT_FALSE(img.ok());
  EXPECT_EQ(img.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(img.error().message(), HasSubstr(missing.string()));
}

TEST_F(ImageTest, DirectoryIsAnError) {
  auto img = load_image(dir_);
  ASSERT_FALSE(img.ok());
  EXPECT_EQ(img.error().code(), ErrorCode::kIo);
  EXPECT_THAT(img.error().message(), HasSubstr("directory"));
}

TEST_F(ImageTest, GarbageIsNotAnImage) {
  write_bytes(file("garbage.png"), Bytes{'h', 'e', 'l', 'l', 'o', 0, 1, 2, 3, 4, 5});
  auto img = load_image(file("garbage.png"));
  ASSERT_FALSE(img.ok());
  EXPECT_EQ(img.error().code(), ErrorCode::kParse);
  EXPECT_THAT(img.error().message(), HasSubstr(file("garbage.png").string()));
  EXPECT_THAT(img.error().message(), HasSubstr("not a JPEG or PNG"));
  EXPECT_THAT(img.error().message(), HasSubstr("68 65 6c 6c"));

  write_bytes(file("empty.jpg"), Bytes{});
  auto empty = load_image(file("empty.jpg"));
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.error().code(), ErrorCode::kParse);
  EXPECT_THAT(empty.error().message(), HasSubstr("empty"));
}

TEST_F(ImageTest, OtherFormatsAreNamed) {
  write_bytes(file("anim.gif"), Bytes{'G', 'I', 'F', '8', '9', 'a', 1, 0, 1, 0});
  auto img = load_image(file("anim.gif"));
  ASSERT_FALSE(img.ok());
  EXPECT_EQ(img.error().code(), ErrorCode::kUnsupported);
  EXPECT_THAT(img.error().message(), HasSubstr("GIF"));
}

TEST_F(ImageTest, MagicBytesFollowedByGarbage) {
  write_bytes(file("fake.jpg"), Bytes{0xFF, 0xD8, 0xFF, 0x00, 0x13, 0x37, 0x42, 0x42});
  auto jpeg = load_image(file("fake.jpg"));
  ASSERT_FALSE(jpeg.ok());
  EXPECT_EQ(jpeg.error().code(), ErrorCode::kParse);
  EXPECT_THAT(jpeg.error().message(), HasSubstr("JPEG"));

  Bytes png = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  for (int i = 0; i < 40; ++i) png.push_back(static_cast<std::uint8_t>(i * 37));
  write_bytes(file("fake.png"), png);
  auto decoded = load_image(file("fake.png"));
  ASSERT_FALSE(decoded.ok());
  EXPECT_EQ(decoded.error().code(), ErrorCode::kParse);
  EXPECT_THAT(decoded.error().message(), HasSubstr("PNG"));
}

TEST_F(ImageTest, TruncatedPngIsAnError) {
  PngSpec spec{.width_px = 64, .height_px = 64};
  for (int i = 0; i < 64 * 64 * 3; ++i) {
    spec.samples.push_back(static_cast<std::uint16_t>((i * 7919) % 256));  // poorly compressible
  }
  write_png(file("full.png"), spec);
  const Bytes full = read_bytes(file("full.png"));
  // Cut inside the header, inside the pixel data, and just before the end (IEND missing).
  for (const std::size_t keep : {std::size_t{20}, full.size() / 2, full.size() - 6}) {
    SCOPED_TRACE("kept " + std::to_string(keep) + " of " + std::to_string(full.size()));
    write_bytes(file("cut.png"), Bytes(full.begin(), full.begin() + static_cast<long>(keep)));
    auto img = load_image(file("cut.png"));
    ASSERT_FALSE(img.ok());
    EXPECT_EQ(img.error().code(), ErrorCode::kParse);
    EXPECT_THAT(img.error().message(), HasSubstr(file("cut.png").string()));
    EXPECT_THAT(img.error().message(), HasSubstr("truncated"));
  }
}

TEST_F(ImageTest, CorruptPngDataIsAnError) {
  PngSpec spec{.width_px = 32, .height_px = 32};
  for (int i = 0; i < 32 * 32 * 3; ++i) spec.samples.push_back(static_cast<std::uint16_t>(i % 199));
  write_png(file("ok.png"), spec);
  Bytes bytes = read_bytes(file("ok.png"));
  bytes[bytes.size() / 2] ^= 0x5A;  // inside IDAT: the chunk CRC no longer matches
  write_bytes(file("corrupt.png"), bytes);
  auto img = load_image(file("corrupt.png"));
  ASSERT_FALSE(img.ok());
  EXPECT_EQ(img.error().code(), ErrorCode::kParse);
  EXPECT_THAT(img.error().message(), HasSubstr("corrupt"));
}

TEST_F(ImageTest, TruncatedJpegIsAnError) {
  write_jpeg(file("full.jpg"), 64, 64, gradient_rgb(64, 64), false, 95, TJSAMP_420);
  const Bytes full = read_bytes(file("full.jpg"));
  for (const std::size_t keep : {std::size_t{100}, full.size() / 2, full.size() - 2}) {
    SCOPED_TRACE("kept " + std::to_string(keep) + " of " + std::to_string(full.size()));
    write_bytes(file("cut.jpg"), Bytes(full.begin(), full.begin() + static_cast<long>(keep)));
    auto img = load_image(file("cut.jpg"));
    ASSERT_FALSE(img.ok());
    EXPECT_EQ(img.error().code(), ErrorCode::kParse);
    EXPECT_THAT(img.error().message(), HasSubstr(file("cut.jpg").string()));
  }
}

TEST_F(ImageTest, TooLargeIsRejected) {
  PngSpec wide{.width_px = kMaxImageSidePx + 1, .height_px = 1, .color_type = PNG_COLOR_TYPE_GRAY};
  wide.samples.assign(static_cast<std::size_t>(kMaxImageSidePx + 1), 0);
  write_png(file("wide.png"), wide);
  auto png = load_image(file("wide.png"));
  ASSERT_FALSE(png.ok());
  EXPECT_EQ(png.error().code(), ErrorCode::kUnsupported);
  EXPECT_THAT(png.error().message(), HasSubstr("16385x1 px"));

  const Bytes tall(static_cast<std::size_t>(kMaxImageSidePx + 1) * 8, 128);
  write_jpeg(file("tall.jpg"), 8, kMaxImageSidePx + 1, tall, true, 75, TJSAMP_GRAY);
  auto jpeg = load_image(file("tall.jpg"));
  ASSERT_FALSE(jpeg.ok());
  EXPECT_EQ(jpeg.error().code(), ErrorCode::kUnsupported);
  EXPECT_THAT(jpeg.error().message(), HasSubstr("8x16385 px"));

  // The limit itself is accepted.
  PngSpec edge{.width_px = kMaxImageSidePx, .height_px = 1, .color_type = PNG_COLOR_TYPE_GRAY};
  edge.samples.assign(static_cast<std::size_t>(kMaxImageSidePx), 5);
  const ImageRgb8 img = png_round_trip(edge, "edge.png");
  EXPECT_EQ(img.width_px, kMaxImageSidePx);
}

TEST_F(ImageTest, SavePpmWritesP6) {
  ImageRgb8 img{.width_px = 2, .height_px = 1, .rgb = {1, 2, 3, 250, 251, 252}};
  ASSERT_TRUE(save_ppm(img, file("out.ppm")).ok());
  const Bytes bytes = read_bytes(file("out.ppm"));
  const std::string header = "P6\n2 1\n255\n";
  ASSERT_EQ(bytes.size(), header.size() + 6);
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + static_cast<long>(header.size())), header);
  EXPECT_EQ(Bytes(bytes.end() - 6, bytes.end()), img.rgb);

  img.rgb.pop_back();
  const Status bad = save_ppm(img, file("bad.ppm"));
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.error().code(), ErrorCode::kInvalidArgument);

  img.rgb.push_back(0);
  const Status nowhere = save_ppm(img, file("no/such/dir/out.ppm"));
  ASSERT_FALSE(nowhere.ok());
  EXPECT_EQ(nowhere.error().code(), ErrorCode::kIo);
}

// Real photos from Debian's opencv-doc (tools/fetch_test_photos.sh). Skipped when absent,
// except in CI (CI=true), where setup.sh fetches them.
fs::path photo_path(const std::string& name, bool* present) {
  const fs::path path = fs::path(MOCAP_SOURCE_DIR) / ".cache" / "photos" / name;
  *present = fs::exists(path);
  return path;
}

#define MOCAP_REQUIRE_PHOTO(path_var, name)                                                    \
  bool present_##path_var = false;                                                             \
  const fs::path path_var = photo_path(name, &present_##path_var);                             \
  if (!present_##path_var) {                                                                   \
    const std::string why = path_var.string() + " not found (run tools/fetch_test_photos.sh)"; \
    MOCAP_SKIP_OR_FAIL_IN_CI(why);                                                             \
  }

TEST(ImagePhotos, Messi5Jpeg) {
  MOCAP_REQUIRE_PHOTO(path, "messi5.jpg");
  auto img = load_image(path);
  ASSERT_TRUE(img.ok()) << img.error().to_string();
  EXPECT_EQ(img->width_px, 548);
  EXPECT_EQ(img->height_px, 342);
  ASSERT_EQ(img->rgb.size(), 548u * 342u * 3u);
  // A colour photo: channels differ somewhere, and the mean is mid-range.
  double sum = 0.0;
  bool colour = false;
  for (std::size_t p = 0; p < img->rgb.size(); p += 3) {
    sum += img->rgb[p] + img->rgb[p + 1] + img->rgb[p + 2];
    colour = colour || img->rgb[p] != img->rgb[p + 1] || img->rgb[p + 1] != img->rgb[p + 2];
  }
  EXPECT_TRUE(colour);
  const double mean = sum / static_cast<double>(img->rgb.size());
  EXPECT_GT(mean, 40.0);
  EXPECT_LT(mean, 215.0);
  // Same pixels as `djpeg -ppm` (libjpeg-turbo 2.1.5); the accurate integer IDCT is bit-exact
  // across libjpeg-turbo versions and SIMD paths.
  EXPECT_EQ(fnv1a64(img->rgb), 0x295c90f7c5062445ULL);
}

TEST(ImagePhotos, BasketballGrayPngs) {
  for (const char* name : {"basketball1.png", "basketball2.png"}) {
    SCOPED_TRACE(name);
    MOCAP_REQUIRE_PHOTO(path, name);
    auto img = load_image(path);
    ASSERT_TRUE(img.ok()) << img.error().to_string();
    EXPECT_EQ(img->width_px, 640);
    EXPECT_EQ(img->height_px, 480);
    ASSERT_EQ(img->rgb.size(), 640u * 480u * 3u);
    std::size_t not_gray = 0;
    int lo = 255;
    int hi = 0;
    for (std::size_t p = 0; p < img->rgb.size(); p += 3) {
      not_gray += (img->rgb[p] != img->rgb[p + 1] || img->rgb[p] != img->rgb[p + 2]) ? 1 : 0;
      lo = std::min<int>(lo, img->rgb[p]);
      hi = std::max<int>(hi, img->rgb[p]);
    }
    EXPECT_EQ(not_gray, 0u);  // 8-bit gray PNGs: R = G = B
    EXPECT_GT(hi - lo, 100);  // real contrast, not a blank frame
    if (std::string(name) == "basketball1.png") {
      // Same pixels as an independent PNG-to-PPM conversion of the file.
      EXPECT_EQ(fnv1a64(img->rgb), 0x549204b42bfb9563ULL);
    }
  }
}

}  // namespace
}  // namespace mocap::image

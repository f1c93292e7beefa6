// mocap calibrate print-board --board FILE|SPEC --out board.png|board.pdf [--dpi 300]
// The board to print, to scale: a PDF page the size of the board (print at 100 %, "actual
// size") or a PNG at --dpi; its description in the margin below it.
#include <zlib.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "runtime/boardcal/board_detect.h"
#include "runtime/core/text_scan.h"
#include "runtime/image/image.h"
#include "tools/common/cli.h"
#include "tools/mocap/commands.h"

namespace mocap::tools {
namespace {

constexpr double kMetresPerInch = 0.0254;

// A one-page PDF: the grey image as a Flate-compressed image XObject filling a page of
// width_px x height_px at `dpi` (points = pixels * 72 / dpi).
Result<std::string> pdf_page(const boardcal::BoardImage& img, int dpi) {
  uLongf packed_size = compressBound(static_cast<uLong>(img.gray.size()));
  std::string packed(packed_size, '\0');
  if (compress2(reinterpret_cast<Bytef*>(packed.data()), &packed_size, img.gray.data(),
                static_cast<uLong>(img.gray.size()), 9) != Z_OK) {
    return Error(ErrorCode::kInternal, "zlib could not compress the board image");
  }
  packed.resize(packed_size);
  const double w_pt = img.width_px * 72.0 / dpi;
  const double h_pt = img.height_px * 72.0 / dpi;
  char buf[256];
  std::array<std::string, 5> objects;
  objects[0] = "<< /Type /Catalog /Pages 2 0 R >>";
  objects[1] = "<< /Type /Pages /Kids [3 0 R] /Count 1 >>";
  std::snprintf(buf, sizeof buf,
                "<< /Type /Page /Parent 2 0 R /MediaBox [0 0 %.3f %.3f] /Resources << /XObject "
                "<< /Im0 4 0 R >> >> /Contents 5 0 R >>",
                w_pt, h_pt);
  objects[2] = buf;
  std::snprintf(buf, sizeof buf,
                "<< /Type /XObject /Subtype /Image /Width %d /Height %d /ColorSpace /DeviceGray "
                "/BitsPerComponent 8 /Filter /FlateDecode /Length %zu >>\nstream\n",
                img.width_px, img.height_px, packed.size());
  objects[3] = std::string(buf) + packed + "\nendstream";
  std::snprintf(buf, sizeof buf, "q %.3f 0 0 %.3f 0 0 cm /Im0 Do Q", w_pt, h_pt);
  const std::string content = buf;
  objects[4] =
      "<< /Length " + std::to_string(content.size()) + " >>\nstream\n" + content + "\nendstream";
  std::string pdf = "%PDF-1.4\n";
  std::array<std::size_t, 5> offsets{};
  for (std::size_t i = 0; i < objects.size(); ++i) {
    offsets[i] = pdf.size();
    pdf += std::to_string(i + 1) + " 0 obj\n" + objects[i] + "\nendobj\n";
  }
  const std::size_t xref = pdf.size();
  pdf += "xref\n0 " + std::to_string(objects.size() + 1) + "\n0000000000 65535 f \n";
  for (std::size_t off : offsets) {
    std::snprintf(buf, sizeof buf, "%010zu 00000 n \n", off);
    pdf += buf;
  }
  pdf += "trailer\n<< /Size " + std::to_string(objects.size() + 1) +
         " /Root 1 0 R >>\nstartxref\n" + std::to_string(xref) + "\n%%EOF\n";
  return pdf;
}

}  // namespace

int run_print_board(Args args) {
  std::string board_arg, out;
  int dpi = 300;
  cli::ArgParser p("mocap calibrate print-board",
                   "The board as an image to print, to scale (a PDF page the board's size: print "
                   "at 100 %, then measure one square), its description in the margin.");
  p.option("--board", &board_arg, "FILE|SPEC", "the board: a board.json or a SPEC (required)");
  p.option("--out", &out, "FILE", "board.png or board.pdf (required)");
  p.option("--dpi", &dpi, "N", "dots per inch (default 300)");
  if (int rc = cli::handle_parse(p, args); rc >= 0) return rc;
  if (board_arg.empty() || out.empty()) {
    return cli::fail(Error(ErrorCode::kInvalidArgument, "--board and --out are required"));
  }
  const bool pdf = out.size() > 4 && out.substr(out.size() - 4) == ".pdf";
  const bool png = out.size() > 4 && out.substr(out.size() - 4) == ".png";
  if (!pdf && !png) {
    return cli::fail(
        Error(ErrorCode::kInvalidArgument, "--out " + out + ": give a .pdf or a .png"));
  }
  if (dpi < 72 || dpi > 2400) {
    return cli::fail(Error(ErrorCode::kInvalidArgument, "--dpi must be 72 to 2400"));
  }
  auto board = boardcal::board_from_argument(board_arg);
  if (!board.ok()) return cli::fail(board.error());
  const int px_per_square = static_cast<int>(std::lround(board->square_m / kMetresPerInch * dpi));
  char caption[256];
  std::snprintf(caption, sizeof caption, "%s  square %.1f mm: print at 100 %%, measure it",
                board->to_spec().c_str(), board->square_m * 1000);
  auto img = boardcal::render_board(*board, px_per_square, px_per_square / 2, caption);
  if (!img.ok()) return cli::fail(img.error());
  Status written = Status::Ok();
  if (pdf) {
    auto bytes = pdf_page(*img, dpi);
    if (!bytes.ok()) return cli::fail(bytes.error());
    written = write_text_file(out, *bytes);
  } else {
    image::ImageRgb8 rgb;
    rgb.width_px = img->width_px;
    rgb.height_px = img->height_px;
    rgb.rgb.reserve(img->gray.size() * 3);
    for (std::uint8_t g : img->gray) rgb.rgb.insert(rgb.rgb.end(), 3, g);
    written = image::save_png(rgb, out);
  }
  if (!written.ok()) return cli::fail(written.error());
  std::printf("%s: %s, %dx%d px at %d dpi (%.1f x %.1f cm); square %.1f mm\n", out.c_str(),
              board->to_spec().c_str(), img->width_px, img->height_px, dpi,
              img->width_px * 2.54 / dpi, img->height_px * 2.54 / dpi, board->square_m * 1000);
  return 0;
}

}  // namespace mocap::tools

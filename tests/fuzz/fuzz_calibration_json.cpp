// libFuzzer target: parse_calibration_json() (runtime/geometry/calibration.h) on arbitrary
// bytes must give a Calibration or an Error, never crash, hang, leak or throw (ASan/UBSan are
// on in the fuzz build). The same parser checks the stage calibration a fusion node sends over
// DDS. A parsed calibration must write (calibration_to_json) and parse back to the same views
// (not bit for bit: loading re-orthonormalises each rotation).
// Seeds: tests/fuzz/corpus/calibration_json/.
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "runtime/geometry/calibration.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  mocap::Result<mocap::Calibration> r = mocap::parse_calibration_json(text, "fuzz.json");
  if (!r.ok()) {
    if (r.error().message().empty()) std::abort();
    return 0;
  }
  if (r->cameras.empty() || r->cameras.size() != r->view_ids.size()) std::abort();
  mocap::Result<std::string> written = mocap::calibration_to_json(*r);
  if (!written.ok()) std::abort();
  mocap::Result<mocap::Calibration> again = mocap::parse_calibration_json(*written, "again.json");
  if (!again.ok() || again->view_ids != r->view_ids) std::abort();
  return 0;
}

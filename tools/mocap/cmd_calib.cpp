// Placeholder replaced by the geometry work (calibration loader) — see runtime/geometry.
#include "tools/mocap/commands.h"

#include <cstdio>

namespace mocap::tools {

int run_calib(Args) {
  std::fputs("mocap calib: calibration loader not built yet\n", stderr);
  return 2;
}

}  // namespace mocap::tools

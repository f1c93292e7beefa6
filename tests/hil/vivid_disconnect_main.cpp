// hil_vivid_disconnect NODE: unplugs the vivid camera NODE (its "Disconnect" control), the way
// tests/hil/guest.sh pulls a camera out from under a running mocapd. Exit 0 when pressed.
#include <cstdio>

#include "tests/hil/vivid.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: hil_vivid_disconnect /dev/videoN (a vivid capture node)\n");
    return 2;
  }
  if (!mocap::hil::vivid_disconnect(argv[1])) {
    std::fprintf(stderr,
                 "hil_vivid_disconnect: %s: cannot open it, or it has no Disconnect "
                 "control (not a vivid node)\n",
                 argv[1]);
    return 1;
  }
  return 0;
}

// vivid's test controls, for the HIL guest (hil_guest_test and the hil_vivid_disconnect tool
// that tests/hil/guest.sh runs under mocapd).
#pragma once

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <string>

namespace mocap::hil {

// Presses vivid's "Disconnect" button control on `node`: the instance then behaves like an
// unplugged USB camera (every ioctl fails with ENODEV, streaming stops) until its last file
// handle is closed, when it comes back by itself. False when the node cannot be opened or has
// no such control (not a vivid node).
inline bool vivid_disconnect(const std::string& node) {
  const int fd = ::open(node.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0) return false;
  bool pressed = false;
  v4l2_queryctrl q{};
  q.id = V4L2_CTRL_FLAG_NEXT_CTRL;
  while (::ioctl(fd, VIDIOC_QUERYCTRL, &q) == 0) {
    if (std::string(reinterpret_cast<const char*>(q.name)) == "Disconnect") {
      v4l2_control c{};
      c.id = q.id;
      c.value = 1;
      pressed = ::ioctl(fd, VIDIOC_S_CTRL, &c) == 0;
      break;
    }
    q.id |= V4L2_CTRL_FLAG_NEXT_CTRL;
  }
  ::close(fd);
  return pressed;
}

}  // namespace mocap::hil

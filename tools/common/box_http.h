// A small HTTP/1.1 client for a mocapd's HTTP port (`mocap take`, `mocap soak`): one request
// per connection, the whole answer read until the server closes it (5 s limit per read).
#pragma once

#include <string>

#include "runtime/core/error.h"

namespace mocap::tools {

struct HttpAnswer {
  int status = 0;
  std::string body;
};

// `method` `target` to mocapd at `box` ("HOST[:PORT]", port 9871 by default), with the access
// token in X-Mocap-Token when not empty. Errors name the box and what to check.
Result<HttpAnswer> box_request(const std::string& box, const std::string& method,
                               const std::string& target, const std::string& token = {});

}  // namespace mocap::tools

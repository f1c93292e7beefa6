// The box's web page (tools/web/page, docs/web.md): its files and three.js, served by mocapd
// from <prefix>/share/mocap-box/web on an installed box, else from the source tree
// (tools/web/page and the pinned npm three in tools/web/node_modules). Only the files listed
// here are served: a URL never becomes a path.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "runtime/net/http.h"

namespace mocap::daemon {

struct WebAsset {
  std::string_view url;        // "/", "/app.js", "/vendor/three.module.js"
  std::string_view installed;  // under share/mocap-box/web
  std::string_view source;     // under the source tree
  std::string_view content_type;
};

// Where the page's files are; an installed box's first.
class WebAssets {
 public:
  WebAssets();
  // The reply for a GET of an asset URL (the file streamed); nullopt for other URLs. A missing
  // file (three.js not installed) is a 404 naming the fix.
  std::optional<net::HttpReply> reply(std::string_view url) const;
  // The file behind `url` (tests); empty when the URL is not an asset.
  std::filesystem::path file(std::string_view url) const;

 private:
  std::filesystem::path installed_root_;  // empty when not installed
};

}  // namespace mocap::daemon

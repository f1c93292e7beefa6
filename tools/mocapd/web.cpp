#include "tools/mocapd/web.h"

#include <array>

#include "runtime/core/log.h"
#include "tools/common/paths.h"

#ifndef MOCAP_SOURCE_DIR
#error "MOCAP_SOURCE_DIR must be defined by the build"
#endif

MOCAP_LOG_CATEGORY(Web)

namespace mocap::daemon {

namespace {

namespace fs = std::filesystem;

constexpr std::string_view kHtml = "text/html; charset=utf-8";
constexpr std::string_view kJs = "text/javascript; charset=utf-8";

constexpr std::array<WebAsset, 7> kAssets = {{
    {"/", "index.html", "tools/web/page/index.html", kHtml},
    {"/index.html", "index.html", "tools/web/page/index.html", kHtml},
    {"/app.js", "app.js", "tools/web/page/app.js", kJs},
    {"/style.css", "style.css", "tools/web/page/style.css", "text/css; charset=utf-8"},
    {"/vendor/three.module.js", "vendor/three.module.js",
     "tools/web/node_modules/three/build/three.module.js", kJs},
    {"/vendor/three.core.js", "vendor/three.core.js",
     "tools/web/node_modules/three/build/three.core.js", kJs},
    {"/vendor/OrbitControls.js", "vendor/OrbitControls.js",
     "tools/web/node_modules/three/examples/jsm/controls/OrbitControls.js", kJs},
}};

// The page's policy: its own files only, the import map in index.html by its hash (the
// browser test loads the page under it and fails on any violation; tests/web/check_csp_hash.py
// fails when index.html's import map changes without this hash).
constexpr std::string_view kPagePolicy =
    "default-src 'none'; script-src 'self' 'sha256-u72gRBPQdtAASr3BdV68nUiVv+3hmu0OFXPGwl6WEZw='; "
    "style-src 'self'; img-src 'self' data: blob:; connect-src 'self'; base-uri 'none'; "
    "form-action 'none'; frame-ancestors 'none'";

const WebAsset* find_asset(std::string_view url) {
  for (const WebAsset& a : kAssets) {
    if (a.url == url) return &a;
  }
  return nullptr;
}

}  // namespace

WebAssets::WebAssets() {
  const fs::path web = tools::share_path("web");
  std::error_code ec;
  if (fs::exists(web / "index.html", ec) && web != fs::path(MOCAP_SOURCE_DIR) / "web") {
    installed_root_ = web;
  }
}

fs::path WebAssets::file(std::string_view url) const {
  const WebAsset* a = find_asset(url);
  if (a == nullptr) return {};
  if (!installed_root_.empty()) return installed_root_ / a->installed;
  return fs::path(MOCAP_SOURCE_DIR) / a->source;
}

std::optional<net::HttpReply> WebAssets::reply(std::string_view url) const {
  const WebAsset* a = find_asset(url);
  if (a == nullptr) return std::nullopt;
  const fs::path path = file(url);
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) {
    net::HttpReply r;
    r.status = 404;
    r.content_type = "text/plain; charset=utf-8";
    // The path stays in the journal: a stranger learns nothing of the box's folders.
    MOCAP_LOG(Web, Warn) << "the page's file " << path.string()
                         << " is missing (tools/setup.sh installs the page and three.js)";
    r.body = std::string(url) +
             " is missing on this box (the page's files and three.js are installed by "
             "tools/setup.sh; the journal names the file)\n";
    return r;
  }
  net::HttpReply r;
  r.headers.emplace_back("Content-Security-Policy", std::string(kPagePolicy));
  r.content_type = std::string(a->content_type);
  r.file = path.string();
  return r;
}

}  // namespace mocap::daemon

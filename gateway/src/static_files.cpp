#include "safestate/gateway/static_files.hpp"

#include <array>
#include <filesystem>
#include <system_error>

namespace safestate::gateway {

namespace fs = std::filesystem;

namespace {

int hex_digit(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool has_dot_dot_segment(std::string_view p) noexcept {
  std::size_t start = 0;
  while (start <= p.size()) {
    std::size_t end = p.find_first_of("/\\", start);
    if (end == std::string_view::npos) {
      end = p.size();
    }
    if (p.substr(start, end - start) == "..") {
      return true;
    }
    start = end + 1;
  }
  return false;
}

bool inside(const fs::path& root, const fs::path& file) {
  auto r = root.begin();
  auto f = file.begin();
  for (; r != root.end(); ++r, ++f) {
    if (f == file.end() || *r != *f) {
      return false;
    }
  }
  return true;
}

struct Mime {
  const char* ext;
  const char* type;
};
constexpr std::array<Mime, 16> kMimes{{
    {".html", "text/html; charset=utf-8"},
    {".htm", "text/html; charset=utf-8"},
    {".js", "text/javascript; charset=utf-8"},
    {".mjs", "text/javascript; charset=utf-8"},
    {".css", "text/css; charset=utf-8"},
    {".svg", "image/svg+xml"},
    {".png", "image/png"},
    {".jpg", "image/jpeg"},
    {".ico", "image/x-icon"},
    {".json", "application/json"},
    {".map", "application/json"},
    {".woff2", "font/woff2"},
    {".woff", "font/woff"},
    {".wasm", "application/wasm"},
    {".txt", "text/plain; charset=utf-8"},
    {".glb", "model/gltf-binary"},
}};

}  // namespace

bool percent_decode(std::string_view in, std::string& out, bool plus_is_space) {
  out.clear();
  out.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    const char c = in[i];
    if (c == '%') {
      if (i + 2 >= in.size()) {
        return false;
      }
      const int hi = hex_digit(in[i + 1]);
      const int lo = hex_digit(in[i + 2]);
      if (hi < 0 || lo < 0) {
        return false;
      }
      out += static_cast<char>(hi * 16 + lo);
      i += 2;
    } else if (c == '+' && plus_is_space) {
      out += ' ';
    } else {
      out += c;
    }
  }
  return true;
}

StaticLookup resolve_static(const std::string& root, std::string_view path, std::string& file) {
  std::string decoded;
  if (path.empty() || path.front() != '/' || !percent_decode(path, decoded, false) ||
      decoded.find('\0') != std::string::npos || has_dot_dot_segment(path) || has_dot_dot_segment(decoded)) {
    return StaticLookup::bad_path;
  }
  if (root.empty()) {
    return StaticLookup::not_found;
  }
  if (decoded.back() == '/') {
    decoded += "index.html";
  }
  std::error_code ec;
  const fs::path base = fs::canonical(root, ec);
  if (ec) {
    return StaticLookup::not_found;
  }
  const fs::path target = fs::weakly_canonical(base / fs::path(decoded).relative_path(), ec);
  if (ec) {
    return StaticLookup::not_found;
  }
  if (!inside(base, target)) {
    return StaticLookup::bad_path;
  }
  if (!fs::is_regular_file(target, ec)) {
    return StaticLookup::not_found;
  }
  file = target.string();
  return StaticLookup::found;
}

const char* mime_type(std::string_view file) {
  const std::size_t dot = file.rfind('.');
  if (dot != std::string_view::npos && file.find('/', dot) == std::string_view::npos) {
    const std::string_view ext = file.substr(dot);
    for (const Mime& m : kMimes) {
      if (ext == m.ext) {
        return m.type;
      }
    }
  }
  return "application/octet-stream";
}

bool hmi_built(const std::string& root) {
  std::error_code ec;
  return !root.empty() && fs::is_regular_file(fs::path(root) / "index.html", ec);
}

std::string builtin_index_html(const std::string& version) {
  return "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>SafeState</title>\n"
         "<style>body{font-family:sans-serif;max-width:40em;margin:3em auto;line-height:1.5}"
         "code{background:#eee;padding:0 .2em}</style></head><body>\n"
         "<h1>SafeState " +
         version +
         "</h1>\n"
         "<p>The operator HMI is not built (no <code>index.html</code> in the static folder).</p>\n"
         "<ul>\n"
         "<li><a href=\"/api/status\">/api/status</a>: the latest status snapshot</li>\n"
         "<li><a href=\"/api/alarms\">/api/alarms</a>: active alarms</li>\n"
         "<li><a href=\"/api/events\">/api/events</a>: the event history</li>\n"
         "<li><a href=\"/api/robot\">/api/robot</a>: the arm model</li>\n"
         "<li><a href=\"/metrics\">/metrics</a>: Prometheus metrics</li>\n"
         "<li><code>/ws</code>: the WebSocket of the client protocol</li>\n"
         "</ul>\n</body></html>\n";
}

}  // namespace safestate::gateway

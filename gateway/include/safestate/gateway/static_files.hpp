// GET / and the HMI's static files (protocol.md "Endpoints").
#pragma once

#include <string>
#include <string_view>

namespace safestate::gateway {

enum class StaticLookup { found, not_found, bad_path };

// Maps a request path ("/", "/assets/app.js", percent-encoded) to a regular file under
// `root`: "/" and paths ending in "/" mean index.html; a `..` segment (also encoded), a
// NUL, or a path that leaves `root` through a symbolic link is bad_path.
StaticLookup resolve_static(const std::string& root, std::string_view path, std::string& file);
// Content-Type by extension (.html .js .mjs .css .svg .png .json .woff2 ...).
const char* mime_type(std::string_view file);
// True when `root` holds an index.html (the HMI is built).
bool hmi_built(const std::string& root);
// The page served at / when the HMI is not built.
std::string builtin_index_html(const std::string& version);
// %XX decoding; false on a malformed escape.
bool percent_decode(std::string_view in, std::string& out, bool plus_is_space);

}  // namespace safestate::gateway

// The visual meshes of a robot description, read from its own package folder only
// (robot/include/safestate/robot/meshes.hpp says which files and why).
#include "safestate/robot/meshes.hpp"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <system_error>

namespace safestate::robot {
namespace {

namespace fs = std::filesystem;

// `inner` (canonical) lies inside `root` (canonical): root's components are a prefix of its.
bool inside(const fs::path& root, const fs::path& inner) {
  auto r = root.begin();
  auto i = inner.begin();
  for (; r != root.end(); ++r, ++i) {
    if (i == inner.end() || *r != *i) return false;
  }
  return i != inner.end();  // strictly below the folder, never the folder itself
}

std::string lower_ext(const fs::path& p) {
  std::string e = p.extension().string();
  if (!e.empty() && e.front() == '.') e.erase(0, 1);
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

struct Target {
  fs::path root;  // canonical
  fs::path file;  // as written, below or beside root
};

// Where a filename points, or the reason it points nowhere servable.
std::optional<Target> target_of(const std::string& uri, const fs::path& urdf_dir, std::string& why) {
  constexpr std::string_view kPackage = "package://";
  constexpr std::string_view kFile = "file://";
  if (uri.rfind(kPackage, 0) == 0) {
    const std::string rest = uri.substr(kPackage.size());
    const std::size_t slash = rest.find('/');
    if (slash == std::string::npos || slash == 0U || slash + 1U == rest.size()) {
      why = "not package://NAME/PATH";
      return std::nullopt;
    }
    const std::string name = rest.substr(0, slash);
    for (fs::path a = urdf_dir; !a.empty(); a = a.parent_path()) {
      if (a.filename() == name) return Target{a, a / rest.substr(slash + 1U)};
      if (a == a.parent_path()) break;
    }
    why = "package " + name + " is not a folder holding the description";
    return std::nullopt;
  }
  if (uri.rfind(kFile, 0) == 0) return Target{urdf_dir, fs::path(uri.substr(kFile.size()))};
  if (uri.find("://") != std::string::npos) {
    why = "unsupported scheme (package:// and file:// are read)";
    return std::nullopt;
  }
  if (uri.empty()) {
    why = "empty filename";
    return std::nullopt;
  }
  return Target{urdf_dir, urdf_dir / uri};
}

}  // namespace

Meshes read_visual_meshes(const Robot& r) {
  Meshes out;
  const std::vector<std::string> uris = visual_mesh_uris(r);
  std::error_code ec;
  const fs::path urdf_dir = (r.d.source == "built-in") ? fs::path() : fs::canonical(fs::path(r.d.source), ec).parent_path();
  std::size_t total = 0;
  for (const std::string& uri : uris) {
    const auto refuse = [&](const std::string& why) { out.refused.push_back({uri, why}); };
    if (urdf_dir.empty() || ec) {
      refuse("the description is not a file: no package folder to read meshes from");
      continue;
    }
    if (out.files.size() >= kMaxMeshes) {
      refuse("more than " + std::to_string(kMaxMeshes) + " meshes");
      continue;
    }
    std::string why;
    const std::optional<Target> t = target_of(uri, urdf_dir, why);
    if (!t) {
      refuse(why);
      continue;
    }
    std::error_code fe;
    const fs::path root = fs::canonical(t->root, fe);
    const fs::path file = fe ? fs::path() : fs::canonical(t->file, fe);
    if (fe) {
      refuse("not found");
      continue;
    }
    if (!inside(root, file)) {
      refuse("outside the description's package folder " + root.string());
      continue;
    }
    const std::string ext = lower_ext(file);
    if (ext != "stl" && ext != "dae" && ext != "obj") {
      refuse("not a mesh the HMI reads (.stl, .dae, .obj)");
      continue;
    }
    if (!fs::is_regular_file(file, fe) || fe) {
      refuse("not a regular file");
      continue;
    }
    const std::uintmax_t size = fs::file_size(file, fe);
    if (fe || size > kMaxMeshBytes || total + size > kMaxMeshTotalBytes) {
      refuse(fe ? "size unreadable" : "too large (at most 64 MiB each, 256 MiB together)");
      continue;
    }
    std::ifstream in(file, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (!in.good() && !in.eof()) {
      refuse("cannot be read");
      continue;
    }
    if (bytes.size() > kMaxMeshBytes || total + bytes.size() > kMaxMeshTotalBytes) {  // grew meanwhile
      refuse("too large (at most 64 MiB each, 256 MiB together)");
      continue;
    }
    total += bytes.size();
    out.files.push_back({uri, ext, std::move(bytes)});
  }
  return out;
}

}  // namespace safestate::robot

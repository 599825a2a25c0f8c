// The visual meshes of a robot description (issue 38 item 6), for the HMI's 3D view: the
// files the URDF's <visual><geometry><mesh filename=...> name, read once at start-up, and
// only from the description's own package folder. The gateway serves them read-only at
// /api/robot/meshes/N.EXT; a mesh that is not served leaves the HMI drawing simple shapes.
//
// Where a filename points (docs/robot.md "Meshes in the HMI"):
//   package://NAME/PATH  the folder named NAME that holds the URDF file (the nearest such
//                        ancestor of the file's folder), then PATH below it;
//   file:///PATH, PATH   the URDF file's own folder (PATH relative to it, or absolute).
// Served only when the file, all symbolic links resolved, lies inside that folder, is a
// regular file of at most kMaxMeshBytes with the extension .stl, .dae or .obj (any case),
// and all meshes together stay within kMaxMeshTotalBytes. Anything else is refused with the
// reason; nothing outside the folder is read.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "safestate/robot/description.hpp"

namespace safestate::robot {

inline constexpr std::size_t kMaxMeshBytes = 64U << 20U;
inline constexpr std::size_t kMaxMeshTotalBytes = 256U << 20U;
inline constexpr std::size_t kMaxMeshes = 256;

struct MeshFile {
  std::string uri;    // the filename as the URDF writes it
  std::string ext;    // "stl", "dae" or "obj"
  std::string bytes;  // the file's content
};

struct MeshRefusal {
  std::string uri;
  std::string why;
};

struct Meshes {
  std::vector<MeshFile> files;  // in the order of visual_mesh_uris()
  std::vector<MeshRefusal> refused;
};

// The distinct mesh filenames of the description's <visual> elements, by link name (a built-in
// description or one that does not parse: none).
std::vector<std::string> visual_mesh_uris(const Robot& r);

// Resolves and reads them as above. A description that is not a file ("built-in") has no
// folder: every mesh is refused.
Meshes read_visual_meshes(const Robot& r);

}  // namespace safestate::robot

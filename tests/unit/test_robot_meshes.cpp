// Issue 38 item 6: the visual meshes the gateway serves to the HMI come only from the
// description's own package folder (robot/include/safestate/robot/meshes.hpp): a package://
// or relative filename inside it is read; one that leaves it (.., a symbolic link, another
// package), is not a mesh, or is missing is refused with the reason, and nothing is read.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "safestate/robot/description.hpp"
#include "safestate/robot/meshes.hpp"

namespace fs = std::filesystem;
using namespace safestate;

namespace {

void write(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary) << text;
}

// The built-in IRB 120 with one visual per listed filename on link_1 .. link_6 and tool0.
std::string with_visuals(const std::vector<std::string>& files) {
  std::string u = robot::builtin_urdf();
  const char* links[] = {"link_1", "link_2", "link_3", "link_4", "link_5", "link_6"};
  for (std::size_t i = 0; i < files.size() && i < 6; ++i) {
    const std::string tag = std::string("<link name=\"") + links[i] + "\">";
    const std::size_t at = u.find(tag);
    EXPECT_NE(at, std::string::npos) << tag;
    u.insert(at + tag.size(), "<visual><geometry><mesh filename=\"" + files[i] + "\" scale=\"0.001 0.001 0.001\"/></geometry></visual>");
  }
  return u;
}

struct Tmp {
  fs::path dir = fs::temp_directory_path() / ("ss-meshes-" + std::to_string(::getpid()));
  Tmp() { fs::remove_all(dir); }
  ~Tmp() { fs::remove_all(dir); }
};

std::unique_ptr<robot::Robot> load(const fs::path& urdf_file, const std::string& text) {
  write(urdf_file, text);
  std::string error;
  auto r = robot::load_file(urdf_file.string(), "", "", error);
  EXPECT_TRUE(r) << error;
  return r;
}

const robot::MeshRefusal* refusal(const robot::Meshes& m, const std::string& uri) {
  for (const auto& r : m.refused) {
    if (r.uri == uri) return &r;
  }
  return nullptr;
}

}  // namespace

TEST(RobotMeshes, InsideThePackageFolderServedOutsideRefused) {
  Tmp t;
  const fs::path pkg = t.dir / "my_arm_description";
  write(pkg / "meshes" / "a.stl", "solid a\nendsolid a\n");
  write(pkg / "meshes" / "b.DAE", "<COLLADA/>");
  write(pkg / "urdf" / "c.obj", "o c\n");
  write(pkg / "meshes" / "notes.txt", "not a mesh");
  write(t.dir / "secret.stl", "solid secret\nendsolid secret\n");
  write(t.dir / "other_pkg" / "meshes" / "x.stl", "solid x\nendsolid x\n");
  fs::create_symlink(t.dir / "secret.stl", pkg / "meshes" / "link.stl");
  const std::vector<std::string> files = {
      "package://my_arm_description/meshes/a.stl",       // served
      "package://my_arm_description/meshes/b.DAE",       // served (extension in any case)
      "c.obj",                                           // relative to the URDF's folder: served
      "package://my_arm_description/../secret.stl",      // .. out of the folder
      "package://my_arm_description/meshes/link.stl",    // a symbolic link out of it
      "package://other_pkg/meshes/x.stl",                // not the description's package
  };
  auto r = load(pkg / "urdf" / "arm.urdf", with_visuals(files));
  ASSERT_TRUE(r);
  const robot::Meshes m = robot::read_visual_meshes(*r);
  std::vector<std::string> served;
  for (const auto& f : m.files) served.push_back(f.uri);
  EXPECT_EQ(served.size(), 3U);
  for (const std::string& f : {files[0], files[1], files[2]}) {
    EXPECT_NE(std::find(served.begin(), served.end(), f), served.end()) << f;
  }
  for (const auto& f : m.files) {
    if (f.uri == files[0]) {
      EXPECT_EQ(f.ext, "stl");
      EXPECT_EQ(f.bytes, "solid a\nendsolid a\n");
    }
    if (f.uri == files[1]) {
      EXPECT_EQ(f.ext, "dae");
    }
    if (f.uri == files[2]) {
      EXPECT_EQ(f.ext, "obj");
    }
  }
  ASSERT_NE(refusal(m, files[3]), nullptr);
  EXPECT_NE(refusal(m, files[3])->why.find("outside the description's package folder"), std::string::npos);
  ASSERT_NE(refusal(m, files[4]), nullptr);
  EXPECT_NE(refusal(m, files[4])->why.find("outside"), std::string::npos);
  ASSERT_NE(refusal(m, files[5]), nullptr);
  EXPECT_NE(refusal(m, files[5])->why.find("package other_pkg is not a folder holding the description"), std::string::npos);
  EXPECT_EQ(m.refused.size(), 3U);
}

TEST(RobotMeshes, WrongKindMissingAndSchemesRefused) {
  Tmp t;
  const fs::path pkg = t.dir / "p";
  write(pkg / "meshes" / "notes.txt", "not a mesh");
  fs::create_directories(pkg / "meshes" / "dir.stl");
  const std::vector<std::string> files = {
      "package://p/meshes/notes.txt", "package://p/meshes/none.stl", "package://p/meshes/dir.stl",
      "http://example.com/a.stl", "package://p", "../meshes/notes.txt",
  };
  auto r = load(pkg / "urdf" / "arm.urdf", with_visuals(files));
  ASSERT_TRUE(r);
  const robot::Meshes m = robot::read_visual_meshes(*r);
  EXPECT_TRUE(m.files.empty());
  ASSERT_EQ(m.refused.size(), files.size());
  EXPECT_NE(refusal(m, files[0])->why.find("not a mesh"), std::string::npos);
  EXPECT_EQ(refusal(m, files[1])->why, "not found");
  EXPECT_EQ(refusal(m, files[2])->why, "not a regular file");
  EXPECT_NE(refusal(m, files[3])->why.find("unsupported scheme"), std::string::npos);
  EXPECT_EQ(refusal(m, files[4])->why, "not package://NAME/PATH");
  EXPECT_NE(refusal(m, files[5])->why.find("outside"), std::string::npos);  // relative: the URDF's own folder
}

TEST(RobotMeshes, BuiltInHasNoneAndAStringDescriptionHasNoFolder) {
  EXPECT_TRUE(robot::read_visual_meshes(robot::active()).files.empty());
  EXPECT_TRUE(robot::read_visual_meshes(robot::active()).refused.empty());
  std::string error;
  auto r = robot::load_text(with_visuals({"package://p/meshes/a.stl"}), "built-in", "", "", error);
  ASSERT_TRUE(r) << error;
  const robot::Meshes m = robot::read_visual_meshes(*r);
  EXPECT_TRUE(m.files.empty());
  ASSERT_EQ(m.refused.size(), 1U);
  EXPECT_NE(m.refused[0].why.find("not a file"), std::string::npos);
}

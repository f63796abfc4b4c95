// examples/read_scene.cpp — read a scene file with scene.h, the reader of
// bvh.out (README.txt, THE LIBRARY IN TEN LINES). Run from the project's folder: it reads
// inputs/gen_1000.disks and checks the count against the file's lines, then
// reads a broken copy and checks the "FILE:LINE: what is wrong" message.
// Exit status 1 if either differs.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h>
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  // [readme:read]
  std::vector<Disk> disks;  std::string error;
  if (!bvh_scene::load_scene("inputs/gen_1000.disks", disks, error))
    std::cerr << error << "\n";          // "FILE:LINE: what is wrong"
  // [end]
  std::ifstream in("inputs/gen_1000.disks");
  std::size_t lines = 0;
  std::string line;
  while (std::getline(in, line))
    ++lines;
  // The same scene with a negative radius on line 3.
  const std::string broken =
      (std::filesystem::temp_directory_path() /
       ("bvh_read_scene_" + std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()) + ".disks"))
          .string();
  {
    std::ofstream out(broken);
    out << "pt= <1 2> radius= 3 color= {1 2 3}\n\npt= <4 5> radius= -1 color= {0 0 0}\n";
  }
  std::vector<Disk> none;
  std::string message;
  const bool read_broken = bvh_scene::load_scene(broken, none, message);
  std::remove(broken.c_str());
  std::cout << "read_scene: " << disks.size() << " disks of " << lines << " lines; broken file: " << message << "\n";
  const bool ok = error.empty() && disks.size() == lines && lines == 1000 && !read_broken &&
                  message == broken + ":3: negative radius";
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}

// extras_test.cpp — the homework's extra credit, on the stand-in framework:
// the alternative build rule (set_build_rule(BVH<T>::BuildRule::sah)) and
// erase(iterator), each checked against a model: a vector of the shapes
// in iteration order, and a brute-force scan with the framework's own
// intersect(). A bvh.h without the extra credit does not compile this;
// tests/course_framework.sh then skips it with a notice. Run under valgrind
// too.
//
//   ./extras_test.out SCENE.disks SCENE.triangles SCENE.quads
#include "utils.h"
#include "shapes.h"
#include "bvh.h"

#include "scene_io.h"

#include <algorithm>
#include <iostream>
#include <string>
#include <tuple>
#include <vector>

static int checks = 0, failures = 0;
#define CHECK(cond)                                                                                                   \
  do {                                                                                                                \
    ++checks;                                                                                                         \
    if (!(cond)) {                                                                                                    \
      ++failures;                                                                                                     \
      std::cout << "FAIL " << __FILE__ << ":" << __LINE__ << ": " #cond << " [" << label << "]\n";                  \
    }                                                                                                                 \
  } while (0)

using Key = std::tuple<double, double, double, double, double, double>;
template <class T> Key key_of(const T &s) {
  return Key(s.getCenter().x, s.getCenter().y, s.getBox().getMin().x, s.getBox().getMin().y, s.getBox().getMax().x,
             s.getBox().getMax().y);
}
template <class T> std::vector<Key> order_of(const BVH<T> &t) {
  std::vector<Key> k;
  for (typename BVH<T>::iterator it = t.begin(); it != t.end(); ++it) k.push_back(key_of(*it));
  return k;
}
template <class T> std::vector<Key> sorted_keys(const std::vector<T> &v) {
  std::vector<Key> k;
  for (const T &s : v) k.push_back(key_of(s));
  std::sort(k.begin(), k.end());
  return k;
}
// collision() against a scan of the stored shapes with the framework's
// intersect(stored, probe), for every probe: the number of disagreements.
template <class T> int collision_errors(const BVH<T> &tree, const std::vector<T> &probes) {
  std::vector<T> stored;
  for (typename BVH<T>::iterator it = tree.begin(); it != tree.end(); ++it) stored.push_back(*it);
  int errors = 0;
  for (const T &p : probes) {
    bool hit = false;
    for (const T &s : stored) hit = hit || intersect(s, p);
    errors += tree.collision(p) != hit;
  }
  return errors;
}

template <class T> void exercise(const std::string &scene, const std::vector<T> &shapes) {
  const std::vector<T> half(shapes.begin(), shapes.begin() + long(shapes.size() / 2));
  const std::vector<T> probes(shapes.begin() + long(shapes.size() / 2), shapes.end());
  for (int sah = 0; sah < 2; ++sah)
    for (int incremental = 0; incremental < 2; ++incremental)
      for (int depth_limit : {0, 4}) {
        const std::string label = scene + (sah ? " sah" : " course") + (incremental ? " insert" : " bulk") +
                                  " depth_limit " + std::to_string(depth_limit);
        BVH<T> tree(3, depth_limit);
        if (sah) tree.set_build_rule(BVH<T>::BuildRule::sah);
        if (incremental)
          for (const T &s : half) tree.insert(s);
        else
          tree.construct(half);
        std::vector<Key> order = order_of(tree);
        std::vector<Key> sorted = order;
        std::sort(sorted.begin(), sorted.end());
        CHECK(sorted == sorted_keys(half)); // every shape exactly once
        CHECK(tree.size() == half.size());
        CHECK(collision_errors(tree, probes) == 0);
        // Erase every other shape while iterating: each shape is visited
        // once and the rest keep their order.
        std::vector<Key> kept;
        std::size_t visited = 0;
        bool odd = false;
        for (typename BVH<T>::iterator it = tree.begin(); it != tree.end(); ++visited) {
          if ((odd = !odd)) {
            it = tree.erase(it);
          } else {
            kept.push_back(key_of(*it));
            ++it;
          }
        }
        CHECK(visited == half.size());
        CHECK(order_of(tree) == kept);
        CHECK(tree.size() == kept.size());
        CHECK(collision_errors(tree, probes) == 0);
        // A copy after erases is deep and equal; then erase from both ends.
        BVH<T> copy(tree);
        CHECK(order_of(copy) == kept);
        while (!tree.empty()) {
          typename BVH<T>::iterator last = tree.end();
          --last;
          CHECK(tree.erase(last) == tree.end());
          if (!tree.empty()) tree.erase(tree.begin());
        }
        CHECK(tree.begin() == tree.end() && tree.size() == 0);
        CHECK(collision_errors(copy, probes) == 0);
        CHECK(order_of(copy) == kept);
      }
}

int main(int argc, char *argv[]) {
  if (argc != 4) scene_io::fail(argv[0], "usage: extras_test.out A.disks B.triangles C.quads");
  exercise("disks", scene_io::load<Disk>(argv[1]));
  exercise("triangles", scene_io::load<Triangle>(argv[2]));
  exercise("quads", scene_io::load<Quad>(argv[3]));
  std::cout << checks << " checks, " << failures << " failed\n";
  return failures == 0 ? 0 : 1;
}

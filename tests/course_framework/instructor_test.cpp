// instructor_test.cpp — what the course's own tests exercise besides
// main.cpp, on the stand-in framework: pre/post ++ and -- in both
// directions, copy construction, assignment (self-assignment too),
// destruction and empty trees: only what the course requires of every
// bvh.h (the extra credit's erase and SAH rule: extras_test.cpp). Run under
// valgrind by tests/course_framework.sh.
// The course's shapes have no operator==, so shapes are compared by their
// centre and box.
//
//   ./instructor_test.out SCENE.disks SCENE.triangles SCENE.quads
#include "utils.h"
#include "shapes.h"
#include "bvh.h"

#include "scene_io.h"

#include <algorithm>
#include <iostream>
#include <sstream>
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
template <class T> std::vector<Key> keys(const std::vector<T> &v) {
  std::vector<Key> k;
  for (const T &s : v) k.push_back(key_of(s));
  return k;
}
template <class T> std::vector<Key> forward_post(const BVH<T> &t) {
  std::vector<Key> k;
  for (typename BVH<T>::iterator it = t.begin(); it != t.end(); it++) k.push_back(key_of(*it));
  return k;
}
template <class T> std::vector<Key> forward_pre(const BVH<T> &t) {
  std::vector<Key> k;
  for (typename BVH<T>::iterator it = t.begin(); it != t.end(); ++it) k.push_back(key_of(*it));
  return k;
}
// From end() down to begin(), with pre-decrement; reversed to forward order.
template <class T> std::vector<Key> backward_pre(const BVH<T> &t) {
  std::vector<Key> k;
  typename BVH<T>::iterator it = t.end();
  while (it != t.begin()) {
    --it;
    k.push_back(key_of(*it));
  }
  std::reverse(k.begin(), k.end());
  return k;
}
// The same with post-decrement, checking that it returns the old position.
template <class T> std::vector<Key> backward_post(const BVH<T> &t, bool &returns_old) {
  std::vector<Key> k;
  returns_old = true;
  typename BVH<T>::iterator it = t.end();
  while (it != t.begin()) {
    typename BVH<T>::iterator before = it;
    typename BVH<T>::iterator old = it--;
    if (old != before) returns_old = false;
    k.push_back(key_of(*it));
  }
  std::reverse(k.begin(), k.end());
  return k;
}
template <class T> std::vector<std::string> colours(const BVH<T> &t) {
  std::vector<std::string> c;
  for (typename BVH<T>::iterator it = t.begin(); it != t.end(); it++) c.push_back((*it).getColor().getHexString());
  return c;
}

template <class T> void exercise(const std::string &label, const std::vector<T> &shapes) {
  // Empty trees.
  {
    BVH<T> empty(4, 0);
    CHECK(empty.begin() == empty.end());
    BVH<T> copy(empty);
    CHECK(copy.begin() == copy.end());
    BVH<T> assigned(2, 3);
    assigned.insert(shapes[0]);
    assigned = empty;
    CHECK(assigned.begin() == assigned.end());
    std::ostringstream picture;
    empty.render_recolor(picture);
    CHECK(picture.str().empty());
  }
  // One shape: ++ reaches end(), -- from end() comes back.
  {
    BVH<T> one(4, 0);
    one.insert(shapes[0]);
    typename BVH<T>::iterator it = one.begin();
    CHECK(key_of(*it) == key_of(shapes[0]));
    typename BVH<T>::iterator old = it++;
    CHECK(it == one.end());
    CHECK(old == one.begin());
    --it;
    CHECK(it == one.begin());
  }
  const std::vector<Key> input = keys(shapes);
  std::vector<Key> sorted_input = input;
  std::sort(sorted_input.begin(), sorted_input.end());
  for (int incremental = 0; incremental < 2; ++incremental) {
    for (int depth_limit : {0, 3}) {
      BVH<T> *tree = new BVH<T>(4, depth_limit);
      if (incremental)
        for (const T &s : shapes) tree->insert(s);
      else
        tree->construct(shapes);
      const std::vector<Key> order = forward_post(*tree);
      std::vector<Key> sorted_order = order;
      std::sort(sorted_order.begin(), sorted_order.end());
      CHECK(sorted_order == sorted_input); // every shape exactly once
      CHECK(forward_pre(*tree) == order);
      CHECK(backward_pre(*tree) == order);
      bool returns_old = false;
      CHECK(backward_post(*tree, returns_old) == order);
      CHECK(returns_old);
      // Post-increment returns the old position.
      typename BVH<T>::iterator it = tree->begin(), old = it++;
      CHECK(old == tree->begin() && (shapes.size() == 1 || it != old));

      // A copy is deep: recolouring the original leaves the copy's colours.
      BVH<T> copy(*tree);
      const std::vector<std::string> before = colours(*tree);
      std::ostringstream picture;
      tree->render_recolor(picture);
      CHECK(!picture.str().empty());
      CHECK(colours(copy) == before);
      CHECK(colours(*tree) != before);
      CHECK(forward_post(copy) == order);

      // Assignment over a non-empty tree, then self-assignment.
      BVH<T> assigned(2, 5);
      for (std::size_t i = 0; i < shapes.size() && i < 10; ++i) assigned.insert(shapes[i]);
      assigned = copy;
      CHECK(forward_post(assigned) == order);
      BVH<T> &alias = assigned;
      assigned = alias;
      CHECK(forward_post(assigned) == order);
      CHECK(colours(assigned) == before);

      // The original goes first: the copies must not share its memory.
      delete tree;
      CHECK(forward_post(copy) == order);
      CHECK(backward_pre(assigned) == order);
    }
  }
}

int main(int argc, char *argv[]) {
  if (argc != 4) scene_io::fail(argv[0], "usage: instructor_test.out A.disks B.triangles C.quads");
  exercise("disks", scene_io::load<Disk>(argv[1]));
  exercise("triangles", scene_io::load<Triangle>(argv[2]));
  exercise("quads", scene_io::load<Quad>(argv[3]));
  std::cout << checks << " checks, " << failures << " failed\n";
  return failures == 0 ? 0 : 1;
}

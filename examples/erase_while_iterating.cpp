// examples/erase_while_iterating.cpp — erase every shape a test picks while
// walking the tree (README.txt, EXTRA CREDIT: ERASE). The rest must be the
// same shapes in the same order as the vector filtered by the same test,
// and the tree must stay valid (exit status 1 if not).
#include <iostream>
#include <iterator>
#include <vector>

#include <bvh/bvh.h>
#include <bvh/scene.h> // bvh_scene::Random: the same numbers on every compiler
using namespace bvh; // the library's names (Disk, BVH, intersect, ...), unqualified

int main() {
  bvh_scene::Random rng(11);
  std::vector<Quad> quads;
  for (int i = 0; i < 3000; ++i) {
    const Point c(rng.uniform(10, 990), rng.uniform(10, 990));
    quads.push_back(Quad(Point(c.x - 3, c.y - 3), Point(c.x + 3, c.y - 3), Point(c.x + 3, c.y + 3),
                         Point(c.x - 3, c.y + 3), Color(rng.channel(), 0, 0)));
  }
  BVH<Quad> tree;
  tree.construct(quads);
  const std::vector<Quad> before(tree.begin(), tree.end());
  auto doomed = [](const Quad &q) { return q.getColor().r % 3 == 0; };
  // [readme:erase]
  for (auto it = tree.begin(); it != tree.end();)   // erase while iterating
    it = doomed(*it) ? tree.erase(it) : std::next(it);
  // [end]
  std::vector<Quad> expected;
  for (const Quad &q : before)
    if (!doomed(q)) expected.push_back(q);
  const std::vector<Quad> after(tree.begin(), tree.end());
  std::cout << "erase_while_iterating: " << before.size() << " -> " << after.size() << " (expected "
            << expected.size() << "), same order: " << (after == expected) << ", validate " << tree.validate()
            << "\n";
  const bool ok = after == expected && tree.validate() && after.size() < before.size() && !after.empty();
  std::cout << (ok ? "ok" : "MISMATCH") << "\n";
  return ok ? 0 : 1;
}

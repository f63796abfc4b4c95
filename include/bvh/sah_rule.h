// bvh/sah_rule.h — SahRule: the binned surface area heuristic.
//
// Centres binned into kSahBins slots per axis; the cut of least sum of
// (area x count). Falls back to the course's cut when the centres fill
// too few bins. Includes build_items.h and count_cut.h.
#ifndef BVH_SAH_RULE_H
#define BVH_SAH_RULE_H

#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

#include "build_items.h"
#include "count_cut.h"

namespace bvh {
namespace detail {

/// Bins per axis of the SAH build.
constexpr int kSahBins = 16;

/// The alternative build rule, binned SAH for a ternary tree. Leaves are
/// where the course's rule makes them. Otherwise the shapes' centres are
/// binned into kSahBins slots along each axis, and the node is cut at the
/// two bin boundaries, on the axis, that minimise the surface area
/// heuristic sum over the 3 groups of (box area x shape count), the
/// quantity the statistics print; every group must be non-empty. When the
/// centres fill fewer than 3 bins on both axes (clusters, duplicates), it
/// falls back to the course's cut into thirds by count on the longer side.
/// O(n) per level plus O(kSahBins^2) per node: O(n log n) for a balanced
/// result. At widths other than 3 the node is cut by binary SAH cuts: the
/// largest group that would still split is cut in two where the binned
/// cost is least, until there are W groups or none would split.
template <class T, class Tr, int W> class SahRule : public ShapesAsItems<T, Tr> {
public:
  using State = typename ShapesAsItems<T, Tr>::State;
  SahRule(const Tr &traits, std::vector<Tagged<T>> &shapes, CountCut<W> counts)
      : ShapesAsItems<T, Tr>(traits, shapes), counts_(counts) {}
  void cut(const BuildTask<State> &t, int depth, const Box &box, std::size_t cut[W + 1], State *) {
    if constexpr (W == 3) {
      cut_in_three(t, box, cut);
    } else {
      // At the depth limit's last level the children are leaves of any size.
      const bool last = counts_.depth_limit > 0 && depth + 1 >= counts_.depth_limit;
      const std::size_t most = last ? 1 : counts_.split_threshold;
      std::size_t bounds[W + 1] = {t.begin, t.end};
      int groups = 1;
      while (groups < W) {
        int widest = 0;
        for (int g = 1; g < groups; ++g)
          if (bounds[g + 1] - bounds[g] > bounds[widest + 1] - bounds[widest]) widest = g;
        if (bounds[widest + 1] - bounds[widest] <= most) break;
        const std::size_t mid = cut_in_two(bounds[widest], bounds[widest + 1]);
        for (int g = groups; g > widest; --g) bounds[g + 1] = bounds[g];
        bounds[widest + 1] = mid;
        ++groups;
      }
      for (int g = 0; g <= W; ++g) cut[g] = g <= groups ? bounds[g] : t.end;
    }
  }

private:
  CountCut<W> counts_;
  /// Cuts [begin, end) (at least 2 shapes) in two non-empty parts by the
  /// binned SAH over both axes, or at the median of the longer side of the
  /// centres when no bin boundary separates them; returns where.
  std::size_t cut_in_two(std::size_t begin, std::size_t end) {
    std::vector<Tagged<T>> &v = this->v_;
    const Box centres = centres_of(begin, end);
    double best_cost = std::numeric_limits<double>::infinity();
    int best_axis = -1, best_i = 0;
    for (int axis = 0; axis < 2; ++axis) {
      double lo, extent;
      if (!span(centres, axis, lo, extent)) continue;
      Box bin_box[kSahBins];
      std::size_t bin_count[kSahBins] = {};
      fill_bins(begin, end, axis, lo, extent, bin_box, bin_count);
      Box suffix[kSahBins + 1];
      std::size_t suffix_n[kSahBins + 1] = {};
      for (int b = kSahBins - 1; b >= 0; --b) {
        suffix[b] = suffix[b + 1];
        suffix[b].extend(bin_box[b]);
        suffix_n[b] = suffix_n[b + 1] + bin_count[b];
      }
      Box prefix;
      std::size_t prefix_n = 0;
      for (int i = 1; i < kSahBins; ++i) {
        prefix.extend(bin_box[i - 1]);
        prefix_n += bin_count[i - 1];
        if (prefix_n == 0 || suffix_n[i] == 0) continue;
        const double cost = prefix.area() * double(prefix_n) + suffix[i].area() * double(suffix_n[i]);
        if (cost < best_cost) {
          best_cost = cost;
          best_axis = axis;
          best_i = i;
        }
      }
    }
    const auto first = v.begin() + long(begin), last = v.begin() + long(end);
    if (best_axis >= 0) {
      double lo, extent;
      span(centres, best_axis, lo, extent);
      const auto mid =
          std::partition(first, last, [&](const Tagged<T> &s) { return bin_of(s, best_axis, lo, extent) < best_i; });
      return std::size_t(mid - v.begin());
    }
    const std::size_t mid = begin + (end - begin + 1) / 2;
    std::nth_element(first, v.begin() + long(mid), last, centre_less(centres.dx() >= centres.dy() ? 0 : 1));
    return mid;
  }
  /// The ternary cut (W = 3).
  void cut_in_three(const BuildTask<State> &t, const Box &box, std::size_t cut[4]) {
    std::vector<Tagged<T>> &v = this->v_; // (a dependent base: named through this)
    const Box centres = centres_of(t.begin, t.end);
    int best_axis = -1, best_i = 0, best_j = 0;
    best_cut(t, centres, best_axis, best_i, best_j);
    const auto first = v.begin() + long(t.begin), last = v.begin() + long(t.end);
    if (best_axis >= 0) {
      double lo, extent;
      span(centres, best_axis, lo, extent);
      const auto mid1 =
          std::partition(first, last, [&](const Tagged<T> &s) { return bin_of(s, best_axis, lo, extent) < best_i; });
      const auto mid2 =
          std::partition(mid1, last, [&](const Tagged<T> &s) { return bin_of(s, best_axis, lo, extent) < best_j; });
      cut[0] = t.begin;
      cut[1] = std::size_t(mid1 - v.begin());
      cut[2] = std::size_t(mid2 - v.begin());
      cut[3] = t.end;
    } else {
      // Fallback: thirds by count along the longer side of the box.
      const auto less = centre_less(box.dx() >= box.dy() ? 0 : 1);
      cut_in_thirds(t.begin, t.end, cut);
      std::nth_element(first, v.begin() + long(cut[1]), last, less);
      std::nth_element(v.begin() + long(cut[1]), v.begin() + long(cut[2]), last, less);
    }
  }

  /// The (axis, first cut, second cut) of least SAH cost over both axes:
  /// groups are bins [0, i), [i, j), [j, kSahBins); axis -1 when no cut
  /// leaves every group non-empty.
  void best_cut(const BuildTask<State> &t, const Box &centres, int &best_axis, int &best_i, int &best_j) const {
    double best_cost = std::numeric_limits<double>::infinity();
    for (int axis = 0; axis < 2; ++axis) {
      double lo, extent;
      if (!span(centres, axis, lo, extent)) continue;
      Box bin_box[kSahBins];
      std::size_t bin_count[kSahBins] = {};
      fill_bins(t.begin, t.end, axis, lo, extent, bin_box, bin_count);
      Box prefix[kSahBins + 1], suffix[kSahBins + 1];
      std::size_t prefix_n[kSahBins + 1] = {}, suffix_n[kSahBins + 1] = {};
      for (int b = 0; b < kSahBins; ++b) {
        prefix[b + 1] = prefix[b];
        prefix[b + 1].extend(bin_box[b]);
        prefix_n[b + 1] = prefix_n[b] + bin_count[b];
      }
      for (int b = kSahBins - 1; b >= 0; --b) {
        suffix[b] = suffix[b + 1];
        suffix[b].extend(bin_box[b]);
        suffix_n[b] = suffix_n[b + 1] + bin_count[b];
      }
      for (int i = 1; i < kSahBins - 1; ++i) {
        if (prefix_n[i] == 0) continue;
        Box middle;
        std::size_t middle_n = 0;
        for (int j = i + 1; j < kSahBins; ++j) {
          middle.extend(bin_box[j - 1]);
          middle_n += bin_count[j - 1];
          if (middle_n == 0 || suffix_n[j] == 0) continue;
          const double cost = prefix[i].area() * double(prefix_n[i]) + middle.area() * double(middle_n) +
                              suffix[j].area() * double(suffix_n[j]);
          if (cost < best_cost) {
            best_cost = cost;
            best_axis = axis;
            best_i = i;
            best_j = j;
          }
        }
      }
    }
  }
  /// The box of the centres of shapes [begin, end).
  Box centres_of(std::size_t begin, std::size_t end) const {
    Box centres;
    for (std::size_t i = begin; i < end; ++i) centres.extend(Box::at(this->traits_.center(this->v_[i].shape)));
    return centres;
  }
  /// The centres' range on `axis` (its low end and extent); false when it
  /// is empty (every centre on one line across the axis).
  static bool span(const Box &centres, int axis, double &lo, double &extent) {
    lo = axis ? centres.y0 : centres.x0;
    extent = (axis ? centres.y1 : centres.x1) - lo;
    return extent > 0;
  }
  /// Bins shapes [begin, end) by centre on `axis`: each bin's box and count.
  void fill_bins(std::size_t begin, std::size_t end, int axis, double lo, double extent, Box bin_box[kSahBins],
                 std::size_t bin_count[kSahBins]) const {
    for (std::size_t i = begin; i < end; ++i) {
      const int b = bin_of(this->v_[i], axis, lo, extent);
      bin_box[b].extend(box_of(this->traits_, this->v_[i].shape));
      ++bin_count[b];
    }
  }
  /// The order of shapes by centre on `axis` (the fallback cut's).
  auto centre_less(int axis) const {
    const Tr &traits = this->traits_;
    return [axis, &traits](const Tagged<T> &a, const Tagged<T> &b) {
      return axis ? traits.center(a.shape).y < traits.center(b.shape).y
                  : traits.center(a.shape).x < traits.center(b.shape).x;
    };
  }
  int bin_of(const Tagged<T> &s, int axis, double lo, double extent) const {
    const double c = axis ? this->traits_.center(s.shape).y : this->traits_.center(s.shape).x;
    return std::min(kSahBins - 1, int(double(kSahBins) * (c - lo) / extent));
  }
};
} // namespace detail
} // namespace bvh

#endif // BVH_SAH_RULE_H

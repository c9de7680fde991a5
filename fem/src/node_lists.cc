// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "node_lists.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace spidarcad::fem::detail {

NodeListIndex IndexNodeLists(const std::string& who, const std::string& subset_name, int num_nodes,
                             const std::vector<int>& outputs, const std::vector<int>& subset) {
  NodeListIndex out;
  out.output_index.assign(num_nodes, -1);
  for (std::size_t a = 0; a < outputs.size(); ++a) {
    const int v = outputs[a];
    if (v < 0 || v >= num_nodes) {
      throw std::invalid_argument(who + ": output node " + std::to_string(v) +
                                  " is out of range [0, " + std::to_string(num_nodes) + ")");
    }
    if (out.output_index[v] >= 0) {
      throw std::invalid_argument(who + ": output node " + std::to_string(v) + " is listed twice");
    }
    out.output_index[v] = static_cast<int>(a);
  }
  out.subset_index.assign(num_nodes, -1);
  out.subset_row.reserve(subset.size());
  for (std::size_t b = 0; b < subset.size(); ++b) {
    const int v = subset[b];
    if (v < 0 || v >= num_nodes || out.output_index[v] < 0) {
      throw std::invalid_argument(who + ": " + subset_name + " node " + std::to_string(v) +
                                  " is not one of the output nodes");
    }
    if (out.subset_index[v] >= 0) {
      throw std::invalid_argument(who + ": " + subset_name + " node " + std::to_string(v) +
                                  " is listed twice");
    }
    out.subset_index[v] = static_cast<int>(b);
    out.subset_row.push_back(out.output_index[v]);
  }
  return out;
}

std::vector<int> NearestAllowed(const std::vector<Eigen::Vector3d>& points,
                                const std::vector<char>& allowed, int k) {
  const int n = static_cast<int>(points.size());
  std::vector<int> out(static_cast<std::size_t>(n) * std::max(k, 0), -1);
  if (k <= 0 || n == 0) return out;
  // A grid over all the points (so that each lies in its cell) holding the allowed ones, about
  // one per cell: cells of side h across the axes the set spans (a surface: two, a curve: one).
  std::vector<int> members;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(INFINITY), hi = -lo;
  for (int c = 0; c < n; ++c) {
    if (allowed[c]) members.push_back(c);
    lo = lo.cwiseMin(points[c]);
    hi = hi.cwiseMax(points[c]);
  }
  const int total = static_cast<int>(members.size());
  if (total == 0) return out;
  const Eigen::Vector3d extent = hi - lo;
  double e[3] = {extent[0], extent[1], extent[2]};
  std::sort(e, e + 3, [](double a, double b) { return a > b; });
  double h = std::cbrt(e[0] * e[1] * e[2] / total);
  if (!(e[2] >= h)) h = std::sqrt(e[0] * e[1] / total);
  if (!(e[1] >= h)) h = e[0] / total;
  if (!(h > 0.0) || !std::isfinite(h)) h = 1.0;  // all points at one place
  int dims[3];
  for (int a = 0; a < 3; ++a)
    dims[a] = std::max(1, static_cast<int>(extent[a] / h) + 1);  // cells of side h exactly
  const auto cell_of = [&](const Eigen::Vector3d& p, int a) {
    return std::clamp(static_cast<int>((p[a] - lo[a]) / h), 0, dims[a] - 1);
  };
  const auto flat = [&](int x, int y, int z) {
    return (static_cast<std::size_t>(z) * dims[1] + y) * dims[0] + x;
  };
  std::vector<int> start(static_cast<std::size_t>(dims[0]) * dims[1] * dims[2] + 1, 0);
  for (int c : members)
    ++start[flat(cell_of(points[c], 0), cell_of(points[c], 1), cell_of(points[c], 2)) + 1];
  for (std::size_t i = 1; i < start.size(); ++i) start[i] += start[i - 1];
  std::vector<int> fill(start.begin(), start.end() - 1), sorted(total);
  for (int c : members)
    sorted[fill[flat(cell_of(points[c], 0), cell_of(points[c], 1), cell_of(points[c], 2))]++] = c;

  std::vector<std::pair<double, int>> d;
  const int max_ring = std::max({dims[0], dims[1], dims[2]});
  for (int b = 0; b < n; ++b) {
    d.clear();
    const Eigen::Vector3d& p = points[b];
    const int cb[3] = {cell_of(p, 0), cell_of(p, 1), cell_of(p, 2)};
    const int others = total - (allowed[b] ? 1 : 0);
    const int m = std::min(k, others);
    for (int r = 0; r <= max_ring; ++r) {
      // The cells at Chebyshev distance r from b's cell.
      for (int z = cb[2] - r; z <= cb[2] + r; ++z) {
        if (z < 0 || z >= dims[2]) continue;
        for (int y = cb[1] - r; y <= cb[1] + r; ++y) {
          if (y < 0 || y >= dims[1]) continue;
          const bool face = std::abs(z - cb[2]) == r || std::abs(y - cb[1]) == r;
          for (int x = cb[0] - r; x <= cb[0] + r; x += (face || r == 0) ? 1 : 2 * r) {
            if (x < 0 || x >= dims[0]) continue;
            const std::size_t cell = flat(x, y, z);
            for (int i = start[cell]; i < start[cell + 1]; ++i) {
              const int c = sorted[i];
              if (c != b) d.emplace_back((points[c] - p).squaredNorm(), c);
            }
          }
        }
      }
      if (static_cast<int>(d.size()) < m) continue;
      if (static_cast<int>(d.size()) == others) break;
      // Every point not yet seen lies beyond r cells: farther than r·h (p lies in its cell). The
      // m-th nearest seen is final when strictly nearer than that.
      std::nth_element(d.begin(), d.begin() + (m - 1), d.end());
      const double bound = r * h;
      if (m > 0 && d[m - 1].first < bound * bound) break;
    }
    std::partial_sort(d.begin(), d.begin() + m, d.end());
    for (int i = 0; i < m; ++i) out[static_cast<std::size_t>(b) * k + i] = d[i].second;
  }
  return out;
}

}  // namespace spidarcad::fem::detail

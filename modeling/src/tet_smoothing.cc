// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/modeling/tet_smoothing.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "spidarcad/base/faces_seen_once.h"
#include "tet_faces.h"

namespace spidarcad::modeling {
namespace {

using Vec = Eigen::Vector3d;

double MinDihedralDeg(const Vec& a, const Vec& b, const Vec& c, const Vec& d) {
  return DihedralAngles(a, b, c, d).minCoeff() * (180.0 / M_PI);
}

// The cosine of the smallest dihedral angle of a positive tetrahedron: the dihedral angle at the
// edge shared by the faces opposite corners k and l is π minus the angle between their outward
// normals, so its cosine is −n_k · n_l, largest for the smallest angle.
double CosMinDihedral(const Vec (&p)[4]) {
  // Outward normals of the faces opposite each corner (the tet positive).
  const Vec n[4] = {
      (p[2] - p[1]).cross(p[3] - p[1]).normalized(), (p[3] - p[0]).cross(p[2] - p[0]).normalized(),
      (p[1] - p[0]).cross(p[3] - p[0]).normalized(), (p[2] - p[0]).cross(p[1] - p[0]).normalized()};
  double c = -1.0;
  for (int k = 0; k < 4; ++k)
    for (int l = k + 1; l < 4; ++l) c = std::max(c, -n[k].dot(n[l]));
  return c;
}

}  // namespace

TetSmoothingStats SmoothSlivers(TetMesh* mesh, const TetSmoothingSettings& settings,
                                const std::vector<char>& fixed) {
  const auto start = std::chrono::steady_clock::now();
  if (!(settings.target_dihedral_deg > 0.0 && settings.target_dihedral_deg < 60.0))
    throw std::invalid_argument("TetSmoothingSettings::target_dihedral_deg = " +
                                std::to_string(settings.target_dihedral_deg) +
                                ": must be in (0, 60)");
  if (settings.sweeps < 1)
    throw std::invalid_argument("TetSmoothingSettings::sweeps = " +
                                std::to_string(settings.sweeps) + ": must be at least 1");
  if (!(settings.max_radius_edge >= 0.0 && std::isfinite(settings.max_radius_edge)))
    throw std::invalid_argument(
        "TetSmoothingSettings::max_radius_edge = " + std::to_string(settings.max_radius_edge) +
        ": must be finite and >= 0");
  ValidateTetMesh(*mesh);
  const Eigen::Index nv = mesh->nodes.cols(), nt = mesh->tets.cols();
  if (!fixed.empty() && static_cast<Eigen::Index>(fixed.size()) != nv)
    throw std::invalid_argument("SmoothSlivers: " + std::to_string(fixed.size()) +
                                " fixed flags for " + std::to_string(nv) + " nodes");

  // Free vertices: on no boundary face and not fixed.
  std::vector<char> free(static_cast<size_t>(nv), 1);
  for (Eigen::Index v = 0; v < nv && !fixed.empty(); ++v)
    if (fixed[static_cast<size_t>(v)]) free[static_cast<size_t>(v)] = 0;
  {
    const std::vector<std::array<int, 3>> keys = internal::TetFaceKeys(*mesh);
    for (const std::size_t i : base::FacesSeenOnce(keys))
      for (const int v : keys[i]) free[static_cast<size_t>(v)] = 0;
  }
  // The tets around each vertex (compressed rows).
  std::vector<int> first(static_cast<size_t>(nv) + 1, 0), around(4 * static_cast<size_t>(nt));
  for (Eigen::Index t = 0; t < nt; ++t)
    for (int k = 0; k < 4; ++k) ++first[static_cast<size_t>(mesh->tets(k, t)) + 1];
  for (size_t v = 1; v < first.size(); ++v) first[v] += first[v - 1];
  {
    std::vector<int> fill(first.begin(), first.end() - 1);
    for (Eigen::Index t = 0; t < nt; ++t)
      for (int k = 0; k < 4; ++k)
        around[static_cast<size_t>(fill[static_cast<size_t>(mesh->tets(k, t))]++)] =
            static_cast<int>(t);
  }
  auto corner = [&](Eigen::Index t, int k) -> Vec { return mesh->nodes.col(mesh->tets(k, t)); };
  std::vector<double> angle(static_cast<size_t>(nt));
  for (Eigen::Index t = 0; t < nt; ++t)
    angle[static_cast<size_t>(t)] =
        MinDihedralDeg(corner(t, 0), corner(t, 1), corner(t, 2), corner(t, 3));

  TetSmoothingStats stats;
  const double target = settings.target_dihedral_deg;
  stats.min_dihedral_before_deg = nt > 0 ? *std::min_element(angle.begin(), angle.end()) : 0.0;
  stats.under_target_before =
      std::count_if(angle.begin(), angle.end(), [&](double a) { return a < target; });

  // The cosine of the smallest dihedral angle of the tets around v with v at x (the larger,
  // the worse), or 2 when one of them would not be positive. The tets are taken from the one at
  // *worst (the worst where v was last placed; then set to the worst here when every tet was
  // looked at), and it stops at the first tet whose cosine reaches `enough` (the value then is
  // at least that): most trial points are refused by that one tet.
  auto star_cos = [&](int v, const Vec& x, double enough, int* worst) {
    const int b = first[static_cast<size_t>(v)], e = first[static_cast<size_t>(v) + 1];
    double c = -1.0;
    int arg = *worst;
    for (int n = 0; n < e - b; ++n) {
      const int i = b + (*worst - b + n) % (e - b);
      const int t = around[static_cast<size_t>(i)];
      Vec p[4];
      for (int k = 0; k < 4; ++k) p[k] = mesh->tets(k, t) == v ? x : corner(t, k);
      if (!((p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) > 0.0)) return 2.0;
      const double ct = CosMinDihedral(p);
      if (ct > c) c = ct, arg = i;
      if (c >= enough) return c;
    }
    *worst = arg;
    return c;
  };
  // The largest radius-edge ratio of the tets around v.
  auto star_radius_edge = [&](int v) {
    double r = 0.0;
    for (int i = first[static_cast<size_t>(v)]; i < first[static_cast<size_t>(v) + 1]; ++i) {
      const int t = around[static_cast<size_t>(i)];
      r = std::max(r, RadiusEdgeRatio(corner(t, 0), corner(t, 1), corner(t, 2), corner(t, 3)));
    }
    return r;
  };
  std::vector<Vec> directions;
  for (int a = -1; a <= 1; ++a)
    for (int b = -1; b <= 1; ++b)
      for (int c = -1; c <= 1; ++c)
        if (a != 0 || b != 0 || c != 0) directions.push_back(Vec(a, b, c).normalized());

  for (int sweep = 0; sweep < settings.sweeps; ++sweep) {
    ++stats.sweeps;
    std::vector<std::pair<double, int>> bad;
    for (Eigen::Index t = 0; t < nt; ++t)
      if (angle[static_cast<size_t>(t)] < target)
        bad.push_back({angle[static_cast<size_t>(t)], static_cast<int>(t)});
    std::sort(bad.begin(), bad.end());
    long moved = 0;
    std::vector<char> searched(static_cast<size_t>(nv), 0);  // once a pass
    for (const auto& [unused, t] : bad) {
      if (!(angle[static_cast<size_t>(t)] < target)) continue;
      for (int k = 0; k < 4; ++k) {
        const int v = mesh->tets(k, t);
        if (!free[static_cast<size_t>(v)] || searched[static_cast<size_t>(v)]) continue;
        searched[static_cast<size_t>(v)] = 1;
        const Vec x0 = mesh->nodes.col(v);
        double shortest = INFINITY;
        for (int i = first[static_cast<size_t>(v)]; i < first[static_cast<size_t>(v) + 1]; ++i)
          for (int j = 0; j < 4; ++j) {
            const int w = mesh->tets(j, around[static_cast<size_t>(i)]);
            if (w != v) shortest = std::min(shortest, (mesh->nodes.col(w) - x0).norm());
          }
        int worst = first[static_cast<size_t>(v)];
        double best = star_cos(v, x0, 2.0, &worst);
        if (!(best <= 1.0) || !(shortest > 0.0)) continue;
        Vec x = x0;
        for (double step = 0.3 * shortest; step >= 0.01 * shortest; step *= 0.5) {
          for (int climb = 0; climb < 32; ++climb) {
            Vec next = x;
            int next_worst = worst;
            for (const Vec& d : directions) {
              const Vec y = x + step * d;
              int w = worst;  // the worst at x first
              const double c = star_cos(v, y, best, &w);
              if (c < best) best = c, next = y, next_worst = w;
            }
            worst = next_worst;
            if (next == x) break;
            x = next;
          }
        }
        if (x == x0) continue;
        // The move may not make the tets around v rounder-edged than TetGen's bound allows, or
        // than they were where that bound did not hold.
        const double radius_edge_before = star_radius_edge(v);
        mesh->nodes.col(v) = x;
        if (star_radius_edge(v) > std::max(radius_edge_before, settings.max_radius_edge)) {
          mesh->nodes.col(v) = x0;
          continue;
        }
        ++moved;
        for (int i = first[static_cast<size_t>(v)]; i < first[static_cast<size_t>(v) + 1]; ++i) {
          const int u = around[static_cast<size_t>(i)];
          angle[static_cast<size_t>(u)] =
              MinDihedralDeg(corner(u, 0), corner(u, 1), corner(u, 2), corner(u, 3));
        }
      }
    }
    stats.moved += moved;
    if (moved == 0) break;
  }
  stats.min_dihedral_after_deg = nt > 0 ? *std::min_element(angle.begin(), angle.end()) : 0.0;
  stats.under_target_after =
      std::count_if(angle.begin(), angle.end(), [&](double a) { return a < target; });
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace spidarcad::modeling

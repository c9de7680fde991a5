// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "scene/snap_features.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <variant>
#include <vector>

#include "spidarcad/modeling/implicit_node.h"

namespace spidarcad::app {

namespace {

using Eigen::Affine3d;
using Eigen::Vector3d;

// Candidates generated before the surface test (bounds the work on huge arrays).
constexpr std::size_t kMaxCandidates = 200000;
// Features kept after it (SnapField::Evaluate is linear in them and runs every tick).
constexpr std::size_t kMaxFeatures = 2000;

// Features before the surface test, in W.
struct Candidates {
  haptics::SnapFeatures features;
  // Per edge of features.edges_W: how far its inner points may lie off the surface beyond the
  // tolerance (a cylinder rim's chord: its sagitta), m.
  std::vector<double> edge_slack;
  // Axes of the round primitives (segments), ExtractSnapAxes.
  std::vector<std::pair<Vector3d, Vector3d>> axes;
  std::size_t count = 0;
  void AddEdge(const Vector3d& a, const Vector3d& b, double slack = 0.0) {
    features.edges_W.emplace_back(a, b);
    edge_slack.push_back(slack);
  }
  void Count(std::size_t n) {
    count += n;
    if (count > kMaxCandidates) {
      throw std::invalid_argument("snap: the scene's primitives give more than " +
                                  std::to_string(kMaxCandidates) +
                                  " candidate features (arrays too large for snapping); remove "
                                  "\"snap\" from the scene");
    }
  }
};

// The affine map of a mirror through the plane n·x = offset (n unit).
Affine3d Mirror(const Vector3d& n, double offset) {
  Affine3d m = Affine3d::Identity();
  m.linear() = Eigen::Matrix3d::Identity() - 2.0 * n * n.transpose();
  m.translation() = 2.0 * offset * n;
  return m;
}

// Corners, edges and faces of the box [-h, h] (local), mapped by X. Faces only when
// `faces_only` (a rounded box: `face_shrink` m of rounding trimmed off each face's rim).
void AddBox(const Vector3d& h, const Affine3d& X, bool faces_only, double face_shrink,
            Candidates* out) {
  haptics::SnapFeatures& f = out->features;
  if (!faces_only) {
    out->Count(8 + 12);
    for (int i = 0; i < 8; ++i) {
      f.vertices_W.push_back(X * Vector3d((i & 1 ? 1 : -1) * h.x(), (i & 2 ? 1 : -1) * h.y(),
                                          (i & 4 ? 1 : -1) * h.z()));
    }
    for (int a = 0; a < 3; ++a) {
      const int b = (a + 1) % 3, c = (a + 2) % 3;
      for (int sb = -1; sb <= 1; sb += 2) {
        for (int sc = -1; sc <= 1; sc += 2) {
          Vector3d p = Vector3d::Zero(), q = Vector3d::Zero();
          p[a] = -h[a];
          q[a] = h[a];
          p[b] = q[b] = sb * h[b];
          p[c] = q[c] = sc * h[c];
          out->AddEdge(X * p, X * q);
        }
      }
    }
  }
  out->Count(6);
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;
    const double hb = h[b] - face_shrink, hc = h[c] - face_shrink;
    if (!(hb > 0 && hc > 0)) continue;
    for (int sa = -1; sa <= 1; sa += 2) {
      haptics::SnapFace face;
      const std::array<std::pair<int, int>, 4> signs{{{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}};
      for (const auto& [sb, sc] : signs) {
        Vector3d p;
        p[a] = sa * h[a];
        p[b] = sb * hb;
        p[c] = sc * hc;
        face.polygon_W.push_back(X * p);
      }
      f.faces_W.push_back(std::move(face));
    }
  }
}

// Prism of `profile` (local xy) over z in [-height/2, height/2], mapped by X.
void AddExtrusion(const std::vector<Eigen::Vector2d>& profile, double height, const Affine3d& X,
                  Candidates* out) {
  const int n = static_cast<int>(profile.size());
  out->Count(5 * static_cast<std::size_t>(n) + 2 + static_cast<std::size_t>(n));
  haptics::SnapFeatures& f = out->features;
  const double z = 0.5 * height;
  auto at = [&](int i, double zz) { return X * Vector3d(profile[i].x(), profile[i].y(), zz); };
  haptics::SnapFace bottom, top;
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    f.vertices_W.push_back(at(i, -z));
    f.vertices_W.push_back(at(i, z));
    out->AddEdge(at(i, -z), at(j, -z));
    out->AddEdge(at(i, z), at(j, z));
    out->AddEdge(at(i, -z), at(i, z));
    haptics::SnapFace side;
    side.polygon_W = {at(i, -z), at(j, -z), at(j, z), at(i, z)};
    f.faces_W.push_back(std::move(side));
    bottom.polygon_W.push_back(at(i, -z));
    top.polygon_W.push_back(at(i, z));
  }
  f.faces_W.push_back(std::move(bottom));
  f.faces_W.push_back(std::move(top));
}

// Rims (chords) and caps (polygons) of the cylinder of `radius` over z in ±height/2, mapped by X.
void AddCylinder(double radius, double height, const Affine3d& X, Candidates* out) {
  out->Count(2 * kCylinderSegments + 3);
  haptics::SnapFeatures& f = out->features;
  out->axes.emplace_back(X * Vector3d(0, 0, -0.5 * height), X * Vector3d(0, 0, 0.5 * height));
  // Sagitta of a chord, in local units; a bound of the map's largest stretch makes it W.
  const double sagitta = radius * (1.0 - std::cos(std::numbers::pi / kCylinderSegments)) *
                         X.linear().norm();  // Frobenius: >= the largest stretch
  for (int s = -1; s <= 1; s += 2) {
    haptics::SnapFace cap;
    for (int i = 0; i < kCylinderSegments; ++i) {
      const double a0 = 2.0 * std::numbers::pi * i / kCylinderSegments;
      const double a1 = 2.0 * std::numbers::pi * (i + 1) / kCylinderSegments;
      const Vector3d p0 =
          X * Vector3d(radius * std::cos(a0), radius * std::sin(a0), s * 0.5 * height);
      const Vector3d p1 =
          X * Vector3d(radius * std::cos(a1), radius * std::sin(a1), s * 0.5 * height);
      out->AddEdge(p0, p1, sagitta);
      cap.polygon_W.push_back(p0);
    }
    f.faces_W.push_back(std::move(cap));
  }
}

void Walk(const modeling::ImplicitNode& node, const Affine3d& X, Candidates* out) {
  auto children = [&](const Affine3d& Y) {
    for (const modeling::ImplicitNode& c : node.children) Walk(c, Y, out);
  };
  std::visit(
      [&](const auto& p) {
        using P = std::decay_t<decltype(p)>;
        if constexpr (std::is_same_v<P, modeling::BoxParams>) {
          AddBox(0.5 * p.size, X, false, 0.0, out);
        } else if constexpr (std::is_same_v<P, modeling::RoundedBoxParams>) {
          AddBox(0.5 * p.size, X, p.radius > 0.0, p.radius, out);
        } else if constexpr (std::is_same_v<P, modeling::ExtrusionParams>) {
          AddExtrusion(p.profile, p.height, X, out);
        } else if constexpr (std::is_same_v<P, modeling::CylinderParams>) {
          AddCylinder(p.radius, p.height, X, out);
        } else if constexpr (std::is_same_v<P, modeling::ConeParams>) {
          out->Count(1);
          out->axes.emplace_back(X * Vector3d(0, 0, -0.5 * p.height),
                                 X * Vector3d(0, 0, 0.5 * p.height));
        } else if constexpr (std::is_same_v<P, modeling::CapsuleParams>) {
          out->Count(1);
          out->axes.emplace_back(X * p.a, X * p.b);
        } else if constexpr (std::is_same_v<P, modeling::TorusParams>) {
          out->Count(1);
          out->axes.emplace_back(X * Vector3d(0, 0, -p.minor_radius),
                                 X * Vector3d(0, 0, p.minor_radius));
        } else if constexpr (std::is_same_v<P, modeling::HalfSpaceParams>) {
          out->Count(1);
          const Vector3d n = p.normal.normalized();
          haptics::SnapFace plane;
          plane.point_W = X * (p.offset * n);
          plane.normal_W = (X.linear().inverse().transpose() * n).normalized();
          out->features.faces_W.push_back(std::move(plane));
        } else if constexpr (std::is_same_v<P, modeling::TranslateParams>) {
          children(X * Eigen::Translation3d(p.translation));
        } else if constexpr (std::is_same_v<P, modeling::RotateParams>) {
          children(X * Eigen::AngleAxisd(p.angle, p.axis.normalized()));
        } else if constexpr (std::is_same_v<P, modeling::ScaleParams>) {
          children(X * Eigen::Scaling(p.factors));
        } else if constexpr (std::is_same_v<P, modeling::MirrorParams>) {
          if (p.keep_original) children(X);
          children(X * Mirror(p.normal.normalized(), p.offset));
        } else if constexpr (std::is_same_v<P, modeling::LinearArrayParams>) {
          for (int i = 0; i < p.count; ++i) children(X * Eigen::Translation3d(i * p.step));
        } else if constexpr (std::is_same_v<P, modeling::PolarArrayParams>) {
          for (int i = 0; i < p.count; ++i)
            children(X * Eigen::AngleAxisd(i * p.step_angle, p.axis.normalized()));
        } else {
          children(X);  // booleans, blends, offset, shell; primitives without features have none
        }
      },
      node.params);
}

// The scene's value at x: the minimum over its solids.
double SceneValue(const modeling::Scene& scene, const Vector3d& x) {
  double v = std::numeric_limits<double>::infinity();
  for (const modeling::Solid& s : scene.solids) v = std::min(v, modeling::EvaluateTree(s.root, x));
  return v;
}

Vector3d Centroid(const std::vector<Vector3d>& polygon) {
  Vector3d c = Vector3d::Zero();
  for (const Vector3d& p : polygon) c += p;
  return c / static_cast<double>(polygon.size());
}

bool Near(const Vector3d& a, const Vector3d& b, double tol) { return (a - b).norm() <= tol; }

}  // namespace

std::string SnapFeatureCounts::ToString() const {
  auto part = [](int n, const char* one, const char* many) {
    return std::to_string(n) + " " + (n == 1 ? one : many);
  };
  return part(vertices, "vertex", "vertices") + ", " + part(edges, "edge", "edges") + ", " +
         part(faces, "face", "faces");
}

SnapFeatureCounts CountSnapFeatures(const haptics::SnapFeatures& features) {
  SnapFeatureCounts c;
  c.vertices = static_cast<int>(features.vertices_W.size());
  c.edges = static_cast<int>(features.edges_W.size());
  c.faces = static_cast<int>(features.faces_W.size());
  return c;
}

std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> ExtractSnapAxes(
    const modeling::Scene& scene, double tolerance) {
  Candidates candidates;
  for (const modeling::Solid& solid : scene.solids)
    Walk(solid.root, Affine3d::Identity(), &candidates);
  std::vector<std::pair<Vector3d, Vector3d>> out;
  for (const auto& [a, b] : candidates.axes) {
    if ((b - a).norm() <= tolerance) continue;
    const bool dup = std::any_of(out.begin(), out.end(), [&](const auto& e) {
      return (Near(a, e.first, tolerance) && Near(b, e.second, tolerance)) ||
             (Near(a, e.second, tolerance) && Near(b, e.first, tolerance));
    });
    if (!dup) out.emplace_back(a, b);
  }
  if (out.size() > kMaxFeatures) {
    throw std::invalid_argument("snap: the scene has " + std::to_string(out.size()) +
                                " round primitives' axes, more than " +
                                std::to_string(kMaxFeatures));
  }
  return out;
}

haptics::SnapFeatures ExtractSnapFeatures(const modeling::Scene& scene, double tolerance) {
  if (!(tolerance > 0.0) || !std::isfinite(tolerance)) {
    throw std::invalid_argument("ExtractSnapFeatures: tolerance must be finite and > 0 m, got " +
                                std::to_string(tolerance));
  }
  Candidates candidates;
  for (const modeling::Solid& solid : scene.solids)
    Walk(solid.root, Affine3d::Identity(), &candidates);
  const haptics::SnapFeatures& in = candidates.features;
  const auto on_surface = [&](const Vector3d& x) {
    return std::abs(SceneValue(scene, x)) <= tolerance;
  };
  // Duplicates: positions equal within the tolerance.
  const double same = tolerance;

  haptics::SnapFeatures out;
  for (const Vector3d& v : in.vertices_W) {
    if (!on_surface(v)) continue;
    if (std::any_of(out.vertices_W.begin(), out.vertices_W.end(),
                    [&](const Vector3d& w) { return Near(v, w, same); }))
      continue;
    out.vertices_W.push_back(v);
  }
  for (std::size_t i = 0; i < in.edges_W.size(); ++i) {
    const Vector3d& a = in.edges_W[i].first;
    const Vector3d& b = in.edges_W[i].second;
    if ((b - a).norm() <= same) continue;
    bool ok = on_surface(a) && on_surface(b);
    for (double t : {0.25, 0.5, 0.75}) {
      ok = ok &&
           std::abs(SceneValue(scene, a + t * (b - a))) <= tolerance + candidates.edge_slack[i];
    }
    if (!ok) continue;
    const bool dup = std::any_of(out.edges_W.begin(), out.edges_W.end(), [&](const auto& e) {
      return (Near(a, e.first, same) && Near(b, e.second, same)) ||
             (Near(a, e.second, same) && Near(b, e.first, same));
    });
    if (!dup) out.edges_W.emplace_back(a, b);
  }
  for (const haptics::SnapFace& face : in.faces_W) {
    if (face.polygon_W.empty()) {  // an unbounded plane: its point nearest the origin
      const Vector3d n = face.normal_W.normalized();
      const Vector3d p0 = n * n.dot(face.point_W);
      if (!on_surface(p0)) continue;
      const bool dup =
          std::any_of(out.faces_W.begin(), out.faces_W.end(), [&](const haptics::SnapFace& g) {
            return g.polygon_W.empty() &&
                   std::abs(std::abs(g.normal_W.normalized().dot(n)) - 1.0) < 1e-12 &&
                   std::abs(n.dot(g.point_W - face.point_W)) <= same;
          });
      if (!dup) out.faces_W.push_back(face);
      continue;
    }
    const Vector3d c = Centroid(face.polygon_W);
    bool ok = on_surface(c);
    for (const Vector3d& p : face.polygon_W)
      ok = ok && on_surface(0.5 * (c + p)) && on_surface(c + 0.9 * (p - c));
    if (!ok) continue;
    const bool dup =
        std::any_of(out.faces_W.begin(), out.faces_W.end(), [&](const haptics::SnapFace& g) {
          if (g.polygon_W.size() != face.polygon_W.size() || !Near(Centroid(g.polygon_W), c, same))
            return false;
          return std::all_of(face.polygon_W.begin(), face.polygon_W.end(), [&](const Vector3d& p) {
            return std::any_of(g.polygon_W.begin(), g.polygon_W.end(),
                               [&](const Vector3d& q) { return Near(p, q, same); });
          });
        });
    if (!dup) out.faces_W.push_back(face);
  }
  const std::size_t kept = out.vertices_W.size() + out.edges_W.size() + out.faces_W.size();
  if (kept > kMaxFeatures) {
    throw std::invalid_argument("snap: the scene has " + std::to_string(kept) + " snap features (" +
                                CountSnapFeatures(out).ToString() + "), more than the " +
                                std::to_string(kMaxFeatures) +
                                " a 1 kHz tick can scan; remove \"snap\" from the scene");
  }
  return out;
}

}  // namespace spidarcad::app

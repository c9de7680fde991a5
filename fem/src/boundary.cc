// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/boundary.h"

#include <Eigen/Geometry>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {

BoundaryConditions::BoundaryConditions(int num_nodes)
    : num_nodes_(num_nodes),
      loads_(Eigen::VectorXd::Zero(3 * static_cast<Eigen::Index>(num_nodes))) {
  if (num_nodes < 0) {
    throw std::invalid_argument("BoundaryConditions: num_nodes must be >= 0, got " +
                                std::to_string(num_nodes));
  }
}

void BoundaryConditions::CheckNode(int v, const char* what) const {
  if (v < 0 || v >= num_nodes_) {
    throw std::invalid_argument(std::string("BoundaryConditions::") + what + ": node " +
                                std::to_string(v) + " is out of range [0, " +
                                std::to_string(num_nodes_) + ")");
  }
}

void BoundaryConditions::FixNode(int v) { PrescribeNode(v, Eigen::Vector3d::Zero()); }

void BoundaryConditions::FixNodes(const std::vector<int>& nodes) {
  for (int v : nodes) FixNode(v);
}

void BoundaryConditions::PrescribeNode(int v, const Eigen::Vector3d& d) {
  CheckNode(v, "PrescribeNode");
  for (int i = 0; i < 3; ++i) PrescribeDof(v, i, d(i));
}

void BoundaryConditions::PrescribeDof(int v, int axis, double d) {
  CheckNode(v, "PrescribeDof");
  if (axis < 0 || axis > 2) {
    throw std::invalid_argument("BoundaryConditions::PrescribeDof: axis must be 0, 1 or 2, got " +
                                std::to_string(axis));
  }
  if (!std::isfinite(d)) {
    throw std::invalid_argument("BoundaryConditions::PrescribeDof: displacement of node " +
                                std::to_string(v) + " is not finite");
  }
  prescribed_[3 * v + axis] = d;
}

void BoundaryConditions::AddPointLoad(int v, const Eigen::Vector3d& f) {
  CheckNode(v, "AddPointLoad");
  if (!f.allFinite()) {
    throw std::invalid_argument("BoundaryConditions::AddPointLoad: force at node " +
                                std::to_string(v) + " is not finite");
  }
  loads_.segment<3>(3 * v) += f;
}

std::vector<int> NodesInBox(const TetMesh& mesh, const Eigen::Vector3d& lower,
                            const Eigen::Vector3d& upper) {
  std::vector<int> out;
  for (int v = 0; v < mesh.num_nodes(); ++v) {
    const Eigen::Vector3d p = mesh.nodes.row(v).transpose();
    if ((p.array() >= lower.array()).all() && (p.array() <= upper.array()).all()) out.push_back(v);
  }
  return out;
}

int FixNodesInBox(const TetMesh& mesh, const Eigen::Vector3d& lower, const Eigen::Vector3d& upper,
                  BoundaryConditions* bcs) {
  const auto nodes = NodesInBox(mesh, lower, upper);
  bcs->FixNodes(nodes);
  return static_cast<int>(nodes.size());
}

double AddTractionInBox(const TetMesh& mesh, const Surface& surface, const Eigen::Vector3d& lower,
                        const Eigen::Vector3d& upper, const Eigen::Vector3d& traction,
                        BoundaryConditions* bcs) {
  auto inside = [&](int v) {
    const Eigen::Vector3d p = mesh.nodes.row(v).transpose();
    return (p.array() >= lower.array()).all() && (p.array() <= upper.array()).all();
  };
  const bool quadratic = mesh.NodesPerElement() == 10;
  double total = 0.0;
  for (int f = 0; f < surface.faces.rows(); ++f) {
    if (!inside(surface.faces(f, 0)) || !inside(surface.faces(f, 1)) ||
        !inside(surface.faces(f, 2)))
      continue;
    const Eigen::Vector3d a = mesh.nodes.row(surface.faces(f, 0)).transpose();
    const Eigen::Vector3d b = mesh.nodes.row(surface.faces(f, 1)).transpose();
    const Eigen::Vector3d c = mesh.nodes.row(surface.faces(f, 2)).transpose();
    const double area = 0.5 * (b - a).cross(c - a).norm();
    total += area;
    for (int k = 0; k < 3; ++k) {
      const int v = quadratic ? surface.faces6(f, 3 + k) : surface.faces(f, k);
      bcs->AddPointLoad(v, traction * (area / 3.0));
    }
  }
  return total;
}

}  // namespace spidarcad::fem

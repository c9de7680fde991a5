// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/stiffness.h"

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace spidarcad::fem {
namespace {

// Derivatives of the shape functions with respect to barycentric coordinates L0..L3
// (npe by 4); the shape functions are treated as functions of four independent L.
Eigen::Matrix<double, Eigen::Dynamic, 4> ShapeDerivativesL(int npe, const Eigen::Vector4d& l) {
  Eigen::Matrix<double, Eigen::Dynamic, 4> d =
      Eigen::Matrix<double, Eigen::Dynamic, 4>::Zero(npe, 4);
  if (npe == 4) {
    d.setIdentity();
    return d;
  }
  for (int i = 0; i < 4; ++i) d(i, i) = 4.0 * l(i) - 1.0;
  for (int k = 0; k < 6; ++k) {
    const int a = kTetEdges[k][0], b = kTetEdges[k][1];
    d(4 + k, a) = 4.0 * l(b);
    d(4 + k, b) = 4.0 * l(a);
  }
  return d;
}

}  // namespace

Eigen::MatrixXd StrainDisplacement(const ElementNodes& x, const Eigen::Vector4d& barycentric,
                                   double* det_j) {
  const int npe = static_cast<int>(x.rows());
  const auto dl = ShapeDerivativesL(npe, barycentric);
  // Natural coordinates ξ = (L1, L2, L3), L0 = 1 − ξ1 − ξ2 − ξ3.
  Eigen::Matrix<double, Eigen::Dynamic, 3> dxi(npe, 3);
  for (int j = 0; j < 3; ++j) dxi.col(j) = dl.col(j + 1) - dl.col(0);
  const Eigen::Matrix3d jac = x.transpose() * dxi;  // J_ij = ∂x_i/∂ξ_j
  if (det_j) *det_j = jac.determinant();
  const Eigen::Matrix<double, Eigen::Dynamic, 3> grad = dxi * jac.inverse();  // ∂N_a/∂x_i
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(6, 3 * npe);
  for (int a = 0; a < npe; ++a) {
    const double gx = grad(a, 0), gy = grad(a, 1), gz = grad(a, 2);
    b(0, 3 * a) = gx;
    b(1, 3 * a + 1) = gy;
    b(2, 3 * a + 2) = gz;
    b(3, 3 * a + 1) = gz;
    b(3, 3 * a + 2) = gy;
    b(4, 3 * a) = gz;
    b(4, 3 * a + 2) = gx;
    b(5, 3 * a) = gy;
    b(5, 3 * a + 1) = gx;
  }
  return b;
}

namespace {

// Four-point rule of degree 2 on the reference tetrahedron (volume 1/6): barycentric point q.
constexpr double kQuadA = 0.5854101966249685, kQuadB = 0.1381966011250105;
Eigen::Vector4d QuadraturePoint(int q) {
  Eigen::Vector4d l = Eigen::Vector4d::Constant(kQuadB);
  l(q) = kQuadA;
  return l;
}

// D with λ removed: the μ part 2μ ε:ε alone (still positive definite on strains).
Matrix6d ShearElasticity(const Material& material) {
  Matrix6d d = material.ElasticityMatrix();
  d.topLeftCorner<3, 3>().array() -= material.Lambda();
  return d;
}

void CheckFormulation(int npe, const Material& material) {
  if (material.formulation == Formulation::kMeanDilatation && npe != 10) {
    throw std::invalid_argument(
        "Formulation::kMeanDilatation needs 10-node (quadratic) tetrahedra, got " +
        std::to_string(npe) +
        "-node elements: a linear element's dilatation is already constant, so its mean "
        "changes nothing and it still locks (upgrade the mesh with MakeQuadratic / --order 2)");
  }
}

// Bᵀ D B over the element's quadrature points, into k (3·Npe by 3·Npe), without B: column 3b + j
// of B holds the derivatives of node b's shape function g_b = (gx, gy, gz) at rows
// j = 0: (0: gx, 4: gz, 5: gy), j = 1: (1: gy, 3: gz, 5: gx), j = 2: (2: gz, 3: gy, 4: gx)
// (StrainDisplacement's Voigt order), so each entry of Bᵀ (D B) is a sum of three products.
// The node blocks with a <= b are computed and mirrored: k is exactly symmetric. Linear
// elements use the one-point rule (weight det J / 6), quadratic ones the 4-point rule
// (det J / 24 each), as ElementStiffness documents.
template <int Npe>
void ElementStiffnessInto(const Eigen::Matrix<double, Npe, 3>& x, const Matrix6d& d,
                          Eigen::Matrix<double, 3 * Npe, 3 * Npe>* k) {
  static_assert(Npe == 4 || Npe == 10);
  constexpr int kPoints = Npe == 4 ? 1 : 4;
  k->setZero();
  for (int q = 0; q < kPoints; ++q) {
    // ∂N/∂ξ (Npe by 3) for ξ = (L1, L2, L3), L0 = 1 − ξ1 − ξ2 − ξ3.
    Eigen::Matrix<double, Npe, 3> dxi = Eigen::Matrix<double, Npe, 3>::Zero();
    if constexpr (Npe == 4) {
      dxi.row(0).setConstant(-1.0);
      dxi.template bottomRows<3>().setIdentity();
    } else {
      const Eigen::Vector4d l = QuadraturePoint(q);
      auto dl = [&](int node, int lj) {  // ∂N_node/∂L_lj
        if (node < 4) return node == lj ? 4.0 * l(lj) - 1.0 : 0.0;
        const int ea = kTetEdges[node - 4][0], eb = kTetEdges[node - 4][1];
        return lj == ea ? 4.0 * l(eb) : lj == eb ? 4.0 * l(ea) : 0.0;
      };
      for (int a = 0; a < Npe; ++a)
        for (int j = 0; j < 3; ++j) dxi(a, j) = dl(a, j + 1) - dl(a, 0);
    }
    const Eigen::Matrix3d jac = x.transpose() * dxi;  // J_ij = ∂x_i/∂ξ_j
    const double w = jac.determinant() / (Npe == 4 ? 6.0 : 24.0);
    const Eigen::Matrix<double, Npe, 3> g = dxi * jac.inverse();  // ∂N_a/∂x_i
    // D B, column by column (6 by 3·Npe).
    Eigen::Matrix<double, 6, 3 * Npe> db;
    for (int b = 0; b < Npe; ++b) {
      const double gx = g(b, 0), gy = g(b, 1), gz = g(b, 2);
      db.col(3 * b) = d.col(0) * gx + d.col(4) * gz + d.col(5) * gy;
      db.col(3 * b + 1) = d.col(1) * gy + d.col(3) * gz + d.col(5) * gx;
      db.col(3 * b + 2) = d.col(2) * gz + d.col(3) * gy + d.col(4) * gx;
    }
    for (int b = 0; b < Npe; ++b)
      for (int a = 0; a <= b; ++a) {
        const double gx = g(a, 0), gy = g(a, 1), gz = g(a, 2);
        for (int j = 0; j < 3; ++j) {
          const auto c = db.col(3 * b + j);
          (*k)(3 * a, 3 * b + j) += w * (gx * c(0) + gz * c(4) + gy * c(5));
          (*k)(3 * a + 1, 3 * b + j) += w * (gy * c(1) + gz * c(3) + gx * c(5));
          (*k)(3 * a + 2, 3 * b + j) += w * (gz * c(2) + gy * c(3) + gx * c(4));
        }
      }
  }
  // Mirror: the lower node blocks, and the lower triangle of each diagonal block.
  for (int b = 0; b < Npe; ++b)
    for (int a = 0; a <= b; ++a)
      for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) {
          if (a == b && i >= j) continue;
          (*k)(3 * b + j, 3 * a + i) = (*k)(3 * a + i, 3 * b + j);
        }
}

// The D that ElementStiffnessInto integrates: D_μ (λ removed) for mean-dilatation elements,
// whose λ part AddMeanDilatation adds; D otherwise.
Matrix6d ElementElasticity(const Material& material) {
  return material.formulation == Formulation::kMeanDilatation ? ShearElasticity(material)
                                                              : material.ElasticityMatrix();
}

}  // namespace

Eigen::RowVectorXd MeanDilatation(const ElementNodes& x, double* volume) {
  const int npe = static_cast<int>(x.rows());
  Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(3 * npe);
  double v = 0.0;
  const int points = npe == 4 ? 1 : 4;
  for (int q = 0; q < points; ++q) {
    double det = 0.0;
    const Eigen::MatrixXd b = StrainDisplacement(
        x, npe == 4 ? Eigen::Vector4d::Constant(0.25) : QuadraturePoint(q), &det);
    const double w = det / (npe == 4 ? 6.0 : 24.0);
    sum += w * (b.row(0) + b.row(1) + b.row(2));
    v += w;
  }
  if (volume) *volume = v;
  return sum / v;
}

namespace {

// With Formulation::kMeanDilatation, adds λ V θ̄ᵀ θ̄ to a 10-node element's k: the volumetric
// energy of the element-mean dilatation (P0 pressure p = λ θ̄ eliminated element by element).
// Entry by entry, so k stays exactly symmetric. Other formulations: nothing.
void AddMeanDilatation(const ElementNodes& x, const Material& material,
                       Eigen::Matrix<double, 30, 30>* k) {
  if (material.formulation != Formulation::kMeanDilatation) return;
  double volume = 0.0;
  const Eigen::RowVectorXd theta = MeanDilatation(x, &volume);
  const double s = material.Lambda() * volume;
  for (int j = 0; j < 30; ++j)
    for (int i = 0; i < 30; ++i) (*k)(i, j) += s * (theta(i) * theta(j));
}

}  // namespace

Eigen::MatrixXd ElementStiffness(const ElementNodes& x, const Material& material) {
  const int npe = static_cast<int>(x.rows());
  if (npe != 4 && npe != 10) {
    throw std::invalid_argument("ElementStiffness: element must have 4 or 10 nodes, got " +
                                std::to_string(npe));
  }
  CheckFormulation(npe, material);  // mean dilatation: 10-node elements only
  if (npe == 4) {
    Eigen::Matrix<double, 12, 12> k;
    ElementStiffnessInto<4>(Eigen::Matrix<double, 4, 3>(x), ElementElasticity(material), &k);
    return k;
  }
  Eigen::Matrix<double, 30, 30> k;
  ElementStiffnessInto<10>(Eigen::Matrix<double, 10, 3>(x), ElementElasticity(material), &k);
  AddMeanDilatation(x, material, &k);
  return k;
}

ElementNodes GetElementNodes(const TetMesh& mesh, int e) {
  const int npe = mesh.NodesPerElement();
  ElementNodes x(npe, 3);
  for (int a = 0; a < npe; ++a) x.row(a) = mesh.nodes.row(mesh.elements(e, a));
  return x;
}

SparseMatrixd AssembleStiffness(const TetMesh& mesh, const MaterialTable& materials) {
  const int n = mesh.num_nodes(), npe = mesh.NodesPerElement(), ne = mesh.num_elements();
  if (npe != 4 && npe != 10) {
    throw std::invalid_argument("AssembleStiffness: elements must have 4 or 10 nodes, got " +
                                std::to_string(npe));
  }
  // Elements of each node, compressed.
  std::vector<int> elem_start(n + 1, 0), elem_of(static_cast<std::size_t>(ne) * npe);
  for (int e = 0; e < ne; ++e)
    for (int a = 0; a < npe; ++a) ++elem_start[mesh.elements(e, a) + 1];
  for (int v = 0; v < n; ++v) elem_start[v + 1] += elem_start[v];
  {
    std::vector<int> fill(elem_start.begin(), elem_start.end() - 1);
    for (int e = 0; e < ne; ++e)
      for (int a = 0; a < npe; ++a) elem_of[fill[mesh.elements(e, a)]++] = e;
  }
  // Neighbours of each node (itself included), sorted; `seen` marks those of the node at hand.
  std::vector<int> adj_start(n + 1, 0), adj, seen(n, -1);
  adj.reserve(static_cast<std::size_t>(n) * (npe == 4 ? 16 : 32));
  for (int b = 0; b < n; ++b) {
    const std::size_t first = adj.size();
    for (int p = elem_start[b]; p < elem_start[b + 1]; ++p)
      for (int a = 0; a < npe; ++a) {
        const int v = mesh.elements(elem_of[p], a);
        if (seen[v] != b) {
          seen[v] = b;
          adj.push_back(v);
        }
      }
    std::sort(adj.begin() + static_cast<std::ptrdiff_t>(first), adj.end());
    adj_start[b + 1] = static_cast<int>(adj.size());
  }
  // Compressed column pattern: column (b, j) holds rows (a, i) for a in adj(b), i = 0..2.
  SparseMatrixd k(3 * n, 3 * n);
  std::vector<int> col_start(3 * n + 1, 0);
  for (int b = 0; b < n; ++b)
    for (int j = 0; j < 3; ++j) col_start[3 * b + j + 1] = 3 * (adj_start[b + 1] - adj_start[b]);
  for (int c = 0; c < 3 * n; ++c) col_start[c + 1] += col_start[c];
  k.resizeNonZeros(col_start.back());
  std::copy(col_start.begin(), col_start.end(), k.outerIndexPtr());
  int* inner = k.innerIndexPtr();
  double* values = k.valuePtr();
  for (int b = 0; b < n; ++b)
    for (int j = 0; j < 3; ++j) {
      int p = col_start[3 * b + j];
      for (int q = adj_start[b]; q < adj_start[b + 1]; ++q)
        for (int i = 0; i < 3; ++i) {
          inner[p] = 3 * adj[q] + i;
          values[p] = 0.0;
          ++p;
        }
    }
  // Element matrices, added into their columns.
  int e = 0;
  auto scatter = [&](const auto& ke) {
    for (int lb = 0; lb < npe; ++lb) {
      const int b = mesh.elements(e, lb);
      const int* nb = adj.data() + adj_start[b];
      const int* nb_end = adj.data() + adj_start[b + 1];
      for (int la = 0; la < npe; ++la) {
        const int rank = static_cast<int>(std::lower_bound(nb, nb_end, mesh.elements(e, la)) - nb);
        for (int j = 0; j < 3; ++j) {
          double* col = values + col_start[3 * b + j] + 3 * rank;
          for (int i = 0; i < 3; ++i) col[i] += ke(3 * la + i, 3 * lb + j);
        }
      }
    }
  };
  // The material of the last region seen: meshes hold few regions, usually in runs.
  int region = 0;
  const Material* material = nullptr;
  Matrix6d d;
  Eigen::Matrix<double, 4, 3> x4;
  Eigen::Matrix<double, 10, 3> x10;
  Eigen::Matrix<double, 12, 12> k4;
  Eigen::Matrix<double, 30, 30> k10;
  for (e = 0; e < ne; ++e) {
    if (material == nullptr || mesh.regions(e) != region) {
      region = mesh.regions(e);
      material = &materials.Get(region);
      CheckFormulation(npe, *material);
      d = ElementElasticity(*material);
    }
    if (npe == 4) {
      for (int a = 0; a < 4; ++a) x4.row(a) = mesh.nodes.row(mesh.elements(e, a));
      ElementStiffnessInto<4>(x4, d, &k4);
      scatter(k4);
    } else {
      for (int a = 0; a < 10; ++a) x10.row(a) = mesh.nodes.row(mesh.elements(e, a));
      ElementStiffnessInto<10>(x10, d, &k10);
      AddMeanDilatation(x10, *material, &k10);
      scatter(k10);
    }
  }
  return k;
}

Eigen::MatrixXd RigidBodyModes(const Eigen::MatrixX3d& nodes) {
  const int n = static_cast<int>(nodes.rows());
  const Eigen::RowVector3d centre = nodes.colwise().mean();
  const double size =
      std::max((nodes.colwise().maxCoeff() - nodes.colwise().minCoeff()).norm(), 1e-300);
  Eigen::MatrixXd r = Eigen::MatrixXd::Zero(3 * n, 6);
  for (int v = 0; v < n; ++v) {
    const Eigen::Vector3d p = (nodes.row(v) - centre).transpose() / size;
    for (int i = 0; i < 3; ++i) r(3 * v + i, i) = 1.0;
    // u = ω × p for unit ω along x, y, z.
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d u = Eigen::Vector3d::Unit(k).cross(p);
      r.block<3, 1>(3 * v, 3 + k) = u;
    }
  }
  return r;
}

Eigen::Matrix<double, 6, 1> ElementStress(const TetMesh& mesh, const MaterialTable& materials,
                                          const Eigen::VectorXd& u, int e) {
  const int npe = mesh.NodesPerElement();
  Eigen::VectorXd ue(3 * npe);
  for (int a = 0; a < npe; ++a) ue.segment<3>(3 * a) = u.segment<3>(3 * mesh.elements(e, a));
  const ElementNodes x = GetElementNodes(mesh, e);
  const Eigen::MatrixXd b = StrainDisplacement(x, Eigen::Vector4d::Constant(0.25));
  const Material& material = materials.Get(mesh.regions(e));
  if (material.formulation != Formulation::kMeanDilatation) {
    return material.ElasticityMatrix() * (b * ue);
  }
  CheckFormulation(npe, material);
  // Shear part at the centroid plus the element pressure λ θ̄ on the normal stresses.
  Eigen::Matrix<double, 6, 1> stress = ShearElasticity(material) * (b * ue);
  stress.head<3>().array() += material.Lambda() * MeanDilatation(x).dot(ue);
  return stress;
}

double VonMises(const Eigen::Matrix<double, 6, 1>& s) {
  const double a = s(0) - s(1), b = s(1) - s(2), c = s(2) - s(0);
  return std::sqrt(0.5 * (a * a + b * b + c * c) + 3.0 * (s(3) * s(3) + s(4) * s(4) + s(5) * s(5)));
}

Eigen::VectorXd ElementVonMises(const TetMesh& mesh, const MaterialTable& materials,
                                const Eigen::VectorXd& u) {
  Eigen::VectorXd vm(mesh.num_elements());
  for (int e = 0; e < mesh.num_elements(); ++e)
    vm(e) = VonMises(ElementStress(mesh, materials, u, e));
  return vm;
}

Eigen::VectorXd AverageToNodes(const TetMesh& mesh, const Eigen::VectorXd& element_values) {
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(mesh.num_nodes());
  Eigen::VectorXd weight = Eigen::VectorXd::Zero(mesh.num_nodes());
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const double vol = std::abs(mesh.CornerVolume(e));
    for (int a = 0; a < mesh.NodesPerElement(); ++a) {
      sum(mesh.elements(e, a)) += vol * element_values(e);
      weight(mesh.elements(e, a)) += vol;
    }
  }
  for (int v = 0; v < mesh.num_nodes(); ++v) sum(v) = weight(v) > 0.0 ? sum(v) / weight(v) : 0.0;
  return sum;
}

}  // namespace spidarcad::fem

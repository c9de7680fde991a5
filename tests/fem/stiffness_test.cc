// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/fem/stiffness.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

namespace spidarcad::fem {
namespace {

// A box mesh of the given order with interior corner nodes moved randomly (fixed seed);
// midside nodes stay at edge midpoints, so elements remain straight-edged.
TetMesh DistortedBox(int order, unsigned seed) {
  BoxMeshSettings s;
  s.nx = 3;
  s.ny = 2;
  s.nz = 2;
  s.upper = Eigen::Vector3d(0.3, 0.2, 0.2);
  TetMesh lin = MakeBoxMesh(s);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02);
  for (int v = 0; v < lin.num_nodes(); ++v) {
    const Eigen::Vector3d p = lin.nodes.row(v).transpose();
    const bool interior = (p.array() > 1e-9).all() && (p.array() < s.upper.array() - 1e-9).all();
    if (interior) lin.nodes.row(v) += Eigen::RowVector3d(jitter(rng), jitter(rng), jitter(rng));
  }
  return order == 2 ? MakeQuadratic(lin) : lin;
}

ElementNodes SkewTet(int order) {
  ElementNodes x(4, 3);
  x << 0.01, 0.02, 0.0, 0.13, 0.0, 0.01, 0.03, 0.11, 0.02, 0.02, 0.04, 0.09;
  if (order == 1) return x;
  ElementNodes q(10, 3);
  q.topRows(4) = x;
  for (int k = 0; k < 6; ++k)
    q.row(4 + k) = 0.5 * (x.row(kTetEdges[k][0]) + x.row(kTetEdges[k][1]));
  return q;
}

class ElementOrderTest : public ::testing::TestWithParam<int> {};

TEST_P(ElementOrderTest, ElementStiffnessIsSymmetricWithSixRigidModesWhenComputed) {
  const ElementNodes x = SkewTet(GetParam());
  const Material mat{2.0e9, 0.3};
  const Eigen::MatrixXd k = ElementStiffness(x, mat);
  EXPECT_LT((k - k.transpose()).norm(), 1e-12 * k.norm());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(k);
  const double max_ev = eig.eigenvalues().maxCoeff();
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(eig.eigenvalues()(i)), 1e-10 * max_ev);
  EXPECT_GT(eig.eigenvalues()(6), 1e-6 * max_ev);
  const Eigen::MatrixXd r = RigidBodyModes(x);
  EXPECT_LT((k * r).norm(), 1e-10 * k.norm() * r.norm());
}

TEST_P(ElementOrderTest, StrainEnergyMatchesClosedFormWhenFieldIsLinear) {
  // u = A x gives the constant strain ε = sym(A); energy ½ uᵀ K u = ½ V εᵀ D ε.
  const ElementNodes x = SkewTet(GetParam());
  const Material mat{1.0e6, 0.25};
  Eigen::Matrix3d a;
  a << 0.01, -0.02, 0.005, 0.003, 0.02, 0.001, -0.004, 0.007, -0.01;
  Eigen::VectorXd u(3 * x.rows());
  for (int i = 0; i < x.rows(); ++i) u.segment<3>(3 * i) = a * x.row(i).transpose();
  const Eigen::Matrix3d e = 0.5 * (a + a.transpose());
  Eigen::Matrix<double, 6, 1> voigt;
  voigt << e(0, 0), e(1, 1), e(2, 2), 2 * e(1, 2), 2 * e(0, 2), 2 * e(0, 1);
  Eigen::Matrix3d edges;
  for (int k = 0; k < 3; ++k) edges.col(k) = (x.row(k + 1) - x.row(0)).transpose();
  const double volume = edges.determinant() / 6.0;
  const double expected = 0.5 * volume * voigt.dot(mat.ElasticityMatrix() * voigt);
  const double energy = 0.5 * u.dot(ElementStiffness(x, mat) * u);
  EXPECT_NEAR(energy, expected, 1e-12 * expected);
}

TEST_P(ElementOrderTest, GlobalStiffnessHasRigidModesInNullSpaceWhenUnconstrained) {
  const TetMesh mesh = DistortedBox(GetParam(), 7);
  MaterialTable mats(Material{3.0e9, 0.35});
  const SparseMatrixd k = AssembleStiffness(mesh, mats);
  ASSERT_EQ(k.rows(), 3 * mesh.num_nodes());
  const SparseMatrixd kt = k.transpose();
  EXPECT_LT((k - kt).norm(), 1e-13 * k.norm());
  const Eigen::MatrixXd r = RigidBodyModes(mesh.nodes);
  const Eigen::MatrixXd kr = k * r;
  for (int m = 0; m < 6; ++m)
    EXPECT_LT(kr.col(m).norm(), 1e-11 * k.norm() * r.col(m).norm()) << "mode " << m;
  // A non-rigid field (a bending shape) is not in the null space.
  Eigen::VectorXd bend = Eigen::VectorXd::Zero(k.rows());
  for (int v = 0; v < mesh.num_nodes(); ++v) bend(3 * v + 2) = mesh.nodes(v, 0) * mesh.nodes(v, 0);
  EXPECT_GT((k * bend).norm(), 1e-3 * k.norm() * bend.norm());
}

// K_e = Σ_q w_q B_qᵀ D B_q from StrainDisplacement, with dense products: the textbook form of
// what ElementStiffness and AssembleStiffness compute without forming B.
Eigen::MatrixXd QuadratureOfBtDB(const ElementNodes& x, const Material& material) {
  const bool linear = x.rows() == 4;
  const double a = 0.5854101966249685, b = 0.1381966011250105;  // the 4-point rule, degree 2
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(3 * x.rows(), 3 * x.rows());
  for (int q = 0; q < (linear ? 1 : 4); ++q) {
    Eigen::Vector4d l = Eigen::Vector4d::Constant(linear ? 0.25 : b);
    if (!linear) l(q) = a;
    double det = 0.0;
    const Eigen::MatrixXd bq = StrainDisplacement(x, l, &det);
    k += (det / (linear ? 6.0 : 24.0)) * bq.transpose() * material.ElasticityMatrix() * bq;
  }
  return k;
}

TEST_P(ElementOrderTest, StiffnessEqualsTheQuadratureOfBtDBInTwoMaterials) {
  const TetMesh mesh = DistortedBox(GetParam(), 11);
  const Material steel{200e9, 0.3}, rubber{5e6, 0.49};
  MaterialTable mats;
  mats.Set(0, steel);
  mats.Set(4, rubber);
  TetMesh two = mesh;
  for (int e = 0; e < two.num_elements(); ++e) two.regions(e) = (e % 3 == 1) ? 4 : 0;
  const SparseMatrixd k = AssembleStiffness(two, mats);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(k.rows(), k.cols());
  const int npe = two.NodesPerElement();
  double worst_element = 0.0;
  for (int e = 0; e < two.num_elements(); ++e) {
    const ElementNodes x = GetElementNodes(two, e);
    const Material& m = mats.Get(two.regions(e));
    const Eigen::MatrixXd ref = QuadratureOfBtDB(x, m);
    worst_element = std::max(worst_element, (ElementStiffness(x, m) - ref).norm() / ref.norm());
    for (int a = 0; a < npe; ++a)
      for (int b = 0; b < npe; ++b)
        dense.block<3, 3>(3 * two.elements(e, a), 3 * two.elements(e, b)) +=
            ref.block<3, 3>(3 * a, 3 * b);
  }
  EXPECT_LT(worst_element, 1e-13);
  EXPECT_LT((Eigen::MatrixXd(k) - dense).norm(), 1e-13 * dense.norm());
  // Exactly symmetric, as the kernel mirrors its upper triangle.
  EXPECT_EQ((k - SparseMatrixd(k.transpose())).norm(), 0.0);
}

TEST_P(ElementOrderTest, AssemblyEqualsDenseSumOfElementMatricesWhenComputed) {
  // Second algorithm: scatter element matrices into a dense matrix.
  const TetMesh mesh = DistortedBox(GetParam(), 3);
  MaterialTable mats(Material{1.0e9, 0.3});
  const SparseMatrixd k = AssembleStiffness(mesh, mats);
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(k.rows(), k.cols());
  const int npe = mesh.NodesPerElement();
  for (int e = 0; e < mesh.num_elements(); ++e) {
    const Eigen::MatrixXd ke = ElementStiffness(GetElementNodes(mesh, e), mats.Get(0));
    for (int a = 0; a < npe; ++a)
      for (int b = 0; b < npe; ++b)
        dense.block<3, 3>(3 * mesh.elements(e, a), 3 * mesh.elements(e, b)) +=
            ke.block<3, 3>(3 * a, 3 * b);
  }
  EXPECT_LT((Eigen::MatrixXd(k) - dense).norm(), 1e-13 * dense.norm());
}

TEST_P(ElementOrderTest, SliverKeepsRigidModesAndExactEnergyWhenNearlyFlat) {
  // Classic sliver: the corners of a unit square lifted alternately by ±h, h = 1e-3.
  const double h = 1e-3;
  ElementNodes c(4, 3);
  c << 0, 0, 0, 1, 0, h, 1, 1, 0, 0, 1, h;
  Eigen::Matrix3d edges;
  for (int k = 0; k < 3; ++k) edges.col(k) = (c.row(k + 1) - c.row(0)).transpose();
  if (edges.determinant() < 0) c.row(1).swap(c.row(3));
  for (int k = 0; k < 3; ++k) edges.col(k) = (c.row(k + 1) - c.row(0)).transpose();
  ASSERT_GT(edges.determinant(), 0.0);
  ElementNodes x = c;
  if (GetParam() == 2) {
    x.resize(10, 3);
    x.topRows(4) = c;
    for (int k = 0; k < 6; ++k)
      x.row(4 + k) = 0.5 * (c.row(kTetEdges[k][0]) + c.row(kTetEdges[k][1]));
  }
  const Material mat{1.0e9, 0.3};
  const Eigen::MatrixXd k = ElementStiffness(x, mat);
  const Eigen::MatrixXd r = RigidBodyModes(x);
  EXPECT_LT((k * r).norm(), 1e-9 * k.norm() * r.norm());
  // Energy of u = A x against ½ V εᵀ D ε, with A a pure shear in the thin direction.
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  a(0, 2) = 1e-3;
  Eigen::VectorXd u(3 * x.rows());
  for (int i = 0; i < x.rows(); ++i) u.segment<3>(3 * i) = a * x.row(i).transpose();
  Eigen::Matrix<double, 6, 1> voigt = Eigen::Matrix<double, 6, 1>::Zero();
  voigt(4) = 1e-3;
  const double expected =
      0.5 * edges.determinant() / 6.0 * voigt.dot(mat.ElasticityMatrix() * voigt);
  EXPECT_NEAR(0.5 * u.dot(k * u), expected, 1e-9 * expected);
}

INSTANTIATE_TEST_SUITE_P(Orders, ElementOrderTest, ::testing::Values(1, 2));

// The mean dilatation of a quadratic field u(x) is the mean of its (linear) divergence over
// the element, i.e. div u at the centroid: computed here from the field's coefficients.
TEST(MeanDilatation, EqualsTheDivergenceAtTheCentroidWhenFieldIsQuadratic) {
  const ElementNodes x = SkewTet(2);
  // u_i = b_i + Σ_j A_ij x_j + Σ_j C_ij x_j², div u = tr A + 2 Σ_i C_ii x_i.
  Eigen::Matrix3d a, c;
  a << 0.3, -0.1, 0.2, 0.05, -0.4, 0.1, 0.2, 0.3, 0.7;
  c << 1.5, 0.2, -0.3, 0.4, -2.0, 0.6, -0.7, 0.1, 3.0;
  const Eigen::Vector3d b(0.01, -0.02, 0.03);
  Eigen::VectorXd ue(30);
  for (int n = 0; n < 10; ++n) {
    const Eigen::Vector3d p = x.row(n).transpose();
    ue.segment<3>(3 * n) = b + a * p + c * p.cwiseProduct(p);
  }
  double volume = 0.0;
  const Eigen::RowVectorXd theta = MeanDilatation(x, &volume);
  const Eigen::Vector3d centroid = x.topRows(4).colwise().mean().transpose();
  const double exact = a.trace() + 2.0 * c.diagonal().dot(centroid);
  EXPECT_NEAR(theta.dot(ue), exact, 1e-12 * std::abs(exact));
  const Eigen::Vector3d e1 = (x.row(1) - x.row(0)).transpose(),
                        e2 = (x.row(2) - x.row(0)).transpose(),
                        e3 = (x.row(3) - x.row(0)).transpose();
  EXPECT_NEAR(volume, e1.dot(e2.cross(e3)) / 6.0, 1e-15);
}

// Mean dilatation keeps the six rigid modes (and only them) in the kernel and is exact for
// constant strain (the patch test): its dilatation is the mean one.
TEST(ElementStiffness, MeanDilatationKeepsRigidModesAndIsExactForConstantStrain) {
  const ElementNodes x = SkewTet(2);
  Material mat{1.0e6, 0.4999};
  mat.formulation = Formulation::kMeanDilatation;
  const Eigen::MatrixXd k = ElementStiffness(x, mat);
  EXPECT_LT((k - k.transpose()).norm(), 1e-12 * k.norm());
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(k);
  const double max_ev = eig.eigenvalues().maxCoeff();
  for (int i = 0; i < 6; ++i) EXPECT_LT(std::abs(eig.eigenvalues()(i)), 1e-10 * max_ev);
  EXPECT_GT(eig.eigenvalues()(6), 0.0);
  const Eigen::MatrixXd r = RigidBodyModes(x);
  EXPECT_LT((k * r).norm(), 1e-10 * k.norm() * r.norm());
  // u = A x: energy ½ uᵀ K u = ½ V εᵀ D ε with the full D.
  Eigen::Matrix3d a;
  a << 1e-3, 2e-4, -3e-4, 5e-4, -2e-3, 1e-4, -1e-4, 4e-4, 3e-3;
  Eigen::VectorXd ue(30);
  for (int n = 0; n < 10; ++n) ue.segment<3>(3 * n) = a * x.row(n).transpose();
  const Eigen::Matrix3d eps = 0.5 * (a + a.transpose());
  Eigen::Matrix<double, 6, 1> voigt;
  voigt << eps(0, 0), eps(1, 1), eps(2, 2), 2 * eps(1, 2), 2 * eps(0, 2), 2 * eps(0, 1);
  double volume = 0.0;
  MeanDilatation(x, &volume);
  const double exact = volume * voigt.dot(mat.ElasticityMatrix() * voigt);
  EXPECT_NEAR(ue.dot(k * ue), exact, 1e-10 * exact);
  // The stress of a constant strain is D ε, as with the plain element.
  TetMesh mesh;
  mesh.nodes = x;
  mesh.elements.resize(1, 10);
  for (int n = 0; n < 10; ++n) mesh.elements(0, n) = n;
  mesh.regions = Eigen::VectorXi::Zero(1);
  const Eigen::Matrix<double, 6, 1> stress = ElementStress(mesh, MaterialTable(mat), ue, 0);
  const Eigen::Matrix<double, 6, 1> expected = mat.ElasticityMatrix() * voigt;
  EXPECT_LT((stress - expected).norm(), 1e-9 * expected.norm());
}

// Mean dilatation is the shear quadrature (Bᵀ D_μ B from StrainDisplacement, D_μ = D with λ
// taken out of its normal block) plus λ V θ̄ᵀ θ̄ from MeanDilatation, in the element and in the
// assembly, exactly symmetric.
TEST(ElementStiffness, MeanDilatationIsTheShearQuadratureAndTheVolumetricTerm) {
  const ElementNodes x = SkewTet(2);
  Material mat{1.0e6, 0.49};
  mat.formulation = Formulation::kMeanDilatation;
  Matrix6d d_mu = mat.ElasticityMatrix();
  d_mu.topLeftCorner<3, 3>().array() -= mat.Lambda();
  Eigen::MatrixXd ref = Eigen::MatrixXd::Zero(30, 30);
  for (int q = 0; q < 4; ++q) {
    Eigen::Vector4d l = Eigen::Vector4d::Constant(0.1381966011250105);
    l(q) = 0.5854101966249685;
    double det = 0.0;
    const Eigen::MatrixXd b = StrainDisplacement(x, l, &det);
    ref += (det / 24.0) * b.transpose() * d_mu * b;
  }
  double volume = 0.0;
  const Eigen::RowVectorXd theta = MeanDilatation(x, &volume);
  ref += mat.Lambda() * volume * theta.transpose() * theta;
  const Eigen::MatrixXd k = ElementStiffness(x, mat);
  EXPECT_LT((k - ref).norm(), 1e-13 * ref.norm());
  EXPECT_EQ((k - k.transpose()).norm(), 0.0);
  TetMesh mesh;
  mesh.nodes = x;
  mesh.elements.resize(1, 10);
  for (int n = 0; n < 10; ++n) mesh.elements(0, n) = n;
  mesh.regions = Eigen::VectorXi::Zero(1);
  EXPECT_LT((Eigen::MatrixXd(AssembleStiffness(mesh, MaterialTable(mat))) - ref).norm(),
            1e-13 * ref.norm());
}

// Linear elements have a constant dilatation already: mean dilatation would still lock, so it
// is refused with a message that says what to do.
TEST(ElementStiffness, MeanDilatationThrowsNamingTheFixWhenElementsAreLinear) {
  Material mat{1.0e6, 0.49};
  mat.formulation = Formulation::kMeanDilatation;
  try {
    ElementStiffness(SkewTet(1), mat);
    ADD_FAILURE() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("10-node"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("MakeQuadratic"), std::string::npos) << e.what();
  }
}

TEST(VonMises, MatchesUniaxialAndPureShearWhenEvaluated) {
  Eigen::Matrix<double, 6, 1> s = Eigen::Matrix<double, 6, 1>::Zero();
  s(0) = 5.0e6;
  EXPECT_NEAR(VonMises(s), 5.0e6, 1e-6);
  s.setZero();
  s(5) = 2.0e6;
  EXPECT_NEAR(VonMises(s), std::sqrt(3.0) * 2.0e6, 1e-6);
  s.setConstant(0.0);
  s.head<3>().setConstant(-1e6);  // hydrostatic: zero
  EXPECT_NEAR(VonMises(s), 0.0, 1e-9);
}

TEST(ElementStress, IsUniformAndExactWhenFieldIsLinear) {
  for (int order : {1, 2}) {
    const TetMesh mesh = DistortedBox(order, 11);
    MaterialTable mats(Material{2.0e11, 0.3});
    const double strain = 1e-4;  // u_x = ε x: σxx = (λ + 2μ) ε, σyy = σzz = λ ε.
    Eigen::VectorXd u = Eigen::VectorXd::Zero(3 * mesh.num_nodes());
    for (int v = 0; v < mesh.num_nodes(); ++v) u(3 * v) = strain * mesh.nodes(v, 0);
    const Material& m = mats.Get(0);
    Eigen::Matrix<double, 6, 1> expected;
    expected << (m.Lambda() + 2 * m.Mu()) * strain, m.Lambda() * strain, m.Lambda() * strain, 0, 0,
        0;
    const Eigen::VectorXd vm = ElementVonMises(mesh, mats, u);
    const Eigen::VectorXd nodal = AverageToNodes(mesh, vm);
    for (int e = 0; e < mesh.num_elements(); ++e) {
      EXPECT_LT((ElementStress(mesh, mats, u, e) - expected).norm(), 1e-9 * expected.norm());
      EXPECT_NEAR(vm(e), VonMises(expected), 1e-9 * VonMises(expected));
    }
    EXPECT_NEAR(nodal.maxCoeff(), VonMises(expected), 1e-9 * VonMises(expected));
    EXPECT_NEAR(nodal.minCoeff(), VonMises(expected), 1e-9 * VonMises(expected));
  }
}

TEST(AssembleStiffness, ThrowsNamingRegionWhenMaterialMissing) {
  TetMesh mesh = DistortedBox(1, 1);
  mesh.regions(0) = 9;
  MaterialTable mats;
  mats.Set(0, Material{1e9, 0.3});
  EXPECT_THROW(AssembleStiffness(mesh, mats), std::invalid_argument);
}

}  // namespace
}  // namespace spidarcad::fem

// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The felt stiffness of an FE part (scene/felt_stiffness.h): the tool's patch, its stiffness from
// a full sparse solve against the haptic path's cached columns, and its convergence with the
// cell size on the platform.
#include "scene/felt_stiffness.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "scene/fe_model.h"
#include "scene/fe_part.h"
#include "scene/fe_setup.h"
#include "scene/fe_touch_field.h"
#include "scene/scene_solid.h"
#include "spidarcad_runner.h"

namespace spidarcad::app {
namespace {

constexpr double kToolRadius = 0.01;  // m, FeTouchSettings' default

// Converged part stiffness K (N/m) of the platform's probes (PlatformFeltProbes): the finest P2
// of the sweep, P2 at 5 mm (234024 nodes), frozen from docs/figures/felt-stiffness.csv, measured
// with
//   build/app/spidarcad felt assets/scenes/platform.json --orders 2 --cells
//   0.0125,0.012,0.010,0.008,0.006,0.005
// (10 minutes on 2 loaded cores; docs/fem.md, "5. Felt stiffness"). P2 from 8 to 5 mm stays within
// 2.6 % (corner 4.30e6 to 4.41e6) and 1 % (gusset 6.16e8 to 6.22e8), a scatter from mesh to mesh
// rather than a trend (P1 at 5.5, 5 and 4 mm agrees: corner -4 %, gusset +1 %).
constexpr double kConvergedCorner = 4.4139e6;
constexpr double kConvergedGusset = 6.21806e8;

// FE mode's default cell for the platform: the largest side of the solid's box / kFeCellsAcross
// (fe_setup.h), as "Set up FE" resolves it.
double DefaultCell() {
  static const double cell =
      PrepareSceneSolid(PlatformScenePath(), "platform", 0.0, kFeCellsAcross).cell;
  return cell;
}

// The platform's design, the solid its meshes are made from, as FE mode and `run` give it to the
// model of a mesh made from it (FeDesignOf): the tool patch is pushed along its normals.
std::shared_ptr<const modeling::CompiledSolid> PlatformDesign() {
  static const std::shared_ptr<const modeling::CompiledSolid> design =
      std::make_shared<const modeling::CompiledSolid>(
          PrepareSceneSolid(PlatformScenePath(), "platform", 0.0, kFeCellsAcross).compiled);
  return design;
}

// The platform at the default cell with elements of `order` (1, 2), built once for the file
// (steel, minimum-x face clamped, its design, no disk cache, column worker stopped).
std::shared_ptr<FeModel> Platform(int order) {
  static std::shared_ptr<FeModel> models[2];
  std::shared_ptr<FeModel>& m = models[order - 1];
  if (!m) {
    static const fem::TetMesh mesh =
        MeshSceneSolidForFe(PlatformScenePath(), "platform", DefaultCell());
    FeModelSettings ms;
    ms.order = order;
    ms.design = PlatformDesign();
    ms.use_disk_cache = false;
    ms.cache.start_worker = false;
    m = FeModel::Build(mesh, ms);
  }
  return m;
}

// FE mode's touch field as `run` and the window build it at world scale 1
// (DefaultFeTouchSettings: the tool patch of radius kDefaultFeToolRadius, sticking, k_c and σ;
// the felt force unbounded here) pushed quasi-statically at a probe: the tool comes down from
// 2 mm above the surface, then is held at 1 mm and at 2 mm past it until the coupled point
// settles (300 ticks each).
struct HapticPush {
  double felt = 0.0;         // Δ(felt force along the push) / Δ(tool depth), N/m
  double part = 0.0;         // the field's published patch stiffness K, N/m
  double reference = 0.0;    // ReferencePatchStiffness of the field's contact set, N/m
  std::vector<int> nodes;    // the field's contact set (mesh nodes, ascending)
  std::vector<int> patch;    // ToolPatchNodes at the field's touch point and normal
  int refused = 0;           // patch nodes beyond kMaxFeContacts
  int substituted = 0;       // contacts on a borrowed column
  double settle_change = 0;  // |Δ felt force| over the last tick at 2 mm, N
};

HapticPush PushQuasiStatically(const std::shared_ptr<FeModel>& model, const FeltProbe& probe) {
  FeTouchSettings ts = ResolvedFieldSettings(*model, DefaultFeTouchSettings(), 1.0);
  ts.max_force = 1e6;
  const double r = ts.tool_radius;
  const Eigen::Vector3d up = -probe.direction.normalized();
  model->cache().ComputeNodes(CandidatesNearPath(*model, {probe.point}, 2.0 * r));
  FeTouchField field(model, ts, nullptr);
  haptics::ToolKinematics tool;
  tool.p_WT = probe.point + (r + 0.002) * up;
  field.Evaluate(tool);
  HapticPush out;
  double force[2] = {0.0, 0.0};
  const double depth[2] = {0.001, 0.002};
  for (int j = 0; j < 2; ++j) {
    tool.p_WT = probe.point + (r - depth[j]) * up;
    haptics::ToolWrench w, previous;
    for (int tick = 0; tick < 300; ++tick) {
      previous = w;
      w = field.Evaluate(tool);
    }
    force[j] = w.f_T_W.dot(up);
    out.settle_change = (w.f_T_W - previous.f_T_W).norm();
  }
  out.felt = (force[1] - force[0]) / (depth[1] - depth[0]);
  const FeContactState& st = field.last_state();
  for (int s = 0; s < st.num_contacts; ++s)
    out.nodes.push_back(model->cache().candidate_node(st.candidate[s]));
  std::sort(out.nodes.begin(), out.nodes.end());
  out.refused = st.refused;
  out.substituted = st.num_substituted;
  out.part = st.stiffness;
  if (!out.nodes.empty()) {
    out.reference = ReferencePatchStiffness(*model, out.nodes, -st.stiffness_normal);
    const Eigen::Vector3d touch = st.p_WC - (r - st.depth) * st.normal;
    out.patch = ToolPatchNodes(*model, touch, r, -st.normal);
    std::printf("%s: touch point (%.6f, %.6f, %.6f), normal (%.6f, %.6f, %.6f), depth %.3e m\n",
                probe.name.c_str(), touch.x(), touch.y(), touch.z(), st.normal.x(), st.normal.y(),
                st.normal.z(), st.depth);
  }
  return out;
}

// Checks one haptic push against the definition: the field's contact set is the tool's patch at
// its touch point, its published K is the reference sparse solve's, and the felt stiffness is
// that K in series with the coupling (the quasi-static equilibrium, to 1e-6).
void ExpectPushIsTheDefinition(const HapticPush& h, const std::string& probe) {
  ASSERT_FALSE(h.nodes.empty()) << probe;
  EXPECT_EQ(h.nodes, h.patch) << probe;
  EXPECT_EQ(h.refused, 0) << probe;
  EXPECT_EQ(h.substituted, 0) << probe;
  EXPECT_NEAR(h.part, h.reference, 1e-9 * h.reference) << probe;
  const double expected = FeltStiffness(h.reference, kDefaultFeCoupling, kDefaultFeForceScale);
  EXPECT_NEAR(h.felt, expected, 1e-6 * expected) << probe;
  EXPECT_LT(h.settle_change, 1e-9) << probe;
}

// The P2 platform at cell h (steel, minimum-x face clamped, its design, no disk cache, no
// worker).
std::shared_ptr<FeModel> PlatformP2At(double h) {
  FeModelSettings ms;
  ms.order = 2;
  ms.design = PlatformDesign();
  ms.use_disk_cache = false;
  ms.cache.start_worker = false;
  return FeModel::Build(MeshSceneSolidForFe(PlatformScenePath(), "platform", h), ms);
}

TEST(FeltStiffness, IsTheCouplingAndTheScaledPartInSeries) {
  EXPECT_NEAR(FeltStiffness(7e6, 1500.0, 1e-4), 1.0 / (1.0 / 1500.0 + 1.0 / 700.0), 1e-9);
  EXPECT_DOUBLE_EQ(FeltStiffness(7e6, 0.0, 1e-4), 700.0);
  EXPECT_DOUBLE_EQ(FeltStiffness(0.0, 1500.0, 1e-4), 0.0);
  EXPECT_NEAR(RichardsonExtrapolate(0.008, 3.0, 0.004, 2.0, 1.0), 1.0, 1e-12);
}

TEST(FeltStiffness, PatchIsTheFreeSurfaceNodesInsideTheToolFacingIt) {
  const std::shared_ptr<FeModel> model = Platform(1);
  const Eigen::Vector3d p(0.29, 0.09, 0.01);
  const std::vector<int> patch = ToolPatchNodes(*model, p, kToolRadius, -Eigen::Vector3d::UnitZ());
  ASSERT_FALSE(patch.empty());
  // Brute force over the surface.
  int expected = 0;
  for (int v : model->surface().nodes) {
    const int b = model->cache().CandidateOfNode(v);
    if (b >= 0 && !model->cache().IsFixed(b) &&
        (model->mesh().nodes.row(v).transpose() - p).norm() < kToolRadius &&
        model->candidate_normals()(b, 2) > 0.0)
      ++expected;
  }
  EXPECT_EQ(static_cast<int>(patch.size()), expected);
  EXPECT_THROW(ReferencePatchStiffness(*model, {}, -Eigen::Vector3d::UnitZ()),
               std::invalid_argument);
  EXPECT_THROW(ReferencePatchStiffness(*model, patch, Eigen::Vector3d::Zero()),
               std::invalid_argument);
}

// The haptic path (cached columns, CachedContactSolver) and the full sparse solve (SolveGrab) give
// the same patch stiffness, P1 and P2.
TEST(FeltStiffness, HapticPathEqualsTheReferenceSparseSolve) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("P" + std::to_string(order));
    const std::shared_ptr<FeModel> model = Platform(order);
    for (const FeltProbe& probe : PlatformFeltProbes()) {
      const std::vector<int> patch =
          ToolPatchNodes(*model, probe.point, kToolRadius, probe.direction);
      const double reference = ReferencePatchStiffness(*model, patch, probe.direction);
      const double cached = CachedPatchStiffness(model.get(), patch, probe.direction);
      std::printf("P%d %s: %zu patch nodes, K = %.9g N/m (reference), %.9g N/m (cached)\n", order,
                  probe.name.c_str(), patch.size(), reference, cached);
      EXPECT_GT(reference, 0.0);
      EXPECT_NEAR(cached, reference, 1e-9 * reference) << probe.name;
    }
  }
}

// FeTouchField (coupled push, FE mode's k_c and σ) publishes its contact set's stiffness: the same
// number as the reference sparse solve of that contact set moved rigidly along the published
// normal. (On this plate the sphere holds one node: the nodes around it inside the sphere are
// released as the plate bends away from them, `refused` counts them; a much stiffer coupling
// that sinks the sphere 8 mm deep leaves the same single node.)
TEST(FeltStiffness, TouchFieldPublishesTheReferenceStiffnessOfItsContactSet) {
  for (int order : {1, 2}) {
    SCOPED_TRACE("P" + std::to_string(order));
    const std::shared_ptr<FeModel> model = Platform(order);
    FeTouchSettings ts;
    ts.tool_radius = kToolRadius;
    ts.force_scale = kDefaultFeForceScale;
    ts.coupling_stiffness = kDefaultFeCoupling;
    ts.max_force = 1e3;
    FeTouchField field(model, ts, nullptr);
    haptics::ToolKinematics tool;
    tool.p_WT = Eigen::Vector3d(0.28, 0.08, 0.01 + kToolRadius - 0.004);
    field.Evaluate(tool);  // focus of the column worker
    model->cache().Start();
    ASSERT_TRUE(model->cache().WaitUntilIdle(300.0));
    model->cache().Stop();
    for (int tick = 0; tick < 20; ++tick) field.Evaluate(tool);
    const FeContactState& st = field.last_state();
    std::printf("centre %.5f %.5f %.5f, contacts %d, refused %d\n", st.p_WC.x(), st.p_WC.y(),
                st.p_WC.z(), st.num_contacts, st.refused);
    ASSERT_GT(st.num_contacts, 0);
    ASSERT_EQ(st.num_substituted, 0);
    ASSERT_GT(st.stiffness, 0.0);
    std::vector<int> nodes;
    for (int s = 0; s < st.num_contacts; ++s)
      nodes.push_back(model->cache().candidate_node(st.candidate[s]));
    const double reference = ReferencePatchStiffness(*model, nodes, -st.stiffness_normal);
    std::printf("P%d: %d contacts, field K = %.9g N/m, reference %.9g N/m\n", order,
                st.num_contacts, st.stiffness, reference);
    EXPECT_NEAR(st.stiffness, reference, 1e-9 * reference);
  }
}

// The symptom of the clamp defect (FeModel.DefaultClampHoldsThePlatformWallFaceAtEveryCellSize):
// from 6 to 5 mm cells P1's K fell to 0.70 (corner) and 0.22 (gusset) of its value as the default
// clamp let go of the wall face. With the wall held, the step changes K by about 6 % (0.94 and
// 1.06).
TEST(FeltStiffness, P1DoesNotDropFromSixToFiveMillimetreCells) {
  FeltSweepSettings settings;
  settings.cells = {0.006, 0.005};
  settings.orders = {1};
  const std::vector<FeltSample> samples = MeasureFeltStiffness(settings);
  ASSERT_EQ(samples.size(), 4u);
  for (int p = 0; p < 2; ++p) {
    const FeltSample& coarse = samples[p];
    const FeltSample& fine = samples[2 + p];
    ASSERT_EQ(coarse.probe, fine.probe);
    const double ratio = fine.stiffness / coarse.stiffness;
    std::printf("%s: K %.4g N/m at 6 mm, %.4g N/m at 5 mm (x %.3f)\n", coarse.probe.c_str(),
                coarse.stiffness, fine.stiffness, ratio);
    EXPECT_GT(ratio, 0.85) << coarse.probe;
    EXPECT_LT(ratio, 1.15) << coarse.probe;
  }
}

// The acceptance figure: with P2 at FE mode's default resolution (12.5 mm) the felt
// stiffness (FE mode's k_c and σ) of both probes is within 5 % of the converged value, and so is
// the part stiffness K itself (the gusset's felt value is held near k_c by the coupling, so K is
// the sharper check). Measured: corner K -1.1 %, felt -0.9 %; gusset K +1.5 %, felt +0.03 %.
TEST(FeltStiffness, P2AtTheDefaultResolutionIsWithinFivePercentOfConverged) {
  const double cell = DefaultCell();
  std::printf("default cell %.2f mm\n", 1e3 * cell);
  EXPECT_GT(cell, 0.011);
  EXPECT_LT(cell, 0.014);
  const std::shared_ptr<FeModel> model = Platform(2);
  for (const FeltProbe& probe : PlatformFeltProbes()) {
    const double converged = probe.name == "corner" ? kConvergedCorner : kConvergedGusset;
    const std::vector<int> patch =
        ToolPatchNodes(*model, probe.point, kToolRadius, probe.direction);
    const double k = ReferencePatchStiffness(*model, patch, probe.direction);
    const double felt = FeltStiffness(k, kDefaultFeCoupling, kDefaultFeForceScale);
    const double felt_converged =
        FeltStiffness(converged, kDefaultFeCoupling, kDefaultFeForceScale);
    std::printf("%s: K = %.4g N/m (%+.1f %% from converged), felt %.1f N/m (%+.2f %%)\n",
                probe.name.c_str(), k, 100.0 * (k / converged - 1.0), felt,
                100.0 * (felt / felt_converged - 1.0));
    EXPECT_NEAR(felt, felt_converged, 0.05 * felt_converged) << probe.name;
    EXPECT_NEAR(k, converged, 0.05 * converged) << probe.name;
  }
}

// Why FE mode's tool pushes along the design's normal: at the platform's free corner at FE mode's
// default cell (P2, 12.5 mm) the coarse surface follows the plate's 3 mm rounded end over a whole
// cell, so the facing nodes within R of the corner probe have mesh normals tilted by degrees, and
// so is the least-squares plane through their positions, while the design is flat there: every
// patch node on the plate's flat top (z = 0.01 m, at least 3 mm in from the free edges x = 0.3 and
// y = 0.1 m) has the design normal +z.
TEST(FeltStiffness, DesignNormalIsTheFaceNormalWhereTheCoarseMeshSlopes) {
  const std::shared_ptr<FeModel> model = Platform(2);
  const FeltProbe corner = PlatformFeltProbes()[0];
  ASSERT_EQ(corner.name, "corner");
  const std::vector<int> patch =
      ToolPatchNodes(*model, corner.point, kToolRadius, corner.direction);
  ASSERT_FALSE(patch.empty());
  const auto degrees = [](const Eigen::Vector3d& n) {
    return std::acos(std::clamp(n.normalized().z(), -1.0, 1.0)) * 180.0 / M_PI;
  };
  double max_mesh_tilt = 0.0;
  int flat = 0, flat_tilted = 0;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (int v : patch) centroid += model->mesh().nodes.row(v).transpose();
  centroid /= static_cast<double>(patch.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (int v : patch) {
    const Eigen::Vector3d x = model->mesh().nodes.row(v).transpose();
    scatter += (x - centroid) * (x - centroid).transpose();
    const int b = model->cache().CandidateOfNode(v);
    const Eigen::Vector3d mesh_n = model->candidate_normals().row(b).transpose();
    const Eigen::Vector3d design_n = model->design_normals().row(b).transpose();
    std::printf("node %6d at (%.4f, %.4f, %.5f): mesh normal tilted %5.2f deg, design %5.2f deg\n",
                v, x.x(), x.y(), x.z(), degrees(mesh_n), degrees(design_n));
    max_mesh_tilt = std::max(max_mesh_tilt, degrees(mesh_n));
    if (std::abs(x.z() - 0.01) < 1e-6 && x.x() <= 0.297 && x.y() <= 0.097) {
      ++flat;
      if (degrees(mesh_n) > 1.0) ++flat_tilted;
      EXPECT_NEAR((design_n - Eigen::Vector3d::UnitZ()).norm(), 0.0, 1e-9)
          << "node " << v << " at " << x.transpose();
    }
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  const Eigen::Vector3d plane_n = eig.eigenvectors().col(0);
  std::printf(
      "corner at 12.5 mm (P2): %zu patch nodes, %d on the flat top (%d of them with a mesh normal "
      "tilted > 1 deg), mesh normals tilted up to %.2f deg, least-squares plane %.2f deg\n",
      patch.size(), flat, flat_tilted, max_mesh_tilt,
      std::min(degrees(plane_n), degrees(-plane_n)));
  EXPECT_GT(flat, 0);
  EXPECT_GT(max_mesh_tilt, 2.0);
}

// Where the mesh has the surface's normal, the haptic path is `felt`'s definition exactly: FE
// mode's field (the tool patch, DefaultFeTouchSettings) pushed quasi-statically on the P2
// platform at 10 mm cells at both probes and at the default 12.5 mm over the gusset pushes the
// tool's patch at the probe along −z, its K is the reference sparse solve's (1e-9) and its felt
// stiffness K in series with the coupling (1e-6): measured at 10 mm K 4.13984e6 (corner, 54
// nodes) and 6.11e8 N/m (gusset), the sweep's 10 mm values; the felt stiffness within 5 % of the
// converged value (corner −4.9 %), K within the stated P2 mesh error of 7 % (corner −6.2 %).
TEST(FeltStiffness, HapticPushIsFeltsDefinitionWhereTheMeshHasTheSurfaceNormal) {
  const std::shared_ptr<FeModel> fine = PlatformP2At(0.010);
  for (const FeltProbe& probe : PlatformFeltProbes()) {
    const double converged = probe.name == "corner" ? kConvergedCorner : kConvergedGusset;
    const double felt_converged =
        FeltStiffness(converged, kDefaultFeCoupling, kDefaultFeForceScale);
    // The default mesh over the gusset only (a fixed array: GCC 12 saw a vector of pairs grown
    // by emplace_back as out of bounds, -Warray-bounds).
    const std::pair<std::string, std::shared_ptr<FeModel>> meshes[2] = {
        {"10 mm", fine}, {"12.5 mm", probe.name == "gusset" ? Platform(2) : nullptr}};
    for (const auto& [label, model] : meshes) {
      if (!model) continue;
      const HapticPush h = PushQuasiStatically(model, probe);
      std::printf(
          "P2 %s at %s: %zu patch nodes, K = %.6g N/m (%+.2f %%), felt %.2f N/m (%+.2f %%)\n",
          probe.name.c_str(), label.c_str(), h.nodes.size(), h.reference,
          100.0 * (h.reference / converged - 1.0), h.felt, 100.0 * (h.felt / felt_converged - 1.0));
      ExpectPushIsTheDefinition(h, probe.name + " at " + label);
      EXPECT_EQ(h.nodes, ToolPatchNodes(*model, probe.point, kToolRadius, probe.direction))
          << probe.name << " at " << label;
      EXPECT_NEAR(h.felt, felt_converged, 0.05 * felt_converged) << probe.name << " at " << label;
      EXPECT_NEAR(h.reference, converged, 0.07 * converged) << probe.name << " at " << label;
    }
  }
}

// The acceptance figure through the haptic path itself: FE mode's field (the tool patch,
// DefaultFeTouchSettings) pushed quasi-statically on the P2 platform at the default resolution
// gives, at both probes, the definition's felt stiffness (its contact set is the tool's patch and
// its felt stiffness the patch's K in series with the coupling) and so lies within 5 % of the
// converged felt stiffness frozen above (kConvergedCorner, kConvergedGusset). Measured
// 2026-12-04: corner 35 patch nodes, K 4.36807e6 N/m (−1.04 %), felt 338.29 N/m (−0.80 %);
// gusset 30 nodes, K +1.50 %, felt +0.03 %. It failed at the corner (K 9.41e6 N/m, felt +68 %)
// while the patch was pushed along the mesh's dominant node normal, tilted by 4.6° there because
// the 12.5 mm surface cannot follow the plate's 3 mm rounded end (test above); it passes since
// the patch is pushed along the design's normal (FeModel::design_normals), +z on the flat top.
TEST(FeltStiffness, HapticPushAtP2DefaultResolutionIsWithinFivePercentOfConverged) {
  const std::shared_ptr<FeModel> model = Platform(2);
  for (const FeltProbe& probe : PlatformFeltProbes()) {
    const HapticPush h = PushQuasiStatically(model, probe);
    const double converged = probe.name == "corner" ? kConvergedCorner : kConvergedGusset;
    const double felt_converged =
        FeltStiffness(converged, kDefaultFeCoupling, kDefaultFeForceScale);
    std::printf(
        "P2 %s: %zu patch nodes, K = %.6g N/m (%+.2f %% from converged), felt %.2f N/m "
        "(%+.2f %%)\n",
        probe.name.c_str(), h.nodes.size(), h.reference, 100.0 * (h.reference / converged - 1.0),
        h.felt, 100.0 * (h.felt / felt_converged - 1.0));
    ExpectPushIsTheDefinition(h, probe.name);
    EXPECT_NEAR(h.felt, felt_converged, 0.05 * felt_converged) << probe.name;
  }
}

// The haptic felt stiffness at two P2 meshes, the default (12.5 mm) and 10 mm cells, agrees
// within the mesh error of P2 on this part: the sweep above (docs/figures/felt-stiffness.csv)
// scatters from mesh to mesh rather than converging monotonically, K within 9 % of the converged
// value from 12.5 to 5 mm and the felt stiffness within 7 %; between these two meshes it gives
// K -5.1 % (corner) and -3.1 % (gusset), felt -4.0 % and -0.1 %. Stated error: felt within 5 %,
// K within 7 %. Measured through the haptic path (2026-12-04, the patch pushed along the design's
// normal): K -5.22 % (corner) and -3.12 % (gusset), felt -4.09 % and -0.07 %; it failed at the
// corner (default K 9.41e6 against 4.14e6 N/m at 10 mm) while the push followed the mesh's
// tilted normal.
TEST(FeltStiffness, HapticPushAgreesAtTwoCellSizesWithinTheMeshError) {
  const std::shared_ptr<FeModel> coarse = Platform(2);
  const std::shared_ptr<FeModel> fine = PlatformP2At(0.010);
  for (const FeltProbe& probe : PlatformFeltProbes()) {
    const HapticPush a = PushQuasiStatically(coarse, probe);
    const HapticPush b = PushQuasiStatically(fine, probe);
    std::printf(
        "P2 %s: default %zu nodes K %.6g felt %.2f; 10 mm %zu nodes K %.6g felt %.2f "
        "(K %+.2f %%, felt %+.2f %%)\n",
        probe.name.c_str(), a.nodes.size(), a.reference, a.felt, b.nodes.size(), b.reference,
        b.felt, 100.0 * (b.reference / a.reference - 1.0), 100.0 * (b.felt / a.felt - 1.0));
    ExpectPushIsTheDefinition(b, probe.name + " at 10 mm");
    EXPECT_NEAR(b.felt, a.felt, 0.05 * a.felt) << probe.name;
    EXPECT_NEAR(b.reference, a.reference, 0.07 * a.reference) << probe.name;
  }
}

// `spidarcad felt --mesher lattice` measures on the lattice route's surface: another mesh of the
// part (other node counts), and a stiffness of the same order; an unknown mesher is refused,
// naming the option and the choices.
TEST(FeltStiffness, CommandMeasuresOnEitherSurface) {
  std::map<std::string, std::pair<long, double>> runs;  // mesher: nodes, K of the corner
  for (const std::string mesher : {"tetrahedra", "lattice"}) {
    const test_support::CommandRun run = test_support::RunSpidarcad(
        "felt --orders 1 --cells 0.012 --probe corner,0.29,0.09,0.01 --mesher " + mesher, "",
        mesher);
    ASSERT_EQ(run.status, 0) << run.all();
    std::istringstream lines(run.out);
    std::string line;
    while (std::getline(lines, line)) {
      std::istringstream row(line);
      std::string probe;
      double cell_mm = 0.0, k = 0.0;
      int order = 0, patch = 0;
      long nodes = 0;
      if (row >> probe >> cell_mm >> order >> nodes >> patch >> k && probe == "corner")
        runs[mesher] = {nodes, k};
    }
    ASSERT_EQ(runs.count(mesher), 1u) << run.out;
  }
  EXPECT_NE(runs["tetrahedra"].first, runs["lattice"].first);
  EXPECT_GT(runs["lattice"].second, 0.5 * runs["tetrahedra"].second);
  EXPECT_LT(runs["lattice"].second, 2.0 * runs["tetrahedra"].second);
  const test_support::CommandRun bad =
      test_support::RunSpidarcad("felt --cells 0.012 --mesher cubes", "", "bad");
  EXPECT_EQ(bad.status, 2) << bad.all();
  EXPECT_NE(bad.all().find("--mesher 'cubes': give lattice or tetrahedra"), std::string::npos)
      << bad.all();
  // --flat-cells coarsens the marching-tetrahedra surface (2026-12-06): refused outside [0, 1]
  // and with the lattice, naming the option.
  for (const std::string args : {"--flat-cells 2", "--flat-cells 0.5 --mesher lattice"}) {
    const test_support::CommandRun refused =
        test_support::RunSpidarcad("felt --cells 0.012 " + args, "", "flat_bad");
    EXPECT_EQ(refused.status, 2) << args << "\n" << refused.all();
    EXPECT_NE(refused.all().find("--flat-cells"), std::string::npos) << args << "\n"
                                                                     << refused.all();
  }
}

}  // namespace
}  // namespace spidarcad::app

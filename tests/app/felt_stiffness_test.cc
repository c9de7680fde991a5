// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// The felt stiffness of an FE part (scene/felt_stiffness.h): the tool's patch, its stiffness from
// a full sparse solve against the haptic path's cached columns, and its convergence with the
// cell size on the platform.
#include "scene/felt_stiffness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "scene/fe_model.h"
#include "scene/fe_setup.h"
#include "scene/fe_touch_field.h"
#include "scene/scene_solid.h"

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

// The platform at the default cell with elements of `order` (1, 2), built once for the file
// (steel, minimum-x face clamped, no disk cache, column worker stopped).
std::shared_ptr<FeModel> Platform(int order) {
  static std::shared_ptr<FeModel> models[2];
  std::shared_ptr<FeModel>& m = models[order - 1];
  if (!m) {
    static const fem::TetMesh mesh =
        MeshSceneSolidForFe(PlatformScenePath(), "platform", DefaultCell());
    FeModelSettings ms;
    ms.order = order;
    ms.use_disk_cache = false;
    ms.cache.start_worker = false;
    m = FeModel::Build(mesh, ms);
  }
  return m;
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

}  // namespace
}  // namespace spidarcad::app

// `spidarcad tension --batch`: tension distribution for poses and wrench requests read from
// stdin, one CSV line in, one CSV line out.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include <Eigen/Geometry>
#include <cmath>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_common.h"
#include "cli/commands.h"
#include "spidarcad/haptics/tension.h"

namespace spidarcad::app {

namespace {

constexpr const char* kTensionHelp =
    "Tension distribution (the paper's Eq. 16-17 as re-derived in docs/architecture.md, Reading\n"
    "the SPIDAR-G paper): for each pose and requested wrench,\n"
    "the string tensions that display it best within the tension bounds.\n"
    "\n"
    "Input (stdin), one line per request, 16 comma-separated numbers; '#' and blank lines\n"
    "are skipped:\n"
    "  x,y,z, x1,y1,z1, x2,y2,z2, fx,fy,fz, mx,my,mz, g\n"
    "  x,y,z       grip centre p0 in the device frame D [m] (origin at the frame centre,\n"
    "              corners at (±a, ±b, ±c))\n"
    "  x1,y1,z1    pole vector p1 [m] (strings 1,2 at p0 + p1, strings 3,4 at p0 − p1)\n"
    "  x2,y2,z2    pole vector p2 [m] (strings 5,7 at p0 + p2, strings 6,8 at p0 − p2)\n"
    "              At rest p1 = (0, d, 0), p2 = (d, 0, 0), d = --pole.\n"
    "  fx,fy,fz    requested force on the grip [N], in D\n"
    "  mx,my,mz    requested moment on the grip about p0 [N·m], in D\n"
    "  g           requested grasp torque [N·m]: g > 0 squeezes the grip closed (drives the\n"
    "              angle between p1 and p2 down); g = Σ τ_i δ_i n·(r_i × c_i), n = p̂1 × p̂2,\n"
    "              δ = +1 for strings 1-4, −1 for strings 5-8.\n"
    "\n"
    "Output (stdout), one line per input line, in order:\n"
    "  t1,...,t8,objective\n"
    "  t1..t8      string tensions [N], each in [tmin, tmax] (string i pulls the grip toward\n"
    "              frame corner Q_i)\n"
    "  objective   J = |f − Fτ|² + S0|m − Mτ|² + S1(g − Gτ)² + S2|τ|² at the exact optimum\n"
    "              (J well above S2|τ|² means part of the request could not be displayed)\n"
    "\n"
    "With --lost each output line goes on with what could not be displayed:\n"
    "  t1,...,t8,objective,status,lost_fx,lost_fy,lost_fz,lost_mx,lost_my,lost_mz,lost_g,closure\n"
    "  status      ok (displayed to 1 %), saturated (part of the request is lost: beyond the\n"
    "              tension bounds, or a direction the strings cannot pull in at this pose)\n"
    "  lost_*      the request minus the displayed wrench A·τ, per component [N, N·m]\n"
    "  closure     force-closure margin of the pose: min_i n_i / max_i |n_i| of the null\n"
    "              vector n of A (A n = 0). > 0: higher tensions can display any wrench;\n"
    "              <= 0: force closure is lost and some wrench directions are lost whatever\n"
    "              --tmax is.\n"
    "A line with NaN or infinity then gives status invalid_input and nan elsewhere.\n"
    "\n"
    "Every line is solved independently (no warm start carries over). The pole vectors are\n"
    "used as given (|p1| = |p2| = d is not enforced); a line whose pose is degenerate (a pole\n"
    "of zero length, parallel poles, an attachment point on its frame corner) is an error\n"
    "(exit status 2, naming the line). A line containing NaN or infinity gives a line of nine\n"
    "'nan' (the device itself would hold every string at tmin).\n"
    "\n"
    "Weights: S0 and S1 weigh squared N·m against squared N, so they must be of order 1/d²\n"
    "(default 1/d² = 625 for d = 0.04 m); with weights of order 1 most of a commanded moment or\n"
    "grasp torque is silently lost. S2 (default 0.001) keeps the optimum unique and smooth.\n"
    "\n"
    "Example (grip at rest, push 1 N along +x):\n"
    "  echo 0,0,0,0,0.04,0,0.04,0,0,1,0,0,0,0,0,0 | spidarcad tension --batch";

struct TensionOptions {
  bool batch = false;
  double tau_min = haptics::TensionSettings{}.tau_min;
  double tau_max = haptics::TensionSettings{}.tau_max;
  std::vector<double> weights;
  bool lost = false;
  haptics::SpidarGeometry geometry;
};

// Throws InputError when the pose of a line cannot define a wrench matrix.
void CheckPose(const haptics::SpidarGeometry& g, const haptics::GripPose& pose, int line) {
  const std::string where = "<stdin>:" + std::to_string(line) + ": ";
  const double n1 = pose.p1.norm(), n2 = pose.p2.norm();
  if (n1 < 1e-6 || n2 < 1e-6) {
    throw InputError(where + "degenerate pose: pole vector " +
                     std::string(n1 < 1e-6 ? "p1" : "p2") + " has length " +
                     FormatNumber(n1 < 1e-6 ? n1 : n2) +
                     " m (expected about d = " + FormatNumber(g.d) + " m)");
  }
  if (pose.p1.cross(pose.p2).norm() < 1e-9 * n1 * n2) {
    throw InputError(where +
                     "degenerate pose: poles p1 and p2 are parallel, the grasp axis is "
                     "undefined");
  }
  for (int i = 0; i < haptics::kNumStrings; ++i) {
    if ((g.Corner(i) - pose.Attachment(i)).norm() < 1e-9) {
      throw InputError(where + "degenerate pose: string " + std::to_string(i + 1) +
                       " has zero length (its attachment point is on frame corner Q" +
                       std::to_string(i + 1) + ")");
    }
  }
}

void RunTension(const TensionOptions& options) {
  if (!options.batch) {
    throw InputError(
        "tension: only batch mode exists; pass --batch and write requests on "
        "stdin (see `spidarcad tension --help`)");
  }
  ValidateGeometry(options.geometry);
  haptics::TensionSettings settings = haptics::TensionSettings::ForPoleLength(options.geometry.d);
  settings.tau_min = options.tau_min;
  settings.tau_max = options.tau_max;
  if (!options.weights.empty()) {
    if (options.weights.size() != 3) {
      throw InputError("--weights: expected three numbers S0,S1,S2, got " +
                       std::to_string(options.weights.size()));
    }
    settings.s0 = options.weights[0];
    settings.s1 = options.weights[1];
    settings.s2 = options.weights[2];
  }
  try {
    settings.Validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(std::string("--tmin/--tmax/--weights: ") + e.what());
  }
  haptics::TensionSolver solver(settings);
  std::string out;
  ForEachCsvRecord(std::cin, "<stdin>", 16, [&](const std::vector<double>& v, int line) {
    int bad = -1;  // first field that is not finite
    for (int k = 0; bad < 0 && k < static_cast<int>(v.size()); ++k)
      if (!std::isfinite(v[k])) bad = k;
    if (bad >= 0) {
      // Refused like ik and fk refuse a bad line: nan out, the line and column on stderr.
      std::cerr << "spidarcad tension: <stdin>:" << line << ": column " << bad + 1 << ": "
                << FormatNumber(v[bad]) << " is not finite (tensions nan)\n";
      out += "nan,nan,nan,nan,nan,nan,nan,nan,nan";
      out += options.lost ? ",invalid_input,nan,nan,nan,nan,nan,nan,nan,nan\n" : "\n";
      return;
    }
    haptics::GripPose pose;
    pose.p0 = Eigen::Vector3d(v[0], v[1], v[2]);
    pose.p1 = Eigen::Vector3d(v[3], v[4], v[5]);
    pose.p2 = Eigen::Vector3d(v[6], v[7], v[8]);
    CheckPose(options.geometry, pose, line);
    haptics::Vector7d q;
    for (int k = 0; k < 7; ++k) q(k) = v[9 + k];
    solver.Reset();  // each line independent of the previous ones
    const haptics::Matrix78d A = haptics::WrenchMatrix(options.geometry, pose);
    const haptics::TensionResult r = solver.Solve(A, q);
    for (int i = 0; i < haptics::kNumStrings; ++i) {
      out +=
          FormatNumber(r.status == haptics::TensionStatus::kInvalidInput ? std::nan("") : r.tau(i));
      out += ',';
    }
    out += FormatNumber(r.objective);
    if (options.lost) {
      out += ',';
      out += haptics::TensionStatusName(r.status);
      for (int k = 0; k < 7; ++k) out += "," + FormatNumber(r.lost(k));
      out += "," + FormatNumber(haptics::ForceClosureAt(A, options.geometry.d).margin);
    }
    out += '\n';
    if (out.size() > (1 << 16)) {
      std::cout << out;
      out.clear();
    }
  });
  std::cout << out << std::flush;
  throw CommandExit{0};
}

}  // namespace

void RegisterTensionCommand(CLI::App& app) {
  auto options = std::make_shared<TensionOptions>();
  CLI::App* cmd = app.add_subcommand("tension", "String tensions that display a wrench (batch)");
  cmd->footer(kTensionHelp);
  cmd->add_flag("--batch", options->batch, "Read requests from stdin, write tensions to stdout");
  cmd->add_option("--tmin", options->tau_min,
                  "Lowest string tension [N] (default 0.2; >= 0; keeps strings taut)");
  cmd->add_option("--tmax", options->tau_max, "Highest string tension [N] (default 8; > tmin)");
  cmd->add_option("--weights", options->weights,
                  "S0,S1,S2: moment weight [1/m²], grasp weight [1/m²], tension penalty "
                  "(default 1/d²,1/d²,0.001)")
      ->delimiter(',')
      ->expected(3);
  cmd->add_flag("--lost", options->lost,
                "Append status, the lost wrench (request minus displayed, 7 columns) and the\n"
                "force-closure margin of the pose to every line");
  AddGeometryOptions(*cmd, &options->geometry);
  cmd->callback([options]() { RunTension(*options); });
}

}  // namespace spidarcad::app

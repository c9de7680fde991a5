// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Internal to spidarcad_fem: the check that opens every SolveFree (StaticSolver in
// static_solver.cc, SubstructuredSolver in substructure.cc).
#pragma once

#include <Eigen/Core>
#include <string>

#include "spidarcad/fem/static_solver.h"

namespace spidarcad::fem::detail {

// Whether a solve of a right-hand side with `rows` rows can run on a factorisation that ended
// with `factor` over `num_free` unknowns. When it cannot, *status (converged false) carries the
// factorisation's own message, or says how many rows were given and expected, and the answer
// is false.
inline bool CanSolve(const SolveStatus& factor, Eigen::Index rows, Eigen::Index num_free,
                     SolveStatus* status) {
  if (!factor.converged) {
    status->message = factor.message;
    return false;
  }
  if (rows != num_free) {
    status->message = "SolveFree: right-hand side has " + std::to_string(rows) +
                      " rows, expected " + std::to_string(num_free);
    return false;
  }
  return true;
}

}  // namespace spidarcad::fem::detail

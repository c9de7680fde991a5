// String-length sensing of the SPIDAR-G: the map between an encoder's counts and the length of
// its string. Real-time safe: every function here is noexcept and allocates nothing.
//
// Model of one string (units: m, N; counts are the signed encoder counter since homing):
//   u = n · m                               nominal paid-out length, m = 2π r / counts_per_rev
//   L = offset + gain · u + quadratic · u²  unstretched string length from eyelet to grip, m
//   l = L · (1 + stretch · τ)               geometric length under tension τ, m
// `gain` is the ratio of the effective pulley radius to the nominal one (string thickness and
// pulley tolerance make it differ by several per cent); `quadratic` [1/m] is the winding
// nonlinearity (the effective radius changes as string winds on: dL/du = gain + 2 quadratic u);
// `stretch` [1/N] is the string's compliance as strain per newton; `offset` is the length at
// count zero (the homing pose). The paper's device: 2000 counts/rev, 8 mm pulleys, so
// m = 2π · 8 mm / 2000 = 0.0251327 mm per count.
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#pragma once

#include <array>
#include <cstdint>

#include "spidarcad/haptics/geometry.h"

namespace spidarcad::haptics {

// Raw encoder counters of the 8 strings (string k in code is string k+1 in the paper).
using EncoderCounts = std::array<std::int32_t, kNumStrings>;

// Nominal encoder hardware shared by all strings.
struct EncoderSpec {
  int counts_per_rev = 2000;     // quadrature counts per pulley revolution
  double pulley_radius = 0.008;  // nominal pulley radius, m

  // Nominal string length per count, m (0.0251327e-3 m for the defaults).
  double MetresPerCount() const noexcept;
  // Throws std::invalid_argument naming the field when a value is not finite and positive.
  void Validate() const;
};

// Calibration parameters of one string's count -> length map (see the file comment).
struct StringEncoderParams {
  double offset = 0.0;     // length at count zero, m
  double gain = 1.0;       // effective / nominal pulley radius, dimensionless
  double quadratic = 0.0;  // winding nonlinearity, 1/m
  double stretch = 0.0;    // compliance, strain per newton, 1/N
};

// Length l (m) of one string for `counts` under tension `tension` (N).
double CountsToLength(const EncoderSpec& spec, const StringEncoderParams& params,
                      std::int32_t counts, double tension) noexcept;

// Exact (real-valued) count at which the string has length `length` (m) under `tension` (N):
// the inverse of CountsToLength before quantisation. NaN when no count reproduces the length
// (the quadratic has no real root, or a parameter is not finite).
double LengthToCountsExact(const EncoderSpec& spec, const StringEncoderParams& params,
                           double length, double tension) noexcept;

// LengthToCountsExact rounded to the nearest count and saturated to the int32 range; 0 for NaN.
// The round trip CountsToLength(LengthToCounts(l)) differs from l by at most half a count's
// length (times the local slope gain + 2 quadratic u and the stretch factor).
std::int32_t LengthToCounts(const EncoderSpec& spec, const StringEncoderParams& params,
                            double length, double tension) noexcept;

// Count -> length maps of all 8 strings: what the haptic loop applies to every reading.
struct EncoderCalibration {
  EncoderSpec spec;
  std::array<StringEncoderParams, kNumStrings> strings{};

  // Lengths (m, shape 8) for the counters `counts` under tensions `tension` (N, shape 8).
  Vector8d Lengths(const EncoderCounts& counts, const Vector8d& tension) const noexcept;
  // Lengths with every string unloaded (no stretch correction).
  Vector8d Lengths(const EncoderCounts& counts) const noexcept;

  // The uncalibrated model: nominal radius (gain 1), no nonlinearity, no stretch, and the
  // count reference at the homing pose, so offset_i = home_lengths_i (m, shape 8).
  static EncoderCalibration Nominal(const EncoderSpec& spec, const Vector8d& home_lengths);
  // Throws std::invalid_argument naming the string and field when a parameter is not finite
  // or the gain is not positive.
  void Validate() const;
};

}  // namespace spidarcad::haptics

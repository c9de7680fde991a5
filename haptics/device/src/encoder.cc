// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/encoder.h"

#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

namespace spidarcad::haptics {

double EncoderSpec::MetresPerCount() const noexcept {
  return 2.0 * std::numbers::pi * pulley_radius / static_cast<double>(counts_per_rev);
}

void EncoderSpec::Validate() const {
  if (counts_per_rev <= 0) {
    throw std::invalid_argument("EncoderSpec: field 'counts_per_rev' must be positive, got " +
                                std::to_string(counts_per_rev));
  }
  if (!std::isfinite(pulley_radius) || pulley_radius <= 0.0) {
    throw std::invalid_argument(
        "EncoderSpec: field 'pulley_radius' must be a finite positive length in metres, got " +
        std::to_string(pulley_radius));
  }
}

double CountsToLength(const EncoderSpec& spec, const StringEncoderParams& params,
                      std::int32_t counts, double tension) noexcept {
  const double u = static_cast<double>(counts) * spec.MetresPerCount();
  const double unstretched = params.offset + u * (params.gain + params.quadratic * u);
  return unstretched * (1.0 + params.stretch * tension);
}

double LengthToCountsExact(const EncoderSpec& spec, const StringEncoderParams& params,
                           double length, double tension) noexcept {
  const double stretch_factor = 1.0 + params.stretch * tension;
  if (!(stretch_factor > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  // Solve quadratic·u² + gain·u − (L − offset) = 0 for the root that tends to (L − offset)/gain
  // as quadratic -> 0, in the cancellation-free form u = 2 e / (gain + sqrt(gain² + 4 q e)).
  const double e = length / stretch_factor - params.offset;
  const double discriminant = params.gain * params.gain + 4.0 * params.quadratic * e;
  if (!(discriminant >= 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const double denominator = params.gain + std::sqrt(discriminant);
  if (!(std::abs(denominator) > 0.0)) return std::numeric_limits<double>::quiet_NaN();
  const double u = 2.0 * e / denominator;
  return u / spec.MetresPerCount();
}

std::int32_t LengthToCounts(const EncoderSpec& spec, const StringEncoderParams& params,
                            double length, double tension) noexcept {
  const double n = LengthToCountsExact(spec, params, length, tension);
  if (std::isnan(n)) return 0;
  constexpr double kLo = static_cast<double>(std::numeric_limits<std::int32_t>::min());
  constexpr double kHi = static_cast<double>(std::numeric_limits<std::int32_t>::max());
  const double rounded = std::nearbyint(n);
  if (rounded <= kLo) return std::numeric_limits<std::int32_t>::min();
  if (rounded >= kHi) return std::numeric_limits<std::int32_t>::max();
  return static_cast<std::int32_t>(rounded);
}

Vector8d EncoderCalibration::Lengths(const EncoderCounts& counts,
                                     const Vector8d& tension) const noexcept {
  Vector8d lengths;
  for (int i = 0; i < kNumStrings; ++i) {
    lengths[i] = CountsToLength(spec, strings[i], counts[i], tension[i]);
  }
  return lengths;
}

Vector8d EncoderCalibration::Lengths(const EncoderCounts& counts) const noexcept {
  return Lengths(counts, Vector8d::Zero());
}

EncoderCalibration EncoderCalibration::Nominal(const EncoderSpec& spec,
                                               const Vector8d& home_lengths) {
  EncoderCalibration calibration;
  calibration.spec = spec;
  for (int i = 0; i < kNumStrings; ++i) {
    calibration.strings[i] = StringEncoderParams{home_lengths[i], 1.0, 0.0, 0.0};
  }
  return calibration;
}

void EncoderCalibration::Validate() const {
  spec.Validate();
  for (int i = 0; i < kNumStrings; ++i) {
    const StringEncoderParams& p = strings[i];
    const auto fail = [i](const char* field, double value, const char* what) {
      throw std::invalid_argument("EncoderCalibration: string " + std::to_string(i + 1) +
                                  " field '" + field + "' " + what + ", got " +
                                  std::to_string(value));
    };
    if (!std::isfinite(p.offset)) fail("offset", p.offset, "must be finite");
    if (!std::isfinite(p.gain) || p.gain <= 0.0)
      fail("gain", p.gain, "must be finite and positive");
    if (!std::isfinite(p.quadratic)) fail("quadratic", p.quadratic, "must be finite");
    if (!std::isfinite(p.stretch) || p.stretch < 0.0) {
      fail("stretch", p.stretch, "must be finite and non-negative");
    }
  }
}

}  // namespace spidarcad::haptics

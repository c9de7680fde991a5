// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/haptics/encoder.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <stdexcept>

namespace spidarcad::haptics {
namespace {

TEST(EncoderSpec, MetresPerCountIsThePapersResolution) {
  // Sec. 6: 2000 pulses per revolution on 8 mm pulleys give 0.0251327 mm per count.
  EXPECT_NEAR(EncoderSpec{}.MetresPerCount(), 0.0251327e-3, 1e-10);
  EXPECT_NEAR((EncoderSpec{4000, 0.01}.MetresPerCount()), 2 * M_PI * 0.01 / 4000, 1e-18);
}

TEST(EncoderSpec, ValidateNamesTheBadField) {
  const EncoderSpec no_counts{0, 0.008};
  const EncoderSpec bad_radius{2000, -1.0};
  EXPECT_THAT([&] { no_counts.Validate(); },
              testing::ThrowsMessage<std::invalid_argument>(testing::HasSubstr("counts_per_rev")));
  EXPECT_THAT([&] { bad_radius.Validate(); },
              testing::ThrowsMessage<std::invalid_argument>(testing::HasSubstr("pulley_radius")));
}

TEST(Encoder, CountsToLengthMatchesTheModelByHand) {
  const EncoderSpec spec;
  const StringEncoderParams p{0.35, 1.05, 0.04, 5e-4};
  const double m = 2 * M_PI * 0.008 / 2000;
  const std::int32_t n = -4321;
  const double u = n * m;
  const double expected = (0.35 + 1.05 * u + 0.04 * u * u) * (1 + 5e-4 * 3.0);
  EXPECT_NEAR(CountsToLength(spec, p, n, 3.0), expected, 1e-15);
}

TEST(Encoder, StretchLengthensTheStringInProportionToTension) {
  const EncoderSpec spec;
  const StringEncoderParams p{0.4, 1.0, 0.0, 1e-3};
  const double l0 = CountsToLength(spec, p, 1000, 0.0);
  const double l8 = CountsToLength(spec, p, 1000, 8.0);
  EXPECT_NEAR(l8 / l0, 1.008, 1e-12);
}

TEST(Encoder, ExactInverseRoundTripsIntegerCounts) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> gain(0.9, 1.1), quad(-0.2, 0.2), offset(0.2, 0.5),
      tension(0.0, 8.0);
  std::uniform_int_distribution<std::int32_t> counts(-15000, 15000);
  const EncoderSpec spec;
  for (int trial = 0; trial < 1000; ++trial) {
    const StringEncoderParams p{offset(rng), gain(rng), quad(rng), 4e-4};
    const std::int32_t n = counts(rng);
    const double tau = tension(rng);
    const double l = CountsToLength(spec, p, n, tau);
    EXPECT_NEAR(LengthToCountsExact(spec, p, l, tau), n, 1e-6);
    EXPECT_EQ(LengthToCounts(spec, p, l, tau), n);
  }
}

TEST(Encoder, QuantisationErrorIsAtMostHalfACount) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> length(0.05, 0.75), gain(0.95, 1.1), quad(-0.1, 0.1);
  const EncoderSpec spec;
  const double m = spec.MetresPerCount();
  for (int trial = 0; trial < 2000; ++trial) {
    const StringEncoderParams p{0.39, gain(rng), quad(rng), 0.0};
    const double l = length(rng);
    const std::int32_t n = LengthToCounts(spec, p, l, 0.0);
    // Local slope dl/dn = m (gain + 2 q u); half a count of it bounds the error.
    const double u = n * m;
    const double slope = m * std::abs(p.gain + 2 * p.quadratic * u);
    EXPECT_LE(std::abs(CountsToLength(spec, p, n, 0.0) - l), 0.5 * slope * (1 + 1e-6) + 1e-15);
  }
}

TEST(Encoder, NoRealRootGivesNanAndZeroCounts) {
  const EncoderSpec spec;
  // offset + u − 10 u² never reaches 1 m: the quadratic has no real root.
  const StringEncoderParams p{0.3, 1.0, -10.0, 0.0};
  EXPECT_TRUE(std::isnan(LengthToCountsExact(spec, p, 1.0, 0.0)));
  EXPECT_EQ(LengthToCounts(spec, p, 1.0, 0.0), 0);
  EXPECT_TRUE(std::isnan(LengthToCountsExact(spec, p, std::nan(""), 0.0)));
}

TEST(Encoder, HugeLengthsSaturateTheCounter) {
  const EncoderSpec spec;
  const StringEncoderParams p{0.0, 1.0, 0.0, 0.0};
  EXPECT_EQ(LengthToCounts(spec, p, 1e6, 0.0), std::numeric_limits<std::int32_t>::max());
  EXPECT_EQ(LengthToCounts(spec, p, -1e6, 0.0), std::numeric_limits<std::int32_t>::min());
}

TEST(EncoderCalibration, NominalReadsHomeLengthsAtZeroCounts) {
  Vector8d home;
  home << 0.39, 0.38, 0.37, 0.36, 0.35, 0.34, 0.33, 0.32;
  const EncoderCalibration cal = EncoderCalibration::Nominal(EncoderSpec{}, home);
  const EncoderCounts zero{};
  EXPECT_EQ(cal.Lengths(zero), home);
  EncoderCounts counts{};
  counts[2] = 1000;
  EXPECT_NEAR(cal.Lengths(counts)[2], 0.37 + 1000 * EncoderSpec{}.MetresPerCount(), 1e-15);
}

TEST(EncoderCalibration, ValidateNamesStringAndField) {
  EncoderCalibration cal = EncoderCalibration::Nominal(EncoderSpec{}, Vector8d::Constant(0.4));
  EXPECT_NO_THROW(cal.Validate());
  cal.strings[4].gain = -1.0;
  EXPECT_THAT([&] { cal.Validate(); },
              testing::ThrowsMessage<std::invalid_argument>(
                  testing::AllOf(testing::HasSubstr("string 5"), testing::HasSubstr("gain"))));
  cal.strings[4].gain = 1.0;
  cal.strings[0].offset = std::nan("");
  EXPECT_THAT([&] { cal.Validate(); },
              testing::ThrowsMessage<std::invalid_argument>(
                  testing::AllOf(testing::HasSubstr("string 1"), testing::HasSubstr("offset"))));
}

}  // namespace
}  // namespace spidarcad::haptics

// Tests of the always-on check macro (base/include/spidarcad/base/check.h).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "spidarcad/base/check.h"

#include <gtest/gtest.h>

namespace {

int Evaluations(int* count) {
  ++*count;
  return 1;
}

TEST(Check, PassesSilentlyAndEvaluatesTheConditionOnce) {
  int count = 0;
  SPIDARCAD_CHECK(Evaluations(&count) == 1);
  SPIDARCAD_CHECK_MSG(Evaluations(&count) == 1, "never shown");
  EXPECT_EQ(count, 2);
}

TEST(CheckDeathTest, AbortsNamingTheConditionFileAndMessageWhenFalse) {
  const int nodes = 3;
  EXPECT_DEATH(SPIDARCAD_CHECK(nodes == 4),
               "internal error at .*check_test.cc:[0-9]+: check 'nodes == 4' failed");
  EXPECT_DEATH(SPIDARCAD_CHECK_MSG(nodes < 0, "node count went negative"),
               "check 'nodes < 0' failed: node count went negative");
}

}  // namespace

// Fuzz harness: the stdin CSV of `spidarcad tension --batch` (see batch_fuzz_common.h).
// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
#include "batch_fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return spidarcad::fuzz::RunBatchHarness("tension", spidarcad::app::RegisterTensionCommand, data,
                                          size);
}

// Copyright the spidarcad authors. SPDX-License-Identifier: AGPL-3.0-or-later
// Command-line handling shared by the benchmark programs: `--help` says what the program
// measures before Google Benchmark's own flags, and an unknown argument is an error (exit
// status 2) instead of being ignored.
#pragma once

#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>

namespace spidarcad::bench {

namespace internal {
inline const char*& Description() {
  static const char* description = "";
  return description;
}
inline void PrintHelp() {
  std::printf("%s\n\nOptions (Google Benchmark):\n", Description());
  benchmark::PrintDefaultHelp();
}
}  // namespace internal

// main() of a Google Benchmark program: parses Google Benchmark's flags (--help prints
// `description`, what the program measures, then the flags), rejects any other argument with
// exit status 2, then runs `before` (e.g. a table printed ahead of the benchmarks) and the
// registered benchmarks, then `after` (e.g. tables of the figures gathered).
inline int RunBenchmarkMain(int argc, char** argv, const char* description,
                            void (*before)() = nullptr, void (*after)() = nullptr) {
  internal::Description() = description;
  benchmark::Initialize(&argc, argv, internal::PrintHelp);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
    std::fprintf(stderr, "Run %s --help for what it measures and the flags it takes.\n", argv[0]);
    return 2;
  }
  if (before != nullptr) before();
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  if (after != nullptr) after();
  return 0;
}

// Prints the machine's load average (1, 5 and 15 minutes) as a sentence, for the tables printed
// after a run: figures on a loaded machine are not those of an idle one.
inline void PrintLoadAverage() {
  double load[3] = {-1, -1, -1};
  if (getloadavg(load, 3) != 3) load[0] = load[1] = load[2] = -1;
  std::printf("\nLoad average at the end %.2f %.2f %.2f.", load[0], load[1], load[2]);
}

}  // namespace spidarcad::bench

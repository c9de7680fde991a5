// Paths the tests need: the source tree, the tests' output directory and the built spidarcad
// executable. They are compiled into tests/support/paths.cc only, so that every other test file's
// command line is the same in every checkout (compiler caches then share the objects).
//
// Force-included into every test file (tests/CMakeLists.txt), so the three names below work
// without an #include. Each is a `const char*` to an absolute path without a trailing slash.
#pragma once

namespace spidarcad::test_support {

// The repository's source directory (assets/, tests/golden/ live under it).
const char* SourceDir();
// A writable directory for the files tests produce (build/tests/output).
const char* TestOutputDir();
// The built spidarcad executable; empty when the app is not built.
const char* SpidarcadExe();

}  // namespace spidarcad::test_support

#define SPIDARCAD_SOURCE_DIR (::spidarcad::test_support::SourceDir())
#define SPIDARCAD_TEST_OUTPUT_DIR (::spidarcad::test_support::TestOutputDir())
#define SPIDARCAD_EXE (::spidarcad::test_support::SpidarcadExe())

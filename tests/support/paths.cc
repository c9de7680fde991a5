#include "support/paths.h"

namespace spidarcad::test_support {

const char* SourceDir() { return SPIDARCAD_TEST_SOURCE_DIR_VALUE; }
const char* TestOutputDir() { return SPIDARCAD_TEST_OUTPUT_DIR_VALUE; }
const char* SpidarcadExe() { return SPIDARCAD_TEST_EXE_VALUE; }

}  // namespace spidarcad::test_support

# Writes OUT, a header defining SPIDARCAD_GIT_COMMIT: the short commit of the checkout at SOURCE,
# with "-dirty" when tracked files differ from it ("unknown" outside a git checkout). Run at every
# build (app/CMakeLists.txt, target spidarcad_git_stamp); the file is rewritten only when its
# content changes, so nothing recompiles between builds of the same commit.
execute_process(COMMAND git rev-parse --short HEAD WORKING_DIRECTORY ${SOURCE}
                OUTPUT_VARIABLE commit OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
execute_process(COMMAND git status --porcelain --untracked-files=no WORKING_DIRECTORY ${SOURCE}
                OUTPUT_VARIABLE dirty OUTPUT_STRIP_TRAILING_WHITESPACE ERROR_QUIET)
if(NOT commit)
  set(commit "unknown")
elseif(dirty)
  string(APPEND commit "-dirty")
endif()
set(content "// Generated at build time by cmake/git_stamp.cmake.\n#pragma once\n#define SPIDARCAD_GIT_COMMIT \"${commit}\"\n")
set(old "")
if(EXISTS ${OUT})
  file(READ ${OUT} old)
endif()
if(NOT old STREQUAL content)
  file(WRITE ${OUT} "${content}")
endif()

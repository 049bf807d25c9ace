# Fails when a CMake file of the project looks for a package without REQUIRED other than
# through drape_find_optional (cmake/DrapeOptional.cmake): such a package is optional in fact
# but escapes -DDRAPE_OPTIONAL_PACKAGES=OFF, the build that proves a fresh machine works.
#   cmake -DSOURCE_DIR=<project> -P optional_packages_test.cmake
file(GLOB_RECURSE files RELATIVE ${SOURCE_DIR}
  ${SOURCE_DIR}/CMakeLists.txt ${SOURCE_DIR}/*/CMakeLists.txt ${SOURCE_DIR}/*.cmake)
set(bad "")
foreach(f IN LISTS files)
  if(f MATCHES "^(build|\\.git|python/build)" OR f MATCHES "/_deps/" OR f STREQUAL "cmake/DrapeOptional.cmake")
    continue()
  endif()
  file(READ ${SOURCE_DIR}/${f} text)
  string(REGEX REPLACE "#[^\n]*" "" text "${text}")  # comments may name find_package
  string(REGEX MATCHALL "[^_a-zA-Z]find_package\\([^)]*\\)" calls "${text}")
  foreach(call IN LISTS calls)
    if(NOT call MATCHES "REQUIRED")
      string(STRIP "${call}" call)
      string(APPEND bad "\n  ${f}: ${call}")
    endif()
  endforeach()
endforeach()
if(bad)
  message(FATAL_ERROR "optional packages must be looked for with drape_find_optional (cmake/DrapeOptional.cmake),"
                      " not a bare find_package:${bad}")
endif()
message(STATUS "every find_package is REQUIRED or goes through drape_find_optional")

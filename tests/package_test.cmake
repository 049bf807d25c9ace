# ctest -P script: proves the installed package works for a program that knows only
# find_package(drape). Installs BUILD_DIR into WORK_DIR/prefix, configures and builds
# SOURCE_DIR (apps/example) against it in WORK_DIR/build, runs the program and checks that
# it reports its own physics check (free fall against the closed form) as passed. Also
# checks that docs/api.md (DOC) lists the example verbatim.
foreach(var BUILD_DIR SOURCE_DIR WORK_DIR CXX DOC)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "package_test.cmake: -D${var}=... is required")
  endif()
endforeach()

# docs/api.md shows the example in full; it must be this very file, so the docs compile.
file(READ ${DOC} doc)
file(READ ${SOURCE_DIR}/main.cpp example)
set(begin "<!-- example:begin -->\n```cpp\n")
string(FIND "${doc}" "${begin}" start)
string(FIND "${doc}" "```\n<!-- example:end -->" stop)
if(start EQUAL -1 OR stop EQUAL -1)
  message(FATAL_ERROR "${DOC} lacks the example:begin/example:end block around the example")
endif()
string(LENGTH "${begin}" begin_length)
math(EXPR start "${start} + ${begin_length}")
math(EXPR length "${stop} - ${start}")
string(SUBSTRING "${doc}" ${start} ${length} listed)
if(NOT listed STREQUAL example)
  message(FATAL_ERROR "the example in ${DOC} differs from ${SOURCE_DIR}/main.cpp: copy the file into the doc")
endif()

file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)

function(run step)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${step} failed (${rc}):\n${out}\n${err}")
  endif()
  set(output "${out}" PARENT_SCOPE)
endfunction()

run("install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f include/drape/drape.h include/drape/world.h)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "install did not put ${f} into the prefix")
  endif()
endforeach()
if(EXISTS ${prefix}/include/sheet_data.h OR EXISTS ${prefix}/include/drape/sheet_data.h)
  message(FATAL_ERROR "a private engine header was installed")
endif()

# Only the temporary prefix is searched, so a drape elsewhere on the machine cannot be found.
run("configure example" ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_PREFIX_PATH=${prefix}
    -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF -DCMAKE_FIND_USE_SYSTEM_PACKAGE_REGISTRY=OFF)
run("build example" ${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run("run example" ${WORK_DIR}/build/drape-example)
if(NOT output MATCHES "free fall matches")
  message(FATAL_ERROR "drape-example did not report a passing free-fall check:\n${output}")
endif()
file(REMOVE_RECURSE ${WORK_DIR})
message(STATUS "package test passed:\n${output}")

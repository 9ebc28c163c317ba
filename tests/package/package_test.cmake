# cmake -DBUILD_DIR=… -DSOURCE_DIR=… -DWORK_DIR=… -DGENERATOR=… -DCXX_COMPILER=… -DBUILD_TYPE=…
#       -P package_test.cmake
# Installs the (already built) MillKit build into WORK_DIR/prefix, then uses it as a client would.
# Fails (FATAL_ERROR) at the first step that does not do what a client expects.
if(NOT BUILD_TYPE)
  set(BUILD_TYPE Release)
endif()
set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})

function(run what)
  cmake_parse_arguments(ARG "" "EXPECT_FAILURE" "COMMAND;OUTPUT_MATCHES" ${ARGN})
  execute_process(COMMAND ${ARG_COMMAND} RESULT_VARIABLE code OUTPUT_VARIABLE out
                  ERROR_VARIABLE err WORKING_DIRECTORY ${SOURCE_DIR})
  if(ARG_EXPECT_FAILURE)
    if(code EQUAL 0)
      message(FATAL_ERROR "${what}: succeeded but should have failed\n${out}\n${err}")
    endif()
  elseif(NOT code EQUAL 0)
    message(FATAL_ERROR "${what}: exit ${code}\n--- stdout\n${out}\n--- stderr\n${err}")
  endif()
  foreach(pattern IN LISTS ARG_OUTPUT_MATCHES)
    if(NOT "${out}${err}" MATCHES "${pattern}")
      message(FATAL_ERROR "${what}: output does not match '${pattern}'\n--- stdout\n${out}\n"
                          "--- stderr\n${err}")
    endif()
  endforeach()
  message(STATUS "${what}: ok")
  set(run_output "${out}" PARENT_SCOPE)
endfunction()

string(TIMESTAMP started "%s")

# 1. Install: copies the built libraries, headers, the CLI and the package files.
run("cmake --install" COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix}
                              --config ${BUILD_TYPE})
file(GLOB config_file ${prefix}/lib*/cmake/MillKit/MillKitConfig.cmake
                      ${prefix}/lib/*/cmake/MillKit/MillKitConfig.cmake)
if(NOT config_file)
  message(FATAL_ERROR "no MillKitConfig.cmake under ${prefix}")
endif()
if(NOT EXISTS ${prefix}/include/millkit/version.h)
  message(FATAL_ERROR "millkit/version.h is not installed")
endif()

# 2. Installed public headers: no third-party headers but Eigen (and the standard library).
file(GLOB_RECURSE headers ${prefix}/include/millkit/*.h)
foreach(header IN LISTS headers)
  file(STRINGS ${header} includes REGEX "^[ \t]*#[ \t]*include")
  foreach(line IN LISTS includes)
    # A millkit header may carry such a name (millkit/optimize/leveller/nlopt_inverse.h).
    if(line MATCHES "nlopt|toml|ceres|sundials|cvode|nvector|CLI|nlohmann|matio" AND
       NOT line MATCHES "[<\"]millkit/")
      message(FATAL_ERROR "${header} includes a third-party header: ${line}")
    endif()
    if(line MATCHES "\"" AND NOT line MATCHES "\"millkit/")
      message(FATAL_ERROR "${header} includes a header that is not installed: ${line}")
    endif()
  endforeach()
endforeach()

# 3. The examples against the installed package: configure, build.
set(common -G ${GENERATOR} -DCMAKE_CXX_COMPILER=${CXX_COMPILER} -DCMAKE_BUILD_TYPE=${BUILD_TYPE}
           -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_PACKAGE_NO_PACKAGE_REGISTRY=ON)
run("configure examples/" COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples -B ${WORK_DIR}/examples
                                   ${common}
    OUTPUT_MATCHES "Build files have been written")
run("build examples/" COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/examples -j 2)
# The examples were built from the installed headers and libraries, not from the source tree.
file(READ ${WORK_DIR}/examples/CMakeCache.txt cache)
if(NOT cache MATCHES "MillKit_DIR:PATH=${prefix}/")
  message(FATAL_ERROR "examples/ did not find MillKit in ${prefix}")
endif()

# 4. Each example on the bundled data (they check their own answers: exit 0 means they held).
set(bin ${WORK_DIR}/examples)
run("simulate_kd" COMMAND ${bin}/simulate_kd/simulate_kd datasets/scenes/mill5_bite.toml
    OUTPUT_MATCHES "mill5 bite" "upper_spindle" "lower_spindle")
run("fit_record" COMMAND ${bin}/fit_record/fit_record datasets/scenes/mill5_bite.toml
                         datasets/records/mill5_two_spindles.csv
                         datasets/records/mill5_two_spindles.fit.toml
    OUTPUT_MATCHES "upper_spindle.backlash" "verdict: ok")
run("kd_sweep" COMMAND ${bin}/kd_sweep/kd_sweep datasets/scenes/mill5_bite.toml
    OUTPUT_MATCHES "5 cases \\(0 failed\\)" "upper_spindle.backlash")

# 5. Components: an unknown REQUIRED component fails find_package with a message naming it; known
#    components alone configure.
function(probe name components)
  file(MAKE_DIRECTORY ${WORK_DIR}/${name})
  file(WRITE ${WORK_DIR}/${name}/CMakeLists.txt
       "cmake_minimum_required(VERSION 3.25)\nproject(${name} LANGUAGES CXX)\n"
       "find_package(MillKit 0.1 REQUIRED COMPONENTS ${components})\n"
       "foreach(c ${components})\n  if(NOT TARGET MillKit::\${c})\n"
       "    message(FATAL_ERROR \"no target MillKit::\${c}\")\n  endif()\nendforeach()\n")
endfunction()
probe(probe_unknown "driveline nonsense")
run("find_package(MillKit REQUIRED COMPONENTS driveline nonsense)"
    COMMAND ${CMAKE_COMMAND} -S ${WORK_DIR}/probe_unknown -B ${WORK_DIR}/probe_unknown/build ${common}
    EXPECT_FAILURE TRUE OUTPUT_MATCHES "MillKit has no component 'nonsense'")
probe(probe_known "optimize balancer leveller")
run("find_package(MillKit REQUIRED COMPONENTS optimize balancer leveller)"
    COMMAND ${CMAKE_COMMAND} -S ${WORK_DIR}/probe_known -B ${WORK_DIR}/probe_known/build ${common})

string(TIMESTAMP finished "%s")
math(EXPR seconds "${finished} - ${started}")
message(STATUS "package test: ${seconds} s")

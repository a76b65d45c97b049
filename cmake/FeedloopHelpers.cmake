# feedloop_add_test(NAME SOURCES a.cpp b.cpp LIBS lib1 lib2 [LABELS l1 l2] [TIMEOUT s]
#                   [LONG_TESTS gtest-filter] [OPTIMIZED])
# One GoogleTest executable; each TEST becomes a ctest case. Tests run from the build directory
# and find repository files through FEEDLOOP_SOURCE_DIR and the corpus through
# FEEDLOOP_SHARED_DIR (absent in a user's clone: such tests GTEST_SKIP with a message).
# The compile options and definitions every test target has (and the owner of the tests'
# precompiled header has, feedloop_add_test_pch below).
function(_feedloop_test_flags name)
  cmake_parse_arguments(F "OPTIMIZED" "" "" ${ARGN})
  # Allocation-counting tests replace operator new/delete with malloc/free; GCC then reports
  # -Wmismatched-new-delete inside gtest's own allocations (a false positive).
  target_compile_options(${name} PRIVATE $<$<CXX_COMPILER_ID:GNU>:-Wno-mismatched-new-delete>)
  # The test programs' own units at -Og in an optimized GCC build (after the config's -O2, so it
  # wins): their code drives the libraries, which keep -O2 and do the simulating; -Og compiles
  # a test unit in ~60-80 % of the time -O2 takes (docs/decisions.md, "CI time").
  target_compile_options(${name} PRIVATE
    $<$<AND:$<CXX_COMPILER_ID:GNU>,$<CONFIG:RelWithDebInfo,Release>>:-Og>)
  # Under the sanitizers the test programs' own units at -O0 (the libraries keep -O1): 25 % less
  # of their compile time over 5 units measured, ~70 s of the sanitizer build. The tests' PCH owner
  # has the same flags (__OPTIMIZE__ must match).
  # OPTIMIZED: a program whose own code does the heavy work (a step-by-step check of whole
  # programs) keeps the build's -O1 and compiles without the tests' PCH: at -O0 four checks took
  # 9 -> 44, 13 -> 32, 6 -> 32 and 5 -> 25 s under the sanitizers.
  if(FEEDLOOP_SANITIZE AND NOT F_OPTIMIZED)
    target_compile_options(${name} PRIVATE -O0)
  endif()
  target_compile_definitions(${name} PRIVATE
    FEEDLOOP_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
    FEEDLOOP_SHARED_DIR="${CMAKE_SOURCE_DIR}/../shared"
    FEEDLOOP_BINARY_DIR="${CMAKE_BINARY_DIR}")
endfunction()

# feedloop_add_test_pch(): the precompiled header every test target reuses (option FEEDLOOP_PCH,
# docs/decisions.md "CI time"): gtest, gmock, nlohmann/json, Eigen and the standard headers most
# tests include. Only third-party and standard headers, whose content depends on no macro that
# differs between test targets: GCC rejects a PCH when a macro it used is defined differently
# (-Winvalid-pch, an error here) and clang errors on a contradicting command-line macro. So the
# owner, feedloop_test_pch, carries only what every test has (_feedloop_test_flags); a test's own
# definitions (FEEDLOOPD_PATH, FUZZ_CORPUS, ...) are macros these headers never read.
function(feedloop_add_test_pch)
  if(NOT FEEDLOOP_PCH OR TARGET feedloop_test_pch)
    return()
  endif()
  set(anchor ${CMAKE_BINARY_DIR}/feedloop_test_pch.cpp)
  file(CONFIGURE OUTPUT ${anchor} CONTENT "// The object that builds the tests' precompiled header.\n")
  add_library(feedloop_test_pch OBJECT ${anchor})
  target_link_libraries(feedloop_test_pch PRIVATE GTest::gtest GTest::gmock nlohmann_json::nlohmann_json
                        Eigen3::Eigen)
  _feedloop_test_flags(feedloop_test_pch)
  target_precompile_headers(feedloop_test_pch PRIVATE
    <gtest/gtest.h> <gmock/gmock.h> <nlohmann/json.hpp> <Eigen/Dense>
    <algorithm> <array> <atomic> <chrono> <cmath> <cstdint> <cstdio> <cstdlib> <cstring>
    <deque> <filesystem> <fstream> <functional> <limits> <map> <memory> <mutex> <optional>
    <random> <set> <sstream> <string> <thread> <vector>)
endfunction()

function(feedloop_add_test name)
  cmake_parse_arguments(T "OPTIMIZED" "TIMEOUT;LONG_TESTS;REALTIME_TESTS;COST" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main GTest::gmock)
  set(_opt)
  if(T_OPTIMIZED)
    set(_opt OPTIMIZED)
  endif()
  _feedloop_test_flags(${name} ${_opt})
  if(FEEDLOOP_PCH AND NOT (T_OPTIMIZED AND FEEDLOOP_SANITIZE))
    feedloop_add_test_pch()
    target_precompile_headers(${name} REUSE_FROM feedloop_test_pch)
  endif()
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  # LONG_TESTS "Suite.Name:Suite.Other" (a gtest filter): those cases of the program get the label
  # `long` (left out of scripts/test.sh, `ctest -L long` runs them), the others its labels.
  # REALTIME_TESTS the same with the label `realtime`: cases whose assertion is about the wall
  # clock (a thread keeping pace), run one at a time after the others (scripts/test.sh).
  set(others_filter)
  set(_excluded)
  if(T_LONG_TESTS)
    list(APPEND _excluded ${T_LONG_TESTS})
    gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 TEST_FILTER "${T_LONG_TESTS}"
      PROPERTIES TIMEOUT ${T_TIMEOUT} LABELS "long")
  endif()
  if(T_REALTIME_TESTS)
    list(APPEND _excluded ${T_REALTIME_TESTS})
    gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 TEST_FILTER "${T_REALTIME_TESTS}"
      PROPERTIES TIMEOUT ${T_TIMEOUT} LABELS "realtime")
  endif()
  if(_excluded)
    list(JOIN _excluded ":" _excluded_filter)
    set(others_filter TEST_FILTER "-${_excluded_filter}")
  endif()
  # COST N: ctest -j starts the costliest tests first (without its timing data from an earlier
  # run, as in a fresh clone, it starts them in the order they were declared, and a long test that
  # starts last runs alone at the end: docs/decisions.md, "CI time"). N ~ the seconds it takes.
  set(_cost)
  if(T_COST)
    set(_cost COST ${T_COST})
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 ${others_filter}
    PROPERTIES TIMEOUT ${T_TIMEOUT} LABELS "${T_LABELS}" ${_cost})
  # The sanitizer stage of scripts/test.sh runs only the tests without these labels, and builds
  # only what it runs (target `sanitizer_tests`, top-level CMakeLists.txt).
  # alloc: tests that count allocations, which count nothing under the sanitizers (their
  # allocator is the sanitizer's; tests/common/malloc_counter.hpp). numeric: the unit tests of the
  # numerical modules (models, plant simulators, fits, the maneuvering controller), whose inputs are
  # the project's own; their code runs under the sanitizers inside the machine tests (engine_*,
  # cli, daemon) that stay in that stage (docs/decisions.md, "CI time").
  set(_skipped_under_sanitizers slow realtime long browser alloc numeric)
  # Label fuzz_replay (tests/fuzz: a fuzz target's corpus replayed through its entry point): a
  # build with the fuzz targets leaves them out too, because its fuzz stage (fuzz/run.sh) runs
  # every file of the same corpus, reproducers included, through the same code first.
  if(FEEDLOOP_FUZZ AND CMAKE_CXX_COMPILER_ID MATCHES "Clang")
    list(APPEND _skipped_under_sanitizers fuzz_replay)
  endif()
  set(_runs_under_sanitizers TRUE)
  foreach(label IN LISTS T_LABELS)
    if(label IN_LIST _skipped_under_sanitizers)
      set(_runs_under_sanitizers FALSE)
    endif()
  endforeach()
  if(_runs_under_sanitizers)
    set_property(GLOBAL APPEND PROPERTY FEEDLOOP_SANITIZER_TESTS ${name})
    # FEEDLOOP_ALL_TESTS_IN_ALL OFF (scripts/test.sh's GCC build, before its sanitizer build): a
    # program whose every case the sanitizer stage runs is not built here (ctest lists it as
    # <name>_NOT_BUILT). A program with wall-clock or long cases is, for those cases.
    if(NOT FEEDLOOP_ALL_TESTS_IN_ALL AND NOT T_REALTIME_TESTS AND NOT T_LONG_TESTS)
      set_target_properties(${name} PROPERTIES EXCLUDE_FROM_ALL TRUE)
    endif()
  endif()
endfunction()

# _feedloop_targets_under(OUT d1 d2 ...): every target defined under those source directories,
# their subdirectories included.
function(_feedloop_targets_under out)
  set(dirs ${ARGN})
  set(targets)
  while(dirs)
    list(POP_FRONT dirs dir)
    get_property(subdirs DIRECTORY ${dir} PROPERTY SUBDIRECTORIES)
    list(APPEND dirs ${subdirs})
    get_property(dir_targets DIRECTORY ${dir} PROPERTY BUILDSYSTEM_TARGETS)
    list(APPEND targets ${dir_targets})
  endwhile()
  set(${out} ${targets} PARENT_SCOPE)
endfunction()

# feedloop_add_library_pch(DIRS d1 d2 ...): one precompiled header (the standard headers most
# modules include, and Eigen) reused by every library and program defined under those source
# directories (option FEEDLOOP_PCH, docs/decisions.md "CI time"). Called once from the top-level
# CMakeLists.txt after the modules, so no module's CMakeLists.txt names it. Left out:
# - the test programs (their own PCH, feedloop_add_test_pch above);
# - feedloop_axis_loop, built with -fno-exceptions -fno-rtti (a PCH must be built with the same);
# - the fuzz targets, compiled with -fsanitize=fuzzer (also a flag the PCH must share);
# - FEEDLOOP_O0_UNDER_SANITIZERS, at -O0 in the sanitizer build (__OPTIMIZE__ must match).
function(feedloop_add_library_pch)
  cmake_parse_arguments(P "" "" "DIRS" ${ARGN})
  if(NOT FEEDLOOP_PCH)
    return()
  endif()
  set(anchor ${CMAKE_BINARY_DIR}/feedloop_lib_pch.cpp)
  file(CONFIGURE OUTPUT ${anchor} CONTENT "// The object that builds the libraries' precompiled header.\n")
  add_library(feedloop_lib_pch OBJECT ${anchor})
  target_link_libraries(feedloop_lib_pch PRIVATE Eigen3::Eigen)
  target_precompile_headers(feedloop_lib_pch PRIVATE
    <Eigen/Dense>
    <algorithm> <array> <atomic> <chrono> <cmath> <complex> <cstddef> <cstdint> <cstdio>
    <cstdlib> <cstring> <deque> <filesystem> <fstream> <functional> <limits> <map> <memory>
    <mutex> <numbers> <optional> <sstream> <string> <string_view> <thread> <utility> <vector>)
  _feedloop_targets_under(targets ${P_DIRS})
  get_property(fuzzers GLOBAL PROPERTY FEEDLOOP_FUZZERS)
  foreach(t IN LISTS targets)
    get_target_property(type ${t} TYPE)
    if(NOT type MATCHES "^(STATIC_LIBRARY|EXECUTABLE)$" OR t STREQUAL "feedloop_axis_loop"
       OR t IN_LIST fuzzers OR t IN_LIST FEEDLOOP_O0_UNDER_SANITIZERS)
      continue()
    endif()
    target_precompile_headers(${t} REUSE_FROM feedloop_lib_pch)
  endforeach()
endfunction()

# feedloop_add_fuzz_coverage(DIRS d1 d2 ...): libFuzzer's coverage instrumentation (what
# -fsanitize=fuzzer-no-link turns on, spelled as -fsanitize-coverage= so that the libraries'
# precompiled header, built without it, stays usable: clang refuses a PCH whose -fsanitize= set
# differs) for every library and program defined under those source directories. The fuzz
# targets get theirs from -fsanitize=fuzzer (fuzz/CMakeLists.txt).
function(feedloop_add_fuzz_coverage)
  cmake_parse_arguments(P "" "" "DIRS" ${ARGN})
  _feedloop_targets_under(targets ${P_DIRS})
  get_property(fuzzers GLOBAL PROPERTY FEEDLOOP_FUZZERS)
  foreach(t IN LISTS targets)
    get_target_property(type ${t} TYPE)
    if(NOT type MATCHES "^(STATIC_LIBRARY|EXECUTABLE|OBJECT_LIBRARY)$" OR t IN_LIST fuzzers)
      continue()
    endif()
    target_compile_options(${t} PRIVATE
      -fsanitize-coverage=inline-8bit-counters,indirect-calls,trace-cmp,pc-table)
  endforeach()
endfunction()

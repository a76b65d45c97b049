# feedloop_add_test(NAME SOURCES a.cpp b.cpp LIBS lib1 lib2 [LABELS l1 l2] [TIMEOUT s])
# One GoogleTest executable; each TEST becomes a ctest case. Tests run from the build directory
# and find repository files through FEEDLOOP_SOURCE_DIR and the corpus through
# FEEDLOOP_SHARED_DIR (absent in a user's clone: such tests GTEST_SKIP with a message).
function(feedloop_add_test name)
  cmake_parse_arguments(T "" "TIMEOUT" "SOURCES;LIBS;LABELS" ${ARGN})
  add_executable(${name} ${T_SOURCES})
  target_link_libraries(${name} PRIVATE ${T_LIBS} GTest::gtest GTest::gtest_main GTest::gmock)
  # Allocation-counting tests replace operator new/delete with malloc/free; GCC then reports
  # -Wmismatched-new-delete inside gtest's own allocations (a false positive).
  target_compile_options(${name} PRIVATE $<$<CXX_COMPILER_ID:GNU>:-Wno-mismatched-new-delete>)
  target_compile_definitions(${name} PRIVATE
    FEEDLOOP_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
    FEEDLOOP_SHARED_DIR="${CMAKE_SOURCE_DIR}/../shared"
    FEEDLOOP_BINARY_DIR="${CMAKE_BINARY_DIR}")
  if(NOT T_TIMEOUT)
    set(T_TIMEOUT 300)
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60
    PROPERTIES TIMEOUT ${T_TIMEOUT} LABELS "${T_LABELS}")
  # The sanitizer stage of scripts/test.sh runs only the tests without these labels, and builds
  # only what it runs (target `sanitizer_tests`, top-level CMakeLists.txt).
  set(_skipped_under_sanitizers slow realtime long browser)
  set(_runs_under_sanitizers TRUE)
  foreach(label IN LISTS T_LABELS)
    if(label IN_LIST _skipped_under_sanitizers)
      set(_runs_under_sanitizers FALSE)
    endif()
  endforeach()
  if(_runs_under_sanitizers)
    set_property(GLOBAL APPEND PROPERTY FEEDLOOP_SANITIZER_TESTS ${name})
  endif()
endfunction()

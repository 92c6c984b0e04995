# Helpers so every target gets the same warnings and tests are declared in one line.

function(moslam_warnings target)
  target_compile_options(${target} PRIVATE
    $<$<CXX_COMPILER_ID:GNU,Clang>:-Wall -Wextra -Wpedantic -Wshadow -Wnon-virtual-dtor
      -Wold-style-cast -Wcast-align -Woverloaded-virtual -Wconversion -Wno-sign-conversion>)
endfunction()

# moslam_library(name SOURCES a.cc b.cc DEPS dep1 dep2)
function(moslam_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(${name} ${ARG_SOURCES})
  add_library(moslam::${name} ALIAS ${name})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR}/src)
  target_link_libraries(${name} PUBLIC ${ARG_DEPS})
  moslam_warnings(${name})
endfunction()

# moslam_test(name SOURCES a_test.cc DEPS lib)  -> a GoogleTest executable registered with CTest.
function(moslam_test name)
  if(NOT MOSLAM_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  # The serial OpenMP runtime of CHOLMOD (solver/serial_openmp.cc) for every test.
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main
    moslam_serial_openmp)
  target_compile_definitions(${name} PRIVATE
    MOSLAM_DATASETS_DIR="${MOSLAM_DATASETS_DIR}"
    MOSLAM_BINARY_DIR="${PROJECT_BINARY_DIR}")
  moslam_warnings(${name})
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60)
endfunction()

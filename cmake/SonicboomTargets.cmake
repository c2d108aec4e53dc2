# Helpers that give every module library and test the same shape and flags.

set(SONICBOOM_WARNINGS -Wall -Wextra -Wno-unused-parameter)

# sonicboom_add_library(<module> SOURCES ... PUBLIC_DEPS ... PRIVATE_DEPS ...)
# builds sonicboom_<module> with public headers in <module>/include and alias sonicboom::<module>
function(sonicboom_add_library module)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_DEPS;PRIVATE_DEPS" ${ARGN})
  add_library(sonicboom_${module} STATIC ${ARG_SOURCES})
  add_library(sonicboom::${module} ALIAS sonicboom_${module})
  target_include_directories(sonicboom_${module}
    PUBLIC ${CMAKE_CURRENT_SOURCE_DIR}/include
    PRIVATE ${CMAKE_CURRENT_SOURCE_DIR})
  target_link_libraries(sonicboom_${module} PUBLIC ${ARG_PUBLIC_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
  target_compile_options(sonicboom_${module} PRIVATE ${SONICBOOM_WARNINGS})
endfunction()

# sonicboom_add_test(<name> SOURCES ... DEPS ... GROUPS "<label>=<gtest filter>" ...)
# Every test gets one ctest label: a GROUPS entry's label for the tests its filter selects
# (suites or single tests, ':'-separated; groups must not overlap), `unit` for the rest. Labels:
# unit (fast logic checks), physics (physical values against theory), golden (stored reference
# outputs), slow (end-to-end runs of the CLI, training).
function(sonicboom_add_test name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;GROUPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest_main GTest::gmock)
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR}/tests)
  target_compile_options(${name} PRIVATE ${SONICBOOM_WARNINGS})
  target_compile_definitions(${name} PRIVATE
    SONICBOOM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    SONICBOOM_CLI="$<TARGET_FILE:sonicboom>")
  # the tests (and the CLI runs they start) solve and cache modes under the build tree, never in
  # the user's home directory
  set(environment "SONICBOOM_CACHE_DIR=${CMAKE_BINARY_DIR}/test-cache/modes")
  # the suite's solves (the reproduce test's structure pool alone is about 2.3 GB) stay cached
  # between tests under a cap of their own instead of the user's default 1 GB budget
  set(budget "SONICBOOM_CACHE_MAX_BYTES=set:8G")
  set(grouped "")
  foreach(group IN LISTS ARG_GROUPS)
    string(FIND "${group}" "=" eq)
    string(SUBSTRING "${group}" 0 ${eq} label)
    math(EXPR first "${eq} + 1")
    string(SUBSTRING "${group}" ${first} -1 filter)
    gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 120 TEST_FILTER "${filter}"
      PROPERTIES LABELS "${label}" ENVIRONMENT "${environment}"
                 ENVIRONMENT_MODIFICATION "${budget}"
      WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
    list(APPEND grouped "${filter}")
  endforeach()
  set(rest "")
  if(grouped)
    list(JOIN grouped ":" negative)
    set(rest "-${negative}")
  endif()
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST DISCOVERY_TIMEOUT 120 TEST_FILTER "${rest}"
    PROPERTIES LABELS unit ENVIRONMENT "${environment}" ENVIRONMENT_MODIFICATION "${budget}"
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
endfunction()

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

# sonicboom_add_test(<name> SOURCES ... DEPS ... LABELS ...)
function(sonicboom_add_test name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest_main GTest::gmock)
  target_include_directories(${name} PRIVATE ${PROJECT_SOURCE_DIR}/tests)
  target_compile_options(${name} PRIVATE ${SONICBOOM_WARNINGS})
  target_compile_definitions(${name} PRIVATE
    SONICBOOM_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    SONICBOOM_CLI="$<TARGET_FILE:sonicboom>")
  set(labels unit)
  if(ARG_LABELS)
    set(labels ${ARG_LABELS})
  endif()
  # the tests (and the CLI runs they start) solve and cache modes under the build tree, never in
  # the user's home directory
  gtest_discover_tests(${name} DISCOVERY_MODE PRE_TEST
    PROPERTIES LABELS "${labels}" ENVIRONMENT "SONICBOOM_CACHE_DIR=${CMAKE_BINARY_DIR}/test-cache/modes"
    WORKING_DIRECTORY ${CMAKE_CURRENT_BINARY_DIR})
endfunction()

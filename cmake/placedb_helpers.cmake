# placedb_add_library(NAME name SRCS a.cc b.cc DEPS lib1 lib2 [INTERNAL])
#   One static library per module folder, exported and installed as part of
#   placedb::placedb; INTERNAL: a library of the clients (cli/, the bag
#   reader), linked into the programs and neither installed nor exported.
#   Include paths are rooted at src/ so every header is included as
#   "placedb/<module>/<file>.h", in the build tree and once installed.
set(PLACEDB_LIBRARIES "" CACHE INTERNAL "the module libraries, in build order")
function(placedb_add_library)
  cmake_parse_arguments(ARG "INTERNAL" "NAME" "SRCS;DEPS" ${ARGN})
  add_library(${ARG_NAME} STATIC ${ARG_SRCS})
  target_include_directories(${ARG_NAME} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/src>
    $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_DEPS})
  target_compile_options(${ARG_NAME} PRIVATE -Wall -Wextra -Wno-unused-parameter
    ${PLACEDB_UBSAN_OPTIONS})
  set_target_properties(${ARG_NAME} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  add_library(placedb::${ARG_NAME} ALIAS ${ARG_NAME})
  if(ARG_INTERNAL)
    return()
  endif()
  install(TARGETS ${ARG_NAME} EXPORT placedbTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  set(PLACEDB_LIBRARIES ${PLACEDB_LIBRARIES} ${ARG_NAME} CACHE INTERNAL "")
endfunction()

# placedb_add_test(NAME name SRCS a_test.cc DEPS lib1 [LABELS l] [COST seconds]
#                  [SPLIT part_name filter [part_name filter ...]])
#   A GoogleTest executable registered with CTest; PLACEDB_DATA_DIR points at
#   the sample data in the repository. SPLIT registers some of its tests
#   (a --gtest_filter) as CTest tests of their own, which run in parallel
#   with the rest: the test `name` then runs every test no part names.
function(placedb_add_test)
  if(NOT PLACEDB_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME;COST" "SRCS;DEPS;LABELS;SPLIT" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${ARG_NAME} PRIVATE PLACEDB_DATA_DIR="${PLACEDB_DATA_DIR}")
  target_compile_options(${ARG_NAME} PRIVATE -Wall -Wextra -Wno-unused-parameter)
  set(tests ${ARG_NAME})
  set(rest "")
  list(LENGTH ARG_SPLIT split_length)
  if(split_length GREATER 0)
    math(EXPR last "${split_length} - 1")
    foreach(i RANGE 0 ${last} 2)
      math(EXPR j "${i} + 1")
      list(GET ARG_SPLIT ${i} part)
      list(GET ARG_SPLIT ${j} filter)
      add_test(NAME ${part} COMMAND ${ARG_NAME} --gtest_filter=${filter})
      list(APPEND tests ${part})
      if(rest)
        set(rest "${rest}:${filter}")
      else()
        set(rest "${filter}")
      endif()
    endforeach()
    add_test(NAME ${ARG_NAME} COMMAND ${ARG_NAME} --gtest_filter=-${rest})
  else()
    add_test(NAME ${ARG_NAME} COMMAND ${ARG_NAME})
  endif()
  set_tests_properties(${tests} PROPERTIES TIMEOUT 900)
  if(ARG_COST)
    # A fresh tree has no timings: CTest starts the costliest first, so that
    # a long test is not the last one left running on one core.
    set_tests_properties(${tests} PROPERTIES COST ${ARG_COST})
  endif()
  if(ARG_LABELS)
    set_tests_properties(${tests} PROPERTIES LABELS "${ARG_LABELS}")
  endif()
endfunction()

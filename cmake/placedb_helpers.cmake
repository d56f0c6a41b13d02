# placedb_add_library(NAME name SRCS a.cc b.cc DEPS lib1 lib2)
#   One static library per module folder, exported and installed. Include
#   paths are rooted at src/ so every header is included as
#   "placedb/<module>/<file>.h", in the build tree and once installed.
set(PLACEDB_LIBRARIES "" CACHE INTERNAL "the module libraries, in build order")
function(placedb_add_library)
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS" ${ARGN})
  add_library(${ARG_NAME} STATIC ${ARG_SRCS})
  target_include_directories(${ARG_NAME} PUBLIC
    $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}/src>
    $<BUILD_INTERFACE:${PROJECT_BINARY_DIR}/include>
    $<INSTALL_INTERFACE:${CMAKE_INSTALL_INCLUDEDIR}>)
  target_link_libraries(${ARG_NAME} PUBLIC ${ARG_DEPS})
  target_compile_options(${ARG_NAME} PRIVATE -Wall -Wextra -Wno-unused-parameter)
  set_target_properties(${ARG_NAME} PROPERTIES POSITION_INDEPENDENT_CODE ON)
  add_library(placedb::${ARG_NAME} ALIAS ${ARG_NAME})
  install(TARGETS ${ARG_NAME} EXPORT placedbTargets
    ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
    LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
  set(PLACEDB_LIBRARIES ${PLACEDB_LIBRARIES} ${ARG_NAME} CACHE INTERNAL "")
endfunction()

# placedb_add_test(NAME name SRCS a_test.cc DEPS lib1 [LABELS l])
#   A GoogleTest executable registered with CTest; PLACEDB_DATA_DIR points at
#   the sample data in the repository.
function(placedb_add_test)
  if(NOT PLACEDB_BUILD_TESTS)
    return()
  endif()
  cmake_parse_arguments(ARG "" "NAME" "SRCS;DEPS;LABELS" ${ARGN})
  add_executable(${ARG_NAME} ${ARG_SRCS})
  target_link_libraries(${ARG_NAME} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gtest_main)
  target_compile_definitions(${ARG_NAME} PRIVATE PLACEDB_DATA_DIR="${PLACEDB_DATA_DIR}")
  target_compile_options(${ARG_NAME} PRIVATE -Wall -Wextra -Wno-unused-parameter)
  add_test(NAME ${ARG_NAME} COMMAND ${ARG_NAME})
  set_tests_properties(${ARG_NAME} PROPERTIES TIMEOUT 900)
  if(ARG_LABELS)
    set_tests_properties(${ARG_NAME} PROPERTIES LABELS "${ARG_LABELS}")
  endif()
endfunction()

# `cmake --install` puts the headers, the module libraries, the placedb
# binary and a CMake package in place, so another project can do
#   find_package(placedb 0.2 REQUIRED)
#   target_link_libraries(app PRIVATE placedb::placedb)
include(CMakePackageConfigHelpers)

# placedb::placedb: every module library (an interface target over them).
add_library(placedb_all INTERFACE)
target_link_libraries(placedb_all INTERFACE ${PLACEDB_LIBRARIES})
set_target_properties(placedb_all PROPERTIES EXPORT_NAME placedb)
install(TARGETS placedb_all EXPORT placedbTargets)

# The public face: placedb/placedb.h and the headers it includes, found by
# following its #include "placedb/..." lines, and nothing else (the
# database container, indexes, thread pools, the CLI, the ROS and Python
# glue stay inside). scripts/check_public_headers.py checks the same closure
# includes no other library's types than OpenCV's core and Eigen's.
include(${CMAKE_CURRENT_LIST_DIR}/placedb_header_closure.cmake)
placedb_header_closure(placedb_public_headers ${PROJECT_SOURCE_DIR}/src ${PROJECT_BINARY_DIR}/include)
foreach(header ${placedb_public_headers})
  get_filename_component(header_dir ${header} DIRECTORY)
  if(EXISTS ${PROJECT_SOURCE_DIR}/src/${header})
    install(FILES ${PROJECT_SOURCE_DIR}/src/${header} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/${header_dir})
  else()
    # Generated (version.h).
    install(FILES ${PROJECT_BINARY_DIR}/include/${header} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/${header_dir})
  endif()
endforeach()
list(LENGTH placedb_public_headers placedb_public_count)
message(STATUS "placedb public headers: ${placedb_public_count} (the closure of placedb/placedb.h)")

set(PLACEDB_CMAKE_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/placedb)
install(EXPORT placedbTargets NAMESPACE placedb:: DESTINATION ${PLACEDB_CMAKE_DIR})
configure_package_config_file(cmake/placedbConfig.cmake.in
  ${PROJECT_BINARY_DIR}/placedbConfig.cmake INSTALL_DESTINATION ${PLACEDB_CMAKE_DIR})
write_basic_package_version_file(${PROJECT_BINARY_DIR}/placedbConfigVersion.cmake
  VERSION ${PROJECT_VERSION} COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/placedbConfig.cmake
  ${PROJECT_BINARY_DIR}/placedbConfigVersion.cmake DESTINATION ${PLACEDB_CMAKE_DIR})

# The consumer-project test: install into a scratch prefix, build
# examples/consumer against it with find_package(placedb), run it on a
# database of the sample data.
if(PLACEDB_BUILD_TESTS)
  set(consumer_python_args)
  if(TARGET placedb_python)
    # The installed Python module imports from the documented path.
    set(consumer_python_args -DPYTHON=${Python3_EXECUTABLE} -DPYTHON_DIR=${PLACEDB_PYTHON_INSTALL_DIR})
  endif()
  add_test(NAME install_consumer_test
    COMMAND ${CMAKE_COMMAND}
      -DBUILD_DIR=${PROJECT_BINARY_DIR} ${consumer_python_args}
      -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
      -DWORK_DIR=${PROJECT_BINARY_DIR}/consumer_test
      -P ${PROJECT_SOURCE_DIR}/cmake/consumer_test.cmake)
  # A sanitized install cannot link into the plain consumer project.
  set_tests_properties(install_consumer_test PROPERTIES TIMEOUT 900 LABELS no-sanitizer)
endif()

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

install(DIRECTORY src/placedb DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}
  FILES_MATCHING PATTERN "*.h"
  PATTERN "testing.h" EXCLUDE
  PATTERN "exe" EXCLUDE
  PATTERN "cli" EXCLUDE)
install(FILES ${PROJECT_BINARY_DIR}/include/placedb/util/version.h
  DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/placedb/util)

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
  add_test(NAME install_consumer_test
    COMMAND ${CMAKE_COMMAND}
      -DBUILD_DIR=${PROJECT_BINARY_DIR}
      -DSOURCE_DIR=${PROJECT_SOURCE_DIR}
      -DWORK_DIR=${PROJECT_BINARY_DIR}/consumer_test
      -P ${PROJECT_SOURCE_DIR}/cmake/consumer_test.cmake)
  # A sanitized install cannot link into the plain consumer project.
  set_tests_properties(install_consumer_test PROPERTIES TIMEOUT 900 LABELS no-sanitizer)
endif()

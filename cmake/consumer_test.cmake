# Run by CTest (install_consumer_test): proves that an installed placedb is
# usable from another CMake project.
#   1. cmake --install the build into WORK_DIR/prefix;
#   2. the installed placedb binary builds a database of the sample data;
#   3. examples/consumer is configured and built with find_package(placedb);
#   4. the consumer opens the database and answers one query, which must be
#      a true match (042.jpg revisits the place of keyframes 1-5).
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    string(REPLACE ";" " " shown "${ARGN}")
    message(FATAL_ERROR "failed (${code}): ${shown}\n${out}\n${err}")
  endif()
  set(last_output "${out}" PARENT_SCOPE)
endfunction()

file(REMOVE_RECURSE ${WORK_DIR})
set(prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f include/placedb/session/place_database.h include/placedb/util/version.h
          lib/cmake/placedb/placedbConfig.cmake bin/placedb)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "the install lacks ${f}")
  endif()
endforeach()
foreach(f include/placedb/util/testing.h include/placedb/cli/flags.h)
  if(EXISTS ${prefix}/${f})
    message(FATAL_ERROR "${f} is not part of the library but was installed")
  endif()
endforeach()

set(images ${SOURCE_DIR}/data/rtabmap_loop/images)
run(${prefix}/bin/placedb build --images ${images} --last 40 --out ${WORK_DIR}/db --quiet)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/consumer -B ${WORK_DIR}/build
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build)
run(${WORK_DIR}/build/where_am_i ${WORK_DIR}/db ${images}/042.jpg)
message(STATUS "consumer output:\n${last_output}")
if(NOT last_output MATCHES "keyframe [1-5] ")
  message(FATAL_ERROR "the consumer's answer is not a true match of 042.jpg:\n${last_output}")
endif()

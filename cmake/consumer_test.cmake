# Run by CTest (install_consumer_test): proves that an installed placedb is
# usable from another CMake project.
#   1. cmake --install the build into WORK_DIR/prefix;
#   2. the installed placedb binary builds a database of the sample data;
#   3. examples/consumer is configured and built with find_package(placedb);
#   4. the consumer opens the database and answers one query, which must be
#      a true match (042.jpg revisits the place of keyframes 1-5);
#   5. with PYTHON and PYTHON_DIR (a build with the module): the installed
#      module imports with PYTHONPATH=PREFIX/PYTHON_DIR, as the README says,
#      and is the installed one.
cmake_policy(VERSION 3.16)
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
foreach(f include/placedb/placedb.h include/placedb/session/place_database.h
          include/placedb/util/version.h
          lib/cmake/placedb/placedbConfig.cmake bin/placedb)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "the install lacks ${f}")
  endif()
endforeach()
# Only the public face: nothing internal, no header of the clients.
foreach(f include/placedb/util/testing.h include/placedb/cli/flags.h
          include/placedb/storage/database.h include/placedb/query/query.h
          include/placedb/session/storage_view.h include/placedb/util/thread_pool.h
          include/placedb/python/conversions.h include/placedb/ros/messages.h
          include/placedb/ros/testbed.h include/placedb/dataset/bag/bag_source.h)
  if(EXISTS ${prefix}/${f})
    message(FATAL_ERROR "${f} is not part of the public face but was installed")
  endif()
endforeach()

# Exactly the closure of placedb/placedb.h is installed: every installed
# header is reached from it, and each one it includes is there.
include(${CMAKE_CURRENT_LIST_DIR}/placedb_header_closure.cmake)
placedb_header_closure(reached ${prefix}/include)
foreach(header ${reached})
  if(NOT EXISTS ${prefix}/include/${header})
    message(FATAL_ERROR "the installed face includes ${header}, which is not installed")
  endif()
endforeach()
file(GLOB_RECURSE installed RELATIVE ${prefix}/include ${prefix}/include/placedb/*.h)
foreach(header ${installed})
  if(NOT header IN_LIST reached)
    message(FATAL_ERROR "${header} is installed but placedb/placedb.h does not include it")
  endif()
endforeach()
# The consumer includes the face and nothing else of placedb.
file(STRINGS ${SOURCE_DIR}/examples/consumer/where_am_i.cc consumer_includes REGEX "#include <placedb/")
if(NOT consumer_includes STREQUAL "#include <placedb/placedb.h>")
  message(FATAL_ERROR "examples/consumer must include only placedb/placedb.h: ${consumer_includes}")
endif()

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

if(DEFINED PYTHON_DIR)
  if(NOT EXISTS ${prefix}/${PYTHON_DIR})
    message(FATAL_ERROR "the install lacks the Python module's folder ${PYTHON_DIR}")
  endif()
  run(${CMAKE_COMMAND} -E env PYTHONPATH=${prefix}/${PYTHON_DIR}
      ${PYTHON} -c "print(__import__('placedb').__file__)")
  string(STRIP "${last_output}" module_file)
  cmake_path(IS_PREFIX prefix "${module_file}" NORMALIZE installed_module)
  if(NOT installed_module)
    message(FATAL_ERROR "import placedb found ${module_file}, not the module installed in ${prefix}")
  endif()
endif()

# placedb_header_closure(OUT ROOTS...): the headers placedb/placedb.h
# includes, directly or not, following its #include "placedb/..." lines,
# with itself first: the public face. Each header is read from the first of
# ROOTS that holds it; a header no root holds is listed but not followed
# (the caller decides whether that is an error). Used by the install rules
# (cmake/placedb_install.cmake) and the installed tree's check
# (cmake/consumer_test.cmake), so both mean the same set.
function(placedb_header_closure out)
  set(reached "")
  set(todo "placedb/placedb.h")
  while(todo)
    list(POP_FRONT todo header)
    if(header IN_LIST reached)
      continue()
    endif()
    list(APPEND reached ${header})
    foreach(root ${ARGN})
      if(EXISTS ${root}/${header})
        file(STRINGS ${root}/${header} includes REGEX "^#include \"placedb/")
        foreach(line ${includes})
          string(REGEX REPLACE "^#include \"([^\"]+)\".*" "\\1" included "${line}")
          list(APPEND todo ${included})
        endforeach()
        break()
      endif()
    endforeach()
  endwhile()
  set(${out} ${reached} PARENT_SCOPE)
endfunction()

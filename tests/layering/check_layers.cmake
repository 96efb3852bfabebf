# Layering check, run by CTest (`cmake -DSOURCE_DIR=<repo> [-DLINK_FILE=<file>] -P this`):
#   server/core  includes no io/, net/, loop/, lab/ or app/ header, nor ZeroMQ, protobuf, spdlog
#   server/loop  includes no io/, net/, lab/ or app/ header, nor ZeroMQ, protobuf, spdlog, fmt;
#                and (LINK_FILE, written at configure time) conica_loop links none of those
#   server/lab   includes no io/, net/, loop/ or app/ header, nor ZeroMQ, protobuf, spdlog, nor
#                <fstream>, <filesystem> or <iostream>, and calls no file or console I/O (fopen,
#                std::ifstream / ofstream / fstream, std::filesystem, printf, std::cout / cerr):
#                curves come in and cards go out through server/io, called by server/app/lab
# Fails naming file:line and the offending include.
if(NOT SOURCE_DIR)
  message(FATAL_ERROR "usage: cmake -DSOURCE_DIR=<repository> -P check_layers.cmake")
endif()

set(wire_headers "zmq\\.h|zmq\\.hpp|zmq_addon\\.hpp|\\.pb\\.h$|^google/protobuf/|^spdlog/|^fmt/")
set(core_forbidden "^(io|net|loop|lab|app)/|${wire_headers}")
set(loop_forbidden "^(io|net|lab|app)/|${wire_headers}")
set(lab_forbidden "^(io|net|loop|app)/|${wire_headers}|^(fstream|filesystem|iostream)$")
# Calls that read or write files or the console, outside comments.
set(lab_io_calls "(^|[^a-z_])(fopen|freopen|fprintf|printf|puts|fputs|fwrite|fread)[ \t]*\\(|std::(i|o)?fstream|std::filesystem|std::(cout|cerr|clog)")

set(violations "")
set(checked 0)
# check_dir(dir forbidden [io_calls]): every include of server/<dir> against `forbidden`, and with
# `io_calls` every line (its // comment dropped) against that pattern too.
function(check_dir dir forbidden)
  file(GLOB files "${SOURCE_DIR}/server/${dir}/*.h" "${SOURCE_DIR}/server/${dir}/*.cc")
  list(LENGTH files n)
  if(n EQUAL 0)
    set(violations "${violations}server/${dir}: no sources found\n" PARENT_SCOPE)
    return()
  endif()
  math(EXPR total "${checked} + ${n}")
  set(checked ${total} PARENT_SCOPE)
  foreach(f ${files})
    file(STRINGS "${f}" lines)
    file(RELATIVE_PATH rel "${SOURCE_DIR}" "${f}")
    set(line_no 0)
    foreach(line IN LISTS lines)
      math(EXPR line_no "${line_no} + 1")
      if(line MATCHES "^[ \t]*#[ \t]*include[ \t]*[<\"]([^>\"]+)[>\"]")
        set(header "${CMAKE_MATCH_1}")
        if(header MATCHES "${forbidden}")
          set(violations "${violations}${rel}:${line_no}: includes ${header} (not allowed in server/${dir})\n")
        endif()
      elseif(ARGC GREATER 2)
        string(REGEX REPLACE "//.*$" "" code "${line}")
        if(code MATCHES "${ARGV2}")
          string(REGEX REPLACE "^[^a-z]+" "" call "${CMAKE_MATCH_0}")
          set(violations "${violations}${rel}:${line_no}: ${call}: file or console I/O (not allowed in server/${dir})\n")
        endif()
      endif()
    endforeach()
  endforeach()
  set(violations "${violations}" PARENT_SCOPE)
endfunction()

check_dir(core "${core_forbidden}")
check_dir(loop "${loop_forbidden}")
check_dir(lab "${lab_forbidden}" "${lab_io_calls}")

if(LINK_FILE)
  file(READ "${LINK_FILE}" links)
  string(STRIP "${links}" links)
  foreach(lib ${links})
    if(lib MATCHES "ZMQ|zmq|[Pp]roto|spdlog|fmt|conica_net|conica_io|conica_scene|conica_curve")
      set(violations "${violations}conica_loop links ${lib} (core and threads only)\n")
    endif()
  endforeach()
endif()

if(violations)
  message(FATAL_ERROR "layering violations:\n${violations}")
endif()
message(STATUS "layering: ${checked} files in server/core, server/loop and server/lab, no forbidden includes or I/O")

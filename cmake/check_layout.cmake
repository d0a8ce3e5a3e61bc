# Checks the module layout (README, "Layout"): include/shine/<module>/ and src/<module>/ name the
# same modules, and no header or source includes a module above its own.
#   cmake -DSOURCE_DIR=<repo> -DRULES=<build>/layout_rules.txt -P cmake/check_layout.cmake
# RULES has one line per module, "module:below1;below2;...", written by the top-level
# CMakeLists.txt from the modules' link dependencies (the transitive set below each module).
cmake_minimum_required(VERSION 3.20)
if(NOT SOURCE_DIR OR NOT RULES)
    message(FATAL_ERROR "usage: cmake -DSOURCE_DIR=... -DRULES=... -P check_layout.cmake")
endif()

file(STRINGS "${RULES}" _lines)
set(_modules "")
foreach(_line ${_lines})
    string(REGEX MATCH "^([a-z_]+):(.*)$" _ "${_line}")
    set(_module "${CMAKE_MATCH_1}")
    list(APPEND _modules ${_module})
    string(REPLACE "," ";" _below "${CMAKE_MATCH_2}")
    set(_below_${_module} ${_below})
endforeach()

set(_problems "")
file(GLOB _include_dirs LIST_DIRECTORIES true RELATIVE "${SOURCE_DIR}/include/shine"
     "${SOURCE_DIR}/include/shine/*")
file(GLOB _src_dirs LIST_DIRECTORIES true RELATIVE "${SOURCE_DIR}/src" "${SOURCE_DIR}/src/*")
foreach(_dir ${_include_dirs} ${_src_dirs})
    if(NOT _dir IN_LIST _modules)
        list(APPEND _problems "include/shine/${_dir} or src/${_dir} is not a module of the build")
    endif()
endforeach()
foreach(_module ${_modules})
    if(NOT _module IN_LIST _include_dirs)
        list(APPEND _problems "module ${_module} has no include/shine/${_module}/")
    endif()
    if(NOT _module IN_LIST _src_dirs)
        list(APPEND _problems "module ${_module} has no src/${_module}/")
    endif()
endforeach()

foreach(_module ${_modules})
    file(GLOB _files "${SOURCE_DIR}/include/shine/${_module}/*.hpp"
         "${SOURCE_DIR}/src/${_module}/*.cpp" "${SOURCE_DIR}/src/${_module}/*.hpp")
    foreach(_file ${_files})
        file(STRINGS "${_file}" _includes REGEX "^#include \"shine/[a-z_]+/")
        foreach(_include ${_includes})
            string(REGEX MATCH "shine/([a-z_]+)/" _ "${_include}")
            set(_used "${CMAKE_MATCH_1}")
            if(NOT _used STREQUAL _module AND NOT _used IN_LIST _below_${_module})
                file(RELATIVE_PATH _rel "${SOURCE_DIR}" "${_file}")
                string(REPLACE ";" ", " _below_text "${_below_${_module}}")
                list(APPEND _problems "${_rel} (module ${_module}) includes module ${_used}, \
which is not below it (below ${_module}: ${_below_text})")
            endif()
        endforeach()
    endforeach()
endforeach()

if(_problems)
    list(JOIN _problems "\n  " _text)
    message(FATAL_ERROR "layout check failed:\n  ${_text}")
endif()
list(LENGTH _modules _count)
message(STATUS "layout check: ${_count} modules, every include points downward")

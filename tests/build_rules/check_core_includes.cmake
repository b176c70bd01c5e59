# Fails when a file of the algorithm core (src/, include/) names a HAL or firmware_host header
# or climbs out of its tree with a relative include: the include path alone cannot catch those.
file(GLOB_RECURSE core_files
     "${ROOT}/src/*.cpp" "${ROOT}/src/*.hpp" "${ROOT}/include/*.hpp" "${ROOT}/include/*.h")
set(violations "")
foreach(path IN LISTS core_files)
  file(STRINGS "${path}" includes REGEX "^[ \t]*#[ \t]*include")
  foreach(line IN LISTS includes)
    if(line MATCHES "[<\"](\\.\\./|blockmap/hal/|hal/|firmware_host/)")
      string(APPEND violations "  ${path}: ${line}\n")
    endif()
  endforeach()
endforeach()
if(violations)
  message(FATAL_ERROR "The core must not include HAL or firmware_host headers:\n${violations}")
endif()
list(LENGTH core_files count)
message(STATUS "core layering: ${count} files checked, no HAL or firmware_host includes")

# Third-party dependencies, all from Debian's archive (scripts/install-deps installs them).
#   Eigen 3      the core's only library (header-only, so one copy serves every architecture)
#   CLI11        command-line parsing in firmware_host (header-only)
#   nlohmann     JSON output of firmware_host and golden files in tests (header-only)
#   toml++       robot and world configuration files (header-only mode)
#   GeographicLib  geodetic <-> local ENU frames (hal/geodesy)
#   libgpiod     GPIO lines on the robot (hal/linux; bookworm's 1.6)
#   libusb-1.0   USB bulk transfers to a SICK TiM (hal/linux)
#   GoogleTest   the test tiers: the host package, or built from /usr/src/googletest with the
#                cross compiler when cross-compiling
#   benchmark    Google Benchmark, host builds with BLOCKMAP_BUILD_BENCHMARKS only
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(CLI11 2.1 REQUIRED)
find_package(nlohmann_json 3.10 REQUIRED)
find_package(Threads REQUIRED)

# Header-only packages whose CMake files point at /usr/include would put the host's C library
# headers in front of a cross compiler's. In cross builds, expose only the package's own
# folder, through a link in the build tree.
function(blockmap_isolate_header_package target folder)
  if(NOT CMAKE_CROSSCOMPILING)
    return()
  endif()
  get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
  list(GET dirs 0 dir)
  set(isolated ${CMAKE_BINARY_DIR}/_isolated/${folder})
  file(MAKE_DIRECTORY ${isolated})
  file(CREATE_LINK ${dir}/${folder} ${isolated}/${folder} SYMBOLIC)
  set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES ${isolated})
endfunction()
blockmap_isolate_header_package(CLI11::CLI11 CLI)
blockmap_isolate_header_package(nlohmann_json::nlohmann_json nlohmann)

# toml++ in header-only mode: Debian's CMake package links its shared library, which exists
# for the host only. One translation unit (hal/config) includes it.
find_path(BLOCKMAP_TOMLPP_INCLUDE_DIR toml++/toml.h PATHS /usr/include NO_CMAKE_FIND_ROOT_PATH
          REQUIRED)
add_library(blockmap_tomlplusplus INTERFACE)
target_compile_definitions(blockmap_tomlplusplus INTERFACE TOML_HEADER_ONLY=1 TOML_EXCEPTIONS=1
                                                            TOML_ENABLE_FORMATTERS=0)
if(CMAKE_CROSSCOMPILING)
  file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/_isolated/tomlplusplus)
  file(CREATE_LINK ${BLOCKMAP_TOMLPP_INCLUDE_DIR}/toml++
       ${CMAKE_BINARY_DIR}/_isolated/tomlplusplus/toml++ SYMBOLIC)
  target_include_directories(blockmap_tomlplusplus SYSTEM INTERFACE
                             ${CMAKE_BINARY_DIR}/_isolated/tomlplusplus)
endif()
add_library(blockmap::tomlplusplus ALIAS blockmap_tomlplusplus)

# Compiled libraries: GeographicLib (hal/geodesy), libgpiod 1.6 (hal/linux GPIO lines) and
# libusb-1.0 (hal/linux USB bulk transfers). The host links Debian's -dev packages. Cross builds
# link the target's shared object from Debian's arm64/armhf package, which
# `scripts/install-deps test` unpacks into a private folder (BLOCKMAP_TARGET_LIBS_DIR;
# installing it with multiarch would bring the target's libc into /lib/<triple>, where QEMU's
# loader finds it before the cross toolchain's). The headers are the host's: they do not depend
# on the architecture, and only the package's own header or folder is exposed, so that the
# host's C library headers never come before the cross compiler's.
if(CMAKE_CROSSCOMPILING)
  if(DEFINED ENV{BLOCKMAP_TARGET_LIBS})
    set(default_target_libs "$ENV{BLOCKMAP_TARGET_LIBS}")
  elseif(DEFINED ENV{XDG_CACHE_HOME})
    set(default_target_libs "$ENV{XDG_CACHE_HOME}/blockmap/target-libs")
  else()
    set(default_target_libs "$ENV{HOME}/.cache/blockmap/target-libs")
  endif()
  set(BLOCKMAP_TARGET_LIBS_DIR "${default_target_libs}" CACHE PATH
      "where scripts/install-deps unpacks the cross builds' target libraries")
endif()

# blockmap::NAME from HEADER (a path under /usr/include), the host's library LIBRARY and the
# target's shared object SONAME, with the target libraries it needs in turn (ARGN: linked too,
# since the binaries' RUNPATH reaches only their direct dependencies under QEMU).
function(blockmap_compiled_library name header library soname)
  string(TOUPPER ${name} upper)
  string(REGEX REPLACE "/.*" "" top ${header})
  find_path(BLOCKMAP_${upper}_INCLUDE_DIR ${header} PATHS /usr/include NO_CMAKE_FIND_ROOT_PATH
            REQUIRED)
  add_library(blockmap_${name} INTERFACE)
  if(CMAKE_CROSSCOMPILING)
    set(libs)
    foreach(object ${soname} ${ARGN})
      set(so ${BLOCKMAP_TARGET_LIBS_DIR}/${BLOCKMAP_TARGET_DEB_ARCH}/usr/lib/${BLOCKMAP_TARGET_TRIPLE}/${object})
      if(NOT EXISTS ${so})
        message(FATAL_ERROR "${so} is missing: run scripts/install-deps test")
      endif()
      if(NOT object STREQUAL soname)
        # Needed by the library, not by our code: kept against the linker's --as-needed.
        set(so "-Wl,--push-state,--no-as-needed" ${so} "-Wl,--pop-state")
      endif()
      list(APPEND libs ${so})
    endforeach()
    set(isolated ${CMAKE_BINARY_DIR}/_isolated/${name})
    file(MAKE_DIRECTORY ${isolated})
    file(CREATE_LINK ${BLOCKMAP_${upper}_INCLUDE_DIR}/${top} ${isolated}/${top} SYMBOLIC)
    target_include_directories(blockmap_${name} SYSTEM INTERFACE ${isolated})
    target_link_libraries(blockmap_${name} INTERFACE ${libs})
  else()
    find_library(BLOCKMAP_${upper}_LIBRARY ${library} REQUIRED)
    target_link_libraries(blockmap_${name} INTERFACE ${BLOCKMAP_${upper}_LIBRARY})
  endif()
  add_library(blockmap::${name} ALIAS blockmap_${name})
endfunction()
blockmap_compiled_library(geographiclib GeographicLib/LocalCartesian.hpp GeographicLib
                          libGeographicLib.so.23)
blockmap_compiled_library(gpiod gpiod.h gpiod libgpiod.so.2)
blockmap_compiled_library(usb libusb-1.0/libusb.h usb-1.0 libusb-1.0.so.0 libudev.so.1)

if(BLOCKMAP_BUILD_TESTS)
  if(CMAKE_CROSSCOMPILING)
    set(BLOCKMAP_GTEST_SOURCE_DIR "/usr/src/googletest" CACHE PATH "GoogleTest sources")
    set(INSTALL_GTEST OFF CACHE BOOL "" FORCE)
    set(BUILD_GMOCK ON CACHE BOOL "" FORCE)
    add_subdirectory(${BLOCKMAP_GTEST_SOURCE_DIR} ${CMAKE_BINARY_DIR}/_googletest EXCLUDE_FROM_ALL)
    foreach(lib gtest gtest_main gmock gmock_main)
      # Our warning flags are for our code: GoogleTest's headers are system headers here too.
      get_target_property(dirs ${lib} INTERFACE_INCLUDE_DIRECTORIES)
      set_target_properties(${lib} PROPERTIES INTERFACE_SYSTEM_INCLUDE_DIRECTORIES "${dirs}")
    endforeach()
  else()
    find_package(GTest REQUIRED)
  endif()
  include(GoogleTest)
endif()

if(BLOCKMAP_BUILD_BENCHMARKS)
  find_package(benchmark REQUIRED)
endif()

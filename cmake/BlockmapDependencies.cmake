# Third-party dependencies, all from Debian's archive (scripts/install-deps installs them).
#   Eigen 3      the core's only library (header-only, so one copy serves every architecture)
#   CLI11        command-line parsing in firmware_host (header-only)
#   GoogleTest   the test tiers: the host package, or built from /usr/src/googletest with the
#                cross compiler when cross-compiling
#   benchmark    Google Benchmark, host builds with BLOCKMAP_BUILD_BENCHMARKS only
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(CLI11 2.1 REQUIRED)
if(CMAKE_CROSSCOMPILING)
  # CLI11's package points at /usr/include, which would put the host's C library headers in
  # front of the cross compiler. Expose only its CLI/ folder, through a link in the build tree.
  get_target_property(cli11_dirs CLI11::CLI11 INTERFACE_INCLUDE_DIRECTORIES)
  list(GET cli11_dirs 0 cli11_dir)
  file(MAKE_DIRECTORY ${CMAKE_BINARY_DIR}/_cli11)
  file(CREATE_LINK ${cli11_dir}/CLI ${CMAKE_BINARY_DIR}/_cli11/CLI SYMBOLIC)
  set_target_properties(CLI11::CLI11 PROPERTIES
      INTERFACE_INCLUDE_DIRECTORIES ${CMAKE_BINARY_DIR}/_cli11)
endif()

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

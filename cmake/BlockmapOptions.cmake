# Build options, one place. Presets (CMakePresets.json) set these; the defaults build a plain
# host tree with tests.
option(BLOCKMAP_BUILD_TESTS "Build the test tiers (unit, memory, build rules)" ON)
option(BLOCKMAP_WORLD_TESTS_ONLY
       "Build only the test programs that drive whole simulated worlds (scripts/test's worlds tree)" OFF)
option(BLOCKMAP_BUILD_BENCHMARKS "Build Google Benchmark programs (host only)" OFF)
option(BLOCKMAP_BUILD_PEER_BENCHMARKS
       "Build the peer benchmark (PCL, CGAL, Open3D; scripts/bench-peers installs them)" OFF)
option(BLOCKMAP_BUILD_SOLVER_BENCHMARKS
       "Build the path solvers' benchmark (Ceres; scripts/bench-solvers installs it)" OFF)
option(BLOCKMAP_SANITIZE "Build with AddressSanitizer and UndefinedBehaviorSanitizer" OFF)
option(BLOCKMAP_BUILD_FUZZERS "Build libFuzzer targets for the protocol codecs (clang only)" OFF)
# Unity builds: the test trees' sources compiled eight to a unit, so that GoogleTest's, Eigen's and
# our own headers are parsed once per eight files instead of once per file (docs/README.md, "What
# scripts/test costs"). Every source must then be fine beside any other: no two files of a
# target may define the same name at namespace scope, anonymous namespaces included.
option(BLOCKMAP_UNITY "Compile each target's sources in batches of eight (unity build)" OFF)
if(BLOCKMAP_UNITY)
  set(CMAKE_UNITY_BUILD ON)
  set(CMAKE_UNITY_BUILD_BATCH_SIZE 8)
endif()
# The release tree: the libraries and the executable one file at a time, as a user builds
# them, and the test and benchmark programs in batches (tests/CMakeLists.txt), which a user
# seldom builds and scripts/test builds whole.
option(BLOCKMAP_UNITY_TESTS "Compile the test and benchmark programs in batches of eight" OFF)
option(BLOCKMAP_USE_CCACHE "Use ccache as the compiler launcher when it is installed" ON)
set(BLOCKMAP_HOST_LABEL "host" CACHE STRING "ctest label of tests built for the host")
set(BLOCKMAP_TARGET_LABEL "${CMAKE_SYSTEM_PROCESSOR}" CACHE STRING
    "ctest label of tests built for a cross target (set by the toolchain file)")

# x86-64 hosts: the x86-64-v2 level (SSE4.2 and POPCNT, every x86-64 CPU since about 2009):
# the voxel grid counts bits and floors coordinates on every point, which without it are
# library calls. Empty for a plain x86-64 build; ARM targets set their own flags.
set(BLOCKMAP_X86_64_LEVEL "x86-64-v2" CACHE STRING
    "-march level of x86-64 builds (x86-64, x86-64-v2, x86-64-v3; empty: compiler default)")
if(CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64)$" AND NOT CMAKE_CROSSCOMPILING
   AND BLOCKMAP_X86_64_LEVEL)
  add_compile_options(-march=${BLOCKMAP_X86_64_LEVEL})
endif()

# Nothing here reads errno after a math function: without this flag every sqrt is a library
# call behind a branch (the detector takes one per sample). Results are the same: IEEE sqrt is
# exact either way.
add_compile_options(-fno-math-errno)

if(BLOCKMAP_USE_CCACHE)
  find_program(BLOCKMAP_CCACHE ccache)
  if(BLOCKMAP_CCACHE)
    set(CMAKE_CXX_COMPILER_LAUNCHER "${BLOCKMAP_CCACHE}")
  endif()
endif()

if(BLOCKMAP_BUILD_FUZZERS)
  if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
    message(FATAL_ERROR "BLOCKMAP_BUILD_FUZZERS needs clang (libFuzzer); use the fuzz preset")
  endif()
  # Coverage instrumentation everywhere; the fuzz targets link libFuzzer's main.
  add_compile_options(-fsanitize=fuzzer-no-link)
endif()

if(BLOCKMAP_SANITIZE)
  # Applied to every target so that the instrumented allocator sees the whole program.
  add_compile_options(-fsanitize=address,undefined -fno-omit-frame-pointer
                      -fno-sanitize-recover=all)
  add_link_options(-fsanitize=address,undefined)
endif()

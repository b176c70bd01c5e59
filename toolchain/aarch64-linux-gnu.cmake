# Cross build for aarch64 (aarch64-linux-gnu) with Debian's cross compilers; ctest runs the test
# binaries under QEMU user mode with the target's libraries from /usr/aarch64-linux-gnu.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_FIND_ROOT_PATH /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# Header-only packages (Eigen, CLI11) live in the host's /usr/share: one copy fits every target.
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64-static -L /usr/aarch64-linux-gnu)
set(BLOCKMAP_TARGET_LABEL aarch64 CACHE STRING "ctest label of the aarch64 tests")
# Debian's names for the target: its multiarch triple and its package architecture (target
# libraries are unpacked from <pkg>_<version>_<arch>.deb by scripts/install-deps).
set(BLOCKMAP_TARGET_TRIPLE aarch64-linux-gnu)
set(BLOCKMAP_TARGET_DEB_ARCH arm64)

# Cross build for armhf (arm-linux-gnueabihf) with Debian's cross compilers; ctest runs the test
# binaries under QEMU user mode with the target's libraries from /usr/arm-linux-gnueabihf.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(CMAKE_C_COMPILER arm-linux-gnueabihf-gcc)
set(CMAKE_CXX_COMPILER arm-linux-gnueabihf-g++)
set(CMAKE_FIND_ROOT_PATH /usr/arm-linux-gnueabihf)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# Header-only packages (Eigen, CLI11) live in the host's /usr/share: one copy fits every target.
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE BOTH)
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-arm-static -L /usr/arm-linux-gnueabihf)
set(BLOCKMAP_TARGET_LABEL armhf CACHE STRING "ctest label of the armhf tests")
# Debian's names for the target: its multiarch triple and its package architecture (target
# libraries are unpacked from <pkg>_<version>_<arch>.deb by scripts/install-deps).
set(BLOCKMAP_TARGET_TRIPLE arm-linux-gnueabihf)
set(BLOCKMAP_TARGET_DEB_ARCH armhf)

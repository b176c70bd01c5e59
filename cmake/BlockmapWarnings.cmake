# The one place where warnings are chosen. Every first-party target calls
# blockmap_target_warnings(); third-party headers come in as SYSTEM includes so that these
# flags judge only our code. Warnings are errors on every compiler and architecture.
function(blockmap_target_warnings target)
  set(common
      -Wall -Wextra -Wpedantic
      -Wconversion -Wsign-conversion      # catches size_t -> uint8_t capacity truncation
      -Wshadow -Wnon-virtual-dtor -Wold-style-cast -Woverloaded-virtual
      -Wcast-qual -Wdouble-promotion -Wformat=2
      -Wimplicit-fallthrough -Wmissing-declarations -Wundef
      # not -Wnull-dereference: gcc 12 reports inlined libstdc++ code at -O3 (false positives)
      # not -Wuseless-cast: a cast that is needed on armhf (32-bit time_t, size_t) is "useless"
      # on x86-64, and the same sources must build everywhere
      -Werror)
  set(gcc_only -Wduplicated-cond -Wduplicated-branches -Wlogical-op)
  set(clang_only -Wshadow-all -Wcomma -Wextra-semi -Wunreachable-code)
  target_compile_options(${target} PRIVATE ${common}
      $<$<CXX_COMPILER_ID:GNU>:${gcc_only}>
      $<$<CXX_COMPILER_ID:Clang>:${clang_only}>)
endfunction()

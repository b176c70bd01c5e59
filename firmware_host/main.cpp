#include <cstdio>
#include <iostream>

#include "cli.hpp"

int main(int argc, char** argv) {
  const int status = blockmap::cli::run(argc, argv, std::cout, std::cerr);
  // Results on stdout count only when they all got there (a full disk, a closed pipe).
  std::cout.flush();
  if (!std::cout || std::fflush(stdout) != 0 || std::ferror(stdout) != 0) {
    std::fputs("blockmap: cannot write the results to standard output\n", stderr);
    return status == blockmap::cli::kExitOk ? blockmap::cli::kExitFailure : status;
  }
  return status;
}

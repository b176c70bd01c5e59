// Files as the commands read and write them: an input read whole only when it is a readable
// file no bigger than its cap, and an output written whole or not at all, so that a failed run
// never leaves half a file where a good one was (docs/formats.md, The command line).
#pragma once

#include <cstddef>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <string_view>

namespace blockmap::hal {

// "PATH: why", one line.
class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Why `path` cannot be read as a file (it is missing, a directory, or not readable), or empty.
// Character devices and pipes are files here (/dev/stdin, a FIFO).
[[nodiscard]] std::string unreadable_file(const std::filesystem::path& path);

// A whole file's bytes. Throws FileError naming the path when it cannot be read or holds more
// than `max_bytes` (memory grows with what is read, never with a size the file claims).
[[nodiscard]] std::string read_whole_file(const std::filesystem::path& path, std::size_t max_bytes);

// Writes `bytes` as the whole of `path`: into a temporary file beside it, flushed to the disk,
// then renamed over it. A path that exists and is not a regular file (/dev/stdout, a FIFO) is
// written in place. Empty when every byte reached it, else "PATH: why".
[[nodiscard]] std::string write_whole_file(const std::filesystem::path& path,
                                           std::string_view bytes);

}  // namespace blockmap::hal

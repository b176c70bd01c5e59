// An output file written whole or not at all (hal::write_whole_file): the text is composed in
// memory, then written under a temporary name, flushed and renamed, so that a full disk or a
// failed run leaves the file that was there before, never half of a new one.
#pragma once

#include <filesystem>
#include <sstream>
#include <string>

#include "blockmap/hal/files.hpp"

namespace blockmap::cli {

// `write(std::ostream&)` composes the file. Empty when every byte reached `path`, else the
// one-line problem naming it.
template <typename Write>
[[nodiscard]] std::string write_output(const std::filesystem::path& path, Write&& write) {
  std::ostringstream text;
  write(text);
  return hal::write_whole_file(path, text.view());
}

}  // namespace blockmap::cli

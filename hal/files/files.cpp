#include "blockmap/hal/files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <system_error>

namespace blockmap::hal {
namespace {

std::string errno_text() {
  return std::error_code(errno, std::generic_category()).message();
}

// A descriptor closed on every way out.
class Descriptor {
 public:
  explicit Descriptor(int fd) noexcept : fd_(fd) {}
  ~Descriptor() {
    if (fd_ >= 0) {
      ::close(fd_);
    }
  }
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  [[nodiscard]] int get() const noexcept { return fd_; }
  // Closes it now: false when the close reports an error (a write the kernel lost).
  bool close() noexcept {
    const int fd = fd_;
    fd_ = -1;
    return ::close(fd) == 0;
  }

 private:
  int fd_;
};

// Every byte of `bytes` into `fd`; false with errno set when one could not be written.
bool write_all(int fd, std::string_view bytes) noexcept {
  while (!bytes.empty()) {
    const ssize_t written = ::write(fd, bytes.data(), bytes.size());
    if (written < 0 && errno == EINTR) {
      continue;
    }
    if (written <= 0) {
      if (written == 0) {
        errno = ENOSPC;
      }
      return false;
    }
    bytes.remove_prefix(static_cast<std::size_t>(written));
  }
  return true;
}

std::string write_in_place(const std::filesystem::path& path, std::string_view bytes) {
  Descriptor file(::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC));
  if (file.get() < 0) {
    return path.string() + ": cannot write: " + errno_text();
  }
  if (!write_all(file.get(), bytes)) {
    return path.string() + ": write failed: " + errno_text();
  }
  if (!file.close()) {
    return path.string() + ": close failed: " + errno_text();
  }
  return {};
}

}  // namespace

std::string unreadable_file(const std::filesystem::path& path) {
  struct stat status {};
  if (::stat(path.c_str(), &status) != 0) {
    return path.string() + ": cannot open: " + errno_text();
  }
  if (S_ISDIR(status.st_mode)) {
    return path.string() + ": is a folder, not a file";
  }
  if (::access(path.c_str(), R_OK) != 0) {
    return path.string() + ": cannot open: " + errno_text();
  }
  return {};
}

std::string read_whole_file(const std::filesystem::path& path, std::size_t max_bytes) {
  if (std::string problem = unreadable_file(path); !problem.empty()) {
    throw FileError(problem);
  }
  const Descriptor file(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (file.get() < 0) {
    throw FileError(path.string() + ": cannot open: " + errno_text());
  }
  constexpr std::size_t kChunkBytes = 1 << 16;
  std::string bytes;
  while (true) {
    const std::size_t had = bytes.size();
    if (had > max_bytes) {
      throw FileError(path.string() + ": larger than the " + std::to_string(max_bytes >> 20) +
                      " MiB this command reads");
    }
    bytes.resize(had + kChunkBytes);
    const ssize_t got = ::read(file.get(), bytes.data() + had, kChunkBytes);
    if (got < 0 && errno == EINTR) {
      bytes.resize(had);
      continue;
    }
    if (got < 0) {
      throw FileError(path.string() + ": read error: " + errno_text());
    }
    bytes.resize(had + static_cast<std::size_t>(got));
    if (got == 0) {
      return bytes;
    }
  }
}

std::string write_whole_file(const std::filesystem::path& path, std::string_view bytes) {
  struct stat status {};
  if (::stat(path.c_str(), &status) == 0 && !S_ISREG(status.st_mode)) {
    if (S_ISDIR(status.st_mode)) {
      return path.string() + ": is a folder, not a file";
    }
    return write_in_place(path, bytes);
  }
  std::filesystem::path temporary = path;
  temporary += ".partial-" + std::to_string(::getpid());
  Descriptor file(::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (file.get() < 0) {
    return path.string() + ": cannot create: " + errno_text();
  }
  std::string problem;
  // fsync: the renamed file is the new one only once its bytes are on the disk.
  if (!write_all(file.get(), bytes) || (::fsync(file.get()) != 0 && errno != EINVAL)) {
    problem = path.string() + ": write failed: " + errno_text();
  } else if (!file.close()) {
    problem = path.string() + ": close failed: " + errno_text();
  } else if (::rename(temporary.c_str(), path.c_str()) != 0) {
    problem = path.string() + ": cannot replace: " + errno_text();
  }
  if (!problem.empty()) {
    ::unlink(temporary.c_str());
  }
  return problem;
}

}  // namespace blockmap::hal

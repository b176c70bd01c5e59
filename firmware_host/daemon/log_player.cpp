#include "daemon/log_player.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pty.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <limits>
#include <optional>
#include <system_error>
#include <thread>

#include "blockmap/hal/config/robot.hpp"
#include "blockmap/hal/gps_observations.hpp"
#include "blockmap/hal/protocol/nmea.hpp"
#include "blockmap/hal/replay/log_ports.hpp"

namespace blockmap::cli::daemon {
namespace {

namespace fs = std::filesystem;

constexpr TimestampNs kNever = std::numeric_limits<TimestampNs>::max();
constexpr std::size_t kRecordBytes = std::size_t{1} << 16;
// How long a write may wait for a pty whose reader is slow before its bytes are discarded.
constexpr int kWriteWaitMs = 200;

// One serial line: a pseudo-terminal whose far end the daemon opens through the link.
struct Line {
  std::string name;
  fs::path link;
  std::mutex lock;  // the fault hooks and the player
  int master = -1;
  int slave = -1;  // kept open so that the line exists before the daemon opens it
  bool muted = false;
  bool unread = false;  // a write found nobody reading: the next ones do not wait for it
  std::uint64_t bytes = 0;
  std::uint64_t discarded = 0;

  std::string open_pty() {
    close_pty();
    if (::openpty(&master, &slave, nullptr, nullptr, nullptr) != 0) {
      return "a pseudo-terminal for " + name + ": " + std::generic_category().message(errno);
    }
    // Raw from the start, so that nothing is echoed or translated before the daemon sets it.
    termios tio{};
    ::tcgetattr(slave, &tio);
    ::cfmakeraw(&tio);
    ::tcsetattr(slave, TCSANOW, &tio);
    ::fcntl(master, F_SETFL, ::fcntl(master, F_GETFL) | O_NONBLOCK);
    std::array<char, 128> path{};
    if (::ptsname_r(master, path.data(), path.size()) != 0) {
      return "the name of " + name +
             "'s pseudo-terminal: " + std::generic_category().message(errno);
    }
    // A new link replaces the old one in one step: the daemon never sees it missing.
    const fs::path temporary = link.string() + ".new";
    std::error_code error;
    fs::remove(temporary, error);
    fs::create_symlink(path.data(), temporary, error);
    if (!error) {
      fs::rename(temporary, link, error);
    }
    return error ? link.string() + ": " + error.message() : std::string();
  }
  void close_pty() {
    for (int* fd : {&master, &slave}) {
      if (*fd >= 0) {
        ::close(*fd);
        *fd = -1;
      }
    }
  }
  // Throws away what the daemon wrote (the lasers' start commands).
  void drain_input() const {
    std::array<std::uint8_t, 256> sink{};
    while (::read(master, sink.data(), sink.size()) > 0) {
    }
  }
  void write(std::span<const std::uint8_t> data) {
    const std::lock_guard<std::mutex> guard(lock);
    if (master < 0 || muted) {
      discarded += data.size();
      return;
    }
    drain_input();
    while (!data.empty()) {
      const ssize_t written = ::write(master, data.data(), data.size());
      if (written > 0) {
        bytes += static_cast<std::uint64_t>(written);
        data = data.subspan(static_cast<std::size_t>(written));
        continue;
      }
      pollfd wait{master, POLLOUT, 0};
      if ((written < 0 && errno != EAGAIN && errno != EINTR) ||
          ::poll(&wait, 1, unread ? 0 : kWriteWaitMs) <= 0) {
        discarded += data.size();  // nobody reads the line: a real line loses it too
        unread = true;
        return;
      }
    }
    unread = false;
  }
};

// The next piece of each log, with the time it is due.
class SerialLog {
 public:
  virtual ~SerialLog() = default;
  // The next piece and its time; false at the end.
  virtual bool next(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns) = 0;
};

class ByteLog final : public SerialLog {
 public:
  explicit ByteLog(const fs::path& path) : stream_(path.string()), buffer_(kRecordBytes) {}
  [[nodiscard]] std::string error() const { return stream_.ok() ? std::string() : stream_.error(); }
  bool next(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns) override {
    const hal::ReadResult result = stream_.read(buffer_, 0);
    if (result.status != IoStatus::kOk) {
      return false;
    }
    bytes = std::span<const std::uint8_t>(buffer_.data(), result.bytes);
    stamp_ns = result.stamp_ns;
    return true;
  }

 private:
  hal::replay::ByteLogFileStream stream_;
  std::vector<std::uint8_t> buffer_;
};

// The time of the log's first sentence that carries a date (RMC), or 0 when none does.
TimestampNs first_dated_ns(const fs::path& path) {
  hal::replay::FileByteStream stream(path.string());
  hal::protocol::nmea::Decoder decoder;
  std::array<std::uint8_t, 4096> buffer{};
  for (hal::ReadResult read = stream.read(buffer, 0); read.status == IoStatus::kOk;
       read = stream.read(buffer, 0)) {
    std::span<const std::uint8_t> rest(buffer.data(), read.bytes);
    while (!rest.empty()) {
      const hal::protocol::nmea::Decoder::Step step = decoder.push(rest, 0);
      rest = rest.subspan(step.consumed);
      if (step.sentence != nullptr && step.sentence->fix.has_date) {
        return hal::fix_stamp_ns(step.sentence->fix, 0);
      }
    }
  }
  return 0;
}

// Raw NMEA, each sentence due at its own UTC (a sentence without a time: with the one before);
// the day from `near_ns`, or when the other logs give none (kNever), from the first date.
class NmeaLog final : public SerialLog {
 public:
  NmeaLog(const fs::path& path, TimestampNs near_ns)
      : stream_(path.string()),
        chunk_(kRecordBytes),
        last_ns_(near_ns != kNever ? near_ns : first_dated_ns(path)) {}
  [[nodiscard]] std::string error() const { return stream_.ok() ? std::string() : stream_.error(); }
  bool next(std::span<const std::uint8_t>& bytes, TimestampNs& stamp_ns) override {
    std::size_t length = 0;
    for (;;) {
      if (read_at_ == read_end_) {
        const hal::ReadResult result = stream_.read(read_buffer_, 0);
        if (result.status != IoStatus::kOk || result.bytes == 0) {
          break;
        }
        read_at_ = 0;
        read_end_ = result.bytes;
      }
      const std::span<const std::uint8_t> rest(read_buffer_.data() + read_at_,
                                               read_end_ - read_at_);
      const hal::protocol::nmea::Decoder::Step step = decoder_.push(rest, 0);
      const std::size_t room = std::min(step.consumed, chunk_.size() - length);
      std::copy_n(rest.begin(), room, chunk_.begin() + static_cast<std::ptrdiff_t>(length));
      length += room;
      read_at_ += step.consumed;
      if (step.sentence != nullptr || step.rejected || length == chunk_.size()) {
        if (step.sentence != nullptr && step.sentence->fix.has_time) {
          last_ns_ = hal::fix_stamp_ns(step.sentence->fix, last_ns_);
        }
        break;
      }
    }
    bytes = std::span<const std::uint8_t>(chunk_.data(), length);
    stamp_ns = last_ns_;
    return length > 0;
  }

 private:
  hal::replay::FileByteStream stream_;
  hal::protocol::nmea::Decoder decoder_;
  std::array<std::uint8_t, 4096> read_buffer_{};
  std::size_t read_at_ = 0;
  std::size_t read_end_ = 0;
  std::vector<std::uint8_t> chunk_;
  TimestampNs last_ns_;
};

}  // namespace

struct LogPlayer::Impl {
  struct Source {
    std::unique_ptr<SerialLog> log;
    std::unique_ptr<Line> line;
    std::span<const std::uint8_t> bytes;
    TimestampNs due_ns = kNever;
    void advance() {
      if (!log->next(bytes, due_ns)) {
        due_ns = kNever;
      }
    }
  };
  std::vector<Source> serial;
  std::optional<hal::replay::CandumpFileBus> can_log;
  CanSink* can = nullptr;
  hal::CanFrame frame;
  TimestampNs frame_due_ns = kNever;
  double speed = 1.0;
  std::atomic<std::uint64_t> can_frames{0};
  std::atomic<std::uint64_t> can_refused{0};

  void next_frame() {
    const hal::CanReceiveResult result = can_log->receive(frame, 0);
    frame_due_ns = result.status == IoStatus::kOk ? result.stamp_ns : kNever;
  }
  Line* find(const std::string& name) {
    for (Source& source : serial) {
      if (source.line->name == name) {
        return source.line.get();
      }
    }
    return nullptr;
  }
};

LogPlayer::LogPlayer() : impl_(std::make_unique<Impl>()) {}

LogPlayer::~LogPlayer() {
  for (Impl::Source& source : impl_->serial) {
    source.line->close_pty();
    std::error_code ignored;
    fs::remove(source.line->link, ignored);
  }
}

std::string LogPlayer::open(const fs::path& dir, const fs::path& pty_dir, CanSink* can,
                            double speed) {
  impl_->speed = speed;
  // The logs' common clock starts at the CAN log's first frame, which also tells the NMEA
  // sentences' UTC which day it is.
  impl_->can_log.emplace((dir / "rmp.candump").string());
  if (!impl_->can_log->ok()) {
    return impl_->can_log->error();
  }
  impl_->next_frame();
  impl_->can = can;
  std::vector<std::string> names;
  if (fs::exists(dir / "robot.toml")) {
    for (const hal::config::LaserSpec& laser :
         hal::config::load_robot((dir / "robot.toml").string()).lasers) {
      if (fs::exists(dir / ("laser_" + laser.name + ".bytelog"))) {
        names.push_back("laser_" + laser.name);
      }
    }
  }
  names.emplace_back("gps");
  std::error_code error;
  fs::create_directories(pty_dir, error);
  // The day of the NMEA sentences' UTC: the CAN log's first frame's, else the lasers'.
  TimestampNs start_ns = impl_->frame_due_ns;
  for (const std::string& name : names) {
    Impl::Source source;
    if (name == "gps") {
      auto log = std::make_unique<NmeaLog>(dir / "gps.nmea", start_ns);
      if (std::string problem = log->error(); !problem.empty()) {
        return problem;
      }
      source.log = std::move(log);
    } else {
      auto log = std::make_unique<ByteLog>(dir / (name + ".bytelog"));
      if (std::string problem = log->error(); !problem.empty()) {
        return problem;
      }
      source.log = std::move(log);
    }
    source.line = std::make_unique<Line>();
    source.line->name = name;
    source.line->link = pty_dir / name;
    if (std::string problem = source.line->open_pty(); !problem.empty()) {
      return problem;
    }
    source.advance();
    start_ns = std::min(start_ns, source.due_ns);
    impl_->serial.push_back(std::move(source));
  }
  return {};
}

std::vector<std::string> LogPlayer::serial_names() const {
  std::vector<std::string> names;
  for (const Impl::Source& source : impl_->serial) {
    names.push_back(source.line->name);
  }
  return names;
}

fs::path LogPlayer::link_of(const std::string& name) const {
  Line* line = impl_->find(name);
  return line != nullptr ? line->link : fs::path();
}

double LogPlayer::play(const std::atomic<bool>& stop) {
  Impl& p = *impl_;
  TimestampNs first_ns = p.frame_due_ns;
  for (const Impl::Source& source : p.serial) {
    first_ns = std::min(first_ns, source.due_ns);
  }
  if (first_ns == kNever) {
    return 0.0;
  }
  const auto wall_start = std::chrono::steady_clock::now();
  TimestampNs played_ns = first_ns;
  while (!stop.load(std::memory_order_acquire)) {
    Impl::Source* next = nullptr;
    TimestampNs due_ns = p.can != nullptr ? p.frame_due_ns : kNever;
    for (Impl::Source& source : p.serial) {
      if (source.due_ns < due_ns) {
        due_ns = source.due_ns;
        next = &source;
      }
    }
    if (due_ns == kNever) {
      break;
    }
    const auto wall_due = wall_start + std::chrono::nanoseconds(static_cast<TimestampNs>(
                                           static_cast<double>(due_ns - first_ns) / p.speed));
    // Sleep in short steps so that a stop request is seen.
    while (!stop.load(std::memory_order_acquire) && std::chrono::steady_clock::now() < wall_due) {
      std::this_thread::sleep_until(
          std::min(wall_due, std::chrono::steady_clock::now() + std::chrono::milliseconds(20)));
    }
    played_ns = due_ns;
    if (next == nullptr) {
      (p.can->send(p.frame) ? p.can_frames : p.can_refused).fetch_add(1);
      p.next_frame();
    } else {
      next->line->write(next->bytes);
      next->advance();
    }
  }
  return seconds_from_ns(played_ns - first_ns);
}

void LogPlayer::unplug(const std::string& name) {
  if (Line* line = impl_->find(name); line != nullptr) {
    const std::lock_guard<std::mutex> guard(line->lock);
    line->close_pty();
  }
}

void LogPlayer::replug(const std::string& name) {
  if (Line* line = impl_->find(name); line != nullptr) {
    const std::lock_guard<std::mutex> guard(line->lock);
    static_cast<void>(line->open_pty());
  }
}

void LogPlayer::inject(const std::string& name, std::span<const std::uint8_t> bytes) {
  if (Line* line = impl_->find(name); line != nullptr) {
    line->write(bytes);
  }
}

void LogPlayer::mute(const std::string& name, bool muted) {
  if (Line* line = impl_->find(name); line != nullptr) {
    const std::lock_guard<std::mutex> guard(line->lock);
    line->muted = muted;
  }
}

PlayerCounters LogPlayer::counters() const {
  PlayerCounters c;
  c.can_frames = impl_->can_frames.load();
  c.can_refused = impl_->can_refused.load();
  for (const Impl::Source& source : impl_->serial) {
    const std::lock_guard<std::mutex> guard(source.line->lock);
    c.serial_bytes += source.line->bytes;
    c.serial_discarded += source.line->discarded;
  }
  return c;
}

}  // namespace blockmap::cli::daemon

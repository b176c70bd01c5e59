#include "blockmap/hal/sim/run_recorder.hpp"

#include <array>
#include <cinttypes>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "blockmap/hal/protocol/candump.hpp"

namespace blockmap::hal::sim {
namespace {

constexpr std::size_t kFileBufferBytes = 1 << 16;

double unix_seconds(TimestampNs stamp_ns) {
  return static_cast<double>(stamp_ns) * 1e-9;
}

}  // namespace

RunRecorder::RunRecorder(std::filesystem::path folder, const Simulation& simulation)
    : folder_(std::move(folder)), simulation_(simulation) {
  std::error_code error;
  std::filesystem::create_directories(folder_, error);
  if (error) {
    throw std::runtime_error("cannot create '" + folder_.string() + "': " + error.message());
  }
  can_ = open("rmp.candump");
  for (std::size_t device = 0; device < simulation.serial_device_count(); ++device) {
    const std::string name = simulation.serial_device_name(device);
    const bool is_gps = device + 1 == simulation.serial_device_count();
    serial_.push_back(open(is_gps ? name + ".nmea" : name + ".bytelog"));
    if (!is_gps) {
      write(serial_.back(), protocol::byte_log::kMagic.data(), protocol::byte_log::kMagic.size());
    }
  }
  truth_ = open("truth.json");
  truth_gps_ = open("truth_gps.csv");
  static constexpr char kGpsHeader[] =
      "t_s,x_m,y_m,z_m,error_e_m,error_n_m,error_u_m,satellites,hdop,fix\n";
  write(truth_gps_, kGpsHeader, sizeof kGpsHeader - 1);
  std::fprintf(truth_.handle,
               "{\"world\": \"%s\", \"robot\": \"%s\", \"start_unix_s\": %.6f,\n\"trajectory\": [",
               simulation.world().name.c_str(), simulation.robot().name.c_str(),
               unix_seconds(simulation.start_ns()));
}

RunRecorder::~RunRecorder() {
  for (File* file : {&can_, &truth_, &truth_gps_}) {
    if (file->handle != nullptr) {
      std::fclose(file->handle);
    }
  }
  for (File& file : serial_) {
    if (file.handle != nullptr) {
      std::fclose(file.handle);
    }
  }
}

RunRecorder::File RunRecorder::open(const std::string& name) {
  File file;
  file.path = folder_ / name;
  file.handle = std::fopen(file.path.c_str(), "wb");
  if (file.handle == nullptr) {
    throw std::runtime_error("cannot write '" + file.path.string() + "'");
  }
  file.buffer = std::make_unique<char[]>(kFileBufferBytes);
  std::setvbuf(file.handle, file.buffer.get(), _IOFBF, kFileBufferBytes);
  return file;
}

void RunRecorder::write(File& file, const void* data, std::size_t size) {
  if (std::fwrite(data, 1, size, file.handle) != size) {
    failed_ = true;
  }
}

void RunRecorder::on_can_frame(TimestampNs stamp_ns, const CanFrame& frame) {
  protocol::candump::Record record;
  record.stamp_ns = stamp_ns;
  record.interface = {'c', 'a', 'n', '0'};
  record.frame = frame;
  std::array<char, 80> line{};
  const std::size_t length = protocol::candump::format_line(record, line);
  line[length] = '\n';
  write(can_, line.data(), length + 1);
}

void RunRecorder::on_serial(std::size_t device, TimestampNs stamp_ns,
                            protocol::byte_log::Direction direction,
                            std::span<const std::uint8_t> bytes) {
  File& file = serial_[device];
  const bool is_gps = device + 1 == serial_.size();
  if (!is_gps) {
    std::array<std::uint8_t, protocol::byte_log::kRecordHeaderBytes> header{};
    protocol::byte_log::encode_record_header(
        {stamp_ns, static_cast<std::uint32_t>(bytes.size()), direction}, header);
    write(file, header.data(), header.size());
  } else if (direction == protocol::byte_log::Direction::kToDevice) {
    return;  // a raw NMEA log holds what the receiver sent
  }
  write(file, bytes.data(), bytes.size());
}

void RunRecorder::on_truth_state(TimestampNs stamp_ns, const RobotState& state) {
  const int length = std::fprintf(
      truth_.handle,
      "%s\n{\"t_s\": %.6f, \"x_m\": %.4f, \"y_m\": %.4f, \"z_m\": %.4f, \"roll_rad\": %.5f, "
      "\"pitch_rad\": %.5f, \"yaw_rad\": %.5f, \"speed_mps\": %.4f}",
      first_state_ ? "" : ",", unix_seconds(stamp_ns), state.position_m.x(), state.position_m.y(),
      state.position_m.z(), state.roll_rad, state.pitch_rad, state.yaw_rad, state.speed_mps);
  failed_ = failed_ || length < 0;
  first_state_ = false;
}

void RunRecorder::on_gps_epoch(const GpsTruth& truth) {
  const int length =
      std::fprintf(truth_gps_.handle, "%.6f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%d,%.2f,%d\n",
                   unix_seconds(truth.epoch_ns), truth.antenna_m.x(), truth.antenna_m.y(),
                   truth.antenna_m.z(), truth.error_m.x(), truth.error_m.y(), truth.error_m.z(),
                   truth.satellites_visible, truth.hdop, truth.fix ? 1 : 0);
  failed_ = failed_ || length < 0;
}

void RunRecorder::write_text_file(std::string_view name, std::string_view text) {
  File file = open(std::string(name));
  write(file, text.data(), text.size());
  if (std::fclose(file.handle) != 0) {
    failed_ = true;
  }
}

void RunRecorder::finish(std::uint64_t seed) {
  std::FILE* out = truth_.handle;
  std::fprintf(out, "\n],\n\"seed\": %" PRIu64 ",\n\"faces\": [", seed);
  const std::vector<TruthFace>& faces = simulation_.scene().faces();
  for (std::size_t i = 0; i < faces.size(); ++i) {
    const TruthFace& face = faces[i];
    std::fprintf(out, "%s\n{\"id\": %d, \"kind\": \"%s\", \"building\": ", i == 0 ? "" : ",",
                 face.id, to_string(face.kind));
    if (face.building_id >= 0) {
      std::fprintf(out, "%d", face.building_id);
    } else {
      std::fprintf(out, "null");
    }
    std::fprintf(out, R"(, "normal": [%.6f, %.6f, %.6f], "d": %.4f, "corners": [)", face.normal.x(),
                 face.normal.y(), face.normal.z(), face.d_m);
    for (std::size_t c = 0; c < face.corners_m.size(); ++c) {
      const Vec3& p = face.corners_m[c];
      std::fprintf(out, "%s[%.4f, %.4f, %.4f]", c == 0 ? "" : ", ", p.x(), p.y(), p.z());
    }
    std::fprintf(out, "], \"returns\": %" PRIu64 "}", face.returns);
  }
  std::fprintf(out, "\n],\n\"buildings\": [");
  const std::vector<Building>& buildings = simulation_.world().buildings;
  for (std::size_t i = 0; i < buildings.size(); ++i) {
    const Building& building = buildings[i];
    std::fprintf(out, "%s\n{\"id\": %d, \"shape\": \"%s\", \"height\": %.4f, \"footprint\": [",
                 i == 0 ? "" : ",", building.id, to_string(building.shape), building.height_m);
    for (std::size_t c = 0; c < building.footprint_m.size(); ++c) {
      std::fprintf(out, "%s[%.4f, %.4f]", c == 0 ? "" : ", ", building.footprint_m[c].x(),
                   building.footprint_m[c].y());
    }
    std::fprintf(out, "]}");
  }
  const GeodeticPoint& origin = simulation_.world().site.origin;
  std::fprintf(out,
               "\n],\n\"origin\": {\"latitude_deg\": %.9f, \"longitude_deg\": %.9f, "
               "\"height_m\": %.3f}\n}\n",
               origin.latitude_deg, origin.longitude_deg, origin.height_m);
  for (File* file : {&can_, &truth_, &truth_gps_}) {
    failed_ = std::fclose(file->handle) != 0 || failed_;
    file->handle = nullptr;
  }
  for (File& file : serial_) {
    failed_ = std::fclose(file.handle) != 0 || failed_;
    file.handle = nullptr;
  }
  if (failed_) {
    throw std::runtime_error("writing '" + folder_.string() + "' failed (disk full?)");
  }
}

}  // namespace blockmap::hal::sim

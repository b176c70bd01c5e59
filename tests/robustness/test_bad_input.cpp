// Every command given what a hostile but ordinary user gives it (issue 55): a bad number, a
// folder where a file belongs, a configuration that asks for too much, a file that lies about
// its size, a disk that is full. Each must end on its own, soon, within its memory, with one
// line that names the problem and a status that says whose it is (docs/formats.md, The command
// line): 2 for the command line and its configuration, 1 for the data and the disk.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "blockmap_process.hpp"
#include "scratch.hpp"
#include "test_data.hpp"

namespace blockmap::testing {
namespace {

namespace fs = std::filesystem;

constexpr int kOk = 0;
constexpr int kFailure = 1;
constexpr int kUsage = 2;

// Far above what any case needs (the mapper's arena is 64 MiB; the sanitizers add their
// shadow), far below what a file that lies about its size used to take.
constexpr std::size_t kMaxPeakBytes = std::size_t{1} << 30;

struct Case {
  const char* name;
  std::vector<std::string> args;
  int status;
  bool needs_log = false;  // a short simulated run in ./log
};

void write_file(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// The inputs the cases name, in the case's own folder.
void make_inputs(const fs::path& dir) {
  fs::create_directories(dir);
  for (const char* folder : {"folder", "folder.json", "folder.ply", "folder.toml", "out_dir"}) {
    fs::create_directories(dir / folder);
  }
  write_file(dir / "cloud.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n0 0 0\n1 1 1\n2 2 2\n");
  write_file(dir / "unknown_table.toml", "[plains]\nmin_votes = 3\n");
  write_file(dir / "unknown_key.toml", "planes = 3\n");
  // A character toml++ 3.3 would take to an unreachable point (marzer/tomlplusplus#295).
  write_file(dir / "non_ascii.toml", "[planes]\n\xcc\xaa = 3\n");
  // A quote after a value, then a non-ASCII character (found by fuzz_replay_folder).
  write_file(dir / "quote_non_ascii.toml", "[planes]\ne=0'\xc3\xb9\n");
  write_file(dir / "refine.toml", "[planes]\nrefine_iterations = 1000000000\n");
  write_file(dir / "fine_any.toml", "[planes]\nangle_bin_deg = 0.25\norientations = \"any\"\n");
  write_file(dir / "max_patches.toml", "[planes]\nmax_patches = 2147483000\n");
  write_file(dir / "capacity.toml", "[registry]\nmax_live_planes = 9223372036854775807\n");
  // A binary_compressed PCD of 116 bytes that claims a billion points in 4 GB.
  std::string pcd =
      "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
      "WIDTH 357913941\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 357913941\n"
      "DATA binary_compressed\n";
  const unsigned char sizes[] = {4, 0, 0, 0, 0xfc, 0xff, 0xff, 0xff, 1, 2, 3, 4};
  pcd.append(reinterpret_cast<const char*>(sizes), sizeof sizes);
  write_file(dir / "lying.pcd", pcd);
  // A plane list of 3 MiB: over a 1 MiB budget's share for JSON.
  std::string list = "{\"planes\":[";
  for (int i = 0; i < 20000; ++i) {
    list += (i > 0 ? "," : "");
    list += R"({"id":1,"normal":[1,0,0],"d_m":0,"centroid_m":[0,0,0],"support":10,)"
            R"("rmse_m":0.01,"label":"wall","polygon_m":[[0,0,0],[0,1,0],[0,1,1]]})";
  }
  write_file(dir / "big.json", list + "]}\n");
}

ProcessLimits limits(double timeout_s, std::size_t max_file_bytes = 0,
                     std::string stdout_path = {}) {
  ProcessLimits chosen;
  chosen.timeout_s = timeout_s;
  chosen.max_file_bytes = max_file_bytes;
  chosen.stdout_path = std::move(stdout_path);
  return chosen;
}

class BadInput : public ::testing::TestWithParam<Case> {};

std::string last_line(const std::string& text) {
  const std::size_t end = text.find_last_not_of('\n');
  if (end == std::string::npos) {
    return {};
  }
  const std::size_t start = text.rfind('\n', end);
  return text.substr(start == std::string::npos ? 0 : start + 1, end + 1 - (start + 1));
}

std::size_t lines(const std::string& text) {
  return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
}

TEST_P(BadInput, EndsSoonWithinItsMemoryWithOneLineAndTheRightStatus) {
  const Case& c = GetParam();
  const fs::path dir = scratch(std::string("robust_") + c.name);
  fs::remove_all(dir);
  make_inputs(dir);
  if (c.needs_log) {
    const ProcessResult log = run_process(
        BLOCKMAP_EXE, {"simulate", "--world", "benning", "--duration-s", "3", "--out", "log"}, dir,
        limits(60.0));
    ASSERT_EQ(log.status, kOk) << log.err;
  }
  const ProcessResult r = run_process(BLOCKMAP_EXE, c.args, dir, limits(10.0));
  ASSERT_FALSE(r.timed_out) << "ran past 10 s: " << r.err;
  ASSERT_TRUE(r.exited) << "ended by signal " << r.signal << ": " << r.err;
  EXPECT_EQ(r.status, c.status) << r.err;
  EXPECT_LT(r.peak_rss_bytes, kMaxPeakBytes);
  for (const char* crash : {"CHECK failed", "terminate called", "runtime error:", "Sanitizer"}) {
    EXPECT_EQ(r.err.find(crash), std::string::npos) << r.err;
  }
  if (c.status != kOk) {
    EXPECT_EQ(last_line(r.err).rfind("blockmap: ", 0), 0u) << r.err;
  }
  if (c.status == kUsage) {
    EXPECT_EQ(lines(r.err), 1u) << r.err;
  }
  fs::remove_all(dir);
}

const std::vector<Case> kCases = {
    // Folders, missing files and unreadable inputs (data: 1).
    {"planes_of_a_folder", {"planes", "folder.ply"}, kFailure},
    {"planes_of_a_missing_file", {"planes", "missing.ply"}, kFailure},
    {"buildings_of_a_folder", {"buildings", "folder.json"}, kFailure},
    {"buildings_points_a_folder",
     {"buildings", "cloud.ply", "--points", "folder.ply", "--svg", "x.svg"},
     kFailure},
    {"decode_nmea_folder", {"decode", "nmea", "folder"}, kFailure},
    {"decode_rmp_folder", {"decode", "rmp", "folder"}, kFailure},
    {"decode_lms2xx_folder", {"decode", "lms2xx", "folder"}, kFailure},
    {"decode_cola_folder", {"decode", "cola", "folder"}, kFailure},
    {"decode_scip2_folder", {"decode", "scip2", "folder"}, kFailure},
    {"replay_of_a_missing_folder", {"replay", "missing", "--out", "o"}, kFailure},
    {"pcd_that_lies_about_its_size", {"planes", "lying.pcd"}, kFailure},
    {"plane_list_over_the_budget", {"buildings", "big.json", "--budget-mib", "1"}, kFailure},
    // Configurations (the command line's: 2).
    {"config_a_folder", {"planes", "cloud.ply", "--config", "folder.toml"}, kUsage},
    {"config_missing", {"planes", "cloud.ply", "--config", "missing.toml"}, kUsage},
    {"config_unknown_table", {"planes", "cloud.ply", "--config", "unknown_table.toml"}, kUsage},
    {"config_unknown_top_key", {"buildings", "cloud.ply", "--config", "unknown_key.toml"}, kUsage},
    {"run_config_unknown_table", {"run", "--config", "unknown_table.toml", "--out", "o"}, kUsage},
    {"config_non_ascii_key", {"planes", "cloud.ply", "--config", "non_ascii.toml"}, kUsage},
    {"config_quote_then_non_ascii",
     {"planes", "cloud.ply", "--config", "quote_non_ascii.toml"},
     kUsage},
    {"config_endless_refinement", {"planes", "cloud.ply", "--config", "refine.toml"}, kUsage},
    {"config_fine_any_orientation", {"planes", "cloud.ply", "--config", "fine_any.toml"}, kUsage},
    {"run_config_fine_any_orientation", {"run", "--config", "fine_any.toml", "--out", "o"}, kUsage},
    {"config_patches_over_the_budget",
     {"planes", "cloud.ply", "--config", "max_patches.toml"},
     kUsage},
    {"config_capacity_beyond_any", {"run", "--config", "capacity.toml", "--out", "o"}, kUsage},
    {"replay_config_unknown_table",
     {"replay", "log", "--config", "unknown_table.toml", "--out", "o"},
     kUsage,
     true},
    // Numbers (2).
    {"seed_negative_run", {"run", "--seed", "-1", "--out", "o"}, kUsage},
    {"seed_negative_simulate",
     {"simulate", "--world", "benning", "--seed", "-1", "--out", "o"},
     kUsage},
    {"duration_nan", {"run", "--duration-s", "nan", "--out", "o"}, kUsage},
    {"duration_nan_simulate",
     {"simulate", "--world", "benning", "--duration-s", "nan", "--out", "o"},
     kUsage},
    {"budget_nan", {"run", "--budget-mib", "nan", "--out", "o"}, kUsage},
    {"budget_beyond_any_machine", {"run", "--budget-mib", "1e300", "--out", "o"}, kUsage},
    {"budget_too_small", {"planes", "cloud.ply", "--budget-mib", "0.5"}, kUsage},
    {"udp_port_past_65535", {"run", "--udp", "127.0.0.1:65536", "--out", "o"}, kUsage},
    {"udp_without_port", {"run", "--udp", "localhost", "--out", "o"}, kUsage},
    {"replay_without_robot_config_unknown_table",
     {"replay", "folder", "--config", "unknown_table.toml", "--out", "o"},
     kUsage},
    {"play_speed_nan", {"play", "log", "--pty-dir", "ptys", "--speed", "nan"}, kUsage, true},
    {"replay_origin_nan", {"replay", "log", "--origin", "nan,0,0", "--out", "o"}, kUsage, true},
    {"replay_origin_height_nan",
     {"replay", "log", "--origin", "0,0,nan", "--out", "o"},
     kUsage,
     true},
    {"replay_origin_height_absurd",
     {"replay", "log", "--origin", "0,0,1e300", "--out", "o"},
     kUsage,
     true},
    {"replay_seed_negative", {"replay", "log", "--seed", "-1", "--out", "o"}, kUsage, true},
    {"buildings_origin_nan",
     {"buildings", "cloud.ply", "--origin", "0,nan,0", "--geojson", "x.geojson"},
     kUsage},
    // Writes that fail (the disk's: 1).
    {"planes_out_full_disk", {"planes", "cloud.ply", "--out", "/dev/full"}, kFailure},
    {"planes_svg_full_disk", {"planes", "cloud.ply", "--svg", "/dev/full"}, kFailure},
    {"planes_out_a_folder", {"planes", "cloud.ply", "--out", "out_dir"}, kFailure},
    {"buildings_vrml_full_disk", {"buildings", "cloud.ply", "--vrml", "/dev/full"}, kFailure},
    {"run_out_not_a_folder", {"run", "--duration-s", "1", "--out", "/dev/full"}, kFailure},
    {"simulate_out_not_a_folder",
     {"simulate", "--world", "benning", "--duration-s", "1", "--out", "/dev/full"},
     kFailure},
};

std::string case_name(const ::testing::TestParamInfo<Case>& param) {
  return param.param.name;
}

INSTANTIATE_TEST_SUITE_P(Commands, BadInput, ::testing::ValuesIn(kCases), case_name);

TEST(Streams, DecodeReadsACaptureOfAnyLengthInConstantMemory) {
  const fs::path dir = scratch("robust_stream");
  fs::remove_all(dir);
  fs::create_directories(dir);
  // 128 MiB of zeros (a sparse file: no disk taken), read through the NMEA decoder.
  constexpr std::uintmax_t kBytes = std::uintmax_t{1} << 27;
  std::ofstream(dir / "zeros.bin").close();
  fs::resize_file(dir / "zeros.bin", kBytes);
  const ProcessResult r =
      run_process(BLOCKMAP_EXE, {"decode", "nmea", "zeros.bin"}, dir, limits(120.0));
  ASSERT_TRUE(r.exited) << r.err;
  EXPECT_EQ(r.status, kOk) << r.err;
  EXPECT_NE(r.err.find("garbage " + std::to_string(kBytes)), std::string::npos) << r.err;
  EXPECT_LT(r.peak_rss_bytes, std::size_t{64} << 20) << "the capture was held, not streamed";
  fs::remove_all(dir);
}

class Writes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = scratch("robust_writes");
    fs::remove_all(dir_);
    make_inputs(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(Writes, AWriteThatFailsLeavesTheFileThatWasThereAndNoPartOfTheNewOne) {
  write_file(dir_ / "planes.json", "the list of an earlier run\n");
  // The new list is longer than the 16 bytes the process may write: its write fails (EFBIG).
  const ProcessResult r = run_process(BLOCKMAP_EXE, {"planes", "cloud.ply", "--out", "planes.json"},
                                      dir_, limits(10.0, 16));
  ASSERT_TRUE(r.exited) << r.err;
  EXPECT_EQ(r.status, kFailure) << r.err;
  EXPECT_NE(last_line(r.err).find("planes.json"), std::string::npos) << r.err;
  EXPECT_EQ(read_text(dir_ / "planes.json"), "the list of an earlier run\n");
  for (const fs::directory_entry& entry : fs::directory_iterator(dir_)) {
    EXPECT_EQ(entry.path().filename().string().find("partial"), std::string::npos) << entry.path();
  }
}

TEST_F(Writes, ResultsThatCannotReachStandardOutputAreAFailure) {
  const ProcessResult r =
      run_process(BLOCKMAP_EXE, {"planes", "cloud.ply"}, dir_, limits(10.0, 0, "/dev/full"));
  ASSERT_TRUE(r.exited) << r.err;
  EXPECT_EQ(r.status, kFailure) << r.err;
  EXPECT_EQ(last_line(r.err), "blockmap: cannot write the results to standard output");
}

TEST_F(Writes, AMapWhoseFilesCannotAllBeWrittenIsAFailureNamingTheFile) {
  // The run's streams and lists are bigger than 4 KiB: the first that passes it fails.
  const ProcessResult r = run_process(BLOCKMAP_EXE, {"run", "--duration-s", "20", "--out", "map"},
                                      dir_, limits(120.0, 4096));
  ASSERT_TRUE(r.exited) << r.err;
  EXPECT_EQ(r.status, kFailure) << r.err;
  EXPECT_NE(last_line(r.err).find("map/"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace blockmap::testing

#include "blockmap/hal/files.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "scratch.hpp"

namespace blockmap::hal {
namespace {

namespace fs = std::filesystem;

class Files : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::scratch("files");
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  [[nodiscard]] std::string text_of(const fs::path& path) const {
    std::ifstream file(path, std::ios::binary);
    std::ostringstream text;
    text << file.rdbuf();
    return text.str();
  }

  fs::path dir_;
};

TEST_F(Files, AFileIsReadWhole) {
  const std::string bytes(200000, 'x');
  std::ofstream(dir_ / "a.txt", std::ios::binary) << bytes;
  EXPECT_EQ(read_whole_file(dir_ / "a.txt", 1 << 20), bytes);
}

TEST_F(Files, AFolderOrAMissingFileIsRefusedNamingIt) {
  fs::create_directories(dir_ / "folder");
  EXPECT_EQ(unreadable_file(dir_ / "folder"),
            (dir_ / "folder").string() + ": is a folder, not a file");
  EXPECT_NE(unreadable_file(dir_ / "missing").find("No such file"), std::string::npos);
  EXPECT_THROW(static_cast<void>(read_whole_file(dir_ / "folder", 1024)), FileError);
  EXPECT_THROW(static_cast<void>(read_whole_file(dir_ / "missing", 1024)), FileError);
}

TEST_F(Files, AFileBiggerThanTheCapIsRefusedHavingReadLittleMore) {
  std::ofstream(dir_ / "big.txt", std::ios::binary) << std::string(300000, 'x');
  try {
    static_cast<void>(read_whole_file(dir_ / "big.txt", 100000));
    FAIL() << "a file over its cap was read";
  } catch (const FileError& error) {
    EXPECT_NE(std::string(error.what()).find("big.txt: larger than"), std::string::npos);
  }
}

TEST_F(Files, AnEndlessDeviceIsReadOnlyToTheCap) {
  EXPECT_THROW(static_cast<void>(read_whole_file("/dev/zero", 1 << 20)), FileError);
}

TEST_F(Files, AWholeWriteReplacesTheFileAndLeavesNoTemporaryOne) {
  std::ofstream(dir_ / "out.json") << "old\n";
  EXPECT_EQ(write_whole_file(dir_ / "out.json", "new\n"), "");
  EXPECT_EQ(text_of(dir_ / "out.json"), "new\n");
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(Files, AWriteThatCannotBeMadeNamesTheFileAndKeepsWhatWasThere) {
  std::ofstream(dir_ / "plain") << "a file, not a folder\n";
  const std::string problem = write_whole_file(dir_ / "plain" / "out.json", "new\n");
  EXPECT_EQ(problem.rfind((dir_ / "plain" / "out.json").string() + ": cannot create", 0), 0u)
      << problem;
  fs::create_directories(dir_ / "folder");
  EXPECT_EQ(write_whole_file(dir_ / "folder", "new\n"),
            (dir_ / "folder").string() + ": is a folder, not a file");
  EXPECT_EQ(text_of(dir_ / "plain"), "a file, not a folder\n");
}

TEST_F(Files, ADeviceIsWrittenInPlaceAndAFullOneIsAFailure) {
  EXPECT_EQ(write_whole_file("/dev/null", "bytes\n"), "");
  EXPECT_EQ(write_whole_file("/dev/full", "bytes\n").rfind("/dev/full: write failed", 0), 0u);
}

}  // namespace
}  // namespace blockmap::hal

// Inputs as csrbf reads them (csrbf/io/input_file.hpp): only regular files and pipes, bounded in
// size, a FIFO without a writer an error after a time, every refusal a FileError naming the file.
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <sys/stat.h>
#include <thread>

using namespace csrbf;

namespace {

std::string refusal(const std::filesystem::path& path) {
  try {
    io::check_readable(path, "a mesh");
  } catch (const io::FileError& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace

TEST(AtomicFile, ReadInputBoundsSizeAndWaitsForAFifo) {
  test::TempDir dir;
  test::write_text(dir / "big.txt", std::string(1000, 'x'));
  try {
    io::read_input(dir / "big.txt", "a test file", 100);
    FAIL();
  } catch (const io::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("big.txt: 1000 bytes is more than the 100 bytes allowed"), std::string::npos)
        << e.what();
  }
  EXPECT_EQ(io::read_input(dir / "big.txt", "a test file").size(), 1000u);
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0644), 0);
  ::setenv("CSRBF_PIPE_TIMEOUT", "1", 1);
  EXPECT_THROW(io::read_input(dir / "fifo", "a test file"), io::FileError);
  // With a writer: read whole.
  std::thread writer([&] { test::write_text(dir / "fifo", "through the pipe"); });
  EXPECT_EQ(io::read_input(dir / "fifo", "a test file"), "through the pipe");
  writer.join();
  ::unsetenv("CSRBF_PIPE_TIMEOUT");
}

TEST(InputFile, OnlyRegularFilesAndPipesAreReadable) {
  test::TempDir dir;
  test::write_text(dir / "mesh.obj", "v 0 0 0\n");
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0644), 0);
  std::filesystem::create_symlink(dir / "mesh.obj", dir / "link.obj");
  std::filesystem::create_symlink(dir / "gone.obj", dir / "dangling.obj");
  EXPECT_EQ(refusal(dir / "mesh.obj"), "accepted");
  EXPECT_EQ(refusal(dir / "link.obj"), "accepted");
  EXPECT_EQ(refusal(dir / "fifo"), "accepted");  // checked without opening it: no writer needed
  EXPECT_EQ(refusal(dir / "missing.obj"), (dir / "missing.obj").string() + ": no such file");
  EXPECT_EQ(refusal(dir / "dangling.obj"), (dir / "dangling.obj").string() + ": no such file");
  EXPECT_EQ(refusal(dir.path), dir.path.string() + ": is a folder, not a mesh");
  EXPECT_EQ(refusal("/dev/zero"), "/dev/zero: is not a regular file (a device or socket), not a mesh");
}

TEST(InputFile, ReadInputReadsWhatIsThereAndRefusesDevices) {
  test::TempDir dir;
  test::write_text(dir / "empty.txt", "");
  const std::string bytes("a\0b\r\n\xff", 6);
  test::write_text(dir / "bytes.bin", bytes);
  EXPECT_EQ(io::read_input(dir / "empty.txt", "a test file"), "");
  EXPECT_EQ(io::read_input(dir / "bytes.bin", "a test file"), bytes);
  EXPECT_EQ(io::read_input(dir / "bytes.bin", "a test file", 6), bytes);  // the limit itself is allowed
  EXPECT_THROW(io::read_input(dir / "bytes.bin", "a test file", 5), io::FileError);
  // /dev/zero never ends: refused by name before it is opened, not read until memory runs out.
  try {
    io::read_input("/dev/zero", "a motion");
    FAIL() << "/dev/zero was read";
  } catch (const io::FileError& e) {
    EXPECT_STREQ(e.what(), "/dev/zero: is not a regular file (a device or socket), not a motion");
  }
}

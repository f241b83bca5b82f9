#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <sys/stat.h>
#include <thread>

using namespace csrbf;

TEST(AtomicFile, WritesAndReplaces) {
  test::TempDir dir;
  io::write_atomically(dir / "a.txt", [](std::ostream& o) { o << "one"; });
  EXPECT_EQ(test::read_text(dir / "a.txt"), "one");
  io::write_atomically(dir / "a.txt", [](std::ostream& o) { o << "two"; });
  EXPECT_EQ(test::read_text(dir / "a.txt"), "two");
  EXPECT_EQ(test::files_in(dir.path), 1u);
}

TEST(AtomicFile, FailureLeavesTheOldFileAndNoTemporary) {
  test::TempDir dir;
  test::write_text(dir / "a.txt", "precious");
  EXPECT_THROW(io::write_atomically(dir / "a.txt",
                                    [](std::ostream& o) {
                                      o << "half";
                                      throw std::runtime_error("writer failed");
                                    }),
               std::runtime_error);
  EXPECT_EQ(test::read_text(dir / "a.txt"), "precious");
  EXPECT_EQ(test::files_in(dir.path), 1u);
  EXPECT_THROW(io::write_atomically_via_folder(dir / "b.gltf",
                                               [](const std::filesystem::path& p) {
                                                 test::write_text(p, "x");
                                                 throw std::runtime_error("exporter failed");
                                               }),
               std::runtime_error);
  EXPECT_EQ(test::files_in(dir.path), 1u);
}

TEST(AtomicFile, ViaFolderMovesSideFiles) {
  test::TempDir dir;
  io::write_atomically_via_folder(dir / "m.gltf", [](const std::filesystem::path& p) {
    test::write_text(p, "gltf");
    test::write_text(p.parent_path() / "m.bin", "bin");
  });
  EXPECT_EQ(test::read_text(dir / "m.gltf"), "gltf");
  EXPECT_EQ(test::read_text(dir / "m.bin"), "bin");
  EXPECT_EQ(test::files_in(dir.path), 2u);
}

TEST(AtomicFile, MissingFolderIsAClearError) {
  test::TempDir dir;
  try {
    io::write_atomically(dir / "no/such/out.obj", [](std::ostream&) {});
    FAIL();
  } catch (const io::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no/such"), std::string::npos) << e.what();
  }
  EXPECT_THROW(io::check_output_path(dir.path), io::FileError);  // a folder is not a file
}

TEST(AtomicFile, OnlyRegularFilesAreReplaced) {
  test::TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "pipe").c_str(), 0644), 0);
  try {
    io::write_atomically(dir / "pipe", [](std::ostream& o) { o << "x"; });
    FAIL();
  } catch (const io::FileError& e) {
    EXPECT_NE(std::string(e.what()).find("not a regular file"), std::string::npos) << e.what();
  }
  EXPECT_THROW(io::check_output_path("/dev/null"), io::FileError);
  EXPECT_NO_THROW(io::check_output_path(dir / "new.obj"));
  test::write_text(dir / "old.obj", "x");
  EXPECT_NO_THROW(io::check_output_path(dir / "old.obj"));
  EXPECT_EQ(test::files_in(dir.path), 2u);
}

TEST(AtomicFile, PartialsOfDeadWritersAreRemovedAndNothingElse) {
  test::TempDir dir;
  // A partial whose writer is alive (its lock is held) stays; one whose writer died is removed by
  // the next Partial in that folder once it is 2 s old; files of the user's stay, even with
  // partial-looking names that lack the marker.
  io::Partial live(dir / "a.obj", io::Partial::Kind::File);
  test::write_text(dir / ".b.obj.csrbf-partial-0123456789abcdef", "dead");  // nobody holds its lock
  std::filesystem::create_directory(dir / ".frames.csrbf-partial-00000000deadbeef");
  test::write_text(dir / ".frames.csrbf-partial-00000000deadbeef" / "frame_00000.png", "png");
  test::write_text(dir / ".b.obj.tmp-1234", "the user's");
  test::write_text(dir / "notes.txt", "the user's");
  EXPECT_EQ(test::files_in(dir.path), 5u);
  io::remove_stale_partials(dir.path);  // all younger than 2 s: kept
  EXPECT_EQ(test::files_in(dir.path), 5u);
  std::this_thread::sleep_for(std::chrono::milliseconds(2100));
  io::write_atomically(dir / "c.obj", [](std::ostream& o) { o << "c"; });
  EXPECT_TRUE(std::filesystem::exists(live.path()));
  EXPECT_FALSE(std::filesystem::exists(dir / ".b.obj.csrbf-partial-0123456789abcdef"));
  EXPECT_FALSE(std::filesystem::exists(dir / ".frames.csrbf-partial-00000000deadbeef"));
  EXPECT_EQ(test::read_text(dir / ".b.obj.tmp-1234"), "the user's");
  EXPECT_EQ(test::read_text(dir / "notes.txt"), "the user's");
  EXPECT_EQ(test::read_text(dir / "c.obj"), "c");
  EXPECT_EQ(test::files_in(dir.path), 4u);
}

TEST(AtomicFile, PartialNamesStayShortAndFramesAreRecognised) {
  test::TempDir dir;
  const std::string name = std::string(240, 'n') + ".obj";
  io::write_atomically(dir / name, [](std::ostream& o) { o << "long"; });
  EXPECT_EQ(test::read_text(dir / name), "long");
  io::Partial p(dir / name, io::Partial::Kind::File, ".mp4");
  EXPECT_LE(p.path().filename().string().size(), 255u);
  EXPECT_TRUE(p.path().filename().string().ends_with(".mp4"));
  EXPECT_TRUE(io::is_frame_name("frame_00000.png"));
  EXPECT_TRUE(io::is_frame_name("frame_1234567.png"));
  EXPECT_FALSE(io::is_frame_name("frame_0000.png"));
  EXPECT_FALSE(io::is_frame_name("frame_0000a.png"));
  EXPECT_FALSE(io::is_frame_name("fish.scene.json"));
}

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

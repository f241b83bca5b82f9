#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

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

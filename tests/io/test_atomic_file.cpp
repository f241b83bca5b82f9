#include "csrbf/io/atomic_file.hpp"
#include "csrbf/io/error.hpp"

#include "io/test_helpers.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <sys/stat.h>
#include <atomic>
#include <sys/wait.h>
#include <thread>
#include <unistd.h>
#include <vector>

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
  // A partial whose writer is alive (its lock is held) stays; one whose writer died (a child that
  // made a file and a folder partial and was gone without cleaning up, as after kill -9) is removed
  // by the next Partial in that folder once it is 2 s old. The user's files stay, even named as
  // partials are: csrbf removes only what carries its mark (an extended attribute), never by name.
  io::Partial live(dir / "a.obj", io::Partial::Kind::File);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto* f = new io::Partial(dir / "b.obj", io::Partial::Kind::File);
    auto* d = new io::Partial(dir / "frames", io::Partial::Kind::Folder);
    test::write_text(d->path() / "frame_00000.png", "png");
    (void)f;
    ::_exit(0);  // no destructors: what a killed run leaves
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  test::write_text(dir / ".c.obj.csrbf-partial-0123456789abcdef", "the user's, named as a partial");
  std::filesystem::create_directory(dir / ".d.csrbf-partial-00000000deadbeef");
  test::write_text(dir / ".d.csrbf-partial-00000000deadbeef" / "notes.txt", "the user's");
  test::write_text(dir / ".b.obj.tmp-1234", "the user's");
  test::write_text(dir / "notes.txt", "the user's");
  EXPECT_EQ(test::files_in(dir.path), 7u);
  io::remove_stale_partials(dir.path);  // all younger than 2 s: kept
  EXPECT_EQ(test::files_in(dir.path), 7u);
  std::this_thread::sleep_for(std::chrono::milliseconds(2100));
  io::write_atomically(dir / "c.obj", [](std::ostream& o) { o << "c"; });
  EXPECT_TRUE(std::filesystem::exists(live.path()));
  for (const auto& e : std::filesystem::directory_iterator(dir.path)) {
    const std::string name = e.path().filename().string();
    EXPECT_FALSE(name.starts_with(".b.obj.csrbf-partial-") || name.starts_with(".frames.csrbf-partial-")) << name;
  }
  EXPECT_EQ(test::read_text(dir / ".c.obj.csrbf-partial-0123456789abcdef"), "the user's, named as a partial");
  EXPECT_EQ(test::read_text(dir / ".d.csrbf-partial-00000000deadbeef" / "notes.txt"), "the user's");
  EXPECT_EQ(test::read_text(dir / ".b.obj.tmp-1234"), "the user's");
  EXPECT_EQ(test::read_text(dir / "notes.txt"), "the user's");
  EXPECT_EQ(test::read_text(dir / "c.obj"), "c");
  EXPECT_EQ(test::files_in(dir.path), 6u);
}

TEST(AtomicFile, ASignalOrTheTimeLimitRemovesPartialFoldersWithWhatIsInThem) {
  // Issue 30, point 8: the handlers removed partial files only, so a partial folder (a VTK, CGNS,
  // glTF or OpenFOAM output being written) outlived SIGTERM and --time-limit until the next run
  // into that folder. Now it goes with the process, with the files, folders and links in it; what a
  // link names, outside, stays.
  test::TempDir dir;
  test::write_text(dir / "outside.txt", "the user's");
  const auto run = [&](int how) {  // 0: SIGTERM, 1: SIGINT, 2: --time-limit
    const pid_t child = ::fork();
    if (child == 0) {
      io::remove_partials_on_signals();
      auto* f = new io::Partial(dir / "a.vtu", io::Partial::Kind::File);
      auto* d = new io::Partial(dir / "case", io::Partial::Kind::Folder);
      (void)f;
      std::filesystem::create_directories(d->path() / "constant" / "polyMesh");
      test::write_text(d->path() / "constant" / "polyMesh" / "points", "points");
      test::write_text(d->path() / "a.vtu", "vtu");
      std::filesystem::create_symlink(dir / "outside.txt", d->path() / "link");
      std::filesystem::create_directory_symlink(dir.path, d->path() / "up");
      for (int k = 0; k < 300; ++k) {
        std::string name("f");  // by appends: GCC 12 warns falsely on '"f" + string' (-Wrestrict)
        name += std::to_string(k);
        test::write_text(d->path() / name, "x");
      }
      if (how == 2) {
        io::limit_time(0.05, false);
        for (;;) ::pause();
      }
      ::raise(how == 0 ? SIGTERM : SIGINT);
      ::_exit(0);  // not reached
    }
    int status = 0;
    EXPECT_EQ(::waitpid(child, &status, 0), child);
    return status;
  };
  for (int how : {0, 1, 2}) {
    const int status = run(how);
    if (how == 2) {
      EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 1) << status;
    } else {
      EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == (how == 0 ? SIGTERM : SIGINT)) << status;
    }
    std::vector<std::string> left;
    for (const auto& e : std::filesystem::directory_iterator(dir.path)) left.push_back(e.path().filename().string());
    EXPECT_EQ(left, std::vector<std::string>{"outside.txt"}) << "after " << how;
    EXPECT_EQ(test::read_text(dir / "outside.txt"), "the user's");
  }
}

TEST(AtomicFile, ANewTargetIsCreatedOnceByConcurrentWriters) {
  test::TempDir dir;
  // Each writer found the name new; exactly one may create it, the others fail with "exists"
  // (a check, then a rename that replaces, let several succeed).
  std::atomic<int> ok{0}, exists{0};
  std::vector<std::thread> writers;
  for (int w = 0; w < 8; ++w)
    writers.emplace_back([&, w] {
      try {
        io::write_atomically(dir / "new.txt", [&](std::ostream& o) {
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
          o << "writer " << w;
        });
        ++ok;
      } catch (const io::FileError& e) {
        if (std::string(e.what()).find("exists") != std::string::npos) ++exists;
      }
    });
  for (auto& t : writers) t.join();
  EXPECT_EQ(ok.load(), 1);
  EXPECT_EQ(exists.load(), 7);
  EXPECT_EQ(test::files_in(dir.path), 1u);
  // The same through a folder (glTF with its .bin).
  ok = 0;
  exists = 0;
  writers.clear();
  for (int w = 0; w < 8; ++w)
    writers.emplace_back([&] {
      try {
        io::write_atomically_via_folder(dir / "m.gltf", [](const std::filesystem::path& p) {
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
          test::write_text(p, "gltf");
          test::write_text(p.parent_path() / "m.bin", "bin");
        });
        ++ok;
      } catch (const io::FileError& e) {
        if (std::string(e.what()).find("exist") != std::string::npos) ++exists;
      }
    });
  for (auto& t : writers) t.join();
  EXPECT_EQ(ok.load(), 1);
  EXPECT_EQ(exists.load(), 7);
  EXPECT_EQ(test::files_in(dir.path), 3u);
  // An existing target is still replaced.
  io::write_atomically(dir / "new.txt", [](std::ostream& o) { o << "again"; });
  EXPECT_EQ(test::read_text(dir / "new.txt"), "again");
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

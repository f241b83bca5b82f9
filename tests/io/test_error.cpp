// The one exception of csrbf's files (csrbf/io/error.hpp): a csrbf::Error that is not bad input
// (the programs exit 1 on it, not 2), whose message is made printable and names the file.
#include "csrbf/io/error.hpp"
#include "csrbf/io/input_file.hpp"

#include <gtest/gtest.h>

#include <string>

using namespace csrbf;

TEST(FileError, IsAnErrorButNotBadInput) {
  const io::FileError e("mesh.obj:3: 'v 1 2' has 2 numbers, not 3");
  EXPECT_NE(dynamic_cast<const Error*>(&e), nullptr);
  EXPECT_EQ(dynamic_cast<const InvalidInput*>(static_cast<const Error*>(&e)), nullptr);
  EXPECT_EQ(dynamic_cast<const UsageError*>(static_cast<const Error*>(&e)), nullptr);
  EXPECT_STREQ(e.what(), "mesh.obj:3: 'v 1 2' has 2 numbers, not 3");
  EXPECT_THROW(throw io::FileError("x"), Error);
  EXPECT_THROW(throw io::FileError(std::string("x")), std::runtime_error);
}

TEST(FileError, AFileNameCannotDriveTheTerminal) {
  // A name read from a file or given on the command line goes into the message escaped.
  const std::string name = "a\x1b[2Jb\n.obj";
  try {
    io::check_readable(name, "a mesh");
    FAIL() << "a missing file was accepted";
  } catch (const io::FileError& e) {
    EXPECT_STREQ(e.what(), "a\\u001b[2Jb\\u000a.obj: no such file");
  }
}

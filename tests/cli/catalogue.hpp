// Shared by the command-line catalogues (test_bad_input.cpp, test_hostile.cpp): one bad input, and
// the program and folders they run with.
#pragma once

#include <string>

namespace csrbf::test {

inline const std::string kCli = CSRBF_CLI;
inline const std::string kExamples = std::string(CSRBF_SOURCE_DIR) + "/examples/";

struct Case {
  std::string name;     // what is wrong
  std::string args;     // after "csrbf"; {dir} is the test's folder
  std::string message;  // a piece of the error message
  int code;             // exit status
};

/// args with {dir} replaced by the test's folder.
inline std::string expand(std::string s, const std::string& dir) {
  for (std::size_t at; (at = s.find("{dir}")) != std::string::npos;) s.replace(at, 5, dir);
  return s;
}

}  // namespace csrbf::test

// Child processes of the renderer (csrbf/render/process.hpp): a program run with a pipe to its
// input, its output and messages kept, its exit status or signal reported, stopped on request; and a
// private X server for the life of a Display, DISPLAY restored after it.
#include "csrbf/render/process.hpp"

#include <gtest/gtest.h>

#include <csignal>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

using namespace csrbf;
using render::Child;

namespace {

/// DISPLAY as it was, put back at the end of a test.
struct SavedDisplay {
  std::optional<std::string> value;
  SavedDisplay() {
    if (const char* d = std::getenv("DISPLAY")) value = d;
  }
  ~SavedDisplay() {
    if (value)
      ::setenv("DISPLAY", value->c_str(), 1);
    else
      ::unsetenv("DISPLAY");
  }
};

std::optional<std::string> display_now() {
  const char* d = std::getenv("DISPLAY");
  return d ? std::optional<std::string>(d) : std::nullopt;
}

}  // namespace

TEST(Child, ReadsItsInputAndKeepsItsOutputAndMessages) {
  Child c({"sh", "-c", "tr a-z A-Z; echo 'to stderr' >&2; exit 3"}, true, -1, true);
  EXPECT_GT(c.pid(), 0);
  const std::string text = "through the pipe\n";
  EXPECT_TRUE(c.write(text.data(), text.size()));
  EXPECT_EQ(c.finish(), 3);
  EXPECT_EQ(c.finish(), 3);  // once finished, the same status
  EXPECT_EQ(c.output(), "THROUGH THE PIPE\n");
  EXPECT_EQ(c.error_output(), "to stderr");  // without its trailing newline
  EXPECT_FALSE(c.stalled());
}

TEST(Child, SignalsAndStopsAreReported) {
  Child killed({"sh", "-c", "kill -TERM $$"}, false);
  EXPECT_EQ(killed.finish(), 128 + SIGTERM);
  // Asked to stop while it runs: killed, and -1.
  Child sleeper({"sleep", "600"}, false);
  EXPECT_EQ(sleeper.finish(-1, [] { return true; }), -1);
  Child again({"sleep", "600"}, false);
  again.kill();
  EXPECT_EQ(again.finish(), 128 + SIGTERM);
}

TEST(Child, WritingToAChildThatExitedIsFalse) {
  std::signal(SIGPIPE, SIG_IGN);  // as MovieWriter does: EPIPE, not a signal
  Child c({"sh", "-c", "exit 0"}, true);
  const std::vector<char> data(std::size_t(1) << 20, 'x');  // more than a pipe holds
  EXPECT_FALSE(c.write(data.data(), data.size()));
  EXPECT_FALSE(c.stalled());
  EXPECT_EQ(c.finish(), 0);
}

TEST(Child, AProgramThatIsNotThereIsNamed) {
  try {
    Child c({"csrbf-no-such-program", "--version"}, false);
    FAIL() << "a missing program was started";
  } catch (const render::RenderError& e) {
    EXPECT_STREQ(e.what(),
                 "cannot run 'csrbf-no-such-program': No such file or directory (is it installed? "
                 "scripts/install-deps.sh installs it)");
    EXPECT_NE(dynamic_cast<const Error*>(&e), nullptr);
  }
}

TEST(Display, APrivateServerForItsLifetime) {
  const SavedDisplay saved;
  ::unsetenv("DISPLAY");
  {
    const render::Display d;
    EXPECT_TRUE(d.is_private());
    EXPECT_EQ(d.name().rfind(':', 0), 0u) << d.name();
    EXPECT_EQ(display_now(), d.name());
    EXPECT_EQ(d.unreachable_display(), "");
    // A display that opens is used as it is.
    const render::Display shared;
    EXPECT_FALSE(shared.is_private());
    EXPECT_EQ(shared.name(), d.name());
  }
  EXPECT_EQ(display_now(), std::nullopt);
  // A DISPLAY that names no server: a private one instead, and DISPLAY put back afterwards.
  ::setenv("DISPLAY", ":4093", 1);
  {
    const render::Display d;
    EXPECT_TRUE(d.is_private());
    EXPECT_EQ(d.unreachable_display(), ":4093");
    EXPECT_EQ(display_now(), d.name());
  }
  EXPECT_EQ(display_now(), ":4093");
}

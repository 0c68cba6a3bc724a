// Runs a program (by default the cndt binary) with a shell command line and collects its exit
// code and its merged stdout/stderr.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace cndt::test {

struct CliRun {
  int code = -1;
  std::string output;
};

inline CliRun run_command(const std::string& command_line) {
  const std::string cmd = command_line + " 2>&1";
  CliRun r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), static_cast<int>(buf.size()), pipe) != nullptr) {
    r.output += buf.data();
  }
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

/// `cndt ARGS`.
inline CliRun run(const std::string& args) {
  return run_command(std::string(CNDT_BINARY) + " " + args);
}

}  // namespace cndt::test

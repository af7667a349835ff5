// v4r - robust model-based object tracking. MIT licence.
// Running the `v4r` command line from a test: exit code, standard output and standard error.
#pragma once

#include <sys/wait.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace v4r_test {

/// \brief What one run of the command line gave.
struct CliRun {
  int code = -1;
  std::string out, err;
};

/// \brief A broken scene file (`text`, the case `what`) as the command line must report it: a
/// non-zero exit and an error naming the file, the `line` and the `field`.
struct BadScene {
  const char* what;
  std::string text;
  int line;
  const char* field;
};

/// The whole content of a file (empty when it cannot be read).
inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Runs `cli args` through the shell, its output captured in files of `dir` (numbered per call).
inline CliRun run_cli(const std::string& cli, const std::string& args, const std::filesystem::path& dir) {
  static int counter = 0;
  const std::filesystem::path out = dir / ("out" + std::to_string(counter) + ".txt");
  const std::filesystem::path err = dir / ("err" + std::to_string(counter++) + ".txt");
  const std::string cmd = cli + " " + args + " >" + out.string() + " 2>" + err.string();
  const int status = std::system(cmd.c_str());
  CliRun r;
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

}  // namespace v4r_test

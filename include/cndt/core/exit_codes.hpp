// Process exit codes shared by cndt and cndtd (sysexits.h values).
#pragma once

#include <string>

namespace cndt::core {

enum ExitCode : int {
  kExitOk = 0,
  kExitUsage = 2,
  kExitDataError = 65,    ///< input data is malformed or holds nothing usable
  kExitNoInput = 66,      ///< an input file is missing or cannot be opened
  kExitIoError = 74,      ///< reading or writing failed
  kExitConfigError = 78,  ///< the configuration is invalid
};

/// An error for a setup step: a message naming what was wrong and where, and the exit code.
struct Error {
  int code = kExitDataError;
  std::string message;
};

}  // namespace cndt::core

// Locating the real captures in ../shared/data (or $CNDT_SHARED_DATA).
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace cndt::test {

inline std::filesystem::path shared_data_dir() {
  if (const char* env = std::getenv("CNDT_SHARED_DATA")) return env;
  return CNDT_SHARED_DATA;
}

/// Full path of a shared capture, or "" when the folder is absent.
inline std::string shared_file(const std::string& relative) {
  const auto p = shared_data_dir() / relative;
  return std::filesystem::exists(p) ? p.string() : std::string();
}

}  // namespace cndt::test

#define CNDT_REQUIRE_SHARED(var, relative)                                    \
  const std::string var = ::cndt::test::shared_file(relative);                \
  if (var.empty()) {                                                          \
    GTEST_SKIP() << "shared capture " << (relative) << " not found under "    \
                 << ::cndt::test::shared_data_dir()                           \
                 << " (set CNDT_SHARED_DATA to the folder of real captures)"; \
  }

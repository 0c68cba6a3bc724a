// A whole file as a string (empty when it cannot be read).
#pragma once

#include <fstream>
#include <iterator>
#include <string>

namespace cndt::test {

inline std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

}  // namespace cndt::test

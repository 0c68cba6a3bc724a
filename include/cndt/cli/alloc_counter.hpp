// Counts heap allocations made by the calling thread while counting is switched on. Linking
// this in replaces the global operator new/delete of the program (they forward to malloc/free).
#pragma once

#include <cstdint>

namespace cndt::cli {

void alloc_counting(bool on) noexcept;
std::uint64_t alloc_count() noexcept;

}  // namespace cndt::cli

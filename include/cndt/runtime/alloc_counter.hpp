// Counts heap allocations made by the calling thread while counting is switched on. Linking this
// in replaces the program's allocation functions: operator new/delete always, and malloc, calloc,
// realloc, posix_memalign, aligned_alloc and memalign too when no sanitizer owns them (so C
// libraries are counted as well); every one forwards to the C library's allocator.
#pragma once

#include <cstdint>

namespace cndt::runtime {

void alloc_counting(bool on) noexcept;
std::uint64_t alloc_count() noexcept;
/// Whether malloc and friends are counted (false in sanitizer builds: operator new only).
bool alloc_counts_malloc() noexcept;

}  // namespace cndt::runtime

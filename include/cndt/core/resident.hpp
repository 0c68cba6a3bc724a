// Capacity that is resident from the start. A reserved vector's pages are only mapped in by the
// first write to them, so a buffer filled to a different size each time (a scan, a voxel array)
// keeps faulting in pages whenever it reaches a new high-water mark: resident memory creeps up
// for as long as the process runs, and the thread filling it stalls in the kernel. Writing the
// whole capacity once at start-up maps it all in; later fills neither allocate nor fault.
#pragma once

#include <cstddef>
#include <vector>

namespace cndt::core {

/// Reserves `n` elements and writes every one of them once with `fill` (a copy, so that every
/// page is written even for element types whose default constructor writes nothing, like
/// Eigen's), then restores the size.
template <class T, class A>
void reserve_resident(std::vector<T, A>& v, std::size_t n, const T& fill) {
  const std::size_t size = v.size();
  v.reserve(n);
  v.resize(v.capacity(), fill);
  v.resize(size, fill);
}

template <class T, class A>
void reserve_resident(std::vector<T, A>& v, std::size_t n) {
  reserve_resident(v, n, T{});
}

}  // namespace cndt::core

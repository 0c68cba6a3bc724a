// Checksums of the published messages.
#pragma once

#include <cstdint>

#include "cndt/core/bytes.hpp"

namespace cndt::output {

/// CRC-8 SAE J1850: polynomial 0x1D, initial value 0xFF, no reflection, final XOR 0xFF (check
/// value 0x4B for the ASCII bytes "123456789"). Protects each CAN frame.
std::uint8_t crc8_sae_j1850(core::ByteSpan bytes) noexcept;

/// CRC-32 (IEEE 802.3, as zlib and PNG: reflected polynomial 0xEDB88320, initial value and final
/// XOR 0xFFFFFFFF; check value 0xCBF43926). Protects each UDP datagram.
std::uint32_t crc32_ieee(core::ByteSpan bytes) noexcept;

}  // namespace cndt::output

// XXH3-64 (seed 0) checksums of the format (spec: "Checksums").
#pragma once

#include <cstddef>
#include <cstdint>

#include "cwbvh/format/format.h"

namespace cwbvh {

/// XXH3-64, seed 0, of `size` bytes: the checksum of a section payload.
uint64_t payload_checksum(const void* data, size_t size);

/// XXH3-64, seed 0, of the 64 header bytes with meta_checksum set to 0,
/// followed by the `table_size` bytes of the section table.
uint64_t meta_checksum(const FileHeader& header, const void* table, size_t table_size);

}  // namespace cwbvh

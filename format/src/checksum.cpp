#include "cwbvh/format/checksum.h"

#include <cstring>

#define XXH_INLINE_ALL
#include <xxhash.h>

namespace cwbvh {

uint64_t payload_checksum(const void* data, size_t size) {
    return XXH3_64bits(data, size);
}

uint64_t meta_checksum(const FileHeader& header, const void* table, size_t table_size) {
    FileHeader zeroed;
    std::memcpy(&zeroed, &header, sizeof zeroed);
    zeroed.meta_checksum = 0;
    XXH3_state_t state;
    XXH3_64bits_reset(&state);
    XXH3_64bits_update(&state, &zeroed, sizeof zeroed);
    if (table_size != 0) XXH3_64bits_update(&state, table, table_size);
    return XXH3_64bits_digest(&state);
}

}  // namespace cwbvh

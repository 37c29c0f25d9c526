// Ray and hit files (spec/rays.md): read with full validation, write. Host only.
// Library: cwbvh_cpu_trace.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"
#include "cwbvh/kernels/ray.h"

namespace cwbvh {

/// Reads a ray file. On bad input returns kIoError (cannot read) or kBadInput with
/// the one-line message "<path>: <what is wrong>" (wrong magic, version, record
/// size, flags, reserved field, or a size that is not exactly 32 + count * 32).
Result read_ray_file(const std::string& path, std::vector<Ray>& rays);

/// Reads a hit file; `flags` receives the header flags (HitFileFlags).
Result read_hit_file(const std::string& path, std::vector<Hit>& hits, uint32_t& flags);

/// Writes a ray / hit file (replacing `path`); kIoError on an I/O failure.
Result write_ray_file(const std::string& path, const Ray* rays, size_t count);
Result write_hit_file(const std::string& path, const Hit* hits, size_t count, uint32_t flags);

/// Validates an in-memory image of a ray (want_hits = false) or hit file and
/// returns the record count; used by the readers and the tests. kBadInput with a
/// message without the path on bad input.
Result parse_ray_file_header(const uint8_t* bytes, size_t size, bool want_hits, uint64_t& count,
                             uint32_t& flags);

}  // namespace cwbvh

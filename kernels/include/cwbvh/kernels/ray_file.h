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

/// Reads a hit file of 16-byte Hit records; `flags` receives the header flags
/// (HitFileFlags). A 1.1 file of InstanceHit records is refused by name (read it
/// with the overload below), so no caller drops instance ids unawares.
Result read_hit_file(const std::string& path, std::vector<Hit>& hits, uint32_t& flags);

/// Reads a hit file of either record layout: 16-byte Hit records leave `instances`
/// empty; 20-byte InstanceHit records (version 1.1) fill `instances`, one per hit.
Result read_hit_file(const std::string& path, std::vector<Hit>& hits, std::vector<uint32_t>& instances,
                     uint32_t& flags);

/// Writes a ray / hit file (replacing `path`); kIoError on an I/O failure.
Result write_ray_file(const std::string& path, const Ray* rays, size_t count);
Result write_hit_file(const std::string& path, const Hit* hits, size_t count, uint32_t flags);
/// With instances == nullptr the 1.0 file above; otherwise a 1.1 file of InstanceHit
/// records (hits[i] with instances[i]).
Result write_hit_file(const std::string& path, const Hit* hits, const uint32_t* instances, size_t count,
                      uint32_t flags);

/// Validates an in-memory image of a ray (want_hits = false) or hit file and
/// returns the record count; used by the readers and the tests. kBadInput with a
/// message without the path on bad input.
Result parse_ray_file_header(const uint8_t* bytes, size_t size, bool want_hits, uint64_t& count,
                             uint32_t& flags);
/// Same, accepting a hit file of either record layout; record_size receives 16 or 20
/// (20 only with version_minor >= 1). A ray file's is always 32.
Result parse_ray_file_header(const uint8_t* bytes, size_t size, bool want_hits, uint64_t& count,
                             uint32_t& flags, uint32_t& record_size);

}  // namespace cwbvh

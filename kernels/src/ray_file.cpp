// Ray and hit files (spec/rays.md).
#include "cwbvh/kernels/ray_file.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "cwbvh/format/file_io.h"

namespace cwbvh {
namespace {

static_assert(std::endian::native == std::endian::little,
              "ray files are little-endian; a big-endian host needs byte swapping here");

constexpr size_t kHeaderSize = sizeof(RayFileHeader);

Result bad(std::string what) { return Result::fail(Status::kBadInput, 0, std::move(what)); }
Result io(std::string what) { return Result::fail(Status::kIoError, 0, std::move(what)); }

/// Reads the 32-byte header and then exactly the records it announces: the file must be a regular
/// file (a FIFO or a device such as /dev/zero is refused before any read), and the header's count
/// is checked against the size fstat reported before anything is allocated.
template <class T>
Result read_records(const std::string& path, bool want_hits, std::vector<T>& out, uint32_t& flags) {
    Expected<RegularFile> f = RegularFile::open(path, false);
    if (!f.ok()) return f.error();
    uint8_t header[kHeaderSize] = {};
    const uint64_t head = std::min<uint64_t>(f->size(), kHeaderSize);
    if (Result r = f->read_exact(header, head); !r.ok()) return r;
    uint64_t count = 0;
    // The header check only reads the first min(size, 32) bytes; `size` is the file's.
    if (Result r = parse_ray_file_header(header, size_t(f->size()), want_hits, count, flags); !r.ok()) {
        r.message = path + ": " + r.message;
        return r;
    }
    out.resize(size_t(count));  // count * sizeof(T) == size - 32: bounded by the file
    return f->read_exact(out.data(), count * sizeof(T));
}

Result write_all(const std::string& path, const RayFileHeader& h, const void* records, size_t bytes) {
    FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) return io(path + ": cannot create: " + std::strerror(errno));
    bool ok = std::fwrite(&h, sizeof h, 1, f) == 1;
    if (ok && bytes > 0) ok = std::fwrite(records, 1, bytes, f) == bytes;
    if (std::fclose(f) != 0) ok = false;
    if (!ok) return io(path + ": write error");
    return Result::success();
}

RayFileHeader make_header(bool hits, uint64_t count, uint32_t flags) {
    RayFileHeader h{};
    std::memcpy(h.magic, hits ? kHitFileMagic : kRayFileMagic, 8);
    h.version_major = kRayFileVersionMajor;
    h.version_minor = kRayFileVersionMinor;
    h.record_size = hits ? uint32_t(sizeof(Hit)) : uint32_t(sizeof(Ray));
    h.count = count;
    h.flags = flags;
    h.reserved = 0;
    return h;
}

}  // namespace

Result parse_ray_file_header(const uint8_t* bytes, size_t size, bool want_hits, uint64_t& count,
                             uint32_t& flags) {
    const char* kind = want_hits ? "hit file" : "ray file";
    if (size < kHeaderSize)
        return bad(std::string("not a ") + kind + ": " + std::to_string(size) +
                   " bytes, shorter than the 32-byte header");
    RayFileHeader h;
    std::memcpy(&h, bytes, sizeof h);
    const uint8_t* want = want_hits ? kHitFileMagic : kRayFileMagic;
    const uint8_t* other = want_hits ? kRayFileMagic : kHitFileMagic;
    if (std::memcmp(h.magic, want, 8) != 0) {
        if (std::memcmp(h.magic, other, 8) == 0)
            return bad(std::string("is a ") + (want_hits ? "ray file" : "hit file") + ", expected a " + kind);
        return bad(std::string("not a ") + kind + " (bad magic)");
    }
    if (h.version_major != kRayFileVersionMajor)
        return bad("unsupported version " + std::to_string(h.version_major) + "." +
                               std::to_string(h.version_minor) + " (this reader knows 1.x)");
    const uint32_t rs = want_hits ? uint32_t(sizeof(Hit)) : uint32_t(sizeof(Ray));
    if (h.record_size != rs)
        return bad("record_size " + std::to_string(h.record_size) + ", expected " + std::to_string(rs));
    const uint32_t allowed = want_hits ? (kHitFileAnyHit | kHitFileWatertight) : 0u;
    if ((h.flags & ~allowed) != 0) return bad("unknown flags 0x" + [&] {
        char b[16];
        std::snprintf(b, sizeof b, "%08x", unsigned(h.flags));
        return std::string(b);
    }());
    if (h.reserved != 0) return bad("reserved header field is not 0");
    const uint64_t payload = size - kHeaderSize;
    // count * rs may overflow; compare by division instead.
    if (h.count > payload / rs || payload != h.count * rs)
        return bad("size " + std::to_string(size) + " bytes does not match count " + std::to_string(h.count) +
                               " (expected 32 + " + std::to_string(rs) + " * count: truncated or trailing bytes)");
    count = h.count;
    flags = h.flags;
    return Result::success();
}

Result read_ray_file(const std::string& path, std::vector<Ray>& rays) {
    uint32_t flags = 0;
    return read_records(path, false, rays, flags);
}

Result read_hit_file(const std::string& path, std::vector<Hit>& hits, uint32_t& flags) {
    return read_records(path, true, hits, flags);
}

Result write_ray_file(const std::string& path, const Ray* rays, size_t count) {
    return write_all(path, make_header(false, count, 0), rays, count * sizeof(Ray));
}

Result write_hit_file(const std::string& path, const Hit* hits, size_t count, uint32_t flags) {
    return write_all(path, make_header(true, count, flags), hits, count * sizeof(Hit));
}

}  // namespace cwbvh

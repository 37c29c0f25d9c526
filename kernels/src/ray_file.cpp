// Ray and hit files (spec/rays.md).
#include "cwbvh/kernels/ray_file.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "cwbvh/format/file_io.h"
#include "cwbvh/format/hex.h"

namespace cwbvh {
namespace {

static_assert(std::endian::native == std::endian::little,
              "ray files are little-endian; a big-endian host needs byte swapping here");

constexpr size_t kHeaderSize = sizeof(RayFileHeader);

Result bad(std::string what) { return Result::fail(Status::kBadInput, 0, std::move(what)); }

/// Opens `path` and checks its header: the file must be a regular file (a FIFO or a device such
/// as /dev/zero is refused before any read), and the header's count is checked against the size
/// fstat reported before anything is allocated. `any_hit_layout`: a hit file may hold 16- or
/// 20-byte records (record_size receives which); otherwise only Hit (Ray) records.
Expected<RegularFile> open_records(const std::string& path, bool want_hits, bool any_hit_layout, uint64_t& count,
                                   uint32_t& flags, uint32_t& record_size) {
    Expected<RegularFile> f = RegularFile::open(path, false);
    if (!f.ok()) return f.error();
    uint8_t header[kHeaderSize] = {};
    const uint64_t head = std::min<uint64_t>(f->size(), kHeaderSize);
    if (Result r = f->read_exact(header, head); !r.ok()) return r;
    // The header check only reads the first min(size, 32) bytes; `size` is the file's.
    Result r = any_hit_layout
                   ? parse_ray_file_header(header, size_t(f->size()), want_hits, count, flags, record_size)
                   : parse_ray_file_header(header, size_t(f->size()), want_hits, count, flags);
    if (!r.ok()) {
        r.message = path + ": " + r.message;
        return r;
    }
    if (!any_hit_layout) record_size = want_hits ? uint32_t(sizeof(Hit)) : uint32_t(sizeof(Ray));
    return f;
}

/// Reads the header (open_records) and then exactly the records it announces.
template <class T>
Result read_records(const std::string& path, bool want_hits, std::vector<T>& out, uint32_t& flags) {
    uint64_t count = 0;
    uint32_t rs = 0;
    Expected<RegularFile> f = open_records(path, want_hits, false, count, flags, rs);
    if (!f.ok()) return f.error();
    out.resize(size_t(count));  // count * sizeof(T) == size - 32: bounded by the file
    return f->read_exact(out.data(), count * sizeof(T));
}

Result write_all(const std::string& path, const RayFileHeader& h, const void* records, size_t bytes) {
    Expected<AtomicOutput> out = AtomicOutput::create(path);  // whole or not at all (file_io.h)
    if (!out.ok()) return out.error();
    Result r = out->write(&h, sizeof h);
    if (r.ok() && bytes > 0) r = out->write(records, bytes);
    return r.ok() ? out->commit() : r;
}

RayFileHeader make_header(bool hits, uint64_t count, uint32_t flags, bool instances = false) {
    RayFileHeader h{};
    std::memcpy(h.magic, hits ? kHitFileMagic : kRayFileMagic, 8);
    h.version_major = kRayFileVersionMajor;
    h.version_minor = instances ? kHitFileInstanceMinor : kRayFileVersionMinor;
    h.record_size = instances ? uint32_t(sizeof(InstanceHit)) : hits ? uint32_t(sizeof(Hit)) : uint32_t(sizeof(Ray));
    h.count = count;
    h.flags = flags;
    h.reserved = 0;
    return h;
}

}  // namespace

Result parse_ray_file_header(const uint8_t* bytes, size_t size, bool want_hits, uint64_t& count,
                             uint32_t& flags) {
    uint32_t rs = 0;
    Result r = parse_ray_file_header(bytes, size, want_hits, count, flags, rs);
    if (r.ok() && want_hits && rs != sizeof(Hit))
        return bad("holds instance ids (version 1.1, record_size " + std::to_string(rs) +
                   "): a two-level scene's hits; this reader takes 16-byte records only");
    return r;
}

Result parse_ray_file_header(const uint8_t* bytes, size_t size, bool want_hits, uint64_t& count,
                             uint32_t& flags, uint32_t& record_size) {
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
    uint32_t rs = want_hits ? uint32_t(sizeof(Hit)) : uint32_t(sizeof(Ray));
    // A hit file from version 1.1 on may hold InstanceHit records (spec/rays.md).
    if (want_hits && h.record_size == sizeof(InstanceHit) && h.version_minor >= kHitFileInstanceMinor)
        rs = uint32_t(sizeof(InstanceHit));
    if (h.record_size != rs)
        return bad("record_size " + std::to_string(h.record_size) + ", expected " + std::to_string(rs) +
                   (want_hits ? " (or 20 from version 1.1 on)" : ""));
    const uint32_t allowed = want_hits ? (kHitFileAnyHit | kHitFileWatertight) : 0u;
    if ((h.flags & ~allowed) != 0) return bad("unknown flags " + hex32(h.flags));
    if (h.reserved != 0) return bad("reserved header field is not 0");
    const uint64_t payload = size - kHeaderSize;
    // count * rs may overflow; compare by division instead.
    if (h.count > payload / rs || payload != h.count * rs)
        return bad("size " + std::to_string(size) + " bytes does not match count " + std::to_string(h.count) +
                               " (expected 32 + " + std::to_string(rs) + " * count: truncated or trailing bytes)");
    count = h.count;
    flags = h.flags;
    record_size = rs;
    return Result::success();
}

Result read_ray_file(const std::string& path, std::vector<Ray>& rays) {
    uint32_t flags = 0;
    return read_records(path, false, rays, flags);
}

Result read_hit_file(const std::string& path, std::vector<Hit>& hits, uint32_t& flags) {
    return read_records(path, true, hits, flags);
}

Result read_hit_file(const std::string& path, std::vector<Hit>& hits, std::vector<uint32_t>& instances,
                     uint32_t& flags) {
    uint64_t count = 0;
    uint32_t rs = 0;
    Expected<RegularFile> f = open_records(path, true, true, count, flags, rs);
    if (!f.ok()) return f.error();
    instances.clear();
    hits.resize(size_t(count));  // count * rs == size - 32: bounded by the file
    if (rs == sizeof(Hit)) return f->read_exact(hits.data(), count * sizeof(Hit));
    std::vector<InstanceHit> records(static_cast<size_t>(count));
    if (Result r = f->read_exact(records.data(), count * sizeof(InstanceHit)); !r.ok()) return r;
    instances.resize(size_t(count));
    for (size_t i = 0; i < records.size(); ++i) {
        hits[i] = Hit{records[i].t, records[i].u, records[i].v, records[i].prim};
        instances[i] = records[i].instance;
    }
    return Result::success();
}

Result write_ray_file(const std::string& path, const Ray* rays, size_t count) {
    return write_all(path, make_header(false, count, 0), rays, count * sizeof(Ray));
}

Result write_hit_file(const std::string& path, const Hit* hits, size_t count, uint32_t flags) {
    return write_all(path, make_header(true, count, flags), hits, count * sizeof(Hit));
}

Result write_hit_file(const std::string& path, const Hit* hits, const uint32_t* instances, size_t count,
                      uint32_t flags) {
    if (instances == nullptr) return write_hit_file(path, hits, count, flags);
    std::vector<InstanceHit> records(count);
    for (size_t i = 0; i < count; ++i)
        records[i] = InstanceHit{hits[i].t, hits[i].u, hits[i].v, hits[i].prim, instances[i]};
    return write_all(path, make_header(true, count, flags, true), records.data(), count * sizeof(InstanceHit));
}

}  // namespace cwbvh

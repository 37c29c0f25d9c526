#include "cwbvh/loader/loader.h"

#include <sys/mman.h>

#include <cerrno>
#include <cstring>

#include "cwbvh/format/file_io.h"
#include "cwbvh/format/source_map.h"

namespace cwbvh {
namespace {

Result io_error(uint32_t rule_id, const std::string& path, const std::string& what) {
    return fail(rule_id, path + ": " + what);
}

}  // namespace

Expected<File> File::open(const std::string& path, const OpenOptions& options) {
    // Refuses a FIFO, device or directory before anything would block on it (rules 1001, 1002).
    Expected<RegularFile> fd = RegularFile::open(path);
    if (!fd.ok()) return fd.error();
    if (fd->size() == 0) return io_error(rule::kEmptyFile, path, "is empty (0 bytes)");
    if (fd->size() > uint64_t(SIZE_MAX)) return io_error(rule::kMapFailed, path, "is too large to map");

    File file;
    file.path_ = path;
    file.map_size_ = size_t(fd->size());
    void* map = ::mmap(nullptr, file.map_size_, PROT_READ, MAP_PRIVATE, fd->fd(), 0);
    if (map == MAP_FAILED) return io_error(rule::kMapFailed, path, std::string("cannot mmap: ") + std::strerror(errno));
    file.map_ = map;
    // Note: if another process truncates the file while it is mapped, reads
    // past the new end raise SIGBUS; writers replace files by rename instead.

    ValidateOptions vo;
    vo.verify_checksums = options.verify_checksums;
    vo.sections = options.sections;
    const std::span<const uint8_t> bytes(static_cast<const uint8_t*>(map), file.map_size_);
    if (Result r = validate(bytes, vo, &file.layout_); !r.ok()) {
        r.message = path + ": " + r.message;
        return r;
    }
    // NODE of a two-level file holds only the bottom levels; a caller that reads it
    // without the top level would trace mesh 0 alone. Refused like an unknown
    // required section (spec 2.4, 3.9): the caller did not ask for the two-level sections.
    if (file.is_two_level() && (options.sections & kMaskNodes) != 0 && (options.sections & kMaskTwoLevel) == 0)
        return fail(rule::kUnknownRequiredSection,
                    path + ": two-level file (format 1.2: MESH, INST, TLAS): open it with the two-level "
                           "sections selected (kMaskTwoLevel, CWBVH_SECTION_TWO_LEVEL); NODE alone holds only "
                           "the bottom levels");
    file.sections_ = options.sections;
    return file;
}

std::span<const uint8_t> File::section(uint32_t type) const {
    const SectionInfo* info = find_section_info(type);
    if (info == nullptr || (sections_ & info->mask) == 0) return {};
    const SectionEntry* e = layout_.find(type);
    return e != nullptr ? layout_.payload(*e) : std::span<const uint8_t>{};
}

std::optional<SourceRef> File::source_of(uint32_t prim) const { return find_source(source_ranges(), prim); }

uint64_t File::stored_triangle_count() const { return source_range_total(source_ranges()); }

uint64_t File::instanced_triangle_count() const {
    const std::span<const MeshRecord> m = meshes();
    uint64_t total = 0;
    for (const InstanceRecord& inst : instances())
        if (inst.mesh < m.size()) total += m[inst.mesh].prim_count;  // < 2^32 * 2^32: no overflow
    return total;
}

File::File(File&& other) noexcept { *this = std::move(other); }

File& File::operator=(File&& other) noexcept {
    if (this != &other) {
        release();
        path_ = std::move(other.path_);
        map_ = std::exchange(other.map_, nullptr);
        map_size_ = std::exchange(other.map_size_, 0);
        sections_ = std::exchange(other.sections_, 0);
        layout_ = std::move(other.layout_);
        other.layout_ = FileLayout{};
    }
    return *this;
}

File::~File() { release(); }

void File::release() {
    if (map_ != nullptr) ::munmap(map_, map_size_);
    map_ = nullptr;
    map_size_ = 0;
    layout_ = FileLayout{};
}

}  // namespace cwbvh

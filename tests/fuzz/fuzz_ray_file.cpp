// libFuzzer target for the ray and hit file readers (spec/rays.md): the input is written to a
// memfd (a regular file, so the readers' RegularFile open accepts it) and read back as a ray
// file and as a hit file. A reader must answer with a Result and never allocate more than the
// file holds (a header announcing 2^40 records is refused before the vector is sized).
#include <sys/mman.h>
#include <unistd.h>

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/kernels/ray_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    static const int fd = memfd_create("cwbvh_fuzz_ray_file", MFD_CLOEXEC);
    static const std::string path = "/proc/self/fd/" + std::to_string(fd);
    if (fd < 0 || ftruncate(fd, 0) != 0) return 0;
    if (size > 0 && pwrite(fd, data, size, 0) != ssize_t(size)) return 0;
    std::vector<cwbvh::Ray> rays;
    if (cwbvh::read_ray_file(path, rays).ok() && rays.size() * sizeof(cwbvh::Ray) + 32 != size) __builtin_trap();
    std::vector<cwbvh::Hit> hits;
    uint32_t flags = 0;
    if (cwbvh::read_hit_file(path, hits, flags).ok() && hits.size() * sizeof(cwbvh::Hit) + 32 != size)
        __builtin_trap();
    // Hit file 1.1 (20-byte records with the instance) and 1.0, through the reader that
    // takes both: a 1.0 file leaves the instances empty, a 1.1 file gives one per hit, and
    // the records cover the file exactly.
    std::vector<uint32_t> instances;
    if (cwbvh::read_hit_file(path, hits, instances, flags).ok()) {
        const size_t record = instances.empty() ? 16 : 20;
        if ((!instances.empty() && instances.size() != hits.size()) || hits.size() * record + 32 != size)
            __builtin_trap();
    }
    return 0;
}

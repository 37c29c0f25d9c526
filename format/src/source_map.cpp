#include "cwbvh/format/source_map.h"

#include <algorithm>

namespace cwbvh {

std::vector<SourceRange> make_source_ranges(std::span<const SourceRef> refs) {
    std::vector<SourceRange> ranges;
    for (size_t i = 0; i < refs.size(); ++i) {
        const SourceRef& r = refs[i];
        if (!ranges.empty()) {
            SourceRange& last = ranges.back();
            // Unsigned arithmetic: first_triangle + count wraps only if the
            // previous run already ended at 2^32 - 1, and then r.triangle cannot match.
            if (last.input == r.input && last.mesh == r.mesh && last.primitive == r.primitive &&
                uint64_t(last.first_triangle) + last.count == r.triangle) {
                ++last.count;
                continue;
            }
        }
        ranges.push_back(SourceRange{uint32_t(i), 1, r.input, r.mesh, r.primitive, r.triangle});
    }
    return ranges;
}

uint64_t source_range_total(std::span<const SourceRange> ranges) {
    return ranges.empty() ? 0 : uint64_t(ranges.back().first) + ranges.back().count;
}

std::optional<SourceRef> find_source(std::span<const SourceRange> ranges, uint32_t prim) {
    // First range whose first > prim; the one before it is the candidate.
    auto it = std::upper_bound(ranges.begin(), ranges.end(), prim,
                               [](uint32_t p, const SourceRange& r) { return p < r.first; });
    if (it == ranges.begin()) return std::nullopt;
    const SourceRange& r = *--it;
    const uint32_t k = prim - r.first;
    if (k >= r.count) return std::nullopt;
    return SourceRef{r.input, r.mesh, r.primitive, r.first_triangle + k};
}

}  // namespace cwbvh

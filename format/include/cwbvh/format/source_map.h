// PMAP helpers: build the SourceRange runs from per-triangle SourceRefs
// (writers) and answer "where does stored triangle `prim` come from"
// (readers). Spec: section 3.3.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "cwbvh/format/format.h"

namespace cwbvh {

/// Maximal runs of `refs` (entry i = stored triangle i): a run continues while
/// input, mesh and primitive stay the same and the triangle index grows by 1.
std::vector<SourceRange> make_source_ranges(std::span<const SourceRef> refs);

/// Number of stored triangles the ranges cover: first + count of the last
/// range (0 if there is none). 64-bit: a corrupt range may end past 2^32.
uint64_t source_range_total(std::span<const SourceRange> ranges);

/// The source of stored triangle `prim` by binary search over ranges that
/// satisfy the PMAP rules (sorted, contiguous); nullopt if no range holds it.
std::optional<SourceRef> find_source(std::span<const SourceRange> ranges, uint32_t prim);

}  // namespace cwbvh

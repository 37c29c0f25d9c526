// Content rules of TRIS, PMAP, BNDS, BILD, BVH2, VERT, INDX, SRCN (52xx-59xx).
#include "cwbvh/format/tree_depth.h"
#include <cmath>
#include <vector>

#include "validate_internal.h"

namespace cwbvh::detail {
namespace {

using std::to_string;

bool all_finite(const float* v, int n) {
    for (int i = 0; i < n; ++i)
        if (!std::isfinite(v[i])) return false;
    return true;
}

Result element_error(uint32_t rule_id, const char* section, const char* element, uint64_t i, const std::string& what) {
    return fail(rule_id, std::string("section ") + section + ": " + element + " " + to_string(i) + ": " + what);
}

/// Number of NUL-terminated names in SRCN (0 if absent).
uint64_t source_name_count(const FileLayout& layout) {
    const SectionEntry* e = layout.find(kSectionSourceNames);
    if (e == nullptr) return 0;
    uint64_t n = 0;
    for (uint8_t b : layout.payload(*e)) n += b == 0;
    return n;
}

/// Marks TRIS records [first, first + n) as used by a leaf of node `node` (rule 5610: each record
/// in exactly one leaf); `twin` is the second child of a single-record tree, already counted.
Result use_records(std::vector<uint8_t>& used, uint64_t first, uint64_t n, bool twin, const char* name, uint64_t node) {
    if (twin) return Result::success();
    for (uint64_t t = first; t < first + n; ++t) {
        if (used[t] != 0)
            return element_error(rule::kBvh2TriangleUse, name, "node", node, "TRIS record " + to_string(t) +
                                     " is already in another leaf");
        used[t] = 1;
    }
    return Result::success();
}

}  // namespace

uint64_t stored_triangle_count(const FileLayout& layout) {
    const SectionEntry* pmap = layout.find(kSectionSourceMap);
    if (pmap == nullptr || pmap->element_count == 0) return 0;
    const auto last = load<SourceRange>(layout.payload(*pmap), pmap->element_count - 1);
    return uint64_t(last.first) + last.count;
}

Result check_triangles(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    // PMAP is mandatory (rule 4012), so the stored triangle count is always known.
    const uint64_t stored = stored_triangle_count(layout);
    for (uint64_t i = 0; i < count; ++i) {
        const auto t = load<TriangleRecord>(payload, i);
        if (t.prim >= stored)
            return element_error(rule::kTriPrim, "TRIS", "record", i, "prim " + to_string(t.prim) +
                                     " is not below the stored triangle count " + to_string(stored) +
                                     " (PMAP total)");
        if (!all_finite(t.v0, 3) || !all_finite(t.v1, 3) || !all_finite(t.v2, 3))
            return element_error(rule::kTriNonFinite, "TRIS", "record", i, "vertex is not finite");
    }
    return Result::success();
}

Result check_source_map(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    const SectionEntry* srcn = layout.find(kSectionSourceNames);
    // Without SRCN (or with a broken one, which its own rule reports) inputs are not checked.
    const bool check_inputs = srcn != nullptr && srcn->size != 0 && layout.payload(*srcn).back() == 0;
    const uint64_t names = check_inputs ? source_name_count(layout) : 0;
    uint64_t next = 0;  // first stored triangle id the next range must start at
    for (uint64_t i = 0; i < count; ++i) {
        const auto r = load<SourceRange>(payload, i);
        if (r.count == 0) return element_error(rule::kPmapRangeEmpty, "PMAP", "range", i, "count is 0");
        if (r.first != next)
            return element_error(rule::kPmapRangeOrder, "PMAP", "range", i, "first " + to_string(r.first) +
                                     " is not " + to_string(next) + " (ranges must tile the stored triangles in order)");
        next = uint64_t(r.first) + r.count;
        if (next > 0x100000000u || uint64_t(r.first_triangle) + r.count > 0x100000000u)
            return element_error(rule::kPmapRangeLimit, "PMAP", "range", i,
                                 "first + count or first_triangle + count exceeds 2^32");
        if (check_inputs && r.input >= names)
            return element_error(rule::kPmapInput, "PMAP", "range", i, "input " + to_string(r.input) +
                                     " is not below the " + to_string(names) + " names in SRCN");
    }
    // Every stored triangle has at least one TRIS record (7a, D4), so the total is bounded by
    // what the file holds; readers size per-triangle tables by it (rule 5305).
    if (const uint64_t records = count_of(layout, kSectionTriangles); next > records)
        return fail(rule::kPmapTotal, "section PMAP: the ranges cover " + to_string(next) +
                                          " stored triangles but TRIS holds only " + to_string(records) +
                                          " records (every stored triangle needs one)");
    return Result::success();
}

Result check_bounds(std::span<const uint8_t> payload) {
    const auto b = load<SceneBounds>(payload, 0);
    if (!all_finite(b.lo, 3) || !all_finite(b.hi, 3))
        return fail(rule::kBoundsInvalid, "section BNDS: bounds are not finite");
    for (int a = 0; a < 3; ++a)
        if (b.lo[a] > b.hi[a])
            return fail(rule::kBoundsInvalid, "section BNDS: lo > hi on axis " + to_string(a));
    return Result::success();
}

Result check_build_info(std::span<const uint8_t> payload) {
    const auto b = load<BuildInfo>(payload, 0);
    for (uint8_t r : b.reserved)
        if (r != 0) return fail(rule::kBuildReserved, "section BILD: reserved bytes are not 0");
    return Result::success();
}

Result check_bvh2(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count, bool leaf_ranges) {
    const char* name = leaf_ranges ? "BV2L" : "BVH2";
    const uint64_t tri_count = count_of(layout, kSectionTriangles);
    std::vector<uint8_t> has_parent(count, 0);
    std::vector<uint8_t> depth(count, 1);  // root = 1; leaves count as a level
    std::vector<uint8_t> tri_used(tri_count, 0);  // rule 5610; TRIS count is bounded by the file
    for (uint64_t i = 0; i < count; ++i) {
        const auto n = load<Bvh2Node>(payload, i);
        if (depth[i] + 1u > kMaxBvh2Depth)
            return element_error(rule::kBvh2Depth, name, "node", i, "has children at depth " +
                                     to_string(depth[i] + 1u) + "; the tree may be at most " +
                                     to_string(kMaxBvh2Depth) + " levels deep");
        if (!leaf_ranges && (n.leaf_count[0] != 0 || n.leaf_count[1] != 0))
            return element_error(rule::kBvh2Reserved, name, "node", i, "reserved field is not 0");
        float box[12];
        std::memcpy(box, &n, sizeof box);  // the 12 box floats are the first 48 bytes
        if (!all_finite(box, 12))
            return element_error(rule::kBvh2NonFinite, name, "node", i, "child box is not finite");
        // A tree over a single record is one node whose two children are both that leaf (3.6).
        const bool twin_leaves = count == 1 && n.child[0] < 0 && n.child[0] == n.child[1] &&
                                 n.leaf_count[0] == n.leaf_count[1];
        for (int c = 0; c < 2; ++c) {
            const int32_t child = n.child[c];
            const uint32_t leaf_count = n.leaf_count[c];
            if (child < 0) {
                const uint64_t first = uint64_t(uint32_t(~child));
                if (!leaf_ranges) {
                    if (first >= tri_count)
                        return element_error(rule::kBvh2Leaf, name, "node", i, "leaf ~child = " + to_string(first) +
                                                 " is not below TRIS count " + to_string(tri_count));
                    if (Result r = use_records(tri_used, first, 1, twin_leaves && c == 1, name, i); !r.ok()) return r;
                    continue;
                }
                if (leaf_count < 1 || leaf_count > kMaxBvh2LeafTriangles)
                    return element_error(rule::kBvh2LeafCount, name, "node", i, "leaf child " + to_string(c) +
                                             " has leaf_count " + to_string(leaf_count) + ", not 1.." +
                                             to_string(kMaxBvh2LeafTriangles));
                // first < 2^31 and leaf_count <= 4: the sum cannot overflow 64 bits.
                if (first + leaf_count > tri_count)
                    return element_error(rule::kBvh2LeafRange, name, "node", i, "leaf records " + to_string(first) +
                                             ".." + to_string(first + leaf_count - 1) + " are not inside TRIS (" +
                                             to_string(tri_count) + " records)");
                if (Result r = use_records(tri_used, first, leaf_count, twin_leaves && c == 1, name, i); !r.ok())
                    return r;
                continue;
            }
            if (leaf_ranges && leaf_count != 0)
                return element_error(rule::kBvh2InternalCount, name, "node", i, "internal child " + to_string(c) +
                                         " has leaf_count " + to_string(leaf_count) + ", not 0");
            if (uint64_t(child) <= i || uint64_t(child) >= count)
                return element_error(rule::kBvh2Child, name, "node", i, "child " + to_string(child) +
                                         " is not in (" + to_string(i) + ", " + to_string(count) + ")");
            if (has_parent[child] != 0)
                return element_error(rule::kBvh2Parents, name, "node", uint64_t(child), "has two parents");
            has_parent[child] = 1;
            depth[child] = uint8_t(depth[i] + 1);
        }
    }
    for (uint64_t j = 1; j < count; ++j)
        if (has_parent[j] == 0) return element_error(rule::kBvh2Parents, name, "node", j, "has no parent");
    for (uint64_t t = 0; t < tri_count; ++t)
        if (tri_used[t] == 0)
            return fail(rule::kBvh2TriangleUse, std::string("section ") + name + ": TRIS record " + to_string(t) +
                                                    " is in no leaf (a ray could never reach it)");
    return Result::success();
}

Result check_vertices(std::span<const uint8_t> payload, uint64_t count) {
    for (uint64_t i = 0; i < count; ++i) {
        float v[3];
        std::memcpy(v, payload.data() + i * sizeof v, sizeof v);
        if (!all_finite(v, 3)) return element_error(rule::kVertNonFinite, "VERT", "vertex", i, "not finite");
    }
    return Result::success();
}

Result check_indices(const FileLayout& layout, std::span<const uint8_t> payload, uint64_t count) {
    const uint64_t verts = count_of(layout, kSectionVertices);
    if (const uint64_t stored = stored_triangle_count(layout); count != stored)
        return fail(rule::kIndexCount, "section INDX: " + to_string(count) +
                                           " triangles but PMAP covers " + to_string(stored) + " stored triangles");
    for (uint64_t i = 0; i < count; ++i) {
        uint32_t idx[3];
        std::memcpy(idx, payload.data() + i * sizeof idx, sizeof idx);
        for (uint32_t k : idx)
            if (k >= verts)
                return element_error(rule::kIndexRange, "INDX", "triangle", i, "index " + to_string(k) +
                                         " is not below VERT count " + to_string(verts));
    }
    return Result::success();
}

Result check_source_names(std::span<const uint8_t> payload) {
    // Empty: no name, and no final NUL (3.7); PMAP's inputs, which rule 5301 skips for a
    // broken SRCN, would name nothing.
    if (payload.empty()) return fail(rule::kNamesTerminator, "section SRCN: empty (no name, no final NUL)");
    if (payload.back() != 0)
        return fail(rule::kNamesTerminator, "section SRCN: last name is not NUL-terminated");
    return Result::success();
}

}  // namespace cwbvh::detail

// verify_encoded(): decode-and-check self test of the NODE/TRIS sections
// against the exact wide tree (used by tests and by cwbvhc's verify pass).
#include <atomic>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cwbvh/compiler/encode.h"
#include "cwbvh/compiler/parallel_exact.h"
#include "cwbvh/compiler/quantize.h"
#include "cwbvh/format/node_decode.h"

namespace cwbvh::compiler {

namespace {

Result fail(const std::string& what, size_t node) {
    return Result::fail(Status::kInternal, 0, "verify: node " + std::to_string(node) + ": " + what);
}

/// The serial check: a walk from the root, the first failure it meets reports.
Result verify_encoded_serial(const EncodedTree& tree, const WideBvh& wide, const Scene& scene, VerifyPart part) {
    const bool boxes = part != VerifyPart::kRecords, records = part != VerifyPart::kBoxes;
    const size_t n = tree.nodes.size();
    if (n == 0 || tree.node_to_wide.size() != n || n != wide.nodes.size()) {
        return Result::fail(Status::kInternal, 0, "verify: node count mismatch");
    }
    if (records &&
        (tree.triangles.size() != wide.leaf_refs.size() || tree.ref_to_tri.size() != wide.leaf_refs.size())) {
        return Result::fail(Status::kInternal, 0, "verify: triangle record count mismatch");
    }
    std::vector<uint8_t> node_seen(n, 0), tri_seen(records ? tree.triangles.size() : 0, 0),
        prim_seen(records ? scene.triangle_count() : 0, 0);
    std::vector<uint32_t> stack{0};
    node_seen[0] = 1;
    while (!stack.empty()) {
        const uint32_t i = stack.back();
        stack.pop_back();
        const CwbvhNode& cn = tree.nodes[i];
        if (tree.node_to_wide[i] >= wide.nodes.size()) return fail("bad wide node mapping", i);
        const WideNode& wn = wide.nodes[tree.node_to_wide[i]];
        for (int a = 0; a < 3; ++a)
            if (cn.e[a] < 1 || cn.e[a] > 254) return fail("exponent out of range", i);
        for (int s = 0; s < kWidth; ++s) {
            const WideChild& ch = wn.slots[s];
            const uint8_t m = cn.meta[s];
            const bool bit = (cn.imask >> s) & 1;
            if (ch.kind == WideChild::kEmpty) {
                if (m != kMetaEmpty || bit) return fail("empty slot " + std::to_string(s) + " not empty", i);
                continue;
            }
            const Aabb dec = decode_child_box(cn, s);
            for (int a = 0; a < 3; ++a) {
                if (cn.q_lo[a][s] > cn.q_hi[a][s]) return fail("inverted quantized box", i);
                if (boxes && (!(dec.lo[a] <= wide.box(ch).lo[a]) || !(dec.hi[a] >= wide.box(ch).hi[a])))
                    return fail("slot " + std::to_string(s) + ": decoded box does not contain the child", i);
            }
            if (ch.kind == WideChild::kInternal) {
                if (m != make_meta_internal(s) || !bit || !meta_is_internal(m))
                    return fail("bad internal meta/imask in slot " + std::to_string(s), i);
                const uint32_t c = internal_child_index(cn, s);
                if (c >= n || c <= i) return fail("child index out of range", i);
                if (node_seen[c]++) return fail("child reached twice", i);
                if (tree.node_to_wide[c] != ch.node) return fail("child is not the wide child", i);
                stack.push_back(c);
                continue;
            }
            if (bit || !meta_is_leaf(m) || meta_leaf_count(m) != int(ch.ref_count))
                return fail("bad leaf meta/imask in slot " + std::to_string(s), i);
            const uint32_t off = uint32_t(meta_leaf_offset(m));
            if (!records) continue;
            if (off + ch.ref_count > uint32_t(kMaxNodeTriangles) ||
                uint64_t(cn.tri_base) + off + ch.ref_count > tree.triangles.size())
                return fail("leaf triangles out of range", i);
            for (uint32_t k = 0; k < ch.ref_count; ++k) {
                const uint32_t t = cn.tri_base + off + k;
                const uint32_t ref = ch.first_ref + k;
                const TriangleRecord& rec = tree.triangles[t];
                if (tri_seen[t]++) return fail("triangle record " + std::to_string(t) + " used twice", i);
                if (tree.ref_to_tri[ref] != t || rec.prim != wide.leaf_refs[ref])
                    return fail("triangle record " + std::to_string(t) + " is not the leaf's", i);
                if (rec.prim >= scene.triangle_count())
                    return fail("bad triangle record " + std::to_string(t), i);
                const auto v = scene.triangle(rec.prim);
                for (int a = 0; a < 3; ++a) {
                    if (rec.v0[a] != v[0][a] || rec.v1[a] != v[1][a] || rec.v2[a] != v[2][a])
                        return fail("triangle record " + std::to_string(t) + " has wrong vertices", i);
                }
                prim_seen[rec.prim] = 1;
            }
        }
    }
    for (size_t i = 0; i < n; ++i)
        if (!node_seen[i]) return fail("unreachable from the root", i);
    for (size_t t = 0; t < tri_seen.size(); ++t) {
        if (!tri_seen[t]) {
            return Result::fail(Status::kInternal, 0,
                                "verify: triangle record " + std::to_string(t) + " is in no leaf");
        }
    }
    for (size_t p = 0; p < prim_seen.size(); ++p) {
        if (!prim_seen[p]) {
            return Result::fail(Status::kInternal, 0,
                                "verify: stored triangle " + std::to_string(p) + " is in no leaf");
        }
    }
    return Result::success();
}

}  // namespace

/// In parallel over all nodes (not a walk): each node's own checks, and
/// marks for the nodes and records its slots reach (bit 0: once, bit 1:
/// again). That passes exactly when the walk does: every node but the root
/// reached once from a smaller index means every node is on the walk.
/// On any failure the serial walk runs to name the same first failure.
Result verify_encoded(const EncodedTree& tree, const WideBvh& wide, const Scene& scene, VerifyPart part) {
    const bool boxes = part != VerifyPart::kRecords, records = part != VerifyPart::kBoxes;
    const size_t n = tree.nodes.size();
    if (n == 0 || tree.node_to_wide.size() != n || n != wide.nodes.size() ||
        (records &&
         (tree.triangles.size() != wide.leaf_refs.size() || tree.ref_to_tri.size() != wide.leaf_refs.size())))
        return verify_encoded_serial(tree, wide, scene, part);
    std::vector<uint8_t> node_seen(n, 0), tri_seen(records ? tree.triangles.size() : 0, 0),
        prim_seen(records ? scene.triangle_count() : 0, 0);
    std::atomic<bool> bad{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 512), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const CwbvhNode& cn = tree.nodes[i];
            bool ok = tree.node_to_wide[i] < wide.nodes.size();
            for (int a = 0; a < 3 && ok; ++a) ok = cn.e[a] >= 1 && cn.e[a] <= 254;
            if (!ok) {
                bad.store(true, std::memory_order_relaxed);
                return;
            }
            const WideNode& wn = wide.nodes[tree.node_to_wide[i]];
            for (int s = 0; s < kWidth && ok; ++s) {
                const WideChild& ch = wn.slots[s];
                const uint8_t m = cn.meta[s];
                const bool bit = (cn.imask >> s) & 1;
                if (ch.kind == WideChild::kEmpty) {
                    ok = m == kMetaEmpty && !bit;
                    continue;
                }
                for (int a = 0; a < 3; ++a) ok = ok && cn.q_lo[a][s] <= cn.q_hi[a][s];
                if (boxes && ok) {
                    const Aabb dec = decode_child_box(cn, s);
                    const Aabb& box = wide.box(ch);
                    for (int a = 0; a < 3; ++a) ok = ok && dec.lo[a] <= box.lo[a] && dec.hi[a] >= box.hi[a];
                }
                if (!ok) break;
                if (ch.kind == WideChild::kInternal) {
                    const uint32_t c = internal_child_index(cn, s);
                    ok = m == make_meta_internal(s) && bit && meta_is_internal(m) && c < n && c > i &&
                         tree.node_to_wide[c] == ch.node;
                    if (ok) mark_parent(node_seen[c]);
                    continue;
                }
                ok = !bit && meta_is_leaf(m) && meta_leaf_count(m) == int(ch.ref_count);
                if (!records) continue;
                const uint32_t off = uint32_t(meta_leaf_offset(m));
                ok = ok && off + ch.ref_count <= uint32_t(kMaxNodeTriangles) &&
                     uint64_t(cn.tri_base) + off + ch.ref_count <= tree.triangles.size();
                for (uint32_t k = 0; k < ch.ref_count && ok; ++k) {
                    const uint32_t t = cn.tri_base + off + k;
                    const uint32_t ref = ch.first_ref + k;
                    const TriangleRecord& rec = tree.triangles[t];
                    mark_parent(tri_seen[t]);
                    ok = tree.ref_to_tri[ref] == t && rec.prim == wide.leaf_refs[ref] && rec.prim < scene.triangle_count();
                    if (!ok) break;
                    const auto v = scene.triangle(rec.prim);
                    for (int a = 0; a < 3; ++a)
                        ok = ok && rec.v0[a] == v[0][a] && rec.v1[a] == v[1][a] && rec.v2[a] == v[2][a];
                    std::atomic_ref<uint8_t>(prim_seen[rec.prim]).store(1, std::memory_order_relaxed);
                }
            }
            if (!ok) {
                bad.store(true, std::memory_order_relaxed);
                return;
            }
        }
    });
    auto all_once = [&](const std::vector<uint8_t>& seen, size_t from) {
        if (bad.load()) return;
        if (lowest_failing(seen.size(), 1 << 14, [&](size_t k) { return k >= from && seen[k] != 1; }) < seen.size())
            bad.store(true);
    };
    if (!bad.load() && node_seen[0] != 0) bad.store(true);
    all_once(node_seen, 1);
    all_once(tri_seen, 0);
    all_once(prim_seen, 0);
    if (!bad.load()) return Result::success();
    Result r = verify_encoded_serial(tree, wide, scene, part);
    if (r.ok()) r = Result::fail(Status::kInternal, 0, "verify: parallel and serial checks disagree");
    return r;
}

}  // namespace cwbvh::compiler

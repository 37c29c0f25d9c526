// WideBvh -> NODE (80-byte compressed wide nodes, Ylitie, Karras, Laine 2017,
// section 3.3) and TRIS (triangle records in leaf order).
#include "cwbvh/compiler/encode.h"

#include <atomic>
#include <cassert>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/parallel_exact.h"
#include "cwbvh/compiler/quantize.h"
#include "cwbvh/format/node_decode.h"

namespace cwbvh::compiler {

namespace {

/// The exact boxes of a wide node's used slots; returns the used-slot mask.
uint8_t child_boxes(const WideBvh& wide, const WideNode& node, Aabb (&boxes)[kWidth]) {
    uint8_t used = 0;
    for (int s = 0; s < kWidth; ++s) {
        if (node.slots[s].kind == WideChild::kEmpty) continue;
        boxes[s] = wide.box(node.slots[s]);
        used = uint8_t(used | (1u << s));
    }
    return used;
}

/// The serial check (the first failing node in index order reports).
Result check_wide_serial(const WideBvh& wide) {
    if (wide.nodes.empty()) return Result::fail(Status::kInvalidArgument, 0, "encode: wide BVH has no nodes");
    if (wide.nodes.size() >= size_t(kInvalidIndex) || wide.leaf_refs.size() >= size_t(kInvalidIndex)) {
        return Result::fail(Status::kInvalidArgument, 0, "encode: wide BVH too large for 32-bit indices");
    }
    if (!wide.binary) return Result::fail(Status::kInvalidArgument, 0, "encode: wide BVH without its binary tree (boxes)");
    const size_t boxes = wide.binary->nodes.size();
    std::vector<uint8_t> parents(wide.nodes.size(), 0);
    for (size_t i = 0; i < wide.nodes.size(); ++i) {
        const WideNode& node = wide.nodes[i];
        bool box_ok = node.bnode < boxes;
        for (const WideChild& ch : node.slots) box_ok = box_ok && (ch.kind == WideChild::kEmpty || ch.bnode < boxes);
        if (!box_ok) {
            return Result::fail(Status::kInvalidArgument, 0,
                                "encode: wide node " + std::to_string(i) + " has a bad binary node (box) index");
        }
        if (node.child_count() == 0) {
            return Result::fail(Status::kInvalidArgument, 0,
                                "encode: wide node " + std::to_string(i) + " has no children");
        }
        uint32_t triangles = 0;
        for (const WideChild& ch : node.slots) {
            if (ch.kind == WideChild::kInternal) {
                if (ch.node == 0 || ch.node >= wide.nodes.size() || parents[ch.node]++ != 0) {
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "encode: wide node " + std::to_string(i) + " has a bad or shared child index");
                }
            } else if (ch.kind == WideChild::kLeaf) {
                if (ch.ref_count < 1 || ch.ref_count > uint32_t(kMaxLeafTriangles) ||
                    ch.first_ref > wide.leaf_refs.size() || ch.ref_count > wide.leaf_refs.size() - ch.first_ref)
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "encode: wide node " + std::to_string(i) + " has a bad leaf");
                triangles += ch.ref_count;
            } else if (ch.kind != WideChild::kEmpty) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "encode: wide node " + std::to_string(i) + " has a bad slot kind");
            }
        }
        if (triangles > uint32_t(kMaxNodeTriangles)) {
            return Result::fail(Status::kInvalidArgument, 0,
                                "encode: wide node " + std::to_string(i) + " has more than 24 triangles");
        }
    }
    for (size_t i = 1; i < wide.nodes.size(); ++i) {
        if (parents[i] != 1) {
            return Result::fail(Status::kInvalidArgument, 0,
                                "encode: wide node " + std::to_string(i) + " is unreachable");
        }
    }
    return Result::success();
}

/// check_wide_serial's conditions in parallel (parent marks: bit 0 once,
/// bit 1 again); any failure reruns the serial check to name it.
Result check_wide(const WideBvh& wide) {
    if (wide.nodes.empty() || wide.nodes.size() >= size_t(kInvalidIndex) ||
        wide.leaf_refs.size() >= size_t(kInvalidIndex) || !wide.binary)
        return check_wide_serial(wide);
    const size_t n = wide.nodes.size(), boxes = wide.binary->nodes.size();
    std::vector<uint8_t> parents(n, 0);
    std::atomic<bool> bad{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const WideNode& node = wide.nodes[i];
            bool ok = node.bnode < boxes && node.child_count() != 0;
            uint32_t triangles = 0;
            for (const WideChild& ch : node.slots) {
                if (ch.kind == WideChild::kEmpty) continue;
                ok = ok && ch.bnode < boxes;
                if (ch.kind == WideChild::kInternal) {
                    if (ch.node == 0 || ch.node >= n) {
                        ok = false;
                        continue;
                    }
                    mark_parent(parents[ch.node]);
                } else if (ch.kind == WideChild::kLeaf) {
                    ok = ok && ch.ref_count >= 1 && ch.ref_count <= uint32_t(kMaxLeafTriangles) &&
                         ch.first_ref <= wide.leaf_refs.size() && ch.ref_count <= wide.leaf_refs.size() - ch.first_ref;
                    triangles += ch.ref_count;
                } else {
                    ok = false;
                }
            }
            if (!ok || triangles > uint32_t(kMaxNodeTriangles)) {
                bad.store(true, std::memory_order_relaxed);
                return;
            }
        }
    });
    if (!bad.load() && lowest_failing(n, 1 << 14, [&](size_t i) { return i > 0 && parents[i] != 1; }) < n) bad = true;
    if (!bad.load()) return Result::success();
    Result r = check_wide_serial(wide);
    if (r.ok()) r = Result::fail(Status::kInternal, 0, "encode: parallel and serial wide checks disagree");
    return r;
}

/// The checks of one wide node's leaf references, in the serial encoder's
/// order (slot order, then reference order), claiming ref_to_tri[ref] for
/// records first_record, first_record + 1, ... (atomically: leaves checked
/// in parallel must not both claim one reference). Writes no record.
Result claim_leaf_refs(const WideBvh& wide, const Scene& scene, const WideNode& node, uint32_t first_record,
                       std::vector<uint32_t>& ref_to_tri) {
    uint32_t record = first_record;
    for (int s = 0; s < kWidth; ++s) {
        const WideChild& ch = node.slots[s];
        if (ch.kind != WideChild::kLeaf) continue;
        for (uint32_t k = 0; k < ch.ref_count; ++k, ++record) {
            const uint32_t ref = ch.first_ref + k;
            const uint32_t prim = wide.leaf_refs[ref];
            uint32_t expected = kInvalidIndex;
            if (!std::atomic_ref<uint32_t>(ref_to_tri[ref]).compare_exchange_strong(expected, record,
                                                                                  std::memory_order_relaxed)) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "encode: leaf reference " + std::to_string(ref) + " used by two leaves");
            }
            if (prim >= scene.triangle_count()) {
                return Result::fail(Status::kInvalidArgument, 0,
                                    "encode: triangle id " + std::to_string(prim) + " out of range");
            }
            const auto& idx = scene.indices[prim];
            for (int v = 0; v < 3; ++v) {
                if (idx[v] >= scene.vertices.size()) {
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "encode: triangle " + std::to_string(prim) + " has a bad vertex index");
                }
            }
        }
    }
    return Result::success();
}

/// The leaf checks again, serially in visit order, so that the first failure
/// reports (as the serial encoder did); success if none fails.
Result first_leaf_error(const WideBvh& wide, const Scene& scene, EncodedTree& out) {
    std::vector<uint32_t>(wide.leaf_refs.size(), kInvalidIndex).swap(out.ref_to_tri);
    std::vector<uint32_t> order{0};
    uint32_t record = 0;
    while (!order.empty()) {
        const WideNode& node = wide.nodes[order.back()];
        order.pop_back();
        if (Result r = claim_leaf_refs(wide, scene, node, record, out.ref_to_tri); !r.ok()) return r;
        for (const WideChild& ch : node.slots) record += ch.kind == WideChild::kLeaf ? ch.ref_count : 0;
        for (int s = kWidth; s-- > 0;)
            if (node.slots[s].kind == WideChild::kInternal) order.push_back(node.slots[s].node);
    }
    return Result::success();
}

/// Layout and quantization; `quantize_bad` gets the lowest NODE index whose
/// quantization failed (out.nodes.size() if none).
Result encode_nodes(const WideBvh& wide, EncodedTree& out, float c_node, float c_prim, size_t& quantize_bad) {
    out = EncodedTree{};
    if (Result r = check_wide(wide); !r.ok()) return r;
    out.nodes.reserve(wide.nodes.size());
    out.node_to_wide.reserve(wide.nodes.size());

    // Layout, serial (indices only): depth first with contiguous sibling
    // blocks (see encode.h). The stack holds (wide node, NODE index) pairs
    // whose NODE slot is already allocated; a node's leaf records are taken
    // when it is visited. The records and boxes are filled in parallel below.
    struct Work {
        uint32_t wide;
        uint32_t out;
    };
    std::vector<Work> stack{{0, 0}};
    out.nodes.emplace_back();
    out.node_to_wide.push_back(0);
    uint64_t children = 0;
    uint64_t records = 0;
    bool too_many = false;
    while (!stack.empty()) {
        const Work w = stack.back();
        stack.pop_back();
        const WideNode& node = wide.nodes[w.wide];
        CwbvhNode cn{};
        Work kids[kWidth];
        int kid_count = 0;
        for (int s = 0; s < kWidth; ++s) {
            const WideChild& ch = node.slots[s];
            if (ch.kind == WideChild::kEmpty) continue;
            ++children;
            if (ch.kind == WideChild::kInternal) {
                if (kid_count == 0) cn.child_base = uint32_t(out.nodes.size());
                const uint32_t index = uint32_t(out.nodes.size());
                out.nodes.emplace_back();
                out.node_to_wide.push_back(ch.node);
                kids[kid_count++] = {ch.node, index};
                cn.imask = uint8_t(cn.imask | (1u << s));
                cn.meta[s] = make_meta_internal(s);
            }
        }
        bool have_leaf = false;
        for (int s = 0; s < kWidth; ++s) {
            const WideChild& ch = node.slots[s];
            if (ch.kind != WideChild::kLeaf) continue;
            if (!have_leaf) {
                if (records >= uint64_t(kInvalidIndex) - kMaxNodeTriangles) {
                    too_many = true;
                    break;
                }
                cn.tri_base = uint32_t(records);
                have_leaf = true;
            }
            const uint32_t offset = uint32_t(records) - cn.tri_base;
            // check_wide bounds the node's triangles by 24, so offset + count <= 24.
            assert(offset + ch.ref_count <= uint32_t(kMaxNodeTriangles));
            cn.meta[s] = make_meta_leaf(int(ch.ref_count), int(offset));
            records += ch.ref_count;
            out.max_leaf_triangles = ch.ref_count > out.max_leaf_triangles ? ch.ref_count : out.max_leaf_triangles;
        }
        if (too_many) {
            return Result::fail(Status::kInvalidArgument, 0, "encode: too many triangle records for 32-bit indices");
        }
        out.nodes[w.out] = cn;  // layout only: the boxes are quantized below
        for (int k = kid_count; k-- > 0;) stack.push_back(kids[k]);  // slot order: lowest slot next
    }

    out.records = records;
    out.avg_children = double(children) / double(out.nodes.size());
    // Quantization, in parallel: each node's exponents and child boxes depend
    // on its own children's exact boxes only. The lowest failing node reports.
    quantize_bad = lowest_failing(out.nodes.size(), 1024, [&](size_t i) {
        Aabb boxes[kWidth];
        const uint8_t used = child_boxes(wide, wide.nodes[out.node_to_wide[i]], boxes);
        return !quantize_node(boxes, used, out.nodes[i]).ok();
    });
    out.sah_wide = sah_cost_wide(wide, c_node, c_prim);
    return Result::success();
}

Result quantize_error(const WideBvh& wide, const EncodedTree& out, size_t bad) {
    Aabb boxes[kWidth];
    const uint8_t used = child_boxes(wide, wide.nodes[out.node_to_wide[bad]], boxes);
    CwbvhNode scratch = out.nodes[bad];
    Result r = quantize_node(boxes, used, scratch);  // again, for its message
    if (r.ok()) r = Result::fail(Status::kInternal, 0, "encode: quantization failed");
    r.message += " (wide node " + std::to_string(out.node_to_wide[bad]) + ")";
    return r;
}

}  // namespace

Result encode_cwbvh_nodes(const WideBvh& wide, EncodedTree& out, float c_node, float c_prim) {
    size_t bad = 0;
    if (Result r = encode_nodes(wide, out, c_node, c_prim, bad); !r.ok()) return r;
    if (bad < out.nodes.size()) return quantize_error(wide, out, bad);
    return Result::success();
}

Result encode_cwbvh_triangles(const WideBvh& wide, const Scene& scene, EncodedTree& out) {
    if (out.nodes.empty() || out.node_to_wide.size() != out.nodes.size()) {
        return Result::fail(Status::kInvalidArgument, 0, "encode: triangles before the nodes are laid out");
    }
    // In parallel, per node: its leaves' triangle records with their checks
    // (reference claims are atomic). A leaf error reruns the checks serially
    // in visit order (the first failure reports), then a reference in no leaf.
    out.ref_to_tri.assign(wide.leaf_refs.size(), kInvalidIndex);
    out.triangles.resize(size_t(out.records));
    std::atomic<bool> leaf_bad{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, out.nodes.size(), 1024), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const WideNode& node = wide.nodes[out.node_to_wide[i]];
            const CwbvhNode& cn = out.nodes[i];
            if (!claim_leaf_refs(wide, scene, node, cn.tri_base, out.ref_to_tri).ok()) {
                leaf_bad.store(true, std::memory_order_relaxed);
                continue;
            }
            uint32_t record = cn.tri_base;
            for (int s = 0; s < kWidth; ++s) {
                const WideChild& ch = node.slots[s];
                if (ch.kind != WideChild::kLeaf) continue;
                for (uint32_t k = 0; k < ch.ref_count; ++k, ++record) {
                    const uint32_t prim = wide.leaf_refs[ch.first_ref + k];
                    const auto& idx = scene.indices[prim];
                    TriangleRecord& t = out.triangles[record];
                    for (int a = 0; a < 3; ++a) {
                        t.v0[a] = scene.vertices[idx[0]][a];
                        t.v1[a] = scene.vertices[idx[1]][a];
                        t.v2[a] = scene.vertices[idx[2]][a];
                    }
                    t.prim = prim;
                }
            }
        }
    });
    if (leaf_bad.load()) {
        Result r = first_leaf_error(wide, scene, out);
        if (r.ok()) r = Result::fail(Status::kInternal, 0, "encode: parallel and serial leaf checks disagree");
        return r;
    }
    if (const size_t m = lowest_failing(out.ref_to_tri.size(), 1 << 14,
                                        [&](size_t k) { return out.ref_to_tri[k] == kInvalidIndex; });
        m < out.ref_to_tri.size()) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "encode: leaf reference " + std::to_string(m) + " is in no leaf");
    }
    return Result::success();
}

Result encode_cwbvh(const WideBvh& wide, const Scene& scene, EncodedTree& out, float c_node, float c_prim) {
    // The serial encoder's order of failures: layout, leaves, quantization.
    size_t bad = 0;
    if (Result r = encode_nodes(wide, out, c_node, c_prim, bad); !r.ok()) return r;
    if (Result r = encode_cwbvh_triangles(wide, scene, out); !r.ok()) return r;
    if (bad < out.nodes.size()) return quantize_error(wide, out, bad);
    return Result::success();
}

Result encode_leaf_order(const WideBvh& wide, const EncodedTree& tree, std::vector<uint32_t>& order) {
    if (tree.nodes.empty() || tree.node_to_wide.size() != tree.nodes.size())
        return Result::fail(Status::kInvalidArgument, 0, "encode: leaf order before the nodes are laid out");
    order.assign(size_t(tree.records), kInvalidIndex);
    std::vector<uint8_t> seen(wide.leaf_refs.size(), 0);
    for (size_t i = 0; i < tree.nodes.size(); ++i) {
        const WideNode& node = wide.nodes[tree.node_to_wide[i]];
        uint32_t record = tree.nodes[i].tri_base;
        for (int s = 0; s < kWidth; ++s) {
            const WideChild& ch = node.slots[s];
            if (ch.kind != WideChild::kLeaf) continue;
            for (uint32_t k = 0; k < ch.ref_count; ++k, ++record) {
                const uint32_t ref = ch.first_ref + k;
                if (record >= order.size() || ref >= wide.leaf_refs.size() || seen[ref]++ != 0 ||
                    order[record] != kInvalidIndex)
                    return Result::fail(Status::kInvalidArgument, 0,
                                        "encode: leaf reference " + std::to_string(ref) + " misplaced");
                order[record] = wide.leaf_refs[ref];
            }
        }
    }
    for (size_t r = 0; r < order.size(); ++r)
        if (order[r] == kInvalidIndex)
            return Result::fail(Status::kInvalidArgument, 0, "encode: record " + std::to_string(r) + " in no leaf");
    return Result::success();
}

}  // namespace cwbvh::compiler

// compile_two_level: the bottom levels (one core compile per distinct mesh, in
// parallel), their concatenation with absolute indices, the instance records
// and the top level built by the same core over the instances' world boxes.
#include "cwbvh/compiler/two_level.h"

#include <algorithm>
#include <chrono>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <map>
#include <numeric>

#include <tbb/parallel_for.h>

#include "cwbvh/compiler/auction.h"
#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/emit.h"
#include "cwbvh/compiler/encode.h"
#include "cwbvh/compiler/import.h"
#include "cwbvh/compiler/progress.h"
#include "cwbvh/compiler/quantize.h"
#include "cwbvh/format/node_decode.h"
#include "cwbvh/format/transform_host.h"
#include "cwbvh/format/tree_depth.h"
#include "cwbvh/format/writer.h"

namespace cwbvh::compiler {
namespace {

Result bad(const std::string& what) { return Result::fail(Status::kBadInput, 0, what); }

std::string number(double x) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.6g", x);
    return buf;
}

constexpr double kFloatMax = 3.4028234663852886e38;  // FLT_MAX



}  // namespace

Result make_instance_record(const Placement& p, const MeshRecord& mesh, InstanceRecord& out) {
    out = InstanceRecord{};
    float m[3][4];
    for (int i = 0; i < 12; ++i) {
        // RN to float: the stored matrix; the inverse, the condition number and
        // the world box are computed from it. (Checked first: a double beyond
        // float's range converts with UB.)
        const double x = p.object_to_world[size_t(i)];
        if (!(std::fabs(x) <= kFloatMax)) return bad("transform entry " + number(x) + " beyond float range");
        m[i / 4][i % 4] = float(x);
    }
    Expected<InstanceRecord> made = make_instance(m, mesh, 0, p.source_node);
    if (!made.ok()) return bad(made.error().message);
    out = *made;
    // make_instance widens the world box for the float ray transform (spec 3.10);
    // beyond the quantizer's bound (import.h) no node can encode it.
    for (int r = 0; r < 3; ++r)
        if (!(std::fabs(out.world_lo[r]) <= kMaxCoordinate) || !(std::fabs(out.world_hi[r]) <= kMaxCoordinate))
            return bad("instance world box beyond +-2^125 (translation or scale too large)");
    return Result::success();
}

namespace {

/// The top level over the instances' world boxes: binary object-split SAH,
/// the same collapse, slots and quantization as a bottom level; INST reordered
/// into the leaf order. `verify`: every decoded slot box contains its exact
/// box and every leaf slot every instance world box it holds.
/// C_prim of the top level's collapse (C_node = 1): entering an instance costs a ray
/// transform and the mesh's root node, far more than the 0.3 of a triangle test, so
/// top-level leaves hold fewer instances. CPU trace, catalog views (board, parts; ball,
/// close), primary and diffuse 1, nodes per ray at C_prim 0.3 / 1 / 3 / 10:
/// kicad_board 7.32-10.81 / 7.09-10.41 / 7.08-10.41 / 7.08-10.41, dense_dragons
/// 36.6-60.8 / 35.9-74.1 / 32.0-54.8 / 33.5-60.2 (bench/results/cpu/2026-11-26-two-level).
constexpr float kTopLevelCostPrim = 3.0f;

Result build_top_level(std::vector<InstanceRecord>& instances, const CoreOptions& options, std::vector<CwbvhNode>& tlas,
                       uint32_t& depth) {
    std::vector<Aabb> boxes(instances.size());
    for (size_t i = 0; i < instances.size(); ++i)
        for (int a = 0; a < 3; ++a) {
            boxes[i].lo[a] = instances[i].world_lo[a];
            boxes[i].hi[a] = instances[i].world_hi[a];
        }
    SbvhConfig sbvh = options.sbvh;
    sbvh.threads = 0;  // the caller's arena
    BinaryBvh binary;
    if (Result r = build_boxes(boxes, sbvh, binary); !r.ok()) return r;
    CollapseConfig collapse = options.collapse;
    collapse.binary_leaf_refs = false;
    collapse.cost_prim = kTopLevelCostPrim;
    WideBvh wide;
    if (Result r = collapse_wide(binary, collapse, wide); !r.ok()) return r;
    assign_slots(wide);
    EncodedTree tree;
    if (Result r = encode_cwbvh_nodes(wide, tree, collapse.cost_node, collapse.cost_prim); !r.ok()) return r;
    if (options.emit.verify) {
        if (Result r = verify_encoded(tree, wide, Scene{}, VerifyPart::kBoxes); !r.ok())
            return Result::fail(Status::kInternal, 0, "internal error: top level failed verification: " + r.message);
    }
    std::vector<uint32_t> order;
    if (Result r = encode_leaf_order(wide, tree, order); !r.ok()) return r;
    if (order.size() != instances.size())
        return Result::fail(Status::kInternal, 0, "internal error: top level does not hold every instance once");
    std::vector<InstanceRecord> sorted(instances.size());
    for (size_t k = 0; k < order.size(); ++k) sorted[k] = instances[order[k]];
    instances.swap(sorted);
    if (options.emit.verify) {
        // TLAS containment against the records as written: each leaf slot's
        // decoded box holds the world boxes of the instances it indexes.
        for (size_t i = 0; i < tree.nodes.size(); ++i) {
            const CwbvhNode& n = tree.nodes[i];
            for (int s = 0; s < kWidth; ++s) {
                if (!meta_is_leaf(n.meta[s])) continue;
                const Aabb box = decode_child_box(n, s);
                const uint32_t first = n.tri_base + uint32_t(meta_leaf_offset(n.meta[s]));
                for (int k = 0; k < meta_leaf_count(n.meta[s]); ++k) {
                    const InstanceRecord& inst = instances[first + uint32_t(k)];
                    for (int a = 0; a < 3; ++a)
                        if (!(box.lo[a] <= inst.world_lo[a] && box.hi[a] >= inst.world_hi[a]))
                            return Result::fail(Status::kInternal, 0,
                                                "internal error: top-level node " + std::to_string(i) + " slot " +
                                                    std::to_string(s) + " does not contain instance " +
                                                    std::to_string(first + uint32_t(k)));
                }
            }
        }
    }
    depth = wide_tree_depth(tree.nodes);
    if (depth > kMaxWideDepth)
        return bad("the top level is " + std::to_string(depth) + " levels deep; the format allows " +
                   std::to_string(kMaxWideDepth));
    tlas = std::move(tree.nodes);
    return Result::success();
}

}  // namespace

Result compile_two_level(const InstancedScene& scene, const CoreOptions& options, const std::string& file,
                         TwoLevelResult& out, const PhaseRunner& run, Progress* progress) {
    out = TwoLevelResult{};
    const size_t meshes = scene.meshes.size();
    if (meshes == 0 || scene.placements.empty())
        return Result::fail(Status::kInvalidArgument, 0, "compile_two_level: no meshes or no placements");
    auto run_phase = [&](const char* name, uint64_t units, const std::function<bool()>& body) {
        return run ? run(name, units, body) : body();
    };

    // 1. Bottom levels: each mesh through the core, largest first (the order
    // of the work only; each result depends on its mesh alone).
    std::vector<EmitResult> emitted(meshes);
    std::vector<Result> results(meshes);
    std::vector<std::map<std::string, double>> seconds(meshes);
    std::vector<uint64_t> splits(meshes, 0);
    std::vector<size_t> order(meshes);
    std::iota(order.begin(), order.end(), size_t(0));
    std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
        return scene.meshes[a].triangle_count() > scene.meshes[b].triangle_count();
    });
    CoreOptions core = options;
    core.sbvh.threads = 0;  // the caller's arena (compile()'s --threads)
    run_phase("meshes", scene.distinct_triangles(), [&] {
        tbb::parallel_for(size_t(0), meshes, [&](size_t k) {
            const size_t m = order[k];
            auto& time = seconds[m];
            const PhaseRunner timed = [&time](const std::string& name, uint64_t, const std::function<bool()>& body) {
                const auto start = std::chrono::steady_clock::now();
                const bool ok = body();
                time[name] += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
                return ok;
            };
            const Scene& s = scene.meshes[m];
            BinaryBvh binary;
            Result r;
            timed("sbvh", 0, [&] {
                r = build_sbvh(s, core.sbvh, binary);
                return r.ok();
            });
            if (r.ok()) {
                splits[m] = binary.spatial_splits;
                r = compile_binary(s, binary, core, emitted[m], timed);
            }
            results[m] = r;
            progress_add(progress, s.triangle_count());  // a mesh done: its triangles
        });
        return true;
    });
    for (size_t m = 0; m < meshes; ++m) {
        if (!results[m].ok()) {
            Result r = results[m];
            const uint32_t src = scene.source_mesh[m];
            r.message = file + ": " +
                        (src == kInvalidIndex ? std::string("the merged geometry placed once")
                                              : "glTF mesh " + std::to_string(src)) +
                        ": " + r.message;
            return r;
        }
    }
    std::map<std::string, double> phase_sum;
    for (size_t m = 0; m < meshes; ++m) {
        out.spatial_splits += splits[m];
        for (const auto& [name, t] : seconds[m]) phase_sum[name] += t;
    }
    for (const char* name : {"sbvh", "collapse", "slots", "encode"})
        if (phase_sum.count(name)) out.mesh_phase_seconds.emplace_back(name, phase_sum[name]);

    // 2. Concatenation with absolute indices; MESH records.
    Result r;
    run_phase("assemble", 0, [&] {
        size_t nodes = 0, tris = 0, ranges = 0;
        for (const EmitResult& e : emitted) {
            nodes += e.tree.nodes.size();
            tris += e.tree.triangles.size();
            ranges += e.source_ranges.size();
        }
        if (nodes >= kInvalidIndex || tris >= kInvalidIndex || scene.distinct_triangles() >= kInvalidIndex) {
            r = bad(file + ": the distinct meshes exceed 32-bit NODE/TRIS indices");
            return false;
        }
        out.nodes.reserve(nodes);
        out.triangles.reserve(tris);
        out.source_ranges.reserve(ranges);
        double sah_binary = 0, sah_wide = 0, children = 0;
        uint64_t prim_first = 0;
        for (size_t m = 0; m < meshes; ++m) {
            EmitResult& e = emitted[m];
            MeshRecord mr{};
            mr.node_first = uint32_t(out.nodes.size());
            mr.node_count = uint32_t(e.tree.nodes.size());
            mr.tri_first = uint32_t(out.triangles.size());
            mr.tri_count = uint32_t(e.tree.triangles.size());
            mr.prim_first = uint32_t(prim_first);
            mr.prim_count = uint32_t(scene.meshes[m].triangle_count());
            for (int a = 0; a < 3; ++a) {
                mr.lo[a] = e.bounds.lo[a];
                mr.hi[a] = e.bounds.hi[a];
            }
            mr.source_mesh = scene.source_mesh[m];
            for (CwbvhNode n : e.tree.nodes) {
                // Unused bases stay 0 (as in a single-level file).
                if (n.imask != 0) n.child_base += mr.node_first;
                bool leaf = false;
                for (int s = 0; s < kWidth; ++s) leaf = leaf || meta_is_leaf(n.meta[s]);
                if (leaf) n.tri_base += mr.tri_first;
                out.nodes.push_back(n);
            }
            for (TriangleRecord t : e.tree.triangles) {
                t.prim += mr.prim_first;
                out.triangles.push_back(t);
            }
            for (SourceRange sr : e.source_ranges) {
                sr.first += mr.prim_first;
                out.source_ranges.push_back(sr);
            }
            const double w = double(mr.prim_count);
            sah_binary += e.build_info.sah_binary * w;
            sah_wide += e.sah_wide * w;
            children += e.avg_children * double(mr.node_count);
            out.references += e.build_info.references;
            out.binary_nodes += e.build_info.binary_nodes;
            out.wide_depth = std::max(out.wide_depth, e.wide_depth);
            out.max_leaf_triangles = std::max(out.max_leaf_triangles, e.max_leaf_triangles);
            prim_first += mr.prim_count;
            out.meshes.push_back(mr);
            e = EmitResult{};  // copied: free it
        }
        out.sah_binary = sah_binary / double(prim_first);
        out.sah_wide = sah_wide / double(prim_first);
        out.avg_children = children / double(out.nodes.size());
        return true;
    });
    if (!r.ok()) return r;

    // 3. Instance records (errors name the glTF node), then the top level.
    run_phase("instances", 0, [&] {
        out.instances.resize(scene.placements.size());
        for (size_t i = 0; i < scene.placements.size(); ++i) {
            const Placement& p = scene.placements[i];
            if (p.mesh >= meshes) {
                r = Result::fail(Status::kInvalidArgument, 0, "compile_two_level: placement of a mesh out of range");
                return false;
            }
            if (Result e = make_instance_record(p, out.meshes[p.mesh], out.instances[i]); !e.ok()) {
                r = bad(file + ": " +
                        (p.source_node == kInvalidIndex ? std::string("identity instance")
                                                        : "glTF node " + std::to_string(p.source_node)) +
                        ": " + e.message);
                return false;
            }
            out.instances[i].mesh = p.mesh;
        }
        return true;
    });
    if (!r.ok()) return r;
    run_phase("tlas", 0, [&] {
        r = build_top_level(out.instances, options, out.tlas, out.tlas_depth);
        if (!r.ok()) r.message = file + ": " + r.message;
        return r.ok();
    });
    if (!r.ok()) return r;

    // 4. BNDS, BILD, SRCN.
    Aabb world;
    for (const InstanceRecord& inst : out.instances) {
        Aabb b;
        for (int a = 0; a < 3; ++a) {
            b.lo[a] = inst.world_lo[a];
            b.hi[a] = inst.world_hi[a];
        }
        world.grow(b);
    }
    for (int a = 0; a < 3; ++a) {
        out.bounds.lo[a] = world.lo[a];
        out.bounds.hi[a] = world.hi[a];
    }
    BuildInfo& info = out.build_info;
    info = build_info_head(options.emit.builder, options.sbvh, options.collapse, scene.input_triangles, scene.dropped,
                           scene.skipped_primitives);
    info.triangles = scene.distinct_triangles();
    info.references = out.references;
    info.binary_nodes = out.binary_nodes;
    info.wide_nodes = out.nodes.size();
    info.sah_binary = out.sah_binary;
    info.sah_wide = out.sah_wide;
    info.avg_children = out.avg_children;
    for (const auto& name : scene.input_names) {
        out.source_names.insert(out.source_names.end(), name.begin(), name.end());
        out.source_names.push_back(0);
    }
    return Result::success();
}

namespace {

void add_sections(Writer& writer, const TwoLevelResult& t) {
    SceneSections s;
    s.nodes = t.nodes;
    s.triangles = t.triangles;
    s.source_ranges = t.source_ranges;
    s.bounds = &t.bounds;
    s.build_info = &t.build_info;
    s.source_names = t.source_names;
    s.meshes = t.meshes;
    s.instances = t.instances;
    s.top_nodes = t.tlas;
    add_scene_sections(writer, s);
}

}  // namespace

Result write_two_level(const TwoLevelResult& t, const std::string& path,
                       std::vector<std::pair<std::string, uint64_t>>& bytes, uint64_t& file_bytes) {
    Writer writer;
    add_sections(writer, t);
    return write_with(writer, path, bytes, file_bytes);
}

Result two_level_bytes(const TwoLevelResult& t, std::vector<uint8_t>& out) {
    Writer writer;
    add_sections(writer, t);
    if (Result r = writer.to_bytes(out); !r.ok()) return Result::fail(r.status, r.rule, r.describe());
    return Result::success();
}

}  // namespace cwbvh::compiler

// encode_scene / scene_sections / write_scene: the bridge from the compiler's
// model to the file format. Which sections are written (their order and flags
// are format/'s add_scene_sections):
//   NODE, TRIS, PMAP, BNDS  required (a renderer needs them)
//   BILD, SRCN              optional, always written
//   BV2L                    optional, --keep-sbvh (binary BVH with leaf ranges, format 1.1)
//   BVH2                    optional, one record per leaf (format 1.0; synthetic and test scenes)
//   VERT, INDX              optional, --keep-mesh
#include "cwbvh/compiler/emit.h"

#include <array>
#include <cstring>
#include <optional>
#include <span>

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include "cwbvh/compiler/build.h"
#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/parallel_exact.h"
#include "cwbvh/compiler/sah_report.h"
#include "cwbvh/format/sections.h"
#include "cwbvh/format/source_map.h"
#include "cwbvh/format/tree_depth.h"
#include "cwbvh/format/writer.h"

namespace cwbvh::compiler {
namespace {

/// BNDS: the scene box; an empty scene writes zeros (spec 3.4).
SceneBounds scene_bounds(const Aabb& box) {
    SceneBounds b{};
    if (box.empty()) return b;
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = box.lo[a];
        b.hi[a] = box.hi[a];
    }
    return b;
}

BuildInfo build_info(const EmitInput& in, const EmitResult& out) {
    const Scene& scene = *in.scene;
    BuildInfo info = build_info_head(in.options->builder, *in.sbvh, *in.collapse, scene.input_triangles,
                                     scene.dropped, scene.skipped_primitives);
    info.triangles = scene.triangle_count();
    info.references = in.references;
    info.binary_nodes = in.binary_nodes;
    info.wide_nodes = out.tree.nodes.size();
    info.sah_binary = in.sah_binary;
    info.sah_wide = out.sah_wide;
    info.avg_children = out.avg_children;
    return info;
}

}  // namespace

BuildInfo build_info_head(uint32_t builder, const SbvhConfig& sbvh, const CollapseConfig& collapse,
                          uint64_t input_triangles, const std::map<std::string, uint64_t>& dropped,
                          const std::map<std::string, uint64_t>& skipped_primitives) {
    BuildInfo info{};
    info.builder = builder;
    info.collapse = collapse.kind;
    info.split_alpha = sbvh.split_alpha;
    info.cost_node = collapse.cost_node;
    info.cost_prim = collapse.cost_prim;
    info.max_leaf_triangles = uint32_t(collapse.max_leaf);
    info.input_triangles = input_triangles;
    const auto count = [&](const char* key) {
        const auto it = dropped.find(key);
        return it == dropped.end() ? uint64_t(0) : it->second;
    };
    info.dropped_nonfinite = count("nonfinite");
    info.dropped_degenerate = count("degenerate");
    for (const auto& [kind, n] : skipped_primitives) info.skipped_primitives += n;
    return info;
}

Aabb scene_box(const Scene& scene) {
    // Min/max are exact: any partition gives the same box. The join grows by
    // the right part's corners (ties take the later value, as the serial
    // loop's grow did, so even signed zeros match) and skips an empty part,
    // whose +inf/-inf corners would make the box infinite.
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, scene.indices.size(), 1 << 14), Aabb{},
        [&](const tbb::blocked_range<size_t>& r, Aabb box) {
            for (size_t i = r.begin(); i != r.end(); ++i)
                for (uint32_t v : scene.indices[i]) box.grow(scene.vertices[v]);
            return box;
        },
        [](Aabb a, const Aabb& b) {
            if (!b.empty()) a.grow(b);
            return a;
        });
}

namespace {

/// PMAP runs of `sources`; with `verify`, each triangle's run decoded back and compared.
Result source_ranges_of(std::span<const SourceRef> sources, bool verify, std::vector<SourceRange>& ranges) {
    // clean.cpp keeps stored triangles in source order within a primitive,
    // so a run breaks only at a dropped triangle or a new primitive/input.
    ranges = make_source_ranges(sources);
    if (verify) {
        if (source_range_total(ranges) != sources.size()) {
            return Result::fail(Status::kInternal, 0, "internal error: PMAP ranges do not cover the stored triangles");
        }
        // In parallel; the lowest wrong triangle reports.
        const size_t i = lowest_failing(sources.size(), 1 << 14, [&](size_t k) {
            const std::optional<SourceRef> r = find_source(ranges, uint32_t(k));
            return !r || std::memcmp(&*r, &sources[k], sizeof(SourceRef)) != 0;
        });
        if (i < sources.size()) {
            return Result::fail(Status::kInternal, 0,
                                "internal error: PMAP range decodes stored triangle " + std::to_string(i) + " wrongly");
        }
    }
    return Result::success();
}

}  // namespace

Result make_scene_source_ranges(Scene& scene, bool verify) {
    if (!scene.source_ranges.empty() || scene.sources.empty()) return Result::success();
    if (Result r = source_ranges_of(scene.sources, verify, scene.source_ranges); !r.ok()) return r;
    std::vector<SourceRef>().swap(scene.sources);
    return Result::success();
}

Result encode_scene(const EmitInput& in, EmitResult& out) {
    const EmitOptions& options = *in.options;
    const bool bvh2 = options.bvh2 != Bvh2Section::kNone;
    out.bvh2_leaf_ranges = options.bvh2 == Bvh2Section::kLeafRanges;
    out.keep_mesh = options.keep_mesh;
    if (!in.wide) {
        if (in.scene->triangle_count() != 0) {
            return Result::fail(Status::kInternal, 0, "internal error: encode without a wide tree");
        }
        // The empty scene (spec 3.2, rule 1): a root without used slots. Its
        // exponents are never decoded; 127 (scale 1) is as good as any.
        CwbvhNode root{};
        root.e[0] = root.e[1] = root.e[2] = 127;
        out.tree = EncodedTree{};
        out.tree.nodes.push_back(root);
    } else {
        // Nodes (they read the exact boxes, i.e. the binary tree), then the
        // binary tree may go (boxes_done) before the triangle records exist.
        auto verify = [&](VerifyPart part) {
            if (!options.verify) return Result::success();
            if (Result r = verify_encoded(out.tree, *in.wide, *in.scene, part); !r.ok())
                return Result::fail(Status::kInternal, 0,
                                    "internal error: encoded tree failed verification: " + r.message);
            return Result::success();
        };
        if (Result r = encode_cwbvh_nodes(*in.wide, out.tree, in.collapse->cost_node, in.collapse->cost_prim);
            !r.ok())
            return r;
        if (Result r = verify(VerifyPart::kBoxes); !r.ok()) return r;
        if (in.boxes_done) in.boxes_done();
        if (Result r = encode_cwbvh_triangles(*in.wide, *in.scene, out.tree); !r.ok()) return r;
        if (Result r = verify(VerifyPart::kRecords); !r.ok()) return r;
        if (bvh2 && !in.binary) {
            return Result::fail(Status::kInternal, 0, "internal error: --keep-sbvh without the binary tree");
        }
        if (bvh2) {
            if (Result r = encode_bvh2(*in.binary, *in.wide, out.tree, out.tree.bvh2, out.bvh2_leaf_ranges); !r.ok())
                return r;
        }
    }

    out.wide_depth = wide_tree_depth(out.tree.nodes);
    if (out.wide_depth > kMaxWideDepth) {
        return Result::fail(Status::kBadInput, 0,
                            "the 8-wide tree is " + std::to_string(out.wide_depth) +
                                " levels deep; the format allows " + std::to_string(kMaxWideDepth) +
                                " (the traversal stack's bound)");
    }
    if (bvh2 && !out.tree.bvh2.empty()) {
        out.bvh2_depth = bvh2_tree_depth(out.tree.bvh2);
        if (out.bvh2_depth > kMaxBvh2Depth) {
            return Result::fail(Status::kBadInput, 0,
                                "the binary SBVH is " + std::to_string(out.bvh2_depth) +
                                    " levels deep; the BV2L section allows " + std::to_string(kMaxBvh2Depth) +
                                    " (the baseline kernel's stack); compile without --keep-sbvh");
        }
    }
    out.wide_nodes = out.tree.nodes.size();
    out.avg_children = out.tree.avg_children;
    out.max_leaf_triangles = out.tree.max_leaf_triangles;
    const Aabb root_box = scene_box(*in.scene);
    out.sah_wide = report_sah_wide(out.tree.nodes, root_box);
    out.bounds = scene_bounds(root_box);
    out.build_info = build_info(in, out);
    for (const auto& name : in.scene->input_names) {
        out.source_names.insert(out.source_names.end(), name.begin(), name.end());
        out.source_names.push_back(0);
    }
    // PMAP: the scene's runs when the front end made them (and freed the
    // per-triangle map), else made here.
    if (!in.scene->source_ranges.empty() || in.scene->sources.empty()) {
        out.source_ranges = in.scene->source_ranges;
    } else if (Result r = source_ranges_of(in.scene->sources, options.verify, out.source_ranges); !r.ok()) {
        return r;
    }
    if (source_range_total(out.source_ranges) != in.scene->triangle_count()) {
        return Result::fail(Status::kInternal, 0, "internal error: PMAP ranges do not cover the stored triangles");
    }
    return Result::success();
}

SceneSections scene_sections(const Scene& scene, const EmitResult& e) {
    SceneSections s;
    s.nodes = e.tree.nodes;
    s.triangles = e.tree.triangles;
    s.source_ranges = e.source_ranges;
    s.bounds = &e.bounds;
    s.build_info = &e.build_info;
    s.source_names = e.source_names;
    s.bvh2 = e.tree.bvh2;
    s.bvh2_leaf_ranges = e.bvh2_leaf_ranges;
    if (e.keep_mesh) {
        static_assert(sizeof(Vec3) == 12 && sizeof(std::array<uint32_t, 3>) == 12);
        s.vertices = {reinterpret_cast<const float*>(scene.vertices.data()), scene.vertices.size() * 3};
        s.indices = {reinterpret_cast<const uint32_t*>(scene.indices.data()), scene.indices.size() * 3};
    }
    return s;
}

Result write_with(const Writer& writer, const std::string& path, std::vector<std::pair<std::string, uint64_t>>& bytes,
                  uint64_t& file_bytes) {
    FileHeader header{};
    std::vector<SectionEntry> table;
    if (Result r = writer.layout(header, table); !r.ok())
        return Result::fail(r.status, r.rule, path + ": " + r.describe());
    if (Result r = writer.write_file(path); !r.ok()) return Result::fail(r.status, r.rule, path + ": " + r.describe());
    bytes.clear();
    for (const auto& s : table) bytes.emplace_back(section_name(s.type), s.size);
    file_bytes = header.file_size;
    return Result::success();
}

Result write_scene(const Scene& scene, const EmitResult& e, const std::string& path,
                 std::vector<std::pair<std::string, uint64_t>>& bytes, uint64_t& file_bytes) {
    Writer writer;
    add_scene_sections(writer, scene_sections(scene, e));
    return write_with(writer, path, bytes, file_bytes);
}

Result scene_bytes(const Scene& scene, const EmitResult& e, std::vector<uint8_t>& out) {
    Writer writer;
    add_scene_sections(writer, scene_sections(scene, e));
    if (Result r = writer.to_bytes(out); !r.ok()) return Result::fail(r.status, r.rule, r.describe());
    return Result::success();
}

}  // namespace cwbvh::compiler

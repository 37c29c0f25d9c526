// encode_scene / write_scene: the bridge from the compiler's model to the
// file format. Which sections are written, and with which flags:
//   NODE, TRIS, PMAP, BNDS  required (a renderer needs them)
//   BILD, SRCN              optional, always written
//   BV2L                    optional, --keep-sbvh (binary BVH with leaf ranges, format 1.1)
//   VERT, INDX              optional, --keep-mesh
#include "cwbvh/compiler/emit.h"

#include <cstring>
#include <optional>
#include <span>

#include "cwbvh/compiler/collapse.h"
#include "cwbvh/compiler/sah_report.h"
#include "cwbvh/source_map.h"
#include "cwbvh/tree_depth.h"
#include "cwbvh/writer.h"

namespace cwbvh::compiler {
namespace {

SceneBounds scene_bounds(const Scene& scene) {
    Aabb box;
    for (const auto& tri : scene.indices)
        for (uint32_t v : tri) box.grow(scene.vertices[v]);
    SceneBounds b{};
    for (int a = 0; a < 3; ++a) {
        b.lo[a] = box.lo[a];
        b.hi[a] = box.hi[a];
    }
    return b;
}

BuildInfo build_info(const EmitInput& in, const EmitResult& out) {
    BuildInfo info{};
    const Scene& scene = *in.scene;
    info.builder = in.options->builder;
    info.collapse = in.collapse->kind;
    info.split_alpha = in.sbvh->split_alpha;
    info.cost_node = in.collapse->cost_node;
    info.cost_prim = in.collapse->cost_prim;
    info.max_leaf_triangles = uint32_t(in.collapse->max_leaf);
    info.input_triangles = scene.input_triangles;
    auto count = [](const std::map<std::string, uint64_t>& m, const char* key) {
        const auto it = m.find(key);
        return it == m.end() ? uint64_t(0) : it->second;
    };
    info.dropped_nonfinite = count(scene.dropped, "nonfinite");
    info.dropped_degenerate = count(scene.dropped, "degenerate");
    for (const auto& [kind, n] : scene.skipped_primitives) info.skipped_primitives += n;
    info.triangles = scene.triangle_count();
    info.references = in.references;
    info.binary_nodes = in.binary_nodes;
    info.wide_nodes = out.tree.nodes.size();
    info.sah_binary = in.sah_binary;
    info.sah_wide = out.sah_wide;
    info.avg_children = out.avg_children;
    return info;
}

const char* section_name(uint32_t type) {
    switch (type) {
        case kSectionNodes: return "NODE";
        case kSectionTriangles: return "TRIS";
        case kSectionSourceMap: return "PMAP";
        case kSectionBounds: return "BNDS";
        case kSectionBuildInfo: return "BILD";
        case kSectionBvh2: return "BVH2";
        case kSectionBvh2Leaves: return "BV2L";
        case kSectionVertices: return "VERT";
        case kSectionIndices: return "INDX";
        case kSectionSourceNames: return "SRCN";
        default: return "????";
    }
}

}  // namespace

bool encode_scene(const EmitInput& in, EmitResult& out, std::string& error) {
    if (!encode_cwbvh(*in.wide, *in.scene, out.tree, error, in.collapse->cost_node, in.collapse->cost_prim))
        return false;
    if (in.options->verify && !verify_encoded(out.tree, *in.wide, *in.scene, error)) {
        error = "internal error: encoded tree failed verification: " + error;
        return false;
    }
    if (in.options->keep_sbvh && !in.binary) {
        error = "internal error: --keep-sbvh without the binary tree";
        return false;
    }
    if (in.options->keep_sbvh && !encode_bvh2(*in.binary, *in.wide, out.tree, out.tree.bvh2, error)) return false;

    out.wide_depth = wide_tree_depth(out.tree.nodes);
    if (out.wide_depth > kMaxWideDepth) {
        error = "the 8-wide tree is " + std::to_string(out.wide_depth) + " levels deep; the format allows " +
                std::to_string(kMaxWideDepth) + " (the traversal stack's bound)";
        return false;
    }
    if (in.options->keep_sbvh) {
        out.bvh2_depth = bvh2_tree_depth(out.tree.bvh2);
        if (out.bvh2_depth > kMaxBvh2Depth) {
            error = "the binary SBVH is " + std::to_string(out.bvh2_depth) + " levels deep; the BV2L section allows " +
                    std::to_string(kMaxBvh2Depth) + " (the baseline kernel's stack); compile without --keep-sbvh";
            return false;
        }
    }
    out.wide_nodes = out.tree.nodes.size();
    out.avg_children = out.tree.avg_children;
    out.max_leaf_triangles = out.tree.max_leaf_triangles;
    Aabb root_box;
    for (const auto& tri : in.scene->indices)
        for (uint32_t v : tri) root_box.grow(in.scene->vertices[v]);
    out.sah_wide = report_sah_wide(out.tree.nodes, root_box);
    out.bounds = scene_bounds(*in.scene);
    out.build_info = build_info(in, out);
    for (const auto& name : in.scene->input_names) {
        out.source_names.insert(out.source_names.end(), name.begin(), name.end());
        out.source_names.push_back(0);
    }
    // PMAP: clean.cpp keeps stored triangles in source order within a
    // primitive, so a run breaks only at a dropped triangle or a new primitive/input.
    out.source_ranges = make_source_ranges(in.scene->sources);
    if (in.options->verify) {
        const std::vector<SourceRef>& sources = in.scene->sources;
        if (source_range_total(out.source_ranges) != sources.size()) {
            error = "internal error: PMAP ranges do not cover the stored triangles";
            return false;
        }
        for (size_t i = 0; i < sources.size(); ++i) {
            const std::optional<SourceRef> r = find_source(out.source_ranges, uint32_t(i));
            if (!r || std::memcmp(&*r, &sources[i], sizeof(SourceRef)) != 0) {
                error = "internal error: PMAP range decodes stored triangle " + std::to_string(i) + " wrongly";
                return false;
            }
        }
    }
    return true;
}

bool write_scene(const EmitInput& in, const EmitResult& e, std::vector<std::pair<std::string, uint64_t>>& bytes,
                 uint64_t& file_bytes, std::string& error) {
    const Scene& scene = *in.scene;
    Writer writer;
    writer.add_array<CwbvhNode>(kSectionNodes, kSectionRequired, e.tree.nodes);
    writer.add_array<TriangleRecord>(kSectionTriangles, kSectionRequired, e.tree.triangles);
    writer.add_array<SourceRange>(kSectionSourceMap, kSectionRequired, e.source_ranges);
    writer.add_array<SceneBounds>(kSectionBounds, kSectionRequired, std::span<const SceneBounds>(&e.bounds, 1));
    writer.add_array<BuildInfo>(kSectionBuildInfo, 0, std::span<const BuildInfo>(&e.build_info, 1));
    writer.add_array<uint8_t>(kSectionSourceNames, 0, e.source_names);
    if (in.options->keep_sbvh) writer.add_array<Bvh2Node>(kSectionBvh2Leaves, 0, e.tree.bvh2);
    if (in.options->keep_mesh) {
        static_assert(sizeof(Vec3) == 12 && sizeof(std::array<uint32_t, 3>) == 12);
        writer.add_section(kSectionVertices, 0, 12, scene.vertices.size(),
                           {reinterpret_cast<const uint8_t*>(scene.vertices.data()), scene.vertices.size() * 12});
        writer.add_section(kSectionIndices, 0, 12, scene.indices.size(),
                           {reinterpret_cast<const uint8_t*>(scene.indices.data()), scene.indices.size() * 12});
    }

    FileHeader header{};
    std::vector<SectionEntry> table;
    if (Result r = writer.layout(header, table); !r.ok()) {
        error = in.options->output + ": " + r.describe();
        return false;
    }
    if (Result r = writer.write_file(in.options->output); !r.ok()) {
        error = in.options->output + ": " + r.describe();
        return false;
    }
    bytes.clear();
    for (const auto& s : table) bytes.emplace_back(section_name(s.type), s.size);
    file_bytes = header.file_size;
    return true;
}

}  // namespace cwbvh::compiler

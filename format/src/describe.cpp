#include "cwbvh/format/describe.h"

#include <cinttypes>
#include <cstdio>
#include <cstring>

#include "cwbvh/format/node_decode.h"

namespace cwbvh {
namespace {

std::string fmt(const char* f, auto... args) {
    char buf[1024];
    std::snprintf(buf, sizeof buf, f, args...);
    return buf;
}

/// Shortest text that reads back as the same float.
std::string num(float v) { return fmt("%.9g", double(v)); }
std::string num(double v) { return fmt("%.17g", v); }

template <class T>
const T* section_or_null(const FileLayout& l, uint32_t type, T& storage) {
    const SectionEntry* e = l.find(type);
    if (e == nullptr || e->size < sizeof(T)) return nullptr;
    std::memcpy(&storage, l.payload(*e).data(), sizeof(T));
    return &storage;
}

template <class T>
T element(const FileLayout& l, const SectionEntry& e, uint64_t i) {
    T v;
    std::memcpy(&v, l.payload(e).data() + i * sizeof(T), sizeof(T));
    return v;
}

std::string vec3(const float* v) { return fmt("[%.9g, %.9g, %.9g]", double(v[0]), double(v[1]), double(v[2])); }

const char* builder_name(uint32_t b) { return b == kBuilderSbvh ? "sbvh" : b == kBuilderEmbree ? "embree" : "unknown"; }
const char* collapse_name(uint32_t c) {
    return c == kCollapseOptimal ? "optimal" : c == kCollapseGreedy ? "greedy" : "unknown";
}

void node_json(std::string& o, const CwbvhNode& n) {
    o += "{\"p\": " + vec3(n.p) + fmt(", \"e\": [%u, %u, %u], \"imask\": %u, \"child_base\": %u, \"tri_base\": %u",
                                      n.e[0], n.e[1], n.e[2], n.imask, n.child_base, n.tri_base);
    o += ", \"slots\": [";
    for (int s = 0; s < kWidth; ++s) {
        const uint8_t m = n.meta[s];
        if (s) o += ", ";
        o += fmt("{\"meta\": %u", m);
        if (meta_is_empty(m)) {
            o += ", \"kind\": \"empty\"}";
            continue;
        }
        if (meta_is_internal(m))
            o += fmt(", \"kind\": \"internal\", \"child\": %u", internal_child_index(n, s));
        else
            o += fmt(", \"kind\": \"leaf\", \"first_triangle\": %u, \"count\": %d",
                     n.tri_base + uint32_t(meta_leaf_offset(m)), meta_leaf_count(m));
        float lo[3], hi[3];
        decode_slot_box(n, s, lo, hi);
        o += ", \"lo\": " + vec3(lo) + ", \"hi\": " + vec3(hi) + "}";
    }
    o += "]}";
}

/// Counts of a two-level file (spec 3.9): instanced = sum over instances of their
/// mesh's stored triangles (what the flattened scene would hold).
struct TwoLevelCounts {
    uint64_t meshes = 0, instances = 0, top_nodes = 0, distinct = 0, instanced = 0;
};

bool two_level_counts(const FileLayout& l, TwoLevelCounts& c) {
    const SectionEntry* me = l.find(kSectionMeshes);
    const SectionEntry* ie = l.find(kSectionInstances);
    const SectionEntry* te = l.find(kSectionTopNodes);
    if (me == nullptr || ie == nullptr || te == nullptr || me->element_size != sizeof(MeshRecord) ||
        ie->element_size != sizeof(InstanceRecord))
        return false;
    c.meshes = me->element_count;
    c.instances = ie->element_count;
    c.top_nodes = te->element_count;
    if (const SectionEntry* pm = l.find(kSectionSourceMap); pm != nullptr && pm->element_count > 0 &&
                                                            pm->element_size == sizeof(SourceRange)) {
        const auto last = element<SourceRange>(l, *pm, pm->element_count - 1);
        c.distinct = uint64_t(last.first) + last.count;
    }
    for (uint64_t i = 0; i < c.instances; ++i) {
        const auto inst = element<InstanceRecord>(l, *ie, i);
        if (inst.mesh < c.meshes) c.instanced += element<MeshRecord>(l, *me, inst.mesh).prim_count;
    }
    return true;
}

std::string matrix(const float m[3][4]) {
    std::string o = "[";
    for (int r = 0; r < 3; ++r) {
        o += r ? ", [" : "[";
        for (int c = 0; c < 4; ++c) o += (c ? ", " : "") + num(m[r][c]);
        o += "]";
    }
    return o + "]";
}

}  // namespace

std::string describe_text(const FileLayout& l) {
    const FileHeader& h = l.header;
    std::string o = fmt("version %u.%u, %" PRIu64 " bytes, %u sections\n", h.version_major, h.version_minor,
                        h.file_size, h.section_count);
    o += "  type  flags      offset        size  elem       count  checksum\n";
    for (const SectionEntry& e : l.table)
        o += fmt("  %-4s  %5u  %10" PRIu64 "  %10" PRIu64 "  %4u  %10" PRIu64 "  %016" PRIx64 "\n",
                 section_name(e.type).c_str(), e.flags, e.offset, e.size, e.element_size, e.element_count, e.checksum);
    SceneBounds b;
    if (section_or_null(l, kSectionBounds, b))
        o += "bounds: lo " + vec3(b.lo) + " hi " + vec3(b.hi) + "\n";
    BuildInfo bi;
    if (section_or_null(l, kSectionBuildInfo, bi)) {
        o += fmt("build: builder %s, collapse %s, split_alpha %s, C_node %s, C_prim %s, max leaf %u\n",
                 builder_name(bi.builder), collapse_name(bi.collapse), num(bi.split_alpha).c_str(),
                 num(bi.cost_node).c_str(), num(bi.cost_prim).c_str(), bi.max_leaf_triangles);
        o += fmt("  input triangles %" PRIu64 ", dropped non-finite %" PRIu64 ", degenerate %" PRIu64
                 ", skipped primitives %" PRIu64 "\n",
                 bi.input_triangles, bi.dropped_nonfinite, bi.dropped_degenerate, bi.skipped_primitives);
        o += fmt("  triangles %" PRIu64 ", references %" PRIu64 ", binary nodes %" PRIu64 ", wide nodes %" PRIu64
                 "\n",
                 bi.triangles, bi.references, bi.binary_nodes, bi.wide_nodes);
        o += "  SAH binary " + num(bi.sah_binary) + ", SAH wide " + num(bi.sah_wide) + ", avg children " +
             num(bi.avg_children) + "\n";
    }
    if (TwoLevelCounts c; two_level_counts(l, c))
        o += fmt("two-level: %" PRIu64 " meshes, %" PRIu64 " instances, %" PRIu64 " top-level nodes; triangles %" PRIu64
                 " distinct, %" PRIu64 " instanced (%.2fx)\n",
                 c.meshes, c.instances, c.top_nodes, c.distinct, c.instanced,
                 c.distinct ? double(c.instanced) / double(c.distinct) : 0.0);
    for (const uint32_t type : {kSectionBvh2Leaves, kSectionBvh2}) {
        const SectionEntry* e = l.find(type);
        if (e == nullptr || e->element_size != sizeof(Bvh2Node)) continue;
        uint64_t leaves = 0, records = 0;
        for (uint64_t i = 0; i < e->element_count; ++i) {
            const auto n = element<Bvh2Node>(l, *e, i);
            for (int c = 0; c < 2; ++c) {
                if (n.child[c] >= 0) continue;
                ++leaves;
                records += n.leaf_count[c] == 0 ? 1u : n.leaf_count[c];  // BVH2: 0 = one record
            }
        }
        o += fmt("binary BVH (%s): %" PRIu64 " nodes, %" PRIu64 " leaves, %.2f triangle records per leaf\n",
                 type == kSectionBvh2Leaves ? "BV2L, leaf ranges" : "BVH2, one triangle per leaf", e->element_count,
                 leaves, leaves ? double(records) / double(leaves) : 0.0);
    }
    return o;
}

std::string describe_json(const FileLayout& l, bool decode_content) {
    const FileHeader& h = l.header;
    std::string o = fmt("{\n  \"version\": [%u, %u],\n  \"file_size\": %" PRIu64 ",\n  \"sections\": [\n",
                        h.version_major, h.version_minor, h.file_size);
    for (size_t i = 0; i < l.table.size(); ++i) {
        const SectionEntry& e = l.table[i];
        o += fmt("    {\"type\": \"%s\", \"flags\": %u, \"offset\": %" PRIu64 ", \"size\": %" PRIu64
                 ", \"element_size\": %u, \"element_count\": %" PRIu64 ", \"checksum\": \"%016" PRIx64 "\"}%s\n",
                 section_name(e.type).c_str(), e.flags, e.offset, e.size, e.element_size, e.element_count, e.checksum,
                 i + 1 < l.table.size() ? "," : "");
    }
    o += "  ]";
    SceneBounds b;
    if (section_or_null(l, kSectionBounds, b)) o += ",\n  \"bounds\": {\"lo\": " + vec3(b.lo) + ", \"hi\": " + vec3(b.hi) + "}";
    BuildInfo bi;
    if (section_or_null(l, kSectionBuildInfo, bi)) {
        o += fmt(",\n  \"build_info\": {\"builder\": \"%s\", \"collapse\": \"%s\", ", builder_name(bi.builder),
                 collapse_name(bi.collapse));
        o += "\"split_alpha\": " + num(bi.split_alpha) + ", \"cost_node\": " + num(bi.cost_node) +
             ", \"cost_prim\": " + num(bi.cost_prim);
        o += fmt(", \"max_leaf_triangles\": %u, \"input_triangles\": %" PRIu64 ", \"dropped_nonfinite\": %" PRIu64
                 ", \"dropped_degenerate\": %" PRIu64 ", \"skipped_primitives\": %" PRIu64 ", \"triangles\": %" PRIu64
                 ", \"references\": %" PRIu64 ", \"binary_nodes\": %" PRIu64 ", \"wide_nodes\": %" PRIu64,
                 bi.max_leaf_triangles, bi.input_triangles, bi.dropped_nonfinite, bi.dropped_degenerate,
                 bi.skipped_primitives, bi.triangles, bi.references, bi.binary_nodes, bi.wide_nodes);
        o += ", \"sah_binary\": " + num(bi.sah_binary) + ", \"sah_wide\": " + num(bi.sah_wide) +
             ", \"avg_children\": " + num(bi.avg_children) + "}";
    }
    if (TwoLevelCounts c; two_level_counts(l, c))
        o += fmt(",\n  \"two_level\": {\"meshes\": %" PRIu64 ", \"instances\": %" PRIu64 ", \"top_nodes\": %" PRIu64
                 ", \"distinct_triangles\": %" PRIu64 ", \"instanced_triangles\": %" PRIu64 "}",
                 c.meshes, c.instances, c.top_nodes, c.distinct, c.instanced);
    if (decode_content) {
        auto list = [&](const char* key, uint32_t type, auto one) {
            const SectionEntry* e = l.find(type);
            if (e == nullptr) return;
            o += fmt(",\n  \"%s\": [", key);
            for (uint64_t i = 0; i < e->element_count; ++i) {
                o += i ? ",\n    " : "\n    ";
                one(*e, i);
            }
            o += "\n  ]";
        };
        list("nodes", kSectionNodes, [&](const SectionEntry& e, uint64_t i) { node_json(o, element<CwbvhNode>(l, e, i)); });
        list("triangles", kSectionTriangles, [&](const SectionEntry& e, uint64_t i) {
            const auto t = element<TriangleRecord>(l, e, i);
            o += "{\"v0\": " + vec3(t.v0) + ", \"v1\": " + vec3(t.v1) + ", \"v2\": " + vec3(t.v2) +
                 fmt(", \"prim\": %u}", t.prim);
        });
        list("source_ranges", kSectionSourceMap, [&](const SectionEntry& e, uint64_t i) {
            const auto r = element<SourceRange>(l, e, i);
            o += fmt("{\"first\": %u, \"count\": %u, \"input\": %u, \"mesh\": %u, \"primitive\": %u, "
                     "\"first_triangle\": %u}",
                     r.first, r.count, r.input, r.mesh, r.primitive, r.first_triangle);
        });
        auto bvh2_node = [&](const SectionEntry& e, uint64_t i, bool leaf_ranges) {
            const auto n = element<Bvh2Node>(l, e, i);
            const float c0lo[3] = {n.c0_lo_x, n.c0_lo_y, n.c0_lo_z}, c0hi[3] = {n.c0_hi_x, n.c0_hi_y, n.c0_hi_z};
            const float c1lo[3] = {n.c1_lo_x, n.c1_lo_y, n.c1_lo_z}, c1hi[3] = {n.c1_hi_x, n.c1_hi_y, n.c1_hi_z};
            o += "{\"child\": [" + std::to_string(n.child[0]) + ", " + std::to_string(n.child[1]) + "]";
            if (leaf_ranges)
                o += ", \"leaf_count\": [" + std::to_string(n.leaf_count[0]) + ", " +
                     std::to_string(n.leaf_count[1]) + "]";
            o += ", \"c0\": {\"lo\": " + vec3(c0lo) + ", \"hi\": " + vec3(c0hi) + "}, \"c1\": {\"lo\": " + vec3(c1lo) +
                 ", \"hi\": " + vec3(c1hi) + "}}";
        };
        list("bvh2", kSectionBvh2, [&](const SectionEntry& e, uint64_t i) { bvh2_node(e, i, false); });
        list("bvh2_leaf_ranges", kSectionBvh2Leaves, [&](const SectionEntry& e, uint64_t i) { bvh2_node(e, i, true); });
        list("meshes", kSectionMeshes, [&](const SectionEntry& e, uint64_t i) {
            const auto m = element<MeshRecord>(l, e, i);
            o += fmt("{\"node_first\": %u, \"node_count\": %u, \"tri_first\": %u, \"tri_count\": %u, "
                     "\"prim_first\": %u, \"prim_count\": %u, ",
                     m.node_first, m.node_count, m.tri_first, m.tri_count, m.prim_first, m.prim_count);
            o += "\"lo\": " + vec3(m.lo) + ", \"hi\": " + vec3(m.hi) + fmt(", \"source_mesh\": %u}", m.source_mesh);
        });
        list("instances", kSectionInstances, [&](const SectionEntry& e, uint64_t i) {
            const auto n = element<InstanceRecord>(l, e, i);
            o += "{\"object_to_world\": " + matrix(n.object_to_world) + ", \"world_to_object\": " +
                 matrix(n.world_to_object) + fmt(", \"mesh\": %u, \"source_node\": %u, ", n.mesh, n.source_node) +
                 "\"world_lo\": " + vec3(n.world_lo) + ", \"world_hi\": " + vec3(n.world_hi) + "}";
        });
        list("top_nodes", kSectionTopNodes,
             [&](const SectionEntry& e, uint64_t i) { node_json(o, element<CwbvhNode>(l, e, i)); });
    }
    o += "\n}\n";
    return o;
}

}  // namespace cwbvh

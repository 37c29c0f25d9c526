// What a renderer links: open a .cwbvh file read-only with mmap, validate
// it, and hand out typed views of its sections. The views point into the
// mapping and live as long as the File.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <utility>

#include "cwbvh/format/format.h"
#include "cwbvh/format/sections.h"
#include "cwbvh/format/status.h"
#include "cwbvh/format/validate.h"

namespace cwbvh {

struct OpenOptions {
    /// Verify payload checksums of the selected sections (the header/table
    /// checksum is always verified).
    bool verify_checksums = true;
    /// Known sections (SectionMask bits) to validate and hand out; the
    /// accessors of other sections return an empty span / nullptr. Header and
    /// section-table rules always run on every entry. A renderer that needs
    /// only traversal passes kMaskNodes | kMaskTriangles (| kMaskTwoLevel: a
    /// two-level file opened with NODE but without kMaskTwoLevel is refused,
    /// rule 4009, as a reader that does not know the two-level sections would).
    uint32_t sections = kMaskAll;
};

// Expected<T> (a value or a Result) is in cwbvh/format/status.h.

/// A validated, memory-mapped .cwbvh file. Move-only; unmaps on destruction.
class File {
public:
    /// Opens `path` (read-only, MAP_PRIVATE), rejects directories, empty and
    /// non-regular files, and validates. Error messages start with the path.
    static Expected<File> open(const std::string& path, const OpenOptions& options = {});

    File() = default;
    File(File&& other) noexcept;
    File& operator=(File&& other) noexcept;
    File(const File&) = delete;
    File& operator=(const File&) = delete;
    ~File();

    const std::string& path() const { return path_; }
    const FileHeader& header() const { return layout_.header; }
    const FileLayout& layout() const { return layout_; }
    std::span<const uint8_t> bytes() const { return layout_.file; }

    std::span<const CwbvhNode> nodes() const { return view<CwbvhNode>(kSectionNodes); }
    std::span<const TriangleRecord> triangles() const { return view<TriangleRecord>(kSectionTriangles); }
    /// PMAP: sorted runs of stored triangles (spec 3.3); source_of() decodes one.
    std::span<const SourceRange> source_ranges() const { return view<SourceRange>(kSectionSourceMap); }
    /// Where stored triangle `prim` (TriangleRecord::prim, a hit's prim) comes
    /// from: binary search over source_ranges(). nullopt if PMAP was not
    /// selected or no range holds `prim`.
    std::optional<SourceRef> source_of(uint32_t prim) const;
    /// Stored triangles = the PMAP total (0 if PMAP was not selected).
    uint64_t stored_triangle_count() const;
    const SceneBounds* bounds() const { return one<SceneBounds>(kSectionBounds); }
    const BuildInfo* build_info() const { return one<BuildInfo>(kSectionBuildInfo); }
    /// The binary BVH of the baseline kernels: BV2L (leaf ranges, format 1.1) when
    /// the file has it, else the legacy BVH2 (one triangle per leaf; its leaf_count
    /// fields are 0, which the traversals read as 1). Empty if neither is present
    /// or kMaskBvh2 was not selected.
    std::span<const Bvh2Node> bvh2() const {
        const std::span<const Bvh2Node> ranges = view<Bvh2Node>(kSectionBvh2Leaves);
        return ranges.empty() ? view<Bvh2Node>(kSectionBvh2) : ranges;
    }
    /// The section bvh2() hands out: kSectionBvh2Leaves, kSectionBvh2, or 0 for none.
    uint32_t bvh2_type() const {
        if (!view<Bvh2Node>(kSectionBvh2Leaves).empty()) return kSectionBvh2Leaves;
        return view<Bvh2Node>(kSectionBvh2).empty() ? 0u : uint32_t(kSectionBvh2);
    }
    /// VERT as float[3] per vertex; INDX as uint32_t[3] per stored triangle.
    std::span<const float> vertices() const { return view<float>(kSectionVertices); }
    std::span<const uint32_t> indices() const { return view<uint32_t>(kSectionIndices); }
    /// SRCN: names each followed by NUL (a name per input file, in PMAP input order).
    std::span<const char> source_names() const { return view<char>(kSectionSourceNames); }

    /// Two-level file (format 1.2, spec 3.9): the file has the MESH, INST and TLAS
    /// sections (whether or not kMaskTwoLevel was selected). NODE then holds the
    /// bottom levels: mesh m's root is nodes()[meshes()[m].node_first], not node 0.
    bool is_two_level() const { return layout_.find(kSectionMeshes) != nullptr; }
    /// MESH: the bottom levels (empty for a single-level file or if kMaskTwoLevel was not selected).
    std::span<const MeshRecord> meshes() const { return view<MeshRecord>(kSectionMeshes); }
    /// INST: the instances, in TLAS leaf order (a TLAS leaf's "triangles" index it).
    std::span<const InstanceRecord> instances() const { return view<InstanceRecord>(kSectionInstances); }
    /// TLAS: the top level, root top_nodes()[0]; child_base indexes TLAS, leaves index INST.
    std::span<const CwbvhNode> top_nodes() const { return view<CwbvhNode>(kSectionTopNodes); }
    /// Sum over instances of their mesh's stored triangles (prim_count): the triangles
    /// of the flattened scene; 0 unless two-level with kMaskTwoLevel selected.
    uint64_t instanced_triangle_count() const;

    /// Payload of a section that was selected and validated (empty if absent).
    std::span<const uint8_t> section(uint32_t type) const;

private:
    template <class T>
    std::span<const T> view(uint32_t type) const {
        const std::span<const uint8_t> b = section(type);
        // Sections are 64-byte aligned in a page-aligned mapping; the cast is
        // the documented purpose of the format (mmap and use in place).
        return {reinterpret_cast<const T*>(b.data()), b.size() / sizeof(T)};
    }
    template <class T>
    const T* one(uint32_t type) const {
        const std::span<const T> v = view<T>(type);
        return v.empty() ? nullptr : v.data();
    }
    void release();

    std::string path_;
    void* map_ = nullptr;
    size_t map_size_ = 0;
    uint32_t sections_ = 0;
    FileLayout layout_;
};

}  // namespace cwbvh

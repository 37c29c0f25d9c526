// cwbvh::DeviceScene: the traversal sections of a validated .cwbvh file in GPU
// memory (NODE + TRIS, optionally the binary BVH: BV2L, or a legacy BVH2 section;
// the BVH2 kernel reads both; and for a two-level scene, format 1.2, the top
// level TLAS with INST and MESH, which trace_two_level reads). Move-only RAII; frees on destruction.
// Plain C++ header: no CUDA types, so callers need not be compiled by nvcc.
//
// Upload method (UploadMethod::kPinnedStaging, the default):
//   The loader maps the file read-only (PROT_READ, MAP_PRIVATE). Registering that
//   mapping with cudaHostRegister needs cudaHostRegisterReadOnly, which is only
//   allowed where the device reports cudaDevAttrHostRegisterReadOnlySupported
//   (not on every platform), pins the file's pages for the lifetime of the
//   registration, and costs a page-table walk per call - too fragile for a
//   loader. A plain cudaMemcpy from pageable memory makes the driver stage
//   through its own small pinned buffer, synchronously. We therefore stage
//   explicitly: two pinned buffers of kStagingChunkBytes each; the CPU copies
//   chunk i+1 from the mapping into one while the DMA engine copies chunk i from
//   the other (cudaMemcpyAsync on a private stream, one event per buffer).
//   Sections smaller than kStagingMinBytes go through plain cudaMemcpy (the
//   staging set-up would cost more than it saves). UploadMethod::kPageable forces
//   plain cudaMemcpy for everything; the GPU benchmark times both.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "cwbvh/format/format.h"
#include "cwbvh/format/status.h"
#include "cwbvh/kernels/node_intersect_fast.h"
#include "cwbvh/kernels/query.h"
#include "cwbvh/kernels/traverse_two_level.h"

namespace cwbvh {

class File;

enum class UploadMethod : uint32_t { kPinnedStaging = 0, kPageable = 1 };

inline constexpr size_t kStagingChunkBytes = size_t(8) << 20;  ///< per pinned staging buffer (2 of them)
inline constexpr size_t kStagingMinBytes = size_t(1) << 20;    ///< smaller sections: plain cudaMemcpy

struct UploadOptions {
    bool bvh2 = true;  ///< also upload the binary BVH (BV2L or BVH2: File::bvh2()) when the file has one (trace_bvh2)
    UploadMethod method = UploadMethod::kPinnedStaging;
    int device = -1;   ///< CUDA device ordinal; -1: the calling thread's current device
};

/// The top level of a two-level scene (format 1.2) as host pointers + counts.
struct TwoLevelSections {
    const CwbvhNode* top_nodes = nullptr;  ///< TLAS
    size_t top_node_count = 0;
    const InstanceRecord* instances = nullptr;  ///< INST
    size_t instance_count = 0;
    const MeshRecord* meshes = nullptr;  ///< MESH
    size_t mesh_count = 0;
};

/// The two-level sections of a validated File; all empty for a single-level file.
TwoLevelSections two_level_sections(const File& file);

struct UploadStats {
    double seconds = 0.0;  ///< wall time of allocation + copies (synchronised)
    uint64_t bytes = 0;    ///< bytes copied host -> device
};

class DeviceScene {
public:
    /// Uploads NODE + TRIS (+ File::bvh2(): BV2L, else BVH2) of a validated File. On failure returns
    /// kInvalidArgument (no NODE, counts past 32 bits) or kDeviceError (no GPU, old driver, out of
    /// memory, ... with file:line).
    static Expected<DeviceScene> upload(const File& file, const UploadOptions& options = {});
    /// Same from raw sections (the C API and tests use this). The sections must be
    /// valid (as validated by the loader): the kernels check indices but trust boxes.
    /// bvh2 may be either binary section (a legacy BVH2's leaf_count fields are 0).
    /// (Pointer + count, not std::span: this header is also compiled as C++17 by nvcc.)
    static Expected<DeviceScene> upload(const CwbvhNode* nodes, size_t node_count,
                                        const TriangleRecord* triangles, size_t triangle_count,
                                        const Bvh2Node* bvh2, size_t bvh2_count, const UploadOptions& options = {});
    /// Same with the top level of a two-level scene (TLAS, INST, MESH; all three or
    /// none). The File overload uploads them whenever the file has them.
    static Expected<DeviceScene> upload(const CwbvhNode* nodes, size_t node_count,
                                        const TriangleRecord* triangles, size_t triangle_count,
                                        const Bvh2Node* bvh2, size_t bvh2_count, const TwoLevelSections& two_level,
                                        const UploadOptions& options = {});

    DeviceScene() = default;
    DeviceScene(DeviceScene&& other) noexcept;
    DeviceScene& operator=(DeviceScene&& other) noexcept;
    DeviceScene(const DeviceScene&) = delete;
    DeviceScene& operator=(const DeviceScene&) = delete;
    ~DeviceScene();

    /// Device pointers (valid on device()).
    const CwbvhNode* nodes() const { return nodes_; }
    const TriangleRecord* triangles() const { return tris_; }
    const Bvh2Node* bvh2() const { return bvh2_; }
    uint32_t node_count() const { return node_count_; }
    uint32_t triangle_count() const { return tri_count_; }
    uint32_t bvh2_count() const { return bvh2_count_; }
    bool has_bvh2() const { return bvh2_ != nullptr; }
    /// The binary BVH has multi-record leaves (BV2L): some leaf_count is nonzero.
    bool bvh2_leaf_ranges() const { return bvh2_leaf_ranges_; }
    uint64_t node_bytes() const { return uint64_t(node_count_) * sizeof(CwbvhNode); }
    uint64_t triangle_bytes() const { return uint64_t(tri_count_) * sizeof(TriangleRecord); }
    uint64_t bvh2_bytes() const { return uint64_t(bvh2_count_) * sizeof(Bvh2Node); }
    int device() const { return device_; }
    /// Two-level scene (TLAS, INST, MESH uploaded): trace_two_level applies.
    bool has_two_level() const { return top_nodes_ != nullptr; }
    /// The device pointers of the two-level traversal (valid when has_two_level()).
    TwoLevelScene two_level() const {
        return TwoLevelScene{top_nodes_, top_node_count_, instances_, instance_count_, meshes_,
                             mesh_count_, nodes_,     node_count_,     tris_,      tri_count_, two_level_scale_};
    }
    /// The scene for inline queries from a kernel (query.h: intersect, occluded), by
    /// value: the device pointers and the fast node test's constants; two-level when
    /// has_two_level(). Valid while this DeviceScene lives.
    SceneView view() const {
        if (has_two_level()) return SceneView{two_level()};
        return single_level_view(nodes_, node_count_, tris_, tri_count_, node_scale_);
    }
    uint64_t top_level_bytes() const {
        return uint64_t(top_node_count_) * sizeof(CwbvhNode) + uint64_t(instance_count_) * sizeof(InstanceRecord) +
               uint64_t(mesh_count_) * sizeof(MeshRecord);
    }
    /// Scene constants of the CWBVH kernel's fast node test (node_scale() over NODE at upload).
    const NodeScale& node_scale() const { return node_scale_; }
    const UploadStats& upload_stats() const { return stats_; }
    bool empty() const { return nodes_ == nullptr; }

private:
    void release() noexcept;

    CwbvhNode* nodes_ = nullptr;
    TriangleRecord* tris_ = nullptr;
    Bvh2Node* bvh2_ = nullptr;
    CwbvhNode* top_nodes_ = nullptr;
    InstanceRecord* instances_ = nullptr;
    MeshRecord* meshes_ = nullptr;
    uint32_t node_count_ = 0, tri_count_ = 0, bvh2_count_ = 0;
    uint32_t top_node_count_ = 0, instance_count_ = 0, mesh_count_ = 0;
    bool bvh2_leaf_ranges_ = false;
    int device_ = -1;
    NodeScale node_scale_{};
    NodeScale two_level_scale_{};  ///< merge_node_scale over NODE and TLAS (two-level scenes)
    UploadStats stats_;
};

}  // namespace cwbvh

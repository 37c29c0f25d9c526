// DeviceScene upload (see device_scene.h for the choice of upload method).
#include "cwbvh/kernels/device_scene.h"

#include <chrono>
#include <cstring>
#include <limits>
#include <optional>
#include <span>
#include <utility>

#include "cwbvh/kernels/cuda_check.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh {
namespace {

/// Pinned double-buffered staging copier; frees everything it made, also on throw.
class Stager {
public:
    Stager() {
        CWBVH_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
        for (int i = 0; i < 2; ++i) {
            CWBVH_CUDA_CHECK(cudaMallocHost(&buf_[i], kStagingChunkBytes));
            CWBVH_CUDA_CHECK(cudaEventCreateWithFlags(&done_[i], cudaEventDisableTiming));
        }
    }
    ~Stager() {
        if (stream_) CWBVH_CUDA_WARN(cudaStreamSynchronize(stream_));
        for (int i = 0; i < 2; ++i) {
            if (done_[i]) CWBVH_CUDA_WARN(cudaEventDestroy(done_[i]));
            if (buf_[i]) CWBVH_CUDA_WARN(cudaFreeHost(buf_[i]));
        }
        if (stream_) CWBVH_CUDA_WARN(cudaStreamDestroy(stream_));
    }
    Stager(const Stager&) = delete;
    Stager& operator=(const Stager&) = delete;

    void copy(void* dst, const void* src, size_t bytes) {
        const auto* s = static_cast<const uint8_t*>(src);
        auto* d = static_cast<uint8_t*>(dst);
        for (size_t off = 0; off < bytes; off += kStagingChunkBytes) {
            const size_t n = bytes - off < kStagingChunkBytes ? bytes - off : kStagingChunkBytes;
            // Wait until the DMA that last read this buffer has finished.
            if (used_[next_]) CWBVH_CUDA_CHECK(cudaEventSynchronize(done_[next_]));
            std::memcpy(buf_[next_], s + off, n);
            CWBVH_CUDA_CHECK(cudaMemcpyAsync(d + off, buf_[next_], n, cudaMemcpyHostToDevice, stream_));
            CWBVH_CUDA_CHECK(cudaEventRecord(done_[next_], stream_));
            used_[next_] = true;
            next_ ^= 1;
        }
    }
    void finish() { CWBVH_CUDA_CHECK(cudaStreamSynchronize(stream_)); }

private:
    cudaStream_t stream_ = nullptr;
    void* buf_[2] = {nullptr, nullptr};
    cudaEvent_t done_[2] = {nullptr, nullptr};
    bool used_[2] = {false, false};
    int next_ = 0;
};

template <class T>
T* alloc_and_copy(std::span<const T> src, Stager* stager, uint64_t& bytes) {
    if (src.empty()) return nullptr;
    T* d = nullptr;
    CWBVH_CUDA_CHECK(cudaMalloc(reinterpret_cast<void**>(&d), src.size_bytes()));
    try {
        if (stager && src.size_bytes() >= kStagingMinBytes) {
            stager->copy(d, src.data(), src.size_bytes());
        } else {
            CWBVH_CUDA_CHECK(cudaMemcpy(d, src.data(), src.size_bytes(), cudaMemcpyHostToDevice));
        }
    } catch (...) {
        CWBVH_CUDA_WARN(cudaFree(d));
        throw;
    }
    bytes += src.size_bytes();
    return d;
}

}  // namespace

TwoLevelSections two_level_sections(const File& file) {
    TwoLevelSections t;
    if (!file.is_two_level() || file.top_nodes().empty()) return t;  // or kMaskTwoLevel not selected
    t.top_nodes = file.top_nodes().data();
    t.top_node_count = file.top_nodes().size();
    t.instances = file.instances().data();
    t.instance_count = file.instances().size();
    t.meshes = file.meshes().data();
    t.mesh_count = file.meshes().size();
    return t;
}

Expected<DeviceScene> DeviceScene::upload(const File& file, const UploadOptions& options) {
    const std::span<const Bvh2Node> bvh2 = options.bvh2 ? file.bvh2() : std::span<const Bvh2Node>{};
    return upload(file.nodes().data(), file.nodes().size(), file.triangles().data(), file.triangles().size(),
                  bvh2.data(), bvh2.size(), two_level_sections(file), options);
}

Expected<DeviceScene> DeviceScene::upload(const CwbvhNode* node_ptr, size_t node_count,
                                          const TriangleRecord* tri_ptr, size_t tri_count,
                                          const Bvh2Node* bvh2_ptr, size_t bvh2_count, const UploadOptions& options) {
    return upload(node_ptr, node_count, tri_ptr, tri_count, bvh2_ptr, bvh2_count, TwoLevelSections{}, options);
}

Expected<DeviceScene> DeviceScene::upload(const CwbvhNode* node_ptr, size_t node_count,
                                          const TriangleRecord* tri_ptr, size_t tri_count,
                                          const Bvh2Node* bvh2_ptr, size_t bvh2_count,
                                          const TwoLevelSections& two_level, const UploadOptions& options) {
    const std::span<const CwbvhNode> nodes(node_ptr, node_ptr ? node_count : 0);
    const std::span<const TriangleRecord> triangles(tri_ptr, tri_ptr ? tri_count : 0);
    const std::span<const Bvh2Node> bvh2(bvh2_ptr, bvh2_ptr ? bvh2_count : 0);
    const std::span<const CwbvhNode> top(two_level.top_nodes, two_level.top_nodes ? two_level.top_node_count : 0);
    const std::span<const InstanceRecord> inst(two_level.instances,
                                               two_level.instances ? two_level.instance_count : 0);
    const std::span<const MeshRecord> mesh(two_level.meshes, two_level.meshes ? two_level.mesh_count : 0);
    constexpr size_t kMaxCount = std::numeric_limits<uint32_t>::max();
    if (!top.empty() && (inst.empty() || mesh.empty())) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "device upload: a two-level scene needs TLAS, INST and MESH together");
    }
    if (top.size() > kMaxCount || inst.size() > kMaxCount || mesh.size() > kMaxCount) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "device upload: more than 2^32-1 top-level nodes, instances or meshes");
    }
    if (nodes.empty()) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "device upload: the scene has no NODE section (not opened, or not selected)");
    }
    if (nodes.size() > kMaxCount || triangles.size() > kMaxCount || bvh2.size() > kMaxCount) {
        return Result::fail(Status::kInvalidArgument, 0,
                            "device upload: more than 2^32-1 nodes or triangles (kernels use 32-bit indices)");
    }
    const auto t0 = std::chrono::steady_clock::now();
    DeviceScene scene;
    try {
        if (options.device >= 0) CWBVH_CUDA_CHECK(cudaSetDevice(options.device));
        CWBVH_CUDA_CHECK(cudaGetDevice(&scene.device_));
        uint64_t bytes = 0;
        std::optional<Stager> stager;
        if (options.method == UploadMethod::kPinnedStaging &&
            nodes.size_bytes() + triangles.size_bytes() + bvh2.size_bytes() + top.size_bytes() + inst.size_bytes() +
                    mesh.size_bytes() >=
                kStagingMinBytes) {
            stager.emplace();
        }
        Stager* s = stager ? &*stager : nullptr;
        scene.nodes_ = alloc_and_copy(nodes, s, bytes);
        scene.node_count_ = uint32_t(nodes.size());
        scene.node_scale_ = cwbvh::node_scale(nodes.data(), nodes.size());
        scene.tris_ = alloc_and_copy(triangles, s, bytes);
        scene.tri_count_ = uint32_t(triangles.size());
        scene.bvh2_ = alloc_and_copy(bvh2, s, bytes);
        scene.bvh2_count_ = uint32_t(bvh2.size());
        if (!top.empty())
            scene.two_level_scale_ =
                merge_node_scale(scene.node_scale_, cwbvh::node_scale(top.data(), top.size()));
        scene.top_nodes_ = alloc_and_copy(top, s, bytes);
        scene.top_node_count_ = uint32_t(top.size());
        scene.instances_ = alloc_and_copy(inst, s, bytes);
        scene.instance_count_ = uint32_t(inst.size());
        scene.meshes_ = alloc_and_copy(mesh, s, bytes);
        scene.mesh_count_ = uint32_t(mesh.size());
        for (const Bvh2Node& n : bvh2)
            if (n.leaf_count[0] != 0 || n.leaf_count[1] != 0) {
                scene.bvh2_leaf_ranges_ = true;
                break;
            }
        if (s) s->finish();
        CWBVH_CUDA_CHECK(cudaDeviceSynchronize());
        scene.stats_.bytes = bytes;
    } catch (const CudaError& e) {
        // scene's destructor frees what was allocated
        return Result::fail(Status::kDeviceError, 0, std::string("device upload: ") + e.what());
    } catch (const std::bad_alloc&) {
        return Result::fail(Status::kDeviceError, 0, "device upload: out of host memory");
    }
    scene.stats_.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return Expected<DeviceScene>(std::move(scene));
}

DeviceScene::DeviceScene(DeviceScene&& o) noexcept
    : nodes_(std::exchange(o.nodes_, nullptr)),
      tris_(std::exchange(o.tris_, nullptr)),
      bvh2_(std::exchange(o.bvh2_, nullptr)),
      top_nodes_(std::exchange(o.top_nodes_, nullptr)),
      instances_(std::exchange(o.instances_, nullptr)),
      meshes_(std::exchange(o.meshes_, nullptr)),
      node_count_(std::exchange(o.node_count_, 0)),
      tri_count_(std::exchange(o.tri_count_, 0)),
      bvh2_count_(std::exchange(o.bvh2_count_, 0)),
      top_node_count_(std::exchange(o.top_node_count_, 0)),
      instance_count_(std::exchange(o.instance_count_, 0)),
      mesh_count_(std::exchange(o.mesh_count_, 0)),
      bvh2_leaf_ranges_(std::exchange(o.bvh2_leaf_ranges_, false)),
      device_(std::exchange(o.device_, -1)),
      node_scale_(std::exchange(o.node_scale_, NodeScale{})),
      two_level_scale_(std::exchange(o.two_level_scale_, NodeScale{})),
      stats_(o.stats_) {}

DeviceScene& DeviceScene::operator=(DeviceScene&& o) noexcept {
    if (this != &o) {
        release();
        nodes_ = std::exchange(o.nodes_, nullptr);
        tris_ = std::exchange(o.tris_, nullptr);
        bvh2_ = std::exchange(o.bvh2_, nullptr);
        node_count_ = std::exchange(o.node_count_, 0);
        tri_count_ = std::exchange(o.tri_count_, 0);
        bvh2_count_ = std::exchange(o.bvh2_count_, 0);
        top_nodes_ = std::exchange(o.top_nodes_, nullptr);
        instances_ = std::exchange(o.instances_, nullptr);
        meshes_ = std::exchange(o.meshes_, nullptr);
        top_node_count_ = std::exchange(o.top_node_count_, 0);
        instance_count_ = std::exchange(o.instance_count_, 0);
        mesh_count_ = std::exchange(o.mesh_count_, 0);
        bvh2_leaf_ranges_ = std::exchange(o.bvh2_leaf_ranges_, false);
        device_ = std::exchange(o.device_, -1);
        node_scale_ = std::exchange(o.node_scale_, NodeScale{});
        two_level_scale_ = std::exchange(o.two_level_scale_, NodeScale{});
        stats_ = o.stats_;
    }
    return *this;
}

DeviceScene::~DeviceScene() { release(); }

void DeviceScene::release() noexcept {
    if (!nodes_ && !tris_ && !bvh2_ && !top_nodes_ && !instances_ && !meshes_) return;
    int current = -1;
    CWBVH_CUDA_WARN(cudaGetDevice(&current));
    if (device_ >= 0 && current != device_) CWBVH_CUDA_WARN(cudaSetDevice(device_));
    if (nodes_) CWBVH_CUDA_WARN(cudaFree(nodes_));
    if (tris_) CWBVH_CUDA_WARN(cudaFree(tris_));
    if (bvh2_) CWBVH_CUDA_WARN(cudaFree(bvh2_));
    if (top_nodes_) CWBVH_CUDA_WARN(cudaFree(top_nodes_));
    if (instances_) CWBVH_CUDA_WARN(cudaFree(instances_));
    if (meshes_) CWBVH_CUDA_WARN(cudaFree(meshes_));
    if (device_ >= 0 && current >= 0 && current != device_) CWBVH_CUDA_WARN(cudaSetDevice(current));
    nodes_ = nullptr;
    tris_ = nullptr;
    bvh2_ = nullptr;
    top_nodes_ = nullptr;
    instances_ = nullptr;
    meshes_ = nullptr;
    node_count_ = tri_count_ = bvh2_count_ = 0;
    top_node_count_ = instance_count_ = mesh_count_ = 0;
    bvh2_leaf_ranges_ = false;
    node_scale_ = NodeScale{};
    two_level_scale_ = NodeScale{};
}

}  // namespace cwbvh

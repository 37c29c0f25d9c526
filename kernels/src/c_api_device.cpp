// C API of the device loader (cwbvh/cwbvh_device.h) over cwbvh::DeviceScene.
#include <cstdio>
#include <new>
#include <string>

#include "cwbvh/cwbvh_device.h"
#include "cwbvh/kernels/device_scene.h"

struct cwbvh_device_scene {
    cwbvh::DeviceScene scene;
};

namespace {
void set_error(char* error, size_t size, const std::string& msg) {
    if (error && size > 0) std::snprintf(error, size, "%s", msg.c_str());
}
}  // namespace

extern "C" cwbvh_status cwbvh_device_upload(const cwbvh_file* file, cwbvh_device_scene** out, char* error,
                                            size_t error_size) {
    if (out) *out = nullptr;
    set_error(error, error_size, "");
    if (!file || !out || cwbvh_status_of(file) != CWBVH_OK) {
        set_error(error, error_size, "cwbvh_device_upload: NULL argument or a file that failed to open");
        return CWBVH_ERROR_INVALID_ARGUMENT;
    }
    uint64_t n_nodes = 0, n_tris = 0, n_bvh2 = 0;
    const auto* nodes = static_cast<const cwbvh::CwbvhNode*>(cwbvh_nodes(file, &n_nodes));
    const auto* tris = static_cast<const cwbvh::TriangleRecord*>(cwbvh_triangles(file, &n_tris));
    const auto* bvh2 = static_cast<const cwbvh::Bvh2Node*>(cwbvh_bvh2(file, &n_bvh2));
    if (!nodes || !tris) {
        set_error(error, error_size, "cwbvh_device_upload: NODE and TRIS must be selected when opening");
        return CWBVH_ERROR_INVALID_ARGUMENT;
    }
    // A two-level file (format 1.2): its top level too (TLAS, INST, MESH).
    cwbvh::TwoLevelSections two_level;
    if (cwbvh_is_two_level(file)) {
        uint64_t n_top = 0, n_inst = 0, n_mesh = 0;
        two_level.top_nodes = static_cast<const cwbvh::CwbvhNode*>(cwbvh_top_nodes(file, &n_top));
        two_level.instances = static_cast<const cwbvh::InstanceRecord*>(cwbvh_instances(file, &n_inst));
        two_level.meshes = static_cast<const cwbvh::MeshRecord*>(cwbvh_meshes(file, &n_mesh));
        two_level.top_node_count = size_t(n_top);
        two_level.instance_count = size_t(n_inst);
        two_level.mesh_count = size_t(n_mesh);
        if (!two_level.top_nodes || !two_level.instances || !two_level.meshes) {
            set_error(error, error_size,
                      "cwbvh_device_upload: a two-level file: CWBVH_SECTION_TWO_LEVEL must be selected when opening");
            return CWBVH_ERROR_INVALID_ARGUMENT;
        }
    }
    try {
        cwbvh::Expected<cwbvh::DeviceScene> scene = cwbvh::DeviceScene::upload(
            nodes, size_t(n_nodes), tris, size_t(n_tris), bvh2, size_t(n_bvh2), two_level);
        if (!scene.ok()) {
            const std::string& why = scene.error().message;
            set_error(error, error_size, why);
            return why.find("cudaErrorMemoryAllocation") != std::string::npos ? CWBVH_ERROR_OUT_OF_MEMORY
                                                                            : CWBVH_ERROR_IO;
        }
        *out = new cwbvh_device_scene{std::move(*scene)};
        return CWBVH_OK;
    } catch (const std::bad_alloc&) {
        set_error(error, error_size, "cwbvh_device_upload: out of host memory");
        return CWBVH_ERROR_OUT_OF_MEMORY;
    }
}

extern "C" const void* cwbvh_device_nodes(const cwbvh_device_scene* s, uint64_t* count) {
    if (count) *count = s ? s->scene.node_count() : 0;
    return s ? s->scene.nodes() : nullptr;
}
extern "C" const void* cwbvh_device_triangles(const cwbvh_device_scene* s, uint64_t* count) {
    if (count) *count = s ? s->scene.triangle_count() : 0;
    return s ? s->scene.triangles() : nullptr;
}
extern "C" const void* cwbvh_device_bvh2(const cwbvh_device_scene* s, uint64_t* count) {
    if (count) *count = s ? s->scene.bvh2_count() : 0;
    return s ? s->scene.bvh2() : nullptr;
}
extern "C" const void* cwbvh_device_top_nodes(const cwbvh_device_scene* s, uint64_t* count) {
    const bool two = s && s->scene.has_two_level();
    if (count) *count = two ? s->scene.two_level().top_node_count : 0;
    return two ? s->scene.two_level().top_nodes : nullptr;
}
extern "C" const void* cwbvh_device_instances(const cwbvh_device_scene* s, uint64_t* count) {
    const bool two = s && s->scene.has_two_level();
    if (count) *count = two ? s->scene.two_level().instance_count : 0;
    return two ? s->scene.two_level().instances : nullptr;
}
extern "C" const void* cwbvh_device_meshes(const cwbvh_device_scene* s, uint64_t* count) {
    const bool two = s && s->scene.has_two_level();
    if (count) *count = two ? s->scene.two_level().mesh_count : 0;
    return two ? s->scene.two_level().meshes : nullptr;
}
extern "C" void cwbvh_device_free(cwbvh_device_scene* s) { delete s; }

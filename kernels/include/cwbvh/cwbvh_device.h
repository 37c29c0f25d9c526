/* C API of the GPU side: upload the traversal sections of an opened .cwbvh file
 * (cwbvh.h) to the current CUDA device. Device pointers are handed out as void*
 * so this header needs no CUDA headers. Library: cwbvh_cuda. */
#ifndef CWBVH_CWBVH_DEVICE_H
#define CWBVH_CWBVH_DEVICE_H

#include <stddef.h>
#include <stdint.h>

#include "cwbvh/cwbvh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct cwbvh_device_scene cwbvh_device_scene;

/* Uploads NODE, TRIS and (if present) BVH2 of `file`, which must have been opened
 * successfully with at least CWBVH_SECTION_NODES | CWBVH_SECTION_TRIANGLES; for a
 * two-level file (cwbvh_is_two_level) also TLAS, INST and MESH, which need
 * CWBVH_SECTION_TWO_LEVEL (CWBVH_ERROR_INVALID_ARGUMENT without it).
 * Returns CWBVH_OK and *out, or an error with *out = NULL; the message (no GPU, old
 * driver, out of device memory, with the failing CUDA call) is copied into
 * error/error_size when error != NULL. Errors: CWBVH_ERROR_INVALID_ARGUMENT (NULL
 * or failed file), CWBVH_ERROR_IO (any CUDA failure), CWBVH_ERROR_OUT_OF_MEMORY. */
cwbvh_status cwbvh_device_upload(const cwbvh_file* file, cwbvh_device_scene** out, char* error,
                                 size_t error_size);

/* Device pointers and counts (NULL/0 if absent). */
const void* cwbvh_device_nodes(const cwbvh_device_scene* scene, uint64_t* count);
const void* cwbvh_device_triangles(const cwbvh_device_scene* scene, uint64_t* count);
const void* cwbvh_device_bvh2(const cwbvh_device_scene* scene, uint64_t* count);
/* Two-level files: the top level (80-byte nodes), instances (128-byte InstanceRecord)
 * and meshes (64-byte MeshRecord); NULL/0 for a single-level file. */
const void* cwbvh_device_top_nodes(const cwbvh_device_scene* scene, uint64_t* count);
const void* cwbvh_device_instances(const cwbvh_device_scene* scene, uint64_t* count);
const void* cwbvh_device_meshes(const cwbvh_device_scene* scene, uint64_t* count);

/* Frees the device memory. NULL is a no-op. */
void cwbvh_device_free(cwbvh_device_scene* scene);

#ifdef __cplusplus
}
#endif

#endif /* CWBVH_CWBVH_DEVICE_H */

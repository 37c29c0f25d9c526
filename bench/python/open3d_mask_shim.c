/* LD_PRELOAD shim for open3d_check.py: wraps Embree's rtcIntersect1M and rtcOccluded1M (the two
 * calls Open3D 0.16's RaycastingScene makes), reports the ray mask of the first ray Open3D
 * passes, and, when CWBVH_SHIM_FIX_MASK=1, sets every ray's mask to all ones before Embree
 * sees it. Build: cc -shared -fPIC -O2 open3d_mask_shim.c -o shim.so -ldl */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

typedef void (*stream_fn)(void* scene, void* context, void* rays, unsigned int m, size_t stride);

/* Embree's own symbol: the Python module that loads Open3D does so with RTLD_LOCAL, so
 * RTLD_NEXT does not see libembree3; ask the library itself. */
static stream_fn embree(const char* name) {
    void* lib = dlopen("libembree3.so.3", RTLD_NOW | RTLD_NOLOAD);
    if (!lib) lib = dlopen("libembree3.so.3", RTLD_NOW);
    stream_fn f = lib ? (stream_fn)dlsym(lib, name) : 0;
    if (!f) {
        fprintf(stderr, "shim: %s not found in libembree3.so.3\n", name);
        abort();
    }
    return f;
}

static void visit(const char* name, void* rays, unsigned int m, size_t stride) {
    static int reported = 0;
    const int fix = getenv("CWBVH_SHIM_FIX_MASK") && getenv("CWBVH_SHIM_FIX_MASK")[0] == '1';
    for (unsigned int i = 0; i < m; ++i) {
        uint32_t* mask = (uint32_t*)((char*)rays + i * stride + 36); /* RTCRay: mask after tfar */
        if (!reported) {
            fprintf(stderr, "shim: %s: first ray's mask = 0x%08x\n", name, *mask);
            reported = 1;
        }
        if (fix) *mask = 0xFFFFFFFFu;
    }
}

void rtcIntersect1M(void* scene, void* context, void* rays, unsigned int m, size_t stride) {
    static stream_fn real = 0;
    if (!real) real = embree("rtcIntersect1M");
    visit("rtcIntersect1M", rays, m, stride);
    real(scene, context, rays, m, stride);
}

void rtcOccluded1M(void* scene, void* context, void* rays, unsigned int m, size_t stride) {
    static stream_fn real = 0;
    if (!real) real = embree("rtcOccluded1M");
    visit("rtcOccluded1M", rays, m, stride);
    real(scene, context, rays, m, stride);
}

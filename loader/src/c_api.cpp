// The C API over cwbvh::File. No exception crosses the boundary.
#include "cwbvh/cwbvh.h"

#include <new>
#include <optional>
#include <string>

#include "cwbvh/loader/loader.h"

static_assert(CWBVH_SECTION_NODES == cwbvh::kMaskNodes && CWBVH_SECTION_ALL == cwbvh::kMaskAll);
static_assert(int(CWBVH_ERROR_CHECKSUM) == int(cwbvh::Status::kChecksumMismatch));
static_assert(int(CWBVH_ERROR_INVALID_ARGUMENT) == int(cwbvh::Status::kInvalidArgument));
static_assert(sizeof(cwbvh_source_ref) == sizeof(cwbvh::SourceRef));
static_assert(CWBVH_SECTION_TWO_LEVEL == cwbvh::kMaskTwoLevel);

struct cwbvh_file {
    cwbvh::File file;
    cwbvh_status status = CWBVH_OK;
    uint32_t rule = 0;
    std::string message;
};

namespace {

template <class T>
const T* section_ptr(const cwbvh_file* f, uint32_t type, uint64_t* count, uint64_t element_size) {
    const std::span<const uint8_t> b = f != nullptr ? f->file.section(type) : std::span<const uint8_t>{};
    if (count != nullptr) *count = b.size() / element_size;
    return b.empty() ? nullptr : reinterpret_cast<const T*>(b.data());
}

}  // namespace

extern "C" {

void cwbvh_open_options_init(cwbvh_open_options* options) {
    if (options == nullptr) return;
    *options = cwbvh_open_options{sizeof(cwbvh_open_options), 1, CWBVH_SECTION_ALL, 0};
}

cwbvh_status cwbvh_open(const char* path, const cwbvh_open_options* options, cwbvh_file** out) {
    if (out == nullptr) return CWBVH_ERROR_INVALID_ARGUMENT;
    *out = nullptr;
    if (path == nullptr) return CWBVH_ERROR_INVALID_ARGUMENT;
    if (options != nullptr && options->struct_size < sizeof(cwbvh_open_options)) return CWBVH_ERROR_INVALID_ARGUMENT;
    // reserved is 0 (the header): a later version may give it a meaning that this one ignores.
    if (options != nullptr && options->reserved != 0) return CWBVH_ERROR_INVALID_ARGUMENT;
    try {
        auto* handle = new cwbvh_file;
        *out = handle;
        cwbvh::OpenOptions o;
        if (options != nullptr) {
            o.verify_checksums = options->verify_checksums != 0;
            o.sections = options->sections & CWBVH_SECTION_ALL;
        }
        auto opened = cwbvh::File::open(path, o);
        if (opened.ok()) {
            handle->file = std::move(*opened);
        } else {
            handle->status = cwbvh_status(opened.error().status);
            handle->rule = opened.error().rule;
            handle->message = opened.error().describe();
        }
        return handle->status;
    } catch (const std::exception&) {  // std::bad_alloc, std::length_error: allocation failed
        delete *out;
        *out = nullptr;
        return CWBVH_ERROR_OUT_OF_MEMORY;
    }
}

cwbvh_status cwbvh_status_of(const cwbvh_file* file) { return file ? file->status : CWBVH_ERROR_INVALID_ARGUMENT; }
uint32_t cwbvh_error_rule(const cwbvh_file* file) { return file ? file->rule : 0; }
const char* cwbvh_error_message(const cwbvh_file* file) {
    return file ? file->message.c_str() : "no handle (invalid argument or out of memory)";
}
const char* cwbvh_status_string(cwbvh_status status) {
    if (status == CWBVH_ERROR_OUT_OF_MEMORY) return "out of memory";  // the C API's own status
    return cwbvh::status_name(cwbvh::Status(status));
}

const void* cwbvh_nodes(const cwbvh_file* f, uint64_t* n) { return section_ptr<void>(f, cwbvh::kSectionNodes, n, 80); }
const void* cwbvh_triangles(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<void>(f, cwbvh::kSectionTriangles, n, sizeof(cwbvh::TriangleRecord));
}
const void* cwbvh_source_ranges(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<void>(f, cwbvh::kSectionSourceMap, n, sizeof(cwbvh::SourceRange));
}
cwbvh_status cwbvh_source_of(const cwbvh_file* f, uint32_t prim, cwbvh_source_ref* out) {
    if (f == nullptr || out == nullptr) return CWBVH_ERROR_INVALID_ARGUMENT;
    const std::optional<cwbvh::SourceRef> r = f->file.source_of(prim);
    if (!r) return CWBVH_ERROR_INVALID_ARGUMENT;
    *out = cwbvh_source_ref{r->input, r->mesh, r->primitive, r->triangle};
    return CWBVH_OK;
}
const float* cwbvh_bounds(const cwbvh_file* f) { return section_ptr<float>(f, cwbvh::kSectionBounds, nullptr, 24); }
const void* cwbvh_build_info(const cwbvh_file* f) { return section_ptr<void>(f, cwbvh::kSectionBuildInfo, nullptr, 256); }
const void* cwbvh_bvh2(const cwbvh_file* f, uint64_t* n) {
    const void* ranges = section_ptr<void>(f, cwbvh::kSectionBvh2Leaves, n, 64);
    return ranges != nullptr ? ranges : section_ptr<void>(f, cwbvh::kSectionBvh2, n, 64);
}
const float* cwbvh_vertices(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<float>(f, cwbvh::kSectionVertices, n, 12);
}
const uint32_t* cwbvh_indices(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<uint32_t>(f, cwbvh::kSectionIndices, n, 12);
}
const char* cwbvh_source_names(const cwbvh_file* f, uint64_t* size) {
    return section_ptr<char>(f, cwbvh::kSectionSourceNames, size, 1);
}
int cwbvh_is_two_level(const cwbvh_file* f) {
    return f != nullptr && f->status == CWBVH_OK && f->file.is_two_level() ? 1 : 0;
}
const void* cwbvh_meshes(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<void>(f, cwbvh::kSectionMeshes, n, sizeof(cwbvh::MeshRecord));
}
const void* cwbvh_instances(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<void>(f, cwbvh::kSectionInstances, n, sizeof(cwbvh::InstanceRecord));
}
const void* cwbvh_top_nodes(const cwbvh_file* f, uint64_t* n) {
    return section_ptr<void>(f, cwbvh::kSectionTopNodes, n, sizeof(cwbvh::CwbvhNode));
}
const void* cwbvh_section(const cwbvh_file* f, uint32_t type, uint64_t* size) {
    return section_ptr<void>(f, type, size, 1);
}

void cwbvh_close(cwbvh_file* file) { delete file; }

}  // extern "C"

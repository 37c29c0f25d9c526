// The OptiX 9.0 peer (optix_peer.h). The OptiX API comes through optix_stubs.h: its
// function table is filled by optixInit(), which dlopens libnvoptix.so.1 (installed
// with the NVIDIA driver), so this builds and links on machines without the driver.
#include "optix_peer.h"

#include <optix.h>
#include <optix_function_table_definition.h>  // the one definition of the function table
#include <optix_stack_size.h>
#include <optix_stubs.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "cwbvh/kernels/cuda_check.h"
#include "optix_params.h"

// The device programs as OptiX IR (optix_programs.cu, embedded at build time by
// bench/optix/embed.cmake).
extern "C" const unsigned char cwbvh_optix_ir[];
extern "C" const size_t cwbvh_optix_ir_size;

namespace cwbvh {
namespace {

// CWBVH_OPTIX_CHECK_LOG: for the calls that write the compile/link log (g_log), which
// then ends the message.
#define CWBVH_OPTIX_CHECK_(expr, tail)                                                                         \
    do {                                                                                                      \
        const OptixResult cwbvh_optix_res_ = (expr);                                                          \
        if (cwbvh_optix_res_ != OPTIX_SUCCESS)                                                                \
            throw std::runtime_error(std::string(#expr) + " failed: " + optixGetErrorName(cwbvh_optix_res_) + \
                                     " (" + optixGetErrorString(cwbvh_optix_res_) + ")" + (tail));            \
    } while (0)
#define CWBVH_OPTIX_CHECK(expr) CWBVH_OPTIX_CHECK_(expr, std::string())
#define CWBVH_OPTIX_CHECK_LOG(expr) CWBVH_OPTIX_CHECK_(expr, log_tail())

thread_local char g_log[2048];
thread_local size_t g_log_size = sizeof g_log;

std::string log_tail() {
    if (g_log[0] == '\0') return {};
    return std::string(": ") + g_log;
}

void reset_log() {
    g_log[0] = '\0';
    g_log_size = sizeof g_log;
}

struct alignas(OPTIX_SBT_RECORD_ALIGNMENT) SbtRecord {
    char header[OPTIX_SBT_RECORD_HEADER_SIZE];
};

template <class T>
T* dev_alloc(size_t bytes) {
    void* p = nullptr;
    if (bytes) CWBVH_CUDA_CHECK(cudaMalloc(&p, bytes));
    return static_cast<T*>(p);
}

/// Elapsed ms between two events recorded around one call on `stream`.
struct EventPair {
    cudaEvent_t a = nullptr, b = nullptr;
    EventPair() {
        CWBVH_CUDA_CHECK(cudaEventCreate(&a));
        CWBVH_CUDA_CHECK(cudaEventCreate(&b));
    }
    ~EventPair() {
        if (a) CWBVH_CUDA_WARN(cudaEventDestroy(a));
        if (b) CWBVH_CUDA_WARN(cudaEventDestroy(b));
    }
    EventPair(const EventPair&) = delete;
    EventPair& operator=(const EventPair&) = delete;
    float ms() const {
        CWBVH_CUDA_CHECK(cudaEventSynchronize(b));
        float t = 0;
        CWBVH_CUDA_CHECK(cudaEventElapsedTime(&t, a, b));
        return t;
    }
};

}  // namespace

struct OptixPeer::Impl {
    OptixDeviceContext ctx = nullptr;
    OptixModule module = nullptr;
    OptixProgramGroup groups[3] = {};  // raygen, miss, hit group
    OptixPipeline pipeline = nullptr;
    OptixShaderBindingTable sbt{};
    SbtRecord* d_sbt = nullptr;  // 3 records: raygen, miss, hit group
    optix_peer::LaunchParams* d_params = nullptr;
    void* d_gas = nullptr;
    OptixTraversableHandle gas = 0;

    ~Impl() {
        if (d_gas) CWBVH_CUDA_WARN(cudaFree(d_gas));
        if (d_params) CWBVH_CUDA_WARN(cudaFree(d_params));
        if (d_sbt) CWBVH_CUDA_WARN(cudaFree(d_sbt));
        if (pipeline) optixPipelineDestroy(pipeline);
        for (OptixProgramGroup g : groups)
            if (g) optixProgramGroupDestroy(g);
        if (module) optixModuleDestroy(module);
        if (ctx) optixDeviceContextDestroy(ctx);
    }

    void make_pipeline() {
        OptixModuleCompileOptions mco{};
        mco.optLevel = OPTIX_COMPILE_OPTIMIZATION_DEFAULT;
        mco.debugLevel = OPTIX_COMPILE_DEBUG_LEVEL_NONE;
        OptixPipelineCompileOptions pco{};
        pco.usesMotionBlur = 0;
        pco.traversableGraphFlags = OPTIX_TRAVERSABLE_GRAPH_FLAG_ALLOW_SINGLE_GAS;
        pco.numPayloadValues = 4;    // t, u, v, prim
        pco.numAttributeValues = 2;  // the built-in triangle barycentrics
        pco.exceptionFlags = OPTIX_EXCEPTION_FLAG_NONE;
        pco.pipelineLaunchParamsVariableName = "params";
        pco.usesPrimitiveTypeFlags = OPTIX_PRIMITIVE_TYPE_FLAGS_TRIANGLE;
        reset_log();
        CWBVH_OPTIX_CHECK_LOG(optixModuleCreate(ctx, &mco, &pco, reinterpret_cast<const char*>(cwbvh_optix_ir),
                                            cwbvh_optix_ir_size, g_log, &g_log_size, &module));

        OptixProgramGroupDesc desc[3] = {};
        desc[0].kind = OPTIX_PROGRAM_GROUP_KIND_RAYGEN;
        desc[0].raygen.module = module;
        desc[0].raygen.entryFunctionName = "__raygen__trace";
        desc[1].kind = OPTIX_PROGRAM_GROUP_KIND_MISS;
        desc[1].miss.module = module;
        desc[1].miss.entryFunctionName = "__miss__miss";
        desc[2].kind = OPTIX_PROGRAM_GROUP_KIND_HITGROUP;
        desc[2].hitgroup.moduleCH = module;
        desc[2].hitgroup.entryFunctionNameCH = "__closesthit__hit";
        OptixProgramGroupOptions pgo{};
        reset_log();
        CWBVH_OPTIX_CHECK_LOG(optixProgramGroupCreate(ctx, desc, 3, &pgo, g_log, &g_log_size, groups));

        OptixPipelineLinkOptions plo{};
        plo.maxTraceDepth = 1;
        reset_log();
        CWBVH_OPTIX_CHECK_LOG(optixPipelineCreate(ctx, &pco, &plo, groups, 3, g_log, &g_log_size, &pipeline));
        OptixStackSizes ss{};
        for (OptixProgramGroup g : groups) CWBVH_OPTIX_CHECK(optixUtilAccumulateStackSizes(g, &ss, pipeline));
        unsigned int dc_trav = 0, dc_state = 0, cont = 0;
        CWBVH_OPTIX_CHECK(optixUtilComputeStackSizes(&ss, 1, 0, 0, &dc_trav, &dc_state, &cont));
        CWBVH_OPTIX_CHECK(optixPipelineSetStackSize(pipeline, dc_trav, dc_state, cont, 1));  // one GAS, no IAS

        SbtRecord rec[3];
        for (int i = 0; i < 3; ++i) CWBVH_OPTIX_CHECK(optixSbtRecordPackHeader(groups[i], &rec[i]));
        d_sbt = dev_alloc<SbtRecord>(sizeof rec);
        CWBVH_CUDA_CHECK(cudaMemcpy(d_sbt, rec, sizeof rec, cudaMemcpyHostToDevice));
        sbt.raygenRecord = reinterpret_cast<CUdeviceptr>(&d_sbt[0]);
        sbt.missRecordBase = reinterpret_cast<CUdeviceptr>(&d_sbt[1]);
        sbt.missRecordStrideInBytes = sizeof(SbtRecord);
        sbt.missRecordCount = 1;
        sbt.hitgroupRecordBase = reinterpret_cast<CUdeviceptr>(&d_sbt[2]);
        sbt.hitgroupRecordStrideInBytes = sizeof(SbtRecord);
        sbt.hitgroupRecordCount = 1;
        d_params = dev_alloc<optix_peer::LaunchParams>(sizeof(optix_peer::LaunchParams));
    }
};

OptixPeer::OptixPeer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
OptixPeer::~OptixPeer() = default;

std::string OptixPeer::version() {
    return "OptiX " + std::to_string(OPTIX_VERSION / 10000) + "." + std::to_string(OPTIX_VERSION / 100 % 100) + "." +
           std::to_string(OPTIX_VERSION % 100) + " headers (ABI " + std::to_string(OPTIX_ABI_VERSION) + ")";
}

std::unique_ptr<OptixPeer> OptixPeer::create(std::string& why) {
    const OptixResult init = optixInit();  // dlopen libnvoptix.so.1 and query the function table
    if (init != OPTIX_SUCCESS) {
        why = std::string("optixInit failed: ") +
              (init == OPTIX_ERROR_LIBRARY_NOT_FOUND        ? "libnvoptix.so.1 not found (no NVIDIA driver with OptiX)"
               : init == OPTIX_ERROR_UNSUPPORTED_ABI_VERSION ? "the driver is too old for the OptiX 9.0 ABI (needs 570+)"
                                                             : "error " + std::to_string(int(init)));
        return nullptr;
    }
    try {
        auto impl = std::make_unique<Impl>();
        CWBVH_CUDA_CHECK(cudaFree(nullptr));  // make the runtime's primary context current
        OptixDeviceContextOptions o{};
        CWBVH_OPTIX_CHECK(optixDeviceContextCreate(nullptr, &o, &impl->ctx));  // nullptr: the current context
        impl->make_pipeline();
        return std::unique_ptr<OptixPeer>(new OptixPeer(std::move(impl)));
    } catch (const std::exception& e) {
        why = e.what();
        return nullptr;
    }
}

OptixGasInfo OptixPeer::build(const TriangleRecord* tris, size_t n) {
    Impl& m = *impl_;
    if (m.d_gas) {
        CWBVH_CUDA_CHECK(cudaFree(m.d_gas));
        m.d_gas = nullptr;
        m.gas = 0;
    }
    // Vertices in stored-id order: GAS primitive p = stored triangle p (the records are
    // in leaf order, and a triangle split by the SBVH appears in several leaves).
    uint32_t count = 0;
    for (size_t i = 0; i < n; ++i) count = std::max(count, tris[i].prim + 1);
    std::vector<float> verts(size_t(count) * 9, 0.0f);  // never-stored ids: all-zero, degenerate
    for (size_t i = 0; i < n; ++i) {
        float* v = &verts[size_t(tris[i].prim) * 9];
        std::memcpy(v, tris[i].v0, 12);
        std::memcpy(v + 3, tris[i].v1, 12);
        std::memcpy(v + 6, tris[i].v2, 12);
    }
    OptixGasInfo info;
    info.triangles = count;
    float* d_verts = dev_alloc<float>(verts.size() * sizeof(float));
    void *d_temp = nullptr, *d_out = nullptr;
    uint64_t* d_compacted = nullptr;
    try {
        CWBVH_CUDA_CHECK(cudaMemcpy(d_verts, verts.data(), verts.size() * sizeof(float), cudaMemcpyHostToDevice));
        const CUdeviceptr vb = reinterpret_cast<CUdeviceptr>(d_verts);
        const unsigned int geom_flags = OPTIX_GEOMETRY_FLAG_DISABLE_ANYHIT;
        OptixBuildInput in{};
        in.type = OPTIX_BUILD_INPUT_TYPE_TRIANGLES;
        in.triangleArray.vertexBuffers = &vb;
        in.triangleArray.numVertices = count * 3;
        in.triangleArray.vertexFormat = OPTIX_VERTEX_FORMAT_FLOAT3;
        in.triangleArray.vertexStrideInBytes = 12;
        in.triangleArray.indexFormat = OPTIX_INDICES_FORMAT_NONE;  // three vertices per triangle
        in.triangleArray.flags = &geom_flags;
        in.triangleArray.numSbtRecords = 1;
        OptixAccelBuildOptions ao{};
        ao.buildFlags = OPTIX_BUILD_FLAG_PREFER_FAST_TRACE | OPTIX_BUILD_FLAG_ALLOW_COMPACTION;
        ao.operation = OPTIX_BUILD_OPERATION_BUILD;
        OptixAccelBufferSizes sizes{};
        CWBVH_OPTIX_CHECK(optixAccelComputeMemoryUsage(m.ctx, &ao, &in, 1, &sizes));
        info.temp_bytes = sizes.tempSizeInBytes;
        info.uncompacted_bytes = sizes.outputSizeInBytes;
        d_temp = dev_alloc<void>(sizes.tempSizeInBytes);
        d_out = dev_alloc<void>(sizes.outputSizeInBytes);
        d_compacted = dev_alloc<uint64_t>(sizeof(uint64_t));
        OptixAccelEmitDesc emit{};
        emit.type = OPTIX_PROPERTY_TYPE_COMPACTED_SIZE;
        emit.result = reinterpret_cast<CUdeviceptr>(d_compacted);
        OptixTraversableHandle h = 0;
        {
            EventPair ev;
            CWBVH_CUDA_CHECK(cudaEventRecord(ev.a, nullptr));
            CWBVH_OPTIX_CHECK(optixAccelBuild(m.ctx, nullptr, &ao, &in, 1, reinterpret_cast<CUdeviceptr>(d_temp),
                                              sizes.tempSizeInBytes, reinterpret_cast<CUdeviceptr>(d_out),
                                              sizes.outputSizeInBytes, &h, &emit, 1));
            CWBVH_CUDA_CHECK(cudaEventRecord(ev.b, nullptr));
            info.build_ms = ev.ms();
        }
        uint64_t compacted = 0;
        CWBVH_CUDA_CHECK(cudaMemcpy(&compacted, d_compacted, sizeof compacted, cudaMemcpyDeviceToHost));
        CWBVH_CUDA_CHECK(cudaFree(d_temp));
        d_temp = nullptr;
        if (compacted > 0 && compacted < sizes.outputSizeInBytes) {
            m.d_gas = dev_alloc<void>(compacted);
            EventPair ev;
            CWBVH_CUDA_CHECK(cudaEventRecord(ev.a, nullptr));
            CWBVH_OPTIX_CHECK(optixAccelCompact(m.ctx, nullptr, h, reinterpret_cast<CUdeviceptr>(m.d_gas), compacted,
                                                &m.gas));
            CWBVH_CUDA_CHECK(cudaEventRecord(ev.b, nullptr));
            info.compact_ms = ev.ms();
            info.gas_bytes = compacted;
            CWBVH_CUDA_CHECK(cudaFree(d_out));
        } else {
            m.d_gas = d_out;
            m.gas = h;
            info.gas_bytes = sizes.outputSizeInBytes;
        }
        d_out = nullptr;
        CWBVH_CUDA_CHECK(cudaFree(d_compacted));
        d_compacted = nullptr;
        CWBVH_CUDA_CHECK(cudaFree(d_verts));  // a triangle GAS keeps its own copy of the vertices
        d_verts = nullptr;
    } catch (...) {
        for (void* p : {static_cast<void*>(d_verts), d_temp, d_out, static_cast<void*>(d_compacted)})
            if (p) CWBVH_CUDA_WARN(cudaFree(p));
        throw;
    }
    return info;
}

void OptixPeer::trace(const Ray* d_rays, Hit* d_hits, size_t n, bool any, float* launch_ms, cudaStream_t stream) {
    Impl& m = *impl_;
    if (!m.gas) throw std::logic_error("OptixPeer::trace before build");
    if (n > (size_t(1) << 30)) throw std::invalid_argument("OptixPeer::trace: more than 2^30 rays in one launch");
    if (n == 0) return;
    const optix_peer::LaunchParams p{d_rays, d_hits, m.gas, any ? 1u : 0u};
    CWBVH_CUDA_CHECK(cudaMemcpyAsync(m.d_params, &p, sizeof p, cudaMemcpyHostToDevice, stream));
    std::unique_ptr<EventPair> ev;
    if (launch_ms) {
        ev = std::make_unique<EventPair>();
        CWBVH_CUDA_CHECK(cudaEventRecord(ev->a, stream));
    }
    CWBVH_OPTIX_CHECK(optixLaunch(m.pipeline, stream, reinterpret_cast<CUdeviceptr>(m.d_params), sizeof p, &m.sbt,
                                  unsigned(n), 1, 1));
    if (launch_ms) {
        CWBVH_CUDA_CHECK(cudaEventRecord(ev->b, stream));
        *launch_ms = ev->ms();
    }
    CWBVH_CUDA_CHECK(cudaStreamSynchronize(stream));
}

}  // namespace cwbvh

// fast_node_selfcheck.h: one thread per case; each case is one function compiled for
// both sides, so device and host run the same source.
#include "cwbvh/kernels/fast_node_selfcheck.h"

#include <cuda_runtime.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "cwbvh/format/hex.h"
#include "cwbvh/kernels/axis_range.h"
#include "cwbvh/kernels/fast_node_pairs.h"
#include "cwbvh/kernels/fp16.h"
#include "cwbvh/kernels/node_intersect_fast.h"

namespace cwbvh {
namespace {

struct Fp16Case {
    uint32_t a, b, c;  // half pairs
    float x, y, z;
    double w;          // float_round_down / _up (format/float_round.h)
    float o, d, t;     // segment_reach (axis_range.h): origin, direction, tmax >= 0
};
struct Fp16Out {
    uint32_t fma, min, le, vmax, vmin, pack, rd, ru;
    float fma_rd, fma_ru, sub_rd, add_ru;
    float w_down, w_up, reach;
};

CWBVH_HD Fp16Out run_case(const Fp16Case& k) {
    Fp16Out o{};
    o.fma = h2_fma(k.a, k.b, k.c);
    o.min = h2_min(k.a, k.b);
    bool lo = false, hi = false;
    h2_le(k.a, k.b, lo, hi);
    o.le = uint32_t(lo) | (uint32_t(hi) << 1);
    o.vmax = vimax3_s16x2_relu(k.a, k.b, k.c);
    o.vmin = vimin3_s16x2(k.a, k.b, k.c);
    o.pack = h2_pack(k.x, k.y);
    o.rd = h2_broadcast_rd(k.x);
    o.ru = h2_broadcast_ru(k.y);
    o.fma_rd = fma_rd(k.x, k.y, k.z);
    o.fma_ru = fma_ru(k.x, k.y, k.z);
    o.sub_rd = sub_rd(k.x, k.z);
    o.add_ru = add_ru(k.y, k.z);
    o.w_down = float_round_down(k.w);
    o.w_up = float_round_up(k.w);
    o.reach = segment_reach(k.o, k.d, k.t);
    return o;
}

__global__ void fp16_kernel(const Fp16Case* in, Fp16Out* out, size_t n) {
    const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (i < n) out[i] = run_case(in[i]);
}

// One (node, ray) pair on the device: the fast test with the host's NodeRay, and the per-ray
// set-up and the reference test from the Ray itself, as the kernels run them.
struct NodeOut {
    uint32_t fast;     ///< intersect_node_fast with the host-built NodeRay
    uint32_t ref;      ///< the reference arithmetic (make_node_ray alone: no fast bit)
    NodeRay set_up;    ///< make_node_ray + enable_fast_node_test on the device
};

CWBVH_HD NodeOut run_pair(const NodeWords& node, const NodeRay& host_ray, const Ray& ray, const NodeScale& sc) {
    NodeOut o;
    o.fast = intersect_node_fast(node, host_ray, ray.tmax, sc.frame_word);
    o.ref = intersect_node_dispatch(node, make_node_ray(ray), ray.tmin, ray.tmax, sc.frame_word);
    o.set_up = make_node_ray(ray);
    enable_fast_node_test(o.set_up, sc, ray.dir, ray.tmin);
    return o;
}

__global__ void node_kernel(const CwbvhNode* nodes, const NodeRay* node_rays, const Ray* rays, NodeScale sc,
                            NodeOut* out, size_t n) {
    const size_t i = size_t(blockIdx.x) * blockDim.x + threadIdx.x;
    if (i < n) out[i] = run_pair(load_node_words(nodes + i), node_rays[i], rays[i], sc);
}

// Device buffers freed on scope exit.
template <class T>
struct Buffer {
    T* p = nullptr;
    ~Buffer() { cudaFree(p); }
};

bool ok(cudaError_t e, FastNodeSelfCheck& r) {
    if (e == cudaSuccess) return true;
    r.error = cudaGetErrorString(e);
    return false;
}

template <class T>
bool to_device(const std::vector<T>& v, Buffer<T>& d, FastNodeSelfCheck& r) {
    return ok(cudaMalloc(reinterpret_cast<void**>(&d.p), v.size() * sizeof(T)), r) &&
           ok(cudaMemcpy(d.p, v.data(), v.size() * sizeof(T), cudaMemcpyHostToDevice), r);
}

uint16_t any_half(std::mt19937_64& g) {
    if (g() % 16 == 0) return g() % 2 ? 0x8000u : 0x0000u;  // +-0: min(+0, -0) is -0 (PTX min)
    for (;;) {
        uint16_t h = uint16_t(g());
        if (g() % 3 == 0) h &= 0x83FFu;  // subnormal
        if (((h >> 10) & 0x1Fu) != 31) return h;
    }
}
float any_float(std::mt19937_64& g) {
    const uint32_t bits = uint32_t(g());
    switch (g() % 4) {
        case 0: return bits_to_float((bits & 0x807FFFFFu) | ((90u + uint32_t(g() % 60)) << 23));  // about the half range
        case 1: return bits_to_float(bits & 0x807FFFFFu);                                      // float subnormal
        default: return bits_to_float((bits & 0x807FFFFFu) | ((1u + uint32_t(g() % 253)) << 23));
    }
}

// Any double: every exponent from below the float subnormals to beyond FLT_MAX, exact
// floats (no rounding), +-0, +-inf and NaN now and then.
double any_double(std::mt19937_64& g) {
    const uint64_t bits = g();
    switch (g() % 8) {
        case 0: return double(bits_to_float(uint32_t(bits)));  // a float (or a float NaN / inf)
        case 1: return (bits & 1) ? -0.0 : 0.0;
        case 2: {
            // Where rounding decides: a finite float, or the midpoint to the next one up in
            // magnitude (FLT_MAX's: halfway to 2^128), moved by -2..2 double steps, either sign.
            uint32_t fb = uint32_t(bits) & 0x7FFFFFFFu;
            if ((fb >> 23) == 0xFFu) fb &= 0x7F7FFFFFu;  // inf / NaN: a finite exponent instead
            const float f = bits_to_float(fb);          // finite, >= 0
            const float up = bits_to_float(fb + 1u);     // +inf past FLT_MAX
            double x = ((bits >> 32) & 1) == 0 ? double(f)
                       : up == kInfinity       ? 0x1.ffffffp127
                                               : 0.5 * (double(f) + double(up));  // exact
            for (int k = int((bits >> 33) % 5) - 2; k != 0; k += k > 0 ? -1 : 1)
                x = std::nextafter(x, k > 0 ? HUGE_VAL : -HUGE_VAL);
            return ((bits >> 36) & 1) ? -x : x;
        }
        default: {
            const uint64_t e = 1023u - 160u + g() % 330u;  // 2^-160 .. 2^169
            double x;
            const uint64_t u = (bits & 0x800FFFFFFFFFFFFFull) | (e << 52);
            std::memcpy(&x, &u, sizeof x);
            return x;
        }
    }
}

// One line per differing result of a case: operation(operands) device D host H, in bits.
void report_fp16(const Fp16Case& k, const Fp16Out& dev, const Fp16Out& host, std::vector<std::string>& lines) {
    const std::string a = hex32(k.a), b = hex32(k.b), c = hex32(k.c);
    const std::string x = hex32(float_to_bits(k.x)), y = hex32(float_to_bits(k.y)), z = hex32(float_to_bits(k.z));
    uint64_t wb;
    std::memcpy(&wb, &k.w, sizeof wb);
    const std::string w = hex64(wb);
    const std::string reach_args = hex32(float_to_bits(k.o)) + ", " + hex32(float_to_bits(k.d)) + ", " +
                                   hex32(float_to_bits(k.t));
    const struct {
        const char* op;
        std::string args;
        uint32_t d, h;
    } rows[] = {
        {"h2_fma", a + ", " + b + ", " + c, dev.fma, host.fma},
        {"h2_min", a + ", " + b, dev.min, host.min},
        {"h2_le (bit 0 low, bit 1 high)", a + ", " + b, dev.le, host.le},
        {"vimax3_s16x2_relu", a + ", " + b + ", " + c, dev.vmax, host.vmax},
        {"vimin3_s16x2", a + ", " + b + ", " + c, dev.vmin, host.vmin},
        {"h2_pack", x + ", " + y, dev.pack, host.pack},
        {"h2_broadcast_rd", x, dev.rd, host.rd},
        {"h2_broadcast_ru", y, dev.ru, host.ru},
        {"fma_rd", x + ", " + y + ", " + z, float_to_bits(dev.fma_rd), float_to_bits(host.fma_rd)},
        {"fma_ru", x + ", " + y + ", " + z, float_to_bits(dev.fma_ru), float_to_bits(host.fma_ru)},
        {"sub_rd", x + ", " + z, float_to_bits(dev.sub_rd), float_to_bits(host.sub_rd)},
        {"add_ru", y + ", " + z, float_to_bits(dev.add_ru), float_to_bits(host.add_ru)},
        {"float_round_down", w, float_to_bits(dev.w_down), float_to_bits(host.w_down)},
        {"float_round_up", w, float_to_bits(dev.w_up), float_to_bits(host.w_up)},
        {"segment_reach", reach_args, float_to_bits(dev.reach), float_to_bits(host.reach)},
    };
    for (const auto& r : rows)
        if (r.d != r.h && lines.size() < FastNodeSelfCheck::kReported)
            lines.push_back(std::string(r.op) + "(" + r.args + "): device " + hex32(r.d) + ", host " + hex32(r.h));
}

}  // namespace

FastNodeSelfCheck run_fast_node_selfcheck(const CwbvhNode* nodes, size_t node_count, uint64_t seed, size_t fp16_cases,
                                          size_t node_pairs) {
    FastNodeSelfCheck r;
    int devices = 0;
    if (!ok(cudaGetDeviceCount(&devices), r)) return r;
    if (devices == 0) {
        r.error = "no CUDA device";
        return r;
    }
    std::mt19937_64 g(seed);

    // Operation cases.
    std::vector<Fp16Case> in(fp16_cases);
    for (Fp16Case& k : in) {
        k.a = uint32_t(any_half(g)) | (uint32_t(any_half(g)) << 16);
        k.b = uint32_t(any_half(g)) | (uint32_t(any_half(g)) << 16);
        k.c = uint32_t(any_half(g)) | (uint32_t(any_half(g)) << 16);
        k.x = any_float(g);
        k.y = any_float(g);
        switch (g() % 8) {
            case 0:
            case 1: k.z = -k.x * k.y; break;  // cancellation
            case 2:
                // Exact zeros, whose sign the rounding direction decides (-0 for RD, IEEE 754
                // 6.3): short significands make x*y a float, so x*y + (-x*y) = 0; x - x = 0.
                k.x = bits_to_float(float_to_bits(k.x) & 0xFFFF0000u);
                k.y = bits_to_float(float_to_bits(k.y) & 0xFFFF0000u);
                k.z = g() % 2 ? -k.x * k.y : k.x;
                break;
            case 3: {  // signed zero terms: +0 + -0 is -0 only under RD
                const float zeros[2] = {0.0f, -0.0f};
                if (g() % 2) k.x = zeros[g() % 2];
                k.z = zeros[g() % 2];
                break;
            }
            default: k.z = any_float(g);
        }
        k.w = any_double(g);
        k.o = any_float(g);
        k.d = any_float(g);  // a quarter subnormal: segment_reach's double path
        k.t = g() % 4 == 0 ? kInfinity : abs_f(any_float(g));
    }
    std::vector<Fp16Out> out(in.size());
    if (!in.empty()) {
        Buffer<Fp16Case> d_in;
        Buffer<Fp16Out> d_out;
        if (!to_device(in, d_in, r) || !ok(cudaMalloc(reinterpret_cast<void**>(&d_out.p), out.size() * sizeof(Fp16Out)), r))
            return r;
        fp16_kernel<<<unsigned((in.size() + 127) / 128), 128>>>(d_in.p, d_out.p, in.size());
        if (!ok(cudaGetLastError(), r) ||
            !ok(cudaMemcpy(out.data(), d_out.p, out.size() * sizeof(Fp16Out), cudaMemcpyDeviceToHost), r))
            return r;
    }
    r.fp16_cases = in.size();
    for (size_t i = 0; i < in.size(); ++i) {
        const Fp16Out want = run_case(in[i]);
        if (std::memcmp(&want, &out[i], sizeof want) != 0) {
            ++r.fp16_mismatches;
            report_fp16(in[i], out[i], want, r.differences);
        }
    }

    // (node, ray) pairs (fast_node_pairs.h).
    const FastNodePairs fp = make_fast_node_pairs(nodes, node_count, seed, node_pairs);
    const std::vector<CwbvhNode>& pn = fp.nodes;
    const std::vector<NodeRay>& pr = fp.node_rays;
    const NodeScale& sc = fp.scale;
    std::vector<NodeOut> got(pn.size());
    if (!pn.empty()) {
        Buffer<CwbvhNode> d_nodes;  // cudaMalloc: 256-byte aligned, so every node is 16-byte aligned
        Buffer<NodeRay> d_node_rays;
        Buffer<Ray> d_rays;
        Buffer<NodeOut> d_out;
        if (!to_device(pn, d_nodes, r) || !to_device(pr, d_node_rays, r) || !to_device(fp.rays, d_rays, r) ||
            !ok(cudaMalloc(reinterpret_cast<void**>(&d_out.p), got.size() * sizeof(NodeOut)), r))
            return r;
        node_kernel<<<unsigned((pn.size() + 127) / 128), 128>>>(d_nodes.p, d_node_rays.p, d_rays.p, sc, d_out.p,
                                                                 pn.size());
        if (!ok(cudaGetLastError(), r) ||
            !ok(cudaMemcpy(got.data(), d_out.p, got.size() * sizeof(NodeOut), cudaMemcpyDeviceToHost), r))
            return r;
    }
    // Code compiled for an architecture before sm_80 never enables the fast test
    // (enable_fast_node_test), so its NodeRay differs from the host's by design there. What
    // counts is the code the kernel runs (PTX of compute_75 JIT-compiled on a newer GPU is
    // still sm_75 code), not the device.
    cudaFuncAttributes fa{};
    if (!ok(cudaFuncGetAttributes(&fa, node_kernel), r)) return r;
    const bool fast_set_up = fa.ptxVersion >= 80;
    r.node_pairs = pn.size();
    for (size_t i = 0; i < pn.size(); ++i) {
        const NodeOut want = run_pair(load_node_words(&pn[i]), pr[i], fp.rays[i], sc);
        r.node_pairs_hit += want.fast != 0;
        const bool fast = got[i].fast == want.fast, ref = got[i].ref == want.ref,
                   set_up = !fast_set_up || std::memcmp(&got[i].set_up, &want.set_up, sizeof(NodeRay)) == 0;
        const std::string ray = fast && ref && set_up ? std::string() : "Ray " + hex_bytes(&fp.rays[i], sizeof(Ray));
        if (!ref) {
            ++r.reference_differences;
            if (r.reference_lines.size() < FastNodeSelfCheck::kReported)
                r.reference_lines.push_back("intersect_node reference(node " + hex_bytes(&pn[i], sizeof pn[i]) + ", " +
                                            ray + "): device " + hex32(got[i].ref) + ", host " + hex32(want.ref));
        }
        if (fast && set_up) continue;
        ++r.node_mismatches;
        if (r.differences.size() >= FastNodeSelfCheck::kReported) continue;
        if (!fast)
            r.differences.push_back("intersect_node_fast(node " + hex_bytes(&pn[i], sizeof pn[i]) + ", NodeRay " +
                                    hex_bytes(&pr[i], sizeof pr[i]) + ", tmax " + hex32(float_to_bits(fp.rays[i].tmax)) +
                                    ", frame_word " + hex32(sc.frame_word) + "): device " + hex32(got[i].fast) +
                                    ", host " + hex32(want.fast));
        if (!set_up)
            r.differences.push_back("make_node_ray + enable_fast_node_test(" + ray + ", frame_word " +
                                    hex32(sc.frame_word) + "): device NodeRay " +
                                    hex_bytes(&got[i].set_up, sizeof(NodeRay)) + ", host " +
                                    hex_bytes(&want.set_up, sizeof(NodeRay)));
    }
    r.ran = true;
    return r;
}

}  // namespace cwbvh

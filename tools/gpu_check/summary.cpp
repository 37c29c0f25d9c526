// cwbvh_gpu_check's geometric-mean summaries: see summary.h.
#include "summary.h"

#include <algorithm>
#include <cstdio>

namespace cwbvh::gpu_check {

double geomean(const std::vector<double>& v) {
    if (v.empty()) return 0.0;
    double s = 0;
    for (double x : v) s += std::log(x);
    return std::exp(s / double(v.size()));
}

const char* kind_name(int set) {
    static const char* const k[] = {"primary", "diffuse1", "diffuse2", "diffuse3", "diffuse4", "diffuse1-4"};
    static_assert(sizeof k / sizeof k[0] == kDiffuseAll + 1);
    return k[set];
}

std::string fmt(bool ok, const char* f, double v) {
    if (!ok) return "-";
    char b[32];
    std::snprintf(b, sizeof b, f, v);
    return b;
}

std::string describe(const FlatCompare& c, bool any) {
    char b[320];
    if (any)
        std::snprintf(b, sizeof b, "%llu disagreeing (hit/miss %llu; edge %llu)", (unsigned long long)c.disagreeing,
                      (unsigned long long)c.hit_vs_miss, (unsigned long long)c.edge);
    else
        std::snprintf(b, sizeof b,
                      "%llu disagreeing (hit/miss %llu, t %llu, source %llu); edge %llu, t within rounding %llu, "
                      "ties %llu, worst t %.2g rel",
                      (unsigned long long)c.disagreeing, (unsigned long long)c.hit_vs_miss,
                      (unsigned long long)c.t_far, (unsigned long long)c.source, (unsigned long long)c.edge,
                      (unsigned long long)c.t_rounding, (unsigned long long)c.ties, c.worst_rel);
    return b;
}

std::string describe(const QueryCompare& c) {
    char b[320];
    std::snprintf(b, sizeof b,
                  "%llu mismatches (a failure); %llu rays not bit for bit: %llu equal-t ties and %llu same triangle "
                  "within %u ulps (closest hit), %llu other valid any-hit records",
                  (unsigned long long)c.mismatches, (unsigned long long)c.not_bitwise, (unsigned long long)c.ties,
                  (unsigned long long)c.near, kKernelUlpBound,
                  (unsigned long long)(c.not_bitwise - c.mismatches - c.ties - c.near));
    return b;
}

namespace {

/// Closest-hit rows that pass `keep`, by scene (first-seen order), view and bounce.
struct RowIndex {
    std::vector<std::string> scenes;
    std::map<std::string, std::map<std::string, std::map<int, const Row*>>> by;
    template <class Keep>
    RowIndex(const std::vector<Row>& rows, Keep keep) {
        for (const Row& r : rows) {
            if (r.query != "closest" || !keep(r)) continue;
            if (!by.count(r.scene)) scenes.push_back(r.scene);
            by[r.scene][r.view][r.bounce] = &r;
        }
    }
};

/// The one reduction behind every summary (summary.h). `figures(rows, n)`: the view's
/// rows of the set's bounces (all present) and their rays; std::nullopt skips the view,
/// a figure <= 0 is absent for that view.
template <size_t N, class Figures>
SetMeans<N> set_means(const RowIndex& index, int set, Figures figures) {
    SetMeans<N> out;
    std::array<std::vector<double>, N> over_scenes;
    const int first = set == kDiffuseAll ? 1 : set, last = set == kDiffuseAll ? kBounces : set;
    for (const std::string& scene : index.scenes) {
        std::array<std::vector<double>, N> values;
        for (const auto& [view, bounces] : index.by.at(scene)) {
            std::vector<const Row*> rs;
            for (int b = first; b <= last; ++b) {
                const auto it = bounces.find(b);
                if (it == bounces.end()) break;
                rs.push_back(it->second);
            }
            if (rs.size() != size_t(last - first + 1)) continue;
            double n = 0;
            for (const Row* r : rs) n += double(r->rays);
            if (n == 0) continue;
            const std::optional<std::array<double, N>> f = figures(rs, n);
            if (!f) continue;
            if (n < double(kMinRaysForMeans)) {
                ++out.left_out;
                continue;
            }
            for (size_t i = 0; i < N; ++i)
                if ((*f)[i] > 0) values[i].push_back((*f)[i]);
        }
        for (size_t i = 0; i < N; ++i) {
            if (values[i].empty()) continue;
            over_scenes[i].push_back(geomean(values[i]));
            out.views[i][scene] = std::move(values[i]);
        }
    }
    for (size_t i = 0; i < N; ++i) out.mean[i] = Mean{over_scenes[i].size(), geomean(over_scenes[i])};
    return out;
}

/// The summed kernel time of `rs` for the result `pick` selects.
template <class Pick>
double sum_ms(const std::vector<const Row*>& rs, Pick pick) {
    double ms = 0;
    for (const Row* r : rs) ms += pick(*r).ms;
    return ms;
}

std::string mean_cell(const Mean& m, const char* f) { return fmt(m.scenes > 0, f, m.value); }

}  // namespace

SetMeans<kKernelFigures> kernel_means(const std::vector<Row>& rows, int set) {
    const RowIndex index(rows, [](const Row&) { return true; });
    using Figures = std::array<double, kKernelFigures>;
    return set_means<kKernelFigures>(index, set, [](const std::vector<const Row*>& rs, double n) -> std::optional<Figures> {
        double ms[kKernels] = {};
        bool have[kKernels];
        std::fill(have, have + kKernels, true);
        for (const Row* r : rs) {
            if (!r->k[kCw].ran) return std::nullopt;
            for (int k = 0; k < kKernels; ++k) {
                ms[k] += r->k[k].ms;
                have[k] = have[k] && r->k[k].ran;
            }
        }
        if (ms[kCw] <= 0) return std::nullopt;
        // A peer's time over the CWBVH kernel's, 0 where it did not run on every bounce.
        auto over = [&](int k) { return have[k] && ms[k] > 0 ? ms[k] / ms[kCw] : 0.0; };
        const bool ox = have[kOx] && ms[kOx] > 0;
        return Figures{n / (ms[kCw] * 1e3), over(kB2), ox ? n / (ms[kOx] * 1e3) : 0.0, over(kOx), over(kNd),
                       over(kRn)};
    });
}

SetMeans<3> two_level_means(const std::vector<Row>& rows, int set) {
    const RowIndex index(rows, [](const Row& r) { return r.tl.present && r.tl.k.ran && r.k[kCw].ran; });
    return set_means<3>(index, set, [](const std::vector<const Row*>& rs, double n) -> std::optional<std::array<double, 3>> {
        const double ms2 = sum_ms(rs, [](const Row& r) -> const KernelResult& { return r.tl.k; });
        const double ms1 = sum_ms(rs, [](const Row& r) -> const KernelResult& { return r.k[kCw]; });
        if (ms2 <= 0 || ms1 <= 0) return std::nullopt;
        return std::array<double, 3>{n / (ms2 * 1e3), n / (ms1 * 1e3), ms1 / ms2};
    });
}

SetMeans<3> inline_means(const std::vector<Row>& rows, int set) {
    const RowIndex index(rows, [](const Row& r) { return r.inl.ran && r.k[kCw].ran; });
    return set_means<3>(index, set, [](const std::vector<const Row*>& rs, double n) -> std::optional<std::array<double, 3>> {
        const double msi = sum_ms(rs, [](const Row& r) -> const KernelResult& { return r.inl; });
        const double msc = sum_ms(rs, [](const Row& r) -> const KernelResult& { return r.k[kCw]; });
        if (msi <= 0 || msc <= 0) return std::nullopt;
        return std::array<double, 3>{n / (msi * 1e3), n / (msc * 1e3), msc / msi};
    });
}

SetMeans<2> postpone_means(const std::vector<Row>& rows, int set, uint32_t percent) {
    const RowIndex index(rows, [percent](const Row& r) {
        const KernelResult* k = r.at_postpone(percent);
        return k && k->ran && r.k[kCw].ran;
    });
    return set_means<2>(index, set, [percent](const std::vector<const Row*>& rs, double n) -> std::optional<std::array<double, 2>> {
        const double msp = sum_ms(rs, [percent](const Row& r) -> const KernelResult& { return *r.at_postpone(percent); });
        const double msc = sum_ms(rs, [](const Row& r) -> const KernelResult& { return r.k[kCw]; });
        if (msp <= 0 || msc <= 0) return std::nullopt;
        return std::array<double, 2>{n / (msp * 1e3), msc / msp};
    });
}

void print_summary(const std::vector<Row>& rows) {
    std::printf("\nGeometric mean over %zu scene(s) (each scene: geometric mean over its views), closest hit; "
                "ray sets of fewer than %zu rays left out:\n",
                RowIndex(rows, [](const Row&) { return true; }).scenes.size(), kMinRaysForMeans);
    std::printf("%-14s %8s %14s %10s %13s %11s %13s %13s %13s\n", "rays", "scenes", "CWBVH Mrays/s", "CWBVH/BVH2",
                "OptiX Mrays/s", "CWBVH/OptiX", "CWBVH/nodefer", "CWBVH/refnode", "sets left out");
    for (int set = 0; set <= kDiffuseAll; ++set) {
        const SetMeans<kKernelFigures> m = kernel_means(rows, set);
        std::printf("%-14s %8zu %14s %10s %13s %11s %13s %13s %13zu\n", kind_name(set), m.mean[kCwbvhMrays].scenes,
                    mean_cell(m.mean[kCwbvhMrays], "%.1f").c_str(), mean_cell(m.mean[kOverBvh2], "%.2fx").c_str(),
                    mean_cell(m.mean[kOptixMrays], "%.1f").c_str(), mean_cell(m.mean[kOverOptix], "%.2fx").c_str(),
                    mean_cell(m.mean[kOverNoDefer], "%.2fx").c_str(), mean_cell(m.mean[kOverRefNode], "%.2fx").c_str(),
                    m.left_out);
    }
    std::printf("CWBVH/nodefer, CWBVH/refnode: the CWBVH kernel over itself without deferred hit distances "
                "(TraceOptions::defer_hits = false) and with the reference node test for every ray (fast_node_test = "
                "false), the same rays and hits; > 1: the part pays; 1.00x before sm_80, which has neither\n");
}

void print_two_level_summary(const std::vector<Row>& rows) {
    FlatCompare flat_all;
    QueryCompare cmp;
    bool present = false, gpu = false;
    for (const Row& r : rows) {
        if (!r.tl.present) continue;
        present = true;
        gpu = gpu || r.tl.k.ran;
        flat_all += r.tl.flat;
        cmp += r.tl.cmp;
    }
    if (!present) return;
    if (!gpu) {
        std::printf("\ntwo-level vs flattened hits (CPU references), all rays and queries: %s\n",
                    describe(flat_all, false).c_str());
        return;
    }
    std::printf("\nTwo-level / flattened CWBVH kernel, geometric mean over %zu scene(s) (each scene: geometric mean "
                "over its views), closest hit, same rays; target >= 0.80x (issue 19):\n",
                RowIndex(rows, [](const Row& r) { return r.tl.present && r.tl.k.ran && r.k[kCw].ran; }).scenes.size());
    std::printf("%-14s %8s %15s %14s %13s %13s\n", "rays", "scenes", "2-level Mrays/s", "flat CW Mr/s",
                "2-level/flat", "sets left out");
    std::map<std::string, std::vector<double>> all;  // scene -> every in-means ratio of the single bounces
    for (int set = 0; set <= kDiffuseAll; ++set) {
        const SetMeans<3> m = two_level_means(rows, set);
        if (set < kDiffuseAll)
            for (const auto& [scene, v] : m.views[kTwoOverFlat]) all[scene].insert(all[scene].end(), v.begin(), v.end());
        std::printf("%-14s %8zu %15s %14s %13s %13zu\n", kind_name(set), m.mean[kTwoLevelMrays].scenes,
                    mean_cell(m.mean[kTwoLevelMrays], "%.1f").c_str(), mean_cell(m.mean[kFlatMrays], "%.1f").c_str(),
                    mean_cell(m.mean[kTwoOverFlat], "%.2fx").c_str(), m.left_out);
    }
    std::vector<double> per_scene;
    for (const auto& [scene, v] : all) per_scene.push_back(geomean(v));
    std::printf("two-level / flattened over every ray set in the means (primary, diffuse 1-4; each scene weighted "
                "equally): %s (target >= 0.80x)\n",
                fmt(!per_scene.empty(), "%.2fx", geomean(per_scene)).c_str());
    std::printf("two-level vs flattened hits (GPU kernels), all rays and queries: %s\n",
                describe(flat_all, false).c_str());
    std::printf("two-level kernel vs trace_two_level_cpu, all rays and queries: %s\n", describe(cmp).c_str());
    // The inline query on the same files (one thread per ray, no persistent warps): which of
    // the two schedules suits two-level scenes, closest hit, every single ray set in the means.
    QueryCompare inl_cmp;
    bool inl_ran = false;
    for (const Row& r : rows) {
        if (!r.tl.present || !r.tl.inl.ran) continue;
        inl_ran = true;
        inl_cmp += r.tl.inl_cmp;
    }
    if (inl_ran) {
        size_t scenes = 0;
        const double ratio = two_level_inline_ratio(rows, &scenes);
        std::printf("inline query on the two-level files / two-level kernel, closest hit, every ray set in the means "
                    "(each scene weighted equally, %zu scene(s)): %s; vs trace_two_level_cpu: %s\n",
                    scenes, fmt(scenes > 0, "%.2fx", ratio).c_str(), describe(inl_cmp).c_str());
    }
}

double two_level_inline_ratio(const std::vector<Row>& rows, size_t* scenes) {
    std::map<std::string, std::vector<double>> by_scene;
    for (const Row& r : rows)
        if (r.tl.present && r.tl.inl.ran && r.tl.k.ran && r.query == "closest" && r.in_means() && r.tl.k.ms > 0 &&
            r.tl.inl.ms > 0)
            by_scene[r.scene].push_back(r.tl.k.ms / r.tl.inl.ms);  // the same rays: speed ratio
    std::vector<double> per;
    for (const auto& [scene, v] : by_scene) per.push_back(geomean(v));
    if (scenes) *scenes = per.size();
    return geomean(per);
}

void print_inline_summary(const std::vector<Row>& rows) {
    QueryCompare cmp;
    uint64_t not_ok = 0;
    bool ran = false;
    for (const Row& r : rows) {
        if (!r.inl.ran) continue;
        ran = true;
        cmp += r.inl_cmp;
        not_ok += r.inl.overflows;
    }
    if (!ran) return;
    std::printf("\nInline query (cwbvh/kernels/query.h: one thread per ray, its own stack in local memory, "
                "compiled for single-level scenes) / CWBVH kernel, geometric mean over %zu scene(s), closest hit:\n",
                RowIndex(rows, [](const Row& r) { return r.inl.ran && r.k[kCw].ran; }).scenes.size());
    std::printf("%-14s %8s %15s %14s %13s %13s\n", "rays", "scenes", "inline Mrays/s", "CWBVH Mrays/s",
                "inline/CWBVH", "sets left out");
    for (int set = 0; set <= kDiffuseAll; ++set) {
        const SetMeans<3> m = inline_means(rows, set);
        std::printf("%-14s %8zu %15s %14s %13s %13zu\n", kind_name(set), m.mean[kInlineMrays].scenes,
                    mean_cell(m.mean[kInlineMrays], "%.1f").c_str(),
                    mean_cell(m.mean[kInlineCwbvhMrays], "%.1f").c_str(),
                    mean_cell(m.mean[kInlineOverCwbvh], "%.2fx").c_str(), m.left_out);
    }
    std::printf("inline query vs the CPU reference, all rays and queries: %s; %llu overflows or bad indices (a "
                "failure)\n",
                describe(cmp).c_str(), (unsigned long long)not_ok);
}

void print_postpone_summary(const std::vector<Row>& rows) {
    std::vector<uint32_t> percents;
    for (const Row& r : rows)
        for (const auto& [pc, k] : r.postpone)
            if (k.ran && std::find(percents.begin(), percents.end(), pc) == percents.end()) percents.push_back(pc);
    if (percents.empty()) return;
    std::sort(percents.begin(), percents.end());
    std::printf("\nTriangle postponing threshold (TraceOptions::postpone_percent), CWBVH kernel, closest hit: speed at "
                "P %% over speed at the default %u %%, geometric mean over scenes (> 1: P is faster):\n",
                kDefaultPostponePercent);
    std::printf("%-14s", "rays");
    for (uint32_t pc : percents) std::printf(" %8u %%", pc);
    std::printf("\n");
    for (int set = 0; set <= kDiffuseAll; ++set) {
        std::printf("%-14s", kind_name(set));
        for (uint32_t pc : percents)
            std::printf(" %10s", mean_cell(postpone_means(rows, set, pc).mean[kPostponeOverDefault], "%.3fx").c_str());
        std::printf("\n");
    }
}

}  // namespace cwbvh::gpu_check

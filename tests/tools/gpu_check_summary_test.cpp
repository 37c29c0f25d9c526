// The geometric means of cwbvh_gpu_check's summary tables (tools/gpu_check/summary.h),
// on made-up rows: these are issue 18's figures, and the GPU machine that fills them has
// no GoogleTest. Each test takes one rule of summary.h's header and its bad case:
// scenes weighted equally whatever their number of views, small ray sets left out (and
// counted), diffuse 1-4 as summed rays over summed times, a view missing a bounce or a
// kernel skipped, peers that did not run absent from their figure only, any-hit rows
// ignored, and the ratios' direction (ours over the peer's time: > 1 is faster).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "summary.h"

namespace cwbvh::gpu_check {
namespace {

constexpr size_t kBig = 4000000;  // rays of a set in the means

/// One closest-hit row; a time <= 0: that kernel did not run.
Row row(const std::string& scene, const std::string& view, int bounce, size_t rays, double cw_ms, double b2_ms = -1,
        double ox_ms = -1, double nd_ms = -1, double rn_ms = -1) {
    Row r;
    r.scene = scene;
    r.view = view;
    r.query = "closest";
    r.bounce = bounce;
    r.rays = rays;
    const double ms[kKernels] = {cw_ms, b2_ms, ox_ms, nd_ms, rn_ms};
    for (int k = 0; k < kKernels; ++k) {
        r.k[k].ran = ms[k] > 0;
        r.k[k].ms = ms[k] > 0 ? ms[k] : 0;
        r.k[k].mrays = ms[k] > 0 ? double(rays) / (ms[k] * 1e3) : 0;
    }
    return r;
}

double mrays(size_t rays, double ms) { return double(rays) / (ms * 1e3); }

/// A closest-hit row of scene alpha (CWBVH 2 ms) with an instanced file whose two-level
/// kernel took `tl_ms`.
Row two_level_row(const std::string& view, double tl_ms) {
    Row r = row("alpha", view, 0, kBig, 2.0);
    r.tl.present = true;
    r.tl.k.ran = true;
    r.tl.k.ms = tl_ms;
    return r;
}

TEST(GpuCheckSummary, ScenesWeighEquallyWhateverTheirViews) {
    // alpha: two views at 1 ms and 4 ms (its mean: 2 ms); beta: one view at 8 ms.
    // Per view then per scene: sqrt(M(2 ms) * M(8 ms)); pooling the three views would give
    // the cube root of M(1) M(4) M(8) instead.
    const std::vector<Row> rows = {row("alpha", "a", 0, kBig, 1.0, 2.0), row("alpha", "b", 0, kBig, 4.0, 4.0),
                                   row("beta", "a", 0, kBig, 8.0, 32.0)};
    const SetMeans<kKernelFigures> m = kernel_means(rows, 0);
    EXPECT_EQ(m.mean[kCwbvhMrays].scenes, 2u);
    EXPECT_NEAR(m.mean[kCwbvhMrays].value, std::sqrt(mrays(kBig, 2.0) * mrays(kBig, 8.0)), 1e-9);
    // CWBVH/BVH2 = BVH2 time over CWBVH time: alpha sqrt(2 * 1) , beta 4.
    EXPECT_NEAR(m.mean[kOverBvh2].value, std::sqrt(std::sqrt(2.0) * 4.0), 1e-12);
    EXPECT_EQ(m.mean[kOptixMrays].scenes, 0u);  // OptiX never ran: absent, not zero
    EXPECT_EQ(m.left_out, 0u);
    ASSERT_EQ(m.views[kCwbvhMrays].at("alpha").size(), 2u);
}

TEST(GpuCheckSummary, SmallRaySetsAreCountedAndLeftOut) {
    const std::vector<Row> rows = {row("alpha", "a", 1, kBig, 2.0, 4.0), row("alpha", "b", 1, kMinRaysForMeans - 1, 1.0, 9.0),
                                   row("beta", "a", 1, 999, 1.0, 9.0)};
    const SetMeans<kKernelFigures> m = kernel_means(rows, 1);
    EXPECT_EQ(m.left_out, 2u);
    EXPECT_EQ(m.mean[kCwbvhMrays].scenes, 1u);  // beta's only view is left out
    EXPECT_NEAR(m.mean[kCwbvhMrays].value, mrays(kBig, 2.0), 1e-9);
    EXPECT_NEAR(m.mean[kOverBvh2].value, 2.0, 1e-12);
    // A set of exactly the threshold is in.
    const SetMeans<kKernelFigures> edge = kernel_means({row("alpha", "a", 1, kMinRaysForMeans, 1.0)}, 1);
    EXPECT_EQ(edge.left_out, 0u);
    EXPECT_EQ(edge.mean[kCwbvhMrays].scenes, 1u);
}

TEST(GpuCheckSummary, DiffuseTogetherSumsRaysAndTimesPerView) {
    // Four bounces of 300k rays each: each alone is left out, together they are in
    // (1.2M rays), as their summed rays over their summed times, not a mean of speeds.
    std::vector<Row> rows;
    const double cw[] = {1.0, 2.0, 3.0, 4.0}, b2[] = {2.0, 2.0, 2.0, 14.0};
    for (int b = 1; b <= kBounces; ++b) rows.push_back(row("alpha", "a", b, 300000, cw[b - 1], b2[b - 1]));
    // A second view without bounce 3: skipped for diffuse 1-4, and not counted as left out.
    for (int b : {1, 2, 4}) rows.push_back(row("alpha", "b", b, kBig, 1.0, 1.0));
    const SetMeans<kKernelFigures> all = kernel_means(rows, kDiffuseAll);
    EXPECT_EQ(all.left_out, 0u);
    ASSERT_EQ(all.mean[kCwbvhMrays].scenes, 1u);
    EXPECT_NEAR(all.mean[kCwbvhMrays].value, mrays(1200000, 10.0), 1e-9);
    EXPECT_NEAR(all.mean[kOverBvh2].value, 20.0 / 10.0, 1e-12);
    EXPECT_EQ(kernel_means(rows, 2).left_out, 1u);  // view a's bounce 2 alone: 300k rays
    EXPECT_STREQ(kind_name(kDiffuseAll), "diffuse1-4");
    EXPECT_STREQ(kind_name(0), "primary");
}

TEST(GpuCheckSummary, APeerThatDidNotRunIsAbsentFromItsFiguresOnly) {
    std::vector<Row> rows;
    // alpha: OptiX ran; beta: no OptiX, and BVH2 missing on one bounce (so no ratio for
    // beta's diffuse 1-4); gamma: the CWBVH kernel did not run: no figure at all.
    for (int b = 0; b <= kBounces; ++b) {
        rows.push_back(row("alpha", "a", b, kBig, 1.0, 3.0, 2.0));
        rows.push_back(row("beta", "a", b, kBig, 1.0, b == 2 ? -1 : 3.0));
        rows.push_back(row("gamma", "a", b, kBig, -1, 3.0, 2.0));
    }
    const SetMeans<kKernelFigures> p = kernel_means(rows, 0);
    EXPECT_EQ(p.mean[kCwbvhMrays].scenes, 2u);
    EXPECT_EQ(p.mean[kOverBvh2].scenes, 2u);
    EXPECT_EQ(p.mean[kOptixMrays].scenes, 1u);
    EXPECT_NEAR(p.mean[kOverOptix].value, 2.0, 1e-12);
    EXPECT_NEAR(p.mean[kOptixMrays].value, mrays(kBig, 2.0), 1e-9);
    const SetMeans<kKernelFigures> d = kernel_means(rows, kDiffuseAll);
    EXPECT_EQ(d.mean[kCwbvhMrays].scenes, 2u);
    EXPECT_EQ(d.mean[kOverBvh2].scenes, 1u);  // beta's BVH2 missed bounce 2
    EXPECT_NEAR(d.mean[kOverBvh2].value, 3.0, 1e-12);
}

TEST(GpuCheckSummary, TheAbsGainsAreTheKernelWithoutThePartsTimeOverTheKernels) {
    // No deferral: alpha 1.5x and 1.0x the production kernel's time on its two views (scene
    // mean sqrt(1.5)); beta 0.8x (the deferral slower); gamma not run: absent. Reference node
    // test: alpha 2.0x on view a only (b did not run it), gamma 1.25x.
    const std::vector<Row> rows = {row("alpha", "a", 1, kBig, 2.0, 4.0, -1, 3.0, 4.0),
                                   row("alpha", "b", 1, kBig, 2.0, 4.0, -1, 2.0),
                                   row("beta", "a", 1, kBig, 5.0, 4.0, -1, 4.0),
                                   row("gamma", "a", 1, kBig, 1.0, 4.0, -1, -1, 1.25)};
    const SetMeans<kKernelFigures> m = kernel_means(rows, 1);
    EXPECT_EQ(m.mean[kOverNoDefer].scenes, 2u);
    EXPECT_NEAR(m.mean[kOverNoDefer].value, std::sqrt(std::sqrt(1.5) * 0.8), 1e-12);
    EXPECT_EQ(m.mean[kOverRefNode].scenes, 2u);
    EXPECT_NEAR(m.mean[kOverRefNode].value, std::sqrt(2.0 * 1.25), 1e-12);
    EXPECT_EQ(m.mean[kCwbvhMrays].scenes, 3u);  // the other figures do not need them
    EXPECT_EQ(m.mean[kOverOptix].scenes, 0u);
    EXPECT_NEAR(rows[0].ratio(kNd), 1.5, 1e-12);  // per row: > 1 where the part makes it faster
    EXPECT_NEAR(rows[0].ratio(kRn), 2.0, 1e-12);
}

TEST(GpuCheckSummary, APostponingThresholdIsMeasuredAgainstTheDefaultOnTheSameViews) {
    // alpha: at 35 % its two views take 1.0 and 4.0 ms against the default's 2.0 and 2.0 (2x
    // and 0.5x: scene mean 1); beta: 35 % not run, 50 % 0.8x; a small set is left out.
    std::vector<Row> rows = {row("alpha", "a", 0, kBig, 2.0), row("alpha", "b", 0, kBig, 2.0),
                             row("beta", "a", 0, kBig, 4.0), row("beta", "b", 0, 999, 1.0)};
    auto at = [](double ms) {
        KernelResult k;
        k.ran = true;
        k.ms = ms;
        return k;
    };
    rows[0].postpone = {{35u, at(1.0)}, {50u, at(2.0)}};
    rows[1].postpone = {{35u, at(4.0)}};
    rows[2].postpone = {{50u, at(5.0)}};
    rows[3].postpone = {{35u, at(0.1)}};
    const SetMeans<2> p35 = postpone_means(rows, 0, 35);
    EXPECT_EQ(p35.mean[kPostponeOverDefault].scenes, 1u);
    EXPECT_NEAR(p35.mean[kPostponeOverDefault].value, 1.0, 1e-12);
    EXPECT_NEAR(p35.mean[kPostponeMrays].value, mrays(kBig, 2.0), 1e-9);  // sqrt(M(1) M(4))
    EXPECT_EQ(p35.left_out, 1u);
    const SetMeans<2> p50 = postpone_means(rows, 0, 50);
    EXPECT_EQ(p50.mean[kPostponeOverDefault].scenes, 2u);
    EXPECT_NEAR(p50.mean[kPostponeOverDefault].value, std::sqrt(1.0 * 0.8), 1e-12);
    EXPECT_EQ(postpone_means(rows, 0, 10).mean[kPostponeOverDefault].scenes, 0u);
    EXPECT_EQ(rows[0].at_postpone(50)->ms, 2.0);
    EXPECT_EQ(rows[1].at_postpone(50), nullptr);
}

TEST(GpuCheckSummary, AnyHitRowsAreNotInTheMeans) {
    Row any = row("alpha", "a", 0, kBig, 100.0, 1.0);
    any.query = "any";
    const SetMeans<kKernelFigures> m = kernel_means({row("alpha", "a", 0, kBig, 1.0, 2.0), any}, 0);
    EXPECT_NEAR(m.mean[kOverBvh2].value, 2.0, 1e-12);
    EXPECT_EQ(kernel_means({any}, 0).mean[kCwbvhMrays].scenes, 0u);
}

TEST(GpuCheckSummary, TwoLevelAndInlineRatiosAreOverTheFlattenedCwbvhKernel) {
    std::vector<Row> rows;
    for (int v = 0; v < 2; ++v) {
        Row r = two_level_row(v ? "b" : "a", v ? 4.0 : 1.0);  // two-level / flat: 2 and 0.5 -> 1
        r.inl.ran = true;
        r.inl.ms = v ? 8.0 : 2.0;  // inline / CWBVH: 0.25 and 1 -> 0.5
        rows.push_back(r);
    }
    Row no_two = row("beta", "a", 0, kBig, 1.0);  // no instanced file: not in the two-level means
    no_two.inl.ran = true;
    no_two.inl.ms = 1.0;
    rows.push_back(no_two);
    const SetMeans<3> t = two_level_means(rows, 0);
    EXPECT_EQ(t.mean[kTwoOverFlat].scenes, 1u);
    EXPECT_NEAR(t.mean[kTwoOverFlat].value, 1.0, 1e-12);
    EXPECT_NEAR(t.mean[kFlatMrays].value, mrays(kBig, 2.0), 1e-9);
    EXPECT_NEAR(t.mean[kTwoLevelMrays].value, mrays(kBig, 2.0), 1e-9);  // sqrt(M(1) M(4)) = M(2)
    const SetMeans<3> i = inline_means(rows, 0);
    EXPECT_EQ(i.mean[kInlineOverCwbvh].scenes, 2u);
    EXPECT_NEAR(i.mean[kInlineOverCwbvh].value, std::sqrt(0.5 * 1.0), 1e-12);
    // A two-level kernel that did not run leaves the view out of the two-level means.
    rows[1].tl.k.ran = false;
    EXPECT_NEAR(two_level_means(rows, 0).mean[kTwoOverFlat].value, 2.0, 1e-12);
}

TEST(GpuCheckSummary, TheInlineQueryOnTwoLevelFilesIsOverTheTwoLevelKernel) {
    std::vector<Row> rows;
    for (int v = 0; v < 2; ++v) {
        Row r = two_level_row(v ? "b" : "a", 4.0);
        r.tl.inl.ran = true;
        r.tl.inl.ms = v ? 1.0 : 4.0;  // inline / two-level kernel: 4 and 1 -> 2
        rows.push_back(r);
    }
    Row small = rows[0];  // fewer rays than the means take: left out
    small.view = "c";
    small.rays = 1000;
    small.tl.inl.ms = 400.0;
    rows.push_back(small);
    Row any = rows[0];  // any hit: left out
    any.query = "any";
    any.tl.inl.ms = 400.0;
    rows.push_back(any);
    size_t scenes = 9;
    EXPECT_NEAR(two_level_inline_ratio(rows, &scenes), 2.0, 1e-12);
    EXPECT_EQ(scenes, 1u);
    for (Row& r : rows) r.tl.inl.ran = false;
    EXPECT_EQ(two_level_inline_ratio(rows, &scenes), 0.0);
    EXPECT_EQ(scenes, 0u);
}

TEST(GpuCheckSummary, GeomeanOfNothingIsZero) {
    EXPECT_EQ(geomean({}), 0.0);
    EXPECT_NEAR(geomean({2.0, 8.0}), 4.0, 1e-12);
    EXPECT_EQ(fmt(false, "%.1f", 3.0), "-");
    EXPECT_EQ(fmt(true, "%.2fx", 1.5), "1.50x");
}

}  // namespace
}  // namespace cwbvh::gpu_check

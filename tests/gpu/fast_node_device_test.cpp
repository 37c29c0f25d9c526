// On a GPU: the fast node test and fp16.h's operations give the bits of their host
// emulation (fast_node_selfcheck.h). Skips without a CUDA device.
#include <gtest/gtest.h>

#include "cwbvh/compiler/synthetic.h"
#include "cwbvh/kernels/fast_node_selfcheck.h"
#include "cwbvh/kernels/gpu_trace.h"

namespace cwbvh {
namespace {

TEST(FastNodeDevice, MatchesTheHostEmulationBitForBit) {
    std::string why;
    if (!gpu_available(why)) GTEST_SKIP() << "SKIPPED: no CUDA device (" << why << ")";
    SyntheticOptions so;
    so.triangles = 20000;
    const SceneData sd = make_synthetic_scene(so);
    const FastNodeSelfCheck r = run_fast_node_selfcheck(sd.nodes.data(), sd.nodes.size());
    ASSERT_TRUE(r.ran) << r.error;
    for (const std::string& d : r.differences) ADD_FAILURE() << "differs: " << d;
    EXPECT_EQ(r.fp16_mismatches, 0u) << "of " << r.fp16_cases;
    EXPECT_EQ(r.node_mismatches, 0u) << "of " << r.node_pairs;
    EXPECT_TRUE(r.reference_within_contraction()) << r.reference_differences << " of " << r.node_pairs;
    EXPECT_GT(r.node_pairs, 100000u);
    EXPECT_GT(r.node_pairs_hit, r.node_pairs / 20);  // the rays reach children
}

}  // namespace
}  // namespace cwbvh

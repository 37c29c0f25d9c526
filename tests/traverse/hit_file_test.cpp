// Hit file 1.1 (spec/rays.md): 20-byte InstanceHit records for two-level scenes,
// next to the unchanged 1.0 layout (16-byte Hit), which is still what a hit file
// without instances is written as, byte for byte.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray_file.h"

namespace cwbvh {
namespace {

std::string temp_path(const char* name) { return ::testing::TempDir() + "cwbvh_hit_file_" + name; }

std::vector<uint8_t> slurp(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return std::vector<uint8_t>(std::istreambuf_iterator<char>(f), {});
}

void spit(const std::string& path, const std::vector<uint8_t>& bytes) {
    std::ofstream f(path, std::ios::binary);
    f.write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

const std::vector<Hit> kHits = {{1.5f, 0.25f, 0.5f, 7u}, make_miss(), {3.0f, 0.0f, 1.0f, 0u}};
const std::vector<uint32_t> kInstances = {12u, kInvalidIndex, 0u};

TEST(HitFile, InstanceRecordsRoundTrip) {
    const std::string path = temp_path("inst.hits");
    ASSERT_TRUE(write_hit_file(path, kHits.data(), kInstances.data(), kHits.size(), kHitFileWatertight).ok());
    const std::vector<uint8_t> bytes = slurp(path);
    ASSERT_EQ(bytes.size(), 32u + 20u * kHits.size());
    RayFileHeader h;
    std::memcpy(&h, bytes.data(), sizeof h);
    EXPECT_EQ(h.version_major, 1);
    EXPECT_EQ(h.version_minor, 1);
    EXPECT_EQ(h.record_size, 20u);
    // Record 0 at offset 32: t, u, v, prim, instance.
    InstanceHit r0;
    std::memcpy(&r0, bytes.data() + 32, sizeof r0);
    EXPECT_EQ(r0.t, 1.5f);
    EXPECT_EQ(r0.prim, 7u);
    EXPECT_EQ(r0.instance, 12u);

    std::vector<Hit> hits;
    std::vector<uint32_t> inst;
    uint32_t flags = 0;
    ASSERT_TRUE(read_hit_file(path, hits, inst, flags).ok());
    EXPECT_EQ(flags, uint32_t(kHitFileWatertight));
    ASSERT_EQ(hits.size(), kHits.size());
    ASSERT_EQ(inst, kInstances);
    for (size_t i = 0; i < hits.size(); ++i) EXPECT_EQ(std::memcmp(&hits[i], &kHits[i], sizeof(Hit)), 0);

    // The 16-byte reader refuses it by name instead of dropping the instances.
    const Result r = read_hit_file(path, hits, flags);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message.find("instance"), std::string::npos) << r.message;
}

TEST(HitFile, OldLayoutUnchangedAndReadable) {
    const std::string a = temp_path("a.hits"), b = temp_path("b.hits");
    ASSERT_TRUE(write_hit_file(a, kHits.data(), kHits.size(), kHitFileAnyHit).ok());
    ASSERT_TRUE(write_hit_file(b, kHits.data(), nullptr, kHits.size(), kHitFileAnyHit).ok());
    const std::vector<uint8_t> bytes = slurp(a);
    EXPECT_EQ(bytes, slurp(b));  // no instances: the 1.0 file
    ASSERT_EQ(bytes.size(), 32u + 16u * kHits.size());
    RayFileHeader h;
    std::memcpy(&h, bytes.data(), sizeof h);
    EXPECT_EQ(h.version_minor, 0);
    EXPECT_EQ(h.record_size, 16u);
    std::vector<Hit> hits;
    std::vector<uint32_t> inst = {5u};
    uint32_t flags = 0;
    ASSERT_TRUE(read_hit_file(a, hits, inst, flags).ok());
    EXPECT_TRUE(inst.empty());
    ASSERT_EQ(hits.size(), kHits.size());
    EXPECT_EQ(hits[0].prim, 7u);
}

TEST(HitFile, InstanceLayoutNeedsMinorOneAndExactSize) {
    const std::string path = temp_path("bad.hits");
    ASSERT_TRUE(write_hit_file(path, kHits.data(), kInstances.data(), kHits.size(), 0).ok());
    std::vector<uint8_t> bytes = slurp(path);
    std::vector<Hit> hits;
    std::vector<uint32_t> inst;
    uint32_t flags = 0;
    // 20-byte records stamped 1.0: a 1.0 file has 16-byte records only.
    bytes[10] = 0;
    spit(path, bytes);
    Result r = read_hit_file(path, hits, inst, flags);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.message.find("record_size 20"), std::string::npos) << r.message;
    // A newer minor keeps the layout readable.
    bytes[10] = 7;
    spit(path, bytes);
    EXPECT_TRUE(read_hit_file(path, hits, inst, flags).ok());
    // Truncated by one byte, and one record size that is neither 16 nor 20.
    bytes.pop_back();
    spit(path, bytes);
    EXPECT_FALSE(read_hit_file(path, hits, inst, flags).ok());
    bytes.push_back(0);
    bytes[12] = 24;
    spit(path, bytes);
    EXPECT_FALSE(read_hit_file(path, hits, inst, flags).ok());
    // A ray file never takes the 20-byte layout.
    uint64_t count = 0;
    uint32_t rs = 0;
    RayFileHeader rh{};
    std::memcpy(rh.magic, kRayFileMagic, 8);
    rh.version_major = 1;
    rh.version_minor = 1;
    rh.record_size = 20;
    rh.count = 0;
    EXPECT_FALSE(parse_ray_file_header(reinterpret_cast<const uint8_t*>(&rh), sizeof rh, false, count, flags, rs).ok());
    std::remove(path.c_str());
}

}  // namespace
}  // namespace cwbvh

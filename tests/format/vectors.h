// The test vectors of spec/vectors/: how each file is made. The committed
// files must equal these bytes, and decode as their .json states
// (vectors_test.cpp). Regenerate with CWBVH_UPDATE_VECTORS=1.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace cwbvh::test {

struct Vector {
    std::string name;            ///< file stem in spec/vectors/
    std::vector<uint8_t> bytes;  ///< the .cwbvh file
};

std::vector<Vector> make_vectors();

}  // namespace cwbvh::test

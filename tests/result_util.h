// Test helper: a library Result as the bool the gtest assertions read, with its
// message copied out for the `<< message` that explains a failure.
#pragma once

#include <string>

#include "cwbvh/format/status.h"

namespace cwbvh::test {

inline bool ok(const Result& r, std::string& message) {
    message = r.message;
    return r.ok();
}

}  // namespace cwbvh::test

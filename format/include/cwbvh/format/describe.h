// Human- and machine-readable descriptions of a validated file: what
// `cwbvh info` prints, and the decoded contents the test vectors state.
#pragma once

#include <string>

#include "cwbvh/format/validate.h"

namespace cwbvh {

/// Version, sections (offset, size, counts, checksum), bounds, build info.
std::string describe_text(const FileLayout& layout);

/// The same as JSON. With decode_content, also every node (decoded child
/// boxes, per-slot kind/child/triangles), triangle record, PMAP entry and
/// BVH2 node: meant for tiny files such as spec/vectors/.
std::string describe_json(const FileLayout& layout, bool decode_content = false);

}  // namespace cwbvh

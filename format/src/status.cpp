#include "cwbvh/format/status.h"

namespace cwbvh {

const char* status_name(Status s) {
    switch (s) {
        case Status::kOk: return "ok";
        case Status::kIoError: return "I/O error";
        case Status::kNotCwbvh: return "not a cwbvh file";
        case Status::kUnsupportedVersion: return "unsupported version";
        case Status::kUnsupported: return "unsupported";
        case Status::kCorrupt: return "corrupt";
        case Status::kChecksumMismatch: return "checksum mismatch";
        case Status::kInvalidArgument: return "invalid argument";
        case Status::kBadInput: return "bad input";
        case Status::kInternal: return "internal error";
        case Status::kDeviceError: return "device error";
    }
    return "unknown status";
}

Status status_for_rule(uint32_t rule_id) {
    if (rule_id >= 1000 && rule_id < 2000) return Status::kIoError;
    switch (rule_id) {
        case rule::kBadMagic: return Status::kNotCwbvh;
        case rule::kUnsupportedMajor: return Status::kUnsupportedVersion;
        case rule::kUnknownRequiredSection: return Status::kUnsupported;
        case rule::kMetaChecksum:
        case rule::kSectionChecksum: return Status::kChecksumMismatch;
        default: return Status::kCorrupt;
    }
}

Result fail(uint32_t rule_id, std::string message) {
    return Result::fail(status_for_rule(rule_id), rule_id, std::move(message));
}

std::string Result::describe() const {
    if (ok()) return "ok";
    // Rule 0: not a numbered rule of the spec (compiler input, ray files, the GPU, the
    // deep checks D1-D7, whose message names the check): the message alone.
    if (rule == 0) return message;
    return message + " [rule " + std::to_string(rule) + "]";
}

}  // namespace cwbvh

// Status codes, validation rule IDs and the one error type of every cwbvh
// library: Result (no value) and Expected<T> (a value or a Result). Rule IDs are
// stable and listed in spec/cwbvh-format.md ("Validation rules"); a test checks
// that the two lists agree. Errors outside the file format (compiler input, ray
// files, the GPU) carry rule 0.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <utility>

namespace cwbvh {

/// Coarse outcome; the rule ID says exactly which check failed.
enum class Status : int {
    kOk = 0,
    kIoError = 1,             ///< cannot open, stat, map or write the file
    kNotCwbvh = 2,            ///< wrong magic: not a .cwbvh file at all
    kUnsupportedVersion = 3,  ///< major version this reader does not know
    kUnsupported = 4,         ///< unknown section marked required
    kCorrupt = 5,             ///< structure violates the spec
    kChecksumMismatch = 6,    ///< header/table or payload checksum differs
    kInvalidArgument = 7,     ///< caller error (writer input, bad options)
    // 8 is the C API's CWBVH_ERROR_OUT_OF_MEMORY (no Status of its own).
    kBadInput = 9,            ///< malformed input other than a .cwbvh file (mesh, ray/hit or view file)
    kInternal = 10,           ///< a self-check of the compiler's own output failed
    kDeviceError = 11,        ///< no usable GPU, or a CUDA call failed
};

/// Short lower-case name ("corrupt", "checksum mismatch", ...).
const char* status_name(Status s);

/// Validation rule IDs (1xxx I/O, 2xxx identity/version, 3xxx header,
/// 4xxx section table, 5xxx section content, 6xxx two-level content).
namespace rule {
// 1xxx: I/O (loader)
inline constexpr uint32_t kOpenFailed = 1001;
inline constexpr uint32_t kNotRegularFile = 1002;
inline constexpr uint32_t kEmptyFile = 1003;
inline constexpr uint32_t kMapFailed = 1004;
inline constexpr uint32_t kWriteFailed = 1005;
// 2xxx: identity and version
inline constexpr uint32_t kBadMagic = 2001;
inline constexpr uint32_t kTruncatedHeader = 2002;
inline constexpr uint32_t kUnsupportedMajor = 2003;
// 3xxx: header
inline constexpr uint32_t kHeaderSize = 3001;
inline constexpr uint32_t kFileSize = 3002;
inline constexpr uint32_t kTableAlignment = 3003;
inline constexpr uint32_t kTableOutsideFile = 3004;
inline constexpr uint32_t kMetaChecksum = 3005;
inline constexpr uint32_t kHeaderFlags = 3006;
inline constexpr uint32_t kHeaderReserved = 3007;
// 4xxx: section table
inline constexpr uint32_t kSectionFlags = 4001;
inline constexpr uint32_t kSectionReserved = 4002;
inline constexpr uint32_t kSectionAlignment = 4003;
inline constexpr uint32_t kSectionSize = 4004;
inline constexpr uint32_t kSectionOutsideFile = 4005;
inline constexpr uint32_t kSectionOverlapsHeader = 4006;
inline constexpr uint32_t kSectionOverlap = 4007;
inline constexpr uint32_t kDuplicateSection = 4008;
inline constexpr uint32_t kUnknownRequiredSection = 4009;
inline constexpr uint32_t kElementSize = 4010;
inline constexpr uint32_t kElementCount = 4011;
inline constexpr uint32_t kMissingSection = 4012;
inline constexpr uint32_t kNonZeroPadding = 4013;
inline constexpr uint32_t kSectionChecksum = 4014;
inline constexpr uint32_t kTrailingBytes = 4015;
// 51xx: NODE
inline constexpr uint32_t kNodeExponent = 5101;
inline constexpr uint32_t kNodeMeta = 5102;
inline constexpr uint32_t kNodeImask = 5103;
inline constexpr uint32_t kNodeChildRange = 5104;
inline constexpr uint32_t kNodeChildOrder = 5105;
inline constexpr uint32_t kNodeParents = 5106;
inline constexpr uint32_t kNodeLeafRange = 5107;
inline constexpr uint32_t kNodeLeafLayout = 5108;
inline constexpr uint32_t kNodeTriangleUse = 5109;
inline constexpr uint32_t kNodePlaneOrder = 5110;
inline constexpr uint32_t kNodeEmptySlot = 5111;
inline constexpr uint32_t kNodeNonFinite = 5112;
inline constexpr uint32_t kNodeDepth = 5113;
inline constexpr uint32_t kNodeEmpty = 5114;
// 52xx: TRIS
inline constexpr uint32_t kTriPrim = 5201;
// 5202 (TRIS reserved fields) was removed with the fields: the 40-byte record has none.
inline constexpr uint32_t kTriNonFinite = 5203;
// 53xx: PMAP
inline constexpr uint32_t kPmapInput = 5301;
inline constexpr uint32_t kPmapRangeEmpty = 5302;
inline constexpr uint32_t kPmapRangeOrder = 5303;
inline constexpr uint32_t kPmapRangeLimit = 5304;
inline constexpr uint32_t kPmapTotal = 5305;
// 54xx: BNDS
inline constexpr uint32_t kBoundsInvalid = 5401;
// 55xx: BILD
inline constexpr uint32_t kBuildReserved = 5501;
// 56xx: BVH2 and BV2L (the same 64-byte record; 5602/5603 are BVH2's, 5607-5609 BV2L's)
inline constexpr uint32_t kBvh2Child = 5601;
inline constexpr uint32_t kBvh2Leaf = 5602;
inline constexpr uint32_t kBvh2Reserved = 5603;
inline constexpr uint32_t kBvh2NonFinite = 5604;
inline constexpr uint32_t kBvh2Parents = 5605;
inline constexpr uint32_t kBvh2Depth = 5606;
inline constexpr uint32_t kBvh2LeafCount = 5607;
inline constexpr uint32_t kBvh2LeafRange = 5608;
inline constexpr uint32_t kBvh2InternalCount = 5609;
inline constexpr uint32_t kBvh2TriangleUse = 5610;
// 57xx: VERT
inline constexpr uint32_t kVertNonFinite = 5701;
// 58xx: INDX
inline constexpr uint32_t kIndexRange = 5801;
inline constexpr uint32_t kIndexCount = 5802;
// 59xx: SRCN
inline constexpr uint32_t kNamesTerminator = 5901;
// 60xx: two-level scenes (format 1.2): MESH 600x, INST 602x, both levels 604x
inline constexpr uint32_t kTwoLevelSections = 6001;
inline constexpr uint32_t kMeshNodeRange = 6002;
inline constexpr uint32_t kMeshTriRange = 6003;
inline constexpr uint32_t kMeshPrimRange = 6004;
inline constexpr uint32_t kMeshBounds = 6005;
inline constexpr uint32_t kMeshReserved = 6006;
inline constexpr uint32_t kMeshPrim = 6007;
inline constexpr uint32_t kInstNonFinite = 6021;
inline constexpr uint32_t kInstCondition = 6022;
inline constexpr uint32_t kInstInverse = 6023;
inline constexpr uint32_t kInstMesh = 6024;
inline constexpr uint32_t kInstWorldBox = 6025;
inline constexpr uint32_t kTwoLevelDepth = 6041;
// 61xx: TLAS, the NODE rules 51xx on the top level with INST in place of TRIS (ID + 1000)
inline constexpr uint32_t kTlasRuleOffset = 1000;
inline constexpr uint32_t kTlasExponent = kNodeExponent + kTlasRuleOffset;
inline constexpr uint32_t kTlasMeta = kNodeMeta + kTlasRuleOffset;
inline constexpr uint32_t kTlasImask = kNodeImask + kTlasRuleOffset;
inline constexpr uint32_t kTlasChildRange = kNodeChildRange + kTlasRuleOffset;
inline constexpr uint32_t kTlasChildOrder = kNodeChildOrder + kTlasRuleOffset;
inline constexpr uint32_t kTlasParents = kNodeParents + kTlasRuleOffset;
inline constexpr uint32_t kTlasLeafRange = kNodeLeafRange + kTlasRuleOffset;
inline constexpr uint32_t kTlasLeafLayout = kNodeLeafLayout + kTlasRuleOffset;
inline constexpr uint32_t kTlasInstanceUse = kNodeTriangleUse + kTlasRuleOffset;
inline constexpr uint32_t kTlasPlaneOrder = kNodePlaneOrder + kTlasRuleOffset;
inline constexpr uint32_t kTlasEmptySlot = kNodeEmptySlot + kTlasRuleOffset;
inline constexpr uint32_t kTlasNonFinite = kNodeNonFinite + kTlasRuleOffset;
inline constexpr uint32_t kTlasDepth = kNodeDepth + kTlasRuleOffset;
inline constexpr uint32_t kTlasEmpty = kNodeEmpty + kTlasRuleOffset;
/// Every rule ID above (a test checks this list against the spec's table).
inline constexpr uint32_t kAll[] = {
    kOpenFailed,      kNotRegularFile,     kEmptyFile,
    kMapFailed,       kWriteFailed,        kBadMagic,
    kTruncatedHeader, kUnsupportedMajor,   kHeaderSize,
    kFileSize,        kTableAlignment,     kTableOutsideFile,
    kMetaChecksum,    kHeaderFlags,        kHeaderReserved,
    kSectionFlags,    kSectionReserved,    kSectionAlignment,
    kSectionSize,     kSectionOutsideFile, kSectionOverlapsHeader,
    kSectionOverlap,  kDuplicateSection,   kUnknownRequiredSection,
    kElementSize,     kElementCount,       kMissingSection,
    kNonZeroPadding,  kSectionChecksum,    kNodeExponent,
    kNodeMeta,        kNodeImask,          kNodeChildRange,
    kNodeChildOrder,  kNodeParents,        kNodeLeafRange,
    kNodeLeafLayout,  kNodeTriangleUse,    kNodePlaneOrder,
    kNodeEmptySlot,   kNodeNonFinite,      kNodeDepth,
    kTriPrim,         kTriNonFinite,       kPmapInput,
    kPmapRangeEmpty,  kPmapRangeOrder,     kPmapRangeLimit,
    kBoundsInvalid,   kBuildReserved,      kBvh2Child,
    kBvh2Leaf,        kBvh2Reserved,       kBvh2NonFinite,
    kBvh2Parents,     kBvh2Depth,          kBvh2LeafCount,
    kBvh2LeafRange,   kBvh2InternalCount,  kVertNonFinite,
    kIndexRange,      kIndexCount,         kNamesTerminator,
    kTrailingBytes,   kNodeEmpty,          kPmapTotal,
    kBvh2TriangleUse, kTwoLevelSections,   kMeshNodeRange,
    kMeshTriRange,    kMeshPrimRange,      kMeshBounds,
    kMeshReserved,    kMeshPrim,           kInstNonFinite,
    kInstCondition,   kInstInverse,        kInstMesh,
    kInstWorldBox,    kTwoLevelDepth,      kTlasExponent,
    kTlasMeta,        kTlasImask,          kTlasChildRange,
    kTlasChildOrder,  kTlasParents,        kTlasLeafRange,
    kTlasLeafLayout,  kTlasInstanceUse,    kTlasPlaneOrder,
    kTlasEmptySlot,   kTlasNonFinite,      kTlasDepth,
    kTlasEmpty,
};
}  // namespace rule

/// The result of an operation: kOk, or a status, a rule ID and a one-line
/// message naming the section and what is wrong (no file name: the caller
/// that knows the path prefixes it). [[nodiscard]] on the type makes every
/// function returning it nodiscard.
struct [[nodiscard]] Result {
    Status status = Status::kOk;
    uint32_t rule = 0;
    std::string message;

    bool ok() const { return status == Status::kOk; }
    static Result success() { return {}; }
    static Result fail(Status s, uint32_t rule_id, std::string msg) {
        return {s, rule_id, std::move(msg)};
    }
    /// "message [rule N]", the message alone for rule 0 (no numbered rule), or "ok".
    std::string describe() const;
};

/// Default status for a rule ID (2001 -> kNotCwbvh, 3005/4014 -> checksum, ...).
Status status_for_rule(uint32_t rule_id);

/// A failed Result with the status implied by the rule.
Result fail(uint32_t rule_id, std::string message);

/// A value, or the Result that says why there is none (error().ok() is false).
template <class T>
class [[nodiscard]] Expected {
public:
    Expected(T value) : value_(std::move(value)) {}
    Expected(Result error) : error_(std::move(error)) {}
    bool ok() const { return value_.has_value(); }
    T& value() { return *value_; }
    const T& value() const { return *value_; }
    T& operator*() { return *value_; }
    const T& operator*() const { return *value_; }
    T* operator->() { return &*value_; }
    const T* operator->() const { return &*value_; }
    const Result& error() const { return error_; }

private:
    std::optional<T> value_;
    Result error_;
};

}  // namespace cwbvh

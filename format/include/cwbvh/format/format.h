// On-disk structures of the .cwbvh format, version 1.
// Normative description: spec/cwbvh-format.md. Every size and offset below is
// static_assert'ed; the spec's tables and these structs change together.
// All multi-byte fields are little-endian. Shared by host and device code.
#pragma once

#include <cstdint>
#include <cstddef>

#include "cwbvh/format/hostdevice.h"

namespace cwbvh {

// ---------------------------------------------------------------------------
// File identity
// ---------------------------------------------------------------------------

/// 12-byte magic. 0xAB and 0xBB catch 7-bit transfers, CR LF catches
/// CRLF<->LF conversion, 0x1A stops DOS `type`, the final LF catches LF->CRLF.
inline constexpr uint8_t kMagic[12] = {0xAB, 'C', 'W', 'B', 'V', 'H',
                                        0xBB, 0x0D, 0x0A, 0x1A, 0x0A, 0x00};
inline constexpr uint16_t kVersionMajor = 1;
/// Newest minor this code writes and knows (a writer stamps the lowest minor
/// that covers the sections it writes: sections.h, SectionInfo::since_minor).
/// 1.1 added the optional BV2L section; 1.2 the two-level sections MESH, INST,
/// TLAS (required when present, so a 1.1 reader rejects such a file).
inline constexpr uint16_t kVersionMinor = 2;
/// Every section's offset is a multiple of this (cache line; mmap-friendly;
/// lets a GPU copy a section with aligned 16-byte vector loads).
inline constexpr uint64_t kSectionAlignment = 64;

struct FileHeader {
    uint8_t magic[12];              ///< kMagic
    uint16_t version_major;         ///< a reader rejects an unknown major
    uint16_t version_minor;         ///< a reader accepts a newer minor
    uint32_t header_size;           ///< sizeof(FileHeader) = 64
    uint32_t section_count;         ///< entries in the section table
    uint64_t section_table_offset;  ///< byte offset of the table, 8-aligned
    uint64_t file_size;             ///< total bytes in the file (truncation check)
    uint64_t meta_checksum;         ///< XXH3-64 of header (this field = 0) ++ section table
    uint32_t flags;                 ///< reserved, must be 0
    uint32_t reserved0;             ///< must be 0
    uint64_t reserved1;             ///< must be 0
};
static_assert(sizeof(FileHeader) == 64);
static_assert(offsetof(FileHeader, magic) == 0);
static_assert(offsetof(FileHeader, version_major) == 12);
static_assert(offsetof(FileHeader, version_minor) == 14);
static_assert(offsetof(FileHeader, header_size) == 16);
static_assert(offsetof(FileHeader, section_count) == 20);
static_assert(offsetof(FileHeader, section_table_offset) == 24);
static_assert(offsetof(FileHeader, file_size) == 32);
static_assert(offsetof(FileHeader, meta_checksum) == 40);
static_assert(offsetof(FileHeader, flags) == 48);
static_assert(offsetof(FileHeader, reserved0) == 52);
static_assert(offsetof(FileHeader, reserved1) == 56);

// ---------------------------------------------------------------------------
// Section table
// ---------------------------------------------------------------------------

constexpr uint32_t fourcc(char a, char b, char c, char d) {
    return uint32_t(uint8_t(a)) | (uint32_t(uint8_t(b)) << 8) |
           (uint32_t(uint8_t(c)) << 16) | (uint32_t(uint8_t(d)) << 24);
}

enum SectionType : uint32_t {
    kSectionNodes = fourcc('N', 'O', 'D', 'E'),      ///< CwbvhNode[], required
    kSectionTriangles = fourcc('T', 'R', 'I', 'S'),  ///< TriangleRecord[] in leaf order, required
    kSectionSourceMap = fourcc('P', 'M', 'A', 'P'),  ///< SourceRange[] runs of stored triangles, required
    kSectionBounds = fourcc('B', 'N', 'D', 'S'),     ///< SceneBounds[1], required
    kSectionBuildInfo = fourcc('B', 'I', 'L', 'D'),  ///< BuildInfo[1], optional
    kSectionBvh2 = fourcc('B', 'V', 'H', '2'),       ///< Bvh2Node[] (binary SBVH, 1 triangle per leaf), optional
    kSectionBvh2Leaves = fourcc('B', 'V', '2', 'L'), ///< Bvh2Node[] with leaf ranges (format 1.1), optional
    kSectionVertices = fourcc('V', 'E', 'R', 'T'),   ///< float[3][] source vertices, optional
    kSectionIndices = fourcc('I', 'N', 'D', 'X'),    ///< uint32_t[3][] per stored triangle, optional
    kSectionSourceNames = fourcc('S', 'R', 'C', 'N'),///< NUL-terminated UTF-8 input names, optional
    // Two-level scenes (format 1.2): all three or none; each required.
    kSectionMeshes = fourcc('M', 'E', 'S', 'H'),     ///< MeshRecord[]: bottom levels (ranges of NODE/TRIS/stored ids)
    kSectionInstances = fourcc('I', 'N', 'S', 'T'),  ///< InstanceRecord[] in top-level leaf order
    kSectionTopNodes = fourcc('T', 'L', 'A', 'S'),   ///< CwbvhNode[]: the top level; leaves index INST
};

enum SectionFlags : uint32_t {
    kSectionRequired = 1u << 0,  ///< a reader that does not know the type must reject the file
};

struct SectionEntry {
    uint32_t type;           ///< SectionType (FourCC)
    uint32_t flags;          ///< SectionFlags; unknown bits must be 0
    uint64_t offset;         ///< from file start; multiple of kSectionAlignment
    uint64_t size;           ///< bytes; == element_size * element_count
    uint32_t element_size;   ///< bytes per element
    uint32_t reserved;       ///< must be 0
    uint64_t element_count;  ///< number of elements
    uint64_t checksum;       ///< XXH3-64 (seed 0) of the section's `size` bytes
};
static_assert(sizeof(SectionEntry) == 48);
static_assert(offsetof(SectionEntry, type) == 0);
static_assert(offsetof(SectionEntry, flags) == 4);
static_assert(offsetof(SectionEntry, offset) == 8);
static_assert(offsetof(SectionEntry, size) == 16);
static_assert(offsetof(SectionEntry, element_size) == 24);
static_assert(offsetof(SectionEntry, reserved) == 28);
static_assert(offsetof(SectionEntry, element_count) == 32);
static_assert(offsetof(SectionEntry, checksum) == 40);

// ---------------------------------------------------------------------------
// NODE: the 80-byte compressed wide node (Ylitie, Karras, Laine 2017)
// ---------------------------------------------------------------------------

inline constexpr int kWidth = 8;               ///< children per node
inline constexpr int kMaxLeafTriangles = 3;    ///< unary count in meta bits 5..7
inline constexpr int kMaxNodeTriangles = 24;   ///< 5-bit offset in meta bits 0..4
inline constexpr uint8_t kMetaEmpty = 0x00;
inline constexpr uint32_t kInvalidIndex = 0xFFFFFFFFu;

/// Child box decoding (normative, see spec): for axis a and slot s,
///   scale  = float with bits (e[a] << 23)          (= 2^(e[a]-127); e in 1..254)
///   lo     = RN_f32(p[a] + scale * q_lo[a][s])      (product is exact)
///   hi     = RN_f32(p[a] + scale * q_hi[a][s])
/// The compiler guarantees lo <= exact child lo and hi >= exact child hi.
struct CwbvhNode {
    float p[3];            ///< quantization origin
    uint8_t e[3];          ///< biased per-axis exponent (IEEE-754 exponent field)
    uint8_t imask;         ///< bit s set: slot s holds an internal node
    uint32_t child_base;   ///< index of the first internal child in NODE
    uint32_t tri_base;     ///< index of the first triangle record in TRIS
    uint8_t meta[8];       ///< per slot: empty 0x00; internal 0x20|(24+s); leaf unary(count)<<5 | offset
    uint8_t q_lo[3][8];    ///< [axis][slot] quantized lower planes (x, y, z)
    uint8_t q_hi[3][8];    ///< [axis][slot] quantized upper planes (x, y, z)
};
static_assert(sizeof(CwbvhNode) == 80);
static_assert(offsetof(CwbvhNode, p) == 0);
static_assert(offsetof(CwbvhNode, e) == 12);
static_assert(offsetof(CwbvhNode, imask) == 15);
static_assert(offsetof(CwbvhNode, child_base) == 16);
static_assert(offsetof(CwbvhNode, tri_base) == 20);
static_assert(offsetof(CwbvhNode, meta) == 24);
static_assert(offsetof(CwbvhNode, q_lo) == 32);
static_assert(offsetof(CwbvhNode, q_hi) == 56);

// ---------------------------------------------------------------------------
// TRIS: one record per triangle reference, in leaf order
// ---------------------------------------------------------------------------

/// Raw vertices (so a watertight test can run on them exactly) plus the
/// stored triangle id; no padding (40 bytes instead of 48 keeps a compiled
/// file under 55 bytes per input triangle). Records are 8-byte aligned
/// (sections are 64-byte aligned, 40 = 5 * 8), so the GPU loads one with
/// five 8-byte (float2) loads instead of three 16-byte ones.
struct TriangleRecord {
    float v0[3];
    float v1[3];
    float v2[3];
    uint32_t prim;  ///< stored triangle id: < stored triangle count (PMAP total)
};
static_assert(sizeof(TriangleRecord) == 40);
static_assert(offsetof(TriangleRecord, v0) == 0);
static_assert(offsetof(TriangleRecord, v1) == 12);
static_assert(offsetof(TriangleRecord, v2) == 24);
static_assert(offsetof(TriangleRecord, prim) == 36);

// ---------------------------------------------------------------------------
// PMAP: stored triangle -> source primitive, as runs
// ---------------------------------------------------------------------------

/// A run of stored triangles [first, first + count) that come from
/// consecutive triangles first_triangle, first_triangle + 1, ... of one
/// source primitive. Ranges are sorted and tile [0, stored triangle count).
struct SourceRange {
    uint32_t first;           ///< first stored triangle id of the run
    uint32_t count;           ///< stored triangles in the run, >= 1
    uint32_t input;           ///< index of the input file (order on the command line; SRCN)
    uint32_t mesh;            ///< glTF: mesh index; other formats: 0
    uint32_t primitive;       ///< glTF: primitive index in the mesh; other formats: 0
    uint32_t first_triangle;  ///< triangle index (in that primitive) of stored triangle `first`
};
static_assert(sizeof(SourceRange) == 24);
static_assert(offsetof(SourceRange, first) == 0);
static_assert(offsetof(SourceRange, count) == 4);
static_assert(offsetof(SourceRange, input) == 8);
static_assert(offsetof(SourceRange, mesh) == 12);
static_assert(offsetof(SourceRange, primitive) == 16);
static_assert(offsetof(SourceRange, first_triangle) == 20);

/// The decoded source of one stored triangle (not stored as such: PMAP holds
/// SourceRange runs; see cwbvh/format/source_map.h).
struct SourceRef {
    uint32_t input;      ///< index of the input file (order on the command line; SRCN)
    uint32_t mesh;       ///< glTF: mesh index; other formats: 0
    uint32_t primitive;  ///< glTF: primitive index in the mesh; other formats: 0
    uint32_t triangle;   ///< triangle index in that primitive (after triangulation)
};
static_assert(sizeof(SourceRef) == 16);
static_assert(offsetof(SourceRef, input) == 0);
static_assert(offsetof(SourceRef, mesh) == 4);
static_assert(offsetof(SourceRef, primitive) == 8);
static_assert(offsetof(SourceRef, triangle) == 12);

// ---------------------------------------------------------------------------
// BNDS: scene bounds
// ---------------------------------------------------------------------------

struct SceneBounds {
    float lo[3];
    float hi[3];
};
static_assert(sizeof(SceneBounds) == 24);
static_assert(offsetof(SceneBounds, lo) == 0);
static_assert(offsetof(SceneBounds, hi) == 12);

// ---------------------------------------------------------------------------
// BVH2 / BV2L: binary BVH nodes in the layout of Aila, Laine & Karras's kernels
// ---------------------------------------------------------------------------

/// The same 64-byte record serves two optional sections (spec 3.6):
///   BVH2 (1.0): child[i] >= 0: index of an internal node; child[i] < 0: a leaf
///               holding the single record TRIS[~child[i]]; leaf_count[] is
///               reserved and must be 0.
///   BV2L (1.1): a leaf child holds leaf_count[i] (1..kMaxBvh2LeafTriangles)
///               consecutive records TRIS[~child[i] ..]; leaf_count[i] is 0 for
///               an internal child.
/// Root is node 0 and is internal. Traversals read a leaf count of 0 as 1, so
/// one loop serves both sections.
struct Bvh2Node {
    float c0_lo_x, c0_hi_x, c0_lo_y, c0_hi_y;
    float c1_lo_x, c1_hi_x, c1_lo_y, c1_hi_y;
    float c0_lo_z, c0_hi_z, c1_lo_z, c1_hi_z;
    int32_t child[2];
    uint32_t leaf_count[2];  ///< BV2L: TRIS records of a leaf child, 0 for an internal one; BVH2: 0
};
static_assert(sizeof(Bvh2Node) == 64);
static_assert(offsetof(Bvh2Node, c0_lo_x) == 0);
static_assert(offsetof(Bvh2Node, c0_hi_x) == 4);
static_assert(offsetof(Bvh2Node, c0_lo_y) == 8);
static_assert(offsetof(Bvh2Node, c0_hi_y) == 12);
static_assert(offsetof(Bvh2Node, c1_lo_x) == 16);
static_assert(offsetof(Bvh2Node, c1_hi_x) == 20);
static_assert(offsetof(Bvh2Node, c1_lo_y) == 24);
static_assert(offsetof(Bvh2Node, c1_hi_y) == 28);
static_assert(offsetof(Bvh2Node, c0_lo_z) == 32);
static_assert(offsetof(Bvh2Node, c0_hi_z) == 36);
static_assert(offsetof(Bvh2Node, c1_lo_z) == 40);
static_assert(offsetof(Bvh2Node, c1_hi_z) == 44);
static_assert(offsetof(Bvh2Node, child) == 48);
static_assert(offsetof(Bvh2Node, leaf_count) == 56);

/// Most TRIS records in one BV2L leaf (rule 5607). Two bits: a traversal packs a
/// leaf's first record and count - 1 into one 32-bit stack entry (bvh2_lane.h).
inline constexpr uint32_t kMaxBvh2LeafTriangles = 4;
/// Most TRIS records a file with a BV2L section may have (rule 4011): the first
/// record of a leaf shifted left by 2 still fits the 31 bits of a negative child.
inline constexpr uint64_t kMaxBvh2LeafTris = uint64_t(1) << 29;

// ---------------------------------------------------------------------------
// BILD: build parameters and statistics (no timings: files are deterministic)
// ---------------------------------------------------------------------------

enum BuilderKind : uint32_t { kBuilderSbvh = 1, kBuilderEmbree = 2 };
enum CollapseKind : uint32_t { kCollapseOptimal = 1, kCollapseGreedy = 2 };

struct BuildInfo {
    uint32_t builder;             ///< BuilderKind
    uint32_t collapse;            ///< CollapseKind
    float split_alpha;            ///< SBVH overlap threshold
    float cost_node;              ///< collapse cost model: C_node
    float cost_prim;              ///< collapse cost model: C_prim
    uint32_t max_leaf_triangles;  ///< 3
    uint64_t input_triangles;     ///< triangles read from the inputs
    uint64_t dropped_nonfinite;   ///< NaN/Inf coordinate
    uint64_t dropped_degenerate;  ///< zero area
    uint64_t skipped_primitives;  ///< points/lines primitives skipped (glTF)
    uint64_t triangles;           ///< stored triangles (PMAP total)
    uint64_t references;          ///< triangle references after spatial splits (TRIS count)
    uint64_t binary_nodes;        ///< nodes of the binary SBVH (internal + leaves)
    uint64_t wide_nodes;          ///< NODE count
    double sah_binary;            ///< SAH cost of the binary tree (spec formula)
    double sah_wide;              ///< SAH cost of the wide tree (spec formula)
    double avg_children;          ///< average children per wide node
    uint8_t reserved[144];        ///< must be 0
};
static_assert(sizeof(BuildInfo) == 256);
static_assert(offsetof(BuildInfo, builder) == 0);
static_assert(offsetof(BuildInfo, collapse) == 4);
static_assert(offsetof(BuildInfo, split_alpha) == 8);
static_assert(offsetof(BuildInfo, cost_node) == 12);
static_assert(offsetof(BuildInfo, cost_prim) == 16);
static_assert(offsetof(BuildInfo, max_leaf_triangles) == 20);
static_assert(offsetof(BuildInfo, input_triangles) == 24);
static_assert(offsetof(BuildInfo, dropped_nonfinite) == 32);
static_assert(offsetof(BuildInfo, dropped_degenerate) == 40);
static_assert(offsetof(BuildInfo, skipped_primitives) == 48);
static_assert(offsetof(BuildInfo, triangles) == 56);
static_assert(offsetof(BuildInfo, references) == 64);
static_assert(offsetof(BuildInfo, binary_nodes) == 72);
static_assert(offsetof(BuildInfo, wide_nodes) == 80);
static_assert(offsetof(BuildInfo, sah_binary) == 88);
static_assert(offsetof(BuildInfo, sah_wide) == 96);
static_assert(offsetof(BuildInfo, avg_children) == 104);
static_assert(offsetof(BuildInfo, reserved) == 112);

// ---------------------------------------------------------------------------
// Two-level scenes (format 1.2): MESH, INST, TLAS (spec 3.9)
// ---------------------------------------------------------------------------
// In a two-level file NODE holds the bottom levels one after another and TRIS
// their triangle records; every index stays absolute (child_base into NODE,
// tri_base into TRIS, prim a stored triangle id), so a bottom level is traversed
// by the single-level loop started at its root. TLAS is an 8-wide tree in the
// NODE layout whose leaf "triangles" are INST records (tri_base + offset indexes
// INST); INST is in TLAS leaf order.

/// One bottom level: a distinct mesh in its own object space.
struct MeshRecord {
    uint32_t node_first;   ///< NODE index of the mesh's root; its nodes are [node_first, node_first + node_count)
    uint32_t node_count;   ///< >= 1
    uint32_t tri_first;    ///< first TRIS record of the mesh
    uint32_t tri_count;    ///< TRIS records of the mesh, >= 1
    uint32_t prim_first;   ///< first stored triangle id of the mesh (PMAP)
    uint32_t prim_count;   ///< stored triangles of the mesh, >= 1; TRIS prims lie in [prim_first, +prim_count)
    float lo[3];           ///< exact object-space bounds of the mesh's TRIS vertices
    float hi[3];
    uint32_t source_mesh;  ///< glTF mesh index (kInvalidIndex: several source meshes merged, e.g. placed once)
    uint32_t reserved[3];  ///< 0
};
static_assert(sizeof(MeshRecord) == 64);
static_assert(offsetof(MeshRecord, node_first) == 0);
static_assert(offsetof(MeshRecord, node_count) == 4);
static_assert(offsetof(MeshRecord, tri_first) == 8);
static_assert(offsetof(MeshRecord, tri_count) == 12);
static_assert(offsetof(MeshRecord, prim_first) == 16);
static_assert(offsetof(MeshRecord, prim_count) == 20);
static_assert(offsetof(MeshRecord, lo) == 24);
static_assert(offsetof(MeshRecord, hi) == 36);
static_assert(offsetof(MeshRecord, source_mesh) == 48);
static_assert(offsetof(MeshRecord, reserved) == 52);

/// One placement of a mesh. Affine 3x4 row-major: x_world[r] = M[r][0]*x + M[r][1]*y + M[r][2]*z + M[r][3].
struct InstanceRecord {
    float object_to_world[3][4];  ///< finite, invertible (spec 3.10 bounds its condition number)
    float world_to_object[3][4];  ///< RN of the exact inverse of object_to_world (computed in double)
    uint32_t mesh;                ///< MESH index
    uint32_t source_node;         ///< glTF node index (kInvalidIndex: none, e.g. the merged identity instance)
    float world_lo[3];            ///< conservative world box of the mesh's bounds under object_to_world
    float world_hi[3];
};
static_assert(sizeof(InstanceRecord) == 128);
static_assert(offsetof(InstanceRecord, object_to_world) == 0);
static_assert(offsetof(InstanceRecord, world_to_object) == 48);
static_assert(offsetof(InstanceRecord, mesh) == 96);
static_assert(offsetof(InstanceRecord, source_node) == 100);
static_assert(offsetof(InstanceRecord, world_lo) == 104);
static_assert(offsetof(InstanceRecord, world_hi) == 116);

}  // namespace cwbvh

/* C API of the cwbvh loader: open a .cwbvh file (mmap + validate) and get
 * pointers to its sections. The layouts of the elements are those of
 * spec/cwbvh-format.md (and format/include/cwbvh/format/format.h for C++).
 *
 * The file is mapped, not copied: while a handle is open the file must not be truncated
 * or rewritten in place (a read past a truncated end is SIGBUS; bytes changed after the
 * validation are not validated). Replacing it by a rename, as cwbvhc does, is safe.
 *
 * Errors are per handle, so the API is thread-safe without globals: like
 * sqlite3_open, cwbvh_open hands back a handle even when it fails (unless
 * memory runs out); cwbvh_error_message() then explains the failure, and the
 * handle must still be closed. Different handles may be used from different
 * threads; one handle is read-only after open and may be shared.
 *
 * cwbvh_device_upload (cwbvh_device.h, CUDA builds) builds on the section
 * accessors below (pointer + byte size per section). */
#ifndef CWBVH_CWBVH_H
#define CWBVH_CWBVH_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef enum cwbvh_status {
    CWBVH_OK = 0,
    CWBVH_ERROR_IO = 1,                   /* cannot open/stat/map; directory; empty */
    CWBVH_ERROR_NOT_CWBVH = 2,            /* wrong magic */
    CWBVH_ERROR_UNSUPPORTED_VERSION = 3,  /* unknown major version */
    CWBVH_ERROR_UNSUPPORTED = 4,          /* unknown required section */
    CWBVH_ERROR_CORRUPT = 5,              /* violates the spec */
    CWBVH_ERROR_CHECKSUM = 6,             /* checksum mismatch */
    CWBVH_ERROR_INVALID_ARGUMENT = 7,     /* NULL path/out, bad struct_size */
    CWBVH_ERROR_OUT_OF_MEMORY = 8
} cwbvh_status;

/* Section selection bits (same values as cwbvh::SectionMask). */
#define CWBVH_SECTION_NODES (1u << 0)
#define CWBVH_SECTION_TRIANGLES (1u << 1)
#define CWBVH_SECTION_SOURCE_MAP (1u << 2)
#define CWBVH_SECTION_BOUNDS (1u << 3)
#define CWBVH_SECTION_BUILD_INFO (1u << 4)
#define CWBVH_SECTION_BVH2 (1u << 5) /* BVH2 and BV2L */
#define CWBVH_SECTION_VERTICES (1u << 6)
#define CWBVH_SECTION_INDICES (1u << 7)
#define CWBVH_SECTION_SOURCE_NAMES (1u << 8)
/* MESH, INST and TLAS of a two-level file (format 1.2). A two-level file opened
 * with CWBVH_SECTION_NODES but without this bit is refused (rule 4009). */
#define CWBVH_SECTION_TWO_LEVEL (1u << 9)
#define CWBVH_SECTION_ALL ((1u << 10) - 1u)

typedef struct cwbvh_open_options {
    uint32_t struct_size;      /* sizeof(cwbvh_open_options): lets the struct grow */
    uint32_t verify_checksums; /* nonzero: verify payload checksums (default 1) */
    uint32_t sections;         /* CWBVH_SECTION_* to validate and expose (default ALL) */
    uint32_t reserved;         /* 0 (cwbvh_open refuses anything else: CWBVH_ERROR_INVALID_ARGUMENT) */
} cwbvh_open_options;

typedef struct cwbvh_file cwbvh_file;

/* The decoded source of one stored triangle (what PMAP's ranges say about it). */
typedef struct cwbvh_source_ref {
    uint32_t input;     /* input file index (SRCN order) */
    uint32_t mesh;      /* glTF mesh index; other formats 0 */
    uint32_t primitive; /* glTF primitive index in the mesh; other formats 0 */
    uint32_t triangle;  /* triangle index in that primitive, after triangulation */
} cwbvh_source_ref;

/* Fills the defaults (checksums on, all sections). */
void cwbvh_open_options_init(cwbvh_open_options* options);

/* Opens and validates `path`. options may be NULL (defaults). On return *out
 * is a handle (also on failure, with the error) or NULL (out of memory or
 * invalid argument). Always cwbvh_close(*out). */
cwbvh_status cwbvh_open(const char* path, const cwbvh_open_options* options, cwbvh_file** out);

/* The status of the open, its validation rule ID (0 if none), and a one-line
 * message naming the file, the section and what is wrong ("" on success).
 * The string lives as long as the handle. file may be NULL. */
cwbvh_status cwbvh_status_of(const cwbvh_file* file);
uint32_t cwbvh_error_rule(const cwbvh_file* file);
const char* cwbvh_error_message(const cwbvh_file* file);
const char* cwbvh_status_string(cwbvh_status status);

/* Section accessors: element pointer and count; NULL/0 if the section is
 * absent, not selected, or the open failed. Pointers live as long as the handle. */
const void* cwbvh_nodes(const cwbvh_file* file, uint64_t* count);        /* 80-byte nodes */
const void* cwbvh_triangles(const cwbvh_file* file, uint64_t* count);    /* 40-byte records */
const void* cwbvh_source_ranges(const cwbvh_file* file, uint64_t* count); /* 24-byte ranges */
const float* cwbvh_bounds(const cwbvh_file* file);                       /* lo[3], hi[3] */
const void* cwbvh_build_info(const cwbvh_file* file);                    /* 256 bytes */
/* Binary BVH, 64-byte nodes: the BV2L section (leaf ranges) if present, else the
 * legacy BVH2 section (leaf_count fields 0 = one triangle per leaf). */
const void* cwbvh_bvh2(const cwbvh_file* file, uint64_t* count);
const float* cwbvh_vertices(const cwbvh_file* file, uint64_t* count);    /* count vertices x 3 */
const uint32_t* cwbvh_indices(const cwbvh_file* file, uint64_t* count);  /* count triangles x 3 */
const char* cwbvh_source_names(const cwbvh_file* file, uint64_t* size);  /* NUL-separated, size bytes */
/* Two-level files (format 1.2, spec 3.9-3.11). cwbvh_is_two_level: 1 if the
 * file has MESH, INST and TLAS (NODE then holds the bottom levels: mesh m's
 * root is node meshes[m].node_first), 0 otherwise or if the open failed.
 * The accessors return NULL/0 for a single-level file or without
 * CWBVH_SECTION_TWO_LEVEL. */
int cwbvh_is_two_level(const cwbvh_file* file);
const void* cwbvh_meshes(const cwbvh_file* file, uint64_t* count);     /* 64-byte MeshRecord */
const void* cwbvh_instances(const cwbvh_file* file, uint64_t* count);  /* 128-byte InstanceRecord, TLAS leaf order */
const void* cwbvh_top_nodes(const cwbvh_file* file, uint64_t* count);  /* 80-byte nodes; leaves index INST */
/* Where stored triangle `prim` (a triangle record's / hit's prim) comes from:
 * binary search over the PMAP ranges. CWBVH_OK and *out filled, or
 * CWBVH_ERROR_INVALID_ARGUMENT (NULL file/out, failed open, PMAP not selected,
 * prim not below the stored triangle count). */
cwbvh_status cwbvh_source_of(const cwbvh_file* file, uint32_t prim, cwbvh_source_ref* out);
/* A section this loader knows, by FourCC (e.g. 0x45444F4E for "NODE"), if the file has it and
 * it was selected at open: bytes and size. An unknown optional section (skipped by the loader,
 * spec 2.4) gives NULL and size 0. */
const void* cwbvh_section(const cwbvh_file* file, uint32_t type, uint64_t* size);

void cwbvh_close(cwbvh_file* file);

#ifdef __cplusplus
}
#endif

#endif /* CWBVH_CWBVH_H */

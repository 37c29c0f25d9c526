// Safe file access for every reader and writer of the project: inputs are
// opened without blocking and refused unless they are regular files (a FIFO
// would hang a reader, a device such as /dev/zero never ends), reads are
// bounded by the size fstat reported, and an output path is checked against
// the inputs before anything is written (the one check of every tool: cwbvhc,
// cwbvh rays/trace/render).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/status.h"

namespace cwbvh {

/// A read-only descriptor of a regular file, closed when destroyed. Move only.
class RegularFile {
public:
    /// Opens `path` with O_NONBLOCK (opening a FIFO must not wait for a writer), fstat()s the
    /// descriptor and refuses anything but a regular file, then clears O_NONBLOCK. Errors
    /// (kIoError) name the path: rule 1001 (cannot open or stat) or 1002 (a directory, FIFO,
    /// device or socket); with `format_rules` false (inputs that are not .cwbvh files) rule 0.
    static Expected<RegularFile> open(const std::string& path, bool format_rules = true);

    RegularFile() = default;
    RegularFile(RegularFile&& other) noexcept;
    RegularFile& operator=(RegularFile&& other) noexcept;
    RegularFile(const RegularFile&) = delete;
    RegularFile& operator=(const RegularFile&) = delete;
    ~RegularFile();

    int fd() const { return fd_; }
    uint64_t size() const { return size_; }  ///< st_size at open
    const std::string& path() const { return path_; }

    /// Reads exactly `n` bytes at the current position; an error (kIoError, rule 0, naming the
    /// path) on a read error or when the file ends first (it shrank after open).
    Result read_exact(void* out, uint64_t n) const;

private:
    int fd_ = -1;
    uint64_t size_ = 0;
    std::string path_;
};

/// The whole of a regular file (RegularFile::open, then exactly its size at open). A file larger
/// than `max_bytes` is refused before anything is allocated.
Result read_regular_file(const std::string& path, uint64_t max_bytes, std::vector<uint8_t>& bytes,
                         bool format_rules = false);

/// True when `a` and `b` name one file: the same path after normalisation (absolute, symlinks in
/// the existing prefix resolved, "." and ".." removed), or, both existing, the same device and
/// inode (hard links, bind mounts).
bool same_file(const std::string& a, const std::string& b);

/// Checks an output path before anything is read or written: it must not be empty, nor one of
/// `others` (the inputs, or another output of the same command) by same_file(); if it exists it
/// must be a regular file, and its folder must exist. Error (kInvalidArgument, rule 0): "output
/// path is empty", "<output>: output is the same file as '<other>'; refusing to overwrite it",
/// "<output>: output is a directory", "<output>: output exists and is not a regular file",
/// "<output>: output folder '<folder>' does not exist".
Result check_output_path(const std::string& output, const std::vector<std::string>& others);

/// An output must not replace a file the inputs name (a glTF's buffers and images, an OBJ's
/// material library). Those can be many, with long hostile paths, so they are compared by
/// one stat each (device and inode) against the output's target, and only when that exists
/// (a missing output replaces nothing). Error (kInvalidArgument, rule 0): "<output>: output
/// is '<file>', which the input names; refusing to overwrite it".
Result check_output_not_referenced(const std::string& output, const std::vector<std::string>& referenced);

/// The file an output path writes: `path`, or the end of the symlink chain it names (a
/// dangling link's target; relative targets joined to the link's folder, never normalised).
std::string output_target(const std::string& path);

/// An output that replaces `path` only when it is complete: the bytes go to a new file beside it
/// (`path.tmp.<pid>.<n>`, created with O_EXCL), and commit() renames that over `path` (atomic on
/// one file system). A failed write or commit, or destruction before commit(), removes the
/// temporary file: `path` keeps its old contents, or stays absent; never a partial file that looks
/// valid. The one write path of every tool (the .cwbvh writer, ray, hit and image files).
/// A replaced file keeps its permission bits; it is a new file all the same (another owner,
/// no ACLs, no longer shared with its other hard links), and the rename is not preceded by
/// an fsync: whole or absent after the process dies, not after a power loss. A symlinked
/// output is written through (its target is replaced; the link stays).
/// Errors name the file and the reason (errno): rule 1001 (cannot create), 1005 (write, close or
/// rename failed).
class AtomicOutput {
public:
    static Expected<AtomicOutput> create(const std::string& path);

    AtomicOutput() = default;
    AtomicOutput(AtomicOutput&& other) noexcept;
    AtomicOutput& operator=(AtomicOutput&& other) noexcept;
    AtomicOutput(const AtomicOutput&) = delete;
    AtomicOutput& operator=(const AtomicOutput&) = delete;
    ~AtomicOutput();

    /// Appends `n` bytes (all of them, or an error).
    Result write(const void* data, uint64_t n);
    /// Closes the temporary file and renames it over the path; after an error nothing is left.
    Result commit();

private:
    void discard();
    int fd_ = -1;
    std::string path_, tmp_;
};

/// `n` bytes as the whole of `path`, through AtomicOutput.
Result write_file_atomic(const std::string& path, const void* data, uint64_t n);

}  // namespace cwbvh

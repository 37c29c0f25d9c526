#include "cwbvh/format/file_io.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <system_error>
#include <utility>

namespace cwbvh {
namespace {

namespace fs = std::filesystem;

/// Absolute path with every symlink in its existing prefix resolved and "." / ".." removed.
fs::path normalized(const std::string& path) {
    std::error_code ec;
    fs::path p = fs::absolute(path, ec);
    if (ec) return fs::path(path).lexically_normal();
    const fs::path canonical = fs::weakly_canonical(p, ec);
    return ec ? p.lexically_normal() : canonical;
}

const char* kind_of(mode_t mode) {
    if (S_ISDIR(mode)) return "is a directory";
    if (S_ISFIFO(mode)) return "is a FIFO";
    if (S_ISCHR(mode) || S_ISBLK(mode)) return "is a device";
    if (S_ISSOCK(mode)) return "is a socket";
    return "is not a regular file";
}

}  // namespace

Expected<RegularFile> RegularFile::open(const std::string& path, bool format_rules) {
    auto io = [&](uint32_t rule_id, const std::string& what) {
        return Result::fail(Status::kIoError, format_rules ? rule_id : 0, path + ": " + what);
    };
    RegularFile f;
    f.path_ = path;
    // O_NONBLOCK: open() of a FIFO without a writer returns at once instead of waiting; the
    // type is then checked on the descriptor itself, so nothing can swap the path in between.
    f.fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
    if (f.fd_ < 0) return io(rule::kOpenFailed, std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    if (::fstat(f.fd_, &st) != 0) return io(rule::kOpenFailed, std::string("cannot stat: ") + std::strerror(errno));
    if (!S_ISREG(st.st_mode)) return io(rule::kNotRegularFile, std::string(kind_of(st.st_mode)) + ", not a regular file");
    const int flags = ::fcntl(f.fd_, F_GETFL);
    if (flags < 0 || ::fcntl(f.fd_, F_SETFL, flags & ~O_NONBLOCK) != 0)
        return io(rule::kOpenFailed, std::string("cannot clear O_NONBLOCK: ") + std::strerror(errno));
    f.size_ = uint64_t(st.st_size);
    return f;
}

RegularFile::RegularFile(RegularFile&& other) noexcept { *this = std::move(other); }

RegularFile& RegularFile::operator=(RegularFile&& other) noexcept {
    if (this != &other) {
        if (fd_ >= 0) ::close(fd_);
        fd_ = std::exchange(other.fd_, -1);
        size_ = std::exchange(other.size_, 0);
        path_ = std::move(other.path_);
    }
    return *this;
}

RegularFile::~RegularFile() {
    if (fd_ >= 0) ::close(fd_);
}

Result RegularFile::read_exact(void* out, uint64_t n) const {
    auto* p = static_cast<uint8_t*>(out);
    while (n > 0) {
        const ssize_t got = ::read(fd_, p, size_t(std::min<uint64_t>(n, uint64_t(1) << 30)));
        if (got < 0) {
            if (errno == EINTR) continue;
            return Result::fail(Status::kIoError, 0, path_ + ": read error: " + std::strerror(errno));
        }
        if (got == 0) return Result::fail(Status::kIoError, 0, path_ + ": file ended early (changed while read?)");
        p += got;
        n -= uint64_t(got);
    }
    return Result::success();
}

Result read_regular_file(const std::string& path, uint64_t max_bytes, std::vector<uint8_t>& bytes,
                         bool format_rules) {
    bytes.clear();
    Expected<RegularFile> f = RegularFile::open(path, format_rules);
    if (!f.ok()) return f.error();
    if (f->size() > max_bytes)
        return Result::fail(Status::kIoError, 0, path + ": " + std::to_string(f->size()) +
                                                     " bytes, more than the " + std::to_string(max_bytes) +
                                                     " this reader accepts");
    bytes.resize(size_t(f->size()));
    return f->read_exact(bytes.data(), bytes.size());
}

bool same_file(const std::string& a, const std::string& b) {
    if (normalized(a) == normalized(b)) return true;
    std::error_code ec;
    const bool equivalent = fs::equivalent(a, b, ec);
    return !ec && equivalent;
}

Result check_output_path(const std::string& output, const std::vector<std::string>& others) {
    if (output.empty()) return Result::fail(Status::kInvalidArgument, 0, "output path is empty");
    auto bad = [&](const std::string& what) { return Result::fail(Status::kInvalidArgument, 0, output + ": " + what); };
    for (const auto& other : others)
        if (same_file(output, other)) return bad("output is the same file as '" + other + "'; refusing to overwrite it");
    std::error_code ec;
    const fs::file_status status = fs::status(output, ec);  // follows symlinks
    if (fs::is_directory(status)) return bad("output is a directory");
    if (fs::exists(status) && !fs::is_regular_file(status)) return bad("output exists and is not a regular file");
    // A file its owner made read-only stays as it is (the write goes to a new file renamed over
    // it, which the folder's permission alone would allow).
    if (fs::exists(status) && ::access(output.c_str(), W_OK) != 0) return bad("output exists and is not writable");
    // The folder the file is written in (AtomicOutput: a temporary file there, renamed) must
    // exist and be writable, so that a long job does not end in "cannot create".
    const fs::path folder = fs::path(output_target(output)).parent_path();
    const std::string where = folder.empty() ? std::string(".") : folder.string();
    if (!fs::is_directory(fs::status(where, ec))) return bad("output folder '" + where + "' does not exist");
    if (::access(where.c_str(), W_OK | X_OK) != 0) return bad("output folder '" + where + "' is not writable");
    return Result::success();
}

Result check_output_not_referenced(const std::string& output, const std::vector<std::string>& referenced) {
    struct stat out {};
    if (::stat(output_target(output).c_str(), &out) != 0) return Result::success();
    for (const std::string& ref : referenced) {
        struct stat st {};
        if (::stat(ref.c_str(), &st) == 0 && st.st_dev == out.st_dev && st.st_ino == out.st_ino)
            return Result::fail(Status::kInvalidArgument, 0,
                                output + ": output is '" + ref + "', which the input names; refusing to overwrite it");
    }
    return Result::success();
}

}  // namespace cwbvh

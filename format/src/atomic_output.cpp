// AtomicOutput (file_io.h): a temporary file beside the output, renamed over it when complete.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <utility>

#include "cwbvh/format/file_io.h"

namespace cwbvh {

std::string output_target(const std::string& path) {
    // A dangling link gets its target created. Chains are followed (40 links, as the kernel).
    // No lexical normalisation: "dir/.." must stay for the kernel to resolve through a
    // symlinked dir, as check_output_path's same_file does (dropping it lexically wrote
    // another file than the one checked, and could replace an input).
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::path p = path;
    for (int hops = 0; hops < 40 && fs::is_symlink(fs::symlink_status(p, ec)); ++hops) {
        const fs::path target = fs::read_symlink(p, ec);
        if (ec) break;
        p = target.is_absolute() ? target : p.parent_path() / target;
    }
    return p.string();
}

Expected<AtomicOutput> AtomicOutput::create(const std::string& path) {
    static std::atomic<uint64_t> counter{0};
    AtomicOutput out;
    // An output that is a symlink is written through: the file it names is replaced, and the
    // link stays (a rename over the link would replace the link itself).
    out.path_ = output_target(path);
    out.tmp_ = out.path_ + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(counter++);
    out.fd_ = ::open(out.tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (out.fd_ < 0) {
        const int e = errno;
        out.tmp_.clear();  // nothing was created: nothing to remove
        return fail(rule::kOpenFailed, path + ": cannot create " + out.path_ + ".tmp.*: " + std::strerror(e));
    }
    // A file that is replaced keeps its permission bits (not its owner, ACLs or other hard
    // links: the output is a new file).
    struct stat old {};
    if (::stat(out.path_.c_str(), &old) == 0) (void)::fchmod(out.fd_, old.st_mode & 07777);
    return out;
}

AtomicOutput::AtomicOutput(AtomicOutput&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), path_(std::move(other.path_)), tmp_(std::exchange(other.tmp_, {})) {}

AtomicOutput& AtomicOutput::operator=(AtomicOutput&& other) noexcept {
    if (this != &other) {
        discard();
        fd_ = std::exchange(other.fd_, -1);
        path_ = std::move(other.path_);
        tmp_ = std::exchange(other.tmp_, {});
    }
    return *this;
}

AtomicOutput::~AtomicOutput() { discard(); }

void AtomicOutput::discard() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    if (!tmp_.empty()) ::unlink(tmp_.c_str());
    tmp_.clear();
}

Result AtomicOutput::write(const void* data, uint64_t n) {
    if (fd_ < 0) return fail(rule::kWriteFailed, path_ + ": write after the output was closed");
    const auto* p = static_cast<const uint8_t*>(data);
    while (n > 0) {
        const ssize_t k = ::write(fd_, p, size_t(std::min<uint64_t>(n, uint64_t(1) << 30)));
        if (k < 0) {
            if (errno == EINTR) continue;
            const int e = errno;
            discard();
            return fail(rule::kWriteFailed, path_ + ": write failed: " + std::strerror(e));
        }
        p += k;
        n -= uint64_t(k);
    }
    return Result::success();
}

Result AtomicOutput::commit() {
    if (fd_ < 0) return fail(rule::kWriteFailed, path_ + ": commit after the output was closed");
    const int fd = std::exchange(fd_, -1);
    if (::close(fd) != 0) {
        const int e = errno;
        discard();
        return fail(rule::kWriteFailed, path_ + ": close failed: " + std::strerror(e));
    }
    if (std::rename(tmp_.c_str(), path_.c_str()) != 0) {
        const int e = errno;
        discard();
        return fail(rule::kWriteFailed, path_ + ": cannot rename the temporary file over it: " + std::strerror(e));
    }
    tmp_.clear();
    return Result::success();
}

Result write_file_atomic(const std::string& path, const void* data, uint64_t n) {
    Expected<AtomicOutput> out = AtomicOutput::create(path);
    if (!out.ok()) return out.error();
    if (Result r = out->write(data, n); !r.ok()) return r;
    return out->commit();
}

}  // namespace cwbvh

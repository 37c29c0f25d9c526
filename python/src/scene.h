// The Python Scene's state: a validated, mapped File shared by every call that uses it (a trace
// in flight, a zero-copy view of VERT/INDX) and, after to_device(), its DeviceScene. close()
// drops the Scene's own reference; calls in flight and views keep the mapping until they end.
#pragma once

#include <memory>
#include <mutex>
#include <string>

#include "common.h"
#include "cwbvh/kernels/device_scene.h"
#include "cwbvh/loader/loader.h"

namespace cwbvh::python {

class SceneHandle {
public:
    explicit SceneHandle(File file) : file_(std::make_shared<const File>(std::move(file))) {}

    /// The file; ValueError("... Scene is closed") after close().
    std::shared_ptr<const File> file() const;
    /// The device copy, or nullptr before to_device() (and after close()).
    std::shared_ptr<const DeviceScene> device() const;
    void set_device(std::shared_ptr<const DeviceScene> device);
    void close();
    bool closed() const;
    const std::string& path() const { return path_; }
    void set_path(std::string path) { path_ = std::move(path); }

private:
    mutable std::mutex mutex_;
    std::shared_ptr<const File> file_;
    std::shared_ptr<const DeviceScene> device_;
    std::string path_;
};

}  // namespace cwbvh::python

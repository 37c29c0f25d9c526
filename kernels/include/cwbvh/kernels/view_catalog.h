// The catalog of benchmark viewpoints (views/catalog.txt; format in spec/rays.md,
// "View catalog"): named pinhole cameras per scene, read by `cwbvh rays --view`,
// cwbvh_gpu_check and bench/run.py, so every benchmark looks at a scene from the
// same places (inside the enclosed scenes). A scene without catalog views uses
// default_camera (ray_gen.h). Host only. Library: cwbvh_cpu_trace.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "cwbvh/format/format.h"
#include "cwbvh/kernels/ray_gen.h"

namespace cwbvh {

/// The catalog format version this build reads ("cwbvh-views 1").
inline constexpr int kViewCatalogVersion = 1;

struct View {
    std::string scene;  ///< scene key: the stem of the input file ("sponza_dabrovic")
    std::string name;   ///< unique within its scene; starts with a letter
    Camera camera;
    uint32_t line = 0;  ///< line in the catalog; 0 for the default camera
};

class ViewCatalog {
public:
    /// Parses catalog text. On bad input returns false with one line
    /// "<source>:<line>: <what is wrong>" in `error` (`out` is left unchanged).
    [[nodiscard]] static bool parse(const std::string& text, const std::string& source, ViewCatalog& out,
                                    std::string& error);
    /// Reads and parses `path`; "<path>: cannot read: <reason>" when it cannot be read.
    [[nodiscard]] static bool load(const std::string& path, ViewCatalog& out, std::string& error);

    const std::string& source() const { return source_; }
    const std::vector<View>& views() const { return views_; }
    bool has_scene(const std::string& scene) const;
    /// The views of `scene` in catalog order; empty when the scene is not in the catalog.
    std::vector<View> views_of(const std::string& scene) const;
    /// `which` is a view name or a 1-based index (decimal digits) among the views of
    /// `scene`. False with a one-line error naming the scene's views otherwise.
    [[nodiscard]] bool find(const std::string& scene, const std::string& which, View& out, std::string& error) const;

private:
    std::string source_;
    std::vector<View> views_;
};

/// The catalog a tool reads by default: $CWBVH_VIEWS when set and non-empty, else
/// the path compiled in (CWBVH_VIEW_CATALOG: the source tree's views/catalog.txt).
std::string default_view_catalog_path();

enum class CatalogLoad {
    kLoaded,  ///< `out` holds the catalog
    kAbsent,  ///< the compiled-in default catalog does not exist (an installed tool without
              ///< its source tree): use default cameras; `error` says why
    kError,   ///< a named catalog (--views, $CWBVH_VIEWS) is unreadable, or any catalog is malformed
};

/// Loads the catalog a tool uses: `path` when non-empty (a --views option), else
/// default_view_catalog_path(). Only the compiled-in default may be absent.
CatalogLoad load_view_catalog(const std::string& path, ViewCatalog& out, std::string& error);

/// Scene key of a path: the file name without its directories and its last
/// extension ("scenes/sponza_dabrovic.cwbvh" -> "sponza_dabrovic").
std::string scene_key(const std::string& path);

/// The views a benchmark uses for `scene`: the catalog's, or, for a scene not in the
/// catalog, one view "default" = default_camera(bounds) with line 0.
std::vector<View> benchmark_views(const ViewCatalog& catalog, const std::string& scene, const SceneBounds& bounds);

/// "ex,ey,ez,tx,ty,tz,fov" with each number printed so that it reads back exactly
/// (parse_camera(format_camera(c)) == c).
std::string format_camera(const Camera& camera);

}  // namespace cwbvh

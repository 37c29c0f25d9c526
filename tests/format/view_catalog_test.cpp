// The benchmark view catalog (kernels view_catalog.h, views/catalog.txt): parser
// errors, lookup, the default-camera fallback, the shipped catalog, and
// `cwbvh rays --view`.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "cwbvh/kernels/view_catalog.h"
#include "format/test_util.h"

namespace cwbvh {
namespace {

constexpr const char* kGood =
    "cwbvh-views 1   # the header\n"
    "# a comment line\n"
    "\n"
    "scene_a   first   -12,3,0,10,5,0,70   # trailing comment\n"
    "scene_a   second  1,2,3,4,5,6,45\n"
    "scene_b   first   0,-1000,500,0,1000,500,80\r\n"
    "\t scene_a third-view 1e1,2.5,-3,0,0,0,10\n";

ViewCatalog parse_ok(const std::string& text) {
    ViewCatalog c;
    const Result r = ViewCatalog::parse(text, "t.txt", c);
    EXPECT_TRUE(r.ok()) << r.message;
    return c;
}

/// The error of a catalog that must not parse.
std::string parse_error(const std::string& text) {
    ViewCatalog c;
    const Result r = ViewCatalog::parse(text, "t.txt", c);
    EXPECT_FALSE(r.ok()) << "parsed: " << text;
    const std::string& err = r.message;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 0) << err;
    return err;
}

bool starts_with(const std::string& s, const std::string& p) { return s.rfind(p, 0) == 0; }

TEST(ViewCatalog, ParsesViewsCommentsAndBlankLines) {
    const ViewCatalog c = parse_ok(kGood);
    ASSERT_EQ(c.views().size(), 4u);
    EXPECT_EQ(c.source(), "t.txt");
    const std::vector<View> a = c.views_of("scene_a");
    ASSERT_EQ(a.size(), 3u);
    EXPECT_EQ(a[0].name, "first");
    EXPECT_EQ(a[0].line, 4u);
    EXPECT_EQ(a[0].camera.eye[0], -12.0f);
    EXPECT_EQ(a[0].camera.target[1], 5.0f);
    EXPECT_EQ(a[0].camera.fov_deg, 70.0f);
    EXPECT_EQ(a[1].name, "second");
    EXPECT_EQ(a[2].name, "third-view");
    EXPECT_EQ(a[2].line, 7u);
    EXPECT_EQ(a[2].camera.eye[0], 10.0f);
    EXPECT_EQ(c.views_of("scene_b").size(), 1u);  // the same view name in another scene is fine
    EXPECT_TRUE(c.has_scene("scene_b"));
    EXPECT_FALSE(c.has_scene("scene_c"));
    EXPECT_TRUE(c.views_of("scene_c").empty());
    EXPECT_TRUE(parse_ok("cwbvh-views 1").views().empty());  // header only, no newline
}

TEST(ViewCatalog, FindsByNameAndOneBasedIndex) {
    const ViewCatalog c = parse_ok(kGood);
    View v;
    Result r = c.find("scene_a", "second", v);
    const std::string& err = r.message;
    ASSERT_TRUE(r.ok()) << err;
    EXPECT_EQ(v.camera.eye[2], 3.0f);
    r = c.find("scene_a", "3", v);
    ASSERT_TRUE(r.ok()) << err;
    EXPECT_EQ(v.name, "third-view");
    r = c.find("scene_a", "1", v);
    ASSERT_TRUE(r.ok()) << err;
    EXPECT_EQ(v.name, "first");
    for (const char* bad : {"0", "4", "99999999999999999999", "nope", "First"}) {
        r = c.find("scene_a", bad, v);
        EXPECT_FALSE(r.ok()) << bad;
        EXPECT_NE(err.find("scene 'scene_a'"), std::string::npos) << err;
        EXPECT_NE(err.find("1 first, 2 second, 3 third-view"), std::string::npos) << err;
    }
    r = c.find("scene_c", "1", v);
    EXPECT_FALSE(r.ok());
    EXPECT_NE(err.find("scene 'scene_c' has no views in t.txt"), std::string::npos) << err;
}

TEST(ViewCatalog, RejectsBadHeaders) {
    EXPECT_TRUE(starts_with(parse_error(""), "t.txt:1: expected the header 'cwbvh-views 1'"));
    EXPECT_TRUE(starts_with(parse_error("\ncwbvh-views 1\n"), "t.txt:1: expected the header"));
    EXPECT_TRUE(starts_with(parse_error("# comment first\ncwbvh-views 1\n"), "t.txt:1: expected the header"));
    EXPECT_TRUE(starts_with(parse_error("cwbvh-view 1\n"), "t.txt:1: expected the header"));
    EXPECT_TRUE(starts_with(parse_error("cwbvh-views\n"), "t.txt:1: expected the header"));
    EXPECT_TRUE(starts_with(parse_error("cwbvh-views 1 extra\n"), "t.txt:1: expected the header"));
    EXPECT_TRUE(starts_with(parse_error("s v 1,2,3,4,5,6,45\n"), "t.txt:1: expected the header"));
    const std::string v2 = parse_error("cwbvh-views 2\ns v 1,2,3,4,5,6,45\n");
    EXPECT_TRUE(starts_with(v2, "t.txt:1: unsupported catalog version '2'")) << v2;
    EXPECT_NE(v2.find("reads cwbvh-views 1"), std::string::npos) << v2;
}

TEST(ViewCatalog, RejectsBadNumbers) {
    const std::string head = "cwbvh-views 1\n# c\n";
    for (const char* cam : {"1,2,x,4,5,6,45", "1,2,3,4,5,6", "1,2,3,4,5,6,45,7", "1,2,3,4,5,6,45,", "1,,3,4,5,6,45",
                            "1,2,3,4,5,6,0", "1,2,3,4,5,6,180", "1,2,3,1,2,3,45", "1e39,2,3,4,5,6,45",
                            "nan,2,3,4,5,6,45", "0x10,2,3,4,5,6,45"}) {
        const std::string e = parse_error(head + "scene view " + cam + "\n");
        EXPECT_TRUE(starts_with(e, "t.txt:3: camera")) << cam << ": " << e;
    }
    constexpr char kNul[] = "s v 1,2,3,4,5,6,45\0junk\n";
    const std::string nul = parse_error(head + std::string(kNul, sizeof kNul - 1));
    EXPECT_TRUE(starts_with(nul, "t.txt:3: NUL byte")) << nul;
}

TEST(ViewCatalog, RejectsWrongFieldCounts) {
    const std::string head = "cwbvh-views 1\n";
    const std::string two = parse_error(head + "scene 1,2,3,4,5,6,45\n");
    EXPECT_EQ(two, "t.txt:2: expected 3 fields 'SCENE VIEW ex,ey,ez,tx,ty,tz,fov', got 2");
    const std::string four = parse_error(head + "\nscene view 1,2,3 4,5,6,45\n");
    EXPECT_EQ(four, "t.txt:3: expected 3 fields 'SCENE VIEW ex,ey,ez,tx,ty,tz,fov', got 4");
    EXPECT_TRUE(starts_with(parse_error(head + "scene\n"), "t.txt:2: expected 3 fields"));
}

TEST(ViewCatalog, RejectsBadNamesAndDuplicates) {
    const std::string head = "cwbvh-views 1\n";
    EXPECT_TRUE(starts_with(parse_error(head + "s 1view 1,2,3,4,5,6,45\n"), "t.txt:2: view name '1view'"));
    EXPECT_TRUE(starts_with(parse_error(head + "s 7 1,2,3,4,5,6,45\n"), "t.txt:2: view name '7'"));
    EXPECT_TRUE(starts_with(parse_error(head + "s a/b 1,2,3,4,5,6,45\n"), "t.txt:2: view name 'a/b'"));
    EXPECT_TRUE(starts_with(parse_error(head + "a/b v 1,2,3,4,5,6,45\n"), "t.txt:2: scene key 'a/b'"));
    const std::string dup = parse_error(head + "s v 1,2,3,4,5,6,45\nt v 1,2,3,4,5,6,45\n\ns v 9,2,3,4,5,6,45\n");
    EXPECT_EQ(dup, "t.txt:5: duplicate view 'v' of scene 's' (first on line 2)");
}

TEST(ViewCatalog, UnknownSceneFallsBackToTheDefaultCamera) {
    const ViewCatalog c = parse_ok(kGood);
    const SceneBounds b{{-1, -2, -3}, {4, 5, 6}};
    const std::vector<View> d = benchmark_views(c, "not_listed", b);
    ASSERT_EQ(d.size(), 1u);
    EXPECT_EQ(d[0].name, "default");
    EXPECT_EQ(d[0].line, 0u);
    const Camera want = default_camera(b);
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(d[0].camera.eye[a], want.eye[a]);
        EXPECT_EQ(d[0].camera.target[a], want.target[a]);
    }
    EXPECT_EQ(d[0].camera.fov_deg, want.fov_deg);
    const std::vector<View> a = benchmark_views(c, "scene_a", b);
    ASSERT_EQ(a.size(), 3u);
    EXPECT_EQ(a[1].name, "second");
}

TEST(ViewCatalog, LoadNamesTheFileAndCatalogPathRules) {
    ViewCatalog c;
    Result r;
    const std::string& err = r.message;
    CatalogLoad loaded = CatalogLoad::kError;
    const std::string missing = test::temp_dir() + "/no_such_catalog.txt";
    r = ViewCatalog::load(missing, c);
    EXPECT_FALSE(r.ok());
    EXPECT_TRUE(starts_with(err, missing + ": cannot open")) << err;
    // A named catalog (--views) must exist; only the compiled-in default may be absent.
    r = load_view_catalog(missing, c, loaded);
    EXPECT_EQ(loaded, CatalogLoad::kError);
    const std::string bad = test::write_temp("bad_catalog.txt", {'x', '\n'});
    r = load_view_catalog(bad, c, loaded);
    EXPECT_EQ(loaded, CatalogLoad::kError);
    EXPECT_TRUE(starts_with(err, bad + ":1: expected the header")) << err;
    const std::string good_text = kGood;
    const std::string good = test::write_temp("good_catalog.txt", {good_text.begin(), good_text.end()});
    r = load_view_catalog(good, c, loaded);
    ASSERT_EQ(loaded, CatalogLoad::kLoaded) << err;
    EXPECT_EQ(c.source(), good);
    EXPECT_EQ(c.views().size(), 4u);
    // $CWBVH_VIEWS replaces the compiled-in path, and is then a named catalog.
    ::setenv("CWBVH_VIEWS", good.c_str(), 1);
    EXPECT_EQ(default_view_catalog_path(), good);
    r = load_view_catalog("", c, loaded);
    EXPECT_EQ(loaded, CatalogLoad::kLoaded) << err;
    ::setenv("CWBVH_VIEWS", missing.c_str(), 1);
    r = load_view_catalog("", c, loaded);
    EXPECT_EQ(loaded, CatalogLoad::kError);
    ::unsetenv("CWBVH_VIEWS");
    EXPECT_EQ(default_view_catalog_path(), std::string(CWBVH_SOURCE_DIR) + "/views/catalog.txt");
}

TEST(ViewCatalog, SceneKeyAndCameraText) {
    EXPECT_EQ(scene_key("a/b/sponza_dabrovic.cwbvh"), "sponza_dabrovic");
    EXPECT_EQ(scene_key("../shared/scenes/dragon_loop1_draco.glb"), "dragon_loop1_draco");
    EXPECT_EQ(scene_key("bunny"), "bunny");
    EXPECT_EQ(scene_key("x.y.obj"), "x.y");
    EXPECT_EQ(scene_key(".hidden"), ".hidden");
    const ViewCatalog c = parse_ok(kGood);
    EXPECT_EQ(format_camera(c.views()[0].camera), "-12,3,0,10,5,0,70");
    Camera odd;
    const float v[7] = {0.1f, 1e-7f, -1.0e38f, 16777217.0f, 1.0f / 3.0f, 123456.789f, 89.99999f};
    std::copy(v, v + 3, odd.eye);
    std::copy(v + 3, v + 6, odd.target);
    odd.fov_deg = v[6];
    Camera back;
    const Result r = parse_camera(format_camera(odd), back);
    ASSERT_TRUE(r.ok()) << r.message << " " << format_camera(odd);
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(back.eye[a], odd.eye[a]);
        EXPECT_EQ(back.target[a], odd.target[a]);
    }
    EXPECT_EQ(back.fov_deg, odd.fov_deg);
}

// ---- the shipped catalog ---------------------------------------------------------------

struct Box {
    const char* scene;
    float lo[3], hi[3];
};
// Bounding boxes of the enclosed scenes, from ../shared/scenes/SCENES.md.
constexpr Box kEnclosed[] = {
    {"sponza_dabrovic", {-17.403f, -0.90669f, -7.7985f}, {17.417f, 15.653f, 7.8015f}},
    {"oa_dm5", {9.2683f, -1072.0f, -150.06f}, {1368.0f, 864.27f, 384.0f}},
    {"oa_oacmpctf3", {-4024.0f, -1464.0f, -1016.0f}, {4024.0f, 1464.0f, 2488.0f}},
};

ViewCatalog shipped() {
    ViewCatalog c;
    const Result r = ViewCatalog::load(std::string(CWBVH_SOURCE_DIR) + "/views/catalog.txt", c);
    EXPECT_TRUE(r.ok()) << r.message;
    return c;
}

TEST(ShippedViewCatalog, ParsesWithOneToThreeViewsPerScene) {
    const ViewCatalog c = shipped();
    ASSERT_FALSE(c.views().empty());
    for (const View& v : c.views()) {
        const size_t n = c.views_of(v.scene).size();
        EXPECT_GE(n, 1u);
        EXPECT_LE(n, 3u) << v.scene;
    }
    for (const char* s : {"bunny", "dragon", "sponza_dabrovic", "oa_oacmpctf3", "oa_dm5", "fg_cg57"})
        EXPECT_TRUE(c.has_scene(s)) << s;
    // The rest of the GPU set (scripts/make-gpu-inputs.sh, issue 18), the DERIVED composite included.
    for (const char* s : {"dense_dragons", "dragon_loop1_draco", "kicad_board", "derived_board_dragons"})
        EXPECT_TRUE(c.has_scene(s)) << s;
}

TEST(ShippedViewCatalog, KeepsTheViewsOfTheMeasuredGpuFigures) {
    const ViewCatalog c = shipped();
    View v;
    Result r = c.find("sponza_dabrovic", "1", v);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_EQ(format_camera(v.camera), "-12,3,0,10,5,0,70");
    r = c.find("oa_oacmpctf3", "1", v);
    ASSERT_TRUE(r.ok()) << r.message;
    EXPECT_EQ(format_camera(v.camera), "0,-1000,500,0,1000,500,80");
}

TEST(ShippedViewCatalog, EnclosedScenesAreSeenFromInside) {
    const ViewCatalog c = shipped();
    for (const Box& b : kEnclosed) {
        const std::vector<View> vs = c.views_of(b.scene);
        EXPECT_FALSE(vs.empty()) << b.scene;
        for (const View& v : vs) {
            for (int a = 0; a < 3; ++a) {
                EXPECT_GT(v.camera.eye[a], b.lo[a]) << b.scene << " " << v.name << " axis " << a;
                EXPECT_LT(v.camera.eye[a], b.hi[a]) << b.scene << " " << v.name << " axis " << a;
            }
        }
    }
}

// ---- cwbvh rays --view -----------------------------------------------------------------

using test::ToolRun;
ToolRun run_tool(const std::string& args) { return test::run_cwbvh(args); }
size_t lines(const std::string& s) { return test::count_lines(s); }

TEST(RaysView, PicksCatalogViewsByNameIndexAndDefault) {
    const std::string file = test::write_temp("rays_views_scene.cwbvh", test::synthetic_file());
    const std::string text =
        "cwbvh-views 1\n"
        "rays_views_scene  near  1,2,3,0,0,0,40\n"
        "rays_views_scene  far   10,20,30,0,0,0,40\n";
    const std::string cat = test::write_temp("rays_views.txt", {text.begin(), text.end()});
    const std::string out = test::temp_dir() + "/rays_views.rays";
    const std::string base = "rays " + file + " --primary --width 4 --height 4 --views " + cat + " -o " + out;

    ToolRun r = run_tool(base);
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: rays_views_scene near (first of 2, " + cat + ":2): 1,2,3,0,0,0,40"),
              std::string::npos)
        << r.out;
    r = run_tool(base + " --view far");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: rays_views_scene far (" + cat + ":3): 10,20,30,0,0,0,40"), std::string::npos)
        << r.out;
    r = run_tool(base + " --view 2 --diffuse");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("rays_views_scene far"), std::string::npos) << r.out;
    r = run_tool(base + " --camera 5,5,5,0,0,0,30");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: --camera: 5,5,5,0,0,0,30"), std::string::npos) << r.out;
    r = run_tool(base + " --scene other");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: default camera (scene 'other' not in " + cat + ")"), std::string::npos) << r.out;
}

TEST(RaysView, BadViewIsAOneLineUsageError) {
    const std::string file = test::write_temp("rays_badview.cwbvh", test::synthetic_file());
    const std::string text = "cwbvh-views 1\nrays_badview only 1,2,3,0,0,0,40\n";
    const std::string cat = test::write_temp("rays_badview.txt", {text.begin(), text.end()});
    const std::string base = "rays " + file + " --primary --width 4 --height 4 --views " + cat + " -o " +
                             test::temp_dir() + "/rays_badview.rays";
    for (const char* v : {"nope", "2", "0"}) {
        const ToolRun r = run_tool(base + " --view " + v);
        EXPECT_EQ(r.code, 2) << v << ": " << r.out;
        EXPECT_EQ(lines(r.out), 1u) << r.out;
        EXPECT_TRUE(starts_with(r.out, "cwbvh: error: rays: --view: ")) << r.out;
    }
    ToolRun r = run_tool(base + " --view only --camera 1,2,3,0,0,0,40");
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(lines(r.out), 1u) << r.out;
    // A scene outside the catalog has one view, the default camera: 1 and "default" name it
    // (as Python's cwbvh.view); any other is a usage error.
    for (const char* v : {"1", "01", "default"}) {
        r = run_tool(base + " --scene elsewhere --view " + v);
        EXPECT_EQ(r.code, 0) << v << ": " << r.out;
    }
    for (const char* v : {"2", "only", "0"}) {
        r = run_tool(base + " --scene elsewhere --view " + v);
        EXPECT_EQ(r.code, 2) << v << ": " << r.out;
        EXPECT_EQ(lines(r.out), 1u) << r.out;
    }
    // A malformed or missing named catalog is bad input (exit 1), one line naming file and line.
    const std::string bad_text = "cwbvh-views 1\nrays_badview only 1,2,3\n";
    const std::string bad = test::write_temp("rays_badcat.txt", {bad_text.begin(), bad_text.end()});
    r = run_tool("rays " + file + " --primary --views " + bad + " -o " + test::temp_dir() + "/x.rays");
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_EQ(lines(r.out), 1u) << r.out;
    EXPECT_NE(r.out.find(bad + ":2: camera"), std::string::npos) << r.out;
    r = run_tool("rays " + file + " --primary --views " + test::temp_dir() + "/none.txt -o " + test::temp_dir() +
                 "/x.rays");
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_EQ(lines(r.out), 1u) << r.out;
}

TEST(RaysView, TheShippedCatalogIsTheDefault) {
    // A file whose stem is a catalog scene gets that scene's first view without --views.
    const std::string file = test::write_temp("sponza_dabrovic.cwbvh", test::synthetic_file());
    const ToolRun r = run_tool("rays " + file + " --primary --width 4 --height 4 -o " + test::temp_dir() +
                               "/sponza.rays");
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: sponza_dabrovic nave (first of "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(std::string(CWBVH_SOURCE_DIR) + "/views/catalog.txt:"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("): -12,3,0,10,5,0,70\n"), std::string::npos) << r.out;
}

// `cwbvh render` takes its camera by the same rule (camera_choice.h): the scene's first
// catalog view by default (inside Sponza and the game levels, where a camera framing the
// bounds would look at the sky box from outside), --view, --camera, and the same errors.
TEST(RenderView, RendersFromTheCatalogLikeRays) {
    const std::string file = test::write_temp("sponza_dabrovic.cwbvh", test::synthetic_file());
    const std::string png = test::temp_dir() + "/render_view.png";
    ToolRun r = run_tool("render " + file + " --width 4 --height 4 -o " + png);
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: sponza_dabrovic nave (first of "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("): -12,3,0,10,5,0,70\n"), std::string::npos) << r.out;
    const std::string text = "cwbvh-views 1\nsponza_dabrovic a 1,2,3,0,0,0,40\nsponza_dabrovic b 4,5,6,0,0,0,40\n";
    const std::string cat = test::write_temp("render_views.txt", {text.begin(), text.end()});
    r = run_tool("render " + file + " --width 4 --height 4 --views " + cat + " --view b -o " + png);
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: sponza_dabrovic b (" + cat + ":3): 4,5,6,0,0,0,40"), std::string::npos) << r.out;
    r = run_tool("render " + file + " --width 4 --height 4 --scene elsewhere -o " + png);
    EXPECT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("view: default camera (scene 'elsewhere' not in "), std::string::npos) << r.out;
    for (const std::string bad : {" --view 9", " --view b --camera 1,2,3,0,0,0,40", " --view"}) {
        r = run_tool("render " + file + " --width 4 --height 4 --views " + cat + " -o " + png + bad);
        EXPECT_EQ(r.code, 2) << bad << ": " << r.out;
        EXPECT_EQ(lines(r.out), 1u) << r.out;
        EXPECT_TRUE(starts_with(r.out, "cwbvh: error: render: ")) << r.out;
    }
    // The catalog is an input: the image may not overwrite it.
    r = run_tool("render " + file + " --views " + cat + " -o " + cat);
    EXPECT_EQ(r.code, 1) << r.out;
    std::ifstream in(cat, std::ios::binary);
    EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), text);
}

}  // namespace
}  // namespace cwbvh

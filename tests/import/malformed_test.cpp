// Regression tests for malformed inputs found by fuzzing the importers
// (compiler/fuzz/fuzz_import.cpp). Each used to abort, exhaust memory or
// loop inside OpenMesh 9.0; each must now give a one-line error naming the
// file and what is wrong.
#include <cmath>
#include <cstdint>
#include <cstring>

#include "import/import_test_util.h"

namespace cwbvh::compiler::test {
namespace {

bool contains(const std::string& s, const std::string& what) {
    return s.find(what) != std::string::npos;
}

// OpenMesh's OBJ reader asserted `!vhandles.empty()` (abort) on a face vertex
// with a texture index but no position index.
TEST(Malformed, ObjFaceVertexWithoutPositionIndexIsAnError) {
    TempDir dir;
    for (const char* face : {"f /1 2 3\n", "f /1/ 2 3\n", "f 1 2 3\nf\t/2/1 1 3\n"}) {
        const std::string p = dir.write("slash.obj", std::string("v 0 0 0\nv 1 0 0\nv 0 1 0\n") + face);
        const auto r = import_files({p});
        ASSERT_FALSE(r.ok) << face;
        EXPECT_TRUE(contains(r.error, p + ": OBJ line ")) << r.error;
        EXPECT_TRUE(contains(r.error, "has no position index")) << r.error;
        EXPECT_EQ(r.error.find('\n'), std::string::npos);
    }
    // Position-less vertex references stay fine when a position is given.
    const auto ok = import_files({dir.write(
        "ok.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1 2//1 3/1\n")});
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.scene.triangle_count(), 1u);
}

// Huge counts in the OFF header: OpenMesh reserved them up front (16 GB for
// 4e9 faces; the assimp sample OutOfMemory.off asks for ~17 GB of vertices).
TEST(Malformed, OffHugeHeaderCountsAreAnError) {
    TempDir dir;
    const std::string tail = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    for (const std::string& counts : {std::string("3 4000000000 0"), std::string("4000000000 1 0"),
                                      std::string("35353523535358 6 0")}) {
        const std::string p = dir.write("huge.off", "OFF\n" + counts + "\n" + tail);
        const auto r = import_files({p});
        ASSERT_FALSE(r.ok) << counts;
        EXPECT_TRUE(contains(r.error, p + ": OFF header ")) << r.error;
    }
}

// A face announcing 4e9 vertices: OpenMesh pushed 4e9 handles after the
// stream ended (out of memory / practically endless).
TEST(Malformed, OffFaceWithHugeVertexCountIsAnError) {
    TempDir dir;
    const std::string p = dir.write("k.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n");
    const auto r = import_files({p});
    ASSERT_FALSE(r.ok);
    EXPECT_EQ(r.error, p + ": OFF face 0: a face of 4000000000 vertices (at most 65536 per polygon)");
}

// Truncated or unparsable OFF bodies: OpenMesh kept looping over the
// announced elements with a failed stream (stale indices).
TEST(Malformed, OffTruncatedOrGarbageBodyIsAnError) {
    TempDir dir;
    struct Case {
        const char* text;
        const char* error;
    };
    const Case cases[] = {
        {"OFF\n3 2000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "OFF header declares 3 vertices and 2000 faces"},
        {"OFF\n3 20 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "at face 1 of 20"},
        {"OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n", "at vertex 3 of 4"},
        {"OFF\n3 1 0\n0 0 zz\n1 0 0\n0 1 0\n3 0 1 2\n",
         "OFF line 3: vertex 0 ('0 0 zz') has 'zz' where OpenMesh's reader reads number 3 of its 3"},
        {"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "at face 0 of 1"},
        {"OFF\n3\n", "OFF header has missing or invalid"},
    };
    for (const Case& c : cases) {
        const std::string p = dir.write("t.off", c.text);
        const auto r = import_files({p});
        ASSERT_FALSE(r.ok) << c.text;
        EXPECT_TRUE(contains(r.error, p + ": ")) << r.error;
        EXPECT_TRUE(contains(r.error, c.error)) << r.error;
    }
}

std::string u32(uint32_t v) {
    std::string s(4, '\0');
    std::memcpy(s.data(), &v, 4);
    return s;
}
std::string f32(float v) {
    std::string s(4, '\0');
    std::memcpy(s.data(), &v, 4);
    return s;
}

TEST(Malformed, OffBinaryLoadsAndTruncatedOrHugeIsAnError) {
    TempDir dir;
    std::string body = u32(3) + u32(1) + u32(0);
    for (float c : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) body += f32(c);
    const std::string face = u32(3) + u32(0) + u32(1) + u32(2);
    const auto ok = import_files({dir.write("b.off", "OFF BINARY\n" + body + face)});
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.scene.triangle_count(), 1u);

    const std::string p = dir.write("t.off", "OFF BINARY\n" + body + face.substr(0, 10));
    const auto truncated = import_files({p});
    ASSERT_FALSE(truncated.ok);
    EXPECT_EQ(truncated.error, p + ": OFF file is truncated or unparsable at face 0 of 1");

    const auto huge = import_files(
        {dir.write("h.off", "OFF BINARY\n" + u32(3) + u32(0xFFFFFFFFu) + u32(0) + body.substr(12) + face)});
    ASSERT_FALSE(huge.ok);
    EXPECT_TRUE(contains(huge.error, "OFF header declares")) << huge.error;
}

// The OFF variants OpenMesh reads keep loading (normals / colours per line).
TEST(Malformed, OffVariantsStillLoad) {
    TempDir dir;
    const auto noff = import_files({dir.write(
        "n.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n")});
    ASSERT_TRUE(noff.ok) << noff.error;
    EXPECT_EQ(noff.scene.triangle_count(), 1u);
    const auto coff = import_files({dir.write(
        "c.off", "COFF\n3 1 0\n0 0 0 255 0 0\n1 0 0 0 255 0\n0 1 0 0 0 255\n3 0 1 2 9 9 9\n")});
    ASSERT_TRUE(coff.ok) << coff.error;
    EXPECT_EQ(coff.scene.triangle_count(), 1u);
    // No trailing newline after the last face.
    const auto bare = import_files({dir.write("e.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2")});
    ASSERT_TRUE(bare.ok) << bare.error;
}

// OpenMesh's PLY header parser is token-based: "1.0\x1a" glued to "element"
// made the next "property" call elements_.back() on an empty vector (SEGV);
// a non-numeric version made it loop forever on a failed stream.
TEST(Malformed, PlyHeaderTokensOpenMeshCannotParseAreAnError) {
    TempDir dir;
    const std::string rest =
        " vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    struct Case {
        std::string text, error;
    };
    const Case cases[] = {
        {"ply\nformat ascii 1.0\x1a" "element" + rest, "PLY header has a property before any element"},
        {"ply\nformat ascii x\nelement" + rest, "PLY header has no valid 'format"},
        {"ply\nformat ascii 1.0\nelement vertex zz\nproperty float x\nend_header\n",
         "PLY header is malformed or has no end_header"},
    };
    for (const Case& c : cases) {
        const std::string p = dir.write("h.ply", c.text);
        const auto r = import_files({p});
        ASSERT_FALSE(r.ok) << c.text;
        EXPECT_EQ(r.error.rfind(p + ": " + c.error, 0), 0u) << r.error;
    }
    const auto ok = import_files({dir.write("ok.ply", "ply\nformat ascii 1.0\nelement" + rest)});
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.scene.triangle_count(), 1u);
}

// OpenMesh's OBJ reader drops a `v` line whose x y z do not parse as floats (nan, inf,
// beyond float, two numbers, "1,0"): every later index then names the next vertex, and
// the file compiled to wrong geometry with exit 0. Found by a hostile-input audit.
TEST(Malformed, ObjVertexTheReaderWouldDropIsAnError) {
    TempDir dir;
    for (const char* v : {"v nan 5 5", "v inf 0 0", "v -nan 0 0", "v 1e39 0 0", "v 1 2", "v 1,0 0 0", "v a b c",
                          "v 0x1p3 0 0"}) {
        const std::string p =
            dir.write("v.obj", std::string("v 0 0 0\n") + v + "\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 4\n");
        const auto r = import_files({p});
        ASSERT_FALSE(r.ok) << v;
        EXPECT_EQ(r.error.rfind(p + ": OBJ line 2: vertex '" + v + "' is not three finite float numbers", 0), 0u)
            << r.error;
        EXPECT_EQ(r.error.find('\n'), std::string::npos);
    }
    // What the reader does read stays fine: w and colours after x y z, tabs, exponents, CRLF.
    const auto ok = import_files({dir.write(
        "ok.obj", "v 0 0 0 1\r\nv\t1e0 0 0 0.5 0.5 0.5\nv 0 1.0E+0 -0\nf 1 2 3\n")});
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.scene.triangle_count(), 1u);
}

// A polygon of more vertices than kMaxFaceVertices: OpenMesh's add_face compares its
// vertices pairwise (45 s for one face of 300k vertices). OBJ, ASCII PLY, OFF.
TEST(Malformed, HugePolygonIsAnError) {
    TempDir dir;
    const uint32_t n = 65537;
    std::string verts, face = "f", list = "65537";
    for (uint32_t i = 0; i < n; ++i) {
        const double a = 6.283185307179586 * i / n;
        verts += std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0\n";
        face += " " + std::to_string(i + 1);
        list += " " + std::to_string(i);
    }
    std::string obj_verts;
    for (size_t i = 0, j = 0; i < verts.size(); i = j + 1) {
        j = verts.find('\n', i);
        obj_verts += "v " + verts.substr(i, j - i + 1);
    }
    const std::string obj = dir.write("big.obj", obj_verts + face + "\n");
    const auto r = import_files({obj});
    ASSERT_FALSE(r.ok);
    EXPECT_EQ(r.error, obj + ": OBJ line 65538: a face of 65537 vertices (at most 65536 per polygon) or more");
    const std::string ply = dir.write("big.ply", "ply\nformat ascii 1.0\nelement vertex 65537\nproperty float x\n"
                                                 "property float y\nproperty float z\nelement face 1\n"
                                                 "property list uint int vertex_indices\nend_header\n" +
                                                     verts + list + "\n");
    const auto rp = import_files({ply});
    ASSERT_FALSE(rp.ok);
    EXPECT_EQ(rp.error, ply + ": PLY face 0: a face of 65537 vertices (at most 65536 per polygon)");
    const std::string off = dir.write("big.off", "OFF\n65537 1 0\n" + verts + list + "\n");
    const auto ro = import_files({off});
    ASSERT_FALSE(ro.ok);
    EXPECT_EQ(ro.error, off + ": OFF face 0: a face of 65537 vertices (at most 65536 per polygon)");
}

// ASCII PLY shorter than its header: OpenMesh kept reading a failed stream and repeated
// the last face (two identical triangles from one, exit 0). A list length that is not a
// decimal integer ("-1", "7.9") is refused too.
TEST(Malformed, PlyAsciiBodyShorterThanItsHeaderIsAnError) {
    TempDir dir;
    const std::string head =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
    struct Case {
        std::string body, error;
    };
    const Case cases[] = {
        {"3 0 1 2\n", "PLY file is truncated or unparsable at face 1 of 2"},
        {"3 0 1 2\n3 0 1\n", "PLY file is truncated at face 1 of 2"},
        {"3 0 1 2\n-1 0 1 2\n", "PLY file is truncated or unparsable at face 1 of 2"},
        {"3 0 1 2\n2.5 0 1 2\n", "PLY file is truncated or unparsable at face 1 of 2"},
    };
    for (const Case& c : cases) {
        const std::string p = dir.write("t.ply", head + c.body);
        const auto r = import_files({p});
        ASSERT_FALSE(r.ok) << c.body;
        EXPECT_EQ(r.error, p + ": " + c.error);
    }
    const std::string short_vertices =
        dir.write("v.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                           "property float z\nend_header\n0 0 0\n1 0\n");
    const auto rv = import_files({short_vertices});
    ASSERT_FALSE(rv.ok);
    EXPECT_EQ(rv.error, short_vertices + ": PLY file is truncated at vertex 1 of 3");
    const auto ok = import_files({dir.write("ok.ply", head + "3 0 1 2\n3 2 1 0\n")});
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.scene.triangle_count(), 2u);
}

// STL: a binary file whose size disagrees with its triangle count, and an ASCII file cut
// inside a facet, are refused with what is wrong (were "no triangles", or read in part
// with a warning and exit 0).
TEST(Malformed, StlInconsistentOrCutIsAnError) {
    TempDir dir;
    std::string bin(80, ' ');
    bin += u32(2);
    for (int t = 0; t < 1; ++t) {
        for (float c : {0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) bin += f32(c);
        bin += std::string(2, '\0');
    }
    const std::string pb = dir.write("b.stl", bin);
    const auto rb = import_files({pb});
    ASSERT_FALSE(rb.ok);
    EXPECT_EQ(rb.error, pb + ": binary STL declares 2 triangles (84 + 50 x 2 = 184 bytes) but the file has 134 bytes");
    const std::string facet =
        "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
    const std::string cut = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0";
    const std::string pa = dir.write("a.stl", "solid x\n" + facet + cut);
    const auto ra = import_files({pa});
    ASSERT_FALSE(ra.ok);
    EXPECT_EQ(ra.error.rfind(pa + ": ASCII STL is truncated or malformed at facet 1", 0), 0u) << ra.error;
    const auto ok = import_files({dir.write("ok.stl", "solid x\n" + facet + facet + "endsolid x\n")});
    ASSERT_TRUE(ok.ok) << ok.error;
    EXPECT_EQ(ok.scene.triangle_count(), 2u);
    // A name after solid / endsolid may hold any word, "facet" included.
    const auto named = import_files({dir.write("named.stl", "solid my facet model\n" + facet + "endsolid my facet model\n")});
    ASSERT_TRUE(named.ok) << named.error;
    EXPECT_EQ(named.scene.triangle_count(), 1u);
    // Keywords in upper case after leading blanks, as some exporters write them: OpenMesh
    // reads them, and so must the check.
    const auto upper = import_files({dir.write(
        "up.stl", "  SOLID X\nFACET NORMAL 0 0 1\nOUTER LOOP\nVERTEX 0 0 0\nVERTEX 1 0 0\nVERTEX 0 1 0\n"
                  "ENDLOOP\nENDFACET\nENDSOLID X\n")});
    ASSERT_TRUE(upper.ok) << upper.error;
    EXPECT_EQ(upper.scene.triangle_count(), 1u);
    bin.replace(80, 4, u32(1));
    const auto okb = import_files({dir.write("okb.stl", bin)});
    ASSERT_TRUE(okb.ok) << okb.error;
    EXPECT_EQ(okb.scene.triangle_count(), 1u);
}

// An OBJ of points (or lines) only said "no triangles"; it now says what it holds.
TEST(Malformed, ObjOfPointsOnlySaysSo) {
    TempDir dir;
    const std::string p = dir.write("p.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1\np 2\nl 1 2\n");
    const auto r = import_files({p});
    ASSERT_FALSE(r.ok);
    EXPECT_EQ(r.error, p + ": no triangles (only 1 lines 2 points elements, which are not traced)");
}

}  // namespace
}  // namespace cwbvh::compiler::test

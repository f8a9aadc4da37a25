// dmmr's PLY reader (ply_reader.h): on well-formed files it builds exactly
// what OpenSceneGraph's PLY plugin builds, and each malformed file is an
// Error naming the file and what is wrong (the plugin crashed on some and
// returned part of the model on others).
#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <osg/Geode>
#include <osg/Geometry>
#include <osgDB/ReadFile>
#include <random>
#include <sstream>

#include "ply_reader.h"
#include "preprocess.h"
#include "test_support.h"

namespace fs = std::filesystem;
using dmmr::test::TempDir;

namespace {

enum class Fmt { Ascii, Little, Big };

// A small PLY writer for the tests: properties of a few types, in any of the
// three formats.
struct Prop {
  std::string type, name;
};
class PlyWriter {
 public:
  explicit PlyWriter(Fmt f) : fmt_(f) {}
  std::string header;
  void value(const std::string& type, double v) {
    if (fmt_ == Fmt::Ascii) {
      std::ostringstream os;
      os.precision(17);
      os << v;
      body_ += (line_start_ ? "" : " ") + os.str();
      line_start_ = false;
      return;
    }
    unsigned char b[8];
    size_t n = 0;
    if (type == "uchar") b[0] = uint8_t(v), n = 1;
    if (type == "ushort") {
      uint16_t x = uint16_t(v);
      std::memcpy(b, &x, n = 2);
    }
    if (type == "int") {
      int32_t x = int32_t(v);
      std::memcpy(b, &x, n = 4);
    }
    if (type == "uint") {
      uint32_t x = uint32_t(v);
      std::memcpy(b, &x, n = 4);
    }
    if (type == "float") {
      float x = float(v);
      std::memcpy(b, &x, n = 4);
    }
    if (type == "double") std::memcpy(b, &v, n = 8);
    if (n == 0) ADD_FAILURE() << "type " << type;
    if ((fmt_ == Fmt::Big) == (std::endian::native == std::endian::little)) std::reverse(b, b + n);
    body_.append(reinterpret_cast<char*>(b), n);
  }
  void endItem() {
    if (fmt_ == Fmt::Ascii) body_ += "\n";
    line_start_ = true;
  }
  std::string file() const {
    const char* f = fmt_ == Fmt::Ascii    ? "ascii"
                    : fmt_ == Fmt::Little ? "binary_little_endian"
                                          : "binary_big_endian";
    return "ply\nformat " + std::string(f) + " 1.0\n" + header + "end_header\n" + body_;
  }

 private:
  Fmt fmt_;
  std::string body_;
  bool line_start_ = true;
};

struct Variant {
  Fmt fmt = Fmt::Ascii;
  bool normals = false;
  std::string colours;  // "", "rgb", "rgba", "diffuse"
  bool flipped = false;
  // An unread vertex property and list, an element between the vertices and
  // the faces, and a face property after the indices. OSG's plugin misreads
  // such files (it does not skip the elements it does not use).
  bool extras = false;
  std::string position_type = "float", index_type = "int";
};

// A 6 x 5 grid of jittered vertices; its cells as triangles and quads.
std::string gridPly(const Variant& v) {
  PlyWriter w(v.fmt);
  const int nx = 6, ny = 5;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  std::string& h = w.header;
  if (v.flipped) h += "comment modified by flipply\n";
  h += "comment made by ply_reader_test\n";
  h += "element vertex " + std::to_string(nx * ny) + "\n";
  for (const char* c : {"x", "y", "z"}) h += "property " + v.position_type + " " + c + "\n";
  if (v.extras) h += "property float confidence\nproperty list uchar int neighbours\n";
  if (v.normals) h += "property float nx\nproperty float ny\nproperty float nz\n";
  std::string cp = v.colours == "diffuse" ? "diffuse_" : "";
  if (!v.colours.empty())
    for (const char* c : {"red", "green", "blue"}) h += "property uchar " + cp + c + "\n";
  if (v.colours == "rgba") h += "property uchar alpha\n";
  int cells = (nx - 1) * (ny - 1);
  if (v.extras) h += "element edge 2\nproperty int vertex1\nproperty int vertex2\n";
  h += "element face " + std::to_string(cells) + "\n";
  h += "property list uchar " + v.index_type + " vertex_indices\n";
  if (v.extras) h += "property uchar flags\n";
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      w.value(v.position_type, i + jitter(rng));
      w.value(v.position_type, j + jitter(rng));
      w.value(v.position_type, 0.5 * std::sin(i + j) + jitter(rng));
      if (v.extras) {
        w.value("float", 0.5);
        w.value("uchar", 2);
        w.value("int", 1);
        w.value("int", 2);
      }
      if (v.normals)
        for (int k = 0; k < 3; ++k) w.value("float", jitter(rng));
      if (!v.colours.empty())
        for (int k = 0; k < (v.colours == "rgba" ? 4 : 3); ++k)
          w.value("uchar", (i * 40 + j * 7 + k * 90) % 256);
      w.endItem();
    }
  if (v.extras) {
    for (int e = 0; e < 2; ++e) {
      w.value("int", e);
      w.value("int", e + 1);
      w.endItem();
    }
  }
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      int a = j * nx + i, b = a + 1, c = a + nx + 1, d = a + nx;
      if ((i + j) % 2) {
        w.value("uchar", 4);
        for (int k : {a, b, c, d}) w.value(v.index_type, k);
      } else {
        w.value("uchar", 3);
        for (int k : {a, b, c}) w.value(v.index_type, k);
      }
      if (v.extras) w.value("uchar", 9);
      w.endItem();
    }
  return w.file();
}

void writeFile(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary) << bytes;
}

const osg::Geometry* geometryOf(const osg::Node* n) {
  const osg::Geode* g = n ? n->asGeode() : nullptr;
  if (!g || g->getNumDrawables() != 1) return nullptr;
  return g->getDrawable(0)->asGeometry();
}

template <typename A>
void expectSameArray(const osg::Array* a, const osg::Array* b, const char* what) {
  ASSERT_EQ(a == nullptr, b == nullptr) << what;
  if (!a) return;
  auto* x = dynamic_cast<const A*>(a);
  auto* y = dynamic_cast<const A*>(b);
  ASSERT_TRUE(x && y) << what;
  ASSERT_EQ(x->size(), y->size()) << what;
  EXPECT_EQ(a->getBinding(), b->getBinding()) << what;
  for (size_t i = 0; i < x->size(); ++i) ASSERT_EQ((*x)[i], (*y)[i]) << what << " " << i;
}

void expectSameAsOsg(const std::string& path) {
  osg::ref_ptr<osg::Node> theirs = osgDB::readRefNodeFile(path);
  osg::ref_ptr<osg::Node> ours = dmmr::readPly(path);
  const osg::Geometry* a = geometryOf(theirs.get());
  const osg::Geometry* b = geometryOf(ours.get());
  ASSERT_TRUE(a && b);
  expectSameArray<osg::Vec3Array>(a->getVertexArray(), b->getVertexArray(), "vertices");
  expectSameArray<osg::Vec3Array>(a->getNormalArray(), b->getNormalArray(), "normals");
  expectSameArray<osg::Vec4Array>(a->getColorArray(), b->getColorArray(), "colours");
  ASSERT_EQ(a->getNumPrimitiveSets(), b->getNumPrimitiveSets());
  for (unsigned p = 0; p < a->getNumPrimitiveSets(); ++p) {
    const osg::PrimitiveSet* x = a->getPrimitiveSet(p);
    const osg::PrimitiveSet* y = b->getPrimitiveSet(p);
    EXPECT_EQ(x->getMode(), y->getMode());
    ASSERT_EQ(x->getNumIndices(), y->getNumIndices());
    for (unsigned i = 0; i < x->getNumIndices(); ++i) ASSERT_EQ(x->index(i), y->index(i)) << p;
  }
}

class PlyMatchesOsg : public testing::TestWithParam<Variant> {};

TEST_P(PlyMatchesOsg, SameGeometryAsOpenSceneGraphsPlugin) {
  TempDir dir;
  std::string path = dir / "grid.ply";
  writeFile(path, gridPly(GetParam()));
  expectSameAsOsg(path);
}

std::vector<Variant> variants() {
  std::vector<Variant> out;
  for (Fmt f : {Fmt::Ascii, Fmt::Little, Fmt::Big}) {
    out.push_back({f, false, "", false, false, "float", "int"});      // smoothed normals
    out.push_back({f, true, "rgb", false, false, "float", "int"});    // normals, colours
    out.push_back({f, false, "rgba", true, false, "double", "int"});  // flipped
    out.push_back({f, true, "diffuse", false, false, "float", "uint"});
  }
  return out;
}
INSTANTIATE_TEST_SUITE_P(Variants, PlyMatchesOsg, testing::ValuesIn(variants()));

// What OSG's plugin misreads: the same grid with properties, lists and an
// element that the model does not use reads as the grid without them.
TEST(PlyReader, PropertiesAndElementsNotUsedAreSkipped) {
  for (Fmt f : {Fmt::Ascii, Fmt::Little, Fmt::Big}) {
    TempDir dir;
    Variant plain{f, true, "rgb", false, false, "float", "int"};
    Variant extras = plain;
    extras.extras = true;
    writeFile(dir / "plain.ply", gridPly(plain));
    writeFile(dir / "extras.ply", gridPly(extras));
    expectSameAsOsg(dir / "plain.ply");
    std::ifstream a(dir / "plain.ply", std::ios::binary), b(dir / "extras.ply", std::ios::binary);
    dmmr::PlyMesh x = dmmr::parsePly(a, "plain.ply"), y = dmmr::parsePly(b, "extras.ply");
    EXPECT_EQ(x.positions, y.positions);
    EXPECT_EQ(x.normals, y.normals);
    EXPECT_EQ(x.colors, y.colors);
    EXPECT_EQ(x.triangles, y.triangles);
    EXPECT_EQ(x.quads, y.quads);
    EXPECT_EQ(x.triangles.size() / 3 + x.quads.size() / 4, 20u);
  }
}

dmmr::PlyMesh parse(const std::string& text) {
  std::istringstream in(text);
  return dmmr::parsePly(in, "m.ply");
}
std::string errorOf(const std::string& text) {
  return dmmr::test::errorOf([&] { parse(text); });
}
bool has(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

const std::string kTriangleHeader =
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
const std::string kTriangleBody = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
std::string asciiTriangle() {
  return "ply\nformat ascii 1.0\n" + kTriangleHeader + kTriangleBody;
}

}  // namespace

TEST(PlyReader, ReadsATriangleAndIgnoresTrailingWhitespace) {
  dmmr::PlyMesh m = parse(asciiTriangle() + "\n\n  \n");
  EXPECT_EQ(m.positions, (std::vector<float>{0, 0, 0, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(m.triangles, (std::vector<uint32_t>{0, 1, 2}));
  EXPECT_TRUE(m.normals.empty() && m.colors.empty() && m.quads.empty());
}

TEST(PlyReader, CrLfHeaderLines) {
  std::string t = asciiTriangle();
  std::string crlf;
  for (char c : t) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  EXPECT_EQ(parse(crlf).triangles.size(), 3u);
}

TEST(PlyReader, PolygonsOfOtherCornerCountsAreCountedNotDrawn) {
  std::string t =
      "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
      "property float z\nelement face 3\nproperty list uchar int vertex_indices\n"
      "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 2 0\n"
      "5 0 1 2 3 4\n4 0 1 2 3\n2 0 1\n";
  dmmr::PlyMesh m = parse(t);
  EXPECT_EQ(m.quads, (std::vector<uint32_t>{0, 1, 2, 3}));
  EXPECT_TRUE(m.triangles.empty());
  EXPECT_EQ(m.other_faces, 2u);
}

TEST(PlyReader, ColoursScaleByTheirTypesRange) {
  std::string t =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nproperty ushort red\nproperty float green\n"
      "property float blue\nend_header\n0 0 0 65535 0.25 7\n";
  dmmr::PlyMesh m = parse(t);
  EXPECT_EQ(m.colors, (std::vector<float>{1.0f, 0.25f, 1.0f, 1.0f}));
}

TEST(PlyReader, TextureCoordinatesAndTextureFile) {
  std::string t =
      "ply\nformat ascii 1.0\ncomment TextureFile tex/a b.png\nelement vertex 1\n"
      "property float x\nproperty float y\nproperty float z\n"
      "property float texture_u\nproperty float texture_v\nend_header\n0 0 0 0.5 "
      "0.75\n";
  dmmr::PlyMesh m = parse(t);
  EXPECT_EQ(m.uv, (std::vector<float>{0.5f, 0.75f}));
  EXPECT_EQ(m.texture_file, "tex/a b.png");
}

// Found by fuzz_ply: an element of no properties and a count of 10^17 held
// the reader in a loop that read nothing.
TEST(PlyReader, AnElementWithoutPropertiesHoldsNoBytes) {
  std::string t = "ply\nformat ascii 1.0\nelement nothing 111991999999999999\n" + kTriangleHeader +
                  kTriangleBody;
  EXPECT_EQ(parse(t).triangles.size(), 3u);
}

// Each rejection names the file and what is wrong.
TEST(PlyReaderRejects, NotAPlyFile) {
  EXPECT_TRUE(has(errorOf("solid cube\n"), "m.ply: not a PLY file"));
  EXPECT_TRUE(has(errorOf(""), "m.ply: not a PLY file"));
}
TEST(PlyReaderRejects, AHeaderCutShort) {
  // OSG's plugin crashed on this one.
  std::string e = errorOf("ply\nformat binary_little_endian 1.0\nelem");
  EXPECT_TRUE(has(e, "m.ply: the file ends inside the header")) << e;
}
TEST(PlyReaderRejects, NoFormatLine) {
  EXPECT_TRUE(has(errorOf("ply\n" + kTriangleHeader + kTriangleBody), "no format line"));
}
TEST(PlyReaderRejects, AnUnknownFormatOrVersion) {
  EXPECT_TRUE(has(errorOf("ply\nformat binary_middle_endian 1.0\n" + kTriangleHeader),
                  "m.ply:2: unknown format 'binary_middle_endian'"));
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 2.0\n" + kTriangleHeader), "unsupported PLY version"));
}
TEST(PlyReaderRejects, AnUnknownKeywordOrType) {
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 1.0\nelemnt vertex 3\nend_header\n"),
                  "m.ply:3: unknown header keyword 'elemnt'"));
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\n"),
                  "unknown property type 'float128'"));
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
                  "a property before any element"));
}
TEST(PlyReaderRejects, ABadElementCount) {
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n"),
                  "element 'vertex' has a bad count '-3'"));
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 1.0\nelement vertex 1\nelement vertex 1\n"),
                  "a second element 'vertex'"));
}
TEST(PlyReaderRejects, VerticesWithoutXYZ) {
  std::string e = errorOf(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nend_header\n0 0\n");
  EXPECT_TRUE(has(e, "m.ply:3: the vertex element has no property z")) << e;
  EXPECT_TRUE(has(errorOf("ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int "
                          "vertex_indices\nend_header\n"),
                  "no vertex element"));
}
TEST(PlyReaderRejects, FacesWithoutIntegerIndices) {
  std::string head =
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
      "property float y\nproperty float z\nelement face 0\n";
  EXPECT_TRUE(has(errorOf(head + "property list uchar float vertex_indices\nend_header\n"),
                  "vertex indices are not integers"));
  EXPECT_TRUE(has(errorOf(head + "property list float int vertex_indices\nend_header\n"),
                  "list count type 'float' is not an integer type"));
  EXPECT_TRUE(
      has(errorOf(head + "property int vertex_indices\nend_header\n"), "no vertex_indices list"));
}
TEST(PlyReaderRejects, VerticesCutShort) {
  PlyWriter w(Fmt::Little);
  w.header = kTriangleHeader.substr(0, kTriangleHeader.size() - std::string("end_header\n").size());
  for (int k = 0; k < 5; ++k) w.value("float", k);  // 1 vertex and 2 of 3 coordinates
  std::string e = errorOf(w.file());
  EXPECT_TRUE(has(e, "m.ply: the file ends in element 'vertex': 1 of its 3 items were read")) << e;
}
TEST(PlyReaderRejects, FacesCutShort) {
  // OSG's plugin returned the faces before the cut as the whole model.
  std::string t =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 2\nproperty list uchar int vertex_indices\n"
      "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 2";
  std::string e = errorOf(t);
  EXPECT_TRUE(has(e, "the file ends in element 'face': 1 of its 2 items were read")) << e;
}
TEST(PlyReaderRejects, AnIndexPastTheVertices) {
  // OSG's plugin crashed on this one.
  std::string e =
      errorOf("ply\nformat ascii 1.0\n" + kTriangleHeader + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  EXPECT_TRUE(has(e, "m.ply: face 0: vertex index 7 is out of range (the file has 3 vertices)"))
      << e;
}
TEST(PlyReaderRejects, ANegativeIndex) {
  std::string e =
      errorOf("ply\nformat ascii 1.0\n" + kTriangleHeader + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n");
  EXPECT_TRUE(has(e, "vertex index -1 is out of range")) << e;
}
TEST(PlyReaderRejects, ANegativeListLength) {
  std::string t =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property float z\nelement face 1\nproperty list char int vertex_indices\n"
      "end_header\n0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n";
  EXPECT_TRUE(has(errorOf(t), "face 0: a list of negative length"));
}
TEST(PlyReaderRejects, AsciiNotANumberNamesItsLine) {
  std::string e =
      errorOf("ply\nformat ascii 1.0\n" + kTriangleHeader + "0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n");
  EXPECT_TRUE(has(e, "m.ply:11: 'zero' is not a number (vertex 1)")) << e;
  e = errorOf("ply\nformat ascii 1.0\n" + kTriangleHeader + "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n");
  EXPECT_TRUE(has(e, "'1.5' is not a value of the property's integer type (face 0)")) << e;
}
TEST(PlyReaderRejects, BytesAfterTheLastElement) {
  std::string e = errorOf(asciiTriangle() + "3 0 1 2\n");
  EXPECT_TRUE(has(e, "m.ply: 9 bytes after the last element")) << e;
}
TEST(PlyReaderRejects, AHeaderWithoutEnd) {
  std::string e = errorOf("ply\nformat ascii 1.0\n" + std::string(2 << 20, '\n'));
  EXPECT_TRUE(has(e, "header longer than")) << e;
}

// Through dmmr-preprocess: a malformed PLY in a directory fails the run
// naming it, or is skipped with --skip-unreadable, and no partial scene stays.
TEST(PlyReader, PreprocessNamesAMalformedPlyOrSkipsIt) {
  TempDir dir;
  fs::create_directories(dir / "in");
  writeFile(dir / "in/a.ply", asciiTriangle());
  writeFile(dir / "in/b.ply", "ply\nformat binary_little_endian 1.0\nelem");
  dmmr::PreprocessOptions o;
  o.inputs = {dir / "in"};
  o.out = dir / "s1";
  o.progress = false;
  std::string e = dmmr::test::errorOf([&] { dmmr::preprocess(o); });
  EXPECT_TRUE(has(e, "b.ply") && has(e, "ends inside the header")) << e;
  for (const auto& entry : fs::directory_iterator(dir.path()))
    EXPECT_FALSE(has(entry.path().filename().string(), "s1")) << entry.path();
  o.out = dir / "s2";
  o.skip_unreadable = true;
  testing::internal::CaptureStderr();
  dmmr::PreprocessStats st = dmmr::preprocess(o);
  std::string err = testing::internal::GetCapturedStderr();
  EXPECT_TRUE(has(err, "skipped") && has(err, "b.ply")) << err;
  EXPECT_EQ(st.inputs, 1u);
  EXPECT_EQ(st.triangles, 1u);
}

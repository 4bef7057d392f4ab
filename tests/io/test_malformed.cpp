// Malformed input: every reader throws IoError "FILE:LINE: reason" (line where it applies)
// and never crashes, hangs, or allocates what a lying header asks for.
#include <random>

#include "io_test_util.h"
#include "mesh/errors.h"

using namespace incise;
using namespace incise::testing;

namespace {

struct Bad {
  std::string name;     // file name (extension picks the reader)
  std::string content;
  std::string reason;   // substring of the message
  long line;            // expected line, 0 = the message must carry no line
};

const std::string kMshHead = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n";
const std::string kMshNodes = "$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n";  // lines 4-10
const std::string kMeditHead = "MeshVersionFormatted 2\nDimension 3\nVertices\n4\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n";
const std::string kVtkHead = "# vtk DataFile Version 4.2\nt\nASCII\nDATASET UNSTRUCTURED_GRID\n";
const std::string kVtuHead =
    "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
    "<UnstructuredGrid>\n<Piece NumberOfPoints=\"4\" NumberOfCells=\"1\">\n";  // lines 1-4
const std::string kVtuHead0 =
    "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
    "<UnstructuredGrid>\n<Piece NumberOfPoints=\"4\" NumberOfCells=\"0\">\n";
std::string vtu_body(const std::string& points, const std::string& conn, const std::string& types = "10") {
  return "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n" + points +
         "\n</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n" + conn +
         "\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n4\n</DataArray>\n"
         "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n" +
         types + "\n</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
}

std::vector<Bad> bad_files() {
  std::vector<Bad> b;
  // ---- gmsh
  b.push_back({"empty.msh", "", "empty file", 0});
  b.push_back({"blank.msh", "\n\n  \n", "unexpected end of file", 4});
  b.push_back({"medit_inside.msh", kMeditHead, "not a Gmsh file", 1});
  b.push_back({"binary.msh", "$MeshFormat\n2.2 1 8\n$EndMeshFormat\n", "binary Gmsh", 2});
  b.push_back({"version.msh", "$MeshFormat\n3.0 0 8\n$EndMeshFormat\n", "unsupported Gmsh version", 2});
  b.push_back({"truncated_nodes.msh", kMshHead + "$Nodes\n4\n1 0 0 0\n2 1 0 0\n", "cannot fit", 5});
  b.push_back({"truncated_line.msh", kMshHead + "$Nodes\n2\n1 0 0 0\n2 1 0 0.25", "unexpected end of file", 7});
  b.push_back({"huge_nodes.msh", kMshHead + "$Nodes\n1000000000000\n1 0 0 0\n", "exceeds 32-bit ids", 5});
  b.push_back({"huge_elements.msh", kMshHead + kMshNodes + "$Elements\n4000000000\n", "cannot fit", 12});
  b.push_back({"nan.msh", kMshHead + "$Nodes\n2\n1 0 0 0\n2 nan 0 0\n", "non-finite x coordinate", 7});
  b.push_back({"inf.msh", kMshHead + "$Nodes\n2\n1 0 0 0\n2 0 -inf 0\n", "non-finite y coordinate", 7});
  b.push_back({"overflow.msh", kMshHead + "$Nodes\n1\n1 0 0 1e999\n", "z coordinate", 6});
  b.push_back({"short_node.msh", kMshHead + "$Nodes\n2\n1 0 0\n2 1 0 0.5\n", "line ends early", 6});
  b.push_back({"unknown_node.msh", kMshHead + kMshNodes + "$Elements\n1\n1 4 2 1 1 1 2 3 9\n$EndElements\n",
               "unknown node 9", 13});
  b.push_back({"too_few_elements.msh", kMshHead + kMshNodes + "$Elements\n2\n1 4 2 1 1 1 2 3 4\n$EndElements\n",
               "expected element id", 14});
  b.push_back({"too_many_elements.msh",
               kMshHead + kMshNodes + "$Elements\n1\n1 4 2 1 1 1 2 3 4\n2 4 2 1 1 1 2 3 4\n$EndElements\n",
               "wrong element count", 14});
  b.push_back({"triangles_only.msh", kMshHead + kMshNodes + "$Elements\n1\n1 2 2 1 1 1 2 3\n$EndElements\n",
               "a volume mesh is needed", 0});
  b.push_back({"repeated_vertex.msh", kMshHead + kMshNodes + "$Elements\n1\n1 4 2 1 1 1 2 2 4\n$EndElements\n",
               "repeated", 13});
  b.push_back({"duplicate_tet.msh",
               kMshHead + kMshNodes + "$Elements\n2\n1 4 2 1 1 1 2 3 4\n2 4 2 1 1 4 3 2 1\n$EndElements\n",
               "same four vertices", 14});
  b.push_back({"duplicate_node.msh", kMshHead + "$Nodes\n2\n1 0 0 0\n1 1 0 0\n$EndNodes\n", "duplicate node id 1", 0});
  b.push_back({"unterminated.msh", kMshHead + "$PhysicalNames\n1\n3 1 \"a\"\n", "not terminated", 4});
  b.push_back({"no_elements.msh", kMshHead + kMshNodes, "no $Elements section", 0});
  b.push_back({"bad_tags.msh", kMshHead + kMshNodes + "$Elements\n1\n1 4 -3 1 2 3 4\n$EndElements\n",
               "bad number of tags", 13});
  b.push_back({"v41_blocks.msh",
               "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2 1 2\n3 1 0 5\n1\n2\n3\n4\n5\n0 0 0\n0 0 0\n0 0 0\n0 0 0\n0 0 0\n",
               "more nodes than the declared 2", 6});
  b.push_back({"v41_count.msh", "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4000000000 1 2\n", "cannot fit", 5});
  b.push_back({"v1_truncated.msh", "$NOD\n2\n1 0 0 0\n2 0 0 0\n", "expected $ENDNOD", 5});
  // ---- medit
  b.push_back({"empty.mesh", "", "empty file", 0});
  b.push_back({"gmsh_inside.mesh", kMshHead, "not a Medit file", 1});
  b.push_back({"dim2.mesh", "MeshVersionFormatted 2\nDimension 2\n", "only 3D", 2});
  b.push_back({"range.mesh", kMeditHead + "Tetrahedra\n1\n1 2 3 5 1\n", "vertex index 5 out of range", 11});
  b.push_back({"zero_index.mesh", kMeditHead + "Tetrahedra\n1\n0 2 3 4 1\n", "vertex index 0 out of range", 11});
  b.push_back({"truncated.mesh", kMeditHead + "Tetrahedra\n2\n1 2 3 4 1\n", "cannot fit", 10});
  b.push_back({"truncated_line.mesh", kMeditHead + "Tetrahedra\n2\n1 2 3 4 1\n2 3 4 1      ", "line ends early", 12});
  b.push_back({"huge.mesh", "MeshVersionFormatted 2\nDimension 3\nVertices\n4000000000\n", "cannot fit", 4});
  b.push_back({"nan.mesh", "MeshVersionFormatted 2\nDimension 3\nVertices\n1\nNaN 0 0 0\n", "non-finite", 5});
  b.push_back({"triangles.mesh", kMeditHead + "Triangles\n1\n1 2 3 4\nEnd\n", "a volume mesh is needed", 0});
  b.push_back({"garbage_kw.mesh", kMeditHead + "12 13\n", "expected a keyword", 9});
  // ---- vtk legacy
  b.push_back({"empty.vtk", "", "empty file", 0});
  b.push_back({"notvtk.vtk", "hello\n", "not a VTK legacy file", 1});
  b.push_back({"poly.vtk", "# vtk DataFile Version 4.2\nt\nASCII\nDATASET POLYDATA\n", "holds no tetrahedra", 4});
  b.push_back({"huge.vtk", kVtkHead + "POINTS 4000000000 double\n0 0 0\n", "cannot fit", 5});
  b.push_back({"nan.vtk", kVtkHead + "POINTS 1 double\n0 nan 0\n", "non-finite", 6});
  b.push_back({"range.vtk",
               kVtkHead + "POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 7\nCELL_TYPES 1\n10\n",
               "references point 7", 0});
  b.push_back({"types.vtk", kVtkHead + "POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 2\n10\n",
               "unexpected end of file", 11});
  b.push_back({"keyword.vtk", kVtkHead + "SPLINES 4\n", "unknown VTK keyword", 5});
  b.push_back({"binary_truncated.vtk",
               "# vtk DataFile Version 4.2\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n\x01\x02\x03",
               "cannot fit", 6});
  b.push_back({"cellsize.vtk", kVtkHead + "POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n9 0 1 2 3\nCELL_TYPES 1\n10\n",
               "bad point count", 0});
  b.push_back({"triangles.vtk", kVtkHead + "POINTS 3 double\n0 0 0 1 0 0 0 1 0\nCELLS 1 4\n3 0 1 2\nCELL_TYPES 1\n5\n",
               "a volume mesh is needed", 0});
  // ---- vtu
  b.push_back({"empty.vtu", "", "empty file", 0});
  b.push_back({"notxml.vtu", "solid x\n", "not a VTK XML file", 1});
  b.push_back({"poly.vtu", "<VTKFile type=\"PolyData\">\n", "is not UnstructuredGrid", 1});
  b.push_back({"lz4.vtu", "<VTKFile type=\"UnstructuredGrid\" compressor=\"vtkLZ4DataCompressor\">\n", "not supported", 1});
  b.push_back({"nan.vtu", kVtuHead + vtu_body("0 0 0 1 0 0 0 1 0 0 0 nan", "0 1 2 3"), "non-finite", 7});
  b.push_back({"count.vtu", kVtuHead + vtu_body("0 0 0 1 0 0 0 1 0 0 0", "0 1 2 3"), "11 values, expected 12", 6});
  b.push_back({"range.vtu", kVtuHead + vtu_body("0 0 0 1 0 0 0 1 0 0 0 1", "0 1 2 4"), "references point 4", 11});
  b.push_back({"huge_index.vtu", kVtuHead + vtu_body("0 0 0 1 0 0 0 1 0 0 0 1", "0 1 2 6.6e26"), "references point 6.6e+26", 11});
  b.push_back({"bad_number.vtu", kVtuHead + vtu_body("0 0 0 1 0 0 0 1 0 0 0 x", "0 1 2 3"), "got 'x'", 7});
  b.push_back({"base64.vtu",
               kVtuHead0 + "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">\n!!!!\n"
                          "</DataArray>\n</Points>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
               "invalid base64", 6});
  b.push_back({"header_lies.vtu",
               kVtuHead0 + "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">\n/////w==\n"
                          "</DataArray>\n</Points>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
               "more bytes than the file holds", 6});
  b.push_back({"unterminated.vtu", "<VTKFile type=\"UnstructuredGrid\"", "unterminated", 1});
  b.push_back({"no_piece.vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid/></VTKFile>", "no <Piece>", 1});
  b.push_back({"huge_piece.vtu", "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid>"
                                 "<Piece NumberOfPoints=\"99999999999999\" NumberOfCells=\"1\">",
               "exceeds 32-bit ids", 1});
  // ---- surfaces given where a volume is needed
  b.push_back({"cube.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "surface format", 0});
  b.push_back({"cube.stl", "solid x\nendsolid x\n", "surface format", 0});
  b.push_back({"noext", "whatever", "unknown tet mesh format", 0});
  return b;
}

void require_io_error(const std::string& path, const std::string& reason, long line) {
  try {
    read_tet_mesh(path);
    FAIL("no exception for " << path);
  } catch (const IoError& e) {
    std::string what = e.what();
    INFO(what);
    REQUIRE(e.file() == path);
    REQUIRE(what.find(reason) != std::string::npos);
    REQUIRE(what.find('\n') == std::string::npos);
    REQUIRE(e.line() == line);
    if (line > 0)
      REQUIRE(what.rfind(path + ":" + std::to_string(line) + ": ", 0) == 0);
    else
      REQUIRE(what.rfind(path + ": ", 0) == 0);
  }
}

}  // namespace

TEST_CASE("malformed files give FILE:LINE: reason", "[io][malformed]") {
  ScratchDir dir("malformed");
  for (const Bad& b : bad_files()) {
    const std::string path = dir / b.name;
    write_text(path, b.content);
    SECTION(b.name) { require_io_error(path, b.reason, b.line); }
  }
}

TEST_CASE("TetGen errors name the .node or .ele file", "[io][malformed]") {
  ScratchDir dir("tetgen_bad");
  const std::string node = "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  auto pair = [&](const std::string& base, const std::string& n, const std::string& e) {
    if (!n.empty()) write_text(dir / (base + ".node"), n);
    if (!e.empty()) write_text(dir / (base + ".ele"), e);
    return dir / (base + ".ele");
  };
  require_io_error(pair("missing", node, ""), "no such file", 0);  // no .ele
  std::string p = pair("seq", "4 3 0 0\n0 0 0 0\n1 1 0 0\n3 0 1 0\n4 0 0 1\n", "1 4 0\n0 0 1 2 3\n");
  try {
    read_tet_mesh(p);
    FAIL();
  } catch (const IoError& e) {
    CHECK(e.file() == dir / "seq.node");
    CHECK(e.line() == 4);
    CHECK(std::string(e.what()).find("out of sequence") != std::string::npos);
  }
  p = pair("range", node, "# c\n2 4 1\n0 0 1 2 3 1\n1 0 1 2 4 1\n");
  try {
    read_tet_mesh(p);
    FAIL();
  } catch (const IoError& e) {
    CHECK(e.file() == dir / "range.ele");
    CHECK(e.line() == 4);
    CHECK(std::string(e.what()).find("point index 4 out of range 0..3") != std::string::npos);
  }
  p = pair("per", node, "1 3 0\n0 0 1 2\n");
  try {
    read_tet_mesh(p);
    FAIL();
  } catch (const IoError& e) {
    CHECK(e.file() == dir / "per.ele");
    CHECK(e.line() == 1);
  }
  p = pair("huge", node, "4000000000 4 0\n0 0 1 2 3\n");
  CHECK_THROWS_WITH(read_tet_mesh(p), Catch::Contains("cannot fit"));
  p = pair("nan", "1 3 0 0\n0 0 inf 0\n", "1 4 0\n0 0 0 0 0\n");
  CHECK_THROWS_WITH(read_tet_mesh(p), Catch::Contains("non-finite"));
  p = pair("empty_ele", node, "\n# nothing\n");
  CHECK_THROWS_WITH(read_tet_mesh(p), Catch::Contains("empty file"));
}

// Every prefix of a valid file and random byte damage: IoError or a valid mesh, never
// anything else (the fuzzers do this at scale; this keeps a deterministic slice in CI).
TEST_CASE("truncated and damaged files never crash", "[io][malformed]") {
  ScratchDir dir("damage");
  TetMesh m = labeled_ellipsoid();
  std::mt19937 rng(12345);
  struct W {
    std::string name;
    WriteOptions o;
  };
  WriteOptions bin;
  bin.binary = true;
  for (const W& w : {W{"d.msh", {}}, W{"d.mesh", {}}, W{"d.vtk", {}}, W{"b.vtk", bin}, W{"d.vtu", {}}, W{"b.vtu", bin},
                     W{"d.node", {}}}) {
    const std::string src = dir / ("src_" + w.name);
    write_tet_mesh(m, src, w.o);
    const bool tetgen = w.name.ends_with(".node");
    const std::string data = read_text(tetgen ? dir / "src_d.ele" : src);
    const std::string target = dir / ("cut_" + w.name);
    const std::string target_ele = dir / "cut_d.ele";
    if (tetgen) write_text(target, read_text(src));
    int ok = 0, errors = 0;
    auto attempt = [&](const std::string& bytes) {
      write_text(tetgen ? target_ele : target, bytes);
      try {
        TetMesh r = read_tet_mesh(target);
        r.validate(TetMesh::ValidateOptions{false, false});
        ++ok;
      } catch (const IoError& e) {
        REQUIRE(std::string(e.what()).find('\n') == std::string::npos);
        ++errors;
      }
    };
    const std::size_t step = std::max<std::size_t>(1, data.size() / 150);
    for (std::size_t cut = 0; cut < data.size(); cut += step) attempt(data.substr(0, cut));
    for (int k = 0; k < 150; ++k) {
      std::string d = data;
      int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) d[rng() % d.size()] = static_cast<char>(rng() % 256);
      attempt(d);
    }
    INFO(w.name << ": " << ok << " read, " << errors << " rejected");
    CHECK(errors > 0);
  }
}

TEST_CASE("binary garbage is rejected by every reader", "[io][malformed]") {
  ScratchDir dir("garbage");
  std::mt19937 rng(7);
  for (std::string ext : {"msh", "mesh", "vtk", "vtu", "node"}) {
    for (int k = 0; k < 20; ++k) {
      std::string bytes(1 + rng() % 3000, '\0');
      for (char& c : bytes) c = static_cast<char>(rng() % 256);
      const std::string path = dir / ("g." + ext);
      write_text(path, bytes);
      if (ext == "node") write_text(dir / "g.ele", bytes);
      CHECK_THROWS_AS(read_tet_mesh(path), IoError);
    }
  }
}

TEST_CASE("messages are clear: BOM, indices, non-UTF-8 bytes, surface outputs", "[io][malformed]") {
  ScratchDir dir("messages");
  // A UTF-8 byte order mark before a gmsh (or any) file is skipped.
  const TetMesh box = make_box(Vec3(1, 1, 1), {1, 1, 1});
  for (const char* name : {"bom.msh", "bom.mesh", "bom.vtk", "bom.vtu"}) {
    write_tet_mesh(box, dir / name);
    write_text(dir / name, "\xEF\xBB\xBF" + read_text(dir / name));
    CHECK(read_tet_mesh(dir / name).num_tets() == box.num_tets());
  }
  // A VTK index names the point and the range as numbers, not "-1.000000 out of range 0..4-1".
  write_text(dir / "neg.vtk", kVtkHead + "POINTS 4 double\n0 0 0 1 0 0 0 1 0 0 0 1\nCELLS 1 5\n4 0 1 2 -1\nCELL_TYPES 1\n10\n");
  CHECK_THROWS_WITH(read_tet_mesh(dir / "neg.vtk"), Catch::Contains("cell #0 references point -1, not an index in 0..3"));
  // Bytes that are not UTF-8 are shown as \xNN in every error (Python gets a str).
  const IoError e("f\xFF.msh", 3, std::string("got '\xC3\x28' and \xE2\x82\xAC\n"));
  CHECK(std::string(e.what()) == "f\\xFF.msh:3: got '\\xC3(' and \xE2\x82\xAC\\x0A");
  // Writing a tet mesh to a surface extension says what to do from the command line too.
  CHECK_THROWS_WITH(write_tet_mesh(box, dir / "x.off"), Catch::Contains("incise convert MESH OUT.off"));
}

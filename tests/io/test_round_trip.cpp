// Every tet format, every direction incise writes: write, read back, compare exactly
// (positions bit-exact, connectivity, labels, boundary tags where the format carries them),
// over several meshes and at extreme scales; then meshio must read every written file.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <numeric>
#include <set>

#include "cut/cutter.h"
#include "io_test_util.h"
#include "mesh/errors.h"
#include "mesh/overlap.h"
#include "quality/improve.h"

using namespace incise;
using namespace incise::testing;

namespace {

struct Variant {
  std::string name;  // file name written
  WriteOptions options;
  TagsCarried tags;  // which boundary tags travel
};

// The cut-tagged boundary faces, each as its sorted vertex ids.
std::set<std::array<std::uint32_t, 3>> cut_faces(const TetMesh& mesh) {
  std::set<std::array<std::uint32_t, 3>> out;
  for (TetId t : mesh.tets())
    for (int f = 0; f < 4; ++f)
      if (!mesh.neighbor(t, f).is_valid() && mesh.face_tag(t, f) == kTagCut) {
        auto fv = mesh.face_vertices(t, f);
        std::array<std::uint32_t, 3> k{fv[0].idx(), fv[1].idx(), fv[2].idx()};
        std::sort(k.begin(), k.end());
        out.insert(k);
      }
  return out;
}

std::vector<Variant> variants() {
  std::vector<Variant> v;
  WriteOptions ascii;
  WriteOptions bin;
  bin.binary = true;
  WriteOptions be = bin;
  be.big_endian = true;
  WriteOptions le64 = bin;
  le64.header_uint64 = true;
  WriteOptions be64 = be;
  be64.header_uint64 = true;
  WriteOptions no_boundary;
  no_boundary.write_boundary = false;
  v.push_back({"m.msh", ascii, TagsCarried::All});
  v.push_back({"nb.msh", no_boundary, TagsCarried::None});
  v.push_back({"m.mesh", ascii, TagsCarried::All});
  v.push_back({"nb.mesh", no_boundary, TagsCarried::None});
  v.push_back({"ascii.vtk", ascii, TagsCarried::Cut});
  v.push_back({"binary.vtk", bin, TagsCarried::Cut});
  v.push_back({"ascii.vtu", ascii, TagsCarried::Cut});
  v.push_back({"le32.vtu", bin, TagsCarried::Cut});
  v.push_back({"be32.vtu", be, TagsCarried::Cut});
  v.push_back({"le64.vtu", le64, TagsCarried::Cut});
  v.push_back({"be64.vtu", be64, TagsCarried::Cut});
  v.push_back({"tg.node", ascii, TagsCarried::Cut});
  v.push_back({"tg2.ele", ascii, TagsCarried::Cut});
  return v;
}

struct Case {
  std::string name;
  TetMesh mesh;
};

std::vector<Case> cases() {
  std::vector<Case> c;
  c.push_back({"box", make_box(Vec3(1, 2, 3), {2, 3, 2}, 4)});
  c.push_back({"ellipsoid", labeled_ellipsoid()});
  c.push_back({"holes", box_with_holes()});
  c.push_back({"tiny", labeled_ellipsoid(1e-8, Vec3(1e-8, -3e-8, 2e-9))});
  c.push_back({"huge", labeled_ellipsoid(1e8, Vec3(3e8, -1e8, 7e7))});
  c.push_back({"offset", labeled_ellipsoid(1e-3, Vec3(1e5, 1e5, -1e5))});
  return c;
}

std::string read_path(const std::string& written) {
  // A TetGen pair is read through either name; read .ele files by the .node name and
  // vice versa, to cover both.
  if (written.size() > 5 && written.substr(written.size() - 5) == ".node") return written.substr(0, written.size() - 5) + ".ele";
  if (written.size() > 4 && written.substr(written.size() - 4) == ".ele") return written.substr(0, written.size() - 4) + ".node";
  return written;
}

}  // namespace

TEST_CASE("every format round-trips exactly", "[io][roundtrip]") {
  ScratchDir dir("roundtrip");
  for (Case& c : cases()) {
    for (const Variant& v : variants()) {
      const std::string path = dir / (c.name + "_" + v.name);
      INFO(c.name << " -> " << v.name);
      write_tet_mesh(c.mesh, path, v.options);
      ReadReport report;
      TetMesh back = read_tet_mesh(read_path(path), &report);
      back.validate();
      CHECK(report.reoriented_tets == 0);
      CHECK(report.skipped_cells == (v.tags == TagsCarried::All ? c.mesh.boundary_faces().size() : 0));
      CHECK(report.unreferenced_vertices == 0);
      CHECK_FALSE(back.has_pending_change());
      require_same_mesh(c.mesh, back, v.tags);
    }
  }
}

TEST_CASE("formats by name and content", "[io]") {
  CHECK(format_from_path("a/b.MSH") == TetFormat::Gmsh22);
  CHECK(format_from_path("x.mesh") == TetFormat::Medit);
  CHECK(format_from_path("x.vtk") == TetFormat::VtkLegacy);
  CHECK(format_from_path("x.vtu") == TetFormat::Vtu);
  CHECK(format_from_path("x.node") == TetFormat::TetGen);
  CHECK(format_from_path("x.ele") == TetFormat::TetGen);
  CHECK(format_from_path("x.off") == TetFormat::Auto);
  CHECK(format_from_path("dir.msh/file") == TetFormat::Auto);
  CHECK(is_tet_mesh_path("x.vtu"));
  CHECK_FALSE(is_tet_mesh_path("x.stl"));

  // An explicit format overrides the extension.
  ScratchDir dir("explicit");
  TetMesh m = make_box(Vec3(1, 1, 1), {1, 1, 1});
  WriteOptions o;
  o.format = TetFormat::Medit;
  write_tet_mesh(m, dir / "box.txt", o);
  CHECK(read_text(dir / "box.txt").rfind("MeshVersionFormatted", 0) == 0);
  CHECK_THROWS_AS(write_tet_mesh(m, dir / "box.off"), IoError);
  CHECK_THROWS_AS(write_tet_mesh(m, dir / "box.xyz"), IoError);
}

TEST_CASE("negative tets are reoriented and counted", "[io]") {
  ScratchDir dir("reorient");
  // Two tets sharing a face, the second written with negative orientation.
  write_text(dir / "neg.mesh",
             "MeshVersionFormatted 2\nDimension 3\nVertices\n5\n0 0 0 0\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 -1 0\n"
             "Tetrahedra\n2\n1 2 3 4 1\n1 2 3 5 2\nEnd\n");
  ReadReport r;
  TetMesh m = read_tet_mesh(dir / "neg.mesh", &r);
  m.validate();
  CHECK(r.reoriented_tets == 1);
  CHECK(m.total_volume() == Approx(1.0 / 3));
  CHECK(m.boundary_faces().size() == 6);
}

TEST_CASE("unreferenced vertices are kept and mixed cells skipped", "[io]") {
  ScratchDir dir("mixed");
  write_text(dir / "mixed.msh",
             "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 5 \"organ\"\n$EndPhysicalNames\n"
             "$Nodes\n7\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n10 5 5 5\n11 6 6 6\n$EndNodes\n"
             "$Elements\n6\n1 15 2 0 1 1\n2 1 2 0 1 1 2\n3 2 2 33 1 1 3 2\n4 4 2 5 1 1 2 3 4\n"
             "5 4 2 6 1 2 3 4 5\n6 3 2 0 1 1 2 5 3\n$EndElements\n"
             "$NodeData\n1\n\"x\"\n1\n0.0\n3\n0\n1\n1\n1 0.5\n$EndNodeData\n");
  ReadReport r;
  TetMesh m = read_tet_mesh(dir / "mixed.msh", &r);
  m.validate();
  CHECK(m.num_vertices() == 7);
  CHECK(m.num_tets() == 2);
  CHECK(r.unreferenced_vertices == 2);
  CHECK(r.skipped_cells == 4);  // point, line, triangle, quad
  CHECK(r.tagged_boundary_faces == 1);
  CHECK(r.format == "gmsh 2.2 ascii");
  // The triangle (1,3,2) carries tag 33 onto the boundary face of tet 1; the rest are surface.
  std::map<int, int> tags;
  for (const auto& f : m.boundary_faces()) ++tags[f.tag];
  CHECK(tags[33] == 1);
  CHECK(tags[kTagSurface] == 5);
  std::map<int, int> labels;
  for (TetId t : m.tets()) ++labels[m.label(t)];
  CHECK(labels[5] == 1);
  CHECK(labels[6] == 1);
}

TEST_CASE("fields are written to VTU and VTK", "[io][fields]") {
  ScratchDir dir("fields");
  TetMesh m = box_with_holes();
  std::vector<Vec3> current(m.vertex_capacity(), Vec3::Zero());
  Field disp{"displacement", 3, std::vector<double>(3 * m.vertex_capacity(), 0.0)};
  Field stress{"stress", 1, std::vector<double>(m.tet_capacity(), 0.0)};
  Field tensor{"sigma", 9, std::vector<double>(9 * m.tet_capacity(), 0.5)};
  for (VertexId v : m.vertices()) {
    Vec3 d(0.01 * v.idx(), -0.02, 0.001 * v.idx() * v.idx());
    current[v.idx()] = m.rest(v) + d;
    for (int k = 0; k < 3; ++k) disp.values[3 * v.idx() + k] = d[k];
  }
  for (TetId t : m.tets()) stress.values[t.idx()] = 1e6 + t.idx();
  MeshFields fields;
  fields.points = &current;
  fields.point_data = {disp};
  fields.cell_data = {stress, tensor};
  for (std::string name : {"f.vtu", "f.vtk"}) {
    for (bool binary : {false, true}) {
      WriteOptions o;
      o.binary = binary;
      const std::string path = dir / ((binary ? "b" : "a") + name);
      write_tet_mesh_with_fields(m, path, fields, o);
      TetMesh back = read_tet_mesh(path);
      REQUIRE(back.num_tets() == m.num_tets());
      auto vb = back.vertices();
      auto va = m.vertices();
      for (std::size_t i = 0; i < va.size(); ++i) REQUIRE(back.rest(vb[i]) == current[va[i].idx()]);
      auto ta = m.tets(), tb = back.tets();
      for (std::size_t i = 0; i < ta.size(); ++i) REQUIRE(back.label(tb[i]) == m.label(ta[i]));
      if (have_meshio()) {
        std::string cmd = "/usr/bin/python3 -c \"import meshio,sys,numpy as np; m=meshio.read(sys.argv[1]); "
                          "d=m.point_data['displacement']; s=np.concatenate(m.cell_data['stress']).ravel(); "
                          "sys.exit(0 if d.shape==(" +
                          std::to_string(m.num_vertices()) + ",3) and abs(s.sum()-" +
                          std::to_string(std::accumulate(stress.values.begin(), stress.values.end(), 0.0)) +
                          ")<1e-3 else 1)\" " + path + " 2>/dev/null";
        INFO(cmd);
        CHECK(std::system(cmd.c_str()) == 0);
      }
    }
  }
  // Fields need a format that carries them, and sizes that match the mesh.
  CHECK_THROWS_AS(write_tet_mesh_with_fields(m, dir / "f.msh", fields), InvalidArgument);
  MeshFields bad;
  bad.point_data = {Field{"short", 3, std::vector<double>(5)}};
  CHECK_THROWS_AS(write_tet_mesh_with_fields(m, dir / "bad.vtu", bad), InvalidArgument);
  CHECK_FALSE(fs::exists(dir / "bad.vtu"));
}

TEST_CASE("meshio reads every file incise writes", "[io][meshio]") {
  if (!have_meshio()) {
    WARN("/usr/bin/python3 has no meshio; skipping the meshio cross-check");
    return;
  }
  ScratchDir dir("meshio_reads");
  std::vector<Case> cs;
  cs.push_back({"ellipsoid", labeled_ellipsoid()});
  cs.push_back({"holes", box_with_holes()});
  cs.push_back({"huge", labeled_ellipsoid(1e8, Vec3(3e8, -1e8, 7e7))});
  for (Case& c : cs) {
    double coord_sum = 0;
    for (VertexId v : c.mesh.vertices()) coord_sum += c.mesh.rest(v).sum();
    std::string labels;
    for (TetId t : c.mesh.tets()) labels += std::to_string(c.mesh.label(t)) + "\n";
    const std::string labels_file = dir / (c.name + "_labels.txt");
    write_text(labels_file, labels);
    char sum[64];
    std::snprintf(sum, sizeof sum, "%.17g", coord_sum);
    std::string cmd = "/usr/bin/python3 " + meshio_tool() + " check " + std::to_string(c.mesh.num_vertices()) + " " +
                      std::to_string(c.mesh.num_tets()) + " " + labels_file + " " + sum;
    for (const Variant& v : variants()) {
      if (v.name == "tg2.ele") continue;  // meshio reads TetGen through the .node name only
      const std::string path = dir / (c.name + "_" + v.name);
      write_tet_mesh(c.mesh, path, v.options);
      cmd += " " + path;
    }
    const std::string log = dir / (c.name + ".log");
    int rc = std::system((cmd + " > " + log + " 2>&1").c_str());
    INFO(c.name << ": " << read_text(log));
    CHECK(rc == 0);
  }
}

TEST_CASE("incise reads every tet format meshio writes", "[io][meshio]") {
  if (!have_meshio()) {
    WARN("/usr/bin/python3 has no meshio; skipping the meshio cross-check");
    return;
  }
  ScratchDir dir("meshio_writes");
  for (double scale : {1.0, 1e-8, 1e8}) {
    TetMesh ref = labeled_ellipsoid(scale);
    const std::string src = dir / "ref.vtu";
    WriteOptions bin;
    bin.binary = true;
    write_tet_mesh(ref, src, bin);
    std::string cmd = "/usr/bin/python3 " + meshio_tool() + " rewrite " + src + " " + dir.path.string() + " > " +
                      (dir / "list.txt") + " 2>/dev/null";
    REQUIRE(std::system(cmd.c_str()) == 0);
    std::istringstream list(read_text(dir / "list.txt"));
    std::string name;
    int carries = 0;
    int files = 0;
    while (list >> name >> carries) {
      ++files;
      INFO(name << " at scale " << scale);
      ReadReport report;
      TetMesh m = read_tet_mesh(dir / name, &report);
      m.validate();
      REQUIRE(m.num_vertices() == ref.num_vertices());
      REQUIRE(m.num_tets() == ref.num_tets());
      auto va = ref.vertices(), vb = m.vertices();
      // meshio writes ascii VTU with 12 significant digits; everything else is exact.
      const double tol = name == "ascii.vtu" ? 1e-11 * scale : 0.0;
      for (std::size_t i = 0; i < va.size(); ++i) REQUIRE((ref.rest(va[i]) - m.rest(vb[i])).norm() <= tol * 4);
      auto ta = ref.tets(), tb = m.tets();
      for (std::size_t i = 0; i < ta.size(); ++i) {
        std::array<std::uint32_t, 4> x, y;
        for (int k = 0; k < 4; ++k) {
          x[k] = ref.tet_vertices(ta[i])[k].idx();
          y[k] = m.tet_vertices(tb[i])[k].idx();
        }
        std::sort(x.begin(), x.end());
        std::sort(y.begin(), y.end());
        REQUIRE(x == y);
        if (carries) REQUIRE(m.label(tb[i]) == ref.label(ta[i]));
      }
      CHECK(std::abs(m.total_volume() - ref.total_volume()) <= 1e-9 * ref.total_volume());
    }
    CHECK(files == 10);
  }
}

TEST_CASE("a frame's cut_face_mask comes back as cut tags, and its cell fields are reported", "[io][fields]") {
  ScratchDir dir("cut_mask");
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  // Tag a few boundary faces as cut and write the mask the way a scene frame does.
  std::vector<double> mask(m.tet_capacity(), 0.0), stress(m.tet_capacity(), 0.0);
  std::set<std::array<std::uint32_t, 3>> cut;
  int n = 0;
  for (TetId t : m.tets()) {
    stress[t.idx()] = 10.0 + t.idx();
    for (int f = 0; f < 4; ++f)
      if (!m.neighbor(t, f).is_valid() && n++ % 3 == 0) {
        m.set_face_tag(t, f, kTagCut);
        mask[t.idx()] += double(1 << f);
        auto fv = m.face_vertices(t, f);
        std::array<std::uint32_t, 3> k{fv[0].idx(), fv[1].idx(), fv[2].idx()};
        std::sort(k.begin(), k.end());
        cut.insert(k);
      }
  }
  REQUIRE(cut.size() > 3);
  // Written twice: as is, and mirrored (x -> -x), which the reader reorients (corners 2 and 3
  // swapped): the mask must follow the faces, not the local numbers.
  for (bool mirrored : {false, true}) {
    std::vector<Vec3> pts(m.vertex_capacity(), Vec3::Zero());
    for (VertexId v : m.vertices()) pts[v.idx()] = mirrored ? Vec3(-m.rest(v).x(), m.rest(v).y(), m.rest(v).z()) : m.rest(v);
    MeshFields fields;
    fields.points = &pts;
    fields.cell_data = {Field{"von_mises", 1, stress}, Field{"cut_face_mask", 1, mask}};
    const std::string path = dir / (mirrored ? "mirrored.vtu" : "frame.vtu");
    write_tet_mesh_with_fields(m, path, fields, WriteOptions{.binary = true});
    ReadReport rep;
    const TetMesh back = read_tet_mesh(path, &rep);
    CHECK(rep.reoriented_tets == (mirrored ? m.num_tets() : 0));
    CHECK(cut_faces(back) == cut);
    REQUIRE(rep.cell_data.size() == 2);
    CHECK(rep.cell_data[0].name == "von_mises");
    REQUIRE(rep.cell_data[0].values.size() == back.num_tets());
    for (TetId t : back.tets()) CHECK(rep.cell_data[0].values[t.idx()] == 10.0 + t.idx());
  }
}

// A cut read back from VTU or VTK, which have no boundary triangles: its cut faces must come
// back as cut faces (the writer adds each tet's cut_face_mask), or the improvement takes them
// for surface and may move one side of the cut into the other, which coincides with it in
// the rest shape (found on a cut organ: `incise improve` wrote overlapping tets it then refused
// to read).
TEST_CASE("a cut written to VTU, VTK or TetGen comes back with its cut faces, and improving it keeps the sides apart",
          "[io][cut]") {
  ScratchDir dir("cut_tags");
  TetMesh m = make_box(Vec3(4, 2, 1), {16, 8, 4});
  {
    // A vertical blade along a quarter circle entering through y = 0 and ending inside: a
    // curved sheet with a front.
    Cutter cutter(m);
    auto blade = [](double a) {
      const Vec3 p(2.03 + std::cos(a), std::sin(a), 0);
      return BladeSegment{Vec3(p.x(), p.y() - (a == 0 ? 0.2 : 0), -0.5), Vec3(p.x(), p.y() - (a == 0 ? 0.2 : 0), 1.5)};
    };
    cutter.start(blade(0));
    for (int k = 1; k <= 20; ++k) cutter.advance(blade(1.2 * k / 20));
    cutter.finish();
  }
  m.compact();
  const auto cut = cut_faces(m);
  REQUIRE(cut.size() > 50);
  for (const char* name : {"cut.vtu", "cut.vtk", "cut-binary.vtu", "cut-binary.vtk", "cut.ele"}) {
    CAPTURE(name);
    const std::string path = dir / name;
    write_tet_mesh(m, path, WriteOptions{.binary = std::string(name).find("binary") != std::string::npos});
    TetMesh back = read_tet_mesh(path);
    CHECK(cut_faces(back) == cut);
    // The improvement as `incise improve` runs it (slides and flips on curved parts).
    ImproveOptions o;
    o.slide_curved = true;
    o.time_limit_s = 0;
    o.max_work = 20000;
    improve(back, o);
    CHECK_FALSE(find_overlapping_tets(back).has_value());
  }
}

TEST_CASE("a TetGen .ele's second attribute is a cut mask only where its header says so", "[io][cut]") {
  ScratchDir dir("tetgen_mask");
  const std::string node = dir / "t.node";
  {
    std::ofstream f(node);
    f << "4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
  }
  auto write_ele = [&](const std::string& text) {
    std::ofstream f(dir / "t.ele");
    f << text;
  };
  // Another tool's second attribute: read as nothing.
  write_ele("1 4 2\n0 0 1 2 3 7 9\n");
  TetMesh plain = read_tet_mesh(node);
  CHECK(cut_faces(plain).empty());
  CHECK(plain.label(TetId(0)) == 7);
  // incise's header: the mask's bits tag the faces (bit k: the face opposite corner k).
  write_ele("# incise tetrahedral mesh; attributes: region label, cut_face_mask\n1 4 2\n0 0 1 2 3 7 9\n");
  TetMesh tagged = read_tet_mesh(node);
  CHECK(cut_faces(tagged).size() == 2);
  for (int k = 0; k < 4; ++k) CHECK((tagged.face_tag(TetId(0), k) == kTagCut) == (k == 0 || k == 3));
  // A mask that is not one: the file and line are named.
  write_ele("# incise tetrahedral mesh; attributes: region label, cut_face_mask\n1 4 2\n0 0 1 2 3 7 16\n");
  try {
    read_tet_mesh(node);
    FAIL("a mask of 16 was read");
  } catch (const IoError& e) {
    CHECK(e.file().find("t.ele") != std::string::npos);
    CHECK(e.line() == 3);
    CHECK(std::string(e.what()).find("cut face mask") != std::string::npos);
  }
}

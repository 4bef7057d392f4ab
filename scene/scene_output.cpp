#include "scene/scene_output.h"

#include <cstdio>
#include <filesystem>
#include <iomanip>

#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/tet_io.h"
#include "sim/fem/quadratic_solver.h"

namespace incise {

namespace {

namespace fs = std::filesystem;

void write_text_atomic(const std::string& path, const std::string& text) {
  AtomicFile f(path);
  f.write(text);
  f.commit();
}

}  // namespace

SceneOutput::SceneOutput(const Scene& scene, std::string dir)
    : dir_(std::move(dir)), cuts_(!scene.cuts.empty()), springs_(scene.model == SceneModel::Springs),
      binary_(scene.output_binary) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw IoError(dir_, 0, "cannot create output directory: " + ec.message());
  csv_ << "frame,time,iterations,relative_residual,solve_ms,budget_exhausted,converged,max_displacement,frame_ms,"
          "setup_ms,cheaper_preconditioner,relinearized,outside_ms,inverted"
       << (cuts_ ? ",cut_ms,tets" : "") << (springs_ ? ",stable_dt" : "") << "\n";
  csv_ << std::setprecision(9);
  pvd_ << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
          "  <Collection>\n";
}

std::string SceneOutput::add(SceneRunner& runner, const SceneFrame& f, bool vtu) {
  const FrameStats& st = f.stats;
  const TetMesh& mesh = runner.mesh();
  const bool converged = st.info == SolveInfo::Success;
  csv_ << f.frame << "," << f.time << "," << st.iterations << "," << st.relative_residual << "," << st.solve_ms << ","
       << (st.budget_exhausted ? 1 : 0) << "," << (converged ? 1 : 0) << "," << f.max_displacement << "," << st.frame_ms
       << "," << st.setup_ms << "," << (st.cheaper_preconditioner ? 1 : 0) << "," << st.relinearized << "," << st.outside_ms
       << "," << f.inverted;
  if (cuts_) csv_ << "," << f.cut_ms << "," << mesh.num_tets();
  if (springs_) csv_ << "," << f.stable_dt;
  csv_ << "\n";
  if (!vtu) return "";

  char name[64];
  std::snprintf(name, sizeof name, "frame_%04d.vtu", f.frame);
  const Eigen::VectorXd& disp = f.displacement;
  std::vector<Vec3> pts(mesh.vertex_capacity(), Vec3::Zero());
  for (VertexId v : mesh.vertices()) pts[v.idx()] = mesh.rest(v) + disp.segment<3>(3 * v.idx());
  MeshFields fields;
  fields.points = &pts;
  std::vector<double> point_disp(disp.data(), disp.data() + disp.size());
  // Quadratic tets: the mid-edge nodes (displaced) and their displacement follow the vertices,
  // the cells are VTK_QUADRATIC_TETRA.
  std::vector<Vec3> mid_points;
  std::vector<std::array<std::uint32_t, 6>> mid_nodes;
  if (const QuadraticSolver* q = runner.fem() ? runner.fem()->quadratic() : nullptr) {
    const P2Mesh& p2 = q->p2();
    const Eigen::VectorXd& qu = runner.fem()->quadratic_displacement();
    point_disp.resize(3 * mesh.vertex_capacity());  // mid-edge data follows every vertex slot
    for (std::size_t e = 0; e < p2.edges.size(); ++e) {
      const std::size_t n = p2.corner_slots + e;
      const Vec3 d = qu.segment<3>(3 * Eigen::Index(n));
      mid_points.push_back(p2.rest(mesh, n) + d);
      point_disp.insert(point_disp.end(), d.data(), d.data() + 3);
    }
    mid_nodes.assign(mesh.tet_capacity(), {});
    for (TetId t : mesh.tets())
      for (std::size_t k = 0; k < 6; ++k) mid_nodes[t.idx()][k] = std::uint32_t(p2.tets[t.idx()][4 + k] - p2.corner_slots);
    fields.mid_points = &mid_points;
    fields.mid_nodes = &mid_nodes;
  }
  fields.point_data.push_back(Field{"displacement", 3, std::move(point_disp)});
  if (runner.fem()) fields.cell_data.push_back(Field{"von_mises", 1, runner.fem()->von_mises()});
  if (cuts_) {
    // Cut faces per tet (0..4): ParaView's threshold on it shows the cut surfaces. The mask
    // says which (bit k: the face opposite the tet's k-th corner), so a reader (incise's, and
    // `incise view RUN_DIR`) gets the cut faces back as boundary tags.
    std::vector<double> cut_faces(mesh.tet_capacity(), 0.0), mask(mesh.tet_capacity(), 0.0);
    for (TetId t : mesh.tets())
      for (int k = 0; k < 4; ++k)
        if (!mesh.neighbor(t, k).is_valid() && mesh.face_tag(t, k) == kTagCut) {
          cut_faces[t.idx()] += 1;
          mask[t.idx()] += double(1 << k);
        }
    fields.cell_data.push_back(Field{"cut_faces", 1, std::move(cut_faces)});
    fields.cell_data.push_back(Field{"cut_face_mask", 1, std::move(mask)});
  }
  WriteOptions wo;
  wo.binary = binary_;
  write_tet_mesh_with_fields(mesh, (fs::path(dir_) / name).string(), fields, wo);
  pvd_ << "    <DataSet timestep=\"" << f.time << "\" group=\"\" part=\"0\" file=\"" << name << "\"/>\n";
  return name;
}

std::vector<std::string> SceneOutput::finish() {
  pvd_ << "  </Collection>\n</VTKFile>\n";
  write_text_atomic((fs::path(dir_) / "stats.csv").string(), csv_.str());
  write_text_atomic((fs::path(dir_) / "frames.pvd").string(), pvd_.str());
  return {"stats.csv", "frames.pvd"};
}

}  // namespace incise

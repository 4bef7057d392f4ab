// incise trade's reference (scene/trade_reference.h): the bodies per level, the quadratic
// reference and its Richardson error bar.
#include "scene/trade_reference.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "mesh/memory_limit.h"
#include "mesh/refine.h"
#include "quality/coarsen.h"
#include "scene/run_scene.h"

namespace incise::trade_detail {

namespace {

// Memory of the reference solve per tet (the mesh, the assembled quadratic system and its
// Cholesky factor, whose fill grows about as the cube root of the size):
// docs/solver.md#picking-settings-for-a-scene-incise-trade.
double reference_bytes_per_tet(double tets) { return 65000 * std::max(1.0, std::cbrt(tets / 4.2e4)); }

// The reference's formulation: quadratic tets, Taylor-Hood when a material is nearly
// incompressible (P2 alone locks mildly there; docs/solver.md#quadratic-tets).
Formulation reference_formulation(const Scene& s) {
  double nu = s.materials.has_default() ? s.materials.fallback().poisson : 0.0;
  for (const auto& [label, m] : s.materials.by_label()) nu = std::max(nu, m.poisson);
  return nu > 0.45 ? Formulation::MixedQuadratic : Formulation::Quadratic;
}

}  // namespace

const char* model_name(SceneModel m) {
  switch (m) {
    case SceneModel::FemLinear: return "fem-linear";
    case SceneModel::FemCorotational: return "fem-corotational";
    case SceneModel::Springs: return "springs";
  }
  return "?";
}

std::string fmt(double v) {
  std::ostringstream s;
  s << std::setprecision(4) << v;
  return s.str();
}


TetMesh body_at(const Scene& s, int level, std::string* how) {
  if (level < -1) throw InvalidArgument("trade: resolutions below -1 are not supported");
  TetMesh m;
  if (level < 0) {
    if (!s.generator.empty()) {
      auto half = [](int n) { return std::max(1, n / 2); };
      if (how) *how = "the " + s.generator + " generator with half the cells";
      if (s.generator == "ellipsoid") m = generate_scene_mesh(s, {half(s.gen_resolution), 0, 0});
      else m = generate_scene_mesh(s, {half(s.gen_cells[0]), half(s.gen_cells[1]), half(s.gen_cells[2])});
      m.compact();
      return m;
    }
    // A file: nothing regenerates it coarser, so contract its edges to about twice their
    // length (quality/coarsen.h: same labels, tags and body within a bounded distance).
    m = load_scene_mesh(s);
    m.compact();
    const CoarsenReport r = coarsen(m);
    m.discard_change();
    m.compact();
    if (how) {
      std::ostringstream t;
      t << std::setprecision(3) << std::filesystem::path(s.mesh_file).filename().string()
        << " coarsened by edge contraction: " << r.tets_before << " -> " << r.tets_after << " tets, mean edge "
        << r.mean_edge_before << " -> " << r.mean_edge_after << ", surface within " << r.max_deviation;
      *how = t.str();
    }
    return m;
  }
  m = load_scene_mesh(s);  // its file (relative to the scene) or its generator, as run_scene reads it
  m.compact();
  for (int k = 0; k < level; ++k) m = refine_uniform(m);
  m.discard_change();
  return m;
}

Probe locate(const TetMesh& run, const PointLocator& loc) {
  Probe p;
  p.at.resize(run.vertex_capacity(), PointLocation{TetId(), {0, 0, 0, 0}, 0});
  for (VertexId v : run.vertices()) p.at[v.idx()] = loc.locate(run.rest(v));
  return p;
}

Eigen::VectorXd sample(const TetMesh& ref, const Probe& p, const Eigen::VectorXd& u_ref) {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(Eigen::Index(3 * p.at.size()));
  for (std::size_t v = 0; v < p.at.size(); ++v)
    if (p.at[v].tet.is_valid()) PointLocator::interpolate(ref, p.at[v], u_ref.data(), 3, out.data() + 3 * v);
  return out;
}

Errors compare(const Eigen::VectorXd& u, const Eigen::VectorXd& ref) {
  const Eigen::Index n = std::min(u.size(), ref.size());
  const double norm = ref.head(n).norm(), diff = (u.head(n) - ref.head(n)).norm();
  double mu = 0, mr = 0;
  for (Eigen::Index i = 0; i + 2 < n; i += 3) {
    mu = std::max(mu, u.segment<3>(i).norm());
    mr = std::max(mr, ref.segment<3>(i).norm());
  }
  return {norm > 0 ? diff / norm : diff, mr > 0 ? std::abs(mu - mr) / mr : std::abs(mu - mr)};
}

const TetMesh& Basis::mesh(int level, std::ostream* progress) {
  auto& m = meshes[level];
  if (!m) {
    m = std::make_unique<TetMesh>(body_at(scene, level, level < 0 ? &coarser : nullptr));
    if (level < 0 && progress) *progress << "trade: level -1: " << coarser << "\n";
  }
  return *m;
}

const Probe& Basis::probe(int level) {
  auto it = probes.find(level);
  if (it == probes.end()) it = probes.emplace(level, locate(*meshes.at(level), *locator)).first;
  return it->second;
}

// `levels`: the resolutions that will be run (empty: the default, see TradeOptions).
void prepare(Basis& b, const Scene& cut_scene, const TradeOptions& opt, std::vector<int> levels) {
  // Meshes of different resolutions cut by one blade give different bodies, so there is no
  // shared reference through a cut: settings are compared on the uncut body, and it is said.
  b.scene = cut_scene;
  if (!b.scene.cuts.empty()) {
    if (opt.progress)
      *opt.progress << "trade: the scene's " << b.scene.cuts.size()
                    << " cut(s) are left out: settings are compared on the uncut body\n";
    b.scene.cuts.clear();
  }
  const Scene& scene = b.scene;
  auto mesh = [&](int level) -> const TetMesh& { return b.mesh(level, opt.progress); };
  if (levels.empty()) {
    // A coarser level (generated with half the cells, or the file's mesh coarsened), the
    // scene's, and a refined one when its reference (64x the scene's tets) stays within what a
    // direct solve does in seconds.
    levels.push_back(-1);
    levels.push_back(0);
    if (64 * mesh(0).num_tets() <= opt.max_reference_tets) levels.push_back(1);
  }
  std::sort(levels.begin(), levels.end());
  levels.erase(std::unique(levels.begin(), levels.end()), levels.end());
  b.levels = levels;
  const int ref_level = opt.reference_level >= 0 ? opt.reference_level : levels.back() + 1;
  if (ref_level <= levels.back())
    throw InvalidArgument("trade: the reference level (" + std::to_string(ref_level) +
                          ") must be above the finest resolution (" + std::to_string(levels.back()) + ")");
  {
    // The reference's size before it is built: each level splits every tet into 8.
    const double tets = double(mesh(0).num_tets()) * std::pow(8.0, ref_level);
    refuse_past_memory("trade: the reference at level " + std::to_string(ref_level), tets * reference_bytes_per_tet(tets),
                       std::to_string(static_cast<long long>(tets)) + " tets", "use a lower --reference-level");
  }
  b.frames = opt.frames >= 0 ? opt.frames : scene.frames;
  const int frames = b.frames;

  // ---- the reference, and the same one level coarser for its error bar ------------------
  const Formulation best = reference_formulation(scene);
  auto solve_reference = [&](int level) {
    Scene rs = scene;
    rs.model = SceneModel::FemCorotational;
    rs.formulation = best;
    // Quadratic tets, assembled, solved directly (LDL^T / CHOLMOD; SparseLU for Taylor-Hood) up
    // to direct_reference_tets; above, SparseLU's fill makes a frame take minutes, and the
    // iterative solver preconditioned by the exact factor of the displacement block (MINRES for
    // Taylor-Hood) to 1e-10 gives the same answer to that digit.
    rs.method = mesh(level).num_tets() <= opt.direct_reference_tets ? SolverMethod::Direct : SolverMethod::Cg;
    rs.cg.preconditioner = Preconditioner::Cholesky;
    rs.cg.tolerance = 1e-10;
    rs.cg.max_iterations = 100000;
    rs.cg.budget_ms = 0;
    rs.inversion_barrier = {};
    rs.integrator = "static";
    std::vector<Eigen::VectorXd> u;
    SceneRunOptions ro;
    ro.frames = frames;
    ro.mesh = &mesh(level);
    ro.on_frame = [&](int, const Eigen::VectorXd& d, const FrameStats&) { u.push_back(d); };
    run_scene(rs, ro);
    return u;
  };
  const TetMesh& ref_mesh = mesh(ref_level);
  const std::string method = ref_mesh.num_tets() <= opt.direct_reference_tets ? "direct"
                             : best == Formulation::MixedQuadratic       ? "minres 1e-10"
                                                                         : "cg 1e-10";
  if (opt.progress)
    *opt.progress << "trade: reference: level " << ref_level << " (" << ref_mesh.num_tets() << " tets), fem-corotational "
                  << formulation_name(best) << ", " << method << ", " << frames << " frames\n";
  auto t0 = std::chrono::steady_clock::now();
  b.ref = solve_reference(ref_level);
  b.reference = {ref_level, ref_mesh.num_tets(), std::string(formulation_name(best)), method, seconds_since(t0), -1};
  b.locator = std::make_unique<PointLocator>(ref_mesh);
  if (ref_level >= 1) {
    const std::vector<Eigen::VectorXd> coarser = solve_reference(ref_level - 1);
    const TetMesh& cm = mesh(ref_level - 1);
    const Probe& at_scene = b.probe(0);
    // Both read at the scene mesh's vertices: the coarser one through its own locator.
    const PointLocator cl(cm);
    const Probe at_scene_coarse = locate(mesh(0), cl);
    double change = 0;
    for (std::size_t f = 0; f < b.ref.size() && f < coarser.size(); ++f)
      change = std::max(change, compare(sample(cm, at_scene_coarse, coarser[f]), sample(ref_mesh, at_scene, b.ref[f])).l2);
    b.reference.change = change;
    // Richardson over the two levels: with error ~ C h^p, the finer one's is change / (2^p - 1).
    b.reference.error_bar = change / (std::pow(2.0, b.reference.order) - 1);
  }
  if (opt.progress) {
    *opt.progress << "trade: reference took " << fmt(b.reference.seconds) << " s";
    if (b.reference.change >= 0)
      *opt.progress << "; it differs from level " << ref_level - 1 << " by " << fmt(b.reference.change)
                    << " (relative L2), so its error bar (Richardson, order " << fmt(b.reference.order)
                    << ") is " << fmt(b.reference.error_bar) << ": errors below that are not resolved";
    *opt.progress << "\n";
  }
}

}  // namespace incise::trade_detail

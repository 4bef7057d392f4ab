// The corotational relinearization, FemModel::update_rotations then add_rotation_rhs (b_R), as a
// frame does it: warm-started quaternion Newton steps, the diagonal and b_R from per-corner
// terms (new) against every tet's polar decomposition from scratch and every vertex recomputed
// from its incident tets (old: set_warm_started_rotations(false), which also recomputes b_R per
// vertex there; before this change b_R was a separate per-tet pass and gather of 1.4-1.6 ms),
// in the same run on the same sequence of displacements. Two sequences: a corotational simulation of the organ scene
// (bottom fixed, a probe pressing the top, as in bench_fem_precond), recorded frame by frame,
// and a fast twist (the mesh twisted about its long axis by 90 degrees over the frames and bent,
// ~0.03 rad per frame at the far end). Per sequence: ms per frame (median, max) old and new,
// their ratio, the largest angle between the new and the exact rotation over all tets and
// frames, the tets that fell back to the exact decomposition, the most Newton steps a packet
// took, and the new add_rotation_rhs alone (now a vector addition).
//   bench_fem_rotations [--mesh MESH] [--cells 30,15,10] [--frames 60] [--threads 2] [--new-only] [--out DIR]
#include <cmath>
#include <ctime>

#include <tbb/global_control.h>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/rest_bounds.h"
#include "mesh/io/tet_io.h"
#include "sim/fem/fem_model.h"
#include "sim/fem/fem_simulation.h"

using namespace incise;
using namespace incise::bench;

namespace {

struct Bounds {
  Vec3 lo, hi;
  explicit Bounds(const TetMesh& m) {
    const RestBounds b = rest_bounds(m);
    lo = b.lo;
    hi = b.hi;
  }
  Vec3 size() const { return hi - lo; }
};

// The organ scene of bench_fem_precond: bottom 15% (z) fixed, a probe on the top near the
// centre pushes down 5% of the height over 30 frames, then holds. Displacements per frame.
std::vector<Eigen::VectorXd> probe_sequence(const TetMesh& m, int frames) {
  const Bounds b(m);
  const Vec3 c = 0.5 * (b.lo + b.hi), s = b.size();
  FemSimulationOptions opt;
  opt.kind = FemKind::Corotational;
  opt.cg.tolerance = 1e-6;
  opt.cg.max_iterations = 20000;
  opt.cg.preconditioner = Preconditioner::BlockJacobi;
  opt.check_rigid_modes = false;  // meshed organs can carry a loose tet or two: they stay at rest
  Material mat;
  mat.young = 1e4;
  mat.poisson = 0.45;
  FemSimulation sim(m, MaterialTable(mat), opt);
  std::vector<VertexId> probe;
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    if (p.z() < b.lo.z() + 0.15 * s.z()) sim.fix(v);
    else if (p.z() > b.hi.z() - 0.25 * s.z() && std::abs(p.x() - c.x()) < 0.12 * s.x() && std::abs(p.y() - c.y()) < 0.12 * s.y())
      probe.push_back(v);
  }
  std::sort(probe.begin(), probe.end(), [&](VertexId a, VertexId d) { return m.rest(a).z() > m.rest(d).z(); });
  probe.resize(std::max<std::size_t>(3, probe.size() / 4));
  std::vector<Eigen::VectorXd> out;
  for (int f = 0; f < frames; ++f) {
    const double k = std::min(1.0, double(f + 1) / 30);
    for (VertexId v : probe) sim.prescribe(v, Vec3(0, 0, -0.05 * s.z() * k));
    sim.step();
    out.push_back(sim.displacement());
  }
  return out;
}

// Twisted about the longest axis by up to 90 degrees at its far end and bent.
std::vector<Eigen::VectorXd> twist_sequence(const TetMesh& m, std::size_t rows, int frames) {
  const Bounds b(m);
  const Vec3 s = b.size(), c = 0.5 * (b.lo + b.hi);
  int a = 0;
  for (int i = 1; i < 3; ++i)
    if (s[i] > s[a]) a = i;
  std::vector<Eigen::VectorXd> out;
  for (int f = 0; f < frames; ++f) {
    const double t = double(f + 1) / frames;
    Eigen::VectorXd u = Eigen::VectorXd::Zero(Eigen::Index(rows));
    for (VertexId v : m.vertices()) {
      const Vec3 p = m.rest(v);
      const double along = (p[a] - b.lo[a]) / s[a];
      const Eigen::Matrix3d r = Eigen::AngleAxisd(0.5 * M_PI * t * along, Vec3::Unit(a)).toRotationMatrix();
      Vec3 d = r * (p - c) + c - p;
      d[(a + 1) % 3] += 0.2 * s[a] * t * along * along;
      u.segment<3>(3 * v.idx()) = d;
    }
    out.push_back(std::move(u));
  }
  return out;
}

// CPU time of the process (all threads) in ms: on a machine shared with other jobs, wall time
// includes the time the threads wait for a core; CPU time / threads is what a quiet machine's
// wall time would be if the threads scale.
double cpu_ms() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return 1e3 * double(ts.tv_sec) + 1e-6 * double(ts.tv_nsec);
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

void run(const char* name, const TetMesh& m, const std::vector<Eigen::VectorXd>& seq, bool new_only, Csv& csv) {
  const MaterialTable mats(Material{});
  FemModel old_model(m, mats, FemKind::Corotational), new_model(m, mats, FemKind::Corotational);
  old_model.set_warm_started_rotations(new_only);  // --new-only: both new (for profiling the new path)
  std::vector<double> t_old, t_new, t_rhs, c_old, c_new;
  double worst = 0;
  std::size_t exact = 0;
  int steps = 0;
  Eigen::VectorXd b(new_model.rows());
  for (const Eigen::VectorXd& u0 : seq) {
    Eigen::VectorXd u = u0;
    u.conservativeResize(new_model.rows());  // the simulation's vectors may be longer
    // A frame's relinearization, as FemSimulation does it: rotations, then b_R.
    b.setZero();
    double t0 = now_ms(), c0 = cpu_ms();
    old_model.update_rotations(u);
    old_model.add_rotation_rhs(b);
    t_old.push_back(now_ms() - t0);
    c_old.push_back(cpu_ms() - c0);
    b.setZero();
    t0 = now_ms(), c0 = cpu_ms();
    new_model.update_rotations(u);
    const double t1 = now_ms();
    new_model.add_rotation_rhs(b);
    t_new.push_back(now_ms() - t0);
    c_new.push_back(cpu_ms() - c0);
    t_rhs.push_back(now_ms() - t1);
    exact += new_model.rotation_stats().exact;
    steps = std::max(steps, new_model.rotation_stats().max_steps);
    for (TetId t : m.tets())
      worst = std::max(worst, Eigen::AngleAxisd(old_model.rotation(t).transpose() * new_model.rotation(t)).angle());
  }
  // The first frame starts from identity everywhere: reported in the max, not the median.
  const double mo = median(t_old), mn = median(t_new);
  const double xo = *std::max_element(t_old.begin(), t_old.end()), xn = *std::max_element(t_new.begin(), t_new.end());
  const double co = median(c_old), cn = median(c_new);
  std::printf("%-7s %7zu %6zu %10.3f %10.3f %10.3f %10.3f %7.2f %10.3f %10.3f %7.2f %10.2e %9zu %6d %9.3f\n", name,
              m.num_tets(), seq.size(), mo, xo, mn, xn, mo / mn, co, cn, co / cn, worst, exact, steps, median(t_rhs));
  csv.row(name, m.num_tets(), seq.size(), mo, xo, mn, xn, mo / mn, co, cn, co / cn, worst, exact, steps, median(t_rhs));
}

}  // namespace

int main(int argc, char** argv) {
  Args args(argc, argv);
  const int frames = int(args.num("--frames", 60));
  const int threads = int(args.num("--threads", 2));
  tbb::global_control gc(tbb::global_control::max_allowed_parallelism, std::size_t(threads));
  TetMesh m;
  const std::string path = args.get("--mesh", "");
  if (!path.empty()) {
    m = read_tet_mesh(path);
  } else {
    const auto cells = args.list("--cells", "30,15,10");  // 27,000 tets
    m = make_box(Vec3(cells[0], cells[1], cells[2]) / cells[0], {int(cells[0]), int(cells[1]), int(cells[2])});
  }
  m.discard_change();
  Csv csv(args.get("--out", "."), "fem_rotations.csv",
          "sequence,tets,frames,old_median_ms,old_max_ms,new_median_ms,new_max_ms,ratio,old_cpu_ms,new_cpu_ms,cpu_ratio,"
          "max_angle_rad,exact_fallbacks,"
          "max_steps,rotation_rhs_median_ms");
  std::printf("update_rotations per frame, %d threads, %s (%zu tets, %zu vertices)\n", threads,
              path.empty() ? "box" : path.c_str(), m.num_tets(), m.num_vertices());
  std::printf("relinearization (update_rotations + add_rotation_rhs); old: polar decomposition of every tet + every\n"
              "vertex from its tets; new: warm-started Newton steps, per-vertex sums of per-corner terms\n");
  std::printf("%-7s %7s %6s %10s %10s %10s %10s %7s %10s %10s %7s %10s %9s %6s %9s\n", "seq", "tets", "frames", "old med",
              "old max", "new med", "new max", "ratio", "old cpu", "new cpu", "cpu rat", "max angle", "fallbacks", "steps",
              "rhs med");
  const FemModel sizing(m, MaterialTable(Material{}), FemKind::Linear);
  const bool new_only = args.flag("--new-only");
  run("probe", m, probe_sequence(m, frames), new_only, csv);
  run("twist", m, twist_sequence(m, sizing.rows(), frames), new_only, csv);
  std::printf("ms per frame (wall median and max; cpu: median CPU time of all threads); ratio = old / new; max angle:\n"
              "new vs exact over all tets and frames (rad); rhs: the new add_rotation_rhs alone.\n"
              "CSV: %s\n",
              csv.path().c_str());
  return 0;
}

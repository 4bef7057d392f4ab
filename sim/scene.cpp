#include "sim/scene.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <ostream>
#include <sstream>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "cut/snap_rule.h"
#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/input_checks.h"
#include "mesh/io/tet_io.h"
#include "sim/integrator.h"
#include "sim/spring_model.h"

namespace incise {

namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

// Reads typed values and reports "FILE: key: expected ..." on anything else.
class Reader {
public:
  explicit Reader(std::string path) : path_(std::move(path)) {}
  [[noreturn]] void fail(const std::string& key, const std::string& what) const { throw IoError(path_, 0, key + ": " + what); }

  void keys(const json& obj, const std::string& key, std::initializer_list<const char*> allowed) const {
    if (!obj.is_object()) fail(key.empty() ? "(top level)" : key, "expected an object");
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      const std::string& k = it.key();
      if (!k.empty() && k[0] == '_') continue;  // "_comment" and friends
      bool ok = false;
      for (const char* a : allowed) ok = ok || k == a;
      if (!ok) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(join(key, k), "unknown key; expected one of " + list);
      }
    }
  }
  static std::string join(const std::string& a, const std::string& b) { return a.empty() ? b : a + "." + b; }

  double number(const json& j, const std::string& key) const {
    if (!j.is_number()) fail(key, "expected a number");
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(key, "expected a finite number");
    return v;
  }
  double positive(const json& j, const std::string& key) const {
    if (!j.is_number() || !(j.get<double>() > 0) || !std::isfinite(j.get<double>())) fail(key, "expected a positive number");
    return j.get<double>();
  }
  double non_negative(const json& j, const std::string& key) const {
    if (!j.is_number() || !(j.get<double>() >= 0) || !std::isfinite(j.get<double>())) fail(key, "expected a number >= 0");
    return j.get<double>();
  }
  int integer(const json& j, const std::string& key, int min) const {
    if (!j.is_number_integer() || j.get<long long>() < min || j.get<long long>() > 1000000000)
      fail(key, "expected an integer >= " + std::to_string(min));
    return int(j.get<long long>());
  }
  bool boolean(const json& j, const std::string& key) const {
    if (!j.is_boolean()) fail(key, "expected true or false");
    return j.get<bool>();
  }
  std::string string(const json& j, const std::string& key) const {
    if (!j.is_string()) fail(key, "expected a string");
    return j.get<std::string>();
  }
  Vec3 vec3(const json& j, const std::string& key) const {
    if (!j.is_array() || j.size() != 3) fail(key, "expected an array of 3 numbers");
    Vec3 v;
    for (int i = 0; i < 3; ++i) v[i] = number(j[std::size_t(i)], key + "[" + std::to_string(i) + "]");
    return v;
  }
  SceneBox box(const json& j, const std::string& key) const {
    if (!j.is_array() || j.size() != 6) fail(key, "expected [xmin, ymin, zmin, xmax, ymax, zmax]");
    SceneBox b;
    for (int i = 0; i < 3; ++i) {
      b.lo[i] = number(j[std::size_t(i)], key + "[" + std::to_string(i) + "]");
      b.hi[i] = number(j[std::size_t(i + 3)], key + "[" + std::to_string(i + 3) + "]");
      if (b.lo[i] > b.hi[i]) fail(key, "expected min <= max on every axis (axis " + std::to_string(i) + ")");
    }
    return b;
  }
  const std::string& path() const { return path_; }

private:
  std::string path_;
};

Material read_material(const Reader& rd, const json& j, const std::string& key, const Material& base) {
  rd.keys(j, key, {"young", "poisson", "density"});
  Material m = base;
  if (j.contains("young")) m.young = rd.positive(j["young"], key + ".young");
  if (j.contains("poisson")) {
    m.poisson = rd.number(j["poisson"], key + ".poisson");
    // 0.5 is allowed here and refused after parsing unless the formulation is mixed.
    if (m.poisson < 0 || m.poisson > 0.5) rd.fail(key + ".poisson", "expected a Poisson's ratio in [0, 0.5]");
  }
  if (j.contains("density")) m.density = rd.positive(j["density"], key + ".density");
  return m;
}

// "xz" -> bits 0 and 2: the held displacement components of a fixed box.
unsigned read_axes(const Reader& rd, const json& j, const std::string& key) {
  const std::string c = rd.string(j, key);
  unsigned axes = 0;
  for (char ch : c) {
    const auto at = std::string_view("xyz").find(ch);
    if (at == std::string_view::npos || (axes >> at & 1u)) axes = 8;  // marks it bad
    else axes |= 1u << at;
  }
  if (axes == 0 || axes > 7) rd.fail(key, "expected the held components as letters, e.g. \"xyz\" or \"z\", got \"" + c + "\"");
  return axes;
}

SceneLoad read_load(const Reader& rd, const json& j, const std::string& key) {
  if (!j.is_object()) rd.fail(key, "expected an object");
  if (!j.contains("type")) rd.fail(key + ".type", "missing; expected \"force\", \"gravity\", \"probe\" or \"pressure\"");
  const std::string type = rd.string(j["type"], key + ".type");
  SceneLoad l;
  l.key = key;
  auto ramp = [&] {
    if (j.contains("from_frame")) l.from_frame = rd.integer(j["from_frame"], key + ".from_frame", 0);
    if (j.contains("to_frame")) l.to_frame = rd.integer(j["to_frame"], key + ".to_frame", 0);
    else l.to_frame = l.from_frame;
    if (l.to_frame < l.from_frame) rd.fail(key + ".to_frame", "expected an integer >= from_frame");
    l.ramp = j.contains("from_frame") || j.contains("to_frame");
  };
  auto need = [&](const char* k) -> const json& {
    if (!j.contains(k)) rd.fail(key + "." + k, "missing");
    return j[k];
  };
  if (type == "force") {
    rd.keys(j, key, {"type", "box", "total", "from_frame", "to_frame"});
    l.kind = SceneLoad::Kind::Force;
    l.box = rd.box(need("box"), key + ".box");
    l.value = rd.vec3(need("total"), key + ".total");
    ramp();
  } else if (type == "gravity") {
    rd.keys(j, key, {"type", "g"});
    l.kind = SceneLoad::Kind::Gravity;
    l.value = rd.vec3(need("g"), key + ".g");
  } else if (type == "probe") {
    rd.keys(j, key, {"type", "box", "displacement", "from_frame", "to_frame"});
    l.kind = SceneLoad::Kind::Probe;
    l.box = rd.box(need("box"), key + ".box");
    l.value = rd.vec3(need("displacement"), key + ".displacement");
    ramp();
    l.ramp = true;
  } else if (type == "pressure") {
    // On boundary faces chosen by tag or box (all three corners inside), pushing against each
    // face's outward normal with p times its rest area.
    rd.keys(j, key, {"type", "value", "tag", "box", "from_frame", "to_frame"});
    l.kind = SceneLoad::Kind::Pressure;
    l.value = Vec3(rd.number(need("value"), key + ".value"), 0, 0);
    if (j.contains("tag") == j.contains("box")) rd.fail(key, "expected exactly one of \"tag\" and \"box\" to select the faces");
    if (j.contains("tag")) l.tag = rd.integer(j["tag"], key + ".tag", 0);
    else l.box = rd.box(j["box"], key + ".box");
    ramp();
  } else {
    rd.fail(key + ".type", "expected \"force\", \"gravity\", \"probe\" or \"pressure\", got \"" + type + "\"");
  }
  return l;
}

void write_text_atomic(const std::string& path, const std::string& text) {
  AtomicFile f(path);
  f.write(text);
  f.commit();
}

// A vertex moved by more than this many times the body's size (the diagonal of its rest
// bounding box) means the solution blew up: no scene asks for that, while a free part under a
// static solve, an explicit step above the stable limit or loads far beyond the material do.
constexpr double kBlowUpFactor = 1e3;

// Largest vertex displacement in `disp` (3 per vertex slot); NaN when any is NaN (std::max
// would skip it), infinite when any is infinite.
double max_displacement(const Eigen::VectorXd& disp) {
  double d = 0;
  for (Eigen::Index i = 0; i + 2 < disp.size(); i += 3) {
    const double n = disp.segment<3>(i).norm();
    if (std::isnan(n)) return n;
    d = std::max(d, n);
  }
  return d;
}

// Throws when a frame's solution blew up: a non-finite displacement or residual, or a vertex
// moved by more than kBlowUpFactor times the body's size. Such a frame is never "converged".
void check_solution(const Scene& s, int frame, double max_disp, double residual, double size) {
  if (max_disp <= kBlowUpFactor * size && std::isfinite(residual)) return;  // false for NaN too
  std::ostringstream m;
  m << s.path << ": frame " << frame << ": the solution blew up (";
  if (!std::isfinite(max_disp)) m << "a displacement is NaN or infinite";
  else if (!std::isfinite(residual)) m << "relative residual " << residual;
  else {
    const double times = max_disp / size;
    m << std::setprecision(2) << "max displacement " << max_disp << ", ";
    if (times < 1e6) m << std::fixed << std::setprecision(0);
    m << times << "x the body's size" << std::defaultfloat;
  }
  m << "); ";
  if (s.model == SceneModel::Springs)
    m << "reduce time.dt or raise time.substeps, or check the loads";
  else if (s.integrator == "static")
    m << "check that every part is fixed or probed and that the loads suit the materials";
  else
    m << "reduce time.dt, or check the loads";
  throw Error(m.str());
}

// The message for a part a cut detached that holds no fixed or prescribed vertex; `why` ends it.
std::string detached_part(const Scene& s, int frame, std::size_t tets, const Vec3& near, const std::string& why) {
  std::ostringstream m;
  m << s.path << ": frame " << frame << ": a cut detached a part of " << tets << " tets near (" << std::setprecision(3)
    << near.x() << ", " << near.y() << ", " << near.z() << ") with no fixed vertex" << why;
  return m.str();
}

}  // namespace

double SceneLoad::factor(int frame) const {
  if (!ramp) return 1;
  if (frame <= from_frame) return to_frame == from_frame && frame >= from_frame ? 1.0 : 0.0;
  if (frame >= to_frame) return 1;
  return double(frame - from_frame) / double(to_frame - from_frame);
}

Scene parse_scene(const std::string& text, const std::string& path) {
  json j;
  try {
    j = json::parse(text, nullptr, true, /*ignore_comments=*/true);
  } catch (const json::parse_error& e) {
    long line = 1;
    for (std::size_t i = 0; i < text.size() && i < e.byte; ++i) line += text[i] == '\n';
    std::string what = e.what();
    const auto p = what.find("parse error");
    throw IoError(path, line, "invalid JSON: " + (p == std::string::npos ? what : what.substr(p)));
  } catch (const json::exception& e) {
    // A number too large for a double (1e999) is an out_of_range error without a position.
    std::string what = e.what();
    const auto p = what.find("] ");
    throw IoError(path, 0, "invalid JSON: " + (p == std::string::npos ? what : what.substr(p + 2)));
  }
  const Reader rd(path);
  rd.keys(j, "", {"mesh", "model", "formulation", "materials", "fixed", "loads", "solver", "time", "output", "cuts",
                  "fragments"});
  Scene s;
  s.path = path;

  if (!j.contains("mesh")) rd.fail("mesh", "missing; expected a mesh file name or {\"generate\": \"box\", ...}");
  const json& jm = j["mesh"];
  if (jm.is_string()) {
    s.mesh_file = jm.get<std::string>();
    if (s.mesh_file.empty()) rd.fail("mesh", "expected a non-empty file name");
  } else if (jm.is_object()) {
    if (!jm.contains("generate")) rd.fail("mesh.generate", "missing; expected \"box\", \"ellipsoid\" or \"tube\"");
    s.generator = rd.string(jm["generate"], "mesh.generate");
    if (s.generator == "box") {
      rd.keys(jm, "mesh", {"generate", "size", "cells"});
      if (jm.contains("size")) s.gen_size = rd.vec3(jm["size"], "mesh.size");
      if (jm.contains("cells")) {
        const json& c = jm["cells"];
        if (!c.is_array() || c.size() != 3) rd.fail("mesh.cells", "expected an array of 3 integers >= 1");
        for (int i = 0; i < 3; ++i) s.gen_cells[std::size_t(i)] = rd.integer(c[std::size_t(i)], "mesh.cells[" + std::to_string(i) + "]", 1);
      }
      for (int i = 0; i < 3; ++i)
        if (!(s.gen_size[i] > 0)) rd.fail("mesh.size", "expected 3 positive numbers");
    } else if (s.generator == "ellipsoid") {
      rd.keys(jm, "mesh", {"generate", "radii", "resolution"});
      if (jm.contains("radii")) s.gen_size = rd.vec3(jm["radii"], "mesh.radii");
      if (jm.contains("resolution")) s.gen_resolution = rd.integer(jm["resolution"], "mesh.resolution", 1);
      for (int i = 0; i < 3; ++i)
        if (!(s.gen_size[i] > 0)) rd.fail("mesh.radii", "expected 3 positive numbers");
    } else if (s.generator == "tube") {
      rd.keys(jm, "mesh", {"generate", "radii", "height", "angle", "cells"});
      s.gen_size = Vec3(0.5, 1, 0.25);
      s.gen_cells = {4, 8, 1};
      if (jm.contains("radii")) {
        const json& r = jm["radii"];
        if (!r.is_array() || r.size() != 2) rd.fail("mesh.radii", "expected [inner, outer]");
        s.gen_size[0] = rd.positive(r[0], "mesh.radii[0]");
        s.gen_size[1] = rd.positive(r[1], "mesh.radii[1]");
        if (!(s.gen_size[0] < s.gen_size[1])) rd.fail("mesh.radii", "expected inner < outer");
      }
      if (jm.contains("height")) s.gen_size[2] = rd.positive(jm["height"], "mesh.height");
      if (jm.contains("angle")) {
        s.gen_angle = rd.positive(jm["angle"], "mesh.angle");
        if (s.gen_angle >= 360) rd.fail("mesh.angle", "expected degrees in (0, 360)");
      }
      if (jm.contains("cells")) {
        const json& c = jm["cells"];
        if (!c.is_array() || c.size() != 3) rd.fail("mesh.cells", "expected an array of 3 integers >= 1");
        for (int i = 0; i < 3; ++i) s.gen_cells[std::size_t(i)] = rd.integer(c[std::size_t(i)], "mesh.cells[" + std::to_string(i) + "]", 1);
      }
    } else {
      rd.fail("mesh.generate", "expected \"box\", \"ellipsoid\" or \"tube\", got \"" + s.generator + "\"");
    }
  } else {
    rd.fail("mesh", "expected a mesh file name or {\"generate\": \"box\", ...}");
  }

  if (j.contains("model")) {
    const std::string m = rd.string(j["model"], "model");
    if (m == "fem-linear") s.model = SceneModel::FemLinear;
    else if (m == "fem-corotational") s.model = SceneModel::FemCorotational;
    else if (m == "springs") s.model = SceneModel::Springs;
    else rd.fail("model", "expected \"fem-linear\", \"fem-corotational\" or \"springs\", got \"" + m + "\"");
  }
  if (j.contains("formulation")) {
    const std::string f = rd.string(j["formulation"], "formulation");
    const auto parsed = parse_formulation(f);
    if (!parsed) rd.fail("formulation", "expected \"standard\", \"nodal-averaged\" or \"mixed\", got \"" + f + "\"");
    s.formulation = *parsed;
    if (s.model == SceneModel::Springs && s.formulation != Formulation::Standard)
      rd.fail("formulation", "is for FEM models; springs have no volumetric strain to treat");
  }

  if (j.contains("materials")) {
    const json& jm2 = j["materials"];
    if (!jm2.is_object()) rd.fail("materials", "expected an object keyed by \"*\" or a region label");
    Material fallback;
    if (jm2.contains("*")) fallback = read_material(rd, jm2["*"], "materials.*", fallback);
    s.materials.set_default(fallback);
    for (auto it = jm2.begin(); it != jm2.end(); ++it) {
      if (it.key() == "*" || (!it.key().empty() && it.key()[0] == '_')) continue;
      std::size_t used = 0;
      int label = 0;
      try {
        label = std::stoi(it.key(), &used);
      } catch (...) {
        used = 0;
      }
      if (used != it.key().size() || it.key().empty())
        rd.fail("materials." + it.key(), "expected \"*\" or an integer region label as key");
      s.materials.set(label, read_material(rd, it.value(), "materials." + it.key(), fallback));
    }
  }

  if (j.contains("fixed")) {
    const json& jf = j["fixed"];
    if (!jf.is_array()) rd.fail("fixed", "expected an array of {\"box\": [...]}");
    for (std::size_t i = 0; i < jf.size(); ++i) {
      const std::string key = "fixed[" + std::to_string(i) + "]";
      rd.keys(jf[i], key, {"box", "components"});
      if (!jf[i].contains("box")) rd.fail(key + ".box", "missing");
      SceneFixed f{rd.box(jf[i]["box"], key + ".box")};
      if (jf[i].contains("components")) f.axes = read_axes(rd, jf[i]["components"], key + ".components");
      s.fixed.push_back(f);
    }
  }
  if (j.contains("loads")) {
    const json& jl = j["loads"];
    if (!jl.is_array()) rd.fail("loads", "expected an array of loads");
    for (std::size_t i = 0; i < jl.size(); ++i) s.loads.push_back(read_load(rd, jl[i], "loads[" + std::to_string(i) + "]"));
  }

  if (j.contains("solver")) {
    const json& js = j["solver"];
    rd.keys(js, "solver", {"method", "tolerance", "max_iterations", "budget_ms", "warm_start", "preconditioner", "operator",
                           "nonlinear_iterations"});
    if (js.contains("method")) {
      const std::string m = rd.string(js["method"], "solver.method");
      if (m == "cg") s.method = SolverMethod::Cg;
      else if (m == "direct") s.method = SolverMethod::Direct;
      else rd.fail("solver.method", "expected \"cg\" or \"direct\", got \"" + m + "\"");
    }
    if (js.contains("tolerance")) s.cg.tolerance = rd.positive(js["tolerance"], "solver.tolerance");
    if (js.contains("max_iterations")) s.cg.max_iterations = rd.integer(js["max_iterations"], "solver.max_iterations", 1);
    if (js.contains("budget_ms")) s.cg.budget_ms = rd.non_negative(js["budget_ms"], "solver.budget_ms");
    if (js.contains("warm_start")) {  // true = "predict", "last" (previous frame only), false = cold
      const json& w = js["warm_start"];
      if (w.is_string() && (w.get<std::string>() == "predict" || w.get<std::string>() == "last")) {
        s.warm_start = true;
        s.predict = w.get<std::string>() == "predict";
      } else if (w.is_boolean()) {
        s.warm_start = w.get<bool>();
      } else {
        rd.fail("solver.warm_start", "expected true, false, \"predict\" or \"last\"");
      }
    }
    if (js.contains("preconditioner")) {
      try {
        s.cg.preconditioner = parse_preconditioner(rd.string(js["preconditioner"], "solver.preconditioner"));
      } catch (const InvalidArgument& e) {
        rd.fail("solver.preconditioner", e.what());
      }
    }
    if (js.contains("operator")) {
      const std::string o = rd.string(js["operator"], "solver.operator");
      if (o == "matrix-free") s.backend = StiffnessBackend::MatrixFree;
      else if (o == "assembled") s.backend = StiffnessBackend::Assembled;
      else rd.fail("solver.operator", "expected \"matrix-free\" or \"assembled\", got \"" + o + "\"");
    }
    if (js.contains("nonlinear_iterations"))
      s.nonlinear_iterations = rd.integer(js["nonlinear_iterations"], "solver.nonlinear_iterations", 1);
  }

  if (j.contains("time")) {
    const json& jt = j["time"];
    rd.keys(jt, "time", {"frames", "dt", "integrator", "damping", "substeps"});
    if (jt.contains("frames")) s.frames = rd.integer(jt["frames"], "time.frames", 1);
    if (jt.contains("dt")) s.dt = rd.positive(jt["dt"], "time.dt");
    if (jt.contains("integrator")) s.integrator = rd.string(jt["integrator"], "time.integrator");
    if (jt.contains("damping")) s.damping = rd.non_negative(jt["damping"], "time.damping");
    if (jt.contains("substeps")) s.substeps = rd.integer(jt["substeps"], "time.substeps", 1);
  }
  if (s.model == SceneModel::Springs) {
    if (s.integrator.empty()) s.integrator = "symplectic-euler";
    try {
      parse_integrator(s.integrator);
    } catch (const InvalidArgument& e) {
      rd.fail("time.integrator", e.what());
    }
    if (s.method == SolverMethod::Direct) rd.fail("solver.method", "\"direct\" is for FEM models; springs use \"cg\" (implicit-euler)");
  } else {
    if (s.integrator.empty()) s.integrator = "static";
    if (s.integrator != "static" && s.integrator != "implicit-euler")
      rd.fail("time.integrator", "expected \"static\" or \"implicit-euler\" for FEM models, got \"" + s.integrator + "\"");
  }

  if (j.contains("output")) {
    const json& jo = j["output"];
    rd.keys(jo, "output", {"every", "binary"});
    if (jo.contains("every")) s.output_every = rd.integer(jo["every"], "output.every", 1);
    if (jo.contains("binary")) s.output_binary = rd.boolean(jo["binary"], "output.binary");
  }
  if (j.contains("cuts")) {
    const json& jc = j["cuts"];
    if (!jc.is_array()) rd.fail("cuts", "expected an array of {\"blade\": [[ax,ay,az],[bx,by,bz]], \"sweep\": [dx,dy,dz], ...}");
    for (std::size_t i = 0; i < jc.size(); ++i) {
      const std::string key = "cuts[" + std::to_string(i) + "]";
      const json& c = jc[i];
      rd.keys(c, key, {"blade", "sweep", "from_frame", "to_frame", "mode", "snap", "improve"});
      SceneCut cut;
      cut.key = key;
      if (!c.contains("blade") || !c["blade"].is_array() || c["blade"].size() != 2)
        rd.fail(key + ".blade", "expected [[ax,ay,az],[bx,by,bz]]");
      cut.a = rd.vec3(c["blade"][0], key + ".blade[0]");
      cut.b = rd.vec3(c["blade"][1], key + ".blade[1]");
      if (!c.contains("sweep")) rd.fail(key + ".sweep", "missing; expected [dx,dy,dz]");
      cut.sweep = rd.vec3(c["sweep"], key + ".sweep");
      if (const std::string why = degenerate_sweep(cut.a, cut.b, cut.sweep); !why.empty()) rd.fail(key, why);
      if (c.contains("from_frame")) cut.from_frame = rd.integer(c["from_frame"], key + ".from_frame", 0);
      cut.to_frame = cut.from_frame;
      if (c.contains("to_frame")) cut.to_frame = rd.integer(c["to_frame"], key + ".to_frame", cut.from_frame);
      // A blade that would move after the last frame never cuts (or stops halfway): say so.
      if (cut.to_frame >= s.frames)
        rd.fail(key + (c.contains("to_frame") ? ".to_frame" : ".from_frame"),
                "frame " + std::to_string(cut.to_frame) + " is after the run's last frame (" +
                    std::to_string(s.frames - 1) + ", time.frames " + std::to_string(s.frames) + ")");
      if (c.contains("mode")) {
        cut.mode = rd.string(c["mode"], key + ".mode");
        if (cut.mode != "subdivide" && cut.mode != "remove")
          rd.fail(key + ".mode", "expected \"subdivide\" or \"remove\", got \"" + cut.mode + "\"");
      }
      if (c.contains("snap")) {
        cut.snap = rd.number(c["snap"], key + ".snap");
        if (const std::string e = snap_error(cut.snap); !e.empty()) rd.fail(key + ".snap", e);
      }
      if (c.contains("improve")) {
        if (!c["improve"].is_boolean()) rd.fail(key + ".improve", "expected true or false");
        cut.improve = c["improve"].get<bool>();
      }
      s.cuts.push_back(cut);
    }
  }
  if (j.contains("fragments")) {
    const std::string f = rd.string(j["fragments"], "fragments");
    if (f == "auto") s.fragments = FragmentPolicy::Auto;
    else if (f == "keep") s.fragments = FragmentPolicy::Keep;
    else if (f == "fix") s.fragments = FragmentPolicy::Fix;
    else if (f == "remove") s.fragments = FragmentPolicy::Remove;
    else if (f == "error") s.fragments = FragmentPolicy::Error;
    else rd.fail("fragments", "expected \"auto\", \"keep\", \"fix\", \"remove\" or \"error\", got \"" + f + "\"");
  }
  // Poisson's ratio 0.5 (incompressible) has no displacement-only stiffness: only the mixed
  // formulation, with pressure as an unknown, solves it.
  if (s.formulation != Formulation::Mixed) {
    auto check = [&](const Material& m, const std::string& key) {
      if (m.poisson >= 0.5)
        rd.fail(key, "Poisson's ratio 0.5 needs \"formulation\": \"mixed\" (pressure as an unknown); the other "
                     "formulations take at most 0.4999");
    };
    if (s.materials.has_default()) check(s.materials.fallback(), "materials.*.poisson");
    for (const auto& [label, m] : s.materials.by_label()) check(m, "materials." + std::to_string(label) + ".poisson");
  }
  if (s.model == SceneModel::Springs)
    for (std::size_t i = 0; i < s.fixed.size(); ++i)
      if (s.fixed[i].axes != 7)
        rd.fail("fixed[" + std::to_string(i) + "].components", "rollers are for FEM models; springs fix whole vertices");
  return s;
}

Scene load_scene(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, 0, "cannot open scene file");
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_scene(ss.str(), path);
}

namespace {

// The boundary faces a pressure load selects (by tag, or all three corners in its box) and, per
// corner vertex, the force of a unit pressure: minus a third of each face's outward rest area
// vector (pressure pushes into the body).
std::vector<std::pair<VertexId, Vec3>> pressure_faces(const TetMesh& mesh, const SceneLoad& l, double tol, const Reader& rd) {
  std::unordered_map<std::uint32_t, Vec3> w;
  std::size_t faces = 0;
  for (const BoundaryFace& f : mesh.boundary_faces()) {
    bool in = l.tag >= 0 ? f.tag == l.tag : true;
    if (l.tag < 0)
      for (VertexId v : f.vertices) in = in && l.box.contains(mesh.rest(v), tol);
    if (!in) continue;
    ++faces;
    const Vec3 a = mesh.rest(f.vertices[0]), b = mesh.rest(f.vertices[1]), c = mesh.rest(f.vertices[2]);
    const Vec3 area = 0.5 * (b - a).cross(c - a);
    for (VertexId v : f.vertices) w.try_emplace(v.idx(), Vec3::Zero()).first->second -= area / 3;  // Eigen leaves a default Vec3 unset
  }
  if (faces == 0)
    rd.fail(l.key + (l.tag >= 0 ? ".tag" : ".box"),
            l.tag >= 0 ? "no boundary face has tag " + std::to_string(l.tag) : std::string("selects no boundary face"));
  std::vector<std::pair<VertexId, Vec3>> out;
  for (const auto& [v, f] : w) out.emplace_back(VertexId(v), f);
  std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) { return x.first.idx() < y.first.idx(); });
  return out;
}

}  // namespace

SceneRunSummary run_scene(const Scene& s, const SceneRunOptions& opt) {
  const Reader rd(s.path);
  // ---- mesh ---------------------------------------------------------------------------
  TetMesh mesh;
  if (opt.mesh) {
    mesh = *opt.mesh;
  } else if (!s.generator.empty()) {
    if (s.generator == "box") mesh = make_box(s.gen_size, s.gen_cells);
    else if (s.generator == "tube") mesh = make_tube(s.gen_size[0], s.gen_size[1], s.gen_size[2], s.gen_angle, s.gen_cells);
    else mesh = make_ellipsoid(s.gen_size, s.gen_resolution);
  } else {
    fs::path p(s.mesh_file);
    if (p.is_relative()) p = fs::path(s.path).parent_path() / p;
    mesh = read_tet_mesh(p.string());
  }
  mesh.discard_change();
  if (mesh.num_tets() == 0) rd.fail("mesh", "the mesh has no tetrahedra");
  if (!s.cuts.empty() && !opt.cut_hook)
    throw InvalidArgument(s.path + ": the scene has cuts: run it with `incise simulate` or run_scene_with_cuts() "
                          "(cut/scene_cuts.h)");

  // ---- boxes -> vertex sets (checked before anything is written) -----------------------
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (VertexId v : mesh.vertices()) {
    lo = lo.cwiseMin(mesh.rest(v));
    hi = hi.cwiseMax(mesh.rest(v));
  }
  const double size = (hi - lo).norm();  // the body's size, for the blow-up check
  const double tol = 1e-9 * size;
  auto select = [&](const SceneBox& b, const std::string& key) {
    std::vector<VertexId> out;
    for (VertexId v : mesh.vertices())
      if (!mesh.incident_tets(v).empty() && b.contains(mesh.rest(v), tol)) out.push_back(v);
    if (out.empty()) {
      std::ostringstream m;
      m << "selects no vertex; the mesh spans [" << lo.x() << ", " << lo.y() << ", " << lo.z() << "] to [" << hi.x() << ", "
        << hi.y() << ", " << hi.z() << "]";
      rd.fail(key, m.str());
    }
    return out;
  };
  std::vector<std::pair<VertexId, unsigned>> fixed;  // vertex, held axes
  for (std::size_t i = 0; i < s.fixed.size(); ++i)
    for (VertexId v : select(s.fixed[i].box, "fixed[" + std::to_string(i) + "].box")) fixed.emplace_back(v, s.fixed[i].axes);
  std::vector<std::vector<VertexId>> load_vertices(s.loads.size());
  // Pressure loads: per vertex, the force of a unit pressure (its share of the selected faces'
  // rest area vectors, a third per corner), fixed when the scene starts like other loads.
  std::vector<std::vector<std::pair<VertexId, Vec3>>> pressure_weights(s.loads.size());
  Vec3 gravity = Vec3::Zero();
  for (std::size_t i = 0; i < s.loads.size(); ++i) {
    const SceneLoad& l = s.loads[i];
    if (l.kind == SceneLoad::Kind::Gravity) gravity += l.value;
    else if (l.kind == SceneLoad::Kind::Pressure) pressure_weights[i] = pressure_faces(mesh, l, tol, rd);
    else load_vertices[i] = select(l.box, l.key + ".box");
  }


  // ---- model (only the one the scene uses) ---------------------------------------------
  std::unique_ptr<FemSimulation> fem;
  std::unique_ptr<SpringModel> springs;
  Integrator integrator = Integrator::SymplecticEuler;
  if (s.model == SceneModel::Springs) {
    SpringOptions so;
    so.damping = s.damping;
    so.cg_tolerance = s.cg.tolerance;
    so.cg_max_iterations = s.cg.max_iterations;
    so.compute_energy = false;
    springs = std::make_unique<SpringModel>(mesh, s.materials, so);
    integrator = parse_integrator(s.integrator);
    for (const auto& [v, axes] : fixed) springs->set_fixed(v, true);  // axes == 7: the parser refuses rollers
    springs->set_gravity(gravity);
  } else {
    FemSimulationOptions fo;
    fo.kind = s.model == SceneModel::FemCorotational ? FemKind::Corotational : FemKind::Linear;
    fo.formulation = s.formulation;
    fo.method = s.method;
    fo.backend = s.backend;
    fo.cg = s.cg;
    fo.warm_start = s.warm_start;
    fo.predict = s.predict;
    fo.dynamic = s.integrator == "implicit-euler";
    fo.dt = s.dt;
    fo.damping = s.damping;
    fo.nonlinear_iterations = s.nonlinear_iterations;
    fo.cholesky = s.cholesky;
    fo.amg = s.amg;
    fo.gravity = gravity;
    fem = std::make_unique<FemSimulation>(mesh, s.materials, fo);
    for (const auto& [v, axes] : fixed) fem->constrain(v, axes);
    for (std::size_t i = 0; i < s.loads.size(); ++i)
      if (s.loads[i].kind == SceneLoad::Kind::Probe)
        for (VertexId v : load_vertices[i]) fem->prescribe(v, Vec3::Zero());
    if (!fo.dynamic) {
      try {
        fem->check_constraints();
      } catch (const InvalidArgument& e) {
        rd.fail("fixed", e.what());
      }
    }
  }

  const int frames = opt.frames >= 0 ? opt.frames : s.frames;
  const bool write = !opt.out_dir.empty();
  if (write) {
    std::error_code ec;
    fs::create_directories(opt.out_dir, ec);
    if (ec) throw IoError(opt.out_dir, 0, "cannot create output directory: " + ec.message());
  }

  SceneRunSummary sum;
  sum.vertices = mesh.num_vertices();
  sum.tets = mesh.num_tets();
  std::ostringstream csv, pvd;
  csv << "frame,time,iterations,relative_residual,solve_ms,budget_exhausted,converged,max_displacement,frame_ms,"
         "setup_ms,cheaper_preconditioner"
      << (s.cuts.empty() ? "" : ",cut_ms,tets") << "\n";
  csv << std::setprecision(9);
  pvd << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
         "  <Collection>\n";
  auto finish = [&] {
    if (!write) return;
    pvd << "  </Collection>\n</VTKFile>\n";
    write_text_atomic((fs::path(opt.out_dir) / "stats.csv").string(), csv.str());
    write_text_atomic((fs::path(opt.out_dir) / "frames.pvd").string(), pvd.str());
    sum.files.push_back("stats.csv");
    sum.files.push_back("frames.pvd");
  };

  std::vector<Vec3> force(mesh.vertex_capacity());
  const bool dynamic = s.model == SceneModel::Springs || s.integrator == "implicit-euler";
  FragmentPolicy policy = s.fragments;
  if (policy == FragmentPolicy::Auto) policy = dynamic ? FragmentPolicy::Keep : FragmentPolicy::Remove;
  std::function<void(const TopologyChange&)> apply_change = [&](const TopologyChange& ch) {
    if (ch.empty()) return;
    if (fem) fem->apply(ch);
    else springs->apply(mesh, ch);
  };
  // Cuts before this frame's solve: the hook edits the mesh; every backend applies the one
  // TopologyChange locally. Detached parts without a fixed or prescribed vertex follow the
  // scene's fragment policy (a static solve has no equilibrium for a free part).
  auto cut_before = [&](int frame) -> double {
    if (!opt.cut_hook) return 0;
    auto current = [&](VertexId v) -> Vec3 {
      if (fem) return mesh.rest(v) + fem->displacement().segment<3>(3 * v.idx());
      return springs->positions()[v.idx()];
    };
    // One pass over the state vector, like a CG iteration's vector update (interpolated new
    // vertices never exceed it, so it holds through the frame's cuts).
    auto max_disp = [&]() -> double {
      double d = 0;
      if (fem) {
        const Eigen::VectorXd& u = fem->displacement();
        for (Eigen::Index i = 0; i + 2 < u.size(); i += 3) d = std::max(d, u.segment<3>(i).squaredNorm());
      } else {
        for (VertexId v : mesh.vertices()) d = std::max(d, (springs->positions()[v.idx()] - mesh.rest(v)).squaredNorm());
      }
      return std::sqrt(d);
    };
    SceneCutResult cr = opt.cut_hook(frame, mesh, current, max_disp, apply_change);
    for (const auto& part : cr.fragments) {
      std::vector<VertexId> verts;
      bool held = false;
      std::size_t tets = 0;
      Vec3 near = Vec3::Zero();  // the rest-space centroid of its tets' corners, for messages
      for (TetId t : part) {
        if (!mesh.is_alive(t)) continue;
        ++tets;
        for (VertexId v : mesh.tet_vertices(t)) {
          verts.push_back(v);
          near += mesh.rest(v);
          held = held || (fem ? fem->is_constrained(v) : springs->is_fixed(v));
        }
      }
      if (held || verts.empty()) continue;
      near /= double(verts.size());
      // Keep is for dynamic scenes, where a free part falls; a static solve has no equilibrium
      // for it (K is singular there) and would return garbage that looks converged.
      if (policy == FragmentPolicy::Keep && !dynamic)
        throw Error(detached_part(s, frame, tets, near,
                                  "; a static solve has no equilibrium for it (set \"fragments\" to \"remove\" or "
                                  "\"fix\", or use a dynamic integrator)"));
      if (policy == FragmentPolicy::Keep) continue;
      ++sum.fragments_handled;
      if (policy == FragmentPolicy::Error)
        throw Error(detached_part(s, frame, tets, near, " (set \"fragments\" to \"remove\", \"fix\" or \"keep\")"));
      if (policy == FragmentPolicy::Fix) {
        for (VertexId v : verts) {
          if (fem) fem->fix(v);
          else springs->set_fixed(v, true);
        }
      } else {  // Remove
        for (TetId t : part)
          if (mesh.is_alive(t)) mesh.remove_tet(t);
        std::sort(verts.begin(), verts.end());
        verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
        for (VertexId v : verts)
          if (mesh.is_alive(v) && mesh.incident_tets(v).empty()) mesh.remove_vertex(v);
        apply_change(mesh.take_change());
      }
    }
    force.resize(mesh.vertex_capacity());
    return cr.ms;
  };
  try {
    for (int frame = 0; frame < frames; ++frame) {
      const double cut_ms = cut_before(frame);
      sum.total_cut_ms += cut_ms;
      // Loads and probes at this frame.
      std::fill(force.begin(), force.end(), Vec3::Zero());
      for (std::size_t i = 0; i < s.loads.size(); ++i) {
        const SceneLoad& l = s.loads[i];
        const double f = l.factor(frame);
        if (l.kind == SceneLoad::Kind::Force) {
          for (VertexId v : load_vertices[i]) force[v.idx()] += f * l.value / double(load_vertices[i].size());
        } else if (l.kind == SceneLoad::Kind::Pressure) {
          for (const auto& [v, w] : pressure_weights[i]) force[v.idx()] += f * l.value.x() * w;
        } else if (l.kind == SceneLoad::Kind::Probe) {
          for (VertexId v : load_vertices[i]) {
            if (fem) fem->prescribe(v, f * l.value);
            else springs->set_prescribed(v, mesh.rest(v) + f * l.value);
          }
        }
      }
      FrameStats st;
      Eigen::VectorXd disp;
      if (fem) {
        fem->clear_forces();
        for (std::size_t v = 0; v < force.size(); ++v)
          if (force[v].squaredNorm() > 0) fem->set_force(VertexId(std::uint32_t(v)), force[v]);
        try {
          st = fem->step();
        } catch (const InvalidArgument& e) {
          rd.fail("fixed", e.what());
        }
        if (st.info == SolveInfo::NotPositiveDefinite || st.info == SolveInfo::NumericalIssue)
          throw Error(s.path + ": frame " + std::to_string(frame) + ": " + st.message);
        disp = fem->displacement().head(Eigen::Index(3 * mesh.vertex_capacity()));
      } else {
        for (std::size_t v = 0; v < force.size(); ++v)
          if (mesh.is_alive(VertexId(std::uint32_t(v)))) springs->set_external_force(VertexId(std::uint32_t(v)), force[v]);
        const auto t0 = std::chrono::steady_clock::now();
        for (int k = 0; k < s.substeps; ++k) {
          const StepStats ss = springs->step(s.dt, integrator);
          st.iterations += ss.cg_iterations;
          st.relative_residual = ss.cg_relative_residual;
        }
        st.solve_ms = st.frame_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        disp = Eigen::VectorXd::Zero(Eigen::Index(3 * mesh.vertex_capacity()));
        const auto& x = springs->positions();
        for (VertexId v : mesh.vertices()) disp.segment<3>(3 * v.idx()) = x[v.idx()] - mesh.rest(v);
      }
      const double maxd = max_displacement(disp);
      check_solution(s, frame, maxd, st.relative_residual, size);
      if (opt.on_frame) opt.on_frame(frame, disp, st);
      const double time = dynamic ? (frame + 1) * s.dt * (s.model == SceneModel::Springs ? s.substeps : 1) : frame;
      const bool converged = st.info == SolveInfo::Success;
      csv << frame << "," << time << "," << st.iterations << "," << st.relative_residual << "," << st.solve_ms << ","
          << (st.budget_exhausted ? 1 : 0) << "," << (converged ? 1 : 0) << "," << maxd << "," << st.frame_ms << ","
          << st.setup_ms << "," << (st.cheaper_preconditioner ? 1 : 0);
      if (!s.cuts.empty()) csv << "," << cut_ms << "," << mesh.num_tets();
      csv << "\n";
      sum.total_iterations += st.iterations;
      sum.total_solve_ms += st.solve_ms;
      sum.frames_budget_exhausted += st.budget_exhausted;
      sum.frames_not_converged += !converged;
      sum.max_displacement = maxd;
      ++sum.frames;

      if (write && (frame % s.output_every == 0 || frame == frames - 1)) {
        char name[64];
        std::snprintf(name, sizeof name, "frame_%04d.vtu", frame);
        std::vector<Vec3> pts(mesh.vertex_capacity(), Vec3::Zero());
        for (VertexId v : mesh.vertices()) pts[v.idx()] = mesh.rest(v) + disp.segment<3>(3 * v.idx());
        MeshFields fields;
        fields.points = &pts;
        fields.point_data.push_back(Field{"displacement", 3, std::vector<double>(disp.data(), disp.data() + disp.size())});
        if (fem) fields.cell_data.push_back(Field{"von_mises", 1, fem->von_mises()});
        if (!s.cuts.empty()) {
          // Cut faces per tet (0..4): ParaView's threshold on it shows the cut surfaces.
          std::vector<double> cut_faces(mesh.tet_capacity(), 0.0);
          for (TetId t : mesh.tets())
            for (int f = 0; f < 4; ++f)
              if (!mesh.neighbor(t, f).is_valid() && mesh.face_tag(t, f) == kTagCut) cut_faces[t.idx()] += 1;
          fields.cell_data.push_back(Field{"cut_faces", 1, std::move(cut_faces)});
        }
        WriteOptions wo;
        wo.binary = s.output_binary;
        write_tet_mesh_with_fields(mesh, (fs::path(opt.out_dir) / name).string(), fields, wo);
        pvd << "    <DataSet timestep=\"" << time << "\" group=\"\" part=\"0\" file=\"" << name << "\"/>\n";
        sum.files.push_back(name);
      }
      if (opt.progress) {
        // Numbered like the files and stats.csv (frame_0000.vtu is frame 0).
        *opt.progress << "simulate: frame " << frame << " (0.." << frames - 1 << "): " << st.iterations << " iterations, residual "
                      << st.relative_residual << ", " << std::fixed << std::setprecision(2) << st.solve_ms << " ms"
                      << std::defaultfloat << std::setprecision(6) << (st.budget_exhausted ? ", budget exhausted" : "")
                      << (!converged && !st.budget_exhausted && fem ? ", NOT CONVERGED" : "") << "\n";
      }
      if (opt.stop && opt.stop(frame)) break;
    }
  } catch (...) {
    finish();  // keep the series and stats of the frames that were computed
    throw;
  }
  finish();
  sum.vertices = mesh.num_vertices();  // after the cuts
  sum.tets = mesh.num_tets();
  return sum;
}

}  // namespace incise

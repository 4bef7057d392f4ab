#include "scene/scene.h"

#include <cerrno>
#include <cstring>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <fstream>
#include <sstream>
#include <string_view>

#include <nlohmann/json.hpp>

#include "cut/snap_rule.h"
#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/input_checks.h"
#include "mesh/io/input_file.h"
#include "mesh/io/tet_io.h"
#include "sim/springs/integrator.h"
#include "sim/petsc/petsc_solver.h"
#include "sim/springs/spring_model.h"

namespace incise {

namespace {

// The most integration steps a frame (time.substeps) and a run (frames x substeps) may take:
// docs/scene.md, time.substeps.
constexpr int kMaxSubsteps = 1000000;
constexpr double kMaxSteps = 1e9;

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
  rd.keys(j, key, {"young", "poisson", "density", "viscosity", "stiffening"});
  Material m = base;
  if (j.contains("young")) m.young = rd.positive(j["young"], key + ".young");
  if (j.contains("poisson")) {
    m.poisson = rd.number(j["poisson"], key + ".poisson");
    // 0.5 is allowed here and refused after parsing unless the formulation is mixed.
    if (m.poisson < 0 || m.poisson > 0.5) rd.fail(key + ".poisson", "expected a Poisson's ratio in [0, 0.5]");
  }
  if (j.contains("density")) m.density = rd.positive(j["density"], key + ".density");
  // Springs only: per label, over the scene-wide "springs" values (docs/solver.md#spring-options).
  if (j.contains("viscosity")) m.viscosity = rd.non_negative(j["viscosity"], key + ".viscosity");
  if (j.contains("stiffening")) {
    m.stiffening = rd.non_negative(j["stiffening"], key + ".stiffening");
    if (m.stiffening > 100) rd.fail(key + ".stiffening", "expected a value in [0, 100]");
  }
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
  if (!j.contains("type")) rd.fail(key + ".type", "missing; expected \"force\", \"gravity\", \"probe\", \"pressure\" or \"traction\"");
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
  } else if (type == "pressure" || type == "traction") {
    // On boundary faces chosen by tag or box (all three corners inside): a pressure pushes against
    // each face's outward normal with p times its rest area, a traction adds the vector times it.
    rd.keys(j, key, {"type", "value", "tag", "box", "from_frame", "to_frame"});
    if (type == "pressure") {
      l.kind = SceneLoad::Kind::Pressure;
      l.value = Vec3(rd.number(need("value"), key + ".value"), 0, 0);
    } else {
      l.kind = SceneLoad::Kind::Traction;
      l.value = rd.vec3(need("value"), key + ".value");
    }
    if (j.contains("tag") == j.contains("box")) rd.fail(key, "expected exactly one of \"tag\" and \"box\" to select the faces");
    if (j.contains("tag")) l.tag = rd.integer(j["tag"], key + ".tag", 0);
    else l.box = rd.box(j["box"], key + ".box");
    ramp();
  } else {
    rd.fail(key + ".type", "expected \"force\", \"gravity\", \"probe\", \"pressure\" or \"traction\", got \"" + type + "\"");
  }
  return l;
}

// A blade's optional "mode", "snap" and "improve" (scene cuts and blade inputs).
void read_blade_options(const Reader& rd, const json& c, const std::string& key, std::string& mode, double& snap,
                        bool& improve) {
  if (c.contains("mode")) {
    mode = rd.string(c["mode"], key + ".mode");
    if (mode != "subdivide" && mode != "remove")
      rd.fail(key + ".mode", "expected \"subdivide\" or \"remove\", got \"" + mode + "\"");
  }
  if (c.contains("snap")) {
    snap = rd.number(c["snap"], key + ".snap");
    if (const std::string e = snap_error(snap); !e.empty()) rd.fail(key + ".snap", e);
  }
  if (c.contains("improve")) {
    if (!c["improve"].is_boolean()) rd.fail(key + ".improve", "expected true or false");
    improve = c["improve"].get<bool>();
  }
}

// solver.backend ("incise", the default, or "petsc": docs/solver.md#petsc-more-than-one-machine) and
// solver.petsc_options. After the model, formulation, method and operator are read.
void parse_solver_backend(const Reader& rd, const json& js, Scene& s) {
  const std::string b = js.contains("backend") ? rd.string(js["backend"], "solver.backend") : "incise";
  if (b != "incise" && b != "petsc") rd.fail("solver.backend", "expected \"incise\" or \"petsc\", got \"" + b + "\"");
  if (js.contains("petsc_options")) {
    if (b != "petsc") rd.fail("solver.petsc_options", "goes with \"backend\": \"petsc\" only");
    s.petsc_options = rd.string(js["petsc_options"], "solver.petsc_options");
  }
  if (b != "petsc") return;
  if (!petsc_built())
    rd.fail("solver.backend", "this incise was built without PETSc (install petsc-dev and openmpi-bin, then reconfigure)");
  if (s.model == SceneModel::Springs) rd.fail("solver.backend", "\"petsc\" solves FEM models; springs use \"incise\"");
  if (s.method != SolverMethod::Cg) rd.fail("solver.backend", "\"petsc\" is a solver of its own: leave solver.method out");
  if (js.contains("operator")) rd.fail("solver.operator", "goes with \"backend\": \"incise\" only");
  s.backend = StiffnessBackend::Petsc;
}

// A cut's "path": [{"frame": F, "blade": [[ax,ay,az],[bx,by,bz]]}, ...], at least two keys,
// frames increasing and below the run's frame count, every blade's ends distinct.
void read_cut_path(const Reader& rd, const json& jp, const std::string& key, int frames, SceneCut& cut) {
  if (!jp.is_array() || jp.size() < 2)
    rd.fail(key, "expected an array of at least two {\"frame\": F, \"blade\": [[ax,ay,az],[bx,by,bz]]}");
  for (std::size_t i = 0; i < jp.size(); ++i) {
    const std::string k = key + "[" + std::to_string(i) + "]";
    rd.keys(jp[i], k, {"frame", "blade"});
    if (!jp[i].contains("frame")) rd.fail(k + ".frame", "missing");
    if (!jp[i].contains("blade") || !jp[i]["blade"].is_array() || jp[i]["blade"].size() != 2)
      rd.fail(k + ".blade", "expected [[ax,ay,az],[bx,by,bz]]");
    SceneCutKey p;
    p.frame = rd.integer(jp[i]["frame"], k + ".frame", cut.path.empty() ? 0 : cut.path.back().frame + 1);
    if (p.frame >= frames)
      rd.fail(k + ".frame", "frame " + std::to_string(p.frame) + " is after the run's last frame (" +
                                std::to_string(frames - 1) + ", time.frames " + std::to_string(frames) + ")");
    p.a = rd.vec3(jp[i]["blade"][0], k + ".blade[0]");
    p.b = rd.vec3(jp[i]["blade"][1], k + ".blade[1]");
    if (!((p.b - p.a).norm() > 0)) rd.fail(k + ".blade", "the blade's two ends are the same point");
    cut.path.push_back(p);
  }
  bool moves = false;
  for (std::size_t i = 1; i < cut.path.size(); ++i)
    moves = moves || !(cut.path[i].a == cut.path[0].a && cut.path[i].b == cut.path[0].b);
  if (!moves) rd.fail(key, "the blade never moves (every key has the first key's position)");
  cut.a = cut.path.front().a;
  cut.b = cut.path.front().b;
  cut.from_frame = cut.path.front().frame + 1;
  cut.to_frame = cut.path.back().frame;
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
                  "inputs", "fragments", "units", "inversion_barrier", "springs"});
  Scene s;
  s.path = path;
  s.source = text;
  if (j.contains("units")) {
    s.units = rd.string(j["units"], "units");
    if (s.units != "mm" && s.units != "m")
      rd.fail("units", "expected \"mm\" (mm, MPa, t/mm^3, mm/s^2) or \"m\" (m, Pa, kg/m^3, m/s^2), got \"" + s.units + "\"");
  }

  if (!j.contains("mesh")) rd.fail("mesh", "missing; expected a mesh file name or {\"generate\": \"box\", ...}");
  const json& jm = j["mesh"];
  if (jm.is_string()) {
    s.mesh_file = jm.get<std::string>();
    if (s.mesh_file.empty()) rd.fail("mesh", "expected a non-empty file name");
  } else if (jm.is_object()) {
    if (!jm.contains("generate")) rd.fail("mesh.generate", "missing; expected \"box\", \"ellipsoid\", \"tube\" or \"cook\"");
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
    } else if (s.generator == "cook") {
      // Cook's membrane, cells x cells x 1 (mesh/generate.h): tags 18 (clamped edge), 19 (loaded edge).
      rd.keys(jm, "mesh", {"generate", "cells", "thickness"});
      s.gen_size = Vec3(48, 60, 1);
      s.gen_cells = {16, 16, 1};
      if (jm.contains("cells")) {
        const int n = rd.integer(jm["cells"], "mesh.cells", 1);
        s.gen_cells = {n, n, 1};
      }
      if (jm.contains("thickness")) s.gen_size[2] = rd.positive(jm["thickness"], "mesh.thickness");
    } else {
      rd.fail("mesh.generate", "expected \"box\", \"ellipsoid\", \"tube\" or \"cook\", got \"" + s.generator + "\"");
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
    if (!parsed) rd.fail("formulation", "expected " + std::string(kFormulationNames) + ", got \"" + f + "\"");
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

  if (j.contains("springs")) {
    const json& jsp = j["springs"];
    if (!jsp.is_object())
      rd.fail("springs", "expected {\"volume\": \"tet\" | \"nodal\" | \"none\", \"stiffness\": \"van-gelder\" | "
                         "\"fitted\", \"connectivity\": \"edges\" | \"across-faces\", \"nodal_share\": S, "
                         "\"inversion_guard\": J, \"viscosity\": T, \"stiffening\": B}");
    rd.keys(jsp, "springs", {"volume", "stiffness", "connectivity", "nodal_share", "inversion_guard", "viscosity", "stiffening"});
    if (jsp.contains("inversion_guard")) {
      s.springs_inversion_guard = rd.non_negative(jsp["inversion_guard"], "springs.inversion_guard");
      if (!(s.springs_inversion_guard < 1)) rd.fail("springs.inversion_guard", "expected a volume ratio in [0, 1)");
    }
    if (jsp.contains("nodal_share")) {
      s.springs_nodal_share = rd.non_negative(jsp["nodal_share"], "springs.nodal_share");
      if (s.springs_nodal_share > 1) rd.fail("springs.nodal_share", "expected a value in [0, 1]");
    }
    if (jsp.contains("connectivity")) {
      s.springs_connectivity = rd.string(jsp["connectivity"], "springs.connectivity");
      if (s.springs_connectivity != "edges" && s.springs_connectivity != "across-faces")
        rd.fail("springs.connectivity", "expected \"edges\" or \"across-faces\", got \"" + s.springs_connectivity + "\"");
    }
    if (jsp.contains("stiffness")) {
      s.springs_stiffness = rd.string(jsp["stiffness"], "springs.stiffness");
      if (!parse_spring_stiffness(s.springs_stiffness))
        rd.fail("springs.stiffness", "expected \"van-gelder\" or \"fitted\", got \"" + s.springs_stiffness + "\"");
    }
    if (!jsp.contains("connectivity"))
      s.springs_connectivity = default_across_faces(*parse_spring_stiffness(s.springs_stiffness)) ? "across-faces" : "edges";
    if (jsp.contains("viscosity")) s.springs_viscosity = rd.non_negative(jsp["viscosity"], "springs.viscosity");
    if (jsp.contains("stiffening")) {
      s.springs_stiffening = rd.non_negative(jsp["stiffening"], "springs.stiffening");
      if (s.springs_stiffening > 100) rd.fail("springs.stiffening", "expected a value in [0, 100]");
    }
    if (jsp.contains("volume")) {
      s.springs_volume = rd.string(jsp["volume"], "springs.volume");
      if (s.springs_volume != "tet" && s.springs_volume != "nodal" && s.springs_volume != "none")
        rd.fail("springs.volume", "expected \"tet\", \"nodal\" or \"none\", got \"" + s.springs_volume + "\"");
    }
    if (jsp.contains("nodal_share") && s.springs_volume != "nodal")
      rd.fail("springs.nodal_share", "is the nodal volume term's share; \"volume\" is \"" + s.springs_volume + "\"");
    if (s.springs_inversion_guard > 0 && s.springs_volume == "none")
      rd.fail("springs.inversion_guard", "acts beside a volume term; \"volume\" is \"none\"");
  }
  if (j.contains("inversion_barrier")) {
    // true: the defaults; an object: {"j_min": J, "stiffness": K}, either optional.
    const json& jb = j["inversion_barrier"];
    const InversionBarrierOptions on{.j_min = kDefaultBarrierJMin};
    if (jb.is_boolean()) {
      if (jb.get<bool>()) s.inversion_barrier = on;
    } else if (jb.is_object()) {
      rd.keys(jb, "inversion_barrier", {"j_min", "stiffness"});
      s.inversion_barrier = on;
      if (jb.contains("j_min")) {
        s.inversion_barrier.j_min = rd.positive(jb["j_min"], "inversion_barrier.j_min");
        if (!(s.inversion_barrier.j_min < 1)) rd.fail("inversion_barrier.j_min", "expected a volume ratio in (0, 1)");
      }
      if (jb.contains("stiffness")) s.inversion_barrier.stiffness = rd.positive(jb["stiffness"], "inversion_barrier.stiffness");
    } else {
      rd.fail("inversion_barrier", "expected true, false or {\"j_min\": J, \"stiffness\": K}");
    }
    if (s.inversion_barrier.j_min > 0 && s.model != SceneModel::FemCorotational)
      rd.fail("inversion_barrier", "goes with \"model\": \"fem-corotational\" only");
  }

  if (j.contains("solver")) {
    const json& js = j["solver"];
    rd.keys(js, "solver", {"method", "tolerance", "max_iterations", "budget_ms", "warm_start", "preconditioner", "operator",
                           "nonlinear_iterations", "backend", "petsc_options"});
    if (js.contains("method")) {
      const std::string m = rd.string(js["method"], "solver.method");
      if (m == "cg") s.method = SolverMethod::Cg;
      else if (m == "direct") s.method = SolverMethod::Direct;
      else rd.fail("solver.method", "expected \"cg\" or \"direct\", got \"" + m + "\"");
    }
    if (js.contains("tolerance")) {
      s.cg.tolerance = rd.positive(js["tolerance"], "solver.tolerance");
      // A relative residual of 1 or more is met by zero displacement: every frame "converged".
      if (!(s.cg.tolerance < 1)) rd.fail("solver.tolerance", "expected a relative residual in (0, 1)");
    }
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
    parse_solver_backend(rd, js, s);
  }

  if (j.contains("time")) {
    const json& jt = j["time"];
    rd.keys(jt, "time", {"frames", "dt", "integrator", "damping", "substeps"});
    if (jt.contains("frames")) s.frames = rd.integer(jt["frames"], "time.frames", 1);
    if (jt.contains("dt")) s.dt = rd.positive(jt["dt"], "time.dt");
    if (jt.contains("integrator")) s.integrator = rd.string(jt["integrator"], "time.integrator");
    if (jt.contains("damping")) s.damping = rd.non_negative(jt["damping"], "time.damping");
    if (jt.contains("substeps")) s.substeps = rd.integer(jt["substeps"], "time.substeps", 1);
    // Work before it starts: a frame is an interactive step, not a batch job.
    if (s.substeps > kMaxSubsteps)
      rd.fail("time.substeps", std::to_string(s.substeps) + " integration steps a frame is more than the " +
                                   std::to_string(kMaxSubsteps) + " allowed: use a larger time.dt");
    if (double(s.frames) * s.substeps > kMaxSteps)
      rd.fail("time.substeps", std::to_string(s.frames) + " frames of " + std::to_string(s.substeps) + " steps are " +
                                   std::to_string(static_cast<long long>(s.frames) * s.substeps) + " steps, more than the " +
                                   std::to_string(static_cast<long long>(kMaxSteps)) + " a run may take: use fewer frames or a larger time.dt");
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
      rd.keys(c, key, {"blade", "sweep", "from_frame", "to_frame", "path", "mode", "snap", "improve", "exact_volumes",
                       "provisional", "material_frame"});
      SceneCut cut;
      cut.key = key;
      if (c.contains("path")) {
        for (const char* k : {"blade", "sweep", "from_frame", "to_frame"})
          if (c.contains(k)) rd.fail(key + "." + k, "not with \"path\" (a path gives the blade's ends at frames)");
        read_cut_path(rd, c["path"], key + ".path", s.frames, cut);
        read_blade_options(rd, c, key, cut.mode, cut.snap, cut.improve);
        if (c.contains("exact_volumes")) cut.exact_volumes = rd.boolean(c["exact_volumes"], key + ".exact_volumes");
        if (c.contains("provisional")) cut.provisional = rd.boolean(c["provisional"], key + ".provisional");
        if (c.contains("material_frame")) cut.material_frame = rd.boolean(c["material_frame"], key + ".material_frame");
        s.cuts.push_back(cut);
        continue;
      }
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
      read_blade_options(rd, c, key, cut.mode, cut.snap, cut.improve);
      if (c.contains("exact_volumes")) cut.exact_volumes = rd.boolean(c["exact_volumes"], key + ".exact_volumes");
      if (c.contains("provisional")) cut.provisional = rd.boolean(c["provisional"], key + ".provisional");
      if (c.contains("material_frame")) cut.material_frame = rd.boolean(c["material_frame"], key + ".material_frame");
      s.cuts.push_back(cut);
    }
  }
  if (j.contains("inputs")) {
    const json& ji = j["inputs"];
    if (!ji.is_array())
      rd.fail("inputs", "expected an array of {\"frame\": F, \"blade\"|\"finish\"|\"grab\"|\"probe\"|\"release\": ...}");
    int last = 0;
    for (std::size_t i = 0; i < ji.size(); ++i) {
      const std::string key = "inputs[" + std::to_string(i) + "]";
      const json& c = ji[i];
      rd.keys(c, key, {"frame", "blade", "finish", "grab", "radius", "probe", "release", "mode", "snap", "improve"});
      SceneInput in;
      if (!c.contains("frame")) rd.fail(key + ".frame", "missing; expected the frame the input comes before");
      in.frame = rd.integer(c["frame"], key + ".frame", 0);
      if (in.frame >= s.frames)
        rd.fail(key + ".frame", "frame " + std::to_string(in.frame) + " is after the run's last frame (" +
                                    std::to_string(s.frames - 1) + ")");
      if (in.frame < last) rd.fail(key + ".frame", "inputs must be in frame order (" + std::to_string(in.frame) + " after " +
                                                    std::to_string(last) + ")");
      last = in.frame;
      int kinds = 0;
      for (const char* k : {"blade", "finish", "grab", "probe", "release"}) kinds += c.contains(k);
      if (kinds != 1) rd.fail(key, "expected exactly one of blade, finish, grab, probe, release");
      auto flag = [&](const char* k) {
        if (!c[k].is_boolean() || !c[k].get<bool>()) rd.fail(key + "." + k, "expected true");
      };
      if (c.contains("blade")) {
        in.kind = SceneInput::Kind::Blade;
        if (!c["blade"].is_array() || c["blade"].size() != 2) rd.fail(key + ".blade", "expected [[ax,ay,az],[bx,by,bz]]");
        in.a = rd.vec3(c["blade"][0], key + ".blade[0]");
        in.b = rd.vec3(c["blade"][1], key + ".blade[1]");
        if (!((in.b - in.a).norm() > 1e-12 * std::max({in.a.norm(), in.b.norm(), 1e-300})))
          rd.fail(key + ".blade", "the blade's two ends are the same point");
        read_blade_options(rd, c, key, in.mode, in.snap, in.improve);
      } else {
        for (const char* k : {"mode", "snap", "improve"})
          if (c.contains(k)) rd.fail(key + "." + k, "only for a blade input");
      }
      if (c.contains("finish")) {
        in.kind = SceneInput::Kind::Finish;
        flag("finish");
      }
      if (c.contains("release")) {
        in.kind = SceneInput::Kind::Release;
        flag("release");
      }
      if (c.contains("grab")) {
        in.kind = SceneInput::Kind::Grab;
        in.a = rd.vec3(c["grab"], key + ".grab");
        if (!c.contains("radius")) rd.fail(key + ".radius", "missing; expected the grab's radius");
        in.radius = rd.positive(c["radius"], key + ".radius");
      } else if (c.contains("radius")) {
        rd.fail(key + ".radius", "only for a grab input");
      }
      if (c.contains("probe")) {
        in.kind = SceneInput::Kind::Probe;
        in.a = rd.vec3(c["probe"], key + ".probe");
      }
      s.inputs.push_back(in);
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
  // Quadratic tets are a reference, solved to tolerance on a fixed mesh (docs/solver.md#quadratic-tets).
  if (is_quadratic(s.formulation)) {
    const std::string f = "\"" + std::string(formulation_name(s.formulation)) + "\"";
    if (!s.cuts.empty()) rd.fail("cuts", "quadratic tets (" + f + ") do not follow cuts; use a linear formulation");
    for (const SceneInput& in : s.inputs)
      if (in.kind == SceneInput::Kind::Blade)
        rd.fail("inputs", "quadratic tets (" + f + ") do not follow cuts; use a linear formulation");
    if (s.cg.budget_ms > 0)
      rd.fail("solver.budget_ms", "quadratic tets (" + f + ") are solved to tolerance; a frame budget cannot be honoured");
    if (s.cg.preconditioner == Preconditioner::Amg)
      rd.fail("solver.preconditioner", "\"amg\" has no hierarchy for quadratic tets; use \"cholesky\", \"block-jacobi\", "
                                       "\"jacobi\" or \"none\"");
    if (s.inversion_barrier.j_min > 0) rd.fail("inversion_barrier", "is for linear tets; quadratic tets have none");
  }
  // Poisson's ratio 0.5 (incompressible) has no displacement-only stiffness: only the mixed
  // formulations, with pressure as an unknown, solve it.
  if (!allows_incompressible(s.formulation)) {
    auto check = [&](const Material& m, const std::string& key) {
      if (m.poisson > 0.4999) {
        char nu[32];
        std::snprintf(nu, sizeof nu, "%.17g", m.poisson);
        rd.fail(key, std::string("Poisson's ratio ") + nu + " needs \"formulation\": \"mixed\" or \"mixed-quadratic\" "
                     "(pressure as an unknown); the other formulations take at most 0.4999 (above, they lock and their solves fail)");
      }
    };
    if (s.materials.has_default()) check(s.materials.fallback(), "materials.*.poisson");
    for (const auto& [label, m] : s.materials.by_label()) check(m, "materials." + std::to_string(label) + ".poisson");
  }
  if (s.model == SceneModel::Springs)
    for (std::size_t i = 0; i < s.fixed.size(); ++i)
      if (s.fixed[i].axes != 7)
        rd.fail("fixed[" + std::to_string(i) + "].components", "rollers are for FEM models; springs fix whole vertices");
  // A ramp that would end after the last frame never reaches its value (cuts refuse the same).
  for (const SceneLoad& l : s.loads)
    if (l.ramp && l.to_frame >= s.frames)
      rd.fail(l.key + ".to_frame", "frame " + std::to_string(l.to_frame) + " is after the run's last frame (" +
                                       std::to_string(s.frames - 1) + ", time.frames " + std::to_string(s.frames) + ")");
  return s;
}

Scene load_scene(const std::string& path) {
  check_input_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_scene(ss.str(), path);
}

TetMesh generate_scene_mesh(const Scene& s, const std::array<int, 3>& cells) {
  if (s.generator == "box") return make_box(s.gen_size, cells);
  if (s.generator == "tube") return make_tube(s.gen_size[0], s.gen_size[1], s.gen_size[2], s.gen_angle, cells);
  if (s.generator == "cook") return make_cook_membrane(cells[0], s.gen_size[2]);
  if (s.generator == "ellipsoid") return make_ellipsoid(s.gen_size, cells[0]);
  throw InvalidArgument("generate_scene_mesh: the scene has no generator");
}

TetMesh load_scene_mesh(const Scene& s) {
  TetMesh mesh;
  if (!s.generator.empty()) {
    mesh = generate_scene_mesh(s, s.generator == "ellipsoid" ? std::array<int, 3>{s.gen_resolution, 0, 0} : s.gen_cells);
  } else {
    fs::path p(s.mesh_file);
    if (p.is_relative()) p = fs::path(s.path).parent_path() / p;
    mesh = read_tet_mesh(p.string());
  }
  mesh.discard_change();
  // A material for a label no tet has would be silently unused (a typo, or the labels of
  // another mesh): name the labels the mesh has.
  if (!s.materials.by_label().empty()) {
    std::set<int> labels;
    for (TetId t : mesh.tets()) labels.insert(mesh.label(t));
    for (const auto& [label, m] : s.materials.by_label())
      if (!labels.count(label)) {
        std::string have;
        for (int l : labels) have += (have.empty() ? "" : ", ") + std::to_string(l);
        throw IoError(s.path, 0, "materials." + std::to_string(label) + ": no tet of the mesh has label " +
                                     std::to_string(label) + " (its labels: " + have + ")");
      }
  }
  return mesh;
}

}  // namespace incise

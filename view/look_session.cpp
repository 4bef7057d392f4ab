#include "view/look_session.h"

#include <cerrno>
#include <cstring>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "mesh/errors.h"
#include "mesh/io/input_file.h"
#include "mesh/io/tet_io.h"
#include "mesh/rest_bounds.h"
#include "quality/report.h"
#include "view/boundary_tracker.h"

namespace incise::view {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kKeptFrames = 32;  // a run's frames kept read (the others are read again)
constexpr std::uint32_t kColourVonMises = 1, kColourQuality = 2, kColourLabel = 3, kColourTag = 4;

std::string read_text(const std::string& path) {
  check_input_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw IoError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

nlohmann::json parse_json(const std::string& path) {
  try {
    return nlohmann::json::parse(read_text(path));
  } catch (const nlohmann::json::parse_error& e) {
    throw IoError(path, 0, std::string("not JSON: ") + e.what());
  }
}

bool is_report(const nlohmann::json& j) {
  return j.is_object() && j.contains("schema") && j["schema"].is_string() &&
         j["schema"].get<std::string>().rfind("incise.quality/", 0) == 0;
}

// frames.pvd's DataSets in order: (time, file). Files must be plain names in the directory.
std::vector<std::pair<double, std::string>> read_pvd(const std::string& pvd) {
  std::istringstream in(read_text(pvd));
  static const std::regex kDataSet(R"re(<DataSet\b[^>]*>)re"), kTime(R"re(timestep="([^"]*)")re"),
      kFile(R"re(\bfile="([^"]*)")re");
  std::vector<std::pair<double, std::string>> out;
  std::string line;
  for (long n = 1; std::getline(in, line); ++n) {
    std::smatch d, t, f;
    if (!std::regex_search(line, d, kDataSet)) continue;
    const std::string tag = d.str();
    if (!std::regex_search(tag, f, kFile)) throw IoError(pvd, n, "DataSet without file=");
    const std::string name = f[1];
    if (name.empty() || name.find('/') != std::string::npos || name.find('\\') != std::string::npos || name == "." ||
        name == "..")
      throw IoError(pvd, n, "'" + name + "': frames must be plain file names inside the run directory");
    double time = double(out.size());
    if (std::regex_search(tag, t, kTime)) {
      char* end = nullptr;
      time = std::strtod(t[1].str().c_str(), &end);
      if (end == t[1].str().c_str() || !std::isfinite(time)) throw IoError(pvd, n, "timestep is not a number");
    }
    out.emplace_back(time, name);
  }
  if (out.empty()) throw IoError(pvd, 0, "lists no frames");
  return out;
}

// stats.csv as {"columns": [names], "rows": [[numbers]]} (empty cells: null).
nlohmann::json read_stats_csv(const std::string& path) {
  std::istringstream in(read_text(path));
  std::string line;
  auto split = [](const std::string& s) {
    std::vector<std::string> cells;
    std::stringstream ss(s);
    for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
    return cells;
  };
  if (!std::getline(in, line)) throw IoError(path, 1, "empty");
  const auto columns = split(line);
  nlohmann::json rows = nlohmann::json::array();
  for (long n = 2; std::getline(in, line); ++n) {
    if (line.empty()) continue;
    const auto cells = split(line);
    if (cells.size() != columns.size())
      throw IoError(path, n, std::to_string(cells.size()) + " cells, the header has " + std::to_string(columns.size()));
    nlohmann::json row = nlohmann::json::array();
    for (const auto& c : cells) {
      char* end = nullptr;
      const double x = std::strtod(c.c_str(), &end);
      if (c.empty() || end != c.c_str() + c.size() || !std::isfinite(x)) row.push_back(nullptr);
      else row.push_back(x);
    }
    rows.push_back(std::move(row));
  }
  return {{"columns", columns}, {"rows", rows}};
}

}  // namespace

ViewArgument classify_view_argument(const std::string& path) {
  std::error_code ec;
  if (fs::is_directory(path, ec)) {
    if (!fs::is_regular_file(fs::path(path) / "frames.pvd", ec))
      throw IoError(path, 0, "a directory without frames.pvd: not a run directory of `incise simulate -o`");
    return ViewArgument::Run;
  }
  if (!fs::exists(path, ec)) throw IoError(path, 0, "no such file");
  if (fs::path(path).extension() == ".json") return is_report(parse_json(path)) ? ViewArgument::Report : ViewArgument::Scene;
  return ViewArgument::Mesh;
}

std::unique_ptr<LookSession> LookSession::open_mesh(const std::string& path) {
  std::unique_ptr<LookSession> s(new LookSession);
  s->mode_ = "look";
  s->source_ = path;
  s->frames_ = {path};
  s->times_ = {0.0};
  std::lock_guard lock(s->mutex_);
  s->show(0);
  return s;
}

std::unique_ptr<LookSession> LookSession::open_report(const std::string& report) {
  const nlohmann::json j = parse_json(report);
  if (!is_report(j)) throw IoError(report, 0, "not a quality report (no \"schema\": \"incise.quality/1\")");
  // "file" is as given on the command line: relative to where `incise quality` ran, which is
  // often here; else beside the report. A report of `incise prepare` before it wrote "file" is
  // NAME.quality.json beside its mesh NAME.<mesh extension>.
  std::error_code ec;
  std::vector<std::string> tries;
  if (j.contains("file") && j["file"].is_string()) {
    const std::string file = j["file"];
    tries.push_back(file);
    if (fs::path(file).is_relative()) tries.push_back((fs::path(report).parent_path() / file).string());
  } else if (const std::string name = fs::path(report).filename().string();
             name.size() > 13 && name.ends_with(".quality.json")) {
    for (const char* ext : {".msh", ".vtu", ".mesh", ".vtk", ".node"})
      tries.push_back((fs::path(report).parent_path() / (name.substr(0, name.size() - 13) + ext)).string());
  }
  std::string mesh;
  for (const std::string& t : tries)
    if (mesh.empty() && fs::is_regular_file(t, ec)) mesh = t;
  if (mesh.empty())
    throw IoError(report, 0, tries.empty() ? "no \"file\": which mesh it reports on"
                                           : "its mesh is not found (tried " + tries.front() + ")");
  std::vector<int> worst;
  if (j.contains("worst") && j["worst"].contains("elements"))
    for (const auto& e : j["worst"]["elements"])
      if (e.contains("tet") && e["tet"].is_number_integer()) worst.push_back(e["tet"].get<int>());
  std::unique_ptr<LookSession> s(new LookSession);
  s->mode_ = "look";
  s->source_ = report;
  s->report_file_ = report;
  s->report_worst_ = std::move(worst);
  s->frames_ = {mesh};
  s->times_ = {0.0};
  std::lock_guard lock(s->mutex_);
  s->show(0);
  return s;
}

std::unique_ptr<LookSession> LookSession::open_run(const std::string& dir) {
  const fs::path pvd = fs::path(dir) / "frames.pvd";
  std::unique_ptr<LookSession> s(new LookSession);
  s->mode_ = "run";
  s->source_ = dir;
  // Files the run directory names must stay in it: a link out of it (to a file elsewhere) is
  // refused, so the viewer serves nothing but the run.
  std::error_code ec;
  const fs::path root = fs::weakly_canonical(fs::absolute(dir), ec);
  auto inside = [&](const fs::path& p) {
    std::error_code e;
    const fs::path real = fs::weakly_canonical(fs::absolute(p), e);
    if (e) return false;
    const auto rel = real.lexically_relative(root);
    return !rel.empty() && *rel.begin() != "..";
  };
  for (const auto& [t, name] : read_pvd(pvd.string())) {
    const fs::path frame = fs::path(dir) / name;
    if (!inside(frame)) throw IoError(frame.string(), 0, "links out of the run directory: refused");
    s->times_.push_back(t);
    s->frames_.push_back(frame.string());
  }
  if (const fs::path csv = fs::path(dir) / "stats.csv"; fs::is_regular_file(csv, ec) && inside(csv))
    s->stats_json_ = read_stats_csv(csv.string()).dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  std::lock_guard lock(s->mutex_);
  s->show(0);
  return s;
}

const TetMesh& LookSession::mesh_of(std::size_t frame) {
  if (auto it = meshes_.find(frame); it != meshes_.end()) return it->second;
  if (meshes_.size() >= kKeptFrames) {
    for (auto it = meshes_.begin(); it != meshes_.end(); ++it)
      if (it->first != current_) {
        von_mises_.erase(it->first);
        meshes_.erase(it);
        break;
      }
  }
  // The reader gives back a frame's cut faces (its cut_face_mask) as tags, and its cell fields.
  ReadReport report;
  TetMesh mesh = read_tet_mesh(frames_[frame], &report);
  for (Field& f : report.cell_data)
    if (f.name == "von_mises") von_mises_[frame] = std::move(f.values);
  return meshes_.emplace(frame, std::move(mesh)).first->second;
}

// The frame's boundary in slots (BoundaryTracker, built whole: O(mesh), once per frame shown),
// plus the faces of the worst elements that are not on the boundary, flagged kTriangleWorst.
void LookSession::show(std::size_t frame) {
  const TetMesh& mesh = mesh_of(frame);
  current_ = frame;
  QualityOptions qo;
  qo.worst_count = kWorstCount;
  const QualityReport report = compute_quality_report(mesh, qo);
  std::vector<TetId> worst;
  if (report_worst_) {
    for (int t : *report_worst_)
      if (t >= 0 && std::size_t(t) < mesh.tet_capacity() && mesh.is_alive(TetId(std::uint32_t(t))))
        worst.push_back(TetId(std::uint32_t(t)));
  } else {
    for (const WorstElement& w : report.worst) worst.push_back(w.tet);
  }
  std::vector<char> is_worst(mesh.tet_capacity(), 0);
  for (TetId t : worst) is_worst[t.idx()] = 1;

  BoundaryTracker tr(mesh, {});
  auto snap = std::make_shared<Snapshot>();
  snap->frame = std::uint32_t(frame);
  std::unordered_map<std::uint32_t, std::uint32_t> slot_of;  // VertexId -> vertex slot
  for (std::size_t i = 0; i < tr.vertices().size(); ++i) {
    const VertexId v = tr.vertices()[i];
    const Vec3 p = v.is_valid() ? mesh.rest(v) : Vec3::Constant(NAN);
    for (int k = 0; k < 3; ++k) snap->positions.push_back(float(p[k]));
    if (v.is_valid()) slot_of[v.idx()] = std::uint32_t(i);
  }
  struct Face {
    TetId tet;
    int local;
  };
  std::vector<Face> faces;  // per triangle slot
  std::size_t triangles = 0, cut = 0;
  for (std::size_t i = 0; i < tr.triangles().size(); ++i) {
    const auto& t = tr.triangles()[i];
    std::uint32_t flags = t.flags;
    if (t.v[0] != kNoSlot && is_worst[t.tet.idx()]) flags |= kTriangleWorst;
    snap->tris.insert(snap->tris.end(), {t.v[0], t.v[1], t.v[2], t.v[0] == kNoSlot ? kNoSlot : flags});
    faces.push_back({t.tet, t.local});
    if (t.v[0] != kNoSlot) ++triangles, cut += (t.flags & kTriangleCut) ? 1 : 0;
  }
  // Face f of tet t drawn with `flags`, its corners given slots (new ones take their positions).
  auto add_face = [&](TetId t, int f, std::uint32_t flags) {
    const auto& tv = mesh.tet_vertices(t);
    std::array<std::uint32_t, 3> c{};
    for (int k = 0; k < 3; ++k) {
      const VertexId v = tv[kFaceLocal[f][k]];
      auto [it, fresh] = slot_of.try_emplace(v.idx(), std::uint32_t(snap->positions.size() / 3));
      if (fresh)
        for (int d = 0; d < 3; ++d) snap->positions.push_back(float(mesh.rest(v)[d]));
      c[k] = it->second;
    }
    snap->tris.insert(snap->tris.end(), {c[0], c[1], c[2], flags});
    faces.push_back({t, f});
    ++triangles;
  };
  for (TetId t : worst)
    for (int f = 0; f < 4; ++f)
      if (mesh.neighbor(t, f).is_valid()) add_face(t, f, kTriangleWorst);  // on the boundary: flagged above
  // Colouring by label, the faces between two labels too (the boundary alone shows only the
  // labels that reach it: a lesion inside an organ would never be seen; the page's section
  // plane uncovers these). Each face once, from the side of the label with fewer tets (the
  // inner structure, as a rule), outward from it and coloured by it. O(mesh), once per show.
  std::size_t interfaces = 0;
  if (colour_ == kColourLabel && report.labels.size() > 1) {
    std::unordered_map<int, std::size_t> label_tets;
    for (const LabelStats& l : report.labels) label_tets[l.label] = l.tets;
    auto inner = [&](TetId a, TetId b) {  // a's side is drawn
      const std::size_t na = label_tets[mesh.label(a)], nb = label_tets[mesh.label(b)];
      return na != nb ? na < nb : mesh.label(a) < mesh.label(b);
    };
    for (TetId t : mesh.tets())
      for (int f = 0; f < 4; ++f) {
        const TetId n = mesh.neighbor(t, f);
        if (!n.is_valid() || mesh.label(n) == mesh.label(t) || !inner(t, n)) continue;
        add_face(t, f, kTriangleInterface);
        ++interfaces;
      }
  }
  // Colours: per triangle, of its tet (quality, label) or its face (tag).
  if (colour_ != 0) {
    snap->scalars.assign(faces.size(), 0.f);
    float lo = INFINITY, hi = -INFINITY;
    std::vector<float> seen;
    for (std::size_t i = 0; i < faces.size(); ++i) {
      if (snap->tris[4 * i] == kNoSlot) continue;
      const Face& fc = faces[i];
      float x = 0;
      if (colour_ == kColourVonMises) {
        const auto it = von_mises_.find(frame);
        x = it != von_mises_.end() && fc.tet.idx() < it->second.size() ? float(it->second[fc.tet.idx()]) : 0.f;
      } else if (colour_ == kColourQuality) x = float(tet_quality(mesh, fc.tet).min_dihedral);
      else if (colour_ == kColourLabel) x = float(mesh.label(fc.tet));
      else if (colour_ == kColourTag) x = mesh.neighbor(fc.tet, fc.local).is_valid() ? 0.f : float(mesh.face_tag(fc.tet, fc.local));
      snap->scalars[i] = x;
      lo = std::min(lo, x), hi = std::max(hi, x);
      if (colour_ == kColourVonMises) seen.push_back(x);
    }
    // Von Mises spans the 2nd to 98th percentile, as live: a few slivers' stresses (a cut's
    // small tets) would otherwise squeeze every other triangle into one colour.
    if (!seen.empty()) {
      auto at = [&](double q) {
        auto it = seen.begin() + std::ptrdiff_t(q * double(seen.size() - 1));
        std::nth_element(seen.begin(), it, seen.end());
        return *it;
      };
      lo = at(0.02);
      hi = at(0.98);
    }
    snap->scalar_lo = std::isfinite(lo) ? lo : 0.f;
    snap->scalar_hi = std::isfinite(hi) ? std::max(hi, snap->scalar_lo) : 1.f;
    snap->scalar_version = ++scalar_version_;
  }
  // Same triangles as the snapshot before (a run without cuts): the page keeps its slots and
  // gets only the positions that moved; otherwise it starts over.
  if (!snapshot_ || snapshot_->tris != snap->tris) ++generation_;
  snap->generation = generation_;
  snap->position_epsilon = float(1e-6 * rest_bounds(mesh).size().norm());
  snap->triangles = triangles;
  snap->cut_triangles = cut;
  snap->tets = mesh.num_tets();
  snap->vertices = mesh.num_vertices();
  std::vector<int> labels;
  std::vector<std::size_t> label_tets;
  for (const LabelStats& l : report.labels) labels.push_back(l.label), label_tets.push_back(l.tets);
  std::vector<std::uint32_t> worst_ids;
  for (TetId t : worst) worst_ids.push_back(t.idx());
  const auto& md = report.metrics[std::size_t(Metric::MinDihedral)];
  nlohmann::json j = {{"mode", mode_},
                      {"source", source_},
                      {"file", frames_[frame]},
                      {"frame", frame},
                      {"frames", frames_.size()},
                      {"von_mises", von_mises_.count(frame) > 0},
                      {"time", times_[frame]},
                      {"tets", snap->tets},
                      {"vertices", snap->vertices},
                      {"triangles", snap->triangles},
                      {"cut_triangles", snap->cut_triangles},
                      {"labels", labels},
                      {"label_tets", label_tets},
                      {"interfaces", interfaces},
                      {"worst", worst_ids},
                      {"worst_from", report_worst_ ? "report " + report_file_ : std::string("computed: mean ratio")},
                      {"min_dihedral", md.min},
                      {"slivers", report.slivers},
                      {"inverted", report.inverted},
                      {"colour", colour_},
                      {"scalar_lo", snap->scalar_lo},
                      {"scalar_hi", snap->scalar_hi},
                      {"paused", true},
                      {"error", ""}};
  // File names and a run's stats.csv are the user's bytes: invalid UTF-8 is replaced.
  constexpr auto replace = nlohmann::json::error_handler_t::replace;
  snap->stats_json = j.dump(-1, ' ', false, replace);
  j["stats"] = nlohmann::json::parse(stats_json_);
  status_ = j.dump(-1, ' ', false, replace);
  snapshot_ = std::move(snap);
}

std::string LookSession::post(const InputMessage& in) {
  std::function<void()> listener;
  {
    std::lock_guard lock(mutex_);
    switch (in.kind) {
      case InputKind::Frame:
        if (in.value >= frames_.size())
          return "frame: " + std::to_string(in.value) + " is past the last (" + std::to_string(frames_.size() - 1) + ")";
        if (in.value == current_) return "";
        try {
          show(in.value);  // reads the frame's file when first shown (the network waits: look mode)
        } catch (const Error& e) {
          return e.what();  // a frame file gone bad since the start: the page says so, the view stays
        }
        break;
      case InputKind::Colour:
        if (in.value == kColourVonMises && !von_mises_.count(current_))
          return "colour: von Mises needs a live scene or a run's FEM frames (this file has no von_mises field)";
        colour_ = in.value;
        show(current_);
        break;
      case InputKind::Pause:
      case InputKind::Resume:
      case InputKind::Step:
      case InputKind::Reset: return "";  // nothing plays
      case InputKind::Ack: return "ack: not for the session";
      case InputKind::Record: return "record: look mode plays nothing to record (incise view SCENE.json --record DIR)";
      case InputKind::Clip: return "clip: look mode shows the worst elements (a report's, or the 10 worst)";
      default: return "look mode: nothing to cut or probe (incise view SCENE.json plays a scene live)";
    }
    listener = listener_;
  }
  if (listener) listener();
  return "";
}

void LookSession::set_listener(std::function<void()> listener) {
  std::lock_guard lock(mutex_);
  listener_ = std::move(listener);
}

std::shared_ptr<const Snapshot> LookSession::snapshot() const {
  std::lock_guard lock(mutex_);
  return snapshot_;
}

std::string LookSession::status_json() const {
  std::lock_guard lock(mutex_);
  return status_;
}

}  // namespace incise::view

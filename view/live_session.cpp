#include "view/live_session.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <optional>

#include <nlohmann/json.hpp>

#include "mesh/clock.h"
#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/rest_bounds.h"
#include "quality/metrics.h"
#include "scene/scene_output.h"
#include "scene/scene_record.h"
#include "scene/scene_runner.h"
#include "view/boundary_tracker.h"
#include "view/quality_watch.h"

namespace incise::view {

namespace fs = std::filesystem;

namespace {
using Clock = std::chrono::steady_clock;
// Colours are recomputed every this many frames (von Mises is a pass over every tet) and after
// each cut step; in between the page keeps the last ones.
constexpr int kColourEvery = 30;
// The clip view draws at most this many tets (the worst ones): 4 faces and 4 corners each on
// the wire, so a wide angle on a large mesh stays a bounded message.
constexpr std::size_t kMaxClipTets = 4000;
}  // namespace

// The runner and everything that follows its mesh; a reset makes a new one.
class LiveState {
public:
  explicit LiveState(const Scene& scene) : runner(scene) {
    const TetMesh& mesh = runner.mesh();
    fixed.assign(mesh.vertex_capacity(), 0);
    for (VertexId v : mesh.vertices())
      fixed[v.idx()] = runner.fem() ? runner.fem()->is_constrained(v) : runner.springs()->is_fixed(v);
    loaded.assign(mesh.vertex_capacity(), 0);
    for (VertexId v : runner.loaded_vertices()) loaded[v.idx()] = 1;
    tracker = std::make_unique<BoundaryTracker>(
        mesh, [this](VertexId v) { return v.idx() < fixed.size() && fixed[v.idx()]; },
        [this](VertexId v) { return v.idx() < loaded.size() && loaded[v.idx()]; });
    quality = std::make_unique<QualityWatch>(mesh);
    runner.set_change_observer([this](const TopologyChange& c) {
      tracker->apply(c);
      quality->apply(c);
    });
  }
  SceneRunner runner;
  std::vector<char> fixed;   // held by the scene when it started (the fixed regions drawn)
  std::vector<char> loaded;  // under a scene load (force, probe, pressure, traction) when it started
  std::unique_ptr<BoundaryTracker> tracker;
  std::unique_ptr<QualityWatch> quality;

  // input state
  bool paused = false, step_once = false, blade = false;
  // Where the blade is: the drag's own path is the blade's (a hand's wobble and the page's
  // single precision stay within the cutter's path tolerance, CutOptions::path_tolerance).
  Vec3 blade_at = Vec3::Zero(), blade_b = Vec3::Zero();
  std::uint32_t colour = 0;
  std::uint32_t clip_deg = 0;  // the clip view: tets below this angle drawn (0: off)
  bool probe = false;
  std::string error;
  // the take being recorded (LiveSession::start_take)
  std::optional<SceneOutput> take;
  std::string take_name, take_dir, last_take;  // last_take: the take ended last (its directory)

  // the last frame's figures and totals
  SceneFrame last;
  double frame_cut_ms = 0, frame_improve_ms = 0, frame_ms = 0;
  std::size_t budget_hits = 0;  // frames the solver budget stopped
  std::size_t frames = 0, blade_steps = 0;
  // The mouse's drags: how many have ended, and the tets the current (or last) one cut. The page
  // compares them across a drag to say "no cut" (the scene's own blade may cut meanwhile, so
  // the mesh's counts cannot tell).
  std::size_t blade_drags = 0, drag_tets_cut = 0;
  bool drag_open = false;  // a BladeStart taken since the last BladeEnd (a refused start leaves it false)
  double total_frame_ms = 0, max_frame_ms = 0, total_blade_ms = 0, max_blade_ms = 0;
  std::vector<float> scalars;
  float scalar_lo = 0, scalar_hi = 0;
  std::uint32_t scalar_version = 0;
  int frames_since_colour = 1 << 20;
};

LiveSession::LiveSession(const Scene& scene, std::string record_dir)
    : record_dir_(std::move(record_dir)), scene_(scene), state_(std::make_unique<LiveState>(scene)) {
  if (!record_dir_.empty()) {
    check_output_dir(record_dir_);
    // The page's Record button makes DIR/take-N much later: a mistyped path must not become a
    // tree of new directories then, nor an error only the page shows.
    const fs::path dir = fs::absolute(record_dir_).lexically_normal();
    std::error_code ec;
    if (!fs::exists(dir, ec) && !fs::is_directory(dir.parent_path(), ec))
      throw IoError(record_dir_, 0, "--record: neither this directory nor its parent " + dir.parent_path().string() +
                                        " exists (create it first)");
  }
  const RestBounds box = rest_bounds(state_->runner.mesh());
  body_size_ = box.size().norm();
  body_center_ = box.center();
  publish();
}

LiveSession::~LiveSession() {
  stop();
  try {
    if (state_->take) end_take(*state_);
  } catch (...) {  // a destructor does not throw; stop() reports what it can
  }
}

void LiveSession::start_take(LiveState& s) {
  int n = 1;
  while (fs::exists(fs::path(record_dir_) / ("take-" + std::to_string(n)))) ++n;
  s.take_name = "take-" + std::to_string(n);
  s.take_dir = (fs::path(record_dir_) / s.take_name).string();
  s.take.emplace(scene_, s.take_dir);
}

void LiveSession::end_take(LiveState& s) {
  if (!s.take) return;
  SceneOutput out = std::move(*s.take);
  s.take.reset();
  s.last_take = s.take_dir;
  s.take_name.clear();
  out.finish();
  RecordedScene r;
  r.inputs = s.runner.inputs_applied();
  r.frames_played = s.runner.frame();
  r.budget_ms = scene_.cg.budget_ms;
  AtomicFile f((std::filesystem::path(s.take_dir) / "scene.json").string());
  f.write(recorded_scene_json(scene_, r));
  f.commit();
}

void LiveSession::start() {
  if (thread_.joinable()) return;
  stop_ = false;
  thread_ = std::thread([this] { loop(); });
}

void LiveSession::stop() {
  stop_ = true;
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (state_->take) end_take(*state_);  // Ctrl-C ends a take like Record does
}

void LiveSession::set_listener(std::function<void()> listener) {
  std::lock_guard lock(mutex_);
  listener_ = std::move(listener);
}

std::shared_ptr<const Snapshot> LiveSession::snapshot() const {
  std::lock_guard lock(mutex_);
  return snapshot_;
}

std::string LiveSession::status_json() const {
  std::lock_guard lock(mutex_);
  return status_;
}

std::string LiveSession::check(const InputMessage& in) const {
  auto inside = [&](float x, float y, float z) { return (Vec3(x, y, z) - body_center_).norm() <= 2 * body_size_; };
  switch (in.kind) {
    case InputKind::BladeStart:
    case InputKind::BladeMove: {
      if (!inside(in.v[0], in.v[1], in.v[2]) || !inside(in.v[3], in.v[4], in.v[5]))
        return "blade: far outside the body";
      const double len = (Vec3(in.v[0], in.v[1], in.v[2]) - Vec3(in.v[3], in.v[4], in.v[5])).norm();
      if (!(len > 1e-6 * body_size_)) return "blade: its ends coincide";
      return "";
    }
    case InputKind::ProbeGrab:
      if (!inside(in.v[0], in.v[1], in.v[2])) return "probe: far outside the body";
      if (in.v[3] > 0.25 * body_size_) return "probe: radius above a quarter of the body's size";
      return "";
    case InputKind::ProbeMove:
      if (Vec3(in.v[0], in.v[1], in.v[2]).norm() > body_size_) return "probe: moved by more than the body's size";
      return "";
    case InputKind::Ack: return "ack: not for the simulation";
    case InputKind::Colour: return in.value <= 2 ? "" : "colour: label and boundary-tag colours are look mode's";
    case InputKind::Frame: return "frame: only a run directory has frames to pick (incise view RUN_DIR)";
    case InputKind::Record:
      return record_dir_.empty() ? "record: start incise view with --record DIR to record takes" : "";
    default: return "";
  }
}

std::string LiveSession::post(const InputMessage& input) {
  const std::string why = check(input);
  if (!why.empty()) return why;
  {
    std::lock_guard lock(mutex_);
    if (pending_.size() >= kMaxPending) return "too many inputs waiting for the next frame";
    pending_.push_back(input);
  }
  wake_.notify_all();
  return "";
}

void LiveSession::loop() {
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / kMaxFps));
  while (!stop_) {
    const auto frame_start = Clock::now();
    std::deque<InputMessage> in;
    {
      std::lock_guard lock(mutex_);
      in.swap(pending_);
    }
    LiveState* s = state_.get();
    s->frame_cut_ms = 0;
    s->frame_improve_ms = 0;
    bool changed = !in.empty();
    try {
      for (std::size_t i = 0; i < in.size(); ++i) {
        const InputMessage& m = in[i];
        const Vec3 a(m.v[0], m.v[1], m.v[2]), b(m.v[3], m.v[4], m.v[5]);
        switch (m.kind) {
          case InputKind::BladeStart:
            if (s->blade) {
              const CutStepReport r = s->runner.finish_blade();
              s->frame_cut_ms += r.ms;
              s->frame_improve_ms += r.ms_improve;
            }
            s->drag_tets_cut = s->runner.advance_blade({a, b}).tets_cut;  // places it
            s->drag_open = true;
            s->blade = true;
            s->blade_at = a;
            s->blade_b = b;
            break;
          case InputKind::BladeMove: {
            // Moves queued behind each other make one step (the cut does not depend on how a
            // motion is sliced, cut/cutter.h), so a fast mouse cannot queue up work.
            if (!s->blade || (i + 1 < in.size() && in[i + 1].kind == InputKind::BladeMove)) break;
            const Vec3 at = a, bt = b;
            if ((at - s->blade_at).norm() + (bt - s->blade_b).norm() <= 1e-9 * body_size_) break;  // did not move
            if (!((at - bt).norm() > 1e-6 * body_size_)) break;  // its ends would coincide
            s->blade_at = at;
            s->blade_b = bt;
            const auto t0 = Clock::now();
            const CutStepReport r = s->runner.advance_blade({at, bt});
            s->frame_improve_ms += r.ms_improve;
            s->drag_tets_cut += r.tets_cut;
            const double ms = ms_since(t0);
            s->frame_cut_ms += ms;
            ++s->blade_steps;
            s->total_blade_ms += ms;
            s->max_blade_ms = std::max(s->max_blade_ms, ms);
            s->frames_since_colour = 1 << 20;
            break;
          }
          case InputKind::BladeEnd:
            if (s->blade) {
              const CutStepReport r = s->runner.finish_blade();
              s->frame_cut_ms += r.ms;
              s->frame_improve_ms += r.ms_improve;
              s->drag_tets_cut += r.tets_cut;
            }
            if (!s->drag_open) s->drag_tets_cut = 0;  // its start was refused: this drag cut nothing
            s->drag_open = false;
            s->blade = false;
            ++s->blade_drags;  // also a drag an error cut short: the page waits for this count
            break;
          case InputKind::ProbeGrab:
            s->probe = s->runner.grab_probe(a, m.v[3]) > 0;  // O(mesh), once per grab
            break;
          case InputKind::ProbeMove:
            if (s->probe) s->runner.move_probe(a);
            break;
          case InputKind::ProbeRelease:
            s->runner.release_probe();
            s->probe = false;
            break;
          case InputKind::Pause: s->paused = true; break;
          case InputKind::Resume:
            s->paused = false;
            s->error.clear();
            break;
          case InputKind::Step: s->step_once = true; break;
          case InputKind::Record:
            if (m.value == 1 && !s->take) start_take(*s);
            if (m.value == 0 && s->take) end_take(*s);
            break;
          case InputKind::Reset: {
            end_take(*s);  // a take replays from the start: it ends where the session does
            const std::uint32_t colour = s->colour, clip = s->clip_deg;
            const bool paused = s->paused;
            const std::string last_take = s->last_take;
            state_ = std::make_unique<LiveState>(scene_);  // O(mesh): a user's reset, not a frame
            s = state_.get();
            s->colour = colour;
            s->clip_deg = clip;
            s->paused = paused;
            s->last_take = last_take;
            ++generation_;
            break;
          }
          case InputKind::Colour:
            s->colour = m.value;
            s->frames_since_colour = 1 << 20;
            break;
          case InputKind::Clip: s->clip_deg = m.value; break;
          case InputKind::Ack:
          case InputKind::Frame: break;  // refused by check()
        }
      }
      if (!s->paused || s->step_once) {
        s->step_once = false;
        const auto t0 = Clock::now();
        s->last = s->runner.step();
        s->frame_ms = ms_since(t0);
        s->frame_cut_ms += s->last.cut_ms;
        s->frame_improve_ms += s->last.cut_improve_ms;
        s->budget_hits += s->last.stats.budget_exhausted;
        if (s->take) s->take->add(s->runner, s->last, true);  // O(mesh) a frame, while recording only
        ++s->frames;
        s->total_frame_ms += s->frame_ms;
        s->max_frame_ms = std::max(s->max_frame_ms, s->frame_ms);
        changed = true;
      }
    } catch (const std::exception& e) {
      // A solver breakdown or a part the scene cannot keep: the run stops here, the page says why.
      s->error = e.what();
      s->paused = true;
      s->blade = false;
      changed = true;
    }
    if (changed) publish();
    std::unique_lock lock(mutex_);
    if (s->paused && !s->step_once)
      wake_.wait_for(lock, std::chrono::milliseconds(100), [&] { return stop_ || !pending_.empty(); });
    else
      wake_.wait_until(lock, frame_start + period, [&] { return bool(stop_); });
  }
}

void LiveSession::publish() {
  LiveState& s = *state_;
  const SceneRunner& r = s.runner;
  const BoundaryTracker& tr = *s.tracker;
  auto snap = std::make_shared<Snapshot>();
  snap->generation = generation_;
  snap->frame = std::uint32_t(r.frame());
  snap->position_epsilon = float(1e-5 * body_size_);
  snap->positions.assign(3 * tr.vertices().size(), NAN);
  for (std::size_t i = 0; i < tr.vertices().size(); ++i) {
    const VertexId v = tr.vertices()[i];
    if (!v.is_valid()) continue;
    const Vec3 p = r.position(v);
    for (int k = 0; k < 3; ++k) snap->positions[3 * i + k] = float(p[k]);
  }
  snap->tris.assign(4 * tr.triangles().size(), kNoSlot);
  for (std::size_t i = 0; i < tr.triangles().size(); ++i) {
    const auto& t = tr.triangles()[i];
    if (t.v[0] == kNoSlot) continue;
    for (int k = 0; k < 3; ++k) snap->tris[4 * i + k] = t.v[k];
    snap->tris[4 * i + 3] = t.flags;
  }
  // Colours: every kColourEvery frames and after cut steps (von Mises is O(mesh)).
  if (s.colour != 0 && ++s.frames_since_colour >= kColourEvery) {
    s.frames_since_colour = 0;
    std::vector<double> vm;
    if (s.colour == 1 && r.fem()) vm = s.runner.fem()->von_mises();
    s.scalars.assign(tr.triangles().size(), 0.f);
    std::vector<float> seen;
    for (std::size_t i = 0; i < tr.triangles().size(); ++i) {
      const auto& t = tr.triangles()[i];
      if (t.v[0] == kNoSlot || !r.mesh().is_alive(t.tet)) continue;
      float x = 0;
      if (s.colour == 1) {
        x = t.tet.idx() < vm.size() ? float(vm[t.tet.idx()]) : 0.f;
      } else {
        const auto& tv = r.mesh().tet_vertices(t.tet);
        x = float(tet_quality(r.position(tv[0]), r.position(tv[1]), r.position(tv[2]), r.position(tv[3])).min_dihedral);
      }
      s.scalars[i] = x;
      seen.push_back(x);
    }
    // The scale spans the 2nd to 98th percentile: a few slivers' stresses would otherwise
    // squeeze every other triangle into one colour.
    s.scalar_lo = 0, s.scalar_hi = 1;
    if (!seen.empty()) {
      auto at = [&](double q) {
        auto it = seen.begin() + std::ptrdiff_t(q * double(seen.size() - 1));
        std::nth_element(seen.begin(), it, seen.end());
        return *it;
      };
      s.scalar_lo = at(0.02);
      s.scalar_hi = std::max(at(0.98), s.scalar_lo);
    }
    ++s.scalar_version;
  }
  if (s.colour != 0) {
    snap->scalars = s.scalars;
    snap->scalars.resize(tr.triangles().size(), 0.f);
    snap->scalar_lo = s.scalar_lo;
    snap->scalar_hi = s.scalar_hi;
    snap->scalar_version = s.scalar_version;
  }
  // The clip view: the tets below the angle (rest shape, as the overlay's count), drawn whole
  // at their current positions after the boundary's slots, flagged like look mode's worst.
  std::size_t clip_tets = 0;
  if (s.clip_deg > 0) {
    const std::vector<TetId> bad = s.quality->tets_below(double(s.clip_deg), kMaxClipTets);
    clip_tets = bad.size();
    if (!snap->scalars.empty()) snap->scalars.resize(tr.triangles().size() + 4 * bad.size(), 0.f);
    for (TetId t : bad) {
      const auto& tv = r.mesh().tet_vertices(t);
      const std::uint32_t first = std::uint32_t(snap->positions.size() / 3);
      for (VertexId v : tv) {
        const Vec3 p = r.position(v);
        for (int k = 0; k < 3; ++k) snap->positions.push_back(float(p[k]));
      }
      for (int f = 0; f < 4; ++f)
        snap->tris.insert(snap->tris.end(), {first + std::uint32_t(kFaceLocal[f][0]), first + std::uint32_t(kFaceLocal[f][1]),
                                             first + std::uint32_t(kFaceLocal[f][2]), kTriangleWorst});
    }
  }
  snap->triangles = tr.triangle_count() + 4 * clip_tets;
  snap->cut_triangles = tr.cut_triangle_count();
  snap->tets = r.mesh().num_tets();
  snap->vertices = r.mesh().num_vertices();
  const FrameStats& st = s.last.stats;
  nlohmann::json j = {{"frame", r.frame()},
                      {"generation", generation_},
                      {"paused", s.paused},
                      {"blade", s.blade},
                      {"blade_drags", s.blade_drags},
                      {"drag_tets_cut", s.drag_tets_cut},
                      {"probe", s.probe},
                      {"recording", s.take_name},
                      {"can_record", !record_dir_.empty()},
                      {"clip_deg", s.clip_deg},
                      {"clip_tets", clip_tets},
                      {"clip_max", kMaxClipTets},
                      {"last_take", s.last_take},
                      {"colour", s.colour},
                      {"tets", snap->tets},
                      {"vertices", snap->vertices},
                      {"triangles", snap->triangles},
                      {"cut_triangles", snap->cut_triangles},
                      {"frame_ms", s.frame_ms},
                      {"cut_ms", s.frame_cut_ms},
                      {"improve_ms", s.frame_improve_ms},
                      {"budget_exhausted", st.budget_exhausted},
                      {"budget_hits", s.budget_hits},
                      {"solve_ms", st.solve_ms},
                      {"iterations", st.iterations},
                      {"residual", st.relative_residual},
                      {"min_dihedral", s.quality->min_dihedral()},
                      {"below", s.quality->below()},
                      {"below_deg", s.quality->below_deg()},
                      {"scalar_lo", s.scalar_lo},
                      {"scalar_hi", s.scalar_hi},
                      {"error", s.error}};
  // An error may quote a file's bytes (a take's path, a scene's message): invalid UTF-8 replaced.
  snap->stats_json = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
  j["frames_played"] = s.frames;
  j["mean_frame_ms"] = s.frames ? s.total_frame_ms / double(s.frames) : 0.0;
  j["max_frame_ms"] = s.max_frame_ms;
  j["blade_steps"] = s.blade_steps;
  j["mean_blade_step_ms"] = s.blade_steps ? s.total_blade_ms / double(s.blade_steps) : 0.0;
  j["max_blade_step_ms"] = s.max_blade_ms;
  j["fragments_handled"] = r.fragments_handled();
  std::function<void()> listener;
  {
    std::lock_guard lock(mutex_);
    snapshot_ = std::move(snap);
    status_ = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    listener = listener_;
  }
  if (listener) listener();
}

}  // namespace incise::view

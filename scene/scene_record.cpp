#include "scene/scene_record.h"

#include <algorithm>
#include <filesystem>

#include <nlohmann/json.hpp>

#include "mesh/errors.h"

namespace incise {

namespace {
using ojson = nlohmann::ordered_json;

ojson point(const Vec3& p) { return ojson::array({p.x(), p.y(), p.z()}); }

ojson input_json(const SceneInput& in) {
  ojson j;
  j["frame"] = in.frame;
  switch (in.kind) {
    case SceneInput::Kind::Blade: {
      j["blade"] = ojson::array({point(in.a), point(in.b)});
      const SceneInput plain;
      if (in.mode != plain.mode) j["mode"] = in.mode;
      if (in.snap != plain.snap) j["snap"] = in.snap;
      if (in.improve != plain.improve) j["improve"] = in.improve;
      break;
    }
    case SceneInput::Kind::Finish: j["finish"] = true; break;
    case SceneInput::Kind::Grab:
      j["grab"] = point(in.a);
      j["radius"] = in.radius;
      break;
    case SceneInput::Kind::Probe: j["probe"] = point(in.a); break;
    case SceneInput::Kind::Release: j["release"] = true; break;
  }
  return j;
}
}  // namespace

std::string recorded_scene_json(const Scene& scene, const RecordedScene& r) {
  if (scene.source.empty()) throw InvalidArgument("recorded_scene_json: the scene has no JSON text (it was not read from a file)");
  ojson j = ojson::parse(scene.source);
  // Frames: the ones played; one more when input came after the last (its cuts happened, the
  // replay solves once more after them). The scene's own blades that had not started are left
  // out; one that was moving when the recording stopped keeps the frames to its end (a blade's
  // steps are fractions of its whole sweep, so it cannot be cut short without moving them).
  int frames = std::max(r.frames_played, 1);
  for (const SceneInput& in : r.inputs) frames = std::max(frames, in.frame + 1);
  for (bool grew = true; grew;) {
    grew = false;
    for (const SceneCut& c : scene.cuts)
      if (c.from_frame < frames && c.to_frame + 1 > frames) {
        frames = c.to_frame + 1;
        grew = true;
      }
  }
  if (j.contains("cuts") && j["cuts"].is_array() && j["cuts"].size() == scene.cuts.size()) {
    ojson kept = ojson::array();
    for (std::size_t i = 0; i < scene.cuts.size(); ++i)
      if (scene.cuts[i].from_frame < frames) kept.push_back(j["cuts"][i]);
    if (kept.empty()) j.erase("cuts");
    else j["cuts"] = std::move(kept);
  }
  if (!j.contains("time") || !j["time"].is_object()) j["time"] = ojson::object();
  j["time"]["frames"] = frames;
  if (r.budget_ms >= 0) {
    if (!j.contains("solver") || !j["solver"].is_object()) j["solver"] = ojson::object();
    j["solver"]["budget_ms"] = r.budget_ms;
  }
  if (!scene.mesh_file.empty()) {
    namespace fs = std::filesystem;
    fs::path p(scene.mesh_file);
    if (p.is_relative()) p = fs::path(scene.path).parent_path() / p;
    j["mesh"] = fs::absolute(p).lexically_normal().string();
  }
  ojson list = ojson::array();
  for (const SceneInput& in : r.inputs) list.push_back(input_json(in));
  j["inputs"] = std::move(list);
  return j.dump(2) + "\n";
}

}  // namespace incise

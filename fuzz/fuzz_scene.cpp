// libFuzzer harness for the scene parser (scene/scene.h): any bytes as a scene file.
// incise::Error is the only acceptable failure (a raw JSON-library exception or a crash is a
// bug: users see the first as a message without the file's name). A scene that parses must
// hold what the parser promises the runner, so the fuzzer checks the validation too.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "mesh/errors.h"
#include "scene/scene.h"

namespace {

bool finite(const incise::Vec3& v) { return v.allFinite(); }

void check_scene(const incise::Scene& s) {
  if (s.frames < 1 || !(s.dt > 0) || !std::isfinite(s.dt) || s.substeps < 1 || s.output_every < 1) std::abort();
  if (s.mesh_file.empty() == s.generator.empty()) std::abort();  // exactly one mesh source
  if (!s.generator.empty() && !(finite(s.gen_size) && (s.gen_size.array() > 0).all())) std::abort();
  for (const auto& f : s.fixed)
    if (!finite(f.box.lo) || !finite(f.box.hi) || f.axes < 1 || f.axes > 7) std::abort();
  for (const auto& l : s.loads) {
    if (!finite(l.value) || !finite(l.box.lo) || !finite(l.box.hi)) std::abort();
    if (l.from_frame < 0 || l.to_frame < l.from_frame) std::abort();
  }
  for (const auto& c : s.cuts) {
    if (!finite(c.a) || !finite(c.b) || !finite(c.sweep)) std::abort();
    if (c.from_frame < 0 || c.to_frame < c.from_frame || c.to_frame >= s.frames) std::abort();
    if (!(c.snap >= 0 && c.snap < 0.5)) std::abort();
    if ((c.b - c.a).norm() == 0 || (c.path.empty() && c.sweep.norm() == 0)) std::abort();
    for (std::size_t i = 0; i < c.path.size(); ++i) {
      const auto& k = c.path[i];
      if (!finite(k.a) || !finite(k.b) || (k.b - k.a).norm() == 0 || k.frame >= s.frames) std::abort();
      if (i > 0 && !(k.frame > c.path[i - 1].frame)) std::abort();
    }
  }
  int last = 0;
  for (const auto& in : s.inputs) {
    if (in.frame < last || in.frame >= s.frames || !finite(in.a) || !finite(in.b)) std::abort();
    last = in.frame;
    if (in.kind == incise::SceneInput::Kind::Blade && ((in.b - in.a).norm() == 0 || !(in.snap >= 0 && in.snap < 0.5)))
      std::abort();
    if (in.kind == incise::SceneInput::Kind::Grab && !(in.radius > 0 && std::isfinite(in.radius))) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    check_scene(incise::parse_scene(text, "fuzz.json"));
  } catch (const incise::Error&) {
  }
  return 0;  // anything else escapes: libFuzzer reports it
}

// The live blade as the page sends it: on the mouse's ray (a fan from the eye), its two ends in
// single precision with a hand's wobble. The session must straighten it into one planar sweep
// and cut the body through: the same result as the exact fan given to the runner directly.
#include <catch2/catch.hpp>

#include <chrono>
#include <random>
#include <thread>

#include <nlohmann/json.hpp>

#include "scene/scene_runner.h"
#include "view/live_session.h"
#include "live_test_util.h"
#include "testing/draws.h"

using namespace incise;
using incise::testing::draw_vec3;
using namespace incise::view;
using incise::view::testing::status;

namespace {

// A fan from an eye above the liver: the blade's ends on two planes facing the eye, swept
// across the body in y at x = 150 (the fixed side is x < 60), n steps.
struct Fan {
  Vec3 eye = Vec3(150, 110, 600);
  double near = 300, far = 700;  // distances along the view axis (-z) of the blade's ends
  std::pair<Vec3, Vec3> at(double y) const {
    const Vec3 dir = (Vec3(150, y, 105) - eye).normalized();
    return {eye + dir * (near / -dir.z()), eye + dir * (far / -dir.z())};
  }
};

InputMessage blade(InputKind kind, const Vec3& a, const Vec3& b) {
  InputMessage m{kind};
  for (int k = 0; k < 3; ++k) m.v[k] = float(a[k]), m.v[3 + k] = float(b[k]);
  return m;
}


}  // namespace

TEST_CASE("a fan-shaped blade from the page, wobbling in single precision, cuts the liver through") {
  const Scene scene = load_scene(std::string(INCISE_SOURCE_DIR) + "/samples/scenes/liver_cut.json");
  const Fan fan;
  const int steps = 12;
  const double y0 = -60, y1 = 280;  // outside the body (y 24..195) at both ends of the sweep
  auto y_at = [&](int k) { return y0 + (y1 - y0) * k / steps; };

  // Exact: the runner directly, doubles, no wobble.
  SceneRunner exact(scene);
  const std::size_t tets0 = exact.mesh().num_tets();
  for (int k = 0; k <= steps; ++k) {
    const auto [a, b] = fan.at(y_at(k));
    exact.advance_blade({a, b});
  }
  exact.finish_blade();
  REQUIRE(exact.fragments_handled() == 1);

  // From the page: the session, floats, each end off its line by up to 0.1 mm (0.03% of the body).
  LiveSession live(scene);
  REQUIRE(live.post({InputKind::Pause}).empty());
  live.start();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> wobble(-0.1, 0.1);
  auto wait_steps = [&](int n) {
    for (int i = 0; i < 2000 && status(live)["blade_steps"].get<int>() < n; ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
  };
  {
    const auto [a, b] = fan.at(y_at(0));
    REQUIRE(live.post(blade(InputKind::BladeStart, a, b)).empty());
  }
  for (int k = 1; k <= steps; ++k) {
    auto [a, b] = fan.at(y_at(k));
    a += draw_vec3(wobble, rng);
    b += draw_vec3(wobble, rng);
    REQUIRE(live.post(blade(InputKind::BladeMove, a, b)).empty());
    wait_steps(k);  // one step each (moves queued together would make one)
  }
  REQUIRE(live.post({InputKind::BladeEnd}).empty());
  for (int i = 0; i < 2000 && status(live)["blade"].get<bool>(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  live.stop();
  const auto s = status(live);
  CHECK(s["blade_steps"] == steps);
  CHECK(s["fragments_handled"] == 1);  // the part away from the fixed side, removed
  // One straight sweep, as the exact one: the same cut up to the start's single precision.
  const double tets = s["tets"].get<double>(), want = double(exact.mesh().num_tets());
  CHECK(tets < double(tets0));
  CHECK(std::abs(tets - want) <= 0.02 * want);
  INFO("tets: page " << tets << ", exact " << want);
}

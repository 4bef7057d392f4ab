#pragma once
// Driving a LiveSession from a test: its /status figures, waiting for them, and page inputs.
#include <chrono>
#include <initializer_list>
#include <thread>

#include <catch2/catch.hpp>
#include <nlohmann/json.hpp>

#include "view/live_session.h"

namespace incise::view::testing {

inline nlohmann::json status(const LiveSession& s) { return nlohmann::json::parse(s.status_json()); }

// Waits (up to 20 s) until `done(status)` holds; fails the test if it never does.
template <class Pred>
void wait_for(const LiveSession& s, Pred done) {
  for (int i = 0; i < 4000 && !done(status(s)); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  REQUIRE(done(status(s)));
}

inline InputMessage msg(InputKind kind, std::initializer_list<float> v = {}, std::uint32_t value = 0) {
  InputMessage m{kind};
  std::size_t i = 0;
  for (float x : v) m.v[i++] = x;
  m.value = value;
  return m;
}

}  // namespace incise::view::testing

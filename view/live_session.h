#pragma once
// LiveSession: a scene played live. It owns the SceneRunner and a thread that plays frames one
// after the other (at most kMaxFps a second), taking the page's input between frames (blade,
// probe, pause/step/reset, colour mode) and publishing each frame as a Snapshot
// (view/frame_diff.h) that the server turns into each page's message. The simulation never
// waits for a page. No Boost here: the server (view/server.cpp) is the only network code.
//
//   LiveSession live(load_scene("liver_cut.json"));
//   live.set_listener([&] { /* a new snapshot is out */ });
//   live.start();
//   std::string error = live.post(input);   // from any thread; "" when taken
#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "scene/scene.h"
#include "view/view_source.h"

namespace incise::view {

class LiveState;  // the runner and what follows it (live_session.cpp)

class LiveSession : public ViewSource {
public:
  static constexpr double kMaxFps = 60;
  static constexpr std::size_t kMaxPending = 256;  // inputs waiting for the next frame

  // Builds the runner (throws what SceneRunner throws: IoError naming the scene and key).
  // `record_dir`: where Record writes its takes (take-1, take-2, ...: each the frames played
  // while recording as frame_NNNN.vtu, frames.pvd and stats.csv, and scene.json, the scene with
  // the inputs given since the start or the last reset, which `incise simulate` replays); empty:
  // Record is refused. The directory is checked (check_output_dir) before anything plays.
  explicit LiveSession(const Scene& scene, std::string record_dir = {});
  ~LiveSession() override;  // stops the thread
  LiveSession(const LiveSession&) = delete;
  LiveSession& operator=(const LiveSession&) = delete;

  void start();
  void stop();
  // Queues an input for the next frame. Returns "" or why it was refused (a blade or probe
  // far outside the body, a full queue); a refused input changes nothing.
  std::string post(const InputMessage& input) override;
  // Called on the simulation thread after each publish (keep it short: post to a network loop).
  void set_listener(std::function<void()> listener) override;
  std::shared_ptr<const Snapshot> snapshot() const override;
  // The figures of /status: counts, frame, timings so far (JSON).
  std::string status_json() const override;

private:
  void loop();
  void publish();
  std::string check(const InputMessage& input) const;
  void start_take(LiveState& s);
  void end_take(LiveState& s);  // writes the take's series, stats and scene.json

  std::string record_dir_;

  Scene scene_;
  std::unique_ptr<LiveState> state_;
  std::uint32_t generation_ = 0;  // bumped by each reset
  double body_size_ = 0;
  Vec3 body_center_ = Vec3::Zero();
  mutable std::mutex mutex_;  // guards pending_, snapshot_, listener_, status_
  std::condition_variable wake_;
  std::deque<InputMessage> pending_;
  std::shared_ptr<const Snapshot> snapshot_;
  std::function<void()> listener_;
  std::string status_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

}  // namespace incise::view

#pragma once
// ViewSource: what the viewer's server (view/server.h) serves. Two kinds: a scene played live
// (LiveSession) and files looked at (LookSession: a mesh, a quality report's mesh, a run
// directory's frames). The server needs only these four calls, so the page, the wire format and
// the security rules are the same for both.
#include <functional>
#include <memory>
#include <string>

#include "view/frame_diff.h"
#include "view/wire_format.h"

namespace incise::view {

class ViewSource {
public:
  virtual ~ViewSource() = default;
  // Takes an input (from the network thread). Returns "" or why it was refused; a refused
  // input changes nothing.
  virtual std::string post(const InputMessage& input) = 0;
  // Called after each new snapshot (keep it short: post to a network loop).
  virtual void set_listener(std::function<void()> listener) = 0;
  virtual std::shared_ptr<const Snapshot> snapshot() const = 0;
  virtual std::string status_json() const = 0;  // GET /status
};

}  // namespace incise::view

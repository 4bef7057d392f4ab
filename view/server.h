#pragma once
// ViewServer: the HTTP + WebSocket server of `incise view` (Boost.Beast, one port, one network
// thread) over a ViewSource (a live scene or files looked at). It serves only its own page files (a fixed list read from the web directory at
// start), a JSON status at /status, and the live stream at /ws. Beast stays inside server.cpp:
// this header and the rest of incise_view do not see Boost.
//
// Security (docs/view.md): bound to 127.0.0.1 unless another host is asked for; every request
// must name this server in Host (a page from another site that resolves its name to us is
// refused), a WebSocket upgrade must come from this server's own page (Origin); request
// headers, bodies and WebSocket messages are size-bounded, inputs rate-bounded per connection,
// connections counted; a bad input gets an error frame and changes nothing.
#include <memory>
#include <string>

#include "view/view_source.h"

namespace incise::view {

struct ServerOptions {
  std::string host = "127.0.0.1";
  unsigned short port = 0;  // 0: a free port
  std::string web_dir;      // index.html, viewer.js, three.js files (the build tree's view/web)
};

class ViewServer {
public:
  static constexpr int kMaxConnections = 16;        // WebSocket pages at once
  static constexpr double kMaxInputsPerSecond = 240;  // per page, averaged over a burst of as many

  // Reads the page files and binds; throws Error (a missing file, an address in use).
  ViewServer(ViewSource& session, const ServerOptions& options);
  ~ViewServer();
  ViewServer(const ViewServer&) = delete;
  ViewServer& operator=(const ViewServer&) = delete;

  std::string url() const;  // http://host:port/
  // Serves until SIGINT or SIGTERM (or stop()).
  void run();
  void stop();

  struct Impl;  // server.cpp's (named here so its connection classes can hold it)

private:
  std::shared_ptr<Impl> impl_;
};

}  // namespace incise::view

// incise view SCENE.json: the scene played live in a browser (docs/view.md). Starts the local
// server, prints its URL on stdout, and serves until interrupted (Ctrl-C).
#include <iostream>
#include <memory>

#include "cli/commands.h"
#include "scene/scene.h"
#include "view/live_session.h"
#include "view/server.h"

namespace incise::cli {

void add_view(CLI::App& app) {
  struct Opts {
    std::string scene, host = "127.0.0.1", web_dir = INCISE_VIEW_WEB_DIR;
    int port = 0;
    double budget_ms = -1;
    bool paused = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("view", "Play a scene live in the browser: cut it with the mouse (docs/view.md)");
  cmd->add_option("scene", o->scene, "Scene file (.json, see docs/scene.md)")->required();
  cmd->add_option("--port", o->port, "TCP port; 0 (default): a free one")->check(CLI::Range(0, 65535));
  cmd->add_option("--host", o->host,
                  "IP address to listen on; default 127.0.0.1 (this machine only). Another address exposes the "
                  "simulation to the network: give it deliberately");
  cmd->add_option("--web-dir", o->web_dir, "Where the page's files are (default: the build tree's view/web)");
  cmd->add_option("--budget-ms", o->budget_ms,
                  "Solver budget per frame in ms, instead of the scene's solver.budget_ms (0: none). Default: the "
                  "scene's, or 30 when the scene sets none: a budget keeps the frame rate while a cut makes the "
                  "solve slow, and an unfinished solve goes on next frame (docs/view.md)")
      ->check(CLI::Range(0.0, 1e6));
  cmd->add_flag("--paused", o->paused, "Start paused (Step or Resume on the page)");
  cmd->callback([o] {
    Scene scene = load_scene(o->scene);
    // Live, a frame must come back in time: without a budget the solves right after a cut took
    // up to 2.8 s on the sample liver. Scenes written for `incise simulate` rarely set one.
    constexpr double kLiveBudgetMs = 30;
    if (o->budget_ms >= 0) scene.cg.budget_ms = o->budget_ms;
    else if (scene.cg.budget_ms <= 0) scene.cg.budget_ms = kLiveBudgetMs;
    view::LiveSession live(scene);
    view::ServerOptions so;
    so.host = o->host;
    so.port = static_cast<unsigned short>(o->port);
    so.web_dir = o->web_dir;
    view::ViewServer server(live, so);
    if (o->paused) live.post({view::InputKind::Pause});
    live.start();
    std::cout << "incise view: " << server.url() << "  (" << o->scene << ", solver budget "
              << (scene.cg.budget_ms > 0 ? std::to_string(int(scene.cg.budget_ms)) + " ms" : std::string("none"))
              << " per frame; Ctrl-C stops)" << std::endl;
    server.run();
    live.stop();
  });
}

}  // namespace incise::cli

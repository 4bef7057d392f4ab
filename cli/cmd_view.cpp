// incise view SCENE.json | MESH | REPORT.json | RUN_DIR (docs/view.md): a scene played live in a
// browser, or files looked at (a mesh, a quality report's mesh, a run directory's frames). The
// mode comes from the argument (view/look_session.h classify_view_argument). Starts the local
// server, prints its URL on stdout, and serves until interrupted (Ctrl-C).
#include <filesystem>
#include <iostream>
#include <memory>

#include "cli/checks.h"
#include "cli/commands.h"
#include "mesh/errors.h"
#include "scene/scene.h"
#include "view/live_session.h"
#include "view/look_session.h"
#include "view/server.h"

namespace incise::cli {

namespace {
// The page's files: an installed incise has them at P/share/incise/web beside its P/bin (found
// from where the executable is, so a moved prefix still works); a build tree's incise serves
// the build tree's copy.
std::string default_web_dir() {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    fs::path prefix = exe.parent_path();
    for (const auto& part : fs::path(INCISE_INSTALL_BINDIR)) {
      (void)part;
      prefix = prefix.parent_path();
    }
    const fs::path installed = prefix / INCISE_VIEW_INSTALLED_WEB_DIR;
    if (fs::exists(installed / "index.html", ec)) return installed.string();
  }
  return INCISE_VIEW_WEB_DIR;
}
}  // namespace

void add_view(CLI::App& app) {
  struct Opts {
    std::string scene, host = "127.0.0.1", web_dir = default_web_dir(), record;
    int port = 0;
    double budget_ms = -1;
    bool paused = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("view", "Play a scene live in the browser and cut it with the mouse, or look at a mesh, "
                                         "a quality report's mesh or a run directory (docs/view.md)");
  cmd->add_option("input", o->scene,
                  "Scene file (.json, docs/scene.md): live; a mesh file, a report of `incise quality --json`, or a "
                  "directory of `incise simulate -o`: look")
      ->required();
  cmd->add_option("--port", o->port, "TCP port; 0 (default): a free one")->check(CLI::Range(0, 65535));
  cmd->add_option("--host", o->host,
                  "IP address to listen on; default 127.0.0.1 (this machine only). Another address exposes the "
                  "simulation to the network: give it deliberately");
  cmd->add_option("--web-dir", o->web_dir, "Where the page's files are (default: " + o->web_dir + ")");
  cmd->add_option("--budget-ms", o->budget_ms,
                  "Budget per frame in ms, the frame's blade steps and the solve together, instead of the scene's "
                  "solver.budget_ms (0: none). Default: the scene's, or 30 when the scene sets none: a budget keeps "
                  "the frame rate while a cut makes the solve slow, and an unfinished solve goes on next frame "
                  "(docs/view.md)")
      ->check(finite_range(0.0, 1e6));
  cmd->add_flag("--paused", o->paused, "Start paused (Step or Resume on the page)");
  cmd->add_option("--record", o->record,
                  "Live: where the page's Record button writes its takes (DIR/take-N: the frames recorded, "
                  "frames.pvd, stats.csv, and scene.json, which `incise simulate` replays; docs/view.md)");
  cmd->callback([o, cmd] {
    view::ServerOptions so;
    so.host = o->host;
    so.port = static_cast<unsigned short>(o->port);
    so.web_dir = o->web_dir;
    const view::ViewArgument kind = view::classify_view_argument(o->scene);
    if (kind != view::ViewArgument::Scene) {
      // Look mode plays nothing: options of a live scene would be silently void.
      for (const char* opt : {"--paused", "--budget-ms", "--record"})
        if (cmd->count(opt) > 0)
          throw InvalidArgument("view: " + std::string(opt) + " is for a scene (live mode); " + o->scene + " is looked at");
      std::unique_ptr<view::LookSession> look = kind == view::ViewArgument::Run    ? view::LookSession::open_run(o->scene)
                                                : kind == view::ViewArgument::Report ? view::LookSession::open_report(o->scene)
                                                                                     : view::LookSession::open_mesh(o->scene);
      view::ViewServer server(*look, so);
      std::cout << "incise view: " << server.url() << "  (" << o->scene << ": "
                << (kind == view::ViewArgument::Run ? std::to_string(look->frame_count()) + " frames" : std::string("look"))
                << "; Ctrl-C stops)" << std::endl;
      server.run();
      return;
    }
    Scene scene = load_scene(o->scene);
    // Live, a frame must come back in time: without a budget the solves right after a cut took
    // up to 2.8 s on the sample liver. Scenes written for `incise simulate` rarely set one.
    constexpr double kLiveBudgetMs = 30;
    if (o->budget_ms >= 0) scene.cg.budget_ms = o->budget_ms;
    else if (scene.cg.budget_ms <= 0) scene.cg.budget_ms = kLiveBudgetMs;
    view::LiveSession live(scene, o->record);
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

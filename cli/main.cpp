// incise: one executable, one subcommand per job. Exit codes: 0 success, 1 bad input or
// failure (one line on stderr naming the file and, where it applies, the line).
#include <cstdio>
#include <iostream>

#include "cli/commands.h"
#include "mesh/errors.h"

int main(int argc, char** argv) {
  CLI::App app{"incise: tetrahedral meshes for surgical simulation: prepare, cut, simulate"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "incise 0.1.0");
  incise::cli::add_info(app);
  incise::cli::add_convert(app);
  incise::cli::add_quality(app);
  incise::cli::add_generate(app);
  incise::cli::add_simulate(app);
  incise::cli::add_tetra(app);
  incise::cli::add_prepare(app);
  incise::cli::add_cut(app);
  incise::cli::add_improve(app);
  incise::cli::add_trade(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return 1;  // usage errors are bad input too
  } catch (const incise::Error& e) {
    std::cerr << "incise: error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "incise: error: out of memory\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "incise: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

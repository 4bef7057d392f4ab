#pragma once
// One function per subcommand; each lives in cli/cmd_<name>.cpp and adds itself to the app.
// The callback runs the command; errors propagate as incise::Error and main() turns them
// into one line on stderr and exit code 1.
#include <CLI/CLI.hpp>

namespace incise::cli {

void add_info(CLI::App& app);
void add_convert(CLI::App& app);
void add_quality(CLI::App& app);
void add_generate(CLI::App& app);
void add_simulate(CLI::App& app);
void add_tetra(CLI::App& app);
void add_prepare(CLI::App& app);
void add_cut(CLI::App& app);
void add_improve(CLI::App& app);
void add_coarsen(CLI::App& app);
void add_trade(CLI::App& app);
void add_view(CLI::App& app);  // cli/cmd_view.cpp when built with INCISE_WITH_VIEW

}  // namespace incise::cli

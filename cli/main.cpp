// incise: one executable, one subcommand per job. Exit codes: 0 success, 1 bad input or
// failure (one line on stderr naming the file and, where it applies, the line).
#include <cctype>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <string>

#include "cli/commands.h"
#include "mesh/errors.h"
#include "mesh/memory_limit.h"

namespace {

// CLI11 reads "-inf" and "-nan" as an option name, so `--sweep 0 0 -inf` would say "at least 3
// required but received 2". No option of incise is spelled like that: name the value instead.
void refuse_non_finite_words(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    for (char& c : a) c = char(std::tolower(static_cast<unsigned char>(c)));
    if (a == "-inf" || a == "-infinity" || a == "-nan") {
      std::string option;  // the option the value belongs to: the last one spelled before it
      for (int j = i - 1; j > 0 && option.empty(); --j)
        if (argv[j][0] == '-' && argv[j][1] == '-') option = std::string(argv[j]) + ": ";
      throw incise::InvalidArgument(option + "'" + argv[i] + "': numbers must be finite");
    }
  }
}

// CLI11 takes an empty word as a value and then keeps the option's default (`--worst ""` ran
// with 10): no value of incise is empty, so an empty word is refused, naming its option.
void refuse_empty_words(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const std::size_t eq = a.find('=');
    if (a.rfind("--", 0) == 0 && eq != std::string::npos && eq + 1 == a.size())
      throw incise::InvalidArgument(a.substr(0, eq) + ": an empty value");
    if (!a.empty()) continue;
    std::string option = i > 1 && argv[i - 1][0] == '-' ? std::string(argv[i - 1]) + ": " : std::string();
    throw incise::InvalidArgument(option + "an empty value" + (option.empty() ? " (argument " + std::to_string(i) + ")" : ""));
  }
}

// One line like every other error (CLI11 prints its message and a "Run with --help" hint).
std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

}  // namespace

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
  incise::cli::add_coarsen(app);
  incise::cli::add_trade(app);
#ifdef INCISE_HAVE_VIEW
  incise::cli::add_view(app);
#endif
  try {
    refuse_non_finite_words(argc, argv);
    refuse_empty_words(argc, argv);
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::cerr << "incise: error: " << one_line(e.what()) << " (see --help)\n";
    return 1;  // usage errors are bad input too
  } catch (const incise::Error& e) {
    std::cerr << "incise: error: " << e.what() << "\n";
    return 1;
  } catch (const std::bad_alloc&) {
    std::cerr << "incise: error: out of memory: the command needed more than the "
              << incise::format_bytes(double(incise::available_memory_bytes()))
              << " this machine has available now; use a smaller input, size or option\n";
    return 1;
  } catch (const std::exception& e) {
    std::cerr << "incise: error: " << e.what() << "\n";
    return 1;
  }
  return 0;
}

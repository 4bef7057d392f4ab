#pragma once
// Small helpers shared by the benchmark programs: argument parsing, timing, CSV output.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

namespace incise::bench {

struct Args {
  std::vector<std::string> argv;
  // --help or -h: say where the options are written (each program's header comment) and exit,
  // instead of running the whole benchmark.
  Args(int argc, char** a) : argv(a + 1, a + argc) {
    if (flag("--help") || flag("-h")) {
      const std::string name = std::filesystem::path(a[0]).filename().string();
      std::printf("%s: a benchmark of incise; its options, sections and what it prints are in the header "
                  "comment of bench/%s.cpp\n",
                  name.c_str(), name.c_str());
      std::exit(0);
    }
  }
  bool flag(const std::string& name) const { return std::find(argv.begin(), argv.end(), name) != argv.end(); }
  std::string get(const std::string& name, const std::string& def) const {
    for (std::size_t i = 0; i + 1 < argv.size(); ++i)
      if (argv[i] == name) return argv[i + 1];
    return def;
  }
  double num(const std::string& name, double def) const { return std::stod(get(name, std::to_string(def))); }
  std::vector<double> list(const std::string& name, const std::string& def) const {
    std::vector<double> out;
    std::stringstream ss(get(name, def));
    for (std::string item; std::getline(ss, item, ',');) out.push_back(std::stod(item));
    return out;
  }
};

inline double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Median of `reps` timings of f() in milliseconds (shared machines: the median resists noise).
inline double time_ms(int reps, const std::function<void()>& f) {
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) {
    const double t0 = now_ms();
    f();
    t.push_back(now_ms() - t0);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

class Csv {
public:
  Csv(const std::string& dir, const std::string& name, const std::string& header) {
    std::filesystem::create_directories(dir.empty() ? "." : dir);
    path_ = (std::filesystem::path(dir.empty() ? "." : dir) / name).string();
    out_.open(path_);
    out_ << header << "\n";
  }
  template <class... T>
  void row(const T&... v) {
    std::ostringstream s;
    s.precision(10);
    ((s << v << ","), ...);
    std::string line = s.str();
    line.pop_back();
    out_ << line << "\n";
    out_.flush();
  }
  const std::string& path() const { return path_; }

private:
  std::string path_;
  std::ofstream out_;
};

}  // namespace incise::bench

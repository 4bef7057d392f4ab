#include "cut/blade_path.h"

#include <cmath>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/io/parse_util.h"

namespace incise {

std::vector<BladeSegment> read_blade_path(const std::string& path) {
  const std::string text = io::read_file_bytes(path);
  std::vector<BladeSegment> out;
  std::istringstream in(text);
  std::string line;
  long number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
    std::istringstream ls(line);
    std::vector<double> v;
    std::string word;
    while (ls >> word) {
      std::size_t used = 0;
      double x = 0;
      try {
        x = std::stod(word, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != word.size()) throw IoError(path, number, "'" + word + "' is not a number");
      if (!std::isfinite(x) || std::abs(x) > 1e15)
        throw IoError(path, number, "coordinates must be finite numbers of magnitude at most 1e15, got " + word);
      v.push_back(x);
    }
    if (v.empty()) continue;
    if (v.size() != 6)
      throw IoError(path, number, "expected 6 numbers (AX AY AZ BX BY BZ), got " + std::to_string(v.size()));
    const BladeSegment b{Vec3(v[0], v[1], v[2]), Vec3(v[3], v[4], v[5])};
    if (!((b.b - b.a).norm() > 0)) throw IoError(path, number, "the blade's two ends are the same point");
    out.push_back(b);
  }
  if (out.size() < 2)
    throw IoError(path, number, "a path needs at least two blade positions (the first places the blade), got " +
                                    std::to_string(out.size()));
  bool moves = false;
  for (const BladeSegment& b : out) moves = moves || !(b.a == out[0].a && b.b == out[0].b);
  if (!moves) throw IoError(path, number, "the blade never moves (every line is the first position)");
  return out;
}

}  // namespace incise

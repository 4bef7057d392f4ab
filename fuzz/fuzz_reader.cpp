// libFuzzer harness for one reader, chosen at compile time (INCISE_FUZZ_EXT): the input
// bytes go to a temporary file with the reader's extension, the reader runs, and
// incise::Error is the only acceptable failure. A mesh that reads must also pass
// validate() (orientation aside: zero-volume tets are kept) and survive a write/read round
// trip, so the fuzzers check the builder and the writers too.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <string_view>

#include "mesh/errors.h"
#include "mesh/io/surface.h"
#include "mesh/io/tet_io.h"

namespace {

const std::string& scratch_dir() {
  static const std::string dir = [] {
    char tmpl[] = "/tmp/incise_fuzz_XXXXXX";
    const char* d = ::mkdtemp(tmpl);
    if (!d) std::abort();
    return std::string(d);
  }();
  return dir;
}

void write_file(const std::string& path, std::string_view bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

[[maybe_unused]] void check_mesh(const incise::TetMesh& m) {
  m.validate(incise::TetMesh::ValidateOptions{false, false});  // InvalidMesh escapes: a reader bug
  if (m.num_tets() > 2000) return;
  const std::string out = scratch_dir() + "/roundtrip.vtu";
  incise::WriteOptions o;
  o.binary = true;
  incise::write_tet_mesh(m, out, o);
  incise::TetMesh back = incise::read_tet_mesh(out);
  if (back.num_tets() != m.num_tets() || back.num_vertices() != m.num_vertices()) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const std::string base = scratch_dir() + "/input";
  try {
#if defined(INCISE_FUZZ_TETGEN)
    // One input holds both files, split at a "#ELE" comment line.
    auto cut = bytes.find("\n#ELE\n");
    write_file(base + ".node", bytes.substr(0, cut));
    write_file(base + ".ele", cut == std::string_view::npos ? std::string_view() : bytes.substr(cut + 6));
    check_mesh(incise::read_tet_mesh(base + ".node"));
#elif defined(INCISE_FUZZ_SURFACE)
    // The first byte picks the format (OFF is read by incise itself, the others by assimp).
    if (size == 0) return 0;
    static const char* kExt[] = {".off", ".stl", ".obj", ".ply"};
    const std::string path = base + kExt[data[0] % 4];
    write_file(path, bytes.substr(1));
    incise::SurfaceMesh s = incise::read_surface(path);
    for (const auto& t : s.triangles)
      for (int v : t)
        if (v < 0 || static_cast<std::size_t>(v) >= s.vertices.size()) std::abort();
#else
    const std::string path = base + "." INCISE_FUZZ_EXT;
    write_file(path, bytes);
    check_mesh(incise::read_tet_mesh(path));
#endif
  } catch (const incise::InvalidMesh&) {
    std::abort();  // the reader accepted something that is not a mesh
  } catch (const incise::Error&) {
  }
  return 0;
}

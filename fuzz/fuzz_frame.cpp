// libFuzzer harness for the viewer's frame loading (view/look_session.cpp, `incise view RUN`):
// a run directory whose frames.pvd, stats.csv or second frame holds the input bytes. Opening
// the run may be refused (incise::Error naming the file); selecting the bad frame must give the
// page an error line and keep the first frame shown; the status must stay valid JSON (UTF-8).
// A crash, a hang, a sanitizer report or any other exception is a bug.
//
// Byte 0 picks the file the rest replaces: 0 frame_0001.vtu, 1 stats.csv, 2 frames.pvd.
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "view/look_session.h"
#include "view/wire_format.h"

namespace {

namespace fs = std::filesystem;
using namespace incise;

const fs::path& run_dir() {
  static const fs::path dir = [] {
    const fs::path d = fs::temp_directory_path() / ("incise-fuzz-frame-" + std::to_string(::getpid()));
    fs::create_directories(d);
    return d;
  }();
  return dir;
}

// A run of two frames as incise simulate writes it: positions, displacement, von Mises, the cut mask.
void write_good_run(const fs::path& d) {
  static const std::string frame = [&] {
    const TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
    MeshFields f;
    f.point_data.push_back(Field{"displacement", 3, std::vector<double>(3 * m.vertex_capacity(), 0.01)});
    f.cell_data.push_back(Field{"von_mises", 1, std::vector<double>(m.tet_capacity(), 2.5)});
    f.cell_data.push_back(Field{"cut_face_mask", 1, std::vector<double>(m.tet_capacity(), 0)});
    write_tet_mesh_with_fields(m, (d / "seed.vtu").string(), f);
    std::ifstream in(d / "seed.vtu", std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  std::ofstream(d / "frame_0000.vtu", std::ios::binary) << frame;
  std::ofstream(d / "frame_0001.vtu", std::ios::binary) << frame;
  std::ofstream(d / "frames.pvd") << "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n"
                                     "<DataSet timestep=\"0\" file=\"frame_0000.vtu\"/>\n"
                                     "<DataSet timestep=\"1\" file=\"frame_0001.vtu\"/>\n</Collection>\n</VTKFile>\n";
  std::ofstream(d / "stats.csv") << "frame,time,iterations,relative_residual\n0,0,3,1e-7\n1,1,4,2e-7\n";
  std::ofstream(d / ".incise-run") << "incise run\n";
}

void check_json(const std::string& s) {
  if (!nlohmann::json::accept(s)) std::abort();  // also refuses invalid UTF-8
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const fs::path& d = run_dir();
  write_good_run(d);
  const char* names[] = {"frame_0001.vtu", "stats.csv", "frames.pvd"};
  std::ofstream(d / names[data[0] % 3], std::ios::binary).write(reinterpret_cast<const char*>(data + 1), std::streamsize(size - 1));
  std::unique_ptr<view::LookSession> look;
  try {
    look = view::LookSession::open_run(d.string());
  } catch (const Error&) {
    return 0;  // a broken run refused at the start, naming the file
  }
  check_json(look->status_json());
  view::InputMessage select;
  select.kind = view::InputKind::Frame;
  for (std::uint32_t f : {1u, 0u, 1u}) {
    select.value = f;
    if (f < look->frame_count()) (void)look->post(select);  // an error line for the page, or ""
    if (!look->snapshot()) std::abort();
    check_json(look->status_json());
  }
  return 0;
}

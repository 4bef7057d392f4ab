// Every reader refuses what is not a regular file, before reading a byte: a symbolic link to
// /dev/zero (which never ends), a FIFO (which blocks until a writer comes), a directory.
#include <catch2/catch.hpp>

#include <sys/stat.h>
#include <zlib.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <cstring>
#include <string>
#include <vector>

#include "cut/blade_path.h"
#include "mesh/errors.h"
#include "mesh/io/input_file.h"
#include "mesh/io/surface.h"
#include "mesh/io/tet_io.h"
#include "scene/scene.h"

namespace fs = std::filesystem;
using namespace incise;

TEST_CASE("readers refuse devices, FIFOs and directories with one line naming the file", "[io][errors]") {
  const fs::path dir = fs::temp_directory_path() / "incise_input_files";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::function<void(const std::string&)> readers[] = {
      [](const std::string& p) { (void)read_tet_mesh(p); },
      [](const std::string& p) { (void)read_surface(p); },
      [](const std::string& p) { (void)load_scene(p); },
      [](const std::string& p) { (void)read_blade_path(p); },
  };
  const char* names[] = {"z.msh", "z.off", "z.json", "z.path"};
  for (int k = 0; k < 4; ++k) {
    CAPTURE(names[k]);
    const fs::path zero = dir / names[k];
    fs::create_symlink("/dev/zero", zero);
    CHECK_THROWS_WITH(readers[k](zero.string()), Catch::Contains(zero.string()) && Catch::Contains("not a regular file (a device)"));
    const fs::path fifo = dir / (std::string("fifo_") + names[k]);
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    CHECK_THROWS_WITH(readers[k](fifo.string()), Catch::Contains("not a regular file (a FIFO)"));
    const fs::path sub = dir / (std::string("dir_") + names[k]);
    fs::create_directory(sub);
    CHECK_THROWS_WITH(readers[k](sub.string()), Catch::Contains("is a directory"));
  }
  // A link to a regular file is read as the file.
  {
    std::ofstream p(dir / "real.path");
    p << "0 0 0 1 1 1\n0 0 1 1 1 2\n";
  }
  fs::create_symlink(dir / "real.path", dir / "link.path");
  CHECK(read_blade_path((dir / "link.path").string()).size() == 2);
  CHECK(check_input_file((dir / "real.path").string()) > 0);
  fs::remove_all(dir);
}

namespace {
std::string base64(const std::string& in) {
  static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < in.size(); i += 3) {
    const unsigned b0 = static_cast<unsigned char>(in[i]), b1 = i + 1 < in.size() ? static_cast<unsigned char>(in[i + 1]) : 0,
                   b2 = i + 2 < in.size() ? static_cast<unsigned char>(in[i + 2]) : 0;
    const unsigned v = (b0 << 16) | (b1 << 8) | b2;
    out += k[(v >> 18) & 63];
    out += k[(v >> 12) & 63];
    out += i + 1 < in.size() ? k[(v >> 6) & 63] : '=';
    out += i + 2 < in.size() ? k[v & 63] : '=';
  }
  return out;
}
}  // namespace

TEST_CASE("a zlib block declaring more than the piece's counts allow is refused before inflating", "[io][errors]") {
  // Four points (96 bytes of Float64) whose compressed array inflates to 8 MB of zeros: the
  // compression ratio is plausible for zeros, the size is not for four points.
  const std::uint32_t total = 8u << 20;
  const std::string zeros(total, '\0');
  uLongf clen = compressBound(total);
  std::string comp(clen, '\0');
  REQUIRE(::compress(reinterpret_cast<Bytef*>(comp.data()), &clen, reinterpret_cast<const Bytef*>(zeros.data()), total) == Z_OK);
  comp.resize(clen);
  std::string header(16, '\0');
  const std::uint32_t h[4] = {1, total, total, std::uint32_t(clen)};
  std::memcpy(header.data(), h, 16);
  const fs::path path = fs::temp_directory_path() / "incise_zlib_bomb.vtu";
  {
    std::ofstream f(path);
    f << R"(<?xml version="1.0"?><VTKFile type="UnstructuredGrid" version="1.0" byte_order="LittleEndian" )"
      << R"(header_type="UInt32" compressor="vtkZLibDataCompressor"><UnstructuredGrid><Piece NumberOfPoints="4" )"
      << R"(NumberOfCells="1"><Points><DataArray type="Float64" NumberOfComponents="3" format="binary">)"
      << base64(header + comp) << R"(</DataArray></Points><Cells><DataArray type="Int32" Name="connectivity" )"
      << R"(format="ascii">0 1 2 3</DataArray><DataArray type="Int32" Name="offsets" format="ascii">4</DataArray>)"
      << R"(<DataArray type="UInt8" Name="types" format="ascii">10</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>)";
  }
  CHECK_THROWS_WITH(read_tet_mesh(path.string()), Catch::Contains("declares 8388608 bytes, more than the piece's counts allow (96)"));
  fs::remove(path);
}

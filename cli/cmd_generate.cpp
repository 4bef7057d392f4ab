// incise generate box|ellipsoid: structured meshes for tests, benchmarks and users.
#include <iostream>

#include "cli/commands.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"

namespace incise::cli {

void add_generate(CLI::App& app) {
  auto* gen = app.add_subcommand("generate", "Generate a structured tetrahedral mesh");
  gen->require_subcommand(1);

  struct BoxOpts {
    std::vector<double> size{1, 1, 1};
    std::vector<int> cells{4, 4, 4};
    int label = 1;
    std::string out;
  };
  auto box = std::make_shared<BoxOpts>();
  auto* b = gen->add_subcommand("box", "Box [0,LX]x[0,LY]x[0,LZ], each cube split into 6 tets");
  b->add_option("--size", box->size, "Edge lengths LX LY LZ")->expected(3)->capture_default_str();
  b->add_option("--cells", box->cells, "Cubes along each axis NX NY NZ")->expected(3)->capture_default_str();
  b->add_option("--label", box->label, "Region label of every tet")->capture_default_str();
  b->add_option("-o,--output", box->out, "Output mesh (format by extension)")->required();
  b->callback([box] {
    TetMesh m = make_box(Vec3(box->size[0], box->size[1], box->size[2]), {box->cells[0], box->cells[1], box->cells[2]},
                         box->label);
    write_tet_mesh(m, box->out);
    std::cerr << "generate: " << m.num_vertices() << " vertices, " << m.num_tets() << " tets -> " << box->out << "\n";
  });

  struct EllOpts {
    std::vector<double> radii{1, 1, 1};
    int n = 4;
    int label = 1;
    std::string out;
  };
  auto ell = std::make_shared<EllOpts>();
  auto* e = gen->add_subcommand("ellipsoid", "Ellipsoid centred at the origin (a ball with equal radii)");
  e->alias("sphere");
  e->add_option("--radii", ell->radii, "Semi-axes RX RY RZ")->expected(3)->capture_default_str();
  e->add_option("--resolution", ell->n, "Cells per radius")->capture_default_str();
  e->add_option("--label", ell->label, "Region label of every tet")->capture_default_str();
  e->add_option("-o,--output", ell->out, "Output mesh (format by extension)")->required();
  e->callback([ell] {
    TetMesh m = make_ellipsoid(Vec3(ell->radii[0], ell->radii[1], ell->radii[2]), ell->n, ell->label);
    write_tet_mesh(m, ell->out);
    std::cerr << "generate: " << m.num_vertices() << " vertices, " << m.num_tets() << " tets -> " << ell->out << "\n";
  });
}

}  // namespace incise::cli

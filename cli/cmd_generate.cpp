// incise generate box|ellipsoid|tube|cook: structured meshes for tests, benchmarks and users.
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

  struct TubeOpts {
    std::vector<double> radii{0.5, 1};
    double height = 0.25;
    double angle = 90;
    std::vector<int> cells{4, 8, 1};
    int label = 1;
    std::string out;
  };
  auto tube = std::make_shared<TubeOpts>();
  auto* t = gen->add_subcommand(
      "tube", "Sector of a thick-walled tube around the z axis (inner wall tagged 16, outer wall 17, the rest 1)");
  t->add_option("--radii", tube->radii, "Inner and outer radius")->expected(2)->capture_default_str();
  t->add_option("--height", tube->height, "Length along z")->capture_default_str();
  t->add_option("--angle", tube->angle, "Sector angle in degrees, from the x axis, in (0, 360)")->capture_default_str();
  t->add_option("--cells", tube->cells, "Cubes across the wall, around, along z")->expected(3)->capture_default_str();
  t->add_option("--label", tube->label, "Region label of every tet")->capture_default_str();
  t->add_option("-o,--output", tube->out, "Output mesh (format by extension)")->required();
  t->callback([tube] {
    TetMesh m = make_tube(tube->radii[0], tube->radii[1], tube->height, tube->angle,
                          {tube->cells[0], tube->cells[1], tube->cells[2]}, tube->label);
    write_tet_mesh(m, tube->out);
    std::cerr << "generate: " << m.num_vertices() << " vertices, " << m.num_tets() << " tets -> " << tube->out << "\n";
  });

  struct CookOpts {
    int cells = 16;
    double thickness = 1;
    int label = 1;
    std::string out;
  };
  auto cook = std::make_shared<CookOpts>();
  auto* c = gen->add_subcommand(
      "cook", "Cook's membrane: the trapezoid (0,0) (48,44) (48,60) (0,44), one layer thick (clamped edge x = 0 tagged 18, "
              "loaded edge x = 48 tagged 19, the rest 1)");
  c->add_option("--cells", cook->cells, "Cells along each side of the trapezoid (N x N x 1)")->capture_default_str();
  c->add_option("--thickness", cook->thickness, "Thickness along z")->capture_default_str();
  c->add_option("--label", cook->label, "Region label of every tet")->capture_default_str();
  c->add_option("-o,--output", cook->out, "Output mesh (format by extension)")->required();
  c->callback([cook] {
    TetMesh m = make_cook_membrane(cook->cells, cook->thickness, cook->label);
    write_tet_mesh(m, cook->out);
    std::cerr << "generate: " << m.num_vertices() << " vertices, " << m.num_tets() << " tets -> " << cook->out << "\n";
  });
}

}  // namespace incise::cli

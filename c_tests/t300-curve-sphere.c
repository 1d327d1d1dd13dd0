/* The TetGen box with a spherical cavity, curved at p = 2..P (P = argv[1], default 5;
 * argv[2] TetGen's max volume, argv[3] icosphere subdivisions)
 * with a projector written in C: no invalid cell, every node on a sphere facet
 * on the sphere to 1e-10, and at p = 2 an independent det J check. */
#include "curve_checks.h"

int main(int argc, char **argv) {
  int max_order = argc > 1 ? atoi(argv[1]) : 5;
  double max_volume = argc > 2 ? atof(argv[2]) : 0.2;
  int subdivisions = argc > 3 ? atoi(argv[3]) : 2; /* of the icosphere */
  FixtureMesh m;
  CHECK(fixture_tetgen_sphere_box(subdivisions, 4, max_volume, &m) == 0, "TetGen failed");
  printf("TetGen sphere cavity: %zu vertices, %zu tets, %zu boundary triangles\n", m.n_vertices,
         m.n_cells, m.n_facets);
  jacobian_check_p2("sphere", &m, sphere_box_projector, 1);
  for (int p = 2; p <= max_order; ++p)
    curve_and_check("sphere", &m, sphere_box_projector, FIXTURE_SPHERE_TAG, dist_sphere, p);
  fixture_mesh_free(&m);
  return 0;
}

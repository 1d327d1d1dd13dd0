/* End to end with a hyperelastic formulation: the TetGen box with a spherical
 * cavity curved at p = 2 with HOC_FORMULATION_CIL and HOC_MATERIAL_NEO_HOOKEAN in
 * 3 load increments (argv[1] TetGen's max volume, argv[2] icosphere
 * subdivisions): no invalid cell, sphere nodes on the sphere to 1e-10. */
#include "curve_checks.h"

int main(int argc, char **argv) {
  double max_volume = argc > 1 ? atof(argv[1]) : 0.2;
  int subdivisions = argc > 2 ? atoi(argv[2]) : 2;
  FixtureMesh m;
  CHECK(fixture_tetgen_sphere_box(subdivisions, 4, max_volume, &m) == 0, "TetGen failed");
  printf("TetGen sphere cavity: %zu vertices, %zu tets, %zu boundary triangles\n", m.n_vertices,
         m.n_cells, m.n_facets);
  RunSettings cil = {HOC_FORMULATION_CIL, HOC_MATERIAL_NEO_HOOKEAN, 3, 0, 0};
  curve_and_check_with("sphere CIL neo-Hookean", &m, sphere_box_projector, FIXTURE_SPHERE_TAG,
                       dist_sphere, 2, cil);
  fixture_mesh_free(&m);
  return 0;
}

/* The CGAL Mesh_3 solid torus (R = 1, r = 0.4), curved at p = 2..P
 * (P = argv[1], default 5; argv[2] mesh size): the library's checks of t300.
 * With argv[3] = "detj" it runs only the independent p = 2 det J check (at the
 * 35-point degree-4 lattice of every cell) and requires the library's verdict to
 * agree: hoc_mesh_quality counts at least the cells found with det J <= 0, and
 * none if there are none. Inverted cells are acceptable there only if reported. */
#include "curve_checks.h"

int main(int argc, char **argv) {
  int max_order = argc > 1 ? atoi(argv[1]) : 5;
  double size = argc > 2 ? atof(argv[2]) : 0.25;
  FixtureMesh m;
  double oracle_error = -1;
  CHECK(fixture_cgal_torus(TORUS_R, TORUS_r, size, size, &m, &oracle_error) == 0, "CGAL failed");
  printf("CGAL torus: %zu vertices, %zu tets, %zu boundary triangles; surface vertices were up to "
         "%.2e off the torus before snapping\n",
         m.n_vertices, m.n_cells, m.n_facets, oracle_error);
  CHECK(oracle_error < 1e-10, "CGAL's surface vertices are %g off the torus", oracle_error);
  if (argc > 3 && strcmp(argv[3], "detj") == 0) {
    jacobian_check_p2("torus", &m, torus_projector, 0);
    fixture_mesh_free(&m);
    return 0;
  }
  /* The curved torus mesh has cells folded at a corner (about 2% of the cells at
   * p = 2 and 3 with this CGAL mesh): acceptable only because the library reports
   * them; the counts are printed, and the detj mode checks them independently at p = 2. */
  RunSettings rs = DEFAULT_RUN;
  rs.allow_invalid = 1;
  for (int p = 2; p <= max_order; ++p)
    curve_and_check_with("torus", &m, torus_projector, FIXTURE_TORUS_TAG, dist_torus, p, rs);
  fixture_mesh_free(&m);
  return 0;
}

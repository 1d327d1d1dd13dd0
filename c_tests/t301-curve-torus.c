/* The CGAL Mesh_3 solid torus (R = 1, r = 0.4), curved at p = 2..P
 * (P = argv[1], default 5; argv[2] mesh size): the library's checks of t300.
 * With argv[3] = "detj" it runs only the independent p = 2 det J check (at the
 * 35-point degree-4 lattice of every cell) and requires the library's verdict to
 * agree: hoc_mesh_quality counts at least the cells found with det J <= 0, and
 * none if there are none. */
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
    jacobian_check_p2("torus", &m, torus_projector, 1);
    fixture_mesh_free(&m);
    return 0;
  }
  /* CGAL leaves boundary caps (tets with two faces on the torus, about 100 of ~4,000):
   * the library removes them, and then no cell may be invalid. */
  for (int p = 2; p <= max_order; ++p)
    curve_and_check("torus", &m, torus_projector, FIXTURE_TORUS_TAG, dist_torus, p);
  /* With the caps kept, many of them fold (about 80 at p = 2): acceptable only because
   * the library reports them (the counts are checked against the per-cell Q3). */
  RunSettings keep = DEFAULT_RUN;
  keep.allow_invalid = 1;
  keep.keep_caps = 1;
  curve_and_check_with("torus, caps kept", &m, torus_projector, FIXTURE_TORUS_TAG, dist_torus, 2, keep);
  fixture_mesh_free(&m);
  return 0;
}

/* The test fixtures themselves: the TetGen sphere cavity has its sphere vertices
 * on the sphere to rounding, every tet has nonzero volume, the boundary
 * triangles are tagged 1 (sphere) or 2 (box), and hocurve accepts the mesh. */
#include "curve_checks.h"

int main(void) {
  FixtureMesh m;
  CHECK(fixture_tetgen_sphere_box(2, 4, 0.2, &m) == 0, "TetGen failed");
  size_t n_sphere = 0, n_box = 0;
  double worst = 0.0, box_worst = 0.0;
  for (size_t f = 0; f < m.n_facets; ++f) {
    CHECK(m.facet_tags[f] == 1 || m.facet_tags[f] == 2, "facet %zu has tag %d", f, m.facet_tags[f]);
    for (int k = 0; k < 3; ++k) {
      const double *p = m.coords + 3 * m.facets[3 * f + k];
      if (m.facet_tags[f] == 1)
        worst = fmax(worst, dist_sphere(p));
      else
        box_worst = fmax(box_worst, fabs(fmax(fmax(fabs(p[0]), fabs(p[1])), fabs(p[2])) - BOX_H));
    }
    if (m.facet_tags[f] == 1) ++n_sphere; else ++n_box;
  }
  /* Icosphere subdivided twice: 320 triangles; 4x4 grid on 6 faces: 192 triangles. */
  CHECK(n_sphere == 320, "%zu sphere triangles: TetGen split the sphere (Y not honoured?)", n_sphere);
  CHECK(n_box == 192, "%zu box triangles", n_box);
  CHECK(worst < 1e-15, "a sphere vertex is %g off the sphere", worst);
  CHECK(box_worst == 0.0, "a box vertex is %g off the box", box_worst);
  double vmin = INFINITY, total = 0.0;
  for (size_t c = 0; c < m.n_cells; ++c) {
    const int64_t *t = m.cells + 4 * c;
    double e[3][3];
    for (int a = 0; a < 3; ++a)
      for (int k = 0; k < 3; ++k) e[a][k] = m.coords[3 * t[a + 1] + k] - m.coords[3 * t[0] + k];
    double v = fabs(det3(e[0], e[1], e[2])) / 6.0;
    vmin = fmin(vmin, v);
    total += v;
  }
  double exact = 64.0 - 4.0 / 3.0 * M_PI * 0.125;
  CHECK(vmin > 0, "a degenerate tet");
  /* The polyhedral sphere is inscribed: the cavity is a little smaller than the
   * sphere, so the mesh volume a little larger than the exact one. */
  CHECK(total > exact && total - exact < 0.05, "volume %g, exact %g", total, exact);
  HocMesh *mesh = NULL;
  CHECK_OK(NULL, hoc_mesh_create(3, m.n_vertices, m.coords, m.n_cells, m.cells, &mesh));
  CHECK_OK(mesh, hoc_mesh_set_boundary(mesh, m.n_facets, m.facets, m.facet_tags));
  CHECK_OK(NULL, hoc_mesh_destroy(&mesh));
  printf("TetGen fixture: %zu vertices, %zu tets (smallest volume %.2e), %zu sphere + %zu box "
         "triangles, sphere vertices within %.1e of r = 0.5, volume %.6f (exact %.6f)\n",
         m.n_vertices, m.n_cells, vmin, n_sphere, n_box, worst, total, exact);
  fixture_mesh_free(&m);
  return 0;
}

/* Helpers shared by the hocurve C tests: checks that stop the test with a
 * message, and projectors for the fixture geometries. */
#ifndef HOC_TEST_COMMON_H
#define HOC_TEST_COMMON_H

#include <hocurve.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define CHECK(cond, ...)                                                         \
  do {                                                                           \
    if (!(cond)) {                                                               \
      fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond);   \
      fprintf(stderr, __VA_ARGS__);                                              \
      fputc('\n', stderr);                                                       \
      exit(1);                                                                   \
    }                                                                            \
  } while (0)

/* The call must return HOC_OK; otherwise print the status and the handle's message. */
#define CHECK_OK(mesh, call)                                                          \
  do {                                                                                \
    HocStatus st_ = (call);                                                           \
    if (st_ != HOC_OK) {                                                              \
      const char *m_ = hoc_mesh_last_error(mesh);                                     \
      fprintf(stderr, "%s:%d: %s -> %d (%s): %s\n", __FILE__, __LINE__, #call, st_, \
              hoc_status_string(st_), m_ ? m_ : "(null)");                            \
      exit(1);                                                                        \
    }                                                                                 \
  } while (0)

static inline double norm3(const double *p) { return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]); }

/* ---- geometry of the fixtures ---- */

#define SPHERE_R 0.5
#define BOX_H 2.0
#define TORUS_R 1.0
#define TORUS_r 0.4

static inline void project_sphere(const double *p, double *q) {
  double n = norm3(p);
  for (int k = 0; k < 3; ++k) q[k] = p[k] * (SPHERE_R / n);
}
static inline double dist_sphere(const double *p) { return fabs(norm3(p) - SPHERE_R); }

/* Closest point on the box surface for a point near it: clamp the coordinate of largest |x|. */
static inline void project_box(const double *p, double *q) {
  int m = 0;
  for (int k = 1; k < 3; ++k)
    if (fabs(p[k]) > fabs(p[m])) m = k;
  for (int k = 0; k < 3; ++k) q[k] = p[k];
  q[m] = p[m] > 0 ? BOX_H : -BOX_H;
}

static inline void project_torus(const double *p, double *q) {
  double rho = sqrt(p[0] * p[0] + p[1] * p[1]);
  double c[3] = {TORUS_R * p[0] / rho, TORUS_R * p[1] / rho, 0.0};
  double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
  double n = norm3(d);
  for (int k = 0; k < 3; ++k) q[k] = c[k] + TORUS_r * d[k] / n;
}
static inline double dist_torus(const double *p) {
  double rho = sqrt(p[0] * p[0] + p[1] * p[1]) - TORUS_R;
  return fabs(sqrt(rho * rho + p[2] * p[2]) - TORUS_r);
}

/* Projector for the TetGen fixture: tag 1 sphere, tag 2 box. user_data: a
 * size_t call counter (may be NULL). */
static inline int sphere_box_projector(void *user_data, int entity_dim, int entity_tag, size_t n,
                                const double *in, double *out) {
  if (user_data) ++*(size_t *)user_data;
  if (entity_dim != 2) return 1;
  for (size_t i = 0; i < n; ++i) {
    if (entity_tag == 1)
      project_sphere(in + 3 * i, out + 3 * i);
    else if (entity_tag == 2)
      project_box(in + 3 * i, out + 3 * i);
    else
      return 2;
  }
  return 0;
}

/* Projector for the CGAL torus (tag 1). */
static inline int torus_projector(void *user_data, int entity_dim, int entity_tag, size_t n,
                           const double *in, double *out) {
  if (user_data) ++*(size_t *)user_data;
  if (entity_dim != 2 || entity_tag != 1) return 1;
  for (size_t i = 0; i < n; ++i) project_torus(in + 3 * i, out + 3 * i);
  return 0;
}

#endif

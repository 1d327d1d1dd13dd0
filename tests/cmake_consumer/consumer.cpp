// Curve a coarse mesh of the unit disc through hocurve.hpp: an octagon cut
// into 8 triangles around the centre, its boundary projected onto the circle,
// at p = 3. Checks the version the build system saw, the node count, that
// every boundary node landed on the circle and that no cell is invalid.
#include <hocurve.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

static int failures = 0;
#define EXPECT(cond, ...)                                                   \
  do {                                                                      \
    if (!(cond)) {                                                          \
      std::fprintf(stderr, "consumer: %s failed: ", #cond);                 \
      std::fprintf(stderr, __VA_ARGS__);                                    \
      std::fputc('\n', stderr);                                             \
      ++failures;                                                           \
    }                                                                       \
  } while (0)

int main() {
  EXPECT(std::strcmp(hoc_version(), HOCURVE_EXPECTED_VERSION) == 0, "library %s, build system %s", hoc_version(),
         HOCURVE_EXPECTED_VERSION);

  const double pi = std::acos(-1.0);
  std::vector<double> coords = {0.0, 0.0};
  for (int i = 0; i < 8; ++i) {
    coords.push_back(std::cos(i * pi / 4));
    coords.push_back(std::sin(i * pi / 4));
  }
  std::vector<int64_t> cells, edges;
  std::vector<int32_t> tags;
  for (int64_t i = 0; i < 8; ++i) {
    int64_t a = 1 + i, b = 1 + (i + 1) % 8;
    cells.insert(cells.end(), {0, a, b});
    edges.insert(edges.end(), {a, b});
    tags.push_back(1);
  }

  try {
    hocurve::Mesh mesh(2, coords, cells);
    mesh.set_boundary(edges, tags);
    mesh.set_projector([](int, int, std::size_t n, const double *in, double *out) {
      for (std::size_t i = 0; i < n; ++i) {
        double r = std::hypot(in[2 * i], in[2 * i + 1]);
        out[2 * i] = in[2 * i] / r;
        out[2 * i + 1] = in[2 * i + 1] / r;
      }
      return 0;
    });
    mesh.set_order(3);
    mesh.run_increments(2);

    // p = 3: 9 vertices, 2 nodes on each of 16 edges, 1 inside each of 8 cells.
    EXPECT(mesh.node_count() == 49, "%zu nodes", mesh.node_count());
    std::vector<double> x = mesh.nodes();
    int on_circle = 0;
    for (std::size_t i = 0; i < x.size() / 2; ++i) {
      double r = std::hypot(x[2 * i], x[2 * i + 1]);
      if (r > 0.99) {
        EXPECT(std::fabs(r - 1.0) < 1e-12, "boundary node %zu at radius %.17g", i, r);
        ++on_circle;
      }
    }
    EXPECT(on_circle == 8 + 16, "%d nodes on the circle", on_circle);
    HocQuality q = mesh.quality();
    EXPECT(q.n_cells == 8 && q.n_invalid == 0 && q.min_q3 > 0.5, "%zu cells, %zu invalid, min Q3 %g", q.n_cells,
           q.n_invalid, q.min_q3);
    std::printf("hocurve %s: disc at p = 3, %zu nodes, %d on the circle, min Q3 %.3f\n", hoc_version(),
                mesh.node_count(), on_circle, q.min_q3);
  } catch (const hocurve::Error &e) {
    std::fprintf(stderr, "consumer: %s\n", e.what());
    return 1;
  }
  return failures == 0 ? 0 : 1;
}

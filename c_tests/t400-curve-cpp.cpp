// The C++ wrapper end to end: RAII and moves, a lambda projector with captured
// state, errors as hocurve::Error with status and message, vector sizes checked
// before anything is read, the library's default increments, and an exception
// thrown inside the projector coming back out of run_increments.
#include <hocurve.hpp>

#include "curve_checks.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <vector>

#define REQUIRE(cond, ...)                                                     \
  do {                                                                         \
    if (!(cond)) {                                                             \
      std::fprintf(stderr, "%s:%d: REQUIRE(%s) failed: ", __FILE__, __LINE__, #cond); \
      std::fprintf(stderr, __VA_ARGS__);                                       \
      std::fputc('\n', stderr);                                                \
      std::exit(1);                                                            \
    }                                                                          \
  } while (0)

struct Boom : std::runtime_error {
  Boom() : std::runtime_error("boom") {}
};

int main() {
  FixtureMesh fx;
  REQUIRE(fixture_tetgen_sphere_box(1, 2, 1.0, &fx) == 0, "TetGen failed");
  std::vector<double> coords(fx.coords, fx.coords + 3 * fx.n_vertices);
  std::vector<int64_t> cells(fx.cells, fx.cells + 4 * fx.n_cells);
  std::vector<int64_t> facets(fx.facets, fx.facets + 3 * fx.n_facets);
  std::vector<int32_t> tags(fx.facet_tags, fx.facet_tags + fx.n_facets);

  // Errors carry the status and the message.
  try {
    hocurve::Mesh bad(3, coords, std::vector<int64_t>{});
    REQUIRE(false, "a mesh without cells was accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_MESH, "status %d", e.status());
    REQUIRE(!e.message().empty(), "a failed create has no message");
    std::printf("no cells: %s\n", e.what());
  }

  // A mesh spread over MPI processes needs a library built with MPI (this one is not).
  try {
    hocurve::Mesh::distributed(0, 3, coords, std::vector<int64_t>(fx.n_vertices, 0), cells);
    REQUIRE(false, "a distributed mesh without MPI");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
    REQUIRE(e.message().find("without MPI") != std::string::npos, "%s", e.what());
  }
  try {
    hocurve::Mesh::distributed(0, 3, coords, std::vector<int64_t>(2, 0), cells);
    REQUIRE(false, "two global ids accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
  }

  // Vector sizes that do not fit: refused before a value is read.
  try {
    hocurve::Mesh bad(3, std::vector<double>(13, 0.0), cells);
    REQUIRE(false, "13 coordinates accepted in 3D");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
    std::printf("13 coordinates: %s\n", e.what());
  }
  try {
    hocurve::Mesh bad(3, coords, std::vector<int64_t>(cells.begin(), cells.end() - 1));
    REQUIRE(false, "a cell with 3 vertices accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
  }

  hocurve::Mesh mesh(3, coords, cells);
  const std::vector<int32_t> more_tags(tags.size() + 1, 1);
  try {
    mesh.set_boundary(facets, more_tags);  // one tag more than facets
    REQUIRE(false, "%zu tags for %zu facets accepted", more_tags.size(), facets.size() / 3);
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
    std::printf("set_boundary: %s\n", e.what());
  }
  try {
    mesh.set_feature_edges(std::vector<int64_t>{0, 1, 2}, std::vector<int32_t>{1});
    REQUIRE(false, "3 edge ids for 1 edge accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
  }
  try {
    mesh.set_order(11);
    REQUIRE(false, "order 11 accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
    REQUIRE(!e.message().empty(), "no message");
    std::printf("order 11: %s\n", e.what());
  }
  try {
    mesh.set_fibres(std::vector<double>(3 * (fx.n_cells + 1), 1.0));
    REQUIRE(false, "fibres for too many cells accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_BUFFER_SIZE, "status %d", e.status());
    std::printf("fibres: %s\n", e.what());
  }
  try {
    mesh.set_newton(1e-6, -1);
    REQUIRE(false, "Newton max_iterations -1 accepted");
  } catch (const hocurve::Error &e) {
    REQUIRE(e.status() == HOC_ERROR_INVALID_ARGUMENT, "status %d", e.status());
    std::printf("newton: %s\n", e.what());
  }
  mesh.set_fibres(std::vector<double>(3 * fx.n_cells, 1.0));
  mesh.reset_fibres();
  mesh.set_newton(1e-6, 20);
  mesh.set_tangent_first(false);

  std::size_t calls = 0;
  const double R = 0.5;
  mesh.set_boundary(facets, tags);
  mesh.set_projector([&calls, R](int dim, int tag, std::size_t n, const double *in, double *out) {
    ++calls;
    if (dim != 2) return 1;
    for (std::size_t i = 0; i < n; ++i) {
      const double *p = in + 3 * i;
      double *q = out + 3 * i;
      if (tag == 1) {
        double s = R / std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        for (int k = 0; k < 3; ++k) q[k] = s * p[k];
      } else {
        std::memcpy(q, p, 3 * sizeof(double));  // the box is flat
      }
    }
    return 0;
  });
  mesh.set_order(4);
  std::vector<double> straight = mesh.nodes();

  // An exception in the projector stops the run and comes back out; nothing moved.
  mesh.set_projector([](int, int, std::size_t, const double *, double *) -> int { throw Boom(); });
  try {
    mesh.run_increments(1);
    REQUIRE(false, "the run survived a throwing projector");
  } catch (const Boom &) {
    std::printf("projector exception rethrown by run_increments\n");
  }
  REQUIRE(mesh.nodes() == straight, "a failed run moved nodes");

  // Move the handle before setting the real projector and running: callbacks follow.
  hocurve::Mesh moved(std::move(mesh));
  REQUIRE(mesh.get() == nullptr, "moved-from mesh still owns a handle");
  moved.set_projector([&calls, R](int dim, int tag, std::size_t n, const double *in, double *out) {
    ++calls;
    if (dim != 2) return 1;
    for (std::size_t i = 0; i < n; ++i) {
      const double *p = in + 3 * i;
      double s = tag == 1 ? R / std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) : 1.0;
      for (int k = 0; k < 3; ++k) out[3 * i + k] = s * p[k];
    }
    return 0;
  });
  hocurve::Mesh target(3, coords, cells);
  target = std::move(moved);  // move assignment destroys target's old handle
  target.run_increments(1);
  REQUIRE(calls > 0, "projector never called");
  HocQuality q = target.quality();
  REQUIRE(q.n_invalid == 0, "%zu invalid cells", q.n_invalid);
  HocTimings t = target.timings();
  REQUIRE(t.total > 0 && t.solve > 0 && t.place_boundary > 0 && t.solve + t.place_boundary <= t.total,
          "timings: total %g, solve %g, placement %g", t.total, t.solve, t.place_boundary);
  REQUIRE(q.n_cells == cells.size() / 4, "n_cells %zu", q.n_cells);
  // Curved valid as first made: not made again with the caps kept.
  REQUIRE(!target.caps_kept_after(), "made again with the caps kept after: %s", target.caps_kept_after()->c_str());

  std::vector<double> x = target.nodes();
  auto [n_cells, npc] = target.cell_count();
  REQUIRE(npc == 35, "p=4 tet has %zu nodes", npc);
  std::vector<int64_t> conn = target.cells(HOC_ORDERING_VTK);
  REQUIRE(conn.size() == n_cells * npc, "connectivity size");
  // Nodes on sphere facets (found on the straight mesh) are on the sphere.
  std::vector<int64_t> native = target.cells();
  std::vector<unsigned char> on(x.size() / 3);
  std::size_t n_boundary = 0;
  std::size_t moved_nodes = mark_surface_nodes(&fx, 1, n_cells, npc, native.data(), straight.data(),
                                               on.size(), on.data(), &n_boundary);
  REQUIRE(n_boundary == fx.n_facets, "%zu boundary faces, %zu given", n_boundary, fx.n_facets);
  REQUIRE(target.input_cells().size() == n_cells, "one input cell per cell");
  {
    // A whole mesh is its own global numbering, all on process 0.
    auto g = target.global_nodes();
    REQUIRE(g.ids.size() == target.node_count(), "one global id per node");
    for (std::size_t i = 0; i < g.ids.size(); i++)
      REQUIRE(g.ids[i] == static_cast<int64_t>(i) && g.owners[i] == 0, "node %zu", i);
  }
  double worst = 0.0;
  for (std::size_t i = 0; i < on.size(); ++i)
    if (on[i]) worst = std::fmax(worst, dist_sphere(&x[3 * i]));
  REQUIRE(moved_nodes > 0 && worst < 1e-10, "%zu sphere nodes, worst %g", moved_nodes, worst);
  // run_increments() takes the library's default number of increments.
  {
    hocurve::Mesh d(3, coords, cells);
    d.set_boundary(facets, tags);
    d.set_projector([](int, int tag, std::size_t n, const double *in, double *out) {
      return sphere_box_projector(nullptr, 2, tag, n, in, out);
    });
    d.set_order(2);
    d.set_adaptive_stepping(0);
    d.run_increments();
    REQUIRE(d.load_fractions().size() == static_cast<std::size_t>(HOC_DEFAULT_INCREMENTS),
            "run_increments() took %zu increments, the default is %d", d.load_fractions().size(),
            HOC_DEFAULT_INCREMENTS);
  }
  std::vector<double> q3 = target.cell_quality(3);
  REQUIRE(q3.size() == n_cells, "cell_quality size");
  std::printf("hocurve %s via C++: %zu cells, p=4, %zu nodes on the sphere within %.1e, min Q3 %.3f, "
              "%zu projector calls\n",
              hocurve::version().c_str(), n_cells, moved_nodes, worst, q.min_q3, calls);
  fixture_mesh_free(&fx);
  return 0;
}

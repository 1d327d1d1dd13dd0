// distributed.c through the C++ wrapper (hocurve::Mesh::distributed): each
// MPI process gives its own share of a mesh with its own projector, curves it
// with the others and writes what its mesh then holds.
//
//   mpirun -np N distributed_cpp DIR ORDER OPTIMIZE FAIL_RANK
//
// Same input (DIR/part.R.txt) and output (DIR/out.R.txt) as distributed.c,
// without the report's figures.
#include <mpi.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "hocurve.hpp"

int main(int argc, char **argv) {
  int provided, rank;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_SERIALIZED, &provided);
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  if (argc != 5) MPI_Abort(MPI_COMM_WORLD, 2);
  const std::string dir = argv[1];
  const int order = std::stoi(argv[2]), optimize = std::stoi(argv[3]), fail_rank = std::stoi(argv[4]);
  std::ifstream in(dir + "/part." + std::to_string(rank) + ".txt");
  int dim, nv, nc, nf, ns;
  in >> dim >> nv >> nc >> nf >> ns;
  std::vector<int64_t> ids(nv), cells(nc * (dim + 1)), facets(nf * dim);
  std::vector<double> coords(nv * dim);
  std::vector<int32_t> tags(nf);
  for (int i = 0; i < nv; i++) {
    in >> ids[i];
    for (int j = 0; j < dim; j++) in >> coords[i * dim + j];
  }
  for (auto &v : cells) in >> v;
  for (int i = 0; i < nf; i++) {
    for (int j = 0; j < dim; j++) in >> facets[i * dim + j];
    in >> tags[i];
  }
  int shape_tag;
  double c[4];
  in >> shape_tag >> c[0] >> c[1] >> c[2] >> c[3];
  if (!in) MPI_Abort(MPI_COMM_WORLD, 2);

  std::FILE *o = std::fopen((dir + "/out." + std::to_string(rank) + ".txt").c_str(), "w");
  try {
    auto mesh = hocurve::Mesh::distributed(MPI_Comm_c2f(MPI_COMM_WORLD), dim, coords, ids, cells);
    mesh.set_boundary(facets, tags);
    const bool failing = rank == fail_rank;
    mesh.set_projector([&](int, int tag, std::size_t n, const double *x, double *out) {
      if (failing) return 7;
      if (tag != shape_tag) return 1;
      for (std::size_t i = 0; i < n; i++) {
        double d = 0.0;
        for (int j = 0; j < dim; j++) d += (x[i * dim + j] - c[j]) * (x[i * dim + j] - c[j]);
        d = std::sqrt(d);
        for (int j = 0; j < dim; j++) out[i * dim + j] = c[j] + c[3] * (x[i * dim + j] - c[j]) / d;
      }
      return 0;
    });
    mesh.set_order(order);
    mesh.set_optimize(optimize != 0);
    const auto before = mesh.nodes();
    try {
      mesh.run_increments(HOC_DEFAULT_INCREMENTS);
    } catch (const hocurve::Error &e) {
      std::fprintf(o, "%d\n%s\n%d\n", e.status(), e.message().c_str(), mesh.nodes() == before);
      std::fclose(o);
      MPI_Finalize();
      return 0;
    }
    const HocQuality q = mesh.quality();
    const auto count = mesh.cell_count();
    const auto nodes = mesh.nodes();
    const auto xyz = mesh.nodes(HOC_ORDERING_GMSH);
    const auto conn = mesh.cells(HOC_ORDERING_GMSH);
    const auto global = mesh.global_nodes();
    std::fprintf(o, "%d\n\n0\n%zu %zu %zu %.17g %zu %zu\n", HOC_OK, global.ids.size(), count.first, count.second,
                 q.min_q3, q.n_invalid, q.n_certified_invalid);
    for (std::size_t i = 0; i < global.ids.size(); i++) {
      std::fprintf(o, "%ld %d", static_cast<long>(global.ids[i]), global.owners[i]);
      for (int j = 0; j < dim; j++) std::fprintf(o, " %.17g", nodes[i * dim + j]);
      std::fprintf(o, "\n");
    }
    for (std::size_t e = 0; e < count.first; e++) {
      const int64_t *cell = &conn[e * count.second];
      for (int a = 0; a <= dim; a++) std::fprintf(o, "%ld ", cell[a] < nv ? static_cast<long>(ids[cell[a]]) : -1L);
      for (std::size_t a = 0; a < count.second; a++)
        for (int j = 0; j < dim; j++) std::fprintf(o, " %.17g", xyz[cell[a] * dim + j]);
      std::fprintf(o, "\n");
    }
  } catch (const hocurve::Error &e) {
    std::fprintf(stderr, "rank %d: %s\n", rank, e.what());
    MPI_Abort(MPI_COMM_WORLD, 1);
  }
  std::fclose(o);
  MPI_Finalize();
  return 0;
}

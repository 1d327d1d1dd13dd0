// CGAL Mesh_3 mesher for the robustness corpus (scripts/gen_corpus.py builds
// and runs it):
//
//   corpus_cgal sphere B r      facet_size facet_distance cell_size edge_size OUT.txt
//   corpus_cgal torus  B R r    facet_size facet_distance cell_size edge_size OUT.txt
//
// meshes the box [-B,B]^3 minus a cavity (sphere of radius r, or torus of
// radii R, r about z, centred at the origin) as an implicit labelled domain:
// label 0 outside the box, 1 in the domain, 2 in the cavity, so the surface
// patches are (0,1) = box and (1,2) = cavity. The box's 12 edges are given as
// polyline features, protected by Mesh_3, so its edges and corners are exact.
// Surface points come from bisection on the labels (relative error bound
// 1e-12); each cavity vertex is then snapped onto the exact surface by its
// closed-form closest point, each box vertex onto the box planes, and the
// largest distance moved is printed as "max_surface_error X".
//
// Output (text): "nv nt nf", nv lines "x y z", nt lines "a b c d" (0-based
// vertices of the domain's tetrahedra, label 1 only), nf lines "a b c tag"
// (boundary triangles; tag 1 = cavity, 2 = box).
//
// Deterministic: the domain's random generator is CGAL::Random(0), Mesh_3 runs
// sequentially, perturbation and exudation run without their default time
// limit (the refinement's wall time, which made the mesh differ run to run),
// and the output numbers vertices in the order the cells are visited.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Labeled_mesh_domain_3.h>
#include <CGAL/Mesh_complex_3_in_triangulation_3.h>
#include <CGAL/Mesh_criteria_3.h>
#include <CGAL/Mesh_domain_with_polyline_features_3.h>
#include <CGAL/Mesh_triangulation_3.h>
#include <CGAL/make_mesh_3.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <vector>

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Point = K::Point_3;
using Base_domain = CGAL::Labeled_mesh_domain_3<K>;
using Domain = CGAL::Mesh_domain_with_polyline_features_3<Base_domain>;
using Tr = CGAL::Mesh_triangulation_3<Domain, CGAL::Default, CGAL::Sequential_tag>::type;
using C3t3 = CGAL::Mesh_complex_3_in_triangulation_3<Tr, Domain::Corner_index, Domain::Curve_index>;
using Criteria = CGAL::Mesh_criteria_3<Tr>;

namespace {

constexpr int CAVITY_TAG = 1, BOX_TAG = 2;

struct Shape {
  bool torus = false;
  double B = 1, R = 0, r = 0.5;

  bool in_cavity(double x, double y, double z) const {
    if (!torus) return x * x + y * y + z * z < r * r;
    double rho = std::sqrt(x * x + y * y) - R;
    return rho * rho + z * z < r * r;
  }
  int label(const Point &p) const {
    double x = p.x(), y = p.y(), z = p.z();
    if (std::fabs(x) > B || std::fabs(y) > B || std::fabs(z) > B) return 0;
    return in_cavity(x, y, z) ? 2 : 1;
  }
  // Closest point on the cavity's surface (p away from the centre / core circle).
  void project(double *p) const {
    if (!torus) {
      double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      for (int k = 0; k < 3; ++k) p[k] *= r / n;
      return;
    }
    double rho = std::sqrt(p[0] * p[0] + p[1] * p[1]);
    double c[3] = {R * p[0] / rho, R * p[1] / rho, 0.0};
    double d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    double n = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; k < 3; ++k) p[k] = c[k] + r * d[k] / n;
  }
};

double arg(char **argv, int i) { return std::strtod(argv[i], nullptr); }

}  // namespace

int main(int argc, char **argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: corpus_cgal sphere|torus B [R] r facet_size facet_distance cell_size edge_size OUT\n");
    return 1;
  }
  Shape s;
  int i = 2;
  if (std::strcmp(argv[1], "sphere") == 0 && argc == 9) {
    s.B = arg(argv, i++);
    s.r = arg(argv, i++);
  } else if (std::strcmp(argv[1], "torus") == 0 && argc == 10) {
    s.torus = true;
    s.B = arg(argv, i++);
    s.R = arg(argv, i++);
    s.r = arg(argv, i++);
  } else {
    std::fprintf(stderr, "corpus_cgal: bad arguments\n");
    return 1;
  }
  const double facet_size = arg(argv, i++), facet_distance = arg(argv, i++), cell_size = arg(argv, i++),
               edge_size = arg(argv, i++);
  const char *out_path = argv[i];
  namespace params = CGAL::parameters;

  const double B = s.B, m = 0.1 * B;
  std::function<int(const Point &)> f = [s](const Point &p) { return s.label(p); };
  Domain domain(f, CGAL::Bbox_3(-B - m, -B - m, -B - m, B + m, B + m, B + m), K::FT(1e-12));
  // The box's 12 edges.
  std::vector<std::vector<Point>> edges;
  for (int axis = 0; axis < 3; ++axis)
    for (int a = -1; a <= 1; a += 2)
      for (int b = -1; b <= 1; b += 2) {
        double p[3], q[3];
        p[axis] = -B;
        q[axis] = B;
        p[(axis + 1) % 3] = q[(axis + 1) % 3] = a * B;
        p[(axis + 2) % 3] = q[(axis + 2) % 3] = b * B;
        edges.push_back({Point(p[0], p[1], p[2]), Point(q[0], q[1], q[2])});
      }
  domain.add_features(edges.begin(), edges.end());
  // Facets of size facet_size near the cavity, growing to cell_size away from it.
  struct FacetSize {
    Shape s;
    double near, far;
    K::FT operator()(const Point &p, int, const Domain::Index &) const {
      double q[3] = {p.x(), p.y(), p.z()};
      double before[3] = {q[0], q[1], q[2]};
      s.project(q);
      double d = std::sqrt((q[0] - before[0]) * (q[0] - before[0]) + (q[1] - before[1]) * (q[1] - before[1]) +
                           (q[2] - before[2]) * (q[2] - before[2]));
      return std::fmin(far, near + 0.5 * d);
    }
  };
  Criteria criteria(params::edge_size = edge_size, params::facet_angle = 25,
                    params::facet_size = FacetSize{s, facet_size, cell_size},
                    params::facet_distance = facet_distance, params::cell_radius_edge_ratio = 2.5,
                    params::cell_size = cell_size);
  // Perturbation and exudation without a time limit: by default Mesh_3 gives
  // each the refinement's wall time, which makes the mesh differ run to run.
  C3t3 c3t3 = CGAL::make_mesh_3<C3t3>(domain, criteria, params::perturb(params::time_limit = 0, params::sliver_bound = 10),
                                      params::exude(params::time_limit = 0, params::sliver_bound = 10));

  std::map<Tr::Vertex_handle, long> index;
  std::vector<double> coords;
  auto id = [&](Tr::Vertex_handle v) {
    auto it = index.find(v);
    if (it != index.end()) return it->second;
    long k = (long)index.size();
    index[v] = k;
    const Point p = v->point().point();
    coords.push_back(p.x());
    coords.push_back(p.y());
    coords.push_back(p.z());
    return k;
  };
  // Number vertices by a deterministic traversal: cells in the complex's order.
  std::vector<long> tets;
  for (auto c = c3t3.cells_in_complex_begin(); c != c3t3.cells_in_complex_end(); ++c) {
    if (c3t3.subdomain_index(c) != 1) continue;
    for (int k = 0; k < 4; ++k) tets.push_back(id(c->vertex(k)));
  }
  std::vector<long> tris;
  std::vector<int> tags;
  for (auto fc = c3t3.facets_in_complex_begin(); fc != c3t3.facets_in_complex_end(); ++fc) {
    auto patch = c3t3.surface_patch_index(*fc);
    int a = patch.first, b = patch.second;
    if (a != 1 && b != 1) continue;  // cannot happen: every surface bounds the domain
    int tag = (a == 2 || b == 2) ? CAVITY_TAG : BOX_TAG;
    for (int k = 1; k <= 3; ++k) {
      auto v = fc->first->vertex((fc->second + k) & 3);
      auto it = index.find(v);
      if (it == index.end()) {
        std::fprintf(stderr, "corpus_cgal: a boundary facet has a vertex in no domain cell\n");
        return 2;
      }
      tris.push_back(it->second);
    }
    tags.push_back(tag);
  }
  // Snap: cavity vertices onto the surface, box vertices onto the planes.
  std::vector<char> on(index.size(), 0);
  for (size_t t = 0; t < tags.size(); ++t)
    for (int k = 0; k < 3; ++k) on[(size_t)tris[3 * t + k]] |= (char)tags[t];
  double worst = 0;
  for (size_t v = 0; v < on.size(); ++v) {
    double *p = &coords[3 * v];
    double before[3] = {p[0], p[1], p[2]};
    if (on[v] & CAVITY_TAG) s.project(p);
    if (on[v] & BOX_TAG)
      for (int k = 0; k < 3; ++k)
        if (std::fabs(std::fabs(p[k]) - B) < 1e-6 * B) p[k] = p[k] > 0 ? B : -B;
    double d = std::sqrt((p[0] - before[0]) * (p[0] - before[0]) + (p[1] - before[1]) * (p[1] - before[1]) +
                         (p[2] - before[2]) * (p[2] - before[2]));
    worst = std::fmax(worst, d);
  }
  if (tets.empty() || tags.empty()) {
    std::fprintf(stderr, "corpus_cgal: empty mesh\n");
    return 2;
  }
  FILE *o = std::fopen(out_path, "w");
  if (!o) {
    std::perror(out_path);
    return 3;
  }
  std::fprintf(o, "%zu %zu %zu\n", index.size(), tets.size() / 4, tags.size());
  for (size_t v = 0; v < index.size(); ++v)
    std::fprintf(o, "%.17g %.17g %.17g\n", coords[3 * v], coords[3 * v + 1], coords[3 * v + 2]);
  for (size_t t = 0; t < tets.size(); t += 4)
    std::fprintf(o, "%ld %ld %ld %ld\n", tets[t], tets[t + 1], tets[t + 2], tets[t + 3]);
  for (size_t t = 0; t < tags.size(); ++t)
    std::fprintf(o, "%ld %ld %ld %d\n", tris[3 * t], tris[3 * t + 1], tris[3 * t + 2], tags[t]);
  std::fclose(o);
  std::printf("max_surface_error %.3e\n", worst);
  return 0;
}

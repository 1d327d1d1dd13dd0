// Tests of the gmsh/OpenCASCADE -> hocurve pipeline.
//
//   occt_test write DIR                       write part.step, sphere-torus.step, plate.step, naca.step, sphere.step
//   occt_test check MODEL H PMIN PMAX [N [FALL]]  curve at p = PMIN..PMAX and check (table on stdout);
//                                             N elements per 2π of curvature (default 12), FALL the
//                                             fall of the between-node distance asked (default 100)
//   occt_test seam                            the placement on facets across periodic seams and at
//                                             poles (sphere, torus, cylinder, cone built in the test)
// OCCT_PLACEMENT=closest uses closest-point projection instead of the
// parametric placement (occt_pipeline.hpp), for comparison; OCCT_DEBUG=1
// prints the between-node distance per CAD entity and the feature-edge
// nodes' distance per (curve, adjacent face), and what the repair changed.
//   occt_test fail MODEL H                    a projector failing on one CAD entity
//
// `check`: no invalid cell; every high-order node classified on a CAD face
// (edge) lies on it to 1e-8 of the model size by gmsh::model::getClosestPoint,
// nodes on a feature edge on its CAD curve and on every CAD face adjacent to
// that curve (getAdjacencies; two faces, one for a seam); nodes of facets on planar CAD
// faces stay in the facet's plane; boundary vertices do not move. It also samples the
// curved boundary between the nodes and prints the largest distance to CAD;
// with the parametric placement that distance must fall at every order and
// by at least FALL times from PMIN to PMAX when PMAX >= PMIN + 3; no node may
// fall back to closest point. The boundary is classified on the mesh after the
// run, whose repair may flip, remove and split cells and so renumber the nodes.
// `seam`: on a sphere, a torus, a cylinder and a cone made with
// gmsh::model::occ and meshed at h = 0.25..0.3, every boundary facet has
// nodes of order 4 placed by the parametric placement; none may fall back to
// closest point, every one lies on its CAD entity, and each is within a tenth
// of its facet's diameter of the closest point to its straight position. Facets
// straddling the seam occur on all four, facets at a pole on the sphere and the
// cone; the test requires them. Before the seam and pole handling, the sphere's
// facets at a pole were unwrapped relative to the pole's arbitrary longitude,
// put nodes 0.6 of the facet away (or fell back), and the ball curved at p = 2
// had an inverted cell. Last, the closest-point fallback is checked on
// points just off the boundary of sphere-torus's faces, where gmsh 4.8's
// getClosestPoint answers the far side of the torus.
// `fail`: the run ends with HOC_ERROR_PROJECTION and the nodes are unchanged.
#include "occt_models.hpp"
#include "occt_pipeline.hpp"

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <set>

namespace {

#define CHECK(cond, ...)                                                       \
  do {                                                                         \
    if (!(cond)) {                                                             \
      std::fprintf(stderr, "%s:%d: CHECK(%s) failed: ", __FILE__, __LINE__, #cond); \
      std::fprintf(stderr, __VA_ARGS__);                                       \
      std::fputc('\n', stderr);                                                \
      std::exit(1);                                                            \
    }                                                                          \
  } while (0)

using Key = std::array<int64_t, 3>;

// Distances from points (dim coordinates each) to gmsh entity (edim, etag).
std::vector<double> cad_distance(int dim, int edim, int etag, const std::vector<double> &pts) {
  const std::size_t n = pts.size() / dim;
  std::vector<double> xyz(3 * n, 0.0), cl, uv, d(n);
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < dim; ++k) xyz[3 * i + k] = pts[dim * i + k];
  gmsh::model::getClosestPoint(edim, etag, xyz, cl, uv);
  for (std::size_t i = 0; i < n; ++i) {
    double s = 0;
    for (int k = 0; k < 3; ++k) s += (cl[3 * i + k] - xyz[3 * i + k]) * (cl[3 * i + k] - xyz[3 * i + k]);
    d[i] = std::sqrt(s);
  }
  return d;
}

// Solve the dense n x n system A x = b (row-major) by Gaussian elimination with pivoting.
std::vector<double> solve_dense(std::vector<double> a, std::vector<double> b, int n, int nrhs) {
  for (int c = 0; c < n; ++c) {
    int piv = c;
    for (int r = c + 1; r < n; ++r)
      if (std::fabs(a[r * n + c]) > std::fabs(a[piv * n + c])) piv = r;
    for (int k = 0; k < n; ++k) std::swap(a[c * n + k], a[piv * n + k]);
    for (int k = 0; k < nrhs; ++k) std::swap(b[c * nrhs + k], b[piv * nrhs + k]);
    for (int r = c + 1; r < n; ++r) {
      double f = a[r * n + c] / a[c * n + c];
      for (int k = c; k < n; ++k) a[r * n + k] -= f * a[c * n + k];
      for (int k = 0; k < nrhs; ++k) b[r * nrhs + k] -= f * b[c * nrhs + k];
    }
  }
  for (int c = n - 1; c >= 0; --c)
    for (int k = 0; k < nrhs; ++k) {
      double s = b[c * nrhs + k];
      for (int j = c + 1; j < n; ++j) s -= a[c * n + j] * b[j * nrhs + k];
      b[c * nrhs + k] = s / a[c * n + c];
    }
  return b;
}

// Monomials s^a t^b, a + b <= p (t ignored, b = 0, for edges).
std::vector<double> monomials(int p, bool tri, double s, double t) {
  std::vector<double> m;
  for (int a = 0; a <= p; ++a)
    for (int b = 0; b <= (tri ? p - a : 0); ++b) m.push_back(std::pow(s, a) * std::pow(t, b));
  return m;
}

struct Row {
  int p;
  std::size_t cells, nodes, checked, planar;
  double node_dist;
  double edge_face_dist;  // feature-edge nodes to the CAD faces adjacent to their curve (-1 in 2D)
  std::size_t edge_nodes, edge_face_checks;
  double sample_dist, min_q3;
  std::size_t invalid;
  double secs;
  std::size_t fallbacks, projected;
};

occt::Placement placement() {
  const char *e = std::getenv("OCCT_PLACEMENT");
  return e && std::string(e) == "closest" ? occt::Placement::Closest : occt::Placement::Parametric;
}

// One facet of the curved mesh: its vertices and the cell nodes on it.
struct Facet {
  int tag;                      // CAD surface (3D) / curve (2D)
  int64_t v[3];                 // vertices (v[2] unused in 2D)
  std::vector<int64_t> nodes;   // every node on it, vertices included
  std::vector<std::array<double, 2>> st;  // each node's (s, t): its barycentric coordinates of v[1], v[2]
};

// Curve `lm` at order p (`optimize` false: without the optimisation stage)
// and check its boundary against the CAD.
Row curve_and_check(const occt::LinearMesh &lm, int p, bool optimize = true) {
  const int dim = lm.dim, nv = dim + 1;
  const double tol = 1e-8 * lm.size;
  occt::Projector proj;
  proj.placement = placement();
  hocurve::Mesh mesh = occt::make_mesh(lm, proj);
  mesh.set_threads(2);
  mesh.set_order(p);
  mesh.set_optimize(optimize);
  // The straight mesh before the run. Its repair may flip, remove and split
  // cells (new vertices appended, the input ones kept, boundary facets
  // unchanged), which renumbers the high-order nodes: the boundary is
  // classified on the mesh after the run, with the reference node
  // coordinates and the boundary vertices' positions taken from this one.
  const std::size_t npc = mesh.cell_count().second;
  const std::vector<double> x0 = mesh.nodes();
  const std::vector<int64_t> cells0 = mesh.cells(HOC_ORDERING_NATIVE);
  const std::size_t n_cells0 = cells0.size() / npc;

  // Boundary facets and feature edges of the linear mesh, by sorted vertices.
  std::map<Key, int> facet_tag, feature;
  std::map<int64_t, std::set<int>> vertex_tags;
  for (std::size_t f = 0; f < lm.facet_tags.size(); ++f) {
    const int64_t *v = &lm.facets[dim * f];
    facet_tag[occt::detail::sorted(v[0], v[1], dim == 3 ? v[2] : -1)] = lm.facet_tags[f];
    for (int i = 0; i < dim; ++i) vertex_tags[v[i]].insert(lm.facet_tags[f]);
  }
  for (std::size_t e = 0; e < lm.edge_tags.size(); ++e)
    feature[occt::detail::sorted(-1, lm.edges[2 * e], lm.edges[2 * e + 1])] = lm.edge_tags[e];
  auto face_key = [&](const int64_t *c, int omit) {
    int64_t f[3] = {-1, -1, -1};
    int j = 0;
    for (int i = 0; i < nv; ++i)
      if (i != omit) f[j++] = c[i];
    return occt::detail::sorted(f[0], f[1], f[2]);
  };

  // Barycentric coordinates of node a of cell c in the straight cell.
  auto bary = [&](const int64_t *c, int64_t node, double *lam) {
    const double *X[4];
    for (int i = 0; i < nv; ++i) X[i] = &x0[dim * c[i]];
    const double *x = &x0[dim * node];
    if (dim == 2) {
      double d = (X[1][0] - X[0][0]) * (X[2][1] - X[0][1]) - (X[2][0] - X[0][0]) * (X[1][1] - X[0][1]);
      lam[1] = ((x[0] - X[0][0]) * (X[2][1] - X[0][1]) - (X[2][0] - X[0][0]) * (x[1] - X[0][1])) / d;
      lam[2] = ((X[1][0] - X[0][0]) * (x[1] - X[0][1]) - (x[0] - X[0][0]) * (X[1][1] - X[0][1])) / d;
      lam[0] = 1 - lam[1] - lam[2];
      return;
    }
    auto det3 = [](const double *a, const double *b, const double *c2) {
      return a[0] * (b[1] * c2[2] - b[2] * c2[1]) - a[1] * (b[0] * c2[2] - b[2] * c2[0]) +
             a[2] * (b[0] * c2[1] - b[1] * c2[0]);
    };
    double e1[3], e2[3], e3[3], r[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = X[1][k] - X[0][k];
      e2[k] = X[2][k] - X[0][k];
      e3[k] = X[3][k] - X[0][k];
      r[k] = x[k] - X[0][k];
    }
    double d = det3(e1, e2, e3);
    lam[1] = det3(r, e2, e3) / d;
    lam[2] = det3(e1, r, e3) / d;
    lam[3] = det3(e1, e2, r) / d;
    lam[0] = 1 - lam[1] - lam[2] - lam[3];
  };

  // Every cell numbers its nodes in the same native order, so local node a has
  // the same barycentric coordinates lam_ref[a] in every cell, new cells of the
  // repair included: taken from the best-shaped straight cell (|det| over the
  // longest edge^dim, least rounding), checked on all, zeros made exact.
  std::size_t ref = 0;
  double best = -1;
  for (std::size_t c = 0; c < n_cells0; ++c) {
    const int64_t *cell = &cells0[c * npc];
    double e[3][3] = {}, longest = 0;
    for (int i = 1; i < nv; ++i)
      for (int k = 0; k < dim; ++k) e[i - 1][k] = x0[dim * cell[i] + k] - x0[dim * cell[0] + k];
    for (int i = 0; i < nv; ++i)
      for (int j = i + 1; j < nv; ++j) {
        double l = 0;
        for (int k = 0; k < dim; ++k) l += std::pow(x0[dim * cell[i] + k] - x0[dim * cell[j] + k], 2);
        longest = std::max(longest, std::sqrt(l));
      }
    const double det = dim == 2 ? e[0][0] * e[1][1] - e[0][1] * e[1][0]
                                : e[0][0] * (e[1][1] * e[2][2] - e[1][2] * e[2][1]) -
                                      e[0][1] * (e[1][0] * e[2][2] - e[1][2] * e[2][0]) +
                                      e[0][2] * (e[1][0] * e[2][1] - e[1][1] * e[2][0]);
    const double shape = std::fabs(det) / std::pow(longest, dim);
    if (shape > best) best = shape, ref = c;
  }
  std::vector<std::array<double, 4>> lam_ref(npc);
  for (std::size_t a = 0; a < npc; ++a) {
    bary(&cells0[ref * npc], cells0[ref * npc + a], lam_ref[a].data());
    for (int i = 0; i < nv; ++i)
      if (std::fabs(lam_ref[a][i]) < 1e-9) lam_ref[a][i] = 0;
  }
  for (std::size_t c = 0; c < n_cells0; ++c)
    for (std::size_t a = 0; a < npc; ++a) {
      double lam[4];
      bary(&cells0[c * npc], cells0[c * npc + a], lam);
      for (int i = 0; i < nv; ++i)
        CHECK(std::fabs(lam[i] - lam_ref[a][i]) <= 1e-6,
              "p = %d: node %zu of straight cell %zu has barycentric coordinate %d %.9g, %.9g in cell %zu", p, a, c, i,
              lam[i], lam_ref[a][i], ref);
    }

  auto t0 = std::chrono::steady_clock::now();
  mesh.run_increments(1);
  double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  CHECK(proj.calls > 0, "the projector was never called");
  const HocQuality q = mesh.quality();
  CHECK(q.n_invalid == 0, "p = %d: %zu invalid cells (min Q3 %g)", p, q.n_invalid, q.min_q3);
  const auto cc = mesh.cell_count();
  const std::size_t n_cells = cc.first, n_nodes = mesh.node_count();
  CHECK(cc.second == npc, "p = %d: %zu nodes per cell after the run, %zu before", p, cc.second, npc);
  const std::vector<int64_t> cells = mesh.cells(HOC_ORDERING_NATIVE);
  const std::vector<double> x = mesh.nodes();
  if (std::getenv("OCCT_DEBUG")) {
    const HocRepair r = mesh.repair_summary();
    std::fprintf(stderr, "  p=%d repair: %zu edge splits, %zu caps; cells %zu -> %zu, nodes %zu -> %zu\n", p,
                 r.edge_splits, r.surface_caps, n_cells0, n_cells, x0.size() / dim, n_nodes);
  }
  for (auto &vt : vertex_tags)
    for (int k = 0; k < dim; ++k)
      CHECK(x[dim * vt.first + k] == x0[dim * vt.first + k], "boundary vertex %lld moved", (long long)vt.first);

  // Facets of the curved (cap-free) mesh: a cell face bounding one cell.
  std::map<Key, int> face_count;
  for (std::size_t c = 0; c < n_cells; ++c)
    for (int o = 0; o < nv; ++o) ++face_count[face_key(&cells[c * npc], o)];

  // Classify: node -> CAD surface(s) (or 2D curve), node -> CAD curve (3D feature edges).
  const bool tri = dim == 3;
  const std::set<int> no_tags;
  auto tags_of = [&](int64_t v) -> const std::set<int> & {
    auto it = vertex_tags.find(v);
    return it == vertex_tags.end() ? no_tags : it->second;
  };
  std::vector<Facet> facets;
  std::map<int64_t, std::set<int>> on_face;
  std::map<int64_t, int> on_curve;
  std::size_t unclassified_facets = 0;
  for (std::size_t c = 0; c < n_cells; ++c) {
    const int64_t *cell = &cells[c * npc];
    for (int o = 0; o < nv; ++o) {
      Key k = face_key(cell, o);
      if (face_count[k] != 1) continue;
      int tag = -1;
      auto it = facet_tag.find(k);
      if (it != facet_tag.end()) tag = it->second;
      else {  // a face made by removing a boundary cap: on a surface all its vertices are on
        std::set<int> common = tags_of(k[0]);
        for (int i = 1; i < dim; ++i) {
          std::set<int> next;
          for (int t : tags_of(k[i]))
            if (common.count(t)) next.insert(t);
          common = next;
        }
        if (common.size() == 1) tag = *common.begin();
      }
      if (tag < 0) {
        ++unclassified_facets;
        continue;
      }
      Facet f{tag, {-1, -1, -1}, {}, {}};
      int fv[3] = {-1, -1, -1}, j = 0;  // the facet's vertices' local indices
      for (int i = 0; i < nv; ++i)
        if (i != o) fv[j] = i, f.v[j++] = cell[i];
      for (std::size_t a = 0; a < npc; ++a) {
        const double *lam = lam_ref[a].data();
        if (lam[o] != 0) continue;
        f.nodes.push_back(cell[a]);
        f.st.push_back({lam[fv[1]], tri ? lam[fv[2]] : 0.0});
        if (a < (std::size_t)nv) continue;  // a vertex
        on_face[cell[a]].insert(tag);
        if (dim == 3)  // on an edge of the face: lam of one more vertex vanishes
          for (int i = 0; i < 4; ++i)
            if (i != o && lam[i] == 0) {
              int64_t e[2], m = 0;
              for (int l = 0; l < 4; ++l)
                if (l != o && l != i) e[m++] = cell[l];
              auto fe = feature.find(occt::detail::sorted(-1, e[0], e[1]));
              if (fe != feature.end()) on_curve[cell[a]] = fe->second;
            }
      }
      facets.push_back(f);
    }
  }
  CHECK(unclassified_facets == 0, "%zu boundary faces not classified", unclassified_facets);

  // Nodes on CAD curves (3D feature edges), then on CAD faces (2D: boundary curves).
  double node_dist = 0;
  std::size_t checked = 0;
  std::map<std::pair<int, int>, std::vector<int64_t>> by_entity;
  for (auto &nc : on_curve) by_entity[{1, nc.second}].push_back(nc.first);
  for (auto &nf : on_face)
    if (!on_curve.count(nf.first))
      for (int t : nf.second) by_entity[{dim - 1, t}].push_back(nf.first);
  for (auto &e : by_entity) {
    std::vector<double> pts;
    for (int64_t n : e.second)
      for (int k = 0; k < dim; ++k) pts.push_back(x[dim * n + k]);
    std::vector<double> d = cad_distance(dim, e.first.first, e.first.second, pts);
    for (std::size_t i = 0; i < d.size(); ++i) {
      CHECK(d[i] <= tol, "p = %d: node %lld is %.3g from CAD entity (%d, %d) (tolerance %.3g)", p,
            (long long)e.second[i], d[i], e.first.first, e.first.second, tol);
      node_dist = std::max(node_dist, d[i]);
      ++checked;
    }
  }
  CHECK(checked > 0, "no node was checked");

  // 3D feature edges: a node on a CAD curve lies on every CAD face adjacent
  // to the curve (gmsh's upward adjacencies: two faces, one for a seam), not
  // only on the curve; and the faces of the node's own boundary facets are
  // among those faces (the classification agrees with the B-rep).
  double edge_face_dist = -1;  // -1: not applicable (2D)
  std::size_t edge_face_checks = 0;
  if (dim == 3) {
    edge_face_dist = 0;
    for (auto &e : by_entity) {
      if (e.first.first != 1) continue;
      const int curve = e.first.second;
      std::vector<int> up, down;
      gmsh::model::getAdjacencies(1, curve, up, down);
      CHECK(!up.empty(), "CAD curve %d bounds no face", curve);
      const std::set<int> faces(up.begin(), up.end());
      for (int64_t n : e.second)
        for (int t : on_face[n])
          CHECK(faces.count(t), "p = %d: node %lld on CAD curve %d is on a facet of CAD face %d, not adjacent to the curve",
                p, (long long)n, curve, t);
      std::vector<double> pts;
      for (int64_t n : e.second)
        for (int k = 0; k < 3; ++k) pts.push_back(x[3 * n + k]);
      for (int face : faces) {
        std::vector<double> d = cad_distance(3, 2, face, pts);
        double worst = 0;
        for (std::size_t i = 0; i < d.size(); ++i) {
          CHECK(d[i] <= tol, "p = %d: node %lld on CAD curve %d is %.3g from adjacent CAD face %d (tolerance %.3g)", p,
                (long long)e.second[i], curve, d[i], face, tol);
          worst = std::max(worst, d[i]);
          ++edge_face_checks;
        }
        edge_face_dist = std::max(edge_face_dist, worst);
        if (std::getenv("OCCT_DEBUG")) {
          std::string ct, ft;
          gmsh::model::getType(1, curve, ct);
          gmsh::model::getType(2, face, ft);
          std::fprintf(stderr, "  p=%d curve %d (%s, %zu nodes) to face %d (%s): %.3e\n", p, curve, ct.c_str(),
                       e.second.size(), face, ft.c_str(), worst);
        }
      }
    }
    CHECK(lm.edge_tags.empty() || !on_curve.empty(), "no high-order node classified on a feature edge");
    CHECK(edge_face_checks >= on_curve.size(), "feature-edge nodes not checked against their faces");
  }

  // Planar CAD faces: every node of their facets stays in the facet's plane.
  std::size_t planar = 0;
  if (dim == 3)
    for (const Facet &f : facets) {
      std::string type;
      gmsh::model::getType(2, f.tag, type);
      if (type != "Plane") continue;
      const double *a = &x0[3 * f.v[0]], *b = &x0[3 * f.v[1]], *c = &x0[3 * f.v[2]];
      double u[3], w[3], n[3];
      for (int k = 0; k < 3; ++k) u[k] = b[k] - a[k], w[k] = c[k] - a[k];
      n[0] = u[1] * w[2] - u[2] * w[1], n[1] = u[2] * w[0] - u[0] * w[2], n[2] = u[0] * w[1] - u[1] * w[0];
      double nn = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      for (int64_t node : f.nodes) {
        double s = 0;
        for (int k = 0; k < 3; ++k) s += (x[3 * node + k] - a[k]) * n[k] / nn;
        CHECK(std::fabs(s) <= tol, "p = %d: node %lld left the plane of CAD face %d by %.3g", p,
              (long long)node, f.tag, std::fabs(s));
        ++planar;
      }
    }

  // The curved facets between the nodes: interpolate each facet's nodes (their
  // reference coordinates from lam_ref) and sample on a lattice of order 2p + 1.
  double sample_dist = 0;
  std::map<int, std::vector<double>> samples;
  for (const Facet &f : facets) {
    const int n = (int)f.nodes.size();
    std::vector<double> vdm, rhs;
    for (int i = 0; i < n; ++i) {
      const int64_t node = f.nodes[i];
      const double s = f.st[i][0], t = f.st[i][1];
      std::vector<double> m = monomials(p, tri, s, t);
      CHECK((int)m.size() == n, "facet has %d nodes, expected %zu", n, m.size());
      vdm.insert(vdm.end(), m.begin(), m.end());
      for (int k = 0; k < dim; ++k) rhs.push_back(x[dim * node + k]);
    }
    std::vector<double> coef = solve_dense(vdm, rhs, n, dim);
    const int ns = 2 * p + 1;
    for (int i = 0; i <= ns; ++i)
      for (int j = 0; j <= (tri ? ns - i : 0); ++j) {
        std::vector<double> m = monomials(p, tri, double(i) / ns, double(j) / ns);
        for (int k = 0; k < dim; ++k) {
          double v = 0;
          for (int l = 0; l < n; ++l) v += m[l] * coef[l * dim + k];
          samples[f.tag].push_back(v);
        }
      }
  }
  for (auto &s : samples) {
    double worst = 0;
    for (double d : cad_distance(dim, dim - 1, s.first, s.second)) worst = std::max(worst, d);
    if (std::getenv("OCCT_DEBUG")) {
      std::string type;
      gmsh::model::getType(dim - 1, s.first, type);
      std::fprintf(stderr, "  p=%d entity %d (%s): sampled %.3e\n", p, s.first, type.c_str(), worst);
    }
    sample_dist = std::max(sample_dist, worst);
  }

  return Row{p,        n_cells,        n_nodes,        checked,          planar,
             node_dist, edge_face_dist, on_curve.size(), edge_face_checks, sample_dist,
             q.min_q3,  q.n_invalid,    secs,           proj.placer ? proj.placer->fallbacks : 0,
             proj.placer ? proj.placer->projected : 0};
}

occt::LinearMesh load(const std::string &model, double h, int per_2pi = 12) {
  occt::import_model(model);
  const int dim = occt::model_dim();
  occt::mesh_linear(dim, h, per_2pi);
  return occt::collect(dim);
}

int check(const std::string &model, double h, int pmin, int pmax, int per_2pi, double fall) {
  occt::LinearMesh lm = load(model, h, per_2pi);
  std::printf("%s: dim %d, %zu vertices, %zu cells, %zu boundary facets, %zu feature edges, size %.4g\n",
              model.c_str(), lm.dim, lm.coords.size() / lm.dim, lm.cells.size() / (lm.dim + 1),
              lm.facet_tags.size(), lm.edge_tags.size(), lm.size);
  const bool parametric = placement() == occt::Placement::Parametric;
  std::printf("placement: %s\n", parametric ? "parametric" : "closest point");
  std::printf("%3s %7s %8s %8s %8s %12s %10s %12s %14s %7s %8s %8s %9s %9s %8s\n", "p", "cells", "nodes", "checked",
              "planar", "node->CAD", "edge nodes", "edge->faces", "between->CAD", "drop", "min Q3", "invalid",
              "fallbacks", "projected", "seconds");
  // Each order is curved twice: with the defaults, and without the
  // optimisation stage, whose boundary is the placement's alone. The
  // convergence with p is the placement's; the polish may slide boundary
  // nodes, each boundary piece as far as twice its distance before or the
  // boundary's largest before, so the largest may at most double.
  auto print = [](const Row &r, const Row *last) {
    char drop[16] = "-";
    if (last) std::snprintf(drop, sizeof drop, "%.1f", last->sample_dist / r.sample_dist);
    char ef[16] = "-";
    if (r.edge_face_dist >= 0) std::snprintf(ef, sizeof ef, "%.3e", r.edge_face_dist);
    std::printf("%3d %7zu %8zu %8zu %8zu %12.3e %10zu %12s %14.3e %7s %8.4f %8zu %9zu %9zu %8.2f\n", r.p, r.cells,
                r.nodes, r.checked, r.planar, r.node_dist, r.edge_nodes, ef, r.sample_dist, drop, r.min_q3, r.invalid,
                r.fallbacks, r.projected, r.secs);
    std::fflush(stdout);
  };
  std::vector<Row> rows, placed;
  for (int p = pmin; p <= pmax; ++p) {
    rows.push_back(curve_and_check(lm, p));
    print(rows.back(), rows.size() > 1 ? &rows[rows.size() - 2] : nullptr);
  }
  std::printf("without the optimisation stage:\n");
  for (int p = pmin; p <= pmax; ++p) {
    placed.push_back(curve_and_check(lm, p, false));
    print(placed.back(), placed.size() > 1 ? &placed[placed.size() - 2] : nullptr);
  }
  for (std::size_t i = 0; i < rows.size(); ++i)
    CHECK(rows[i].sample_dist <= 2 * placed[i].sample_dist * (1 + 1e-6) + 1e-12 * lm.size,
          "p = %d: the optimisation moved the boundary from %.3g to %.3g from the CAD", rows[i].p,
          placed[i].sample_dist, rows[i].sample_dist);
  // Convergence with p on the fixed mesh. On a circular arc the
  // distance falls in pairs of orders (rate h^(p+2) at even p, h^(p+1) at odd
  // p; see examples/occt/README.md), so only a fall at every order and a large overall one are asked.
  if (parametric) {
    // Every node placed through the parametrisation (a fallback to closest
    // point hid a bad getClosestPoint answer on the torus; README).
    for (const Row &r : rows) CHECK(r.fallbacks == 0, "p = %d: %zu placement fallbacks", r.p, r.fallbacks);
    for (std::size_t i = 1; i < placed.size(); ++i)
      CHECK(placed[i].sample_dist < placed[i - 1].sample_dist,
            "between->CAD did not fall from p = %d (%.3g) to p = %d (%.3g)", placed[i - 1].p,
            placed[i - 1].sample_dist, placed[i].p, placed[i].sample_dist);
    if (pmax >= pmin + 3)
      CHECK(placed.back().sample_dist * fall <= placed.front().sample_dist,
            "between->CAD fell only from %.3g (p = %d) to %.3g (p = %d), less than %g times",
            placed.front().sample_dist, pmin, placed.back().sample_dist, pmax, fall);
  }
  return 0;
}

// The parametric placement on facets across periodic seams and at poles: see the header.
int seam() {
  struct Case {
    const char *name;
    double h;
    bool pole;  // has facets at a singular point of its parametrisation
  };
  const Case cases[] = {{"sphere", 0.25, true}, {"torus", 0.3, false}, {"cylinder", 0.3, false}, {"cone", 0.25, true}};
  const int p = 4;
  std::printf("%-9s %6s %7s %6s %6s %9s %7s %12s %14s %9s\n", "model", "tets", "facets", "seam", "pole",
              "distorted", "nodes", "node->CAD", "worst/diam", "fallbacks");
  for (const Case &c : cases) {
    gmsh::model::add(c.name);
    const std::string n = c.name;
    if (n == "sphere") gmsh::model::occ::addSphere(0, 0, 0, 1);
    else if (n == "torus") gmsh::model::occ::addTorus(0, 0, 0, 1.5, 0.5);
    else if (n == "cylinder") gmsh::model::occ::addCylinder(0, 0, 0, 0, 0, 2, 1);
    else gmsh::model::occ::addCone(0, 0, 0, 0, 0, 2, 1, 0);
    gmsh::model::occ::synchronize();
    occt::mesh_linear(3, c.h);
    occt::LinearMesh lm = occt::collect(3);
    occt::Placer placer(lm);
    const double tol = 1e-8 * lm.size;
    std::map<Key, int> feature;
    for (std::size_t e = 0; e < lm.edge_tags.size(); ++e)
      feature[occt::detail::sorted(-1, lm.edges[2 * e], lm.edges[2 * e + 1])] = lm.edge_tags[e];
    // The nodes of an order-p lattice on each facet (vertices excluded), on the
    // facet's surface, or on the CAD curve of the facet edge they lie on.
    std::set<std::pair<Key, int>> done;  // (sorted facet or edge, lattice point) placed already
    double node_dist = 0, worst = 0;
    std::size_t nodes = 0;
    for (std::size_t f = 0; f < lm.facet_tags.size(); ++f) {
      const int64_t *v = &lm.facets[3 * f];
      const double *X[3] = {&lm.coords[3 * v[0]], &lm.coords[3 * v[1]], &lm.coords[3 * v[2]]};
      double diam = 0;
      for (int i = 0; i < 3; ++i) diam = std::max(diam, occt::detail::dist3(X[i], X[(i + 1) % 3]));
      for (int i = 0; i <= p; ++i)
        for (int j = 0; i + j <= p; ++j) {
          const int k = p - i - j, ijk[3] = {i, j, k};
          if (i == p || j == p || k == p) continue;  // a vertex
          int edim = 2, etag = lm.facet_tags[f];
          Key id = occt::detail::sorted(v[0], v[1], v[2]);
          int at = i * (p + 1) + j;
          for (int e = 0; e < 3; ++e)
            if (ijk[e] == 0) {  // on the edge opposite vertex e: one node per edge, keyed from its smaller vertex
              const int64_t a = v[(e + 1) % 3], b = v[(e + 2) % 3];
              id = occt::detail::sorted(-1, a, b);
              at = a < b ? ijk[(e + 1) % 3] : p - ijk[(e + 1) % 3];
              auto fe = feature.find(id);
              if (fe != feature.end()) edim = 1, etag = fe->second;
            }
          if (!done.insert({id, at}).second) continue;
          double x[3], y[3], cp[3];
          for (int d = 0; d < 3; ++d) x[d] = (ijk[0] * X[0][d] + ijk[1] * X[1][d] + ijk[2] * X[2][d]) / p;
          placer.place(edim, etag, x, y);
          occt::Placer::closest(edim, etag, y, cp);
          const double on = occt::detail::dist3(cp, y);
          CHECK(on <= tol, "%s: node at (%g, %g, %g) is %.3g from CAD entity (%d, %d)", c.name, x[0], x[1], x[2], on,
                edim, etag);
          occt::Placer::closest(edim, etag, x, cp);
          const double off = occt::detail::dist3(cp, y) / diam;
          CHECK(off <= 0.1,
                "%s: node at (%g, %g, %g) on CAD entity (%d, %d) placed at (%g, %g, %g), %.3g of its facet from the "
                "closest point (%g, %g, %g)",
                c.name, x[0], x[1], x[2], edim, etag, y[0], y[1], y[2], off, cp[0], cp[1], cp[2]);
          node_dist = std::max(node_dist, on);
          worst = std::max(worst, off);
          ++nodes;
          // The local foot (the optimisation's sliding nodes) of a point a
          // little off the node: on the entity, and no farther than the
          // checked closest point, across seams and at poles.
          double near[3], foot[3], best[3];
          for (int d = 0; d < 3; ++d) near[d] = y[d] + 0.03 * diam * (d == 0 ? 1.0 : -0.5);
          CHECK(placer.local_foot(edim, etag, near, foot), "%s: no local foot near (%g, %g, %g)", c.name, y[0], y[1],
                y[2]);
          placer.closest_checked(edim, etag, near, best);
          occt::Placer::closest(edim, etag, foot, cp);
          CHECK(occt::detail::dist3(cp, foot) <= tol && occt::detail::dist3(foot, near) <= occt::detail::dist3(best, near) + tol,
                "%s: local foot (%g, %g, %g) of (%g, %g, %g): %.3g off entity (%d, %d), %.3g from it against %.3g",
                c.name, foot[0], foot[1], foot[2], near[0], near[1], near[2], occt::detail::dist3(cp, foot), edim, etag,
                occt::detail::dist3(foot, near), occt::detail::dist3(best, near));
        }
    }
    std::printf("%-9s %6zu %7zu %6zu %6zu %9zu %7zu %12.3e %14.3f %9zu\n", c.name, lm.cells.size() / 4,
                lm.facet_tags.size(), placer.seam_facets, placer.pole_facets, placer.distorted_facets, nodes, node_dist,
                worst, placer.fallbacks);
    std::fflush(stdout);
    CHECK(placer.fallbacks == 0, "%s: %zu nodes fell back to closest point (%zu seam, %zu far, %zu on no facet)",
          c.name, placer.fallbacks, placer.fallbacks_seam, placer.fallbacks_far, placer.fallbacks_unlocated);
    CHECK(placer.seam_facets > 0, "%s: no facet straddles the seam", c.name);
    std::printf("%-9s local feet from the facet under the point: %zu of %zu\n", c.name, placer.facet_feet, nodes);
    CHECK(placer.facet_feet > nodes / 2, "%s: only %zu of %zu local feet from a facet", c.name, placer.facet_feet, nodes);
    CHECK(!c.pole || placer.pole_facets > 0, "%s: no facet at a pole", c.name);
    gmsh::model::remove();
  }

  // The closest-point fallback: gmsh 4.8's getClosestPoint on the torus patch
  // of sphere-torus, for a point 1e-8..1e-6 below the equator the patch ends
  // on, answers the far side of the torus (4.4 away). Placer::closest_checked
  // compares it with the local foot from the nearest mesh vertex.
  gmsh::model::add("sphere-torus");
  occt::build_sphere_torus();
  occt::mesh_linear(3, 0.4);
  occt::LinearMesh lm = occt::collect(3);
  occt::Placer placer(lm);
  gmsh::vectorpair faces;
  gmsh::model::getEntities(faces, 2);
  std::size_t probes = 0, far = 0;
  double worst = 0;
  for (auto &f : faces) {
    std::vector<int> up, down;
    gmsh::model::getAdjacencies(2, f.second, up, down);
    for (int c : down) {
      std::vector<double> lo, hi;
      gmsh::model::getParametrizationBounds(1, c, lo, hi);
      for (int i = 0; i < 20; ++i) {
        std::vector<double> x;
        gmsh::model::getValue(1, c, {lo[0] + (hi[0] - lo[0]) * (i + 0.5) / 20}, x);
        for (double off : {-1e-6, -1e-8, 1e-8, 1e-6}) {
          double y[3], z[3], xo[3] = {x[0], x[1], x[2] + off};
          occt::Placer::closest(2, f.second, xo, y);
          placer.closest_checked(2, f.second, xo, z);
          far += occt::detail::dist3(y, xo) > 1e-3;
          worst = std::max(worst, occt::detail::dist3(z, xo));
          ++probes;
        }
      }
    }
  }
  std::printf("sphere-torus: %zu points 1e-8..1e-6 off the faces' boundary curves: getClosestPoint answered %zu of "
              "them more than 1e-3 away, the checked closest point at most %.3g away (%zu replaced)\n",
              probes, far, worst, placer.closest_replaced);
  CHECK(worst <= 2e-6, "the checked closest point is %.3g from its point", worst);
  gmsh::model::remove();
  return 0;
}

int fail(const std::string &model, double h) {
  occt::LinearMesh lm = load(model, h);
  // Fail on the first curved CAD entity that has facets.
  int tag = -1;
  for (int t : lm.facet_tags) {
    std::string type;
    gmsh::model::getType(lm.dim - 1, t, type);
    if (type != "Plane" && type != "Line") {
      tag = t;
      break;
    }
  }
  CHECK(tag >= 0, "no curved entity");
  occt::Projector proj;
  proj.fail_dim = lm.dim - 1;
  proj.fail_tag = tag;
  hocurve::Mesh mesh = occt::make_mesh(lm, proj);
  mesh.set_order(3);
  const std::vector<double> before = mesh.nodes();
  HocStatus st = hoc_mesh_run_increments(mesh.get(), 1);
  CHECK(st == HOC_ERROR_PROJECTION, "status %d (%s), expected HOC_ERROR_PROJECTION", st, hoc_status_string(st));
  const char *m = hoc_mesh_last_error(mesh.get());
  const std::string msg = m ? m : "";  // valid only until the next call on the handle
  const std::vector<double> after = mesh.nodes();
  CHECK(after == before, "the nodes changed after a failed run");
  std::printf("projector failing on entity (%d, %d): %s: %s; nodes unchanged\n", lm.dim - 1, tag,
              hoc_status_string(st), msg.c_str());
  return 0;
}

}  // namespace

int main(int argc, char **argv) {
  if (argc < 2 || (argc < 3 && std::string(argv[1]) != "seam")) {
    std::fprintf(stderr, "usage: occt_test write DIR | check MODEL H PMIN PMAX [PER_2PI [FALL]] | seam | fail MODEL H\n");
    return 2;
  }
  gmsh::initialize();
  gmsh::option::setNumber("General.Terminal", 0);
  int rc = 2;
  try {
    std::string mode = argv[1];
    if (mode == "write") {
      for (const char *name : {"part", "sphere-torus", "plate", "naca", "sphere"})
        occt::write_model(name, std::string(argv[2]) + "/" + name + ".step");
      rc = 0;
    } else if (mode == "check" && argc >= 6 && argc <= 8) {
      rc = check(argv[2], std::atof(argv[3]), std::atoi(argv[4]), std::atoi(argv[5]), argc >= 7 ? std::atoi(argv[6]) : 12,
                 argc == 8 ? std::atof(argv[7]) : 100);
    } else if (mode == "seam") {
      rc = seam();
    } else if (mode == "fail" && argc == 4) {
      rc = fail(argv[2], std::atof(argv[3]));
    }
  } catch (const std::exception &e) {
    std::fprintf(stderr, "occt_test: %s\n", e.what());
    rc = 1;
  } catch (const std::string &s) {  // gmsh's API throws its error message
    std::fprintf(stderr, "occt_test: gmsh: %s\n", s.c_str());
    rc = 1;
  } catch (...) {
    std::fprintf(stderr, "occt_test: gmsh error\n");
    rc = 1;
  }
  gmsh::finalize();
  return rc;
}

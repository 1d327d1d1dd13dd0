// gmsh (OpenCASCADE) -> hocurve: the linear mesh of a CAD model with every
// boundary facet, and every mesh line on a model curve, classified on its CAD
// entity by gmsh itself, and a projector that calls gmsh::model::getClosestPoint.
// Shared by the hocurve-occt tool and its tests.
#ifndef HOCURVE_OCCT_PIPELINE_HPP
#define HOCURVE_OCCT_PIPELINE_HPP

#include <gmsh.h>
#include <hocurve.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <exception>
#include <initializer_list>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace occt {

// The linear mesh handed to hocurve, with gmsh's classification.
struct LinearMesh {
  int dim = 3;                         // 3: tets, 2: triangles in the plane z = 0
  std::vector<double> coords;          // dim per vertex
  std::vector<int64_t> cells;          // dim + 1 per cell
  std::vector<int64_t> facets;         // dim per boundary facet (triangles / edges)
  std::vector<int32_t> facet_tags;     // gmsh surface (3D) or curve (2D) tags
  std::vector<int64_t> edges;          // 2 per 3D feature edge
  std::vector<int32_t> edge_tags;      // gmsh curve tags
  std::vector<int> node_dim, node_tag; // gmsh entity each vertex is classified on
  std::vector<double> node_uv;         // 2 per vertex: its parameters there (curve: u, 0; point, volume: 0, 0)
  double size = 1.0;                   // bounding-box diagonal of the model
};

// Diagonal of the model's bounding box.
inline double model_size() {
  double x0, y0, z0, x1, y1, z1;
  gmsh::model::getBoundingBox(-1, -1, x0, y0, z0, x1, y1, z1);
  return std::sqrt((x1 - x0) * (x1 - x0) + (y1 - y0) * (y1 - y0) + (z1 - z0) * (z1 - z0));
}

// Dimension of the current model: 3 if it has volumes, else 2 (then it must lie in z = 0).
inline int model_dim() {
  gmsh::vectorpair v;
  gmsh::model::getEntities(v, 3);
  if (!v.empty()) return 3;
  double x0, y0, z0, x1, y1, z1;
  gmsh::model::getBoundingBox(-1, -1, x0, y0, z0, x1, y1, z1);
  // OpenCASCADE's bounding boxes are enlarged by the shape tolerance (about 1e-7).
  if (std::fabs(z0) > 1e-5 * model_size() || std::fabs(z1) > 1e-5 * model_size())
    throw std::runtime_error("a model without volumes must lie in the plane z = 0");
  return 2;
}

// Import a STEP/BREP file into a fresh gmsh model.
inline void import_model(const std::string &path) {
  gmsh::model::add("hocurve-occt");
  gmsh::vectorpair out;
  gmsh::model::occ::importShapes(path, out);
  gmsh::model::occ::synchronize();
  if (out.empty()) throw std::runtime_error("no shape in " + path);
}

// Mesh the current model linearly (3D if it has volumes, else 2D) with target
// size h (<= 0: gmsh's default) and at least `per_2pi` elements per 2π of
// curvature (0: off), so that a small hole gets more than a few chords.
inline void mesh_linear(int dim, double h, int per_2pi = 12) {
  gmsh::option::setNumber("Mesh.MeshSizeFromCurvature", per_2pi);
  if (h > 0) {
    gmsh::option::setNumber("Mesh.MeshSizeMax", h);
    gmsh::option::setNumber("Mesh.MeshSizeMin", 0.1 * h);
  }
  gmsh::option::setNumber("Mesh.ElementOrder", 1);
  gmsh::model::mesh::generate(dim);
}

namespace detail {
inline std::array<int64_t, 3> sorted(int64_t a, int64_t b, int64_t c) {
  std::array<int64_t, 3> t{a, b, c};
  std::sort(t.begin(), t.end());
  return t;
}
}  // namespace detail

// Collect the linear mesh of the current model. Boundary facets are the mesh
// elements of the model surfaces (3D) or curves (2D) that bound one cell only
// (internal interfaces are skipped); 3D feature edges are the mesh lines on
// the model curves that are edges of a boundary facet.
inline LinearMesh collect(int dim) {
  LinearMesh m;
  m.dim = dim;
  m.size = model_size();
  const int cell_type = dim == 3 ? 4 : 2, nv = dim + 1;
  std::vector<std::size_t> elem_tags, node_tags;
  gmsh::model::mesh::getElementsByType(cell_type, elem_tags, node_tags);
  if (elem_tags.empty()) throw std::runtime_error("gmsh made no cells");
  std::map<std::size_t, int64_t> index;  // gmsh node tag -> 0-based vertex
  for (std::size_t t : node_tags) index.emplace(t, 0);
  int64_t k = 0;
  for (auto &e : index) e.second = k++;
  m.coords.assign(dim * index.size(), 0.0);
  {
    std::vector<std::size_t> all;
    std::vector<double> xyz, uv;
    gmsh::model::mesh::getNodes(all, xyz, uv);
    for (std::size_t i = 0; i < all.size(); ++i) {
      auto it = index.find(all[i]);
      if (it == index.end()) continue;
      for (int d = 0; d < dim; ++d) m.coords[dim * it->second + d] = xyz[3 * i + d];
      if (dim == 2 && std::fabs(xyz[3 * i + 2]) > 1e-12 * m.size)
        throw std::runtime_error("a 2D mesh node is not in the plane z = 0");
    }
  }
  // Classification and parameters of each vertex (the placement starts its
  // parameter searches from them instead of a global closest point).
  m.node_dim.assign(index.size(), -1);
  m.node_tag.assign(index.size(), -1);
  m.node_uv.assign(2 * index.size(), 0.0);
  {
    gmsh::vectorpair all_ents;
    gmsh::model::getEntities(all_ents);
    for (auto &e : all_ents) {
      if (e.first >= dim) continue;
      std::vector<std::size_t> tags;
      std::vector<double> xyz, uv;
      gmsh::model::mesh::getNodes(tags, xyz, uv, e.first, e.second, false, true);
      for (std::size_t i = 0; i < tags.size(); ++i) {
        auto it = index.find(tags[i]);
        if (it == index.end()) continue;
        m.node_dim[it->second] = e.first;
        m.node_tag[it->second] = e.second;
        for (int k = 0; k < e.first && uv.size() == e.first * tags.size(); ++k)
          m.node_uv[2 * it->second + k] = uv[e.first * i + k];
      }
    }
  }
  m.cells.reserve(node_tags.size());
  for (std::size_t t : node_tags) m.cells.push_back(index.at(t));

  // Faces (3D) or edges (2D) of the cells, with how many cells hold each.
  std::map<std::array<int64_t, 3>, int> count;
  const std::size_t n_cells = elem_tags.size();
  for (std::size_t c = 0; c < n_cells; ++c) {
    const int64_t *v = &m.cells[nv * c];
    for (int omit = 0; omit < nv; ++omit) {
      int64_t f[3] = {-1, -1, -1};
      int j = 0;
      for (int i = 0; i < nv; ++i)
        if (i != omit) f[j++] = v[i];
      ++count[detail::sorted(f[0], f[1], f[2])];
    }
  }
  auto boundary = [&](int64_t a, int64_t b, int64_t c) {
    auto it = count.find(detail::sorted(a, b, c));
    return it != count.end() && it->second == 1;
  };

  gmsh::vectorpair ents;
  gmsh::model::getEntities(ents, dim - 1);
  const int facet_type = dim == 3 ? 2 : 1;
  std::map<std::array<int64_t, 3>, int> boundary_edges;  // 3D: edges of boundary facets
  for (auto &e : ents) {
    std::vector<std::size_t> et, nt;
    gmsh::model::mesh::getElementsByType(facet_type, et, nt, e.second);
    for (std::size_t f = 0; f < et.size(); ++f) {
      int64_t v[3] = {-1, -1, -1};
      bool ok = true;
      for (int i = 0; i < dim; ++i) {
        auto it = index.find(nt[dim * f + i]);
        if (it == index.end()) ok = false;
        else v[i] = it->second;
      }
      if (!ok || !boundary(v[0], v[1], v[2])) continue;
      for (int i = 0; i < dim; ++i) m.facets.push_back(v[i]);
      m.facet_tags.push_back(e.second);
      if (dim == 3)
        for (int i = 0; i < 3; ++i) boundary_edges[detail::sorted(-1, v[i], v[(i + 1) % 3])] = 1;
    }
  }
  if (dim == 3) {
    gmsh::model::getEntities(ents, 1);
    for (auto &e : ents) {
      std::vector<std::size_t> et, nt;
      gmsh::model::mesh::getElementsByType(1, et, nt, e.second);
      for (std::size_t f = 0; f < et.size(); ++f) {
        auto a = index.find(nt[2 * f]), b = index.find(nt[2 * f + 1]);
        if (a == index.end() || b == index.end()) continue;
        if (!boundary_edges.count(detail::sorted(-1, a->second, b->second))) continue;
        m.edges.push_back(a->second);
        m.edges.push_back(b->second);
        m.edge_tags.push_back(e.second);
      }
    }
  }
  return m;
}

namespace detail {
inline double dist3(const double *a, const double *b) {
  return std::sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}
// x + period * k closest to `near` (period <= 0: x).
inline double unwrap(double x, double near, double period) {
  return period > 0 ? x - period * std::round((x - near) / period) : x;
}
// Items (edges, facets) bucketed on a uniform grid by their bounding boxes, so
// that locating a point costs a few candidates instead of a scan of the entity.
class Buckets {
 public:
  using Box = std::array<double, 6>;  // lo xyz, hi xyz
  void build(const std::vector<Box> &boxes, double eps) {
    double sum = 0;
    for (const Box &b : boxes) sum += std::max({b[3] - b[0], b[4] - b[1], b[5] - b[2]});
    h_ = boxes.empty() ? 1.0 : std::max(sum / boxes.size(), 1e3 * eps + 1e-300);
    for (std::size_t i = 0; i < boxes.size(); ++i) {
      std::array<int64_t, 3> lo, hi;
      for (int k = 0; k < 3; ++k) lo[k] = cell(boxes[i][k] - eps), hi[k] = cell(boxes[i][k + 3] + eps);
      for (int64_t a = lo[0]; a <= hi[0]; ++a)
        for (int64_t b = lo[1]; b <= hi[1]; ++b)
          for (int64_t c = lo[2]; c <= hi[2]; ++c) cells_[{a, b, c}].push_back(i);
    }
  }
  // Candidates whose (enlarged) box may hold x; empty if none.
  const std::vector<std::size_t> &query(const double *x) const {
    static const std::vector<std::size_t> none;
    auto it = cells_.find({cell(x[0]), cell(x[1]), cell(x[2])});
    return it == cells_.end() ? none : it->second;
  }

 private:
  int64_t cell(double v) const { return static_cast<int64_t>(std::floor(v / h_)); }
  double h_ = 1.0;
  std::map<std::array<int64_t, 3>, std::vector<std::size_t>> cells_;
};

// x wrapped into [lo, lo + period) (period <= 0: x).
inline double wrap(double x, double lo, double period) {
  return period > 0 ? x - period * std::floor((x - lo) / period) : x;
}
}  // namespace detail

// How the projector places a high-order node on its CAD entity.
//  - Closest: the closest point to the straight-sided node (gmsh::model::getClosestPoint,
//    checked against the local foot: Placer::closest_checked).
//  - Parametric: through the CAD parametrisation of the linear edge or facet
//    the node lies on. A node at fraction t of a mesh edge on a CAD curve goes
//    to C(u_a + t (u_b - u_a)), u_a, u_b the parameters of the edge's vertices
//    (on a circle: equal angles, so GLL nodes stay GLL in arc length; vertex
//    parameters are refined by Gauss-Newton, see Placer::newton). A node
//    inside a facet on a CAD surface, with barycentric coordinates λ, goes to
//    S(Σ λ_k (u,v)_k + Σ_e (λ_i + λ_j) [(u,v)(y_e) − lin_e]) where e = (i, j)
//    runs over the facet's edges on CAD curves, y_e is the curve point of the
//    edge at t = λ_j / (λ_i + λ_j), and lin_e the linear interpolation of the
//    edge's (u,v) at t: the edge's curvature is blended into the facet, as in a
//    transfinite (Gordon–Hall) map. Without the blend, a facet on a plane
//    whose edge follows a circle keeps its interior nodes straight while its
//    edge bulges inwards, and at p = 5 that facet, whose nodes are all
//    prescribed, folds (see README).
//    The facet's (u,v) are first brought to one period (Placer::unwrap_shortest),
//    and a vertex on a singular point of the parametrisation (a sphere's pole,
//    a cone's apex) takes no part in its free parameter (Placer::facet_uv).
//    Where the parametrisation is far from affine over a facet (next to a
//    pole), the facet's nodes are projected instead (Placer::facet_info): the
//    foot on the surface of the straight node plus the same edge blend in space.
//    A node the parametric placement cannot handle (not on a known edge or
//    facet, a facet whose parameters span more than half a period, or placed
//    farther than half the element from its straight position) falls back to
//    the closest point; each such node is counted.
enum class Placement { Closest, Parametric };

// Node placement on the CAD entities of a collected linear mesh.
class Placer {
 public:
  Placer(const LinearMesh &m) : m_(m) {
    const int d = m.dim;
    if (d == 2)
      for (std::size_t f = 0; f < m.facet_tags.size(); ++f)
        curve_edges_[m.facet_tags[f]].push_back({m.facets[2 * f], m.facets[2 * f + 1]});
    else {
      for (std::size_t e = 0; e < m.edge_tags.size(); ++e) {
        curve_edges_[m.edge_tags[e]].push_back({m.edges[2 * e], m.edges[2 * e + 1]});
        feature_[key(m.edges[2 * e], m.edges[2 * e + 1])] = m.edge_tags[e];
      }
      for (std::size_t f = 0; f < m.facet_tags.size(); ++f) {
        auto &list = surface_facets_[m.facet_tags[f]];
        for (int i = 0; i < 3; ++i)
          edge_facets_[key(m.facets[3 * f + i], m.facets[3 * f + (i + 1) % 3])].push_back({m.facet_tags[f], list.size()});
        list.push_back({m.facets[3 * f], m.facets[3 * f + 1], m.facets[3 * f + 2]});
      }
    }
    const double eps = 1e-9 * m.size;
    for (auto &c : curve_edges_) {
      std::vector<detail::Buckets::Box> boxes;
      for (auto &e : c.second) boxes.push_back(box({e.first, e.second}));
      curve_buckets_[c.first].build(boxes, eps);
    }
    for (auto &f : surface_facets_) {
      std::vector<detail::Buckets::Box> boxes;
      for (auto &t : f.second) boxes.push_back(box({t[0], t[1], t[2]}));
      surface_buckets_[f.first].build(boxes, eps);
    }
  }

  // True while hocurve places the high-order nodes (up to its projection
  // stage). After that, the calls come from the optimisation's sliding
  // nodes: they are answered by the checked closest point (the projection
  // the optimisation's tangent frames assume, not a parametric map of some
  // straight facet) and are not counted as placements below. The host
  // clears it from its progress callback, and sets it again (start_run)
  // when hocurve starts a run: it makes a second one with the caps kept
  // when the first fails.
  bool placing = true;
  // A run starts: placing again, and the per-node counts below start from
  // zero, so they describe the run that stands (the per-facet ones are of
  // the input's facets and are kept).
  void start_run() {
    placing = true;
    fallbacks = fallbacks_unlocated = closest_replaced = fallbacks_seam = fallbacks_far = projected = 0;
  }
  // Nodes placed by closest point for want of a parametric placement, in
  // total and by reason (each node counts once, under the first reason met).
  std::size_t fallbacks = 0;
  std::size_t fallbacks_unlocated = 0;  // on no edge or facet of its entity (faces made by cap removal)
  std::size_t closest_replaced = 0;     // fallbacks whose getClosestPoint answer was farther than the
                                        // local foot (closest_checked)
  std::size_t fallbacks_seam = 0;       // its facet's parameters span more than half a period once
                                        // unwrapped, or every vertex of it is on a pole
  std::size_t fallbacks_far = 0;        // placed farther than half its edge or facet from where it was
  std::size_t projected = 0;            // nodes of distorted facets, projected instead (facet_info)
  std::size_t pole_facets = 0;          // facets with a vertex on a singular point (pole, apex)
  std::size_t seam_facets = 0;          // facets whose vertex parameters were unwrapped across a seam
  std::size_t distorted_facets = 0;     // facets whose parametrisation is too far from affine
  // A facet is distorted where S of its linear (u,v) is more than this
  // fraction of the facet from the foot of the straight point (facet_info).
  // Measured at h = 0.25..0.4: torus and sphere-torus facets ≤ 0.048 (the
  // torus converges well placed through its parametrisation), a sphere's
  // facets at its poles 0.16-0.26 and the next ring up to 0.17, a cone's apex 0.22.
  static constexpr double kDistortion = 0.05;

  // Place point x (3 coordinates) on entity (edim, etag) into y (3 coordinates).
  void place(int edim, int etag, const double *x, double *y) {
    Miss why = Miss::Unlocated;
    if (edim == 1 && (why = place_on_curve(etag, x, y)) == Miss::None) return;
    if (edim == 2 && m_.dim == 3 && (why = place_on_surface(etag, x, y)) == Miss::None) return;
    if (placing) {
      ++fallbacks;
      ++(why == Miss::Seam ? fallbacks_seam : why == Miss::Far ? fallbacks_far : fallbacks_unlocated);
    }
    closest_checked(edim, etag, x, y);
  }

  // The optimisation's sliding nodes sit within a fraction of an element of
  // the entity, next to where they were placed: the local foot, by
  // Gauss-Newton from the parameters of the nearest mesh vertex, answers them
  // without gmsh's global getClosestPoint (which took two thirds of the
  // optimisation's time on SampleCrankshaft4A). Accepted only if it is no
  // farther from x than that vertex, a point of the entity; else false.
  // On a surface, the Gauss-Newton starts from the facet under x first
  // (facet_foot), and from the nearest vertex only if that fails.
  bool local_foot(int edim, int etag, const double *x, double *y) {
    std::vector<double> z;
    auto accept = [&](int64_t v) {
      if (v < 0) return false;
      auto pv = vertex(v);
      if (!(detail::dist3(z.data(), x) <= detail::dist3(pv.data(), x))) return false;
      for (int k = 0; k < 3; ++k) y[k] = z[k];
      return true;
    };
    if (edim == 2 && accept(facet_foot(etag, x, z))) return ++facet_feet, true;
    return accept(nearest_foot(edim, etag, x, z));
  }
  // Local feet found from the facet under the point (the others from the nearest vertex).
  std::size_t facet_feet = 0;

  // The foot of x on entity (edim, etag) by Gauss-Newton from the parameters
  // of the entity's mesh vertex nearest to x, into z (3 coordinates); returns
  // that vertex, or -1 (z unset) if there is none or the evaluation failed.
  int64_t nearest_foot(int edim, int etag, const double *x, std::vector<double> &z) {
    const int64_t v = nearest_vertex(edim, etag, x);
    if (v < 0) return -1;
    const VParam &vp = vertex_param(edim, etag, v);
    double uv[2] = {vp.uv[0], vp.uv[1]};
    newton(edim, etag, x, uv, 30, kFootTolerance * m_.size, &z);
    return z.size() == 3 ? v : -1;
  }

  // The foot of x on surface `tag` by Gauss-Newton from the (u,v) of the
  // point of x's facet under it (the candidate facet x is most inside when
  // projected onto its plane, its vertex parameters unwrapped:
  // facet_params), into z; returns the facet's vertex nearest to x, or -1
  // (z unset) if no facet lies under x or its parameters span more than
  // half a period (nearest_foot then). Closer than the nearest vertex's
  // parameters, it takes fewer iterations: on component8 at p = 3, 1.8 a
  // point against 2.6 (screw: 2.6 against 3.4).
  int64_t facet_foot(int tag, const double *x, std::vector<double> &z) {
    auto it = surface_facets_.find(tag);
    if (it == surface_facets_.end()) return -1;
    std::size_t best = 0;
    double lam[3] = {0, 0, 0}, best_score = -HUGE_VAL;
    for (std::size_t i : surface_buckets_.at(tag).query(x)) {
      double l[3];
      barycentric(it->second[i], x, l);
      const double score = std::min({l[0], l[1], l[2]});
      if (score > best_score) best = i, best_score = score, lam[0] = l[0], lam[1] = l[1], lam[2] = l[2];
    }
    if (!(best_score >= -kFacetMargin)) return -1;
    const FacetParams &fp = facet_params(tag, best);
    if (fp.miss != Miss::None) return -1;
    double sum = 0, uv[2];
    for (double &l : lam) sum += (l = std::max(l, 0.0));
    for (double &l : lam) l /= sum;
    facet_uv(fp.uvf, lam, uv);
    newton(2, tag, x, uv, 30, kFootTolerance * m_.size, &z);
    if (z.size() != 3) return -1;
    int64_t v = -1;
    double bd = HUGE_VAL;
    for (int64_t w : it->second[best]) {
      auto p = vertex(w);
      const double d = detail::dist3(p.data(), x);
      if (d < bd) bd = d, v = w;
    }
    return v;
  }

  // A point counts as over a facet if its barycentric coordinates on the
  // facet's plane are at least this negative (a node slid just past the
  // facet's edge, or a curved boundary's bulge).
  static constexpr double kFacetMargin = 0.25;

  // Barycentric coordinates l of the projection of x onto the plane of facet f.
  void barycentric(const std::array<int64_t, 3> &f, const double *x, double *l) const {
    auto a = vertex(f[0]), b = vertex(f[1]), c = vertex(f[2]);
    double u[3], w[3], r[3];
    for (int k = 0; k < 3; ++k) u[k] = b[k] - a[k], w[k] = c[k] - a[k], r[k] = x[k] - a[k];
    double uu = 0, uw = 0, ww = 0, ru = 0, rw = 0;
    for (int k = 0; k < 3; ++k) uu += u[k] * u[k], uw += u[k] * w[k], ww += w[k] * w[k], ru += r[k] * u[k], rw += r[k] * w[k];
    const double det = uu * ww - uw * uw;
    l[1] = (ru * ww - rw * uw) / det, l[2] = (rw * uu - ru * uw) / det, l[0] = 1 - l[1] - l[2];
  }

  // Gauss-Newton halves a step that does not lower the distance at most
  // this many times, unless it moved the point by less than kRoundOff of
  // the model (converged).
  static constexpr int kHalvings = 10;
  static constexpr double kRoundOff = 1e-9;

  // The local foot's Gauss-Newton stops once a step moves the point by less
  // than this fraction of the model: the next would move it less still.
  // (Iterating until a step no longer lowered the distance took 3.0
  // iterations a point from the nearest vertex on component8 at p = 3,
  // 2.6 with this stop; screw 3.7 and 3.4.)
  static constexpr double kFootTolerance = 1e-12;

  // Closest point, checked against a local search: gmsh 4.8's getClosestPoint
  // can answer a point on the far side of a closed face (4.4 away on the
  // torus, README). Gauss-Newton from the parameters of the entity's mesh
  // vertex nearest to x finds the local foot; the nearer of the two is taken.
  void closest_checked(int edim, int etag, const double *x, double *y) {
    closest(edim, etag, x, y);
    std::vector<double> z;
    if (nearest_foot(edim, etag, x, z) >= 0 && detail::dist3(z.data(), x) < detail::dist3(y, x) * (1 - 1e-9)) {
      for (int k = 0; k < 3; ++k) y[k] = z[k];
      if (placing) ++closest_replaced;
    }
  }

  static void closest(int edim, int etag, const double *x, double *y, double *param = nullptr) {
    std::vector<double> cl, uv;
    gmsh::model::getClosestPoint(edim, etag, {x[0], x[1], x[2]}, cl, uv);
    if (cl.size() != 3) throw std::runtime_error("getClosestPoint gave no point");
    for (int k = 0; k < 3; ++k) y[k] = cl[k];
    if (!param) return;
    // gmsh 4.8's getClosestPoint leaves its parametric coordinates at zero; ask for them.
    gmsh::model::getParametrization(edim, etag, cl, uv);
    for (int k = 0; k < edim; ++k) param[k] = uv.at(k);
  }

  // Gauss-Newton on |E(uv) - x|^2 over the parameters uv of entity (edim, etag),
  // from the uv given, on the entity's untrimmed parametrisation (no wrapping, so
  // uv stays in the caller's unwrapped frame). Stops when a step no longer
  // lowers the distance even halved (kHalvings), or moves the point by at
  // most `tol`; returns the final distance |E(uv) - x|, and with `foot` the
  // point E(uv). For a point on
  // the entity, started near it, this converges quadratically, and unlike
  // getClosestPoint it cannot jump to another part of the entity: gmsh 4.8's
  // getClosestPoint on a face, for a point 1e-8 outside the face's parameter
  // range (the curve the face ends on), answers the far side of a torus.
  double newton(int edim, int etag, const double *x, double *uv, int iters = 8, double tol = 0,
                std::vector<double> *foot = nullptr) const {
    std::vector<double> at(uv, uv + edim), e, d;
    gmsh::model::getValue(edim, etag, at, e);
    double dist = detail::dist3(e.data(), x);
    for (int it = 0; it < iters && dist > 0; ++it) {
      gmsh::model::getDerivative(edim, etag, at, d);
      double r[3], a[3] = {0, 0, 0}, b[2] = {0, 0}, step[2] = {0, 0};
      for (int k = 0; k < 3; ++k) r[k] = x[k] - e[k];
      for (int i = 0; i < edim; ++i) {
        for (int k = 0; k < 3; ++k) b[i] += d.at(3 * i + k) * r[k];
        for (int j = i; j < edim; ++j)
          for (int k = 0; k < 3; ++k) a[i + j] += d.at(3 * i + k) * d.at(3 * j + k);  // a = [uu, uv, vv]
      }
      if (edim == 1) {
        if (!(a[0] > 0)) break;
        step[0] = b[0] / a[0];
      } else {
        const double det = a[0] * a[2] - a[1] * a[1], big = std::max(a[0], a[2]);
        if (!(big > 0)) break;
        if (det > 1e-14 * big * big) {
          step[0] = (a[2] * b[0] - a[1] * b[1]) / det;
          step[1] = (a[0] * b[1] - a[1] * b[0]) / det;
        } else if (a[0] >= a[2]) {  // singular (a pole, where S_v vanishes): move along u only
          step[0] = b[0] / a[0];
        } else {  // a pole where S_u vanishes (sphere, cone apex): move along v only
          step[1] = b[1] / a[2];
        }
      }
      // A step that overshoots (next to a pole, where S_u is small and the
      // surface turns fast in u, the full step jumps across it) is halved
      // until it lowers the distance; one that fails by round-off ends the
      // iteration.
      std::vector<double> next(at), en;
      double dn = HUGE_VAL, moved = 0;
      for (int half = 0; half <= kHalvings; ++half) {
        for (int i = 0; i < edim; ++i) next[i] = at[i] + std::ldexp(step[i], -half);
        gmsh::model::getValue(edim, etag, next, en);
        dn = detail::dist3(en.data(), x);
        moved = detail::dist3(en.data(), e.data());
        if (dn < dist || moved <= kRoundOff * m_.size) break;
      }
      if (!(dn < dist)) break;
      at = next, e = en, dist = dn;
      if (moved <= tol) break;
    }
    for (int i = 0; i < edim; ++i) uv[i] = at[i];
    if (foot) *foot = e;
    return dist;
  }

 private:
  struct Param {       // parametrisation bounds of an entity
    double lo[2], hi[2], period[2];  // period 0: not periodic in that direction
    bool affine;                     // a plane: S(u,v) is affine in (u,v)
  };
  // Parameters of a vertex on a surface (curve: uv[0]); free[k]: the surface
  // does not depend on parameter k at the vertex (a pole of a sphere, the apex
  // of a cone: S_u = 0 there), so uv[k] is meaningless and is chosen per node.
  struct VParam {
    double uv[2];
    bool free[2];
  };
  // Why a node was not placed through the parametrisation.
  enum class Miss { None, Unlocated, Seam, Far };
  using EdgeKey = std::pair<int64_t, int64_t>;
  static EdgeKey key(int64_t a, int64_t b) { return a < b ? EdgeKey{a, b} : EdgeKey{b, a}; }

  detail::Buckets::Box box(std::initializer_list<int64_t> vs) const {
    detail::Buckets::Box b{HUGE_VAL, HUGE_VAL, HUGE_VAL, -HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (int64_t v : vs) {
      auto x = vertex(v);
      for (int k = 0; k < 3; ++k) b[k] = std::min(b[k], x[k]), b[k + 3] = std::max(b[k + 3], x[k]);
    }
    return b;
  }

  std::array<double, 3> vertex(int64_t v) const {
    std::array<double, 3> p{0, 0, 0};
    for (int k = 0; k < m_.dim; ++k) p[k] = m_.coords[m_.dim * v + k];
    return p;
  }

  const Param &param_info(int edim, int etag) {
    auto it = params_.find({edim, etag});
    if (it != params_.end()) return it->second;
    Param p{{0, 0}, {0, 0}, {0, 0}, false};
    std::vector<double> lo, hi;
    gmsh::model::getParametrizationBounds(edim, etag, lo, hi);
    if (edim == 2) {
      std::string type;
      gmsh::model::getType(edim, etag, type);
      p.affine = type == "Plane";
    }
    const double tol = 1e-9 * m_.size;
    for (int k = 0; k < edim; ++k) {
      p.lo[k] = lo.at(k);
      p.hi[k] = hi.at(k);
      // Periodic in direction k if the two ends of the parameter range meet (at 3 places across).
      bool closed = hi.at(k) > lo.at(k);
      for (double s : {0.2, 0.5, 0.8}) {
        std::vector<double> a(edim), b(edim), xa, xb;
        for (int j = 0; j < edim; ++j) a[j] = b[j] = lo.at(j) + s * (hi.at(j) - lo.at(j));
        a[k] = lo.at(k);
        b[k] = hi.at(k);
        gmsh::model::getValue(edim, etag, a, xa);
        gmsh::model::getValue(edim, etag, b, xb);
        if (detail::dist3(xa.data(), xb.data()) > tol) closed = false;
        if (edim == 1) break;
      }
      if (closed) p.period[k] = hi.at(k) - lo.at(k);
    }
    return params_.emplace(std::make_pair(edim, etag), p).first->second;
  }

  // The mesh vertex of entity (edim, etag) nearest to x (its edges or facets
  // near x first, all of them if none is), or -1 if the entity has none.
  int64_t nearest_vertex(int edim, int etag, const double *x) const {
    int64_t best = -1;
    double bd = HUGE_VAL;
    auto consider = [&](int64_t v) {
      auto p = vertex(v);
      const double d = detail::dist3(p.data(), x);
      if (d < bd) bd = d, best = v;
    };
    if (edim == 1) {
      auto it = curve_edges_.find(etag);
      if (it == curve_edges_.end()) return -1;
      auto &cand = curve_buckets_.at(etag).query(x);
      if (!cand.empty())
        for (std::size_t i : cand) consider(it->second[i].first), consider(it->second[i].second);
      else
        for (auto &e : it->second) consider(e.first), consider(e.second);
    } else {
      auto it = surface_facets_.find(etag);
      if (it == surface_facets_.end()) return -1;
      auto &cand = surface_buckets_.at(etag).query(x);
      if (!cand.empty())
        for (std::size_t i : cand)
          for (int64_t v : it->second[i]) consider(v);
      else
        for (auto &f : it->second)
          for (int64_t v : f) consider(v);
    }
    return best;
  }

  // Parameter(s) of vertex v on entity (edim, etag), cached.
  const VParam &vertex_param(int edim, int etag, int64_t v) {
    auto k = std::make_tuple(edim, etag, v);
    auto it = vparam_.find(k);
    if (it != vparam_.end()) return it->second;
    auto x = vertex(v);
    double y[3];
    VParam r{{0, 0}, {false, false}};
    // Start from gmsh's own parameters of the vertex: on the entity itself,
    // or reparametrised from the curve or point it is classified on onto the
    // surface (cheap: the curve's p-curve), then Gauss-Newton. Only if that
    // does not land on the vertex, a global closest point (two orders of
    // magnitude dearer on B-spline faces).
    if (!guess_param(edim, etag, v, x.data(), r.uv)) {
      closest(edim, etag, x.data(), y, r.uv);
      // getClosestPoint's parameter is only good to ~1e-8 (the end vertex of a
      // torus seam came back 1.8e-8 off, its parameter outside the curve's range).
      newton(edim, etag, x.data(), r.uv);
    }
    if (edim == 2) {
      // A singular point: sweeping parameter k over its whole range moves the
      // point by less than 1e-9 of the model (at a sphere's pole, refined by
      // the rank-1 Gauss-Newton step, |S_u| is ~1e-16).
      const Param &p = param_info(2, etag);
      std::vector<double> d;
      gmsh::model::getDerivative(2, etag, {r.uv[0], r.uv[1]}, d);
      for (int j = 0; j < 2; ++j) {
        const double n = std::sqrt(d.at(3 * j) * d.at(3 * j) + d.at(3 * j + 1) * d.at(3 * j + 1) + d.at(3 * j + 2) * d.at(3 * j + 2));
        r.free[j] = n * (p.hi[j] - p.lo[j]) <= 1e-9 * m_.size;
      }
      if (r.free[0] && r.free[1]) r.free[0] = r.free[1] = false;  // degenerate everywhere: no choice to make
    }
    return vparam_[k] = r;
  }

  // Parameters of vertex v (at x) on entity (edim, etag) from gmsh's
  // classification of it, refined by Gauss-Newton; false unless they map to
  // within 1e-3 of the model's size of x. STEP parts' curves lie off their
  // faces by up to ~4e-4 of the model (U_Joint_2's by 0.021 in 139, the
  // crankshaft's by 0.18): there Gauss-Newton lands on the foot of the
  // vertex on the face, the parameters a global closest point would give
  // (to 1e-7 at all 186 such vertices of the five parts at p = 2), at a
  // fortieth of its cost, and on the side of a seam that the curve's
  // p-curve says.
  bool guess_param(int edim, int etag, int64_t v, const double *x, double *uv) {
    if (m_.node_dim.size() <= std::size_t(v)) return false;
    const int nd = m_.node_dim[v], nt = m_.node_tag[v];
    if (nd == edim && nt == etag) {
      uv[0] = m_.node_uv[2 * v], uv[1] = m_.node_uv[2 * v + 1];
    } else if (edim == 2 && (nd == 0 || nd == 1)) {
      std::vector<double> out;
      try {
        std::vector<double> in;
        if (nd == 1) in.push_back(m_.node_uv[2 * v]);
        gmsh::model::reparametrizeOnSurface(nd, nt, in, etag, out, 0);
      } catch (...) {
        return false;
      }
      if (out.size() != 2) return false;
      uv[0] = out[0], uv[1] = out[1];
    } else {
      return false;
    }
    return newton(edim, etag, x, uv) <= 1e-3 * m_.size;
  }

  // The point at fraction t of mesh edge (a, b) of CAD curve `tag`, through the curve's parameter.
  std::array<double, 3> curve_point(int tag, int64_t a, int64_t b, double t) {
    const Param &p = param_info(1, tag);
    double ua = vertex_param(1, tag, a).uv[0], ub = vertex_param(1, tag, b).uv[0];
    ub = detail::unwrap(ub, ua, p.period[0]);
    double u = detail::wrap(ua + t * (ub - ua), p.lo[0], p.period[0]);
    std::vector<double> xyz;
    gmsh::model::getValue(1, tag, {u}, xyz);
    return {xyz.at(0), xyz.at(1), xyz.at(2)};
  }

  Miss place_on_curve(int tag, const double *x, double *y) {
    auto it = curve_edges_.find(tag);
    if (it == curve_edges_.end()) return Miss::Unlocated;
    const std::pair<int64_t, int64_t> *best = nullptr;
    double best_d = 0, best_t = 0;
    for (std::size_t i : curve_buckets_.at(tag).query(x)) {
      auto &e = it->second[i];
      auto a = vertex(e.first), b = vertex(e.second);
      double ab2 = 0, t = 0;
      for (int k = 0; k < 3; ++k) ab2 += (b[k] - a[k]) * (b[k] - a[k]), t += (x[k] - a[k]) * (b[k] - a[k]);
      t /= ab2;
      if (t < -1e-9 || t > 1 + 1e-9) continue;
      double q[3];
      for (int k = 0; k < 3; ++k) q[k] = a[k] + t * (b[k] - a[k]);
      double d = detail::dist3(q, x);
      if (d > 1e-8 * std::sqrt(ab2)) continue;
      if (!best || d < best_d) best = &e, best_d = d, best_t = t;
    }
    if (!best) return Miss::Unlocated;
    auto a = vertex(best->first), b = vertex(best->second);
    auto q = curve_point(tag, best->first, best->second, best_t);
    if (detail::dist3(q.data(), x) > 0.5 * detail::dist3(a.data(), b.data())) return Miss::Far;
    for (int k = 0; k < 3; ++k) y[k] = q[k];
    return Miss::None;
  }

  Miss place_on_surface(int tag, const double *x, double *y) {
    auto it = surface_facets_.find(tag);
    if (it == surface_facets_.end()) return Miss::Unlocated;
    // The facets holding x (one inside a facet, two on an edge, more at a vertex); best: the most inside.
    std::size_t best = 0, found = 0;
    double lam[3] = {0, 0, 0}, best_score = -1;
    std::size_t holding[8];
    for (std::size_t i : surface_buckets_.at(tag).query(x)) {
      auto &f = it->second[i];
      auto a = vertex(f[0]), b = vertex(f[1]), c = vertex(f[2]);
      double l[3], q[3];
      barycentric(f, x, l);
      const double score = std::min({l[0], l[1], l[2]});
      if (score < -1e-9) continue;
      for (int k = 0; k < 3; ++k) q[k] = l[0] * a[k] + l[1] * b[k] + l[2] * c[k];
      if (detail::dist3(q, x) > 1e-8 * std::max(detail::dist3(a.data(), b.data()), detail::dist3(a.data(), c.data()))) continue;
      if (found < 8) holding[found] = i;
      if (!found++ || score > best_score) best = i, best_score = score, lam[0] = l[0], lam[1] = l[1], lam[2] = l[2];
    }
    if (!found) return Miss::Unlocated;
    const auto &f = it->second[best];
    const FacetInfo &info = facet_info(tag, best);
    if (info.miss != Miss::None) return info.miss;
    // A node on an edge is projected if a facet of the edge is distorted, so
    // that its place does not depend on which facet was found.
    bool distorted = false;
    for (std::size_t h = 0; h < std::min<std::size_t>(found, 8); ++h) distorted = distorted || projected_facet(tag, holding[h]);
    const Param &p = param_info(2, tag);
    const Facet &uvf = info.uvf;
    double target[2], shift[3] = {0, 0, 0};
    facet_uv(uvf, lam, target);
    // Blend the facet's edges into it (transfinite, Gordon-Hall): an edge on a
    // CAD curve by its curve point, in (u,v) for the parametric placement and
    // in space (`shift`) for the projected one; in a parametric facet, an edge
    // shared with a projected facet by the foot of its straight point, so the
    // facet meets the nodes that edge got.
    for (int e = 0; e < 3; ++e) {
      const int i = e, j = (e + 1) % 3;
      auto fe = feature_.find(key(f[i], f[j]));
      const double s = lam[i] + lam[j];
      if (s < 1e-12) continue;
      const double t = lam[j] / s;
      auto va = vertex(f[i]), vb = vertex(f[j]);
      double le[3] = {0, 0, 0}, lin[2], uve[2];
      le[i] = 1 - t, le[j] = t;
      facet_uv(uvf, le, lin);
      for (int k = 0; k < 2; ++k) uve[k] = lin[k];
      if (fe == feature_.end()) {
        if (distorted || !projected_edge(tag, f[i], f[j])) continue;
        double xe[3];
        for (int k = 0; k < 3; ++k) xe[k] = (1 - t) * va[k] + t * vb[k];
        newton(2, tag, xe, uve, 20);
        for (int k = 0; k < 2; ++k) target[k] += s * (uve[k] - lin[k]);
        continue;
      }
      auto ye = curve_point(fe->second, f[i], f[j], t);
      for (int k = 0; k < 3; ++k) shift[k] += s * (ye[k] - ((1 - t) * va[k] + t * vb[k]));
      // (u,v) of the curve point: Gauss-Newton from the edge's linear (u,v),
      // already unwrapped; closest point (unwrapped) only if that does not
      // come within 5 % of the edge, which rules out a wrong local minimum
      // (the far side of a closed face is about a diameter away). A curve
      // lies on its face to the CAD's tolerance, ~1e-13 on the models here
      // but 1.2e-3 of a unit edge on one face of wrenchnut, where a bound
      // of 1e-3 sent 1501 points through gmsh's global closest point, a
      // quarter of the run at p = 2.
      if (!(newton(2, tag, ye.data(), uve) <= 5e-2 * detail::dist3(va.data(), vb.data()))) {
        double z[3];
        closest(2, tag, ye.data(), z, uve);
        for (int k = 0; k < 2; ++k) uve[k] = detail::unwrap(uve[k], lin[k], p.period[k]);
      }
      for (int k = 0; k < 2; ++k) target[k] += s * (uve[k] - lin[k]);
    }
    if (distorted) {
      // The foot of the blended point on the surface, by Gauss-Newton from the
      // parametric guess (local: it cannot jump to another part of the face).
      double xb[3];
      for (int k = 0; k < 3; ++k) xb[k] = x[k] + shift[k];
      newton(2, tag, xb, target, 20);
    }
    for (int k = 0; k < 2; ++k) target[k] = detail::wrap(target[k], p.lo[k], p.period[k]);
    std::vector<double> xyz;
    gmsh::model::getValue(2, tag, {target[0], target[1]}, xyz);
    if (xyz.size() != 3 || detail::dist3(xyz.data(), x) > 0.5 * info.diam) return Miss::Far;
    for (int k = 0; k < 3; ++k) y[k] = xyz[k];
    if (distorted && placing) ++projected;
    return Miss::None;
  }

  // A facet's vertex parameters, unwrapped, with their free directions.
  struct Facet {
    double uv[3][2];
    bool free[3][2];
  };

  // What the parametric placement needs of a facet, computed once.
  struct FacetInfo {
    Facet uvf;                 // vertex parameters, unwrapped, free directions
    Miss miss = Miss::None;    // Seam: no parametric placement (ambiguous or all-pole facet)
    bool distorted = false;    // the parametrisation is too far from affine over the facet
    double distortion = 0;     // its measure (below), over the facet's diameter
    double diam = 0;           // longest edge
  };

  // A facet's vertex parameters, unwrapped into one common period, with
  // their free directions: Miss::Seam if there is no such period (see
  // facet_info); seam: it straddles the seam; pole: a vertex is on a
  // singular point. Computed once, and counted nowhere (facet_info counts
  // the facets the placement uses; the local foot uses these too).
  struct FacetParams {
    Facet uvf;
    Miss miss = Miss::None;
    bool seam = false, pole = false;
  };
  const FacetParams &facet_params(int tag, std::size_t idx) {
    auto key = std::make_pair(tag, idx);
    auto it = facet_params_.find(key);
    if (it != facet_params_.end()) return it->second;
    FacetParams fp;
    const auto &f = surface_facets_.at(tag)[idx];
    const Param &p = param_info(2, tag);
    for (int i = 0; i < 3; ++i) {
      const VParam &vp = vertex_param(2, tag, f[i]);
      for (int k = 0; k < 2; ++k) fp.uvf.uv[i][k] = vp.uv[k], fp.uvf.free[i][k] = vp.free[k];
      fp.pole = fp.pole || vp.free[0] || vp.free[1];
    }
    for (int k = 0; k < 2 && fp.miss == Miss::None; ++k) {
      int n = 0;
      for (int i = 0; i < 3; ++i) n += !fp.uvf.free[i][k];
      const int u = n > 0 && p.period[k] > 0 ? unwrap_shortest(fp.uvf, k, p.lo[k], p.period[k]) : 0;
      if (n == 0 || u < 0) fp.miss = Miss::Seam;
      fp.seam = fp.seam || u > 0;
    }
    return facet_params_.emplace(key, fp).first->second;
  }

  // Facet `idx` of surface `tag`: vertex parameters in one common period
  // (see unwrap_shortest; a vertex on a singular point, a sphere's pole or a
  // cone's apex, is left out of its free direction and takes, at each node,
  // the λ-weighted parameter of the other vertices: `facet_uv`), and whether
  // the (u,v)-linear map is distorted: at the facet's centroid and edge
  // midpoints, S of the linear (u,v) lies more than kDistortion of the facet
  // from the foot of the straight point on the surface. Near a pole the
  // parametrisation is far from affine (a facet next to a sphere's pole has its
  // edge midpoint on a circle of latitude, 16 % of the edge away from the great
  // circle), and its facets are placed by projection instead.
  const FacetInfo &facet_info(int tag, std::size_t idx) {
    auto key = std::make_pair(tag, idx);
    auto it = facet_info_.find(key);
    if (it != facet_info_.end()) return it->second;
    FacetInfo info;
    const auto &f = surface_facets_.at(tag)[idx];
    const FacetParams &fp = facet_params(tag, idx);
    const Facet &uvf = info.uvf = fp.uvf;
    info.miss = fp.miss;
    const bool seam = fp.seam, pole = fp.pole;
    for (int i = 0; i < 3; ++i) {
      auto a = vertex(f[i]), b = vertex(f[(i + 1) % 3]);
      info.diam = std::max(info.diam, detail::dist3(a.data(), b.data()));
    }
    if (seam) ++seam_facets;
    if (info.miss == Miss::None && pole) ++pole_facets;
    // A plane's parametrisation is affine: its facets are not distorted, and
    // are not sampled (a third of U_Joint_2's facets, half the crankshaft's).
    if (info.miss == Miss::None && !param_info(2, tag).affine) {
      static const double samples[4][3] = {{1 / 3., 1 / 3., 1 / 3.}, {0.5, 0.5, 0}, {0, 0.5, 0.5}, {0.5, 0, 0.5}};
      double worst = 0;
      for (auto &l : samples) {
        double uv[2], foot[2], xl[3] = {0, 0, 0};
        facet_uv(uvf, l, uv);
        for (int i = 0; i < 3; ++i) {
          auto v = vertex(f[i]);
          for (int k = 0; k < 3; ++k) xl[k] += l[i] * v[k];
        }
        foot[0] = uv[0], foot[1] = uv[1];
        // To a thousandth of the distortion that counts: a step that moves
        // the foot by less ends the iteration (to round-off, three or four
        // more evaluations of the surface and its derivatives).
        newton(2, tag, xl, foot, 20, 1e-3 * kDistortion * info.diam);
        std::vector<double> a, b;
        gmsh::model::getValue(2, tag, {uv[0], uv[1]}, a);
        gmsh::model::getValue(2, tag, {foot[0], foot[1]}, b);
        worst = std::max(worst, detail::dist3(a.data(), b.data()));
      }
      info.distortion = worst / info.diam;
      info.distorted = info.distortion > kDistortion;
      if (info.distorted) ++distorted_facets;
    }
    return facet_info_.emplace(key, info).first->second;
  }

  bool projected_facet(int tag, std::size_t idx) {
    const FacetInfo &fi = facet_info(tag, idx);
    return fi.miss != Miss::None || fi.distorted;
  }
  // A mesh edge inside surface `tag` whose nodes are projected: one of its facets is.
  bool projected_edge(int tag, int64_t a, int64_t b) {
    for (auto &tf : edge_facets_.at(key(a, b)))
      if (tf.first == tag && projected_facet(tag, tf.second)) return true;
    return false;
  }

  // Unwrap direction k (period `period`) of the facet's non-free vertices to
  // the shortest arc that holds them: cut the circle of parameters at the
  // widest gap between them. Returns 1 if that arc crosses the seam (lo ≡ lo +
  // period: the facet straddles it), 0 if not, -1 if the arc is longer than
  // half a period (the facet's place on the circle is ambiguous).
  static int unwrap_shortest(Facet &f, int k, double lo, double period) {
    std::vector<std::pair<double, int>> w;
    for (int i = 0; i < 3; ++i)
      if (!f.free[i][k]) w.push_back({detail::wrap(f.uv[i][k], lo, period), i});
    std::sort(w.begin(), w.end());
    const std::size_t n = w.size();
    std::size_t start = 0;  // the arc starts after the widest gap
    double gap = w[0].first + period - w[n - 1].first;
    for (std::size_t i = 1; i < n; ++i)
      if (w[i].first - w[i - 1].first > gap) gap = w[i].first - w[i - 1].first, start = i;
    if (period - gap > 0.5 * period) return -1;
    for (std::size_t i = 0; i < n; ++i) f.uv[w[i].second][k] = w[i].first + (i < start ? period : 0.0);
    return start != 0;
  }

  // (u,v) of the facet at barycentric coordinates l: Σ l_i (u,v)_i, where the
  // parameter of a vertex in a free direction (a pole) is the l-weighted mean
  // of the other vertices' (so an edge from a pole follows a meridian).
  static void facet_uv(const Facet &f, const double *l, double *uv) {
    for (int k = 0; k < 2; ++k) {
      double sw = 0, s = 0;
      for (int i = 0; i < 3; ++i)
        if (!f.free[i][k]) sw += l[i], s += l[i] * f.uv[i][k];
      const double mean = sw > 1e-300 ? s / sw : 0.0;
      uv[k] = 0;
      for (int i = 0; i < 3; ++i) uv[k] += l[i] * (f.free[i][k] ? mean : f.uv[i][k]);
    }
  }

  const LinearMesh &m_;
  std::map<int, std::vector<std::pair<int64_t, int64_t>>> curve_edges_;
  std::map<int, std::vector<std::array<int64_t, 3>>> surface_facets_;
  std::map<int, detail::Buckets> curve_buckets_, surface_buckets_;
  std::map<EdgeKey, int> feature_;
  std::map<std::pair<int, int>, Param> params_;
  std::map<std::pair<int, std::size_t>, FacetParams> facet_params_;
  std::map<std::tuple<int, int, int64_t>, VParam> vparam_;
  std::map<std::pair<int, std::size_t>, FacetInfo> facet_info_;
  std::map<EdgeKey, std::vector<std::pair<int, std::size_t>>> edge_facets_;  // (surface, facet index)
};

// hocurve's projector: places the points of a batch on gmsh entity
// (entity_dim, entity_tag), by `placement` (Parametric needs `placer`).
// Points have `mesh_dim` coordinates (2D models lie in z = 0). Any gmsh error,
// a wrong-sized answer or a non-finite coordinate gives a nonzero return
// (hocurve then stops with HOC_ERROR_PROJECTION); nothing unwinds into hocurve.
struct Projector {
  int mesh_dim = 3;
  Placement placement = Placement::Parametric;
  std::unique_ptr<Placer> placer;  // made by make_mesh
  int fail_tag = -1;  // tests: fail on this entity tag (of dimension fail_dim)
  int fail_dim = -1;
  std::size_t calls = 0, points = 0;
  double seconds = 0.0;  // wall time inside the callback (hocurve calls it from one thread at a time)

  static int callback(void *user, int entity_dim, int entity_tag, size_t n, const double *in, double *out) {
    auto *self = static_cast<Projector *>(user);
    const auto t0 = std::chrono::steady_clock::now();
    struct Clock {  // adds the call's time on every return path
      Projector *p;
      std::chrono::steady_clock::time_point t0;
      ~Clock() { p->seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }
    } clock{self, t0};
    try {
      ++self->calls;
      self->points += n;
      if (entity_dim == self->fail_dim && entity_tag == self->fail_tag) return 1;
      const int d = self->mesh_dim;
      std::vector<double> xyz(3 * n, 0.0), closest, uv;
      for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < d; ++k) xyz[3 * i + k] = in[d * i + k];
      if (self->placer) {
        closest.resize(3 * n);
        for (size_t i = 0; i < n; ++i)
          if (self->placement == Placement::Parametric && self->placer->placing)
            self->placer->place(entity_dim, entity_tag, &xyz[3 * i], &closest[3 * i]);
          else if (self->placer->placing || !self->placer->local_foot(entity_dim, entity_tag, &xyz[3 * i], &closest[3 * i]))
            self->placer->closest_checked(entity_dim, entity_tag, &xyz[3 * i], &closest[3 * i]);
      } else {
        gmsh::model::getClosestPoint(entity_dim, entity_tag, xyz, closest, uv);
      }
      if (closest.size() != 3 * n) return 2;
      for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < d; ++k) {
          double v = closest[3 * i + k];
          if (!std::isfinite(v)) return 3;
          out[d * i + k] = v;
        }
      return 0;
    } catch (...) {
      return 4;
    }
  }
};

// Set up a hocurve mesh from the collected linear mesh (which must outlive it:
// the projector reads it). Its progress callback ends the placement when
// hocurve's projection stage (1) is over: later projector calls slide nodes
// in the optimisation (Placer::placing); and starts it again at each run's
// first stage (0). A host that sets its own progress callback must do both
// itself.
inline hocurve::Mesh make_mesh(const LinearMesh &m, Projector &proj) {
  hocurve::Mesh mesh(m.dim, m.coords, m.cells);
  mesh.set_boundary(m.facets, m.facet_tags);
  if (!m.edges.empty()) mesh.set_feature_edges(m.edges, m.edge_tags);
  proj.mesh_dim = m.dim;
  proj.placer.reset(new Placer(m));
  Projector *pp = &proj;
  mesh.set_projector([pp](int dim, int tag, std::size_t n, const double *in, double *out) {
    return Projector::callback(pp, dim, tag, n, in, out);
  });
  mesh.set_progress([pp](int stage, int, int) {
    if (!pp->placer) return 0;
    if (stage == HOC_STAGE_ELEVATE) pp->placer->start_run();
    else if (stage > HOC_STAGE_PROJECT) pp->placer->placing = false;
    return 0;
  });
  return mesh;
}

}  // namespace occt

#endif

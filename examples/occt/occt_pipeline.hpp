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
//  - Closest: the closest point to the straight-sided node (gmsh::model::getClosestPoint).
//  - Parametric: through the CAD parametrisation of the linear edge or facet
//    the node lies on. A node at fraction t of a mesh edge on a CAD curve goes
//    to C(u_a + t (u_b - u_a)), u_a, u_b the parameters of the edge's vertices
//    (on a circle: equal angles, so GLL nodes stay GLL in arc length). A node
//    inside a facet on a CAD surface, with barycentric coordinates λ, goes to
//    S(Σ λ_k (u,v)_k + Σ_e (λ_i + λ_j) [(u,v)(y_e) − lin_e]) where e = (i, j)
//    runs over the facet's edges on CAD curves, y_e is the curve point of the
//    edge at t = λ_j / (λ_i + λ_j), and lin_e the linear interpolation of the
//    edge's (u,v) at t: the edge's curvature is blended into the facet, as in a
//    transfinite (Gordon–Hall) map. Without the blend, a facet on a plane
//    whose edge follows a circle keeps its interior nodes straight while its
//    edge bulges inwards, and at p = 5 that facet, whose nodes are all
//    prescribed, folds (see README). A node the parametric placement cannot
//    handle (not on a known edge or facet, or placed farther than half the
//    element from its straight position) falls back to the closest point.
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
      for (std::size_t f = 0; f < m.facet_tags.size(); ++f)
        surface_facets_[m.facet_tags[f]].push_back({m.facets[3 * f], m.facets[3 * f + 1], m.facets[3 * f + 2]});
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

  std::size_t fallbacks = 0;  // nodes placed by closest point for want of a parametric placement

  // Place point x (3 coordinates) on entity (edim, etag) into y (3 coordinates).
  void place(int edim, int etag, const double *x, double *y) {
    if (edim == 1 && place_on_curve(etag, x, y)) return;
    if (edim == 2 && m_.dim == 3 && place_on_surface(etag, x, y)) return;
    ++fallbacks;
    closest(edim, etag, x, y);
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

 private:
  struct Param {       // parametrisation bounds of an entity
    double lo[2], period[2];  // period 0: not periodic in that direction
  };
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
    Param p{{0, 0}, {0, 0}};
    std::vector<double> lo, hi;
    gmsh::model::getParametrizationBounds(edim, etag, lo, hi);
    const double tol = 1e-9 * m_.size;
    for (int k = 0; k < edim; ++k) {
      p.lo[k] = lo.at(k);
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

  // Parameter(s) of vertex v on entity (edim, etag), cached.
  std::array<double, 2> vertex_param(int edim, int etag, int64_t v) {
    auto k = std::make_tuple(edim, etag, v);
    auto it = vparam_.find(k);
    if (it != vparam_.end()) return it->second;
    auto x = vertex(v);
    double y[3], uv[2] = {0, 0};
    closest(edim, etag, x.data(), y, uv);
    return vparam_[k] = {uv[0], uv[1]};
  }

  // The point at fraction t of mesh edge (a, b) of CAD curve `tag`, through the curve's parameter.
  std::array<double, 3> curve_point(int tag, int64_t a, int64_t b, double t) {
    const Param &p = param_info(1, tag);
    double ua = vertex_param(1, tag, a)[0], ub = vertex_param(1, tag, b)[0];
    ub = detail::unwrap(ub, ua, p.period[0]);
    double u = detail::wrap(ua + t * (ub - ua), p.lo[0], p.period[0]);
    std::vector<double> xyz;
    gmsh::model::getValue(1, tag, {u}, xyz);
    return {xyz.at(0), xyz.at(1), xyz.at(2)};
  }

  bool place_on_curve(int tag, const double *x, double *y) {
    auto it = curve_edges_.find(tag);
    if (it == curve_edges_.end()) return false;
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
    if (!best) return false;
    auto a = vertex(best->first), b = vertex(best->second);
    auto q = curve_point(tag, best->first, best->second, best_t);
    if (detail::dist3(q.data(), x) > 0.5 * detail::dist3(a.data(), b.data())) return false;
    for (int k = 0; k < 3; ++k) y[k] = q[k];
    return true;
  }

  bool place_on_surface(int tag, const double *x, double *y) {
    auto it = surface_facets_.find(tag);
    if (it == surface_facets_.end()) return false;
    const std::array<int64_t, 3> *best = nullptr;
    double lam[3] = {0, 0, 0}, best_score = -1;
    for (std::size_t i : surface_buckets_.at(tag).query(x)) {
      auto &f = it->second[i];
      auto a = vertex(f[0]), b = vertex(f[1]), c = vertex(f[2]);
      double u[3], w[3], r[3];
      for (int k = 0; k < 3; ++k) u[k] = b[k] - a[k], w[k] = c[k] - a[k], r[k] = x[k] - a[k];
      double uu = 0, uw = 0, ww = 0, ru = 0, rw = 0;
      for (int k = 0; k < 3; ++k) uu += u[k] * u[k], uw += u[k] * w[k], ww += w[k] * w[k], ru += r[k] * u[k], rw += r[k] * w[k];
      const double det = uu * ww - uw * uw;
      const double s = (ru * ww - rw * uw) / det, t = (rw * uu - ru * uw) / det;
      const double l[3] = {1 - s - t, s, t};
      const double score = std::min({l[0], l[1], l[2]});
      if (score < -1e-9) continue;
      double q[3];
      for (int k = 0; k < 3; ++k) q[k] = a[k] + s * u[k] + t * w[k];
      if (detail::dist3(q, x) > 1e-8 * std::sqrt(std::max(uu, ww))) continue;
      if (score > best_score) best = &f, best_score = score, lam[0] = l[0], lam[1] = l[1], lam[2] = l[2];
    }
    if (!best) return false;
    const auto &f = *best;
    const Param &p = param_info(2, tag);
    std::array<double, 2> uv[3];
    for (int i = 0; i < 3; ++i) {
      uv[i] = vertex_param(2, tag, f[i]);
      for (int k = 0; k < 2; ++k) uv[i][k] = detail::unwrap(uv[i][k], uv[0][k], p.period[k]);
    }
    double target[2] = {0, 0};
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 2; ++k) target[k] += lam[i] * uv[i][k];
    // Blend the curvature of the facet's edges on CAD curves into the facet.
    for (int e = 0; e < 3; ++e) {
      const int i = e, j = (e + 1) % 3;
      auto fe = feature_.find(key(f[i], f[j]));
      const double s = lam[i] + lam[j];
      if (fe == feature_.end() || s < 1e-12) continue;
      const double t = lam[j] / s;
      auto ye = curve_point(fe->second, f[i], f[j], t);
      double z[3], uve[2];
      closest(2, tag, ye.data(), z, uve);
      for (int k = 0; k < 2; ++k) {
        const double lin = (1 - t) * uv[i][k] + t * uv[j][k];
        target[k] += s * (detail::unwrap(uve[k], lin, p.period[k]) - lin);
      }
    }
    for (int k = 0; k < 2; ++k) target[k] = detail::wrap(target[k], p.lo[k], p.period[k]);
    std::vector<double> xyz;
    gmsh::model::getValue(2, tag, {target[0], target[1]}, xyz);
    double diam = 0;
    for (int i = 0; i < 3; ++i) {
      auto a = vertex(f[i]), b = vertex(f[(i + 1) % 3]);
      diam = std::max(diam, detail::dist3(a.data(), b.data()));
    }
    if (xyz.size() != 3 || detail::dist3(xyz.data(), x) > 0.5 * diam) return false;
    for (int k = 0; k < 3; ++k) y[k] = xyz[k];
    return true;
  }

  const LinearMesh &m_;
  std::map<int, std::vector<std::pair<int64_t, int64_t>>> curve_edges_;
  std::map<int, std::vector<std::array<int64_t, 3>>> surface_facets_;
  std::map<int, detail::Buckets> curve_buckets_, surface_buckets_;
  std::map<EdgeKey, int> feature_;
  std::map<std::pair<int, int>, Param> params_;
  std::map<std::tuple<int, int, int64_t>, std::array<double, 2>> vparam_;
};

// hocurve's projector: places the points of a batch on gmsh entity
// (entity_dim, entity_tag), by `placement` (Parametric needs `placer`).
// Points have `mesh_dim` coordinates (2D models lie in z = 0). Any gmsh error,
// a wrong-sized answer or a non-finite coordinate gives a nonzero return
// (hocurve then stops with HOC_ERROR_PROJECTION); nothing unwinds into hocurve.
struct Projector {
  int mesh_dim = 3;
  Placement placement = Placement::Parametric;
  std::unique_ptr<Placer> placer;  // made by make_mesh for Placement::Parametric
  int fail_tag = -1;  // tests: fail on this entity tag (of dimension fail_dim)
  int fail_dim = -1;
  std::size_t calls = 0, points = 0;

  static int callback(void *user, int entity_dim, int entity_tag, size_t n, const double *in, double *out) {
    auto *self = static_cast<Projector *>(user);
    try {
      ++self->calls;
      self->points += n;
      if (entity_dim == self->fail_dim && entity_tag == self->fail_tag) return 1;
      const int d = self->mesh_dim;
      std::vector<double> xyz(3 * n, 0.0), closest, uv;
      for (size_t i = 0; i < n; ++i)
        for (int k = 0; k < d; ++k) xyz[3 * i + k] = in[d * i + k];
      if (self->placement == Placement::Parametric && self->placer) {
        closest.resize(3 * n);
        for (size_t i = 0; i < n; ++i) self->placer->place(entity_dim, entity_tag, &xyz[3 * i], &closest[3 * i]);
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
// the projector reads it).
inline hocurve::Mesh make_mesh(const LinearMesh &m, Projector &proj) {
  hocurve::Mesh mesh(m.dim, m.coords, m.cells);
  mesh.set_boundary(m.facets, m.facet_tags);
  if (!m.edges.empty()) mesh.set_feature_edges(m.edges, m.edge_tags);
  proj.mesh_dim = m.dim;
  proj.placer.reset(proj.placement == Placement::Parametric ? new Placer(m) : nullptr);
  Projector *pp = &proj;
  mesh.set_projector([pp](int dim, int tag, std::size_t n, const double *in, double *out) {
    return Projector::callback(pp, dim, tag, n, in, out);
  });
  return mesh;
}

}  // namespace occt

#endif

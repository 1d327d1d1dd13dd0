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
#include <map>
#include <stdexcept>
#include <string>
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

// hocurve's projector: closest points on gmsh entity (entity_dim, entity_tag).
// Points have `mesh_dim` coordinates (2D models lie in z = 0). Any gmsh error,
// a wrong-sized answer or a non-finite coordinate gives a nonzero return
// (hocurve then stops with HOC_ERROR_PROJECTION); nothing unwinds into hocurve.
struct Projector {
  int mesh_dim = 3;
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
      gmsh::model::getClosestPoint(entity_dim, entity_tag, xyz, closest, uv);
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

// Set up a hocurve mesh from the collected linear mesh.
inline hocurve::Mesh make_mesh(const LinearMesh &m, Projector &proj) {
  hocurve::Mesh mesh(m.dim, m.coords, m.cells);
  mesh.set_boundary(m.facets, m.facet_tags);
  if (!m.edges.empty()) mesh.set_feature_edges(m.edges, m.edge_tags);
  proj.mesh_dim = m.dim;
  Projector *pp = &proj;
  mesh.set_projector([pp](int dim, int tag, std::size_t n, const double *in, double *out) {
    return Projector::callback(pp, dim, tag, n, in, out);
  });
  return mesh;
}

}  // namespace occt

#endif

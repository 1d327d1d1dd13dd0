// Test models, built with gmsh's OpenCASCADE kernel and exported to STEP (no
// CAD file is downloaded): a filleted plate with two holes, a sphere fused
// with a torus, and a 2D plate with a circular and an elliptic hole.
#ifndef HOCURVE_OCCT_MODELS_HPP
#define HOCURVE_OCCT_MODELS_HPP

#include <gmsh.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace occt {

// (a) Mechanical part: a 4 x 2 x 1 block, its four vertical edges filleted
// (r = 0.4), with two through holes (r = 0.3): planes, cylinders, fillets.
inline void build_part() {
  int box = gmsh::model::occ::addBox(0, 0, 0, 4, 2, 1);
  gmsh::model::occ::synchronize();
  gmsh::vectorpair curves;
  gmsh::model::occ::getEntities(curves, 1);
  std::vector<int> vertical;
  for (auto &c : curves) {
    double x0, y0, z0, x1, y1, z1;
    gmsh::model::occ::getBoundingBox(1, c.second, x0, y0, z0, x1, y1, z1);
    if (z1 - z0 > 0.9 && x1 - x0 < 1e-6 && y1 - y0 < 1e-6) vertical.push_back(c.second);
  }
  gmsh::vectorpair out, map;
  gmsh::model::occ::fillet({box}, vertical, {0.4}, out);
  int h1 = gmsh::model::occ::addCylinder(1.2, 1, -0.5, 0, 0, 2, 0.3);
  int h2 = gmsh::model::occ::addCylinder(2.8, 1, -0.5, 0, 0, 2, 0.3);
  std::vector<gmsh::vectorpair> m;
  gmsh::model::occ::cut(out, {{3, h1}, {3, h2}}, map, m);
  gmsh::model::occ::synchronize();
}

// (b) A torus (R = 1.5, r = 0.7) with a sphere (r = 1, same centre) cut out
// of its inner side: an outer torus patch and a concave sphere patch meeting on
// two circles. (Fusing a sphere with a torus fails inside OpenCASCADE 7.6:
// "BRep_Tool:: TopoDS_Vertex hasn't gp_Pnt"; the cut works.)
inline void build_sphere_torus() {
  int s = gmsh::model::occ::addSphere(0, 0, 0, 1);
  int t = gmsh::model::occ::addTorus(0, 0, 0, 1.5, 0.7);
  gmsh::vectorpair out;
  std::vector<gmsh::vectorpair> m;
  gmsh::model::occ::cut({{3, t}}, {{3, s}}, out, m);
  gmsh::model::occ::synchronize();
}

// (c) 2D: a 4 x 2 plate in z = 0 with a circular (r = 0.4) and an elliptic
// (0.5 x 0.3) hole.
inline void build_plate() {
  int r = gmsh::model::occ::addRectangle(0, 0, 0, 4, 2);
  int d1 = gmsh::model::occ::addDisk(1, 1, 0, 0.4, 0.4);
  int d2 = gmsh::model::occ::addDisk(3, 1, 0, 0.5, 0.3);
  gmsh::vectorpair out;
  std::vector<gmsh::vectorpair> m;
  gmsh::model::occ::cut({{2, r}}, {{2, d1}, {2, d2}}, out, m);
  gmsh::model::occ::synchronize();
}

// Build model `name` ("part", "sphere-torus", "plate") and write it to `path` (.step/.brep).
inline void write_model(const std::string &name, const std::string &path) {
  gmsh::model::add(name);
  if (name == "part") build_part();
  else if (name == "sphere-torus") build_sphere_torus();
  else if (name == "plate") build_plate();
  else throw std::runtime_error("unknown model " + name);
  gmsh::write(path);
  gmsh::model::remove();
}

}  // namespace occt

#endif

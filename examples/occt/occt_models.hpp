// Test models, built with gmsh's OpenCASCADE kernel and exported to STEP (no
// CAD file is downloaded): a filleted block with two holes, a torus with a
// sphere cut out, a 2D plate with a circular and an elliptic hole, a 2D
// NACA 0012 aerofoil in a box, and a ball.
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

// Half-thickness of the NACA 4-digit section `t` (thickness / chord) at x in
// [0, 1], chord 1, closed trailing edge (last coefficient -0.1036: y(1) = 0).
inline double naca_thickness(double t, double x) {
  return 5 * t * (0.2969 * std::sqrt(x) - 0.1260 * x - 0.3516 * x * x + 0.2843 * x * x * x - 0.1036 * x * x * x * x);
}

// Camber line y_c and its slope for NACA 4-digit max camber m at position p.
inline void naca_camber(double m, double p, double x, double &yc, double &slope) {
  if (m == 0 || p == 0) {
    yc = slope = 0;
  } else if (x < p) {
    yc = m / (p * p) * (2 * p * x - x * x);
    slope = 2 * m / (p * p) * (p - x);
  } else {
    yc = m / ((1 - p) * (1 - p)) * (1 - 2 * p + 2 * p * x - x * x);
    slope = 2 * m / ((1 - p) * (1 - p)) * (p - x);
  }
}

// (d) 2D: a NACA 4-digit aerofoil `digits` (e.g. "0012"), chord 1, leading edge
// at the origin, closed trailing edge, in the box [-1.5, 2.5] x [-1, 1] (z = 0).
// The upper and the lower surface are each an OCC B-spline interpolating 41
// points of the NACA formula (cosine spacing, so the leading edge is well
// sampled); they meet at the leading and the trailing edge.
inline void build_naca(const std::string &digits = "0012") {
  if (digits.size() != 4) throw std::runtime_error("NACA 4-digit code expected, got " + digits);
  const double m = (digits[0] - '0') / 100.0, p = (digits[1] - '0') / 10.0, t = std::stod(digits.substr(2)) / 100.0;
  const int n = 40;
  auto point = [&](double x, bool upper) {
    double yc, slope;
    naca_camber(m, p, x, yc, slope);
    const double yt = naca_thickness(t, x), th = std::atan(slope), sg = upper ? 1 : -1;
    return gmsh::model::occ::addPoint(x - sg * yt * std::sin(th), yc + sg * yt * std::cos(th), 0);
  };
  const int te = gmsh::model::occ::addPoint(1, 0, 0), le = gmsh::model::occ::addPoint(0, 0, 0);
  std::vector<int> upper{te}, lower{le};
  for (int i = n - 1; i >= 1; --i) upper.push_back(point(0.5 * (1 - std::cos(M_PI * i / n)), true));
  upper.push_back(le);
  for (int i = 1; i <= n - 1; ++i) lower.push_back(point(0.5 * (1 - std::cos(M_PI * i / n)), false));
  lower.push_back(te);
  const int cu = gmsh::model::occ::addSpline(upper), cl = gmsh::model::occ::addSpline(lower);
  const int foil = gmsh::model::occ::addPlaneSurface({gmsh::model::occ::addCurveLoop({cu, cl})});
  const int box = gmsh::model::occ::addRectangle(-1.5, -1, 0, 4, 2);
  gmsh::vectorpair out;
  std::vector<gmsh::vectorpair> map;
  gmsh::model::occ::cut({{2, box}}, {{2, foil}}, out, map);
  gmsh::model::occ::synchronize();
}

// (e) A ball (r = 1): one sphere face whose parametrisation (longitude u,
// latitude v) has its seam on a meridian and two poles, where S_u = 0 and u
// is meaningless: the facets around a pole straddle the seam and touch a
// singular point.
inline void build_sphere() {
  gmsh::model::occ::addSphere(0, 0, 0, 1);
  gmsh::model::occ::synchronize();
}

// Build model `name` ("part", "sphere-torus", "plate", "naca", "sphere") and write it to `path` (.step/.brep).
inline void write_model(const std::string &name, const std::string &path) {
  gmsh::model::add(name);
  if (name == "part") build_part();
  else if (name == "sphere-torus") build_sphere_torus();
  else if (name == "plate") build_plate();
  else if (name == "naca") build_naca("0012");
  else if (name == "sphere") build_sphere();
  else throw std::runtime_error("unknown model " + name);
  gmsh::write(path);
  gmsh::model::remove();
}

}  // namespace occt

#endif

// A toroidal cavity (radii 1 and 0.35, axis z, centre origin) in the box
// [-2, 2]^2 x [-1, 1], for bench/compare_gmsh.sh --case torus. The
// bounding box that finds the torus is loose: OpenCASCADE bounds a torus
// generously, and nothing else lies within 0.2 of it.
// OpenCASCADE kernel; the torus's surface tag is printed ("torus surface
// tag = N") since the boolean renumbers entities.
SetFactory("OpenCASCADE");
R = 1.0;
r = 0.35;
Box(1) = {-2, -2, -1, 4, 4, 2};
Torus(2) = {0, 0, 0, R, r};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
e = 0.2;
cavity() = Surface In BoundingBox{-R - r - e, -R - r - e, -r - e, R + r + e, R + r + e, r + e};
Printf("torus surface tag = %g", cavity(0));
// Sizes: h_cavity on the torus, h_box on the box walls.
DefineConstant[ h_cavity = 0.15, h_box = 0.8 ];
MeshSize{ PointsOf{ Volume{3}; } } = h_box;
MeshSize{ PointsOf{ Surface{cavity(0)}; } } = h_cavity;
Mesh.MshFileVersion = 4.1;

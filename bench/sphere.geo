// A spherical cavity (radius 0.5, centre origin) in the box [-2, 2]^3, for
// bench/compare_gmsh.sh. OpenCASCADE kernel; the sphere's surface tag is
// printed ("sphere surface tag = N") since the boolean renumbers entities.
SetFactory("OpenCASCADE");
R = 0.5;
L = 2.0;
Box(1) = {-L, -L, -L, 2 * L, 2 * L, 2 * L};
Sphere(2) = {0, 0, 0, R};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
e = 1e-3;
sphere() = Surface In BoundingBox{-R - e, -R - e, -R - e, R + e, R + e, R + e};
Printf("sphere surface tag = %g", sphere(0));
// Sizes: h_sphere on the sphere, h_box on the box walls.
DefineConstant[ h_sphere = 0.15, h_box = 0.8 ];
MeshSize{ PointsOf{ Volume{3}; } } = h_box;
MeshSize{ PointsOf{ Surface{sphere(0)}; } } = h_sphere;
Mesh.MshFileVersion = 4.1;

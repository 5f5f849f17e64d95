// Aluminium L-bracket, in metres: a base plate bolted down through two M6 clearance holes and
// an upright flange with a hole at its tip (where a part would hang). Meshed with 10-node
// tetrahedra, coarsely (about 1 650 nodes, 5 000 DOFs) so that calibration tests stay fast:
//
//   gmsh -3 bracket.geo -o bracket.msh
//
// x runs along the base, y across the bracket, z up; the upright's outer face is x = 0.
SetFactory("OpenCASCADE");

t = 0.006;            // plate thickness
base_length = 0.080;  // x
width = 0.050;        // y
height = 0.070;       // z, the upright
bolt_x = 0.055;       // the bolt holes' centres in the base
bolt_y1 = 0.015;
bolt_y2 = 0.035;
bolt_d = 0.0066;      // M6 clearance hole
tip_z = 0.055;        // the tip hole's centre in the upright, at y = width / 2
tip_d = 0.008;
mesh_size = 0.018;

Box(1) = {0, 0, 0, base_length, width, t};
Box(2) = {0, 0, 0, t, width, height};
Cylinder(3) = {bolt_x, bolt_y1, -t, 0, 0, 3 * t, bolt_d / 2};
Cylinder(4) = {bolt_x, bolt_y2, -t, 0, 0, 3 * t, bolt_d / 2};
Cylinder(5) = {-t, width / 2, tip_z, 3 * t, 0, 0, tip_d / 2};
BooleanUnion(10) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
BooleanDifference(11) = { Volume{10}; Delete; }{ Volume{3, 4, 5}; Delete; };

// Faces are picked by bounding boxes, which survive changes of the boolean operations' numbering.
e = 1e-5;
Physical Volume("bracket") = {11};
Physical Surface("bolt_hole_1") = Surface In BoundingBox{bolt_x - bolt_d/2 - e, bolt_y1 - bolt_d/2 - e, -e,
                                                          bolt_x + bolt_d/2 + e, bolt_y1 + bolt_d/2 + e, t + e};
Physical Surface("bolt_hole_2") = Surface In BoundingBox{bolt_x - bolt_d/2 - e, bolt_y2 - bolt_d/2 - e, -e,
                                                          bolt_x + bolt_d/2 + e, bolt_y2 + bolt_d/2 + e, t + e};
Physical Surface("tip_hole") = Surface In BoundingBox{-e, width/2 - tip_d/2 - e, tip_z - tip_d/2 - e,
                                                       t + e, width/2 + tip_d/2 + e, tip_z + tip_d/2 + e};
Physical Surface("base_bottom") = Surface In BoundingBox{-e, -e, -e, base_length + e, width + e, e};

MeshSize{ PointsOf{ Volume{11}; } } = mesh_size;
Mesh.MeshSizeMax = mesh_size;
Mesh.ElementOrder = 2;
Mesh.HighOrderOptimize = 2;  // untangle curved tet10 at the holes (finer meshes fold some without it)
Mesh.MshFileVersion = 4.1;

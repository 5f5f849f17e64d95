// The Gmsh seeds of fuzz/seeds/gmsh/ (see fuzz/seeds/README.md): a 2x1x1 hex8 box and a tet10 box.
SetFactory("Built-in");
Point(1) = {0, 0, 0, 1};
l[] = Extrude {2, 0, 0} { Point{1}; Layers{2}; };
s[] = Extrude {0, 1, 0} { Line{l[1]}; Layers{1}; Recombine; };
v[] = Extrude {0, 0, 1} { Surface{s[1]}; Layers{1}; Recombine; };
Physical Volume("part") = {v[1]};
Physical Surface("bottom") = {s[1]};
Physical Point("origin") = {1};

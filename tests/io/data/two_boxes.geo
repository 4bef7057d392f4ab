// Two unit boxes sharing a face: two volumes with their own physical groups (7 and 9) and
// one tagged physical surface (21, the x=0 face). The io tests mesh it with gmsh in
// several .msh versions.
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Box(2) = {1, 0, 0, 1, 1, 1};
BooleanFragments{ Volume{1}; Delete; }{ Volume{2}; Delete; }
Physical Volume(7) = {1};
Physical Volume(9) = {2};
Physical Surface(21) = {1};
Mesh.CharacteristicLengthMax = 0.4;

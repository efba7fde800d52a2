// The curved incision of cases/curved_incision.toml: a cylindrical
// arc (radius 0.03 about the line x = 0, z = 0.13, along y) from x = -0.005
// (outside the beam) to x = 0.018 (inside: the front), across y in [-0.005, 0.065].
// Made with: gmsh -2 curved_incision.geo -format msh41 -o curved_incision.msh
SetFactory("OpenCASCADE");
R = 0.03; zc = 0.13;
t0 = Asin(-0.005 / R); t1 = Asin(0.018 / R);
Point(1) = {0, -0.005, zc};
Point(2) = {R * Sin(t0), -0.005, zc - R * Cos(t0)};
Point(3) = {R * Sin(t1), -0.005, zc - R * Cos(t1)};
Circle(1) = {2, 1, 3};
Extrude {0, 0.07, 0} { Curve{1}; }
Mesh.MeshSizeMax = 0.004;

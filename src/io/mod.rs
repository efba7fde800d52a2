//! Input and output: gmsh `.msh` 4.1 in, VTU/PVD and probes CSV out.

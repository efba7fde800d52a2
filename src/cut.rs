//! Cut geometry: level sets, classification of tetrahedra, sub-tetrahedra.

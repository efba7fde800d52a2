//! Mass: how an integration cell's mass is lumped onto the DOFs of its
//! element (seed eq. 77–82).

use crate::mesh::ElementKind;

/// Lumped mass of one integration cell per node of its element.
///
/// Tet4: the row sum of the cell's consistent mass, ρ∫_cell N_k (positive).
/// Tet10: HRZ, the cell mass ρV_cell shared in proportion to ∫_cell N_k²,
/// because the row sum gives zero or negative vertex masses on Tet10.
///
/// Each cell's share goes to the DOF that moves that side, u_k + ψ a_k:
/// M^uu += m, M^aa += ψ² m, M^ua += ψ m. Summed over the cells this is the
/// seed's eq. (81)–(82) (with ∫N_k in place of the volume fractions) plus the
/// coupling M^ua the seed drops; with it a part freed by the cut keeps exactly
/// its own inertia and falls with g.
pub fn lump_cell_mass(
    kind: ElementKind,
    rho: f64,
    cell_volume: f64,
    int_n: &[f64; 10],
    int_n2: &[f64; 10],
) -> [f64; 10] {
    let mut share = [0.0; 10];
    match kind {
        ElementKind::Tet4 => {
            for k in 0..4 {
                share[k] = rho * int_n[k];
            }
        }
        ElementKind::Tet10 => {
            let sum: f64 = int_n2.iter().sum();
            for k in 0..10 {
                share[k] = rho * cell_volume * int_n2[k] / sum;
            }
        }
    }
    share
}

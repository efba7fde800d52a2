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

/// Lumped masses of an element's integration cells ([`lump_cell_mass`] per
/// cell, `volumes[c]`, `int_n[c]`, `int_n2[c]` its ∫N_k and ∫N_k²; the
/// model passes a cut Tet10 element's sides as its cells, each the sum of
/// its sub-tets, so that the masses do not depend on the split). Tet4:
/// each cell's row sums, whose sum over the cells is the uncut element's.
/// Tet10: each cell's HRZ shares, then balanced (iterative proportional
/// fitting) so that each node's shares sum to its HRZ mass in the uncut
/// element while each cell keeps its mass ρV_c. The first makes the
/// standard DOFs' masses those of the uncut element (a cut event that adds
/// shifted DOFs at rest keeps the kinetic energy: per-cell HRZ changed them
/// by up to 1e-4 relative); the second keeps each side's own mass (a freed
/// part's centre falls with g). Without a cut (one cell) it is HRZ.
pub fn lump_element_mass(
    kind: ElementKind,
    rho: f64,
    volumes: &[f64],
    int_n: &[[f64; 10]],
    int_n2: &[[f64; 10]],
) -> Vec<[f64; 10]> {
    let mut shares: Vec<[f64; 10]> = volumes
        .iter()
        .zip(int_n.iter().zip(int_n2))
        .map(|(&v, (n, n2))| lump_cell_mass(kind, rho, v, n, n2))
        .collect();
    if kind != ElementKind::Tet10 || shares.len() < 2 {
        return shares;
    }
    let mut whole = [0.0; 10];
    for n2 in int_n2 {
        for k in 0..10 {
            whole[k] += n2[k];
        }
    }
    let volume: f64 = volumes.iter().sum();
    let total: f64 = whole.iter().sum();
    let node_mass = whole.map(|w| rho * volume * w / total);
    let cell_mass: Vec<f64> = volumes.iter().map(|v| rho * v).collect();
    // Rows (nodes) last: their sums are what the kinetic energy sees.
    for _ in 0..BALANCE_ITERATIONS {
        for (share, &m) in shares.iter_mut().zip(&cell_mass) {
            let sum: f64 = share.iter().sum();
            if sum > 0.0 {
                share.iter_mut().for_each(|s| *s *= m / sum);
            }
        }
        let mut worst: f64 = 0.0;
        for k in 0..10 {
            let sum: f64 = shares.iter().map(|s| s[k]).sum();
            if sum > 0.0 {
                worst = worst.max((sum / node_mass[k] - 1.0).abs());
                shares.iter_mut().for_each(|s| s[k] *= node_mass[k] / sum);
            }
        }
        if worst <= BALANCE_TOLERANCE {
            break;
        }
    }
    shares
}

/// Iterative proportional fitting of [`lump_element_mass`]: it stops when
/// the node sums are within this of their targets after a cell scaling (the
/// cells' masses then are too), or after this many rounds.
const BALANCE_TOLERANCE: f64 = 1e-14;
const BALANCE_ITERATIONS: usize = 200;

#[cfg(test)]
mod tests {
    use super::*;

    /// A Tet10 element's HRZ node masses split over uneven cells: the node
    /// sums are the uncut element's HRZ masses and each cell keeps ρV_c, all
    /// positive; one cell is plain HRZ; Tet4 is the cells' row sums.
    #[test]
    fn cut_tet10_lumping_keeps_the_element_node_masses_and_the_cell_masses() {
        let rho = 2.5;
        // Three cells with made-up (positive) ∫N_k² profiles and volumes.
        let volumes = [0.02, 0.7, 0.28];
        let int_n2: Vec<[f64; 10]> = (0..3)
            .map(|c| std::array::from_fn(|k| volumes[c] * (1.0 + ((3 * c + k) % 7) as f64) * 1e-2))
            .collect();
        let int_n = vec![[0.0; 10]; 3];
        let shares = lump_element_mass(ElementKind::Tet10, rho, &volumes, &int_n, &int_n2);
        let whole: [f64; 10] = std::array::from_fn(|k| int_n2.iter().map(|c| c[k]).sum());
        let uncut = lump_cell_mass(ElementKind::Tet10, rho, 1.0, &[0.0; 10], &whole);
        for k in 0..10 {
            let sum: f64 = shares.iter().map(|s| s[k]).sum();
            assert!(
                (sum - uncut[k]).abs() <= 1e-14 * uncut[k],
                "node {k}: {sum} vs {}",
                uncut[k]
            );
        }
        for (c, s) in shares.iter().enumerate() {
            let m: f64 = s.iter().sum();
            assert!(
                (m - rho * volumes[c]).abs() <= 1e-13 * rho * volumes[c],
                "cell {c}: {m}"
            );
            assert!(s.iter().all(|&x| x > 0.0));
        }
        let one = lump_element_mass(ElementKind::Tet10, rho, &[1.0], &[[0.0; 10]], &[whole]);
        assert_eq!(one[0], uncut);
        let n: Vec<[f64; 10]> = vec![[0.1; 10], [0.3; 10]];
        let tet4 = lump_element_mass(ElementKind::Tet4, rho, &[0.5, 0.5], &n, &n);
        assert_eq!(tet4[1][0], rho * 0.3);
    }
}

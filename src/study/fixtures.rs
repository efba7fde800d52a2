//! The fixtures that tests, benches, examples and the stress suite share:
//! the seed's clamped beam (its test object, figure 9a: 3 cm × 6 cm × 20 cm, E = 3·10⁵ Pa,
//! ν = 0.35, ρ = 1070 kg/m³, bottom face z = 0 clamped, gravity 9.81 m/s²
//! along +x), the blade that opens the seed's cut on it, and the spin given
//! to a fragment freed by a complete cut.
//!
//! Each caller used to carry its own copy of these; one definition keeps the
//! meshes, materials, fixes and loads they compute with the same.

use crate::blade::{Blade, CutItem, CutSet};
use crate::cut::{CutSetup, FrontMode, DEFAULT_SNAP};
use crate::material::Material;
use crate::mesh::{box_mesh, TetMesh};
use crate::model::{Formulation, Model, ModelError, ModelInput};
use nalgebra::{Point3, Vector3};

/// The seed beam's material (figure 9a's test object).
pub const BEAM_MATERIAL: Material = Material {
    young: 3.0e5,
    poisson: 0.35,
    density: 1070.0,
};

/// The seed beam's gravity: 9.81 m/s² along +x, across the beam.
pub fn beam_gravity() -> Vector3<f64> {
    Vector3::new(9.81, 0.0, 0.0)
}

/// The seed beam [0, 0.03] × [0, 0.06] × [0, 0.2] m with `div` hexes per
/// axis (six Tet4 each), as Tet10 when `tet10`.
pub fn beam_mesh(div: [usize; 3], tet10: bool) -> TetMesh {
    let m = box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.2), div);
    if tet10 {
        m.to_tet10()
    } else {
        m
    }
}

/// Every node on the face z = 0 (within 1e-12) fixed at zero displacement.
pub fn clamped_bottom(mesh: &TetMesh) -> Vec<(usize, [Option<f64>; 3])> {
    mesh.nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| p.z.abs() < 1e-12)
        .map(|(i, _)| (i, [Some(0.0); 3]))
        .collect()
}

/// `mesh` with [`BEAM_MATERIAL`], the bottom face z = 0 clamped
/// ([`clamped_bottom`]), an optional cut, optional gravity and no other load;
/// with the mass when `need_mass`.
pub fn clamped_beam(
    mesh: TetMesh,
    formulation: Formulation,
    cut: Option<CutSetup>,
    gravity: Option<Vector3<f64>>,
    need_mass: bool,
) -> Result<Model, ModelError> {
    let fixed = clamped_bottom(&mesh);
    Model::build(ModelInput {
        mesh,
        material: BEAM_MATERIAL,
        formulation,
        cut,
        fixed,
        gravity,
        body_force: None,
        tractions: &[],
        need_mass,
    })
}

/// The seed's `gravity` scene on `mesh`: [`clamped_beam`] under
/// [`beam_gravity`], with mass (what the benches and examples time).
pub fn seed_beam(
    mesh: TetMesh,
    formulation: Formulation,
    cut: Option<CutSetup>,
) -> Result<Model, ModelError> {
    clamped_beam(mesh, formulation, cut, Some(beam_gravity()), true)
}

/// One blade opening the seed's cut on the beam (x from 0 to 0.015 at
/// z = 0.1, edge across y from −0.01 to 0.07) from time `t0` to `t1`; default
/// snap, front extended.
pub fn seed_blade(t0: f64, t1: f64) -> CutSet {
    let blade = Blade::straight(
        0,
        Point3::new(0.0, -0.01, 0.1),
        Point3::new(0.0, 0.07, 0.1),
        Vector3::new(0.015, 0.0, 0.0),
        t0,
        t1,
    )
    .expect("the seed blade is well formed");
    CutSet {
        items: vec![CutItem::Blade(blade)],
        snap: DEFAULT_SNAP,
        front: FrontMode::Extend,
        options: Vec::new(),
    }
}

/// Spins the side of `cut` above it (φ ≥ 0) rigidly: writes v = ω × (x − c)
/// into the velocity `v` (DOFs of `model`) on the upper side's DOFs, u where
/// the node lies above and the enriched DOFs a that the upper side sees
/// (ψ = ±1 there), so that u ± a is ω × (x − c) above and the lower
/// side (u below, u − a) keeps its velocity.
pub fn spin_upper_side(
    model: &Model,
    cut: &CutSetup,
    v: &mut [f64],
    omega: Vector3<f64>,
    c: Vector3<f64>,
) {
    let n_nodes = model.mesh.n_nodes();
    for i in 0..n_nodes {
        let w = omega.cross(&(model.mesh.nodes[i].coords - c));
        for k in 0..3 {
            if cut.phi[i] >= 0.0 {
                v[3 * i + k] = w[k];
            }
            if let Some(j) = cut.enriched[i] {
                v[3 * (n_nodes + j) + k] = w[k];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clamped_beam_fixes_exactly_the_bottom_face() {
        // Tet4: the (3 + 1)(6 + 1) corner nodes of z = 0; Tet10 adds the
        // face's edge and diagonal mid-nodes: (2·3 + 1)(2·6 + 1).
        for (tet10, want) in [(false, 4 * 7), (true, 7 * 13)] {
            let mesh = beam_mesh([3, 6, 10], tet10);
            let fixed = clamped_bottom(&mesh);
            assert_eq!(fixed.len(), want, "tet10 = {tet10}");
            assert!(fixed
                .iter()
                .all(|&(i, f)| mesh.nodes[i].z == 0.0 && f == [Some(0.0); 3]));
            let n = mesh.n_nodes();
            let model = seed_beam(mesh, Formulation::Linear, None).unwrap();
            assert_eq!(model.n_free, 3 * (n - want), "tet10 = {tet10}");
            assert!(model.lumped_mass.is_some());
        }
    }

    #[test]
    fn the_seed_blade_cuts_the_beam_once_it_has_entered() {
        let mesh = beam_mesh([3, 6, 11], false);
        let cuts = seed_blade(0.0, 1.0);
        let cut = cuts.setup_at(&mesh, 1.0).unwrap().expect("cut at t = 1");
        assert!(cut.n_cut() > 0);
    }
}

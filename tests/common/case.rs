//! Loads a case file with blades or triangle surfaces: the scene reads the
//! schema, [`CutSet::from_scene`] makes its cuts; the model builder applies
//! the scene's fixes and gravity (the scene's own build refuses blades and
//! surfaces until they are wired into it).

use std::path::Path;
use xfem_cut::blade::CutSet;
use xfem_cut::cut::CutSetup;
use xfem_cut::mesh::TetMesh;
use xfem_cut::model::{Model, ModelError, ModelInput};
use xfem_cut::scene::{Analysis, Scene};

/// The scene and its cuts.
pub fn load(path: &Path) -> (Scene, CutSet) {
    let scene = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    let cuts = CutSet::from_scene(&scene).unwrap_or_else(|e| panic!("{e}"));
    (scene, cuts)
}

/// The scene's model of `mesh` with the cut `cut` (fixes selected as the scene does, gravity, mass if dynamic).
pub fn build(scene: &Scene, mesh: &TetMesh, cut: Option<CutSetup>) -> Result<Model, ModelError> {
    let (lo, hi) = mesh.bounding_box();
    let tol = 1e-9 * (hi - lo).norm();
    let mut fixed = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        let mut c = [None; 3];
        for fx in &scene.fixes {
            if (0..3).all(|k| p[k] >= fx.min[k] - tol && p[k] <= fx.max[k] + tol) {
                for ((ck, &on), &u) in c.iter_mut().zip(&fx.components).zip(&fx.displacement) {
                    if on {
                        *ck = Some(u);
                    }
                }
            }
        }
        if c.iter().any(Option::is_some) {
            fixed.push((i, c));
        }
    }
    Model::build(ModelInput {
        mesh: mesh.clone(),
        material: scene.material,
        formulation: scene.formulation,
        cut,
        fixed,
        gravity: scene.gravity,
        body_force: None,
        tractions: &[],
        need_mass: matches!(scene.analysis, Analysis::Dynamic { .. }),
    })
}

//! The seed beam the examples time: bottom clamped, gravity in +x,
//! corotational, with mass.
use nalgebra::{Point3, Vector3};
use xfem_cut::material::Material;
use xfem_cut::mesh::box_mesh;
use xfem_cut::model::{Formulation, Model, ModelInput};

pub fn clamped_beam(div: [usize; 3]) -> Model {
    let mesh = box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.2), div);
    let fixed = mesh
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| p.z.abs() < 1e-12)
        .map(|(i, _)| (i, [Some(0.0); 3]))
        .collect();
    Model::build(ModelInput {
        mesh,
        material: Material {
            young: 3e5,
            poisson: 0.35,
            density: 1070.0,
        },
        formulation: Formulation::Corotational,
        cut: None,
        fixed,
        gravity: Some(Vector3::new(9.81, 0.0, 0.0)),
        body_force: None,
        tractions: &[],
        need_mass: true,
    })
    .expect("the beam model builds")
}

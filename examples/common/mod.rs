//! The seed beam the examples time: bottom clamped, gravity in +x,
//! corotational, with mass.
use xfem_cut::model::{Formulation, Model};
use xfem_cut::study::fixtures::{beam_mesh, seed_beam};

pub fn clamped_beam(div: [usize; 3]) -> Model {
    seed_beam(beam_mesh(div, false), Formulation::Corotational, None)
        .expect("the beam model builds")
}

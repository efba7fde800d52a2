//! Isotropic linear elasticity: Young's modulus and Poisson ratio to Lamé parameters.

/// Young's modulus E (Pa), Poisson ratio ν and density ρ (kg/m³).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    pub young: f64,
    pub poisson: f64,
    pub density: f64,
}

/// Lamé parameters λ, μ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lame {
    pub lambda: f64,
    pub mu: f64,
}

impl From<Material> for Lame {
    /// λ = Eν / ((1+ν)(1−2ν)), μ = E / (2(1+ν)).
    fn from(m: Material) -> Self {
        let (e, nu) = (m.young, m.poisson);
        Lame {
            lambda: e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)),
            mu: e / (2.0 * (1.0 + nu)),
        }
    }
}

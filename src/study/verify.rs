//! Verification: L2 errors against a reference field on another mesh, and
//! observed convergence orders.
//!
//! The error is integrated with the reference mesh's own quadrature (degree 5
//! on each reference tetrahedron); each quadrature point is located in our
//! mesh with the R*-tree of [`Locator`]; in a cut element of ours the side is
//! the sign of our level set at the reference element's centroid, so a point
//! on a crack face takes the side of the reference element it belongs to.

use crate::element::{barycentric_gradients, shape_gradients, shape_values};
use crate::locate::Locator;
use crate::material::Lame;
use crate::mesh::TetMesh;
use crate::model::Model;
use crate::quadrature::DEGREE5;
use nalgebra::{Matrix3, Point3, Vector3};

/// A displacement field: a mesh and one value per node (Tet4 or Tet10).
pub struct Field<'a> {
    pub mesh: &'a TetMesh,
    pub values: &'a [Vector3<f64>],
}

impl Field<'_> {
    /// Value at barycentric point `l` of element `e`.
    pub fn at(&self, e: usize, l: &[f64; 4]) -> Vector3<f64> {
        let mut n = [0.0; 10];
        shape_values(self.mesh.kind, l, &mut n);
        self.mesh
            .element(e)
            .iter()
            .enumerate()
            .fold(Vector3::zeros(), |s, (k, &i)| s + self.values[i] * n[k])
    }

    /// Gradient ∇u at barycentric point `l` of element `e` (zero on a
    /// degenerate element).
    pub fn gradient_at(&self, e: usize, l: &[f64; 4]) -> Matrix3<f64> {
        let Some(dl) = barycentric_gradients(&self.mesh.vertex_points(e)) else {
            return Matrix3::zeros();
        };
        let mut g = [Vector3::zeros(); 10];
        shape_gradients(self.mesh.kind, l, &dl, &mut g);
        self.mesh
            .element(e)
            .iter()
            .enumerate()
            .fold(Matrix3::zeros(), |s, (k, &i)| {
                s + self.values[i] * g[k].transpose()
            })
    }

    /// Linear strain energy ½∫ ε : σ of the field for a material with Lamé
    /// parameters `lame` (degree 5 per element: exact for Tet4 and Tet10).
    pub fn strain_energy(&self, lame: &Lame) -> f64 {
        let mut energy = 0.0;
        for e in 0..self.mesh.n_elements() {
            let vol = self.mesh.volume(e).abs();
            for q in &DEGREE5 {
                let g = self.gradient_at(e, &q.bary);
                let eps = (g + g.transpose()) * 0.5;
                let density =
                    0.5 * lame.lambda * eps.trace().powi(2) + lame.mu * eps.norm_squared();
                energy += q.weight * vol * density;
            }
        }
        energy
    }
}

#[derive(Debug, thiserror::Error)]
pub enum VerifyError {
    #[error(
        "{missed} of {total} reference quadrature points lie outside our mesh (first at {first:?})"
    )]
    Outside {
        missed: usize,
        total: usize,
        first: [f64; 3],
    },
}

/// Absolute and relative L2 error ‖u_ref − u_h‖ / ‖u_ref‖.
#[derive(Debug, Clone, Copy)]
pub struct L2Error {
    pub absolute: f64,
    pub reference_norm: f64,
    pub relative: f64,
}

/// The side of the cut a reference element with centroid `centroid` lies
/// on, seen from our element `e` (`fallback`: barycentric coordinates to use
/// where the centroid's cannot be computed): the sign of our level set
/// interpolated there (planar in an element: exact); 0 without a cut.
pub fn side_of(model: &Model, e: usize, centroid: &Point3<f64>, fallback: [f64; 4]) -> i8 {
    let Some(c) = &model.cut else {
        return 0;
    };
    let at = crate::mesh::barycentric(&model.mesh.vertex_points(e), centroid).unwrap_or(fallback);
    let phi: f64 = model
        .mesh
        .vertices(e)
        .iter()
        .zip(at)
        .map(|(&i, l)| c.phi[i] * l)
        .sum();
    if phi >= 0.0 {
        1
    } else {
        -1
    }
}

/// L2 error of our solution `d` on `model` against `reference`.
pub fn l2_error(
    reference: &Field<'_>,
    model: &Model,
    d: &[f64],
    locator: &Locator,
) -> Result<L2Error, VerifyError> {
    let rmesh = reference.mesh;
    let (mut err2, mut norm2) = (0.0, 0.0);
    let mut missed = 0;
    let mut first = [0.0; 3];
    let total = rmesh.n_elements() * DEGREE5.len();
    for e in 0..rmesh.n_elements() {
        let p = rmesh.vertex_points(e);
        let vol = rmesh.volume(e).abs();
        let centroid = Point3::from(p.iter().fold(Vector3::zeros(), |s, q| s + q.coords) / 4.0);
        for q in &DEGREE5 {
            let x = Point3::from(
                p.iter()
                    .zip(q.bary)
                    .fold(Vector3::zeros(), |s, (pi, l)| s + pi.coords * l),
            );
            let u_ref = reference.at(e, &q.bary);
            let Some((oe, ob)) = locator.locate(&model.mesh, &x) else {
                if missed == 0 {
                    first = [x.x, x.y, x.z];
                }
                missed += 1;
                continue;
            };
            let side = side_of(model, oe, &centroid, ob);
            let u_h = model.displacement_at(d, oe, &x, side);
            err2 += q.weight * vol * (u_ref - u_h).norm_squared();
            norm2 += q.weight * vol * u_ref.norm_squared();
        }
    }
    if missed > 0 {
        return Err(VerifyError::Outside {
            missed,
            total,
            first,
        });
    }
    let absolute = err2.sqrt();
    let reference_norm = norm2.sqrt();
    Ok(L2Error {
        absolute,
        reference_norm,
        relative: absolute / reference_norm.max(f64::MIN_POSITIVE),
    })
}

/// Observed order: least-squares slope of log(error) against log(h).
pub fn observed_order(h: &[f64], error: &[f64]) -> Option<f64> {
    let pts: Vec<(f64, f64)> = h
        .iter()
        .zip(error)
        .filter(|(h, e)| **h > 0.0 && **e > 0.0)
        .map(|(h, e)| (h.ln(), e.ln()))
        .collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Material;
    use crate::mesh::box_mesh;
    use crate::model::{Formulation, ModelInput};

    fn model_of(mesh: TetMesh) -> Model {
        Model::build(ModelInput {
            mesh,
            material: Material {
                young: 1.0,
                poisson: 0.3,
                density: 1.0,
            },
            formulation: Formulation::Linear,
            cut: None,
            fixed: vec![],
            gravity: None,
            body_force: None,
            tractions: &[],
            need_mass: false,
        })
        .unwrap()
    }

    #[test]
    fn observed_order_recovers_a_synthetic_slope() {
        let h = [0.1, 0.05, 0.025, 0.0125];
        let e: Vec<f64> = h.iter().map(|h: &f64| 3.0 * h.powf(1.7)).collect();
        assert!((observed_order(&h, &e).unwrap() - 1.7).abs() < 1e-12);
    }

    #[test]
    fn error_against_itself_is_zero_and_quadratic_field_is_exact_across_meshes() {
        let quad = |p: &Point3<f64>| Vector3::new(p.x * p.y, p.z * p.z - p.x, 0.5 * p.y);
        let a = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [2, 3, 2]).to_tet10();
        let b = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [3, 2, 4]).to_tet10();
        let va: Vec<Vector3<f64>> = a.nodes.iter().map(quad).collect();
        let model = model_of(b);
        let d: Vec<f64> = model
            .mesh
            .nodes
            .iter()
            .flat_map(|p| {
                let u = quad(p);
                [u.x, u.y, u.z]
            })
            .collect();
        let loc = Locator::new(&model.mesh);
        let e = l2_error(
            &Field {
                mesh: &a,
                values: &va,
            },
            &model,
            &d,
            &loc,
        )
        .unwrap();
        assert!(
            e.relative < 1e-13,
            "quadratic field on two Tet10 meshes: {e:?}"
        );
        // A linear field on Tet4 against a cubic-free exact integral: ∫|x|² over the unit cube = 1.
        let lin = |p: &Point3<f64>| Vector3::new(p.x, 0.0, 0.0);
        let c = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [2, 2, 2]);
        let vc: Vec<Vector3<f64>> = c.nodes.iter().map(lin).collect();
        let zero = vec![0.0; model.n_dofs()];
        let e = l2_error(
            &Field {
                mesh: &c,
                values: &vc,
            },
            &model,
            &zero,
            &loc,
        )
        .unwrap();
        assert!(
            (e.reference_norm.powi(2) - 1.0 / 3.0).abs() < 1e-14,
            "{e:?}"
        );
    }

    /// ½∫ε:σ of u = (xy, z² − x, y/2) on the unit cube: λ/6 + 43μ/24 in closed
    /// form, from the reference field and from the model's own assembly.
    #[test]
    fn strain_energy_of_a_quadratic_field_is_exact() {
        let quad = |p: &Point3<f64>| Vector3::new(p.x * p.y, p.z * p.z - p.x, 0.5 * p.y);
        let mesh = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [2, 3, 2]).to_tet10();
        let values: Vec<Vector3<f64>> = mesh.nodes.iter().map(quad).collect();
        let model = model_of(mesh.clone());
        let lame = model.lame;
        let exact = lame.lambda / 6.0 + 43.0 * lame.mu / 24.0;
        let field = Field {
            mesh: &mesh,
            values: &values,
        };
        let e = field.strain_energy(&lame);
        assert!((e - exact).abs() < 1e-13 * exact, "{e} against {exact}");
        let d: Vec<f64> = values.iter().flat_map(|u| [u.x, u.y, u.z]).collect();
        let from_model = crate::assembly::evaluate(
            &model,
            &d,
            &mut crate::assembly::Rotations::identity(&model),
            &mut crate::assembly::Workspace::new(&model),
            crate::assembly::Request {
                forces: None,
                tangent: None,
                update_rotations: false,
                exact_tangent: false,
            },
        );
        assert!(
            (from_model - exact).abs() < 1e-13 * exact,
            "{from_model} against {exact}"
        );
    }
}

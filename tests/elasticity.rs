//! Analytical checks of the elasticity core: patch tests, rigid motions,
//! manufactured solutions, the cantilever, Newmark energy and frequency.

use nalgebra::{Matrix3, Point3, Rotation3, Unit, Vector3};
use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
use xfem_cut::material::Material;
use xfem_cut::mesh::{box_mesh, TetMesh};
use xfem_cut::model::{Formulation, Model, ModelInput};
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};

const MAT: Material = Material {
    young: 3.0e5,
    poisson: 0.35,
    density: 1070.0,
};

/// A unit cube mesh with interior nodes moved pseudo-randomly (still valid).
fn distorted_cube(n: usize) -> TetMesh {
    let mut m = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [n, n, n]);
    let h = 1.0 / n as f64;
    let mut seed = 12345u64;
    let mut rnd = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((seed >> 33) as f64 / (1u64 << 31) as f64) - 0.5
    };
    for p in m.nodes.iter_mut() {
        let interior = (0..3).all(|k| p[k] > 1e-12 && p[k] < 1.0 - 1e-12);
        if interior {
            for k in 0..3 {
                p[k] += 0.25 * h * rnd();
            }
        }
    }
    assert!((0..m.n_elements()).all(|e| m.volume(e) > 0.0));
    m
}

fn on_boundary(p: &Point3<f64>) -> bool {
    (0..3).any(|k| p[k].abs() < 1e-12 || (p[k] - 1.0).abs() < 1e-12)
}

fn model_with_boundary_field(
    mesh: TetMesh,
    formulation: Formulation,
    field: impl Fn(&Point3<f64>) -> Vector3<f64>,
) -> Model {
    let fixed = mesh
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| on_boundary(p))
        .map(|(i, p)| {
            let u = field(p);
            (i, [Some(u.x), Some(u.y), Some(u.z)])
        })
        .collect();
    Model::build(ModelInput {
        mesh,
        material: MAT,
        formulation,
        cut: None,
        fixed,
        gravity: None,
        tractions: &[],
        need_mass: false,
    })
    .unwrap()
}

fn max_node_error(
    model: &Model,
    d: &[f64],
    field: impl Fn(&Point3<f64>) -> Vector3<f64>,
) -> (f64, f64) {
    let mut err: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for (i, p) in model.mesh.nodes.iter().enumerate() {
        let u = field(p);
        let got = Vector3::new(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
        err = err.max((got - u).norm());
        scale = scale.max(u.norm());
    }
    (err, scale)
}

#[test]
fn linear_patch_test_is_exact_for_tet4_and_tet10() {
    let a = Matrix3::new(
        0.01, 0.002, -0.003, 0.004, -0.005, 0.006, 0.001, 0.003, 0.002,
    );
    let b = Vector3::new(0.001, -0.002, 0.003);
    let field = |p: &Point3<f64>| a * p.coords + b;
    for mesh in [distorted_cube(3), distorted_cube(3).to_tet10()] {
        let kind = mesh.kind;
        let model = model_with_boundary_field(mesh, Formulation::Linear, field);
        let mut chol = Cholesky::new(&model.pattern).unwrap();
        let sol = solve_static(&model, &mut chol, &StaticOptions::default()).unwrap();
        let (err, scale) = max_node_error(&model, &sol.d, field);
        assert!(
            err <= 1e-12 * scale,
            "{kind:?}: patch test error {err:e} (scale {scale:e})"
        );
    }
}

#[test]
fn tet10_reproduces_a_quadratic_field_with_its_body_force() {
    // u = c (x², 0, 0) has div σ = (λ + 2μ) 2c e_x, so the body force ρ g = −(λ+2μ) 2c e_x.
    let c = 0.01;
    let lame = xfem_cut::material::Lame::from(MAT);
    let field = |p: &Point3<f64>| Vector3::new(c * p.x * p.x, 0.0, 0.0);
    let mesh = distorted_cube(2).to_tet10();
    let fixed = mesh
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| on_boundary(p))
        .map(|(i, p)| {
            let u = field(p);
            (i, [Some(u.x), Some(u.y), Some(u.z)])
        })
        .collect();
    let g = Vector3::new(
        -(lame.lambda + 2.0 * lame.mu) * 2.0 * c / MAT.density,
        0.0,
        0.0,
    );
    let model = Model::build(ModelInput {
        mesh,
        material: MAT,
        formulation: Formulation::Linear,
        cut: None,
        fixed,
        gravity: Some(g),
        tractions: &[],
        need_mass: false,
    })
    .unwrap();
    let mut chol = Cholesky::new(&model.pattern).unwrap();
    let sol = solve_static(&model, &mut chol, &StaticOptions::default()).unwrap();
    let (err, scale) = max_node_error(&model, &sol.d, field);
    assert!(
        err <= 1e-11 * scale,
        "quadratic field error {err:e} (scale {scale:e})"
    );
}

/// Internal forces at displacement d (all DOFs).
fn forces(model: &Model, d: &[f64]) -> Vec<f64> {
    let mut f = vec![0.0; model.n_dofs()];
    let mut rot = Rotations::identity(model);
    let mut ws = Workspace::new(model);
    evaluate(
        model,
        d,
        &mut rot,
        &mut ws,
        Request {
            forces: Some(&mut f),
            tangent: None,
            update_rotations: true,
        },
    );
    f
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

#[test]
fn rigid_rotation_gives_zero_corotational_force_and_linear_ghost_forces() {
    for mesh in [distorted_cube(2), distorted_cube(2).to_tet10()] {
        let build = |f| {
            Model::build(ModelInput {
                mesh: mesh.clone(),
                material: MAT,
                formulation: f,
                cut: None,
                fixed: vec![],
                gravity: None,
                tractions: &[],
                need_mass: false,
            })
            .unwrap()
        };
        let corot = build(Formulation::Corotational);
        let linear = build(Formulation::Linear);
        // Reference scale: forces of a 1% uniaxial strain.
        let strain: Vec<f64> = mesh
            .nodes
            .iter()
            .flat_map(|p| [0.01 * p.x, 0.0, 0.0])
            .collect();
        let scale = norm(&forces(&linear, &strain));
        for angle in [0.3f64, std::f64::consts::FRAC_PI_2, std::f64::consts::PI] {
            let r = Rotation3::from_axis_angle(
                &Unit::new_normalize(Vector3::new(1.0, 2.0, -0.5)),
                angle,
            );
            let t = Vector3::new(0.3, -0.1, 0.2);
            let d: Vec<f64> = mesh
                .nodes
                .iter()
                .flat_map(|p| {
                    let u = r * p.coords + t - p.coords;
                    [u.x, u.y, u.z]
                })
                .collect();
            let fc = norm(&forces(&corot, &d));
            assert!(
                fc <= 1e-10 * scale,
                "{:?} angle {angle}: corotational force {fc:e} vs scale {scale:e}",
                mesh.kind
            );
            let fl = norm(&forces(&linear, &d));
            assert!(
                fl > 0.1 * scale,
                "linear formulation should show ghost forces at angle {angle}: {fl:e}"
            );
        }
    }
}

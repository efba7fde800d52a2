//! Shared builders for the surface and blade tests: a 1 × 1 × 2 bar, bottom
//! face clamped, gravity, models built through the library.
#![allow(dead_code)]

pub mod case;

use nalgebra::{Point3, Vector3};
use xfem_cut::cut::CutSetup;
use xfem_cut::material::Material;
use xfem_cut::mesh::{box_mesh, TetMesh};
use xfem_cut::model::{Formulation, Model, ModelError, ModelInput};
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};

pub fn bar(div: [usize; 3]) -> TetMesh {
    box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 2.0), div)
}

pub const MATERIAL: Material = Material {
    young: 1.0e4,
    poisson: 0.3,
    density: 1000.0,
};

/// The bar's model: bottom (z = 0) clamped, gravity `g`, optionally the top (z = 2) moved by `top`.
pub fn model(
    mesh: &TetMesh,
    cut: Option<CutSetup>,
    formulation: Formulation,
    g: Vector3<f64>,
    top: Option<Vector3<f64>>,
    need_mass: bool,
) -> Result<Model, ModelError> {
    let mut fixed = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        if p.z == 0.0 {
            fixed.push((i, [Some(0.0); 3]));
        } else if let (Some(t), true) = (top, p.z == 2.0) {
            fixed.push((i, [Some(t.x), Some(t.y), Some(t.z)]));
        }
    }
    Model::build(ModelInput {
        mesh: mesh.clone(),
        material: MATERIAL,
        formulation,
        cut,
        fixed,
        gravity: Some(g),
        body_force: None,
        tractions: &[],
        need_mass,
    })
}

/// Static solution of a model (all DOFs).
pub fn solve(model: &Model) -> Vec<f64> {
    let mut chol = Cholesky::new(&model.pattern).unwrap();
    let sol = solve_static(model, &mut chol, &StaticOptions::default()).unwrap();
    assert!(sol.residual <= 1e-9, "residual {:e}", sol.residual);
    sol.d
}

/// Largest nodal difference of two solutions on the same mesh, seen from both sides, relative to the largest value.
pub fn relative_difference(a: &Model, da: &[f64], b: &Model, db: &[f64]) -> f64 {
    let (mut diff, mut scale): (f64, f64) = (0.0, 0.0);
    for i in 0..a.mesh.n_nodes() {
        for side in [-1i8, 1] {
            let (x, y) = (
                a.node_displacement(da, i, side),
                b.node_displacement(db, i, side),
            );
            diff = diff.max((x - y).norm());
            scale = scale.max(x.norm());
        }
    }
    diff / scale
}

/// The largest difference of two probe lists, relative to the largest
/// displacement of the first.
pub fn largest_difference(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let scale = a.iter().map(|v| v.norm()).fold(0.0, f64::max);
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).norm() / scale)
        .fold(0.0, f64::max)
}

/// The patch origin + s u + t v, s, t in [0, 1], as an n × n grid of quads,
/// two triangles each (inner edges and vertices too).
pub fn patch_triangles(
    origin: Point3<f64>,
    u: Vector3<f64>,
    v: Vector3<f64>,
    n: usize,
) -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
    let mut points = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            let (s, t) = (i as f64 / n as f64, j as f64 / n as f64);
            points.push(origin + u * s + v * t);
        }
    }
    let id = |i: usize, j: usize| j * (n + 1) + i;
    let mut tris = Vec::new();
    for j in 0..n {
        for i in 0..n {
            tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    (points, tris)
}

/// A closed box surface (12 triangles, normals outward): centre `c`,
/// half-sides `half` along the axes turned by `r`. Vertex k has the
/// half-side's + end along axis a where bit a of k is set.
pub fn box_triangles(
    c: Vector3<f64>,
    half: Vector3<f64>,
    r: nalgebra::Rotation3<f64>,
) -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
    let v: Vec<Point3<f64>> = (0..8)
        .map(|k| {
            let s = Vector3::new(
                if k & 1 == 1 { 1.0 } else { -1.0 },
                if k & 2 == 2 { 1.0 } else { -1.0 },
                if k & 4 == 4 { 1.0 } else { -1.0 },
            );
            Point3::from(c + r * s.component_mul(&half))
        })
        .collect();
    let mut tris = Vec::new();
    for q in [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ] {
        tris.push([q[0], q[1], q[2]]);
        tris.push([q[0], q[2], q[3]]);
    }
    (v, tris)
}

/// Runs a dynamic scene at its first level as the CLI does (its blades
/// cutting while it runs): the final model, state and sweep.
pub fn run_scene(scene: &xfem_cut::scene::Scene) -> xfem_cut::blade::Progressive {
    use xfem_cut::blade::{run_dynamic, CutSet};
    use xfem_cut::scene::Analysis;
    let mesh = scene.mesh(0).unwrap();
    let cuts = CutSet::from_scene(scene).unwrap();
    let (fixed, tractions) = scene.selections(&mesh).unwrap();
    let build = |cut| scene.model_input(mesh.clone(), cut, fixed.clone(), &tractions);
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        panic!("a dynamic scene")
    };
    run_dynamic(&cuts, &mesh, &build, options, |_, _, _| {}).unwrap()
}

/// A large corotational state of `model`: every node turned 60° about a
/// skew axis after a 5 % stretch and a wobble, every enriched DOF wobbled.
pub fn rotated_state(model: &Model) -> Vec<f64> {
    let rot = nalgebra::Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(Vector3::new(1.0, 2.0, 0.5)),
        std::f64::consts::FRAC_PI_3,
    );
    let mut d = vec![0.0; model.n_dofs()];
    for (i, p) in model.mesh.nodes.iter().enumerate() {
        let x = p.coords;
        let u = rot * Vector3::new(1.05 * x.x, x.y + 0.03 * (3.0 * x.z).sin(), x.z) - x;
        d[3 * i..3 * i + 3].copy_from_slice(u.as_slice());
    }
    for (k, v) in d.iter_mut().enumerate().skip(3 * model.mesh.n_nodes()) {
        *v = 0.01 * ((k as f64) * 0.7).sin();
    }
    d
}

/// The internal forces (all DOFs) at `d`, each group's rotation its polar
/// rotation there.
pub fn internal_forces(model: &Model, d: &[f64]) -> Vec<f64> {
    use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
    let mut f = vec![0.0; model.n_dofs()];
    evaluate(
        model,
        d,
        &mut Rotations::identity(model),
        &mut Workspace::new(model),
        Request {
            forces: Some(&mut f),
            tangent: None,
            update_rotations: true,
            exact_tangent: false,
        },
    );
    f
}

/// The exact corotational tangent at `d` against the whole Jacobian J of
/// [`internal_forces`] on the free DOFs, column by column by central
/// differences (step 1e-6): ‖K − J‖ / ‖J‖ and the antisymmetric part of J,
/// ‖J − sym J‖ / ‖J‖.
pub fn tangent_against_central_differences(model: &Model, d: &[f64]) -> (f64, f64) {
    use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
    let nf = model.n_free;
    let mut dof_of = vec![0; nf];
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != xfem_cut::model::NONE {
            dof_of[eq as usize] = dof;
        }
    }
    let h = 1e-6;
    let mut jac = nalgebra::DMatrix::<f64>::zeros(nf, nf);
    let mut dd = d.to_vec();
    for j in 0..nf {
        let dof = dof_of[j];
        dd[dof] = d[dof] + h;
        let fp = internal_forces(model, &dd);
        dd[dof] = d[dof] - h;
        let fm = internal_forces(model, &dd);
        dd[dof] = d[dof];
        for i in 0..nf {
            jac[(i, j)] = (fp[dof_of[i]] - fm[dof_of[i]]) / (2.0 * h);
        }
    }
    let mut k = vec![0.0; model.pattern.nnz()];
    evaluate(
        model,
        d,
        &mut Rotations::identity(model),
        &mut Workspace::new(model),
        Request {
            forces: None,
            tangent: Some(&mut k),
            update_rotations: true,
            exact_tangent: true,
        },
    );
    let mut tangent = nalgebra::DMatrix::<f64>::zeros(nf, nf);
    let (mut e, mut y) = (vec![0.0; nf], vec![0.0; nf]);
    for j in 0..nf {
        e[j] = 1.0;
        y.fill(0.0);
        model.pattern.sym_mul_add(&k, &e, &mut y);
        tangent.set_column(j, &nalgebra::DVector::from_column_slice(&y));
        e[j] = 0.0;
    }
    let symmetric = (&jac + jac.transpose()) * 0.5;
    (
        (&tangent - &jac).norm() / jac.norm(),
        (&jac - &symmetric).norm() / jac.norm(),
    )
}

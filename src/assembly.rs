//! Assembly: internal forces, strain energy and the tangent stiffness from the
//! per-group kernel, scattered into the free-DOF CSC values.
//!
//! This runs every Newton iteration / time step; it borrows the [`Model`] and
//! writes into buffers owned by the caller ([`Workspace`]), allocating nothing.

use crate::model::{group_rotation, Formulation, GroupKernel, Model, NONE};
use nalgebra::{Matrix3, Vector3};

/// Per-step state that persists across iterations: one rotation per group
/// (the warm start of the next polar decomposition).
#[derive(Debug, Clone)]
pub struct Rotations(pub Vec<Matrix3<f64>>);

impl Rotations {
    pub fn identity(model: &Model) -> Rotations {
        Rotations(vec![Matrix3::identity(); model.groups.len()])
    }
}

/// Scratch buffers sized for the largest element.
pub struct Workspace {
    rotated: Vec<Vector3<f64>>,
    disp: Vec<Vector3<f64>>,
    cross: Vec<[Vector3<f64>; 3]>,
}

impl Workspace {
    pub fn new(model: &Model) -> Workspace {
        let m = model
            .elements
            .iter()
            .map(|e| e.shapes.len())
            .max()
            .unwrap_or(0);
        Workspace {
            rotated: vec![Vector3::zeros(); m],
            disp: vec![Vector3::zeros(); m],
            cross: vec![[Vector3::zeros(); 3]; m],
        }
    }
}

/// What to compute in one pass over the elements.
pub struct Request<'a> {
    /// Internal forces, all DOFs (overwritten).
    pub forces: Option<&'a mut [f64]>,
    /// Tangent R K Rᵀ on the free DOFs, lower CSC values (overwritten).
    pub tangent: Option<&'a mut [f64]>,
    /// Update the rotations from `d` (corotational); otherwise use those stored.
    pub update_rotations: bool,
    /// Corotational: the exact tangent of the forces (rotation derivative
    /// included; statics) instead of R K Rᵀ (the seed's; dynamics).
    pub exact_tangent: bool,
}

/// One pass over all groups at displacement `d`: returns the strain energy.
pub fn evaluate(
    model: &Model,
    d: &[f64],
    rot: &mut Rotations,
    ws: &mut Workspace,
    mut req: Request<'_>,
) -> f64 {
    if let Some(f) = req.forces.as_deref_mut() {
        f.fill(0.0);
    }
    if let Some(k) = req.tangent.as_deref_mut() {
        k.fill(0.0);
    }
    let lame = model.lame;
    let mut energy = 0.0;
    for el in &model.elements {
        let shapes = &model.shape_ids[el.shapes.clone()];
        let m = shapes.len();
        for (a, &s) in shapes.iter().enumerate() {
            let s = s as usize;
            ws.disp[a] = Vector3::new(d[3 * s], d[3 * s + 1], d[3 * s + 2]);
        }
        for g in el.groups.clone() {
            let group = model.groups[g];
            let grads = &model.grads[group.grads as usize..group.grads as usize + m];
            let f = GroupKernel::deformation_gradient(grads, |a| ws.disp[a]);
            if req.update_rotations && model.formulation == Formulation::Corotational {
                rot.0[g] = group_rotation(model.formulation, &f, &rot.0[g]);
            }
            let kernel = GroupKernel {
                lame,
                weight: group.weight,
                grads,
                rotation: rot.0[g],
            };
            let eps = kernel.strain(&f);
            energy += kernel.energy(&eps);
            if let Some(out) = req.forces.as_deref_mut() {
                let sigma = kernel.stress(&eps);
                kernel.add_forces(&sigma, |a, fa| {
                    let s = shapes[a] as usize;
                    for c in 0..3 {
                        out[3 * s + c] += fa[c];
                    }
                });
            }
            if let Some(k) = req.tangent.as_deref_mut() {
                // Each global lower entry is reached from exactly one of (a,b,i,j), (b,a,j,i).
                let map = &model.scatter[el.scatter..el.scatter + 9 * m * m];
                let n = 3 * m;
                let mut add = |a: usize, b: usize, block: &Matrix3<f64>| {
                    for i in 0..3 {
                        for j in 0..3 {
                            let v = block[(i, j)];
                            let p1 = map[(3 * a + i) * n + 3 * b + j];
                            if p1 != NONE {
                                k[p1 as usize] += v;
                            }
                            if a != b {
                                let p2 = map[(3 * b + j) * n + 3 * a + i];
                                if p2 != NONE {
                                    k[p2 as usize] += v;
                                }
                            }
                        }
                    }
                };
                let exact = req.exact_tangent
                    && model.formulation == Formulation::Corotational
                    && kernel.exact_tangent_blocks(
                        &f,
                        &mut ws.rotated[..m],
                        &mut ws.cross[..m],
                        &mut add,
                    );
                if !exact {
                    kernel.tangent_blocks(&mut ws.rotated[..m], add);
                }
            }
        }
    }
    energy
}

/// y += R K Rᵀ z for all DOFs (z over all DOFs), with the stored rotations.
pub fn tangent_product(
    model: &Model,
    z: &[f64],
    rot: &Rotations,
    ws: &mut Workspace,
    y: &mut [f64],
) {
    let lame = model.lame;
    for el in &model.elements {
        let shapes = &model.shape_ids[el.shapes.clone()];
        let m = shapes.len();
        for (a, &s) in shapes.iter().enumerate() {
            let s = s as usize;
            ws.disp[a] = Vector3::new(z[3 * s], z[3 * s + 1], z[3 * s + 2]);
        }
        for g in el.groups.clone() {
            let group = model.groups[g];
            let grads = &model.grads[group.grads as usize..group.grads as usize + m];
            // ∇z, then the local strain of Rᵀz: sym(Rᵀ ∇z).
            let gz = GroupKernel::deformation_gradient(grads, |a| ws.disp[a]) - Matrix3::identity();
            let kernel = GroupKernel {
                lame,
                weight: group.weight,
                grads,
                rotation: rot.0[g],
            };
            let rgz = kernel.rotation.transpose() * gz;
            let eps = (rgz + rgz.transpose()) * 0.5;
            let sigma = kernel.stress(&eps);
            kernel.add_forces(&sigma, |a, fa| {
                let s = shapes[a] as usize;
                for c in 0..3 {
                    y[3 * s + c] += fa[c];
                }
            });
        }
    }
}

/// Copies the free part of a full-DOF vector into `out` (by equation number).
pub fn gather_free(model: &Model, full: &[f64], out: &mut [f64]) {
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != NONE {
            out[eq as usize] = full[dof];
        }
    }
}

/// Adds `free` (by equation number) into the full-DOF vector.
pub fn scatter_free_add(model: &Model, free: &[f64], full: &mut [f64]) {
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != NONE {
            full[dof] += free[eq as usize];
        }
    }
}

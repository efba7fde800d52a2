//! The per-group element kernel, run every Newton iteration and time step:
//! deformation gradient, rotation, stress, internal forces and tangent blocks
//! of one integration group (seed eq. 30, 36–40). It reads the group's
//! gradients and weight from the [`crate::model::Model`] and nothing else.

use crate::corotation::polar_rotation;
use crate::material::Lame;
use crate::model::Formulation;
use nalgebra::{Matrix3, Vector3};

/// Per-group kernel: deformation gradient, rotation, stress, forces, tangent.
///
/// Seed eq. (36)–(40): f = R K (Rᵀx − x₀), tangent R K Rᵀ, with K of eq. (30).
/// K_ab = w (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a·g_b) I), so R K_ab Rᵀ is built from
/// the rotated gradients R g_a without storing K.
pub struct GroupKernel<'a> {
    pub lame: Lame,
    pub weight: f64,
    pub grads: &'a [Vector3<f64>],
    pub rotation: Matrix3<f64>,
}

impl<'a> GroupKernel<'a> {
    /// Deformation gradient F = I + Σ_a d_a ⊗ ∇φ_a of the group.
    pub fn deformation_gradient(
        grads: &[Vector3<f64>],
        disp: impl Fn(usize) -> Vector3<f64>,
    ) -> Matrix3<f64> {
        let mut f = Matrix3::identity();
        for (a, g) in grads.iter().enumerate() {
            f += disp(a) * g.transpose();
        }
        f
    }

    /// Local (unrotated) small strain ε = sym(RᵀF) − I.
    pub fn strain(&self, f: &Matrix3<f64>) -> Matrix3<f64> {
        let rf = self.rotation.transpose() * f;
        (rf + rf.transpose()) * 0.5 - Matrix3::identity()
    }

    /// Stress σ = λ tr(ε) I + 2μ ε.
    pub fn stress(&self, eps: &Matrix3<f64>) -> Matrix3<f64> {
        Matrix3::identity() * (self.lame.lambda * eps.trace()) + eps * (2.0 * self.lame.mu)
    }

    /// Strain energy of the group, w (μ ε:ε + λ/2 tr(ε)²).
    pub fn energy(&self, eps: &Matrix3<f64>) -> f64 {
        self.weight
            * (self.lame.mu * eps.norm_squared() + 0.5 * self.lame.lambda * eps.trace().powi(2))
    }

    /// Internal forces f_a = w R σ ∇φ_a (adds to `out`, one per shape function).
    pub fn add_forces(&self, sigma: &Matrix3<f64>, mut out: impl FnMut(usize, Vector3<f64>)) {
        let rs = self.rotation * sigma * self.weight;
        for (a, g) in self.grads.iter().enumerate() {
            out(a, rs * g);
        }
    }

    /// The tangent R K Rᵀ block by block, for b ≤ a only (the matrix is
    /// symmetric): calls `add(a, b, block)` with the 3×3 block (a, b).
    pub fn tangent_blocks(
        &self,
        rotated: &mut [Vector3<f64>],
        mut add: impl FnMut(usize, usize, &Matrix3<f64>),
    ) {
        let (lambda, mu, w) = (self.lame.lambda, self.lame.mu, self.weight);
        for (r, g) in rotated.iter_mut().zip(self.grads) {
            *r = self.rotation * g;
        }
        for a in 0..self.grads.len() {
            let ra = rotated[a] * w;
            for b in 0..=a {
                let rb = rotated[b];
                let dot = mu * w * self.grads[a].dot(&self.grads[b]);
                let mut block = ra * rb.transpose() * lambda + rb * ra.transpose() * mu;
                block[(0, 0)] += dot;
                block[(1, 1)] += dot;
                block[(2, 2)] += dot;
                add(a, b, &block);
            }
        }
    }

    /// The exact tangent of the corotational forces (the derivative of the
    /// polar rotation included), block by block for b ≤ a, at deformation
    /// gradient `f` whose polar rotation is `self.rotation`:
    ///
    /// K_ab[i][j] = w (2μ δ_ij ∇φ_a·∇φ_b + λ (R∇φ_a)_i (R∇φ_b)_j
    ///              + (λ tr ε − 2μ) (R (v_jb × ∇φ_a))_i),
    /// v_jb = (tr S I − S)⁻¹ (∇φ_b × Rᵀe_j), S = RᵀF,
    ///
    /// from dP = 2μ (dF − dR) + λ tr(RᵀdF) R + λ tr ε dR, dR = R W with
    /// (tr S I − S) axial(W) = axial(RᵀdF − dFᵀR) (refs/README.md derives it).
    /// R K Rᵀ drops the dR terms; they are the geometric stiffness that a
    /// slender body in bending needs for Newton to converge. Returns false
    /// (and adds nothing) where tr S I − S is singular (a degenerate element),
    /// so the caller can use R K Rᵀ for the group.
    pub fn exact_tangent_blocks(
        &self,
        f: &Matrix3<f64>,
        rotated: &mut [Vector3<f64>],
        v: &mut [[Vector3<f64>; 3]],
        mut add: impl FnMut(usize, usize, &Matrix3<f64>),
    ) -> bool {
        let (lambda, mu, w) = (self.lame.lambda, self.lame.mu, self.weight);
        let r = self.rotation;
        let s = r.transpose() * f;
        let s = (s + s.transpose()) * 0.5;
        let tr = s.trace();
        let z = Matrix3::identity() * tr - s;
        let scale = tr.abs().max(1.0);
        if z.determinant().abs() <= 1e-10 * scale * scale * scale {
            return false;
        }
        let Some(z_inv) = z.try_inverse() else {
            return false;
        };
        let c = lambda * (tr - 3.0) - 2.0 * mu;
        for (b, g) in self.grads.iter().enumerate() {
            rotated[b] = r * g;
            for j in 0..3 {
                let rj = Vector3::new(r[(j, 0)], r[(j, 1)], r[(j, 2)]);
                v[b][j] = z_inv * g.cross(&rj);
            }
        }
        for a in 0..self.grads.len() {
            let ga = self.grads[a];
            for b in 0..=a {
                let dot = 2.0 * mu * ga.dot(&self.grads[b]);
                let mut block = rotated[a] * rotated[b].transpose() * lambda;
                for j in 0..3 {
                    let col = r * v[b][j].cross(&ga) * c;
                    for i in 0..3 {
                        block[(i, j)] += col[i];
                    }
                    block[(j, j)] += dot;
                }
                add(a, b, &(block * w));
            }
        }
        true
    }
}

/// Rotation of a group for the formulation (identity for linear).
pub fn group_rotation(
    formulation: Formulation,
    f: &Matrix3<f64>,
    guess: &Matrix3<f64>,
) -> Matrix3<f64> {
    match formulation {
        Formulation::Linear => Matrix3::identity(),
        Formulation::Corotational => polar_rotation(f, guess),
    }
}

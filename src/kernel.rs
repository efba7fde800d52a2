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

/// The kernel of a dense group (one rotation for many quadrature points,
/// [`crate::model::Group`]): local displacements u_a = Rᵀ(X_a + d_a) − X_a
/// (X_a = 0 for enriched functions), local forces h = K u, energy
/// E = ½ u·h. With R fixed this is exactly the sum of its points'
/// [`GroupKernel`]s sharing R: RᵀF_q − I = Σ_a u_a ⊗ ∇φ_a(q), since the
/// standard functions reproduce X (Σ X_a ⊗ ∇φ_a = I).
///
/// R is the polar rotation of the group's F̄ = I + Σ_a d_a ⊗ ḡ_a, and the
/// forces are the gradient of E(x) with R = R(F̄(x)):
/// f_b = R h_b − T_bᵀ τ, with τ = Σ_a u_a × h_a (the moment of the local
/// forces about the rotated frame; zero for one point, whose RᵀF is
/// symmetric) and T_b = Z⁻¹ [ḡ_b]× Rᵀ the rotation's derivative
/// (ω = Σ_b T_b dx_b for dR = R [ω]×; Z = tr S I − S, S = RᵀF̄). So the
/// group is conservative (energy is kept in dynamics) and its tangent is a
/// Hessian: symmetric, as the Cholesky solve needs. (R h_b alone, the
/// seed's R K (Rᵀx − x₀), is not a gradient when the points' RᵀF_q differ:
/// its Jacobian has an antisymmetric part of the order of the stress.)
pub struct DenseKernel<'a> {
    /// The symmetric (3m)² K by its lower triangle, rows packed
    /// ([`packed_len`] values: row i's columns 0..=i from i(i+1)/2).
    pub stiffness: &'a [f64],
    pub rotation: Matrix3<f64>,
}

/// Values of a symmetric n × n matrix held by its lower triangle, rows
/// packed ([`DenseKernel::stiffness`]). Half the (3m)² of the full matrix:
/// a dense tip group's K u reads its K from memory at every force pass
/// (60 × 60 a Tet4 tip element, 6.7 MB over the 234 groups of the 1k-Tet4
/// tip scene), so halving it halves that pass.
pub fn packed_len(n: usize) -> usize {
    n * (n + 1) / 2
}

/// Position of entry (r, c) of a symmetric matrix in its packed lower
/// triangle (either order).
#[inline(always)]
pub fn packed_index(r: usize, c: usize) -> usize {
    let (r, c) = if r >= c { (r, c) } else { (c, r) };
    r * (r + 1) / 2 + c
}

/// The rotation derivative of a dense group at F̄: Z⁻¹, S, and per
/// function T_b = Z⁻¹ [ḡ_b]× Rᵀ.
pub struct RotationDerivative {
    pub s: Matrix3<f64>,
    pub z_inv: Matrix3<f64>,
}

/// The force correction −T_bᵀ τ's data: the rotation derivative, the
/// averaged gradients and τ.
pub type Correction<'a> = (&'a RotationDerivative, &'a [Vector3<f64>], Vector3<f64>);

fn cross3(v: &[f64]) -> Matrix3<f64> {
    Vector3::new(v[0], v[1], v[2]).cross_matrix()
}

fn vec3(v: &[f64]) -> Vector3<f64> {
    Vector3::new(v[0], v[1], v[2])
}

impl DenseKernel<'_> {
    /// u and y = u + X (3m each) from the displacements `disp` and
    /// reference positions `x0`.
    pub fn local_displacements(
        &self,
        disp: &[Vector3<f64>],
        x0: impl Fn(usize) -> Vector3<f64>,
        u: &mut [f64],
        y: &mut [f64],
    ) {
        let rt = self.rotation.transpose();
        for (a, d) in disp.iter().enumerate() {
            let x = x0(a);
            let ya = rt * (x + d);
            let ua = ya - x;
            u[3 * a..3 * a + 3].copy_from_slice(ua.as_slice());
            y[3 * a..3 * a + 3].copy_from_slice(ya.as_slice());
        }
    }

    /// h = K u; returns the energy ½ u·h. One pass over the packed lower
    /// triangle: row i's entries left of the diagonal give h_i their dot
    /// with u and, as the upper triangle's column i, add u_i times
    /// themselves to h_0..h_{i−1}.
    pub fn local_forces(&self, u: &[f64], h: &mut [f64]) -> f64 {
        let n = u.len();
        let h = &mut h[..n];
        h.fill(0.0);
        let mut start = 0;
        for i in 0..n {
            let row = &self.stiffness[start..start + i];
            let (left, rest) = h.split_at_mut(i);
            rest[0] += dot_axpy(row, &u[..i], u[i], left) + self.stiffness[start + i] * u[i];
            start += i + 1;
        }
        0.5 * dot(u, h)
    }

    /// Z⁻¹ and S at F̄ `f`, or `None` where Z is singular (a degenerate
    /// state: the caller then drops the rotation's derivative).
    pub fn rotation_derivative(&self, f: &Matrix3<f64>) -> Option<RotationDerivative> {
        let s = self.rotation.transpose() * f;
        let s = (s + s.transpose()) * 0.5;
        let tr = s.trace();
        let z = Matrix3::identity() * tr - s;
        let scale = tr.abs().max(1.0);
        if z.determinant().abs() <= 1e-10 * scale * scale * scale {
            return None;
        }
        z.try_inverse().map(|z_inv| RotationDerivative { s, z_inv })
    }

    /// τ = Σ_a u_a × h_a.
    pub fn moment(u: &[f64], h: &[f64]) -> Vector3<f64> {
        u.chunks_exact(3)
            .zip(h.chunks_exact(3))
            .fold(Vector3::zeros(), |t, (ua, ha)| {
                t + vec3(ua).cross(&vec3(ha))
            })
    }

    /// Forces f_b = R h_b − T_bᵀ τ (adds to `out`, one per shape function);
    /// without `derivative`, R h_b.
    pub fn add_forces(
        &self,
        h: &[f64],
        correction: Option<Correction<'_>>,
        mut out: impl FnMut(usize, Vector3<f64>),
    ) {
        let r = self.rotation;
        // T_bᵀ τ = R [ḡ_b]×ᵀ Z⁻ᵀ τ = −R (ḡ_b × Z⁻ᵀ τ).
        let zt = correction.map(|(rd, grads, tau)| (rd.z_inv.transpose() * tau, grads));
        for (a, ha) in h.chunks_exact(3).enumerate() {
            let mut fa = vec3(ha);
            if let Some((zt, grads)) = zt {
                fa += grads[a].cross(&zt);
            }
            out(a, r * fa);
        }
    }

    /// Block (a, b) of the local stiffness.
    #[inline(always)]
    fn block(&self, a: usize, b: usize) -> Matrix3<f64> {
        Matrix3::from_fn(|i, j| self.stiffness[packed_index(3 * a + i, 3 * b + j)])
    }

    /// The tangent R K Rᵀ block by block, for b ≤ a.
    pub fn tangent_blocks(&self, m: usize, mut add: impl FnMut(usize, usize, &Matrix3<f64>)) {
        let r = self.rotation;
        for a in 0..m {
            for b in 0..=a {
                add(a, b, &(r * self.block(a, b) * r.transpose()));
            }
        }
    }

    /// The Hessian of the group's energy (the exact tangent of its forces),
    /// block by block for b ≤ a; `grads` the averaged gradients, `u`, `y`,
    /// `h` the local displacements, positions and forces at this state:
    ///
    /// H_ab = R K_ab Rᵀ + P_a T_b + T_aᵀ P_bᵀ − T_aᵀ A T_b + D_ab, where
    /// - P_a = R Q_a, Q_a = Σ_c K_ac [u_c]× − [h_a]×: d(R h_a) = R K_ab Rᵀ
    ///   dx_b + P_a ω (dR = R [ω]×, du_c = Rᵀdx_c + [y_c]× ω, and K
    ///   annihilates the infinitesimal rotation of X);
    /// - dτ = Σ_b (A T_b − P_bᵀ) dx_b, A = Σ_a ([u_a]× N_a − [h_a]× [y_a]×),
    ///   N_a = Σ_c K_ac [u_c]× (∂τ/∂ω and ∂τ/∂x);
    /// - D_ab e_k = −(dT_a/dx_bk)ᵀ τ = R (ḡ_a × v₁) + R (ω_bk × (ḡ_a × v₂)),
    ///   v₁ = −Z⁻ᵀ dZᵀ Z⁻ᵀ τ, v₂ = Z⁻ᵀ τ, dZ = tr(dS) I − dS,
    ///   dS = sym(−[ω_bk]× S + Rᵀ e_k ḡ_bᵀ), ω_bk = T_b e_k.
    ///
    /// For one point τ ≡ 0 and this is [`GroupKernel::exact_tangent_blocks`].
    ///
    /// Compiled for the widest SIMD the machine has (run-time dispatch; the
    /// same operations in the same order on every path).
    #[allow(clippy::too_many_arguments)]
    pub fn exact_tangent_blocks(
        &self,
        rd: &RotationDerivative,
        grads: &[Vector3<f64>],
        u: &[f64],
        y: &[f64],
        h: &[f64],
        p: &mut [Matrix3<f64>],
        t: &mut [Matrix3<f64>],
        rows: &mut [[f64; 3]],
        add: impl FnMut(usize, usize, &Matrix3<f64>),
    ) {
        pulp::Arch::new().dispatch(
            #[inline(always)]
            || self.exact_tangent_blocks_here(rd, grads, u, y, h, p, t, rows, add),
        )
    }

    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn exact_tangent_blocks_here(
        &self,
        rd: &RotationDerivative,
        grads: &[Vector3<f64>],
        u: &[f64],
        y: &[f64],
        h: &[f64],
        p: &mut [Matrix3<f64>],
        t: &mut [Matrix3<f64>],
        rows: &mut [[f64; 3]],
        mut add: impl FnMut(usize, usize, &Matrix3<f64>),
    ) {
        // In the group's frame: H_ab = R L_ab Rᵀ with L_ab = K_ab + Q_a T̂_b
        // + T̂_aᵀ (Q_bᵀ − A T̂_b) + M_ab, T_b = T̂_b Rᵀ (T̂_b = Z⁻¹ [ḡ_b]×), and
        // M_ab e_l = D_ab R e_l (ω_bl = T̂_b e_l, dS = sym(−[ω_bl]× S + e_l ḡ_bᵀ)).
        let m = grads.len();
        let r = self.rotation;
        let tau = DenseKernel::moment(u, h);
        let mut a_mat = Matrix3::zeros();
        // N = K X, X's rows 3c..3c+2 those of [u_c]×: one pass over the
        // packed lower triangle (entry (i, j), j < i, adds K_ij X_j to N_i
        // and K_ij X_i to N_j).
        let n = 3 * m;
        let (x, nk) = rows[..2 * n].split_at_mut(n);
        for (c, uc) in u.chunks_exact(3).enumerate() {
            x[3 * c] = [0.0, -uc[2], uc[1]];
            x[3 * c + 1] = [uc[2], 0.0, -uc[0]];
            x[3 * c + 2] = [-uc[1], uc[0], 0.0];
        }
        nk.fill([0.0; 3]);
        let mut start = 0;
        for i in 0..n {
            let (row, xi) = (&self.stiffness[start..start + i], x[i]);
            let kii = self.stiffness[start + i];
            let mut acc = [kii * xi[0], kii * xi[1], kii * xi[2]];
            for ((&kij, xj), nj) in row.iter().zip(x.iter()).zip(nk.iter_mut()) {
                for l in 0..3 {
                    acc[l] += kij * xj[l];
                    nj[l] += kij * xi[l];
                }
            }
            for l in 0..3 {
                nk[i][l] += acc[l];
            }
            start += i + 1;
        }
        for a in 0..m {
            let na = Matrix3::from_fn(|i, l| nk[3 * a + i][l]);
            let ha = cross3(&h[3 * a..3 * a + 3]);
            a_mat += cross3(&u[3 * a..3 * a + 3]) * na - ha * cross3(&y[3 * a..3 * a + 3]);
            p[a] = na - ha;
            t[a] = rd.z_inv * grads[a].cross_matrix();
        }
        let zt = rd.z_inv.transpose();
        let v2 = zt * tau;
        for b in 0..m {
            let u_b = p[b].transpose() - a_mat * t[b];
            let mut v1 = [Vector3::zeros(); 3];
            let mut omega = [Vector3::zeros(); 3];
            for l in 0..3 {
                let w = t[b].column(l).into_owned();
                let mut el = Vector3::zeros();
                el[l] = 1.0;
                let ds = -w.cross_matrix() * rd.s + el * grads[b].transpose();
                let ds = (ds + ds.transpose()) * 0.5;
                let dz = Matrix3::identity() * ds.trace() - ds;
                v1[l] = -(zt * dz.transpose() * zt) * tau;
                omega[l] = w;
            }
            for a in b..m {
                let mut local = self.block(a, b) + p[a] * t[b] + t[a].transpose() * u_b;
                let gv2 = grads[a].cross(&v2);
                for l in 0..3 {
                    let col = grads[a].cross(&v1[l]) + omega[l].cross(&gv2);
                    for i in 0..3 {
                        local[(i, l)] += col[i];
                    }
                }
                add(a, b, &(r * local * r.transpose()));
            }
        }
    }
}

/// Σ_j k_j u_j, with y_j += k_j x on the way (four running sums, as [`dot`]).
#[inline(always)]
fn dot_axpy(k: &[f64], u: &[f64], x: f64, y: &mut [f64]) -> f64 {
    let (k4, u4) = (k.chunks_exact(4), u.chunks_exact(4));
    let (kt, ut) = (k4.remainder(), u4.remainder());
    let mut y4 = y.chunks_exact_mut(4);
    let mut s = [0.0; 4];
    for ((kc, uc), yc) in k4.zip(u4).zip(&mut y4) {
        for l in 0..4 {
            s[l] += kc[l] * uc[l];
            yc[l] += kc[l] * x;
        }
    }
    let mut tail = 0.0;
    for ((kv, uv), yv) in kt.iter().zip(ut).zip(y4.into_remainder()) {
        tail += kv * uv;
        *yv += kv * x;
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// a · b with four running sums, so the compiler can keep them in one SIMD
/// register (a single running sum is a chain of dependent additions: a
/// dense tip group's K u, (3m)² terms, took 56 % of a linear 1k-Tet4 step).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let (a4, b4) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = a4
        .remainder()
        .iter()
        .zip(b4.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut s = [0.0; 4];
    for (x, y) in a4.zip(b4) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A symmetric n × n matrix (row-major) and its packed lower triangle.
    fn symmetric(n: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut full = vec![0.0; n * n];
        for r in 0..n {
            for c in 0..=r {
                let v = next();
                full[r * n + c] = v;
                full[c * n + r] = v;
            }
        }
        let mut packed = vec![0.0; packed_len(n)];
        for r in 0..n {
            for c in 0..=r {
                packed[packed_index(r, c)] = full[r * n + c];
                assert_eq!(packed_index(r, c), packed_index(c, r));
            }
        }
        (full, packed)
    }

    #[test]
    fn packed_forces_and_blocks_equal_the_full_matrix() {
        // m = 1, 2, 7 and 20 (a Tet4 tip element's functions): the row
        // lengths of the packed pass cover every remainder of the chunks of 4.
        for m in [1, 2, 7, 20] {
            let n = 3 * m;
            let (full, packed) = symmetric(n, m as u64);
            let kernel = DenseKernel {
                stiffness: &packed,
                rotation: Matrix3::identity(),
            };
            let u: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut h = vec![f64::NAN; n];
            let energy = kernel.local_forces(&u, &mut h);
            let mut want_energy = 0.0;
            for i in 0..n {
                let want: f64 = (0..n).map(|j| full[i * n + j] * u[j]).sum();
                assert!(
                    (h[i] - want).abs() <= 1e-14 * (1.0 + want.abs()),
                    "m {m} row {i}"
                );
                want_energy += 0.5 * u[i] * want;
            }
            assert!((energy - want_energy).abs() <= 1e-13 * (1.0 + want_energy.abs()));
            for a in 0..m {
                for b in 0..=a {
                    let block = kernel.block(a, b);
                    for i in 0..3 {
                        for j in 0..3 {
                            assert_eq!(block[(i, j)], full[(3 * a + i) * n + 3 * b + j]);
                        }
                    }
                }
            }
        }
    }
}

//! Code verification: exact solutions run through the solver, no reference
//! software. Two cases, each at several levels, with relative L2 and energy
//! errors and the orders they give beside the orders theory expects:
//!
//! - [`ThroughCut`], a manufactured solution with a jump: a smooth field on
//!   each side of an oblique plane that cuts the unit box completely (a
//!   different field on each side), body force f = −div σ and cut-face
//!   traction t = σ n from the field (analytic, [`SmoothField`]), the field
//!   imposed on the whole outer boundary. X-FEM Heaviside Tet4 and Tet10:
//!   the enriched space holds each side's interpolant, so the orders are the
//!   smooth ones, 2 / 1 (Tet4) and 3 / 2 (Tet10) in L2 / energy.
//! - [`WilliamsFront`], the near-front field: Williams' mode I+II (plane
//!   strain) + III field around a straight front crossing the box obliquely
//!   (an exact solution of 3-D linear elasticity with traction-free crack
//!   faces), imposed on the whole outer boundary, with geometric tip,
//!   topological tip and extended cuts (issue 11).
//!
//! [`run_study`] runs every [`Variant`]; rows go to `reports/data/exact.csv`.

use crate::assembly::{field_load, FieldLoadAt};
use crate::cut::{setup_cut, Blending, CutInput, CutSetup, FrontMode, PlanarPatch};
use crate::front::{branch_with_gradients, N_BRANCH};
use crate::io::csv::{read_rows, sci, write_rows};
use crate::io::IoError;
use crate::material::{Lame, Material};
use crate::mesh::{box_mesh, ElementKind, TetMesh, TET10_EDGES};
use crate::model::{Formulation, Model, ModelInput};
use crate::solve::Cholesky;
use crate::statics::{solve_static, StaticOptions};
use crate::study::StudyError;
use nalgebra::{Matrix3, Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

/// The material of both cases (unit box, unit Young's modulus).
pub const MATERIAL: Material = Material {
    young: 1.0,
    poisson: 0.3,
    density: 1.0,
};

/// The profile g of a ridge term a g(k·x + p).
#[derive(Debug, Clone, Copy)]
pub enum Profile {
    Sin,
    Exp,
    /// g(s) = sⁿ.
    Power(i32),
}

impl Profile {
    /// g, g′, g″ at s.
    pub fn eval(self, s: f64) -> [f64; 3] {
        match self {
            Profile::Sin => [s.sin(), s.cos(), -s.sin()],
            Profile::Exp => [s.exp(); 3],
            Profile::Power(n) => {
                let f = f64::from(n);
                let p = |k: i32| if k < 0 { 0.0 } else { s.powi(k) };
                [p(n), f * p(n - 1), f * (f - 1.0) * p(n - 2)]
            }
        }
    }
}

/// One ridge term u = a g(k·x + p): ∇u = g′ a kᵀ, ∂²u_i/∂x_j∂x_l = g″ a_i k_j k_l.
#[derive(Debug, Clone, Copy)]
pub struct Ridge {
    pub a: Vector3<f64>,
    pub k: Vector3<f64>,
    pub p: f64,
    pub g: Profile,
}

/// A smooth displacement field: a sum of ridge terms, with its gradient,
/// stress and the body force that keeps it in equilibrium, all in closed form.
#[derive(Debug, Clone)]
pub struct SmoothField {
    pub terms: Vec<Ridge>,
}

impl SmoothField {
    pub fn value(&self, x: &Point3<f64>) -> Vector3<f64> {
        self.terms.iter().fold(Vector3::zeros(), |s, t| {
            s + t.a * t.g.eval(t.k.dot(&x.coords) + t.p)[0]
        })
    }

    /// ∇u (rows: components of u, columns: ∂/∂x_j).
    pub fn gradient(&self, x: &Point3<f64>) -> Matrix3<f64> {
        self.terms.iter().fold(Matrix3::zeros(), |s, t| {
            s + t.a * t.k.transpose() * t.g.eval(t.k.dot(&x.coords) + t.p)[1]
        })
    }

    /// f = −div σ(u) for linear elasticity (seed eq. 9 with σ = λ tr ε I + 2μ ε):
    /// per term −g″ [(λ + μ)(a·k) k + μ |k|² a].
    pub fn body_force(&self, x: &Point3<f64>, lame: &Lame) -> Vector3<f64> {
        self.terms.iter().fold(Vector3::zeros(), |s, t| {
            let g2 = t.g.eval(t.k.dot(&x.coords) + t.p)[2];
            s - (t.k * ((lame.lambda + lame.mu) * t.a.dot(&t.k))
                + t.a * (lame.mu * t.k.norm_squared()))
                * g2
        })
    }
}

/// Linear-elastic stress of a displacement gradient.
pub fn stress(gu: &Matrix3<f64>, lame: &Lame) -> Matrix3<f64> {
    let eps = (gu + gu.transpose()) * 0.5;
    Matrix3::identity() * (lame.lambda * eps.trace()) + eps * (2.0 * lame.mu)
}

/// Strain energy density ½ ε:σ of a displacement gradient.
pub fn energy_density(gu: &Matrix3<f64>, lame: &Lame) -> f64 {
    let eps = (gu + gu.transpose()) * 0.5;
    lame.mu * eps.norm_squared() + 0.5 * lame.lambda * eps.trace().powi(2)
}

/// Nodes of the unit box's boundary.
fn on_boundary(p: &Point3<f64>) -> bool {
    (0..3).any(|c| p[c].abs() < 1e-12 || (p[c] - 1.0).abs() < 1e-12)
}

/// A structured mesh of [0,1]³ (6 tets per cube), interior nodes jittered by up to `jitter` h.
pub fn unit_box(div: usize, kind: ElementKind, jitter: f64) -> TetMesh {
    let mut m = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [div; 3]);
    let h = 1.0 / div as f64;
    let mut seed: u64 = 0x2545_f491_4f6c_dd1d;
    let mut rnd = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for p in m.nodes.iter_mut() {
        let d = Vector3::new(rnd(), rnd(), rnd()) * (jitter * h);
        if !on_boundary(p) {
            *p += d;
        }
    }
    match kind {
        ElementKind::Tet4 => m,
        ElementKind::Tet10 => m.to_tet10(),
    }
}

/// The linear static model of an exact-solution problem on `mesh`: the
/// study's material, `cut` (None on a pre-cut mesh), the DOFs `fixed`, no
/// other load (add a manufactured one to [`Model::load`]).
pub fn linear_model(
    mesh: TetMesh,
    cut: Option<CutSetup>,
    fixed: Vec<(usize, [Option<f64>; 3])>,
) -> Result<Model, crate::model::ModelError> {
    Model::build(ModelInput {
        mesh,
        material: MATERIAL,
        formulation: Formulation::Linear,
        cut,
        fixed,
        gravity: None,
        body_force: None,
        tractions: &[],
        need_mass: false,
    })
}

/// A plane patch through `c` with unit normal `n`, reaching 3 beyond the unit box.
fn plane_patch(c: Point3<f64>, n: Vector3<f64>) -> PlanarPatch {
    let t0 = if n.x.abs() < 0.9 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let t1 = (t0 - n * n.dot(&t0)).normalize();
    let t2 = n.cross(&t1);
    PlanarPatch {
        origin: c - t1 * 3.0 - t2 * 3.0,
        u: t1 * 6.0,
        v: t2 * 6.0,
    }
}

/// The manufactured solution with a jump: `plus` where n·(x − c) ≥ 0, `minus` elsewhere.
#[derive(Debug, Clone)]
pub struct ThroughCut {
    pub c: Point3<f64>,
    pub n: Vector3<f64>,
    pub plus: SmoothField,
    pub minus: SmoothField,
}

impl Default for ThroughCut {
    fn default() -> Self {
        ThroughCut::new()
    }
}

impl ThroughCut {
    /// The plane n ∝ (0.3, 1, 0.2) through (0.5, 0.47, 0.52) (it leaves the box
    /// through its four side faces); polynomial + trigonometric on the + side,
    /// exponential + trigonometric + offset on the − side.
    pub fn new() -> ThroughCut {
        let v = Vector3::new;
        ThroughCut {
            c: Point3::new(0.5, 0.47, 0.52),
            n: v(0.3, 1.0, 0.2).normalize(),
            plus: SmoothField {
                terms: vec![
                    Ridge {
                        a: v(1.0, 0.4, -0.6),
                        k: v(1.3, -0.7, 0.9) * 2.0,
                        p: 0.2,
                        g: Profile::Sin,
                    },
                    Ridge {
                        a: v(0.3, -0.2, 0.5),
                        k: v(0.5, 0.8, -0.4),
                        p: 0.1,
                        g: Profile::Power(3),
                    },
                    Ridge {
                        a: v(-0.2, 0.6, 0.1),
                        k: v(0.9, 0.2, 0.7),
                        p: -0.3,
                        g: Profile::Power(2),
                    },
                ],
            },
            minus: SmoothField {
                terms: vec![
                    Ridge {
                        a: v(-0.4, 0.9, 0.2),
                        k: v(0.6, -0.3, 0.8),
                        p: 0.0,
                        g: Profile::Exp,
                    },
                    Ridge {
                        a: v(0.2, 0.1, 0.7),
                        k: v(-1.1, 2.0, 0.4) * 1.5,
                        p: 0.3,
                        g: Profile::Sin,
                    },
                    Ridge {
                        a: v(0.3, -0.5, 0.4),
                        k: Vector3::zeros(),
                        p: 1.0,
                        g: Profile::Power(0),
                    },
                ],
            },
        }
    }

    pub fn patch(&self) -> PlanarPatch {
        plane_patch(self.c, self.n)
    }

    /// The signed distance to the plane.
    pub fn level_set(&self, x: &Point3<f64>) -> f64 {
        self.n.dot(&(x - self.c))
    }

    /// The field of side `side` (±1; 0: the side x lies on).
    pub fn field(&self, x: &Point3<f64>, side: i8) -> &SmoothField {
        let side = if side != 0 {
            side
        } else if self.level_set(x) >= 0.0 {
            1
        } else {
            -1
        };
        if side > 0 {
            &self.plus
        } else {
            &self.minus
        }
    }

    /// Exact displacement and gradient at x seen from `side`.
    pub fn exact(&self, x: &Point3<f64>, side: i8) -> (Vector3<f64>, Matrix3<f64>) {
        let f = self.field(x, side);
        (f.value(x), f.gradient(x))
    }

    /// Body force or cut-face traction σ n_out of side `side` at x.
    pub fn load(
        &self,
        x: &Point3<f64>,
        side: i8,
        at: FieldLoadAt<'_>,
        lame: &Lame,
    ) -> Vector3<f64> {
        let f = self.field(x, side);
        match at {
            FieldLoadAt::Volume => f.body_force(x, lame),
            FieldLoadAt::CutFace { normal } => stress(&f.gradient(x), lame) * normal,
        }
    }

    /// Prescribed values on every boundary node: the standard DOFs the own
    /// side's field, the Heaviside DOFs a_i = H_i (u_own − u_other)(x_i), so
    /// that u_i + ψ a_i (ψ = (s − H_i)/2, eq. 58–59) is each side's field at
    /// the node seen from either side.
    pub fn boundary_values(
        &self,
        mesh: &TetMesh,
        cut: &CutSetup,
    ) -> Vec<(usize, [Option<f64>; 3])> {
        let n_nodes = mesh.n_nodes();
        let mut fixed = Vec::new();
        for (i, p) in mesh.nodes.iter().enumerate() {
            if !on_boundary(p) {
                continue;
            }
            let side = cut.node_side[i];
            let own = self.exact(p, side).0;
            fixed.push((i, own.map(Some).into()));
            if let Some(j) = cut.enriched[i] {
                let a = (own - self.exact(p, -side).0) * f64::from(side);
                fixed.push((n_nodes + j, a.map(Some).into()));
            }
        }
        fixed
    }
}

/// The straight front: a line through `c` along `t` in the plane with normal
/// `n`; the crack lies behind it (−m side, m = n × t).
#[derive(Debug, Clone)]
pub struct WilliamsFront {
    pub c: Point3<f64>,
    pub n: Vector3<f64>,
    pub t: Vector3<f64>,
    pub m: Vector3<f64>,
    /// Williams coefficients b_k of the branch functions F_k (global frame).
    pub b: [Vector3<f64>; N_BRANCH],
}

impl Default for WilliamsFront {
    fn default() -> Self {
        WilliamsFront::new()
    }
}

impl WilliamsFront {
    /// K_I = 1, K_II = 0.7, K_III = 0.5 about a front through (0.513, 0.479, 0.507).
    pub fn new() -> WilliamsFront {
        WilliamsFront::oriented(
            Point3::new(0.513, 0.479, 0.507),
            Vector3::new(0.15, 1.0, 0.2),
            Vector3::new(0.1, 0.05, 1.0),
        )
    }

    /// The same field about the front through `c` in the plane of normal
    /// `normal`, along `along` projected into that plane.
    pub fn oriented(c: Point3<f64>, normal: Vector3<f64>, along: Vector3<f64>) -> WilliamsFront {
        let n = normal.normalize();
        let t = (along - n * n.dot(&along)).normalize();
        let m = n.cross(&t);
        let mu = Lame::from(MATERIAL).mu;
        let kappa = 3.0 - 4.0 * MATERIAL.poisson;
        let s = (2.0 * std::f64::consts::PI).sqrt();
        let (k1, k2, k3) = (1.0, 0.7, 0.5);
        let (c1, c2, c3) = (k1 / (2.0 * mu) / s, k2 / (2.0 * mu) / s, 2.0 * k3 / mu / s);
        // Local frame (x = m ahead, y = n normal, z = t along the front):
        // mode I  u_x = c1((κ−1)F2 + F3), u_y = c1((κ+1)F1 − F4);
        // mode II u_x = c2((κ+1)F1 + F4), u_y = c2(−(κ−1)F2 + F3); mode III u_z = c3 F1.
        let local = [
            Vector3::new(c2 * (kappa + 1.0), c1 * (kappa + 1.0), c3),
            Vector3::new(c1 * (kappa - 1.0), -c2 * (kappa - 1.0), 0.0),
            Vector3::new(c1, c2, 0.0),
            Vector3::new(c2, -c1, 0.0),
        ];
        let r = Matrix3::from_columns(&[m, n, t]);
        WilliamsFront {
            c,
            n,
            t,
            m,
            b: local.map(|v| r * v),
        }
    }

    /// The crack: the half plane behind the front (reaching 3 beyond the box).
    pub fn patch(&self) -> PlanarPatch {
        let l = 3.0;
        PlanarPatch {
            origin: self.c - self.t * l - self.m * l,
            u: self.t * (2.0 * l),
            v: self.m * l,
        }
    }

    /// (φ, ψ): distance to the crack plane and, in it, to the front.
    pub fn level_sets(&self, x: &Point3<f64>) -> (f64, f64) {
        (self.n.dot(&(x - self.c)), self.m.dot(&(x - self.c)))
    }

    /// The length of the front inside the unit box: its line c + s t
    /// clipped to [0, 1]³ (what the tip DOFs per length of front divide by).
    pub fn length_in_unit_box(&self) -> f64 {
        let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for k in 0..3 {
            let (c, t) = (self.c[k], self.t[k]);
            if t.abs() < 1e-15 {
                if !(0.0..=1.0).contains(&c) {
                    return 0.0;
                }
                continue;
            }
            let (a, b) = ((0.0 - c) / t, (1.0 - c) / t);
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        }
        (hi - lo).max(0.0)
    }

    /// Exact displacement and gradient at x seen from `side` (0: from φ's sign).
    pub fn exact(&self, x: &Point3<f64>, side: i8) -> (Vector3<f64>, Matrix3<f64>) {
        let (f, g) = self.level_sets(x);
        let (v, gr) = branch_with_gradients(f, g, &self.n, &self.m, side);
        let mut u = Vector3::zeros();
        let mut gu = Matrix3::zeros();
        for k in 0..N_BRANCH {
            u += self.b[k] * v[k];
            gu += self.b[k] * gr[k].transpose();
        }
        (u, gu)
    }

    /// The standard DOF value at node `i` that makes u_h(x_i) = u(x_i): the
    /// exact value, less, at a Tet10 mid-node, what the tip functions of its
    /// edge's tip-enriched vertices add there: ½ Σ_v (F(x_i) − F(x_v)) b.
    pub fn standard_value(
        &self,
        mesh: &TetMesh,
        cut: &CutSetup,
        edges: &[Option<(usize, usize)>],
        i: usize,
    ) -> Vector3<f64> {
        let x = mesh.nodes[i];
        let side = cut.node_side[i];
        let mut u = self.exact(&x, side).0;
        if let Some((a, b)) = edges[i] {
            for v in [a, b] {
                let w = cut.edge_tip_weight(a, b, v);
                if w > 0.0 {
                    let held = held_branches(mesh, cut, v);
                    let part = |p: &Point3<f64>, side: i8| {
                        let (f, g) = self.level_sets(p);
                        let z = Vector3::zeros();
                        let (values, _) = branch_with_gradients(f, g, &z, &z, side);
                        (0..N_BRANCH)
                            .filter(|k| !held.contains(k))
                            .fold(Vector3::zeros(), |u, k| u + self.b[k] * values[k])
                    };
                    u -= (part(&x, side) - part(&mesh.nodes[v], cut.node_side[v])) * (0.5 * w);
                }
            }
        }
        u
    }

    /// Prescribed values on every boundary node: standard DOFs the exact nodal
    /// value, Heaviside DOFs the jump to the other side's continuation
    /// (u_other = −u_i: every branch function changes sign under θ → θ − 2π),
    /// tip DOFs the Williams coefficients b_k times √h ([`CutSetup::tip_scale`]).
    pub fn boundary_values(
        &self,
        mesh: &TetMesh,
        cut: &CutSetup,
    ) -> Vec<(usize, [Option<f64>; 3])> {
        let edges = mid_edges(mesh);
        let mut fixed = Vec::new();
        for (i, p) in mesh.nodes.iter().enumerate() {
            if on_boundary(p) {
                self.node_values(mesh, cut, &edges, i, |s, v| {
                    fixed.push((s, v.map(Some).into()))
                });
            }
        }
        fixed
    }

    /// The field's nodal interpolant: the DOFs ([`Self::boundary_values`]'
    /// at every node) of all `n_shape` shape functions, 3 a shape (the
    /// model's full DOF vector). Where every vertex of an element is
    /// tip-enriched it is the field itself; elsewhere its error is the
    /// space's (`examples/blending_zones.rs`).
    pub fn interpolant(&self, mesh: &TetMesh, cut: &CutSetup, n_shape: usize) -> Vec<f64> {
        let edges = mid_edges(mesh);
        let mut d = vec![0.0; 3 * n_shape];
        for i in 0..mesh.n_nodes() {
            self.node_values(mesh, cut, &edges, i, |s, v| {
                d[3 * s..3 * s + 3].copy_from_slice(v.as_slice())
            });
        }
        d
    }

    /// The DOF values of node `i`'s shape functions that interpolate the
    /// field, each handed to `put(shape, value)`.
    fn node_values(
        &self,
        mesh: &TetMesh,
        cut: &CutSetup,
        edges: &[Option<(usize, usize)>],
        i: usize,
        mut put: impl FnMut(usize, Vector3<f64>),
    ) {
        let n_nodes = mesh.n_nodes();
        let p = &mesh.nodes[i];
        let side = cut.node_side[i];
        put(i, self.standard_value(mesh, cut, edges, i));
        if let Some(j) = cut.enriched[i] {
            // a = H (u_own − u_other − (T_own − T_other)): the jump the
            // Heaviside DOF must add to what the tip functions of a
            // mid-node's tip-enriched edge vertices already jump there,
            // ½ (F(+) − F(−)) b each. u_other = −u_own for this field, so
            // a = 2 H u_own (1 − k/2) with k such vertices (0 at a vertex).
            let k = edges[i].map_or(0.0, |(a, b)| {
                cut.edge_tip_weight(a, b, a) + cut.edge_tip_weight(a, b, b)
            });
            // With the ramp the node's Heaviside function makes 1 − R_i of
            // the jump there and the tip functions (on every vertex of an
            // element with R > 0) the rest: a = the whole jump.
            let own = self.exact(p, side).0;
            let share = if cut.ramp.is_empty() {
                1.0 - 0.5 * k
            } else {
                1.0
            };
            put(n_nodes + j, own * (2.0 * f64::from(side) * share));
        }
        if let Some(t) = cut.tip[i] {
            // (A ring node's held branch functions are zero.) The
            // model's functions are over √h: their DOFs are b √h.
            let held = held_branches(mesh, cut, i);
            for k in 0..N_BRANCH {
                let b = if held.contains(&k) {
                    Vector3::zeros()
                } else {
                    self.b[k] / cut.tip_scale[t]
                };
                put(n_nodes + cut.n_enriched + N_BRANCH * t + k, b);
            }
        }
    }
}

/// The branch functions of tip node `i` held at zero: on the ramp's ring,
/// those outside [`crate::model::tip_branches`]; none elsewhere.
fn held_branches(mesh: &TetMesh, cut: &CutSetup, i: usize) -> Vec<usize> {
    let free = crate::model::tip_branches(mesh.kind, cut, i);
    (0..N_BRANCH).filter(|k| !free.contains(k)).collect()
}

/// Per node, the vertices of the edge it is the mid-node of (Tet10).
pub fn mid_edges(mesh: &TetMesh) -> Vec<Option<(usize, usize)>> {
    let mut out = vec![None; mesh.n_nodes()];
    if mesh.kind == ElementKind::Tet10 {
        for e in 0..mesh.n_elements() {
            let c = mesh.element(e);
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                out[c[4 + k]] = Some((c[a], c[b]));
            }
        }
    }
    out
}

/// The "perfectly remeshed" cut of the Tet4 `mesh` by the plane φ = 0 of
/// `level_set`: every element the plane crosses split into a tet and a prism
/// or two prisms, each prism into three tets by the smallest-global-id rule
/// (Dompierre et al. 1999), so that neighbours split their shared faces
/// alike and the mesh is conforming; the nodes on the plane (edge
/// intersections, computed from each edge in one order) duplicated per side;
/// then Tet10 when `kind` asks. A node with φ = 0 counts as the + side.
/// Returns the mesh and each node's side.
pub fn precut_mesh(
    mesh: &TetMesh,
    level_set: impl Fn(&Point3<f64>) -> f64,
    kind: ElementKind,
) -> (TetMesh, Vec<i8>) {
    use std::collections::HashMap;
    let phi: Vec<f64> = mesh.nodes.iter().map(&level_set).collect();
    let n_nodes = mesh.n_nodes();
    // Global point ids: nodes, then edge intersections (by vertex pair).
    let mut edge_id: HashMap<(usize, usize), usize> = HashMap::new();
    let mut points: Vec<Point3<f64>> = mesh.nodes.clone();
    let mut cross = |a: usize, b: usize, points: &mut Vec<Point3<f64>>| -> usize {
        let (i, j) = (a.min(b), a.max(b));
        *edge_id.entry((i, j)).or_insert_with(|| {
            let t = phi[i] / (phi[i] - phi[j]);
            points.push(mesh.nodes[i] + (mesh.nodes[j] - mesh.nodes[i]) * t);
            points.len() - 1
        })
    };
    let mut tets: Vec<([usize; 4], i8)> = Vec::new();
    let prism = |p: [usize; 6], side: i8, tets: &mut Vec<([usize; 4], i8)>| {
        const ROT: [[usize; 6]; 6] = [
            [0, 1, 2, 3, 4, 5],
            [1, 2, 0, 4, 5, 3],
            [2, 0, 1, 5, 3, 4],
            [3, 5, 4, 0, 2, 1],
            [4, 3, 5, 1, 0, 2],
            [5, 4, 3, 2, 1, 0],
        ];
        let k = (0..6).min_by_key(|&k| p[k]).unwrap_or(0);
        let v = ROT[k].map(|r| p[r]);
        let split = if v[1].min(v[5]) < v[2].min(v[4]) {
            [[0, 1, 2, 5], [0, 1, 5, 4], [0, 4, 5, 3]]
        } else {
            [[0, 1, 2, 4], [0, 4, 2, 5], [0, 4, 5, 3]]
        };
        for t in split {
            tets.push((t.map(|q| v[q]), side));
        }
    };
    for e in 0..mesh.n_elements() {
        let v = mesh.vertices(e);
        let plus: Vec<usize> = v.iter().copied().filter(|&i| phi[i] >= 0.0).collect();
        let minus: Vec<usize> = v.iter().copied().filter(|&i| phi[i] < 0.0).collect();
        match (plus.len(), minus.len()) {
            (4, _) => tets.push((v, 1)),
            (_, 4) => tets.push((v, -1)),
            (1, 3) | (3, 1) => {
                let (one, three, s) = if plus.len() == 1 {
                    (plus[0], &minus, 1)
                } else {
                    (minus[0], &plus, -1)
                };
                let q = three
                    .iter()
                    .map(|&b| cross(one, b, &mut points))
                    .collect::<Vec<_>>();
                tets.push(([one, q[0], q[1], q[2]], s));
                prism(
                    [three[0], three[1], three[2], q[0], q[1], q[2]],
                    -s,
                    &mut tets,
                );
            }
            _ => {
                let (a, b, c, d) = (plus[0], plus[1], minus[0], minus[1]);
                let (ac, ad, bc, bd) = (
                    cross(a, c, &mut points),
                    cross(a, d, &mut points),
                    cross(b, c, &mut points),
                    cross(b, d, &mut points),
                );
                prism([a, ac, ad, b, bc, bd], 1, &mut tets);
                prism([c, ac, bc, d, ad, bd], -1, &mut tets);
            }
        }
    }
    // Nodes: one per (side, point) used.
    let mut index: HashMap<(i8, usize), usize> = HashMap::new();
    let mut nodes = Vec::new();
    let mut cells = Vec::with_capacity(4 * tets.len());
    for (t, s) in &tets {
        for &p in t {
            let side = if p < n_nodes {
                if phi[p] >= 0.0 {
                    1
                } else {
                    -1
                }
            } else {
                *s
            };
            let id = *index.entry((side, p)).or_insert_with(|| {
                nodes.push(points[p]);
                nodes.len() - 1
            });
            cells.push(id);
        }
    }
    let mut m = TetMesh {
        kind: ElementKind::Tet4,
        nodes,
        cells,
    };
    m.orient_positively();
    if kind == ElementKind::Tet10 {
        m = m.to_tet10();
    }
    let mut side = vec![0i8; m.n_nodes()];
    for (e, (_, s)) in tets.iter().enumerate() {
        for &i in m.element(e) {
            side[i] = *s;
        }
    }
    (m, side)
}

/// Adds ∫ t·N_a over the faces of `mesh` on the plane of `tc` (each from its
/// element's side, outward normal) to `load` (standard shapes, no cut).
fn add_interface_traction(mesh: &TetMesh, side: &[i8], tc: &ThroughCut, load: &mut [f64]) {
    use crate::element::shape_values;
    use crate::mesh::{barycentric, TET_FACES};
    let lame = Lame::from(MATERIAL);
    let gauss = crate::front::gauss_legendre(4);
    let mut n = [0.0; 10];
    for e in 0..mesh.n_elements() {
        let verts = mesh.vertex_points(e);
        let tol = 1e-9 * mesh.element_size(e);
        let s = side[mesh.element(e)[0]];
        for (opposite, face) in TET_FACES.iter().enumerate() {
            let p = face.map(|k| verts[k]);
            if p.iter().any(|x| tc.level_set(x).abs() > tol) {
                continue;
            }
            let cross = (p[1] - p[0]).cross(&(p[2] - p[0]));
            let area2 = cross.norm();
            let mut normal = cross / area2;
            if normal.dot(&(verts[opposite] - p[0])) > 0.0 {
                normal = -normal;
            }
            for &(u, wu) in &gauss {
                for &(v, wv) in &gauss {
                    let x = p[0] + (p[1] - p[0]) * u + (p[2] - p[0]) * (v * (1.0 - u));
                    let w = wu * wv * (1.0 - u) * area2;
                    let t = tc.load(&x, s, FieldLoadAt::CutFace { normal: &normal }, &lame);
                    shape_values(
                        mesh.kind,
                        &barycentric(&verts, &x).unwrap_or([0.25; 4]),
                        &mut n,
                    );
                    for (k, &i) in mesh.element(e).iter().enumerate() {
                        for c in 0..3 {
                            load[3 * i + c] += w * t[c] * n[k];
                        }
                    }
                }
            }
        }
    }
}

/// Relative L2 and energy errors of `d` against `exact` (value, gradient by
/// point and side), integrated with [`Model::field_points`]; a point of an
/// element the cut does not enrich has side 0.
pub fn relative_errors(
    model: &Model,
    d: &[f64],
    exact: impl Fn(&Point3<f64>, i8) -> (Vector3<f64>, Matrix3<f64>),
) -> (f64, f64) {
    let lame = Lame::from(model.material);
    let (mut e2, mut u2, mut ee, mut ue) = (0.0, 0.0, 0.0, 0.0);
    for e in 0..model.mesh.n_elements() {
        for (x, w, side) in model.field_points(e) {
            let (uh, gh) = model.field_at(d, e, &x, side);
            let (u, g) = exact(&x, side);
            e2 += w * (uh - u).norm_squared();
            u2 += w * u.norm_squared();
            ee += w * energy_density(&(gh - g), &lame);
            ue += w * energy_density(&g, &lame);
        }
    }
    ((e2 / u2).sqrt(), (ee / ue).sqrt())
}

/// Which exact solution.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Case {
    ThroughCut,
    NearFront,
}

impl Case {
    /// What the case is, for the report.
    pub fn description(self) -> &'static str {
        match self {
            Case::ThroughCut => "A manufactured solution with a jump: on each side of the oblique plane n ∝ (0.3, 1, 0.2) through (0.5, 0.47, 0.52), which cuts the box completely, its own smooth field (+ side: sine, cubic and quadratic ridge terms; − side: exponential and sine ridge terms and an offset). Body force f = −div σ in closed form and the traction σ n_out on both cut faces from each side's field (`assembly::field_load`); on the outer boundary the standard DOFs take the own side's field and the Heaviside DOFs the jump to the other side's field, so the discrete field equals the exact one at boundary nodes from both sides. X-FEM Heaviside holds each side's interpolant: theory 2 / 1 (Tet4) and 3 / 2 (Tet10) in L2 / energy. `FEM pre-cut`: the perfectly remeshed cut, FEM on a conforming mesh of the same structured box with every element the plane crosses split along it (the nodes on the plane duplicated per side, `exact::precut_mesh`), the same loads (the traction on the faces on the plane) and the same theory.",
            Case::NearFront => "Williams' near-front field (modes I + II in plane strain, K_I = 1, K_II = 0.7, and mode III, K_III = 0.5) around a straight front through (0.513, 0.479, 0.507) crossing the box obliquely, the crack behind it: an exact solution of 3-D linear elasticity with traction-free crack faces and no body force. Boundary values: standard DOFs the exact nodal values, Heaviside DOFs the jump the tip functions do not already make, tip DOFs the Williams coefficients (times √h: the functions are over √h). Theory: geometric tip enrichment (every node within R = 0.2 of the front) restores the smooth rates (2 / 1 for Tet4, 3 / 2 for Tet10); topological tip enrichment (the nodes of front elements) is limited by the √r singularity outside the enriched band (1 / 0.5); `extend` lengthens the cut by up to an element and has no clean rate. Tet10's geometric rows fall short of 3 / 2 and stay so deeper than the table goes (2.79 / 1.74 from n = 12 to 16, 2.68 / 1.69 to 20): the one-element ramp does not lift them, and the quadrature only in part: rules refined further (the front cells' collapsed rules 5 → 8 points a direction, the polar rule's (4, 3) → (7, 5), the cells near the front red-refined 3 deep out to twice their size) moved the energy errors by under 0.4 % at n = 8 and 12 and by 1.4 / 3.5 % at n = 16 / 20, the last order 1.69 → 1.79; what limits them is the blending layer (`examples/blending_zones.rs`, `tests/front.rs` `tet10_blending_layer_interpolant_converges_at_about_one_and_a_half`): the field's nodal interpolant is the field itself in the elements all of whose vertices are tip-enriched (error 1e-12) and errs 3.27e-2 / 1.84e-2 / 1.23e-2 in energy in the one-element blending layer at n = 8 / 12 / 16 (order 1.43, 1.40), where the partial partition of unity Σ_{k∈I} λ_k, whose gradient is 1/h, multiplies the branch functions and what the quadratic functions must make up of them errs O(h^1.5) in energy; the linear one-element ramp leaves that interpolant the same function. The Galerkin solution does better than the interpolant there (its blending part converges at 1.9–2.0) by moving error into the fully enriched elements (order 1.0–1.3, 15 / 24 / 32 % of the error² at n = 8 / 12 / 16), and its orders stay under 2 with that trade. A blending function smooth over a width that does not shrink with h (cutoff-function enrichment) is the known remedy; it is not built.",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Case::ThroughCut => "through_cut",
            Case::NearFront => "near_front",
        }
    }
}

/// One variant of a case: element, cut treatment, levels and the orders
/// theory expects (L2, energy; `None` where there is no clean rate).
#[derive(Debug, Clone)]
pub struct Variant {
    pub case: Case,
    pub name: &'static str,
    pub kind: ElementKind,
    pub front: FrontMode,
    pub tip_radius: Option<f64>,
    /// Interior nodes moved by up to this fraction of h (0: structured).
    pub jitter: f64,
    /// What the tip functions do in blending elements: a case's default
    /// ([`Blending::for_cut`]: with Tet4 and `tip_radius` the ramp of
    /// corrected X-FEM where R spans [`crate::cut::RAMP_SPAN`] elements,
    /// here from n = 16 on), or none ("no ramp" in the name: standard
    /// X-FEM, for comparison).
    pub blending: Blending,
    /// FEM on the pre-cut conforming mesh ([`precut_mesh`]) instead of X-FEM.
    pub precut: bool,
    /// Divisions per box edge, one per level.
    pub divisions: Vec<usize>,
    pub theory: Theory,
}

/// Orders theory expects in (L2, energy); `None` where there is no clean rate.
pub type Theory = (Option<f64>, Option<f64>);

/// The variants the report runs (about 5 minutes on 2 cores); "jittered":
/// interior nodes moved by up to 0.2 h; "no ramp": standard X-FEM in the
/// blending elements ([`Blending::None`]) where a case's default ramps them.
pub fn study_variants() -> Vec<Variant> {
    /// Case, name, element, front, tip radius, divisions, theory (L2, energy).
    type Entry = (
        Case,
        &'static str,
        ElementKind,
        FrontMode,
        Option<f64>,
        &'static [usize],
        Theory,
    );
    use ElementKind::{Tet10, Tet4};
    use FrontMode::{Extend, Tip};
    let (t4, t10) = ((Some(2.0), Some(1.0)), (Some(3.0), Some(2.0)));
    #[rustfmt::skip]
    let table: [Entry; 13] = [
        (Case::ThroughCut, "FEM pre-cut", Tet4, Extend, None, &[4, 6, 8, 12, 16], t4),
        (Case::ThroughCut, "FEM pre-cut", Tet10, Extend, None, &[2, 3, 4, 6, 8], t10),
        (Case::ThroughCut, "xfem heaviside", Tet4, Extend, None, &[4, 6, 8, 12, 16], t4),
        (Case::ThroughCut, "xfem heaviside", Tet10, Extend, None, &[2, 3, 4, 6, 8], t10),
        (Case::ThroughCut, "xfem heaviside jittered", Tet4, Extend, None, &[4, 6, 8, 12, 16], t4),
        (Case::ThroughCut, "xfem heaviside jittered", Tet10, Extend, None, &[2, 3, 4, 6, 8], t10),
        (Case::NearFront, "geometric tip R=0.2", Tet4, Tip, Some(0.2), &[6, 8, 12, 16, 24, 32], t4),
        (Case::NearFront, "geometric tip R=0.2", Tet10, Tip, Some(0.2), &[2, 3, 4, 6, 8, 12], t10),
        (Case::NearFront, "geometric tip R=0.2 jittered", Tet4, Tip, Some(0.2), &[6, 8, 12, 16, 24, 32], t4),
        (Case::NearFront, "geometric tip R=0.2 no ramp jittered", Tet4, Tip, Some(0.2), &[12, 16, 24, 32], t4),
        (Case::NearFront, "geometric tip R=0.2 jittered", Tet10, Tip, Some(0.2), &[3, 4, 6, 8, 12], t10),
        (Case::NearFront, "topological tip", Tet4, Tip, None, &[6, 8, 12, 16], (Some(1.0), Some(0.5))),
        (Case::NearFront, "extend", Tet4, Extend, None, &[6, 8, 12, 16], (None, None)),
    ];
    table
        .into_iter()
        .map(
            |(case, name, kind, front, tip_radius, divisions, theory)| Variant {
                case,
                name,
                kind,
                front,
                tip_radius,
                jitter: if name.contains("jittered") { 0.2 } else { 0.0 },
                blending: if name.contains("no ramp") {
                    Blending::None
                } else {
                    Blending::for_cut(front, tip_radius, kind)
                },
                precut: name.starts_with("FEM"),
                divisions: divisions.to_vec(),
                theory,
            },
        )
        .collect()
}

/// The prefix of the [`radius_sweep`] variants' names.
pub const SWEEP: &str = "tip_radius sweep";

/// What `tip_radius` buys: the near-front case on one mesh per element
/// (Tet4 n = 16, Tet10 n = 6), the front extended (no tip DOFs), tip-enriched
/// topologically, and geometrically with R from under an element to most of
/// the box. `xfem-cut converge --exact` runs them after [`study_variants`]
/// (one level each: no orders); the report tabulates the tip DOFs per unit
/// length of front against R with the errors and times they buy.
pub fn radius_sweep() -> Vec<Variant> {
    let mut out = Vec::new();
    for (kind, n) in [(ElementKind::Tet4, 16), (ElementKind::Tet10, 6)] {
        let mut add = |name: &'static str, front: FrontMode, tip_radius: Option<f64>| {
            out.push(Variant {
                case: Case::NearFront,
                name,
                kind,
                front,
                tip_radius,
                jitter: 0.0,
                blending: Blending::for_cut(front, tip_radius, kind),
                precut: false,
                divisions: vec![n],
                theory: (None, None),
            })
        };
        add("tip_radius sweep: extend", FrontMode::Extend, None);
        add("tip_radius sweep: topological", FrontMode::Tip, None);
        add("tip_radius sweep: R=0.05", FrontMode::Tip, Some(0.05));
        add("tip_radius sweep: R=0.1", FrontMode::Tip, Some(0.1));
        add("tip_radius sweep: R=0.2", FrontMode::Tip, Some(0.2));
        add("tip_radius sweep: R=0.3", FrontMode::Tip, Some(0.3));
        add("tip_radius sweep: R=0.4", FrontMode::Tip, Some(0.4));
    }
    out
}

/// What the [`radius_sweep`]'s rows (in its order: extend, topological, R
/// ascending, per element) must show: tip enrichment at least halves the
/// extended front's L2 error; a larger R never enriches fewer nodes, and
/// where it enriches more, both errors fall; R = 0.4 enriches more nodes
/// than the front elements hold. The first failure, in words.
pub fn check_radius_sweep(rows: &[&Row]) -> Result<(), String> {
    let variants = radius_sweep();
    for kind in [ElementKind::Tet4, ElementKind::Tet10] {
        let names: Vec<&str> = variants
            .iter()
            .filter(|v| v.kind == kind)
            .map(|v| v.name)
            .collect();
        let k: Vec<&Row> = names
            .iter()
            .map(|n| {
                rows.iter()
                    .copied()
                    .find(|r| r.element == kind.name() && r.variant == *n)
                    .ok_or_else(|| format!("{} {n}: no row", kind.name()))
            })
            .collect::<Result<_, _>>()?;
        let kind = kind.name();
        if k[0].tip != 0 {
            return Err(format!("{kind} extend: {} tip nodes", k[0].tip));
        }
        if k[1].l2 * 2.0 >= k[0].l2 {
            return Err(format!(
                "{kind}: topological tip L2 {:.3e} not under half of extend's {:.3e}",
                k[1].l2, k[0].l2
            ));
        }
        for w in k[1..].windows(2) {
            let (a, b) = (w[0], w[1]);
            if b.tip < a.tip || b.dofs < a.dofs {
                return Err(format!(
                    "{kind} {}: fewer tip nodes or DOFs than {}",
                    b.variant, a.variant
                ));
            }
            if b.tip > a.tip && !(b.l2 < a.l2 && b.energy < a.energy) {
                return Err(format!(
                    "{kind} {}: L2 {:.3e}, energy {:.3e} not below {}'s {:.3e}, {:.3e}",
                    b.variant, b.l2, b.energy, a.variant, a.l2, a.energy
                ));
            }
        }
        let (top, last) = (k[1], k[k.len() - 1]);
        if last.tip <= top.tip {
            return Err(format!(
                "{kind} {}: no more tip nodes than topological",
                last.variant
            ));
        }
    }
    Ok(())
}

/// Where the study writes its rows, relative to `reports/`.
pub const CSV: &str = "data/exact.csv";

/// One solve of an exact-solution case: a row of `exact.csv`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Row {
    pub case: String,
    pub variant: String,
    pub element: String,
    pub level: usize,
    /// Divisions per edge of the unit box (h = 1/divisions).
    pub divisions: usize,
    pub elements: usize,
    pub dofs: usize,
    pub heaviside: usize,
    pub tip: usize,
    #[serde(rename = "l2_rel", serialize_with = "sci")]
    pub l2: f64,
    #[serde(rename = "energy_rel", serialize_with = "sci")]
    pub energy: f64,
    /// The orders theory expects (NaN: none).
    #[serde(rename = "l2_theory", serialize_with = "sci")]
    pub l2_theory: f64,
    #[serde(rename = "energy_theory", serialize_with = "sci")]
    pub energy_theory: f64,
    #[serde(rename = "seconds", serialize_with = "sci")]
    pub seconds: f64,
}

/// Solves `variant` at `divisions` and measures its errors.
pub fn solve(variant: &Variant, level: usize) -> Result<Row, StudyError> {
    let t0 = Instant::now();
    let div = variant.divisions[level];
    let mesh_kind = if variant.precut {
        ElementKind::Tet4
    } else {
        variant.kind
    };
    let mesh = unit_box(div, mesh_kind, variant.jitter);
    let lame = Lame::from(MATERIAL);
    let through = ThroughCut::new();
    let front = WilliamsFront::new();
    let patch = match variant.case {
        Case::ThroughCut => through.patch(),
        Case::NearFront => front.patch(),
    };
    let cut = setup_cut(
        &mesh,
        &[CutInput {
            surface: &patch,
            snap: crate::cut::DEFAULT_SNAP,
            front: variant.front,
            tip_radius: variant.tip_radius,
            blending: variant.blending,
        }],
    )?;
    if variant.precut {
        return solve_precut(variant, level, &mesh, &through, t0);
    }
    let fixed = match variant.case {
        Case::ThroughCut => through.boundary_values(&mesh, &cut),
        Case::NearFront => front.boundary_values(&mesh, &cut),
    };
    let (heaviside, tip) = (cut.n_heaviside(), cut.n_tip());
    let elements = mesh.n_elements();
    let mut model = linear_model(mesh, Some(cut), fixed)?;
    if variant.case == Case::ThroughCut {
        let load = field_load(&model, |x, side, at| through.load(x, side, at, &lame));
        for (l, f) in model.load.iter_mut().zip(load) {
            *l += f;
        }
    }
    let mut chol = Cholesky::new(&model.pattern)?;
    let sol = solve_static(&model, &mut chol, &StaticOptions::default())?;
    let (l2, energy) = match variant.case {
        Case::ThroughCut => relative_errors(&model, &sol.d, |x, s| through.exact(x, s)),
        Case::NearFront => relative_errors(&model, &sol.d, |x, s| front.exact(x, s)),
    };
    Ok(Row {
        case: variant.case.name().to_string(),
        variant: variant.name.to_string(),
        element: variant.kind.name().to_string(),
        level,
        divisions: div,
        elements,
        dofs: model.n_free,
        heaviside,
        tip,
        l2,
        energy,
        l2_theory: variant.theory.0.unwrap_or(f64::NAN),
        energy_theory: variant.theory.1.unwrap_or(f64::NAN),
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// FEM on the pre-cut conforming mesh ([`precut_mesh`]) of the through-cut:
/// every boundary node prescribed to its side's field, the body force and the
/// traction on both faces of the plane from each side's field.
fn solve_precut(
    variant: &Variant,
    level: usize,
    mesh: &TetMesh,
    tc: &ThroughCut,
    t0: Instant,
) -> Result<Row, StudyError> {
    let (mesh, side) = precut_mesh(mesh, |x| tc.level_set(x), variant.kind);
    let lame = Lame::from(MATERIAL);
    let fixed = mesh
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, p)| on_boundary(p))
        .map(|(i, p)| (i, tc.exact(p, side[i]).0.map(Some).into()))
        .collect();
    let elements = mesh.n_elements();
    let side_copy = side.clone();
    let mut model = linear_model(mesh, None, fixed)?;
    let load = field_load(&model, |x, s, at| tc.load(x, s, at, &lame));
    for (l, f) in model.load.iter_mut().zip(load) {
        *l += f;
    }
    add_interface_traction(&model.mesh, &side_copy, tc, &mut model.load);
    let mut chol = Cholesky::new(&model.pattern)?;
    let sol = solve_static(&model, &mut chol, &StaticOptions::default())?;
    // Points are inside elements, so the plane's sign gives their side.
    let (l2, energy) = relative_errors(&model, &sol.d, |x, s| tc.exact(x, s));
    Ok(Row {
        case: variant.case.name().to_string(),
        variant: variant.name.to_string(),
        element: variant.kind.name().to_string(),
        level,
        divisions: variant.divisions[level],
        elements,
        dofs: model.n_free,
        heaviside: 0,
        tip: 0,
        l2,
        energy,
        l2_theory: variant.theory.0.unwrap_or(f64::NAN),
        energy_theory: variant.theory.1.unwrap_or(f64::NAN),
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Runs every level of every variant; `progress` is told each finished solve.
pub fn run_study(
    variants: &[Variant],
    mut progress: impl FnMut(&Row),
) -> Result<Vec<Row>, StudyError> {
    let mut rows = Vec::new();
    for v in variants {
        for level in 0..v.divisions.len() {
            let row = solve(v, level).map_err(|e| {
                e.during(format!(
                    "{} {} {} n = {}",
                    v.case.name(),
                    v.name,
                    v.kind.name(),
                    v.divisions[level]
                ))
            })?;
            progress(&row);
            rows.push(row);
        }
    }
    Ok(rows)
}

/// Observed orders in h (L2, energy) between the last two levels of rows of one variant.
pub fn last_orders(rows: &[&Row]) -> Option<(f64, f64)> {
    let [.., a, b] = rows else {
        return None;
    };
    let r = (b.divisions as f64 / a.divisions as f64).ln();
    Some(((a.l2 / b.l2).ln() / r, (a.energy / b.energy).ln() / r))
}

/// Rows grouped by (case, variant, element), in their order of appearance.
pub fn by_variant(rows: &[Row]) -> Vec<Vec<&Row>> {
    let mut out: Vec<Vec<&Row>> = Vec::new();
    for r in rows {
        match out
            .iter_mut()
            .find(|g| g[0].case == r.case && g[0].variant == r.variant && g[0].element == r.element)
        {
            Some(g) => g.push(r),
            None => out.push(vec![r]),
        }
    }
    out
}

/// The hash of what the study's rows depend on: this executable (the solver
/// and the study code) and the variants run. `xfem-cut converge --exact`
/// keeps it next to the CSV (`exact.csv.hash`) and skips a run whose inputs
/// have not changed, as `make refs` does for the references.
pub fn inputs_hash(variants: &[Variant]) -> Result<String, StudyError> {
    use std::hash::{Hash, Hasher};
    let exe = std::env::current_exe()
        .map_err(|e| IoError::os(Path::new("the running executable"), "locate", e))?;
    let bytes = std::fs::read(&exe).map_err(|e| IoError::os(&exe, "read", e))?;
    let mut h = std::hash::DefaultHasher::new();
    bytes.hash(&mut h);
    format!("{variants:?}").hash(&mut h);
    Ok(format!("{:016x}", h.finish()))
}

pub fn write_csv(path: &Path, rows: &[Row]) -> Result<(), IoError> {
    write_rows(path, rows)
}

pub fn read_csv(path: &Path) -> Result<Vec<Row>, IoError> {
    read_rows(path, false)
}

//! A crack front inside elements (issue 11): the exact Williams mode I+II+III
//! field around a straight front that crosses a box obliquely, imposed on the
//! whole outer boundary, and the X-FEM solution's L2 and energy errors under
//! refinement for geometric tip, topological tip and extended cuts.

use nalgebra::{Matrix3, Point3, Vector3};
use xfem_cut::cut::{setup_cut, CutInput, CutSetup, FrontMode, PlanarPatch};
use xfem_cut::front::{branch_with_gradients, N_BRANCH};
use xfem_cut::material::{Lame, Material};
use xfem_cut::mesh::{box_mesh, ElementKind, TetMesh};
use xfem_cut::model::{Formulation, Model, ModelInput};
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};

const MATERIAL: Material = Material {
    young: 1.0,
    poisson: 0.3,
    density: 1.0,
};

/// The front: a straight line through `c` along `t`, in the plane with normal
/// `n`; the cut lies behind it (−m side, m = n × t).
struct Front {
    c: Point3<f64>,
    n: Vector3<f64>,
    t: Vector3<f64>,
    m: Vector3<f64>,
    /// Williams coefficients b_k of F_k (global frame).
    b: [Vector3<f64>; N_BRANCH],
}

impl Front {
    fn new() -> Front {
        let c = Point3::new(0.513, 0.479, 0.507);
        let n = Vector3::new(0.15, 1.0, 0.2).normalize();
        let t0 = Vector3::new(0.1, 0.05, 1.0);
        let t = (t0 - n * n.dot(&t0)).normalize();
        let m = n.cross(&t);
        let lame = Lame::from(MATERIAL);
        let mu = lame.mu;
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
        Front {
            c,
            n,
            t,
            m,
            b: local.map(|v| r * v),
        }
    }

    fn patch(&self) -> PlanarPatch {
        let l = 3.0;
        PlanarPatch {
            origin: self.c - self.t * l - self.m * l,
            u: self.t * (2.0 * l),
            v: self.m * l,
        }
    }

    fn level_sets(&self, x: &Point3<f64>) -> (f64, f64) {
        (self.n.dot(&(x - self.c)), self.m.dot(&(x - self.c)))
    }

    /// Exact displacement and gradient at x seen from `side` (0: from φ's sign).
    fn exact(&self, x: &Point3<f64>, side: i8) -> (Vector3<f64>, Matrix3<f64>) {
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
}

fn stress(gu: &Matrix3<f64>) -> Matrix3<f64> {
    let lame = Lame::from(MATERIAL);
    let eps = (gu + gu.transpose()) * 0.5;
    Matrix3::identity() * (lame.lambda * eps.trace()) + eps * (2.0 * lame.mu)
}

#[test]
fn the_williams_field_is_in_equilibrium_with_free_cut_faces() {
    let fr = Front::new();
    let h = 1e-5;
    // div σ = 0 at points around the front (central differences of the exact gradient).
    for x in [
        Point3::new(0.6, 0.55, 0.3),
        Point3::new(0.4, 0.52, 0.7),
        Point3::new(0.3, 0.4, 0.5),
        Point3::new(0.55, 0.45, 0.1),
    ] {
        let mut div = Vector3::zeros();
        let mut scale: f64 = 0.0;
        for j in 0..3 {
            let mut e = Vector3::zeros();
            e[j] = h;
            let sp = stress(&fr.exact(&(x + e), 0).1);
            let sm = stress(&fr.exact(&(x - e), 0).1);
            scale = scale.max(sp.norm());
            div += (sp.column(j) - sm.column(j)) / (2.0 * h);
        }
        println!("div σ at {x:?}: {:.2e} (σ ~ {scale:.2e})", div.norm());
        assert!(div.norm() < 1e-5 * scale, "div σ = {div:?} at {x:?}");
    }
    // Traction σ n = 0 on both cut faces behind the front; not zero ahead.
    for a in [0.1, 0.25, 0.4] {
        let x = fr.c - fr.m * a + fr.t * 0.05;
        for side in [1, -1] {
            let s = stress(&fr.exact(&x, side).1);
            let tr = s * fr.n;
            println!(
                "traction on side {side} at ψ = −{a}: {:.2e} (σ ~ {:.2e})",
                tr.norm(),
                s.norm()
            );
            assert!(tr.norm() < 1e-12 * s.norm());
        }
        let ahead = stress(&fr.exact(&(fr.c + fr.m * a), 0).1) * fr.n;
        assert!(ahead.norm() > 1e-2);
    }
}

/// A structured box mesh of [0,1]³, interior nodes jittered by up to `jitter` h.
fn mesh(div: usize, kind: ElementKind, jitter: f64) -> TetMesh {
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
        let inner = (0..3).all(|c| p[c] > 1e-12 && p[c] < 1.0 - 1e-12);
        let d = Vector3::new(rnd(), rnd(), rnd()) * (jitter * h);
        if inner {
            *p += d;
        }
    }
    match kind {
        ElementKind::Tet4 => m,
        ElementKind::Tet10 => m.to_tet10(),
    }
}

/// Prescribed values on every boundary node: standard DOFs the exact nodal
/// value, Heaviside DOFs the jump to the other side's continuation
/// (u_other = −u_i, every branch function changes sign under θ → θ − 2π),
/// tip DOFs the Williams coefficients b_k.
fn boundary_values(fr: &Front, mesh: &TetMesh, cut: &CutSetup) -> Vec<(usize, [Option<f64>; 3])> {
    let n_nodes = mesh.n_nodes();
    let mut fixed = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        let on_boundary = (0..3).any(|c| p[c].abs() < 1e-12 || (p[c] - 1.0).abs() < 1e-12);
        if !on_boundary {
            continue;
        }
        let side = cut.node_side[i];
        let u = fr.exact(p, side).0;
        fixed.push((i, [Some(u.x), Some(u.y), Some(u.z)]));
        if let Some(j) = cut.enriched[i] {
            let a = u * (2.0 * f64::from(side));
            fixed.push((n_nodes + j, [Some(a.x), Some(a.y), Some(a.z)]));
        }
        if let Some(t) = cut.tip[i] {
            for k in 0..N_BRANCH {
                let b = fr.b[k];
                fixed.push((
                    n_nodes + cut.n_enriched + N_BRANCH * t + k,
                    [Some(b.x), Some(b.y), Some(b.z)],
                ));
            }
        }
    }
    fixed
}

struct Run {
    dofs: usize,
    n_tip: usize,
    n_heaviside: usize,
    l2: f64,
    energy: f64,
}

fn solve(div: usize, kind: ElementKind, jitter: f64, front: FrontMode, radius: Option<f64>) -> Run {
    let fr = Front::new();
    let mesh = mesh(div, kind, jitter);
    let patch = fr.patch();
    let cut = setup_cut(
        &mesh,
        &[CutInput {
            surface: &patch,
            snap: 1e-4,
            front,
            tip_radius: radius,
        }],
    )
    .unwrap();
    let fixed = boundary_values(&fr, &mesh, &cut);
    let (n_tip, n_heaviside) = (cut.n_tip(), cut.n_heaviside());
    let model = Model::build(ModelInput {
        mesh,
        material: MATERIAL,
        formulation: Formulation::Linear,
        cut: Some(cut),
        fixed,
        gravity: None,
        body_force: None,
        tractions: &[],
        need_mass: false,
    })
    .unwrap();
    let mut chol = Cholesky::new(&model.pattern).unwrap();
    let sol = solve_static(&model, &mut chol, &StaticOptions::default()).unwrap();
    let lame = Lame::from(MATERIAL);
    let energy_density = |g: &Matrix3<f64>| {
        let eps = (g + g.transpose()) * 0.5;
        lame.mu * eps.norm_squared() + 0.5 * lame.lambda * eps.trace().powi(2)
    };
    let (mut e2, mut u2, mut ee, mut ue) = (0.0, 0.0, 0.0, 0.0);
    for e in 0..model.mesh.n_elements() {
        for (x, w, side) in model.field_points(e) {
            let (uh, gh) = model.field_at(&sol.d, e, &x, side);
            let (u, g) = fr.exact(&x, side);
            e2 += w * (uh - u).norm_squared();
            u2 += w * u.norm_squared();
            ee += w * energy_density(&(gh - g));
            ue += w * energy_density(&g);
        }
    }
    Run {
        dofs: model.n_free,
        n_tip,
        n_heaviside,
        l2: (e2 / u2).sqrt(),
        energy: (ee / ue).sqrt(),
    }
}

fn study(
    name: &str,
    divs: &[usize],
    kind: ElementKind,
    jitter: f64,
    front: FrontMode,
    radius: Option<f64>,
) -> (f64, f64, Vec<Run>) {
    let runs: Vec<Run> = divs
        .iter()
        .map(|&n| solve(n, kind, jitter, front, radius))
        .collect();
    for (n, r) in divs.iter().zip(&runs) {
        println!(
            "{name} n {n:3} free DOFs {:7} tip {:5} heaviside {:5}: L2 {:.3e} energy {:.3e}",
            r.dofs, r.n_tip, r.n_heaviside, r.l2, r.energy
        );
    }
    let k = divs.len() - 1;
    let ratio = (divs[k] as f64 / divs[k - 1] as f64).ln();
    let l2 = (runs[k - 1].l2 / runs[k].l2).ln() / ratio;
    let en = (runs[k - 1].energy / runs[k].energy).ln() / ratio;
    println!("{name}: last orders L2 {l2:.2} energy {en:.2}");
    (l2, en, runs)
}

#[test]
fn geometric_tip_enrichment_converges_at_the_optimal_rate_tet4() {
    let (l2, en, _) = study(
        "tet4 structured geometric R=0.2",
        &[8, 12, 16, 24],
        ElementKind::Tet4,
        0.0,
        FrontMode::Tip,
        Some(0.2),
    );
    assert!(l2 >= 1.8, "L2 order {l2}");
    assert!(en >= 0.85, "energy order {en}");
}

#[test]
fn the_exact_field_is_in_the_tip_enriched_space() {
    // With every node tip-enriched, u_i = u(x_i) and b_ik = b_k give
    // u_h = Σ N_i u_i + Σ N_i Σ_k (F_k − F_k(x_i)) b_k = Σ_k b_k F_k exactly
    // (partition of unity): values and gradients at every integration point,
    // on both sides of the cut, in front, cut, crossed-ahead and plain elements.
    let fr = Front::new();
    for kind in [ElementKind::Tet4, ElementKind::Tet10] {
        for jitter in [0.0, 0.2] {
            let mesh = mesh(3, kind, jitter);
            let patch = fr.patch();
            let cut = setup_cut(&mesh, &[CutInput::tip(&patch, 1e-4, Some(10.0))]).unwrap();
            assert_eq!(cut.n_tip(), mesh.n_nodes());
            assert!(cut.n_partial() > 0, "the front passes inside elements");
            let n_nodes = mesh.n_nodes();
            let mut d = vec![0.0; 3 * (n_nodes + cut.n_enriched + N_BRANCH * cut.n_tip)];
            for (i, p) in mesh.nodes.iter().enumerate() {
                let u = fr.exact(p, cut.node_side[i]).0;
                d[3 * i..3 * i + 3].copy_from_slice(u.as_slice());
                let t = cut.tip[i].unwrap();
                for k in 0..N_BRANCH {
                    let s = n_nodes + cut.n_enriched + N_BRANCH * t + k;
                    d[3 * s..3 * s + 3].copy_from_slice(fr.b[k].as_slice());
                }
            }
            let model = Model::build(ModelInput {
                mesh,
                material: MATERIAL,
                formulation: Formulation::Linear,
                cut: Some(cut),
                fixed: vec![],
                gravity: None,
                body_force: None,
                tractions: &[],
                need_mass: false,
            })
            .unwrap();
            let (mut worst_u, mut worst_g, mut points) = (0.0f64, 0.0f64, 0);
            for e in 0..model.mesh.n_elements() {
                for (x, _, side) in model.field_points(e) {
                    let (uh, gh) = model.field_at(&d, e, &x, side);
                    let (u, g) = fr.exact(&x, side);
                    worst_u = worst_u.max((uh - u).norm() / u.norm().max(1e-3));
                    worst_g = worst_g.max((gh - g).norm() / g.norm());
                    points += 1;
                }
            }
            println!("{kind:?} jitter {jitter}: {points} points, worst relative value error {worst_u:.1e}, gradient {worst_g:.1e}");
            assert!(
                worst_u < 1e-10 && worst_g < 1e-10,
                "{kind:?}: {worst_u} {worst_g}"
            );
        }
    }
}

/// log-log interpolation of the runs' errors at `dofs` (the runs sorted by DOFs).
fn at_dofs(runs: &[Run], dofs: f64, err: impl Fn(&Run) -> f64) -> f64 {
    let k = runs
        .windows(2)
        .position(|w| (w[1].dofs as f64) >= dofs)
        .unwrap_or(runs.len() - 2);
    let (a, b) = (&runs[k], &runs[k + 1]);
    let t = (dofs.ln() - (a.dofs as f64).ln()) / ((b.dofs as f64).ln() - (a.dofs as f64).ln());
    (err(a).ln() + t * (err(b).ln() - err(a).ln())).exp()
}

#[test]
fn tet10_beats_tet4_at_equal_dofs_and_topological_and_extend_trail() {
    let (_, _, t4) = study(
        "tet4 geometric R=0.2",
        &[6, 8, 12, 16],
        ElementKind::Tet4,
        0.0,
        FrontMode::Tip,
        Some(0.2),
    );
    let (_, _, t10) = study(
        "tet10 geometric R=0.2",
        &[3, 4, 6],
        ElementKind::Tet10,
        0.0,
        FrontMode::Tip,
        Some(0.2),
    );
    for r in &t10[1..] {
        let l2_4 = at_dofs(&t4, r.dofs as f64, |r| r.l2);
        let en_4 = at_dofs(&t4, r.dofs as f64, |r| r.energy);
        println!(
            "at {} DOFs: tet10 L2 {:.3e} vs tet4 {:.3e}; energy {:.3e} vs {:.3e}",
            r.dofs, r.l2, l2_4, r.energy, en_4
        );
        assert!(r.l2 < l2_4 && r.energy < en_4);
    }
    study(
        "tet4 jittered geometric R=0.2",
        &[6, 8, 12, 16],
        ElementKind::Tet4,
        0.2,
        FrontMode::Tip,
        Some(0.2),
    );
    let (l2_topo, _, _) = study(
        "tet4 topological",
        &[6, 8, 12, 16],
        ElementKind::Tet4,
        0.0,
        FrontMode::Tip,
        None,
    );
    let (l2_ext, _, ext) = study(
        "tet4 extend",
        &[6, 8, 12, 16],
        ElementKind::Tet4,
        0.0,
        FrontMode::Extend,
        None,
    );
    // Without geometric enrichment the rate drops (about 1 and below in L2, issue 11).
    assert!(l2_topo < 1.8 && l2_ext < 1.8, "{l2_topo} {l2_ext}");
    assert!(ext.last().unwrap().l2 > t4.last().unwrap().l2);
}

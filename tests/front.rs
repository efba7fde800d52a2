//! A crack front inside elements (issue 11): the exact Williams mode I+II+III
//! field around a straight front that crosses a box obliquely, imposed on the
//! whole outer boundary, and the X-FEM solution's L2 and energy errors under
//! refinement for geometric tip, topological tip and extended cuts.

mod common;

use nalgebra::{Matrix3, Point3, Vector3};
use xfem_cut::cut::{setup_cut, Blending, CutInput, CutSetup, FrontMode, PlanarPatch};
use xfem_cut::front::N_BRANCH;
use xfem_cut::material::Lame;
use xfem_cut::mesh::{ElementKind, TetMesh};
use xfem_cut::model::{Formulation, Model, ModelInput};
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};

use xfem_cut::study::exact::{mid_edges, unit_box as mesh, WilliamsFront as Front, MATERIAL};

fn stress(gu: &Matrix3<f64>) -> Matrix3<f64> {
    xfem_cut::study::exact::stress(gu, &Lame::from(MATERIAL))
}

fn standard_value(
    fr: &Front,
    mesh: &TetMesh,
    cut: &CutSetup,
    edges: &[Option<(usize, usize)>],
    i: usize,
) -> Vector3<f64> {
    fr.standard_value(mesh, cut, edges, i)
}

fn boundary_values(fr: &Front, mesh: &TetMesh, cut: &CutSetup) -> Vec<(usize, [Option<f64>; 3])> {
    fr.boundary_values(mesh, cut)
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

struct Run {
    dofs: usize,
    n_tip: usize,
    n_heaviside: usize,
    l2: f64,
    energy: f64,
}

fn solve_blended(
    div: usize,
    kind: ElementKind,
    jitter: f64,
    front: FrontMode,
    radius: Option<f64>,
    blending: Blending,
) -> (Run, Model, Vec<f64>) {
    solve_about(&Front::new(), div, kind, jitter, front, radius, blending)
}

/// The model of the exact field about `fr` on `mesh` (its values on the
/// boundary), the front treated by `front`, `radius` and `blending`.
fn exact_model(
    fr: &Front,
    mesh: &TetMesh,
    front: FrontMode,
    radius: Option<f64>,
    blending: Blending,
    need_mass: bool,
) -> Model {
    let patch = fr.patch();
    let cut = setup_cut(
        mesh,
        &[CutInput {
            surface: &patch,
            snap: 1e-4,
            front,
            tip_radius: radius,
            blending,
        }],
    )
    .unwrap();
    let fixed = boundary_values(fr, mesh, &cut);
    Model::build(ModelInput {
        mesh: mesh.clone(),
        material: MATERIAL,
        formulation: Formulation::Linear,
        cut: Some(cut),
        fixed,
        gravity: None,
        body_force: None,
        tractions: &[],
        need_mass,
    })
    .unwrap()
}

fn solve_about(
    fr: &Front,
    div: usize,
    kind: ElementKind,
    jitter: f64,
    front: FrontMode,
    radius: Option<f64>,
    blending: Blending,
) -> (Run, Model, Vec<f64>) {
    let mesh = mesh(div, kind, jitter);
    let model = exact_model(fr, &mesh, front, radius, blending, false);
    let cut = model.cut.as_ref().unwrap();
    let (n_tip, n_heaviside) = (cut.n_tip(), cut.n_heaviside());
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
    let run = Run {
        dofs: model.n_free,
        n_tip,
        n_heaviside,
        l2: (e2 / u2).sqrt(),
        energy: (ee / ue).sqrt(),
    };
    (run, model, sol.d)
}

fn study(
    name: &str,
    divs: &[usize],
    kind: ElementKind,
    jitter: f64,
    front: FrontMode,
    radius: Option<f64>,
) -> (f64, f64, Vec<Run>) {
    study_blended(name, divs, kind, jitter, front, radius, Blending::None)
}

fn study_blended(
    name: &str,
    divs: &[usize],
    kind: ElementKind,
    jitter: f64,
    front: FrontMode,
    radius: Option<f64>,
    blending: Blending,
) -> (f64, f64, Vec<Run>) {
    let runs: Vec<Run> = divs
        .iter()
        .map(|&n| solve_blended(n, kind, jitter, front, radius, blending).0)
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
    // With every vertex tip-enriched, b_vk = b_k and standard values with
    // Σ N_i u_i = Σ λ_v u(x_v) give u_h = Σ λ_v u_v + Σ λ_v Σ_k (F_k − F_k(x_v)) b_k
    // = Σ_k b_k F_k exactly (partition of unity): values and gradients at every integration point,
    // on both sides of the cut, in front, cut, crossed-ahead and plain elements.
    let fr = Front::new();
    for kind in [ElementKind::Tet4, ElementKind::Tet10] {
        for jitter in [0.0, 0.2] {
            let mesh = mesh(3, kind, jitter);
            let patch = fr.patch();
            let cut = setup_cut(&mesh, &[CutInput::tip(&patch, 1e-4, Some(10.0))]).unwrap();
            assert_eq!(
                cut.n_tip(),
                mesh.cells
                    .chunks(kind.nodes())
                    .flat_map(|c| c[..4].to_vec())
                    .collect::<std::collections::HashSet<_>>()
                    .len()
            );
            assert!(cut.n_partial() > 0, "the front passes inside elements");
            let n_nodes = mesh.n_nodes();
            let edges = mid_edges(&mesh);
            let mut d = vec![0.0; 3 * (n_nodes + cut.n_enriched + N_BRANCH * cut.n_tip)];
            for i in 0..n_nodes {
                let u = standard_value(&fr, &mesh, &cut, &edges, i);
                d[3 * i..3 * i + 3].copy_from_slice(u.as_slice());
                if let Some(t) = cut.tip[i] {
                    for k in 0..N_BRANCH {
                        let s = n_nodes + cut.n_enriched + N_BRANCH * t + k;
                        let b = fr.b[k] / cut.tip_scale[t];
                        d[3 * s..3 * s + 3].copy_from_slice(b.as_slice());
                    }
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
            // Node displacements (VTU output) seen from both sides: the exact
            // field at the node, Tet10 mid-nodes next to tip vertices included.
            let mut worst_node: f64 = 0.0;
            let c = model.cut.as_ref().unwrap();
            for (i, p) in model.mesh.nodes.iter().enumerate() {
                let own = c.node_side[i];
                let u = fr.exact(p, own).0;
                worst_node = worst_node
                    .max((model.node_displacement(&d, i, own) - u).norm() / u.norm().max(1e-3));
                worst_node = worst_node
                    .max((model.node_displacement(&d, i, 0) - u).norm() / u.norm().max(1e-3));
            }
            println!("    node displacements: worst relative error {worst_node:.1e}");
            assert!(worst_node < 1e-10, "{kind:?}: nodes {worst_node}");
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
fn tet10_tet4_topological_and_extend_side_by_side() {
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
    // Tet10 is more accurate than Tet4 at equal DOFs (measured: 4.3× in L2,
    // 4.7× in energy at 4914 DOFs), and its error falls. (Until the boundary
    // values of Heaviside mid-nodes between tip vertices were right, Tet10
    // was the worse of the two: those DOFs were imposed as if the tip
    // functions did not jump there too.)
    for r in &t10[1..] {
        let l2_4 = at_dofs(&t4, r.dofs as f64, |r| r.l2);
        let en_4 = at_dofs(&t4, r.dofs as f64, |r| r.energy);
        println!(
            "at {} DOFs: tet10 L2 {:.3e} vs tet4 {:.3e}; energy {:.3e} vs {:.3e}",
            r.dofs, r.l2, l2_4, r.energy, en_4
        );
        assert!(r.l2 < l2_4 && r.energy < en_4, "at {} DOFs", r.dofs);
    }
    assert!(t10
        .windows(2)
        .all(|w| w[1].l2 < w[0].l2 && w[1].energy < w[0].energy));
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

#[test]
fn the_cut_ends_at_the_front_inside_elements() {
    // The front line lies inside elements (front elements exist); the
    // opening u(φ=+0) − u(φ=−0) along the plane: zero on the front and
    // ahead of it, the exact √r opening behind it.
    // Tet4 also with the ramp (what a case takes where R spans 2.5 median
    // edges): behind the front in cut blending elements the jump comes from
    // the tip functions and the ramped Heaviside enrichment together.
    for (kind, blending) in [
        (ElementKind::Tet4, Blending::None),
        (ElementKind::Tet4, Blending::Ramp),
        (ElementKind::Tet10, Blending::None),
    ] {
        println!("{kind:?} {blending:?}");
        cut_ends_at_the_front(kind, blending);
    }
}

fn cut_ends_at_the_front(kind: ElementKind, blending: Blending) {
    use xfem_cut::locate::Locator;
    let fr = Front::new();
    let n = if kind == ElementKind::Tet4 { 8 } else { 4 };
    let (_, model, d) = solve_blended(n, kind, 0.0, FrontMode::Tip, Some(0.2), blending);
    let ramped = model.cut.as_ref().unwrap().ramp.iter().any(|&r| r);
    assert_eq!(ramped, blending == Blending::Ramp);
    assert!(model.cut.as_ref().unwrap().n_partial() > 0);
    let locator = Locator::new(&model.mesh);
    let h = 1.0 / n as f64;
    let opening = |x: &Point3<f64>| {
        let (e, _) = locator.locate(&model.mesh, x).expect("inside");
        model.field_at(&d, e, x, 1).0 - model.field_at(&d, e, x, -1).0
    };
    let mut largest: f64 = 0.0;
    for a in [0.3, 0.6, 1.0, 2.0] {
        let x = fr.c - fr.m * (a * h) + fr.t * 0.05;
        let exact = fr.exact(&x, 1).0 - fr.exact(&x, -1).0;
        let o = opening(&x);
        largest = largest.max(o.norm());
        println!(
            "behind by {a} h: opening {:.4e}, exact {:.4e}",
            o.norm(),
            exact.norm()
        );
        assert!((o - exact).norm() < 0.1 * exact.norm());
    }
    for s in [-0.3, 0.0, 0.2, 0.4] {
        for a in [0.0, 0.3, 1.0] {
            let x = fr.c + fr.m * (a * h) + fr.t * s;
            let o = opening(&x).norm();
            println!("ahead by {a} h at s = {s}: opening {o:.2e}");
            // On the front (within model::FRONT_SNAP h, the interpolated level
            // sets' round-off) the tip functions vanish; ahead, F₁ = 0.
            assert!(o <= 1e-10 * largest, "opening {o:e} at {a} h ahead");
        }
    }
}

/// The exact corotational tangent with tip DOFs against the whole Jacobian of
/// the forces by central differences: the sides of tip elements are dense
/// groups (one rotation for many points) whose forces are the gradient of
/// their energy, so the Jacobian is symmetric and equals the tangent.
#[test]
fn corotational_exact_tangent_with_tip_dofs_matches_central_differences() {
    // Tet4 also with the ramp of corrected X-FEM (what a case takes where
    // `tip_radius` spans 2.5 median edges): the ring's tip blocks too.
    let fr = Front::new();
    let patch = fr.patch();
    for (kind, blending) in [
        (ElementKind::Tet4, Blending::None),
        (ElementKind::Tet4, Blending::Ramp),
        (ElementKind::Tet10, Blending::None),
    ] {
        let mesh = mesh(3, kind, 0.2);
        let input = CutInput {
            blending,
            ..CutInput::tip(&patch, 1e-4, Some(0.3))
        };
        let cut = setup_cut(&mesh, &[input]).unwrap();
        assert!(cut.n_tip() > 0 && cut.n_heaviside() > 0);
        assert_eq!(cut.ramp.iter().any(|&r| r), blending == Blending::Ramp);
        let fixed: Vec<_> = (0..mesh.n_nodes())
            .filter(|&i| mesh.nodes[i].z == 0.0)
            .map(|i| (i, [Some(0.0); 3]))
            .collect();
        let model = Model::build(ModelInput {
            mesh,
            material: MATERIAL,
            formulation: Formulation::Corotational,
            cut: Some(cut),
            fixed,
            gravity: None,
            body_force: None,
            tractions: &[],
            need_mass: false,
        })
        .unwrap();
        let d = common::rotated_state(&model);
        let (rel, antisymmetric) = common::tangent_against_central_differences(&model, &d);
        let dense = model.groups.iter().filter(|g| g.is_dense()).count();
        println!(
            "{kind:?} {blending:?}: {} groups ({dense} dense), tangent vs J of central differences \
             {rel:.2e}; antisymmetric part of J {antisymmetric:.2e}",
            model.groups.len()
        );
        assert!(
            dense > 0,
            "{kind:?}: the tip elements' sides are dense groups"
        );
        assert!(rel <= 1e-6, "{kind:?}: {rel:e}");
    }
}

#[test]
fn dofs_added_per_front_length_against_tip_radius() {
    // The front's length inside the unit box, from the line's parameter range.
    let fr = Front::new();
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for c in 0..3 {
        let (a, b) = ((0.0 - fr.c[c]) / fr.t[c], (1.0 - fr.c[c]) / fr.t[c]);
        if fr.t[c].abs() > 1e-12 {
            lo = lo.max(a.min(b));
            hi = hi.min(a.max(b));
        }
    }
    let length = hi - lo;
    let patch = fr.patch();
    let mut previous = 0;
    for n in [8, 16] {
        let mesh = mesh(n, ElementKind::Tet4, 0.0);
        for radius in [None, Some(0.05), Some(0.1), Some(0.2)] {
            let t0 = std::time::Instant::now();
            let cut = setup_cut(&mesh, &[CutInput::tip(&patch, 1e-4, radius)]).unwrap();
            let dt = t0.elapsed().as_secs_f64();
            let added = 3 * cut.n_heaviside() + 12 * cut.n_tip();
            println!(
                "h 1/{n} tip_radius {radius:?}: {} tip, {} Heaviside nodes, {:.0} DOFs added per unit front length (front {length:.3}); set-up {:.1} ms",
                cut.n_tip(),
                cut.n_heaviside(),
                added as f64 / length,
                dt * 1e3
            );
            let t1 = std::time::Instant::now();
            let model = Model::build(ModelInput {
                mesh: mesh.clone(),
                material: MATERIAL,
                formulation: Formulation::Linear,
                cut: Some(cut.clone()),
                fixed: vec![(0, [Some(0.0); 3])],
                gravity: None,
                body_force: None,
                tractions: &[],
                need_mass: false,
            })
            .unwrap();
            println!(
                "    precompute (Model::build) {:.1} ms, {} groups (rough wall clock, shared machine)",
                t1.elapsed().as_secs_f64() * 1e3,
                model.groups.len()
            );
            if radius.is_some() {
                assert!(cut.n_tip() >= previous);
            }
            previous = cut.n_tip();
        }
        previous = 0;
    }
}

/// The patch test with tip-enriched nodes: uniaxial stress along the front
/// direction t (σ n = 0 on the cut faces), so the linear field is the exact
/// solution with the cut. Extended cuts reproduce it to round-off. With tip
/// nodes it holds to quadrature accuracy: the residual of the exact state on
/// the tip rows, ∫∇(Nᵢ(F − F(xᵢ))) : σ, vanishes exactly (divergence theorem,
/// σ n = 0 on the cut), but its integrand is near-singular (∇F ~ r^(-1/2)) in
/// the cells the front passes close to. Relative to the largest force of that
/// state, on this jittered h = 1/4 mesh (Tet4 topological): 6.3e-4 with the
/// plain degree-5 rule in every cell not touching the front; 4.9e-5 with one
/// red refinement of the near cells (what the model does,
/// [`xfem_cut::front::near_front_rule`]); 3.4e-5 refining twice at a quarter;
/// 1.2e-6 refining three times at gap < size with 6³ collapsed rules on the
/// front cells (17× the points). The solution's error follows the residual
/// (displacement 0.5×, energy norm 1.6× it, at every rule tried), so the test
/// asserts both: the rule's residual, and an error no larger than a small
/// multiple of it (a modelling error would not shrink with the rule).
/// Those figures took each cell's vertices in the element's listing order.
/// In its canonical order (ascending nodes, what the model does since the
/// listing must not matter, tests/listing.rs) the same rules give, Tet4
/// topological, residual / displacement / energy-norm error: 2.7e-5 /
/// 3.8e-5 / 9.5e-5 (the model's rule), 1.1e-5 / 1.9e-5 / 5.9e-5 (refined
/// twice), 1.2e-6 / 8.1e-7 / 2.1e-6 (three times, 6³): the errors still
/// fall with the residual, at 0.7–5.4 times it, so the multiple is 6. The
/// model's rule later gave 4.7e-5 / 3.8e-5 / 9.5e-5; with cells at 1e-3 …
/// 0.1 of their size from the front in polar coordinates
/// (`front::polar_rule`) 2.8e-5 / 1.9e-5 / 6.4e-5 (Tet10 with R = 0.2:
/// 1.2e-4 / 4.1e-5 / 1.4e-4 → 1.2e-4 / 2.3e-5 / 6.9e-5); Tet4 with R = 0.2
/// and the ramp (what a case takes from R = 2.5 median edges on): 2.5e-5 /
/// 3.5e-5 / 7.9e-5. The
/// strain is compared in the energy norm: a tip DOF's strain grows like
/// r^(-1/2) at the front, so a pointwise bound would measure how close the
/// rule's points come to it.
#[test]
fn patch_test_with_tip_nodes_present() {
    let fr = Front::new();
    let patch = fr.patch();
    let lame = Lame::from(MATERIAL);
    let s = 1e-2;
    let nu = MATERIAL.poisson;
    let eps =
        (fr.t * fr.t.transpose() * (1.0 + nu) - Matrix3::identity() * nu) * (s / MATERIAL.young);
    let sigma = Matrix3::identity() * (lame.lambda * eps.trace()) + eps * (2.0 * lame.mu);
    assert!((sigma * fr.n).norm() < 1e-15);
    let offset = Vector3::new(1e-3, -2e-3, 5e-4);
    let exact = |x: &Point3<f64>| eps * x.coords + offset;
    let mut failures = Vec::new();
    for (name, kind, input, bound) in [
        (
            "Tet4 extend",
            ElementKind::Tet4,
            CutInput::extend(&patch, 1e-4),
            1e-12,
        ),
        (
            "Tet4 topological",
            ElementKind::Tet4,
            CutInput::tip(&patch, 1e-4, None),
            1e-2,
        ),
        (
            "Tet4 R = 0.2",
            ElementKind::Tet4,
            CutInput::tip(&patch, 1e-4, Some(0.2)),
            1e-2,
        ),
        (
            "Tet4 R = 0.2 ramp",
            ElementKind::Tet4,
            CutInput {
                blending: Blending::Ramp,
                ..CutInput::tip(&patch, 1e-4, Some(0.2))
            },
            1e-2,
        ),
        (
            "Tet10 R = 0.2",
            ElementKind::Tet10,
            CutInput::tip(&patch, 1e-4, Some(0.2)),
            1e-2,
        ),
        (
            "Tet10 R = 0.2 ramp",
            ElementKind::Tet10,
            CutInput {
                blending: Blending::Ramp,
                ..CutInput::tip(&patch, 1e-4, Some(0.2))
            },
            1e-2,
        ),
    ] {
        let mesh = mesh(4, kind, 0.2);
        let cut = setup_cut(&mesh, &[input]).unwrap();
        let n_nodes = mesh.n_nodes();
        let mut fixed = Vec::new();
        for (i, p) in mesh.nodes.iter().enumerate() {
            if (0..3).any(|c| p[c].abs() < 1e-12 || (p[c] - 1.0).abs() < 1e-12) {
                let u = exact(p);
                fixed.push((i, [Some(u.x), Some(u.y), Some(u.z)]));
                if let Some(j) = cut.enriched[i] {
                    fixed.push((n_nodes + j, [Some(0.0); 3]));
                }
                if let Some(t) = cut.tip[i] {
                    for k in 0..N_BRANCH {
                        fixed.push((n_nodes + cut.n_enriched + N_BRANCH * t + k, [Some(0.0); 3]));
                    }
                }
            }
        }
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
        // The residual of the exact state (standard DOFs linear, enriched 0),
        // relative to the largest internal force of the same state.
        let residual = {
            use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
            let mut d = vec![0.0; model.n_dofs()];
            for (i, p) in model.mesh.nodes.iter().enumerate() {
                d[3 * i..3 * i + 3].copy_from_slice(exact(p).as_slice());
            }
            let mut f = vec![0.0; model.n_dofs()];
            evaluate(
                &model,
                &d,
                &mut Rotations::identity(&model),
                &mut Workspace::new(&model),
                Request {
                    forces: Some(&mut f),
                    tangent: None,
                    update_rotations: false,
                    exact_tangent: false,
                },
            );
            let scale = f.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            let free = model.equation.iter().enumerate();
            let worst = free
                .filter(|(_, &eq)| eq != xfem_cut::model::NONE)
                .fold(0.0f64, |a, (dof, _)| a.max(f[dof].abs()));
            worst / scale
        };
        let u_scale = (eps * Vector3::new(1.0, 1.0, 1.0)).norm() + offset.norm();
        let (mut u_err, mut e_err, mut e_ref) = (0.0f64, 0.0f64, 0.0f64);
        for e in 0..model.mesh.n_elements() {
            for (x, w, side) in model.field_points(e) {
                let (u, g) = model.field_at(&sol.d, e, &x, side);
                u_err = u_err.max((u - exact(&x)).norm() / u_scale);
                e_err += w * (g - eps).norm_squared();
                e_ref += w * eps.norm_squared();
            }
        }
        let e_err = (e_err / e_ref).sqrt();
        let enriched: f64 = sol.d[3 * n_nodes..]
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()))
            / u_scale;
        println!("{name}: {n_tip} tip, {n_heaviside} Heaviside nodes; residual of the exact state {residual:.1e}; displacement error {u_err:.1e}, energy-norm error {e_err:.1e}, largest enriched DOF {enriched:.1e} (relative)");
        let response = 6.0 * residual.max(1e-13);
        if !(residual <= bound && u_err <= response && e_err <= response) {
            failures.push(format!(
                "{name}: residual {residual:e}, errors {u_err:e} {e_err:e}"
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

#[test]
fn two_fronts_in_one_element_are_refused_naming_both() {
    let fr = Front::new();
    let a = fr.patch();
    // A second cut parallel to the first, 0.05 above it: its front lies in
    // the same elements at h = 1/4.
    let b = PlanarPatch {
        origin: a.origin + fr.n * 0.05,
        ..a.clone()
    };
    let mesh = mesh(4, ElementKind::Tet4, 0.0);
    let err = setup_cut(
        &mesh,
        &[CutInput::tip(&a, 1e-4, None), CutInput::tip(&b, 1e-4, None)],
    )
    .expect_err("refused");
    let text = err.to_string();
    println!("{text}");
    assert!(text.contains("cut[0]") && text.contains("cut[1]"), "{text}");
}

/// A tip element's sides as dense groups (the default) against one point
/// group per quadrature point ([`Integration::SubTetQuadrature`]): the same
/// linear tangent, forces and energy to round-off (the dense stiffness is
/// the points' sum), and corotational static solutions that differ only by
/// the spread of the rotations over a side, with the same Newton iterations.
#[test]
fn dense_tip_groups_are_their_points_summed() {
    use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};
    use xfem_cut::model::Integration;
    let fr = Front::new();
    let patch = fr.patch();
    for kind in [ElementKind::Tet4, ElementKind::Tet10] {
        let mesh = mesh(3, kind, 0.2);
        let cut = setup_cut(&mesh, &[CutInput::tip(&patch, 1e-4, Some(0.3))]).unwrap();
        let fixed: Vec<_> = (0..mesh.n_nodes())
            .filter(|&i| mesh.nodes[i].z == 0.0)
            .map(|i| (i, [Some(0.0); 3]))
            .collect();
        let build = |formulation, integration| {
            Model::build_with(
                ModelInput {
                    mesh: mesh.clone(),
                    material: MATERIAL,
                    formulation,
                    cut: Some(cut.clone()),
                    fixed: fixed.clone(),
                    gravity: Some(Vector3::new(0.3, 0.1, 0.0) * GRAVITY_SCALE),
                    body_force: None,
                    tractions: &[],
                    need_mass: false,
                },
                integration,
            )
            .unwrap()
        };
        let pass = |model: &Model, d: &[f64]| {
            let mut f = vec![0.0; model.n_dofs()];
            let mut k = vec![0.0; model.pattern.nnz()];
            let energy = evaluate(
                model,
                d,
                &mut Rotations::identity(model),
                &mut Workspace::new(model),
                Request {
                    forces: Some(&mut f),
                    tangent: Some(&mut k),
                    update_rotations: true,
                    exact_tangent: true,
                },
            );
            (f, k, energy)
        };
        let rel = |a: &[f64], b: &[f64]| {
            let diff: f64 = a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum();
            let norm: f64 = b.iter().map(|y| y * y).sum();
            (diff / norm).sqrt()
        };
        let (dense, points) = (
            build(Formulation::Linear, Integration::Grouped),
            build(Formulation::Linear, Integration::SubTetQuadrature),
        );
        assert_eq!(dense.pattern.nnz(), points.pattern.nnz());
        let n_dense = dense.groups.iter().filter(|g| g.is_dense()).count();
        assert!(n_dense > 0 && points.groups.iter().all(|g| !g.is_dense()));
        let d: Vec<f64> = (0..dense.n_dofs())
            .map(|k| 0.01 * ((k as f64) * 0.37).sin())
            .collect();
        let ((fa, ka, ea), (fb, kb, eb)) = (pass(&dense, &d), pass(&points, &d));
        let (rf, rk, re) = (rel(&fa, &fb), rel(&ka, &kb), ((ea - eb) / eb).abs());
        println!(
            "{kind:?} linear: {} groups ({n_dense} dense) vs {} point groups: \
             forces {rf:.1e}, tangent {rk:.1e}, energy {re:.1e}",
            dense.groups.len(),
            points.groups.len()
        );
        assert!(rf <= 1e-12 && rk <= 1e-12 && re <= 1e-12, "{kind:?}");

        let solve = |model: &Model| {
            let mut chol = Cholesky::new(&model.pattern).unwrap();
            let opts = StaticOptions {
                load_steps: 4,
                ..StaticOptions::default()
            };
            solve_static(model, &mut chol, &opts).unwrap()
        };
        let (a, b) = (
            solve(&build(Formulation::Corotational, Integration::Grouped)),
            solve(&build(
                Formulation::Corotational,
                Integration::SubTetQuadrature,
            )),
        );
        let n_nodes = mesh.n_nodes();
        let largest = b.d[..3 * n_nodes]
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        let r = rel(&a.d[..3 * n_nodes], &b.d[..3 * n_nodes]);
        println!(
            "{kind:?} corotational: largest displacement {largest:.3} (box 1), nodal solutions \
             differ by {r:.1e}; Newton iterations {:?} vs {:?}",
            a.iterations, b.iterations
        );
        assert!(largest > 0.1, "{kind:?}: a large deformation");
        assert!(r <= 1e-2, "{kind:?}: {r:e}");
        assert_eq!(a.iterations, b.iterations, "{kind:?}");
    }
}

/// Gravity scale of [`dense_tip_groups_are_their_points_summed`]: bends the
/// unit box clamped at z = 0 by about a fifth of its size.
const GRAVITY_SCALE: f64 = 0.3;

#[test]
#[ignore = "measurement: cargo test --release --test front blending_measure -- --ignored --nocapture"]
fn blending_measure() {
    for (name, radius) in [("geometric R=0.2", Some(0.2)), ("topological", None)] {
        for (b, blending) in [("none", Blending::None), ("ramp", Blending::Ramp)] {
            study_blended(
                &format!("tet4 {name} blending {b}"),
                &[8, 12, 16, 24],
                ElementKind::Tet4,
                0.0,
                FrontMode::Tip,
                radius,
                blending,
            );
        }
    }
}

#[test]
#[ignore = "diagnostic: cargo test --release --test front blending_interpolant -- --ignored --nocapture"]
fn blending_interpolant() {
    let fr = Front::new();
    let patch = fr.patch();
    for blending in [Blending::None, Blending::Ramp] {
        for n in [8, 16] {
            let mesh = mesh(n, ElementKind::Tet4, 0.0);
            let input = CutInput {
                blending,
                ..CutInput::tip(&patch, 1e-4, Some(0.2))
            };
            let cut = setup_cut(&mesh, &[input]).unwrap();
            let edges = mid_edges(&mesh);
            let nn = mesh.n_nodes();
            let mut d = vec![0.0; 3 * (nn + cut.n_enriched + N_BRANCH * cut.n_tip)];
            for i in 0..nn {
                let u = standard_value(&fr, &mesh, &cut, &edges, i);
                d[3 * i..3 * i + 3].copy_from_slice(u.as_slice());
                if let Some(j) = cut.enriched[i] {
                    let side = cut.node_side[i];
                    let a = fr.exact(&mesh.nodes[i], side).0 * (2.0 * f64::from(side));
                    d[3 * (nn + j)..3 * (nn + j) + 3].copy_from_slice(a.as_slice());
                }
                if let Some(t) = cut.tip[i] {
                    for k in 0..N_BRANCH {
                        let s = nn + cut.n_enriched + N_BRANCH * t + k;
                        let b = fr.b[k] / cut.tip_scale[t];
                        d[3 * s..3 * s + 3].copy_from_slice(b.as_slice());
                    }
                }
            }
            let model = Model::build(ModelInput {
                mesh,
                material: MATERIAL,
                formulation: Formulation::Linear,
                cut: Some(cut),
                fixed: Vec::new(),
                gravity: None,
                body_force: None,
                tractions: &[],
                need_mass: false,
            });
            let Ok(model) = model else {
                println!("build failed");
                continue;
            };
            let (mut e2, mut u2, mut g2, mut gg) = (0.0, 0.0, 0.0, 0.0);
            for e in 0..model.mesh.n_elements() {
                for (x, w, side) in model.field_points(e) {
                    let (uh, gh) = model.field_at(&d, e, &x, side);
                    let (u, g) = fr.exact(&x, side);
                    e2 += w * (uh - u).norm_squared();
                    u2 += w * u.norm_squared();
                    g2 += w * (gh - g).norm_squared();
                    gg += w * g.norm_squared();
                }
            }
            println!(
                "{blending:?} n {n}: interpolant H1 seminorm {:.3e}",
                (g2 / gg).sqrt()
            );
            println!(
                "{blending:?} n {n}: interpolant L2 {:.3e}",
                (e2 / u2).sqrt()
            );
        }
    }
}

/// Corrected X-FEM (`Blending::Ramp`) on the exact near-front field, Tet4
/// structured, geometric R = 0.2 (issue 11; all four levels measured with
/// `blending_measure`). Without the ramp: L2 1.25e-2 / 6.45e-3 / 3.96e-3 /
/// 1.91e-3, energy 0.240 / 0.178 / 0.142 / 0.0999 (orders 1.80 / 0.87); with
/// it: L2 6.56e-3 / 3.22e-3 / 1.92e-3 / 9.17e-4, energy 0.111 / 0.0748 /
/// 0.0569 / 0.0387 (orders 1.83 / 0.95), 1.2–1.7× the DOFs. Asserted: the
/// orders, and errors at n = 24 that the run without the ramp misses by 1.5×
/// (L2) and 1.6× (energy).
#[test]
fn ramp_blending_lowers_the_error_at_the_optimal_rate_tet4() {
    let (l2, en, runs) = study_blended(
        "tet4 structured geometric R=0.2 ramp",
        &[8, 12, 16, 24],
        ElementKind::Tet4,
        0.0,
        FrontMode::Tip,
        Some(0.2),
        Blending::Ramp,
    );
    assert!(l2 >= 1.75, "L2 order {l2}");
    assert!(en >= 0.9, "energy order {en}");
    let last = &runs[3];
    assert!(last.l2 < 1.25e-3, "L2 {}", last.l2);
    assert!(last.energy < 0.062, "energy {}", last.energy);
}

/// Corrected X-FEM on Tet10 (the ramp's Heaviside functions N_k (1 − R_k)
/// ψ_k, R_k the ramp at the node: `model::ElementShapes::eval`), exact
/// near-front field, structured, geometric R = 0.2, against the plain
/// blending (`blending_measure_tet10` runs n = 2 … 8). Measured: L2 4.36e-3
/// / 2.75e-3 / 1.07e-3 against 4.60e-3 / 3.39e-3 / 1.47e-3, energy 0.0598 /
/// 0.0498 / 0.0312 against 0.0661 / 0.0599 / 0.0410 at n = 3 / 4 / 6, at
/// 1.02–1.15× the DOFs. With the Heaviside functions ramped by 1 − R(x)
/// instead (before), their shifts were cubic and the ramp 3.5–7× worse
/// (L2 2.01e-2 / 1.20e-2, energy 0.309 / 0.245 at n = 3 / 4). Asserted:
/// the ramp lower in both at each level.
#[test]
fn ramp_blending_lowers_the_error_tet10() {
    for n in [3, 4, 6] {
        let run = |b| solve_blended(n, ElementKind::Tet10, 0.0, FrontMode::Tip, Some(0.2), b).0;
        let (plain, ramp) = (run(Blending::None), run(Blending::Ramp));
        println!(
            "n {n}: L2 {:.3e} / {:.3e}, energy {:.3e} / {:.3e}, DOFs {} / {} (none / ramp)",
            plain.l2, ramp.l2, plain.energy, ramp.energy, plain.dofs, ramp.dofs
        );
        assert!(ramp.l2 < plain.l2, "n {n}: L2 {} vs {}", ramp.l2, plain.l2);
        assert!(
            ramp.energy < plain.energy,
            "n {n}: energy {} vs {}",
            ramp.energy,
            plain.energy
        );
    }
}

/// The ramp with the crack on a node layer (z = 0.5 of the n = 16 box, the
/// front along y at x = 0.51, inside elements): the cut runs along the
/// faces of the elements below the layer, whose layer vertices (φ = 0) in
/// I must keep their Heaviside function for the 1 − R of the jump in the
/// blending elements. They did not, and the ramp was 5× worse than no
/// ramp there (L2 2.27e-2 against 4.34e-3, energy 0.377 against 0.153).
/// Asserted: the ramp on the layer errs within 1.1× of the ramp with the
/// crack moved 0.013 off it, and below no ramp on the layer by 1.5× (L2)
/// and 1.8× (energy): on the layer 2.06e-3 / 0.0721 against 4.34e-3 /
/// 0.153; off it 2.09e-3 / 0.0729.
#[test]
fn the_ramp_holds_with_the_crack_on_a_node_layer() {
    let along_y = |z: f64| {
        Front::oriented(
            Point3::new(0.51, 0.5, z),
            Vector3::new(0.0, 0.0, 1.0),
            Vector3::new(0.0, 1.0, 0.0),
        )
    };
    let run = |z: f64, blending| {
        let (run, model, _) = solve_about(
            &along_y(z),
            16,
            ElementKind::Tet4,
            0.0,
            FrontMode::Tip,
            Some(0.2),
            blending,
        );
        let cut = model.cut.as_ref().unwrap();
        let on_layer = model.mesh.nodes.iter().enumerate().filter(|(i, p)| {
            p.z == 0.5 && cut.enriched[*i].is_some() && cut.ramp.get(*i) == Some(&true)
        });
        (run, on_layer.count())
    };
    let (layer, layer_heaviside_in_i) = run(0.5, Blending::Ramp);
    let (off, _) = run(0.513, Blending::Ramp);
    let (plain, _) = run(0.5, Blending::None);
    println!(
        "on the layer: ramp L2 {:.3e} energy {:.3e} ({} layer nodes of I with a Heaviside DOF), none {:.3e} / {:.3e}; off it: ramp {:.3e} / {:.3e}",
        layer.l2, layer.energy, layer_heaviside_in_i, plain.l2, plain.energy, off.l2, off.energy
    );
    assert!(layer_heaviside_in_i > 0);
    assert!(
        layer.l2 <= 1.1 * off.l2,
        "L2 {} vs {} off the layer",
        layer.l2,
        off.l2
    );
    assert!(
        layer.energy <= 1.1 * off.energy,
        "energy {} vs {}",
        layer.energy,
        off.energy
    );
    assert!(
        1.5 * layer.l2 < plain.l2,
        "L2 {} vs {} without the ramp",
        layer.l2,
        plain.l2
    );
    assert!(
        1.8 * layer.energy < plain.energy,
        "energy {} vs {}",
        layer.energy,
        plain.energy
    );
}

#[test]
#[ignore = "measurement: cargo test --release --test front blending_measure_tet10 -- --ignored --nocapture"]
fn blending_measure_tet10() {
    for (b, blending) in [("none", Blending::None), ("ramp", Blending::Ramp)] {
        study_blended(
            &format!("tet10 geometric R=0.2 blending {b}"),
            &[2, 3, 4, 6, 8],
            ElementKind::Tet10,
            0.0,
            FrontMode::Tip,
            Some(0.2),
            blending,
        );
    }
}

/// The probes of the seed's beam (3 × 6 × 10 elements, so z = 0.1 is a
/// node layer) under gravity in x, cut by the patch from (0, 0, `z`) along
/// (0.0137, 0, 0) and `v`, its front inside elements; asserts that
/// elements hold the front.
fn layer_probes(element: &str, z: f64, v: [f64; 3]) -> Vec<Vector3<f64>> {
    use std::path::Path;
    use xfem_cut::run::{probe_values, solve_scene};
    use xfem_cut::scene::Scene;
    let text = format!(
        r#"name = "layer"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [[3, 6, 10]]
element = "{element}"
[material]
young = 3.0e5
poisson = 0.35
density = 1070.0
[[cut]]
origin = [0.0, 0.0, {z}]
u = [0.0137, 0.0, 0.0]
v = [{}, {}, {}]
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
displacement = [0.0, 0.0, 0.0]
[gravity]
acceleration = [9.81, 0.0, 0.0]
[analysis]
type = "static"
[[probe]]
points = [[0.0, 0.03, 0.2], [0.03, 0.03, 0.2], [0.0, 0.03, 0.1]]
"#,
        v[0], v[1], v[2]
    );
    let scene = Scene::parse(&text, Path::new("layer.toml")).unwrap();
    let r = solve_scene(&scene, 0, None, false).unwrap();
    let c = r.model.cut.as_ref().unwrap();
    assert!(
        c.n_tip() > 0 && c.n_partial() > 0,
        "{element} z = {z}: no front elements"
    );
    probe_values(&scene, &r).unwrap()
}

/// The beam's longest element edge (0.01 × 0.01 × 0.02).
fn layer_h() -> f64 {
    (0.01f64.powi(2) * 2.0 + 0.02f64.powi(2)).sqrt()
}

/// A cut whose plane is a node layer of the mesh, its front crossing the
/// faces in that layer (the seed's beam, 10 layers in z: z = 0.1 is one; the
/// front x = 0.0137 between the node lines x = 0.01 and 0.02) ends where it
/// is given: the beam's tip moves as with the plane 2 snaps (2e-4 h) below
/// the layer, where nothing snaps. Before, the faces were cut whole or not
/// at all by their centroids, and the cut ended near x = 0.01 (the tip 9.5 %
/// (Tet4) off).
#[test]
fn a_front_across_the_faces_of_a_node_layer_ends_where_it_is_given() {
    for element in ["tet4", "tet10"] {
        let v = [0.0, 0.06, 0.0];
        let on = layer_probes(element, 0.1, v);
        let off = layer_probes(element, 0.1 - 2e-4 * layer_h(), v);
        for (a, b) in on.iter().zip(&off) {
            let rel = (a - b).norm() / b.norm();
            println!("{element}: layer {a:?}, 2 snaps below {b:?}: {rel:.1e}");
            assert!(rel < 1e-3, "{element}: {rel:e}");
        }
    }
}

/// The same front, skewed across the layer's faces, with its plane a hair
/// off the node layer (±1e-8 h, what single precision makes of z = 0.1 in
/// an STL, and ±0.9 snap): every node of the layer snaps onto the plane,
/// and the faces the front crosses are lifted to the same side as with the
/// plane on the layer, so the tip moves by round-off. Before, nodes
/// snapped from below were lifted below, the elements above the layer held
/// the front instead of those below, and the tip moved 1.1 % (Tet4) from
/// 1e-8 h.
#[test]
fn a_plane_within_the_snap_of_a_node_layer_solves_as_on_it() {
    let v = [0.0035, 0.06, 0.0];
    for element in ["tet4", "tet10"] {
        let on = layer_probes(element, 0.1, v);
        let scale = on.iter().map(|p| p.norm()).fold(0.0, f64::max);
        for offset in [1e-8, -1e-8, 0.9e-4, -0.9e-4] {
            let off = layer_probes(element, 0.1 + offset * layer_h(), v);
            let diff = on
                .iter()
                .zip(&off)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            println!(
                "{element}: plane {offset:e} h off the layer: {:.1e}",
                diff / scale
            );
            // The plane moves by `offset`, the solution with it: O(offset).
            assert!(
                diff <= 10.0 * offset.abs() * scale,
                "{element} {offset:e}: {:e}",
                diff / scale
            );
        }
    }
}

/// An oblique patch entering through the face x = 0 of the beam: the nodes of
/// that face project past the patch's edge on one side of it. Those feet
/// lie beyond an edge outside the body, which is not front: they are behind
/// the front, and how far the patch (and its front) runs on outside the
/// body changes nothing inside it. Before: ψ > 0 there (ahead of the front),
/// a front in the first element column was refused as cutting nothing, and
/// a deeper one gave other probes (1e-4 relative) as the patch grew outside.
#[test]
fn how_far_an_oblique_patch_runs_on_outside_the_body_changes_nothing() {
    use std::path::Path;
    use xfem_cut::run::{probe_values, solve_scene};
    use xfem_cut::scene::Scene;
    let scene = |element: &str, depth: f64, out_u: f64, out_v: f64| {
        // The edge o + u + t v inside the body, tilted about y and along y.
        let u = Vector3::new(depth, 0.0006, -0.15 * depth);
        let v = Vector3::new(0.0, 0.062, -0.0084);
        let o = Vector3::new(-0.001, -0.001, 0.0857) - u * out_u - v * out_v;
        let (u, v) = (u * (1.0 + out_u), v * (1.0 + 2.0 * out_v));
        let text = format!(
            r#"name = "oblique"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [[3, 5, 11]]
element = "{element}"
[material]
young = 3.0e5
poisson = 0.45
density = 1070.0
[[cut]]
origin = [{}, {}, {}]
u = [{}, {}, {}]
v = [{}, {}, {}]
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
displacement = [0.0, 0.0, 0.0]
[gravity]
acceleration = [9.81, 2.0, -3.0]
[analysis]
type = "static"
[[probe]]
points = [[0.0, 0.03, 0.2], [0.03, 0.03, 0.2], [0.006, 0.018, 0.095], [0.024, 0.042, 0.09]]
"#,
            o.x, o.y, o.z, u.x, u.y, u.z, v.x, v.y, v.z
        );
        let scene = Scene::parse(&text, Path::new("oblique.toml")).unwrap();
        let r = solve_scene(&scene, 0, None, false)
            .unwrap_or_else(|e| panic!("{element} depth {depth}: {e}"));
        assert!(r.model.cut.as_ref().unwrap().n_tip() > 0);
        probe_values(&scene, &r).unwrap()
    };
    for element in ["tet4", "tet10"] {
        // Fronts at x ≈ 0.0074 (in the first element column) and ≈ 0.0125.
        for depth in [0.0084, 0.0135] {
            let near = scene(element, depth, 0.0, 0.0);
            for (out_u, out_v) in [(0.4, 0.0), (0.0, 0.3), (0.7, 0.5)] {
                let far = scene(element, depth, out_u, out_v);
                let scale = near.iter().map(|p| p.norm()).fold(0.0, f64::max);
                let diff = near
                    .iter()
                    .zip(&far)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                println!(
                    "{element} depth {depth}, patch on by {out_u}, {out_v}: {:.1e}",
                    diff / scale
                );
                assert!(
                    diff <= 1e-10 * scale,
                    "{element} depth {depth}: {:e}",
                    diff / scale
                );
            }
        }
    }
}

/// `front = "extend"` with the cut on a node layer and its front crossing
/// the layer's faces: a face the front crosses opens whole, as it does with
/// the plane moved 3e-4 h off the layer to either side (the elements beside
/// it are then crossed, and extended). Before, the face's centroid decided,
/// and the layer's result was 20 % off both sides' (Tet4, front at x =
/// 0.0137); now it lies within the two sides' own difference of them.
#[test]
fn an_extended_front_across_the_faces_of_a_node_layer_opens_them_as_either_side_does() {
    use std::path::Path;
    use xfem_cut::run::{probe_values, solve_scene};
    use xfem_cut::scene::Scene;
    let scene = |element: &str, z: f64| {
        let text = format!(
            r#"name = "layer"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [[3, 6, 10]]
element = "{element}"
[material]
young = 3.0e5
poisson = 0.35
density = 1070.0
[[cut]]
origin = [0.0, 0.0, {z}]
u = [0.0137, 0.0, 0.0]
v = [0.0, 0.06, 0.0]
front = "extend"
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
displacement = [0.0, 0.0, 0.0]
[gravity]
acceleration = [9.81, 0.0, 0.0]
[analysis]
type = "static"
[[probe]]
points = [[0.0, 0.03, 0.2], [0.03, 0.03, 0.2]]
"#
        );
        let scene = Scene::parse(&text, Path::new("layer.toml")).unwrap();
        let r = solve_scene(&scene, 0, None, false).unwrap();
        probe_values(&scene, &r).unwrap()
    };
    let rel = |a: &[Vector3<f64>], b: &[Vector3<f64>]| {
        let scale = b.iter().map(|p| p.norm()).fold(0.0, f64::max);
        a.iter()
            .zip(b)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
            / scale
    };
    for element in ["tet4", "tet10"] {
        let h = (0.01f64.powi(2) * 2.0 + 0.02f64.powi(2)).sqrt();
        let on = scene(element, 0.1);
        let above = scene(element, 0.1 + 3e-4 * h);
        let below = scene(element, 0.1 - 3e-4 * h);
        let sides = rel(&above, &below);
        let (up, down) = (rel(&on, &above), rel(&on, &below));
        println!(
            "{element}: layer vs above {up:.1e}, vs below {down:.1e}; above vs below {sides:.1e}"
        );
        // Either side moves the probes by ~1e-3 of the 20 % the centroid rule cost.
        assert!(
            up.max(down) < 2e-3,
            "{element}: {up:e} {down:e} (sides {sides:e})"
        );
    }
}

/// A scene symmetric under the swap x ↔ y (a square prism, the cut plane
/// z = 0.053 from the edge x = y = 0 up to the front x + y = 0.035, gravity
/// along (1, 1, 0)): mirrored probes read mirrored displacements. An extended
/// front and the linear formulation give it to round-off; a tip front to
/// the accuracy of its quadrature, since the sub-tets and collapsed rules of
/// front elements follow the elements' vertex order, which the mirror
/// changes (1.1e-6 … 1.4e-6 relative measured; the patch test's quadrature
/// residual is 4.9e-5 of the forces). Checked through the CLI by a fuzz run.
#[test]
fn a_mirror_symmetric_scene_gives_mirrored_probes() {
    use xfem_cut::run::{probe_values, solve_scene};
    use xfem_cut::scene::Scene;
    let probes = [[0.01, 0.03, 0.1], [0.005, 0.02, 0.06], [0.03, 0.035, 0.04]];
    let mirrored = probes.map(|p| [p[1], p[0], p[2]]);
    let points: Vec<String> = probes
        .iter()
        .chain(&mirrored)
        .map(|p| format!("[{}, {}, {}]", p[0], p[1], p[2]))
        .collect();
    let s = std::f64::consts::FRAC_1_SQRT_2;
    for (element, front, bound) in [
        ("tet4", "extend", 1e-12),
        ("tet10", "extend", 1e-12),
        ("tet4", "tip", 1e-5),
        ("tet10", "tip", 1e-5),
    ] {
        let text = format!(
            r#"name = "mirror"
[body]
box = [[0.0, 0.0, 0.0], [0.04, 0.04, 0.1]]
levels = [[4, 4, 10]]
element = "{element}"
[material]
young = 3.0e5
poisson = 0.3
density = 1000.0
[[cut]]
origin = [{ox}, {oy}, 0.053]
u = [{ux}, {uy}, 0.0]
v = [{v}, {v}, 0.0]
front = "{front}"
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
[gravity]
acceleration = [3.0, 3.0, 0.0]
[analysis]
type = "static"
formulation = "linear"
[[probe]]
points = [{points}]
"#,
            ox = -0.07 * s,
            oy = 0.05 * s,
            ux = 0.12 * s,
            uy = -0.12 * s,
            v = 0.035 * s,
            points = points.join(", ")
        );
        let scene = Scene::parse(&text, std::path::Path::new("mirror.toml")).unwrap();
        let run = solve_scene(&scene, 0, None, false).unwrap();
        let u = probe_values(&scene, &run).unwrap();
        let scale = u.iter().map(|v| v.norm()).fold(0.0, f64::max);
        let k = probes.len();
        let worst = (0..k)
            .map(|i| (u[k + i] - Vector3::new(u[i].y, u[i].x, u[i].z)).norm())
            .fold(0.0, f64::max)
            / scale;
        println!("{element} {front}: mirror error {worst:.1e} (relative)");
        assert!(scale > 1e-5, "{scale:e}");
        assert!(worst <= bound, "{element} {front}: {worst:e}");
    }
}

/// The four random front orientations (normal, direction along the front)
/// of `fronts_at_any_angle_converge_alike`: a 64-bit LCG from one seed.
fn random_orientations() -> Vec<(Vector3<f64>, Vector3<f64>)> {
    let mut seed = 12345u64;
    let mut unit = || {
        seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..4)
        .map(|_| {
            let n = Vector3::new(unit(), unit(), unit());
            (n, Vector3::new(unit(), unit(), unit()))
        })
        .collect()
}

#[test]
fn fronts_at_any_angle_converge_alike() {
    // The exact field about fronts of other orientations: random ones and
    // ones along the structured mesh's edges and faces (a front in a node
    // plane, along an edge direction, in the plane of the hexes' diagonal
    // faces; the random ones on jittered meshes). Geometric tip enrichment,
    // Tet4, 12 and 20 divisions: orders measured 1.50 … 1.80 (L2) and
    // 0.75 … 0.88 (energy; unjittered, the random orientations gave
    // 1.52 … 1.73 and 0.75 … 0.80), the random orientations lowest, still
    // short of their asymptotes (2 and 1; the
    // first orientation's 0.87 here is 0.85+ at 16 → 24 in
    // `geometric_tip_enrichment_converges_at_the_optimal_rate_tet4`). The
    // bounds 1.4 and 0.7 catch an orientation whose tip treatment fails:
    // the topological tip gave 0.71 … 0.93 and 0.44 … 0.53 on the same
    // meshes, `extend` 0.40 … 1.48 and 0.40 … 0.62 (both unjittered). Tet10, 6
    // and 9 divisions: 2.43 … 3.22 and 1.45 … 2.13 (asymptotes 3 and 2; bounds
    // 2.2 and 1.3). At 4 → 7 the plane x = y, parallel to the hexes'
    // diagonal faces, was still at 1.55 and 0.68 (the two mesh-aligned
    // orientations before it: ≥ 2.25 and ≥ 1.01).
    // (name, normal, along, node jitter: the random orientations on meshes
    // whose nodes are moved by up to 0.2 h, as unstructured ones are)
    let mut orientations = vec![
        (
            "along z, plane y",
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            0.0,
        ),
        (
            "along a face diagonal",
            Vector3::new(0.0, 1.0, 0.0),
            Vector3::new(1.0, 0.0, 1.0),
            0.0,
        ),
        (
            "plane x = y",
            Vector3::new(1.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, 1.0),
            0.0,
        ),
        (
            "along the body diagonal",
            Vector3::new(1.0, -1.0, 0.0),
            Vector3::new(1.0, 1.0, 1.0),
            0.0,
        ),
    ];
    for (n, t) in random_orientations() {
        orientations.push(("random, jittered", n, t, 0.2));
    }
    // (element, coarse and fine divisions, smallest L2 and energy orders)
    let studies = [
        (ElementKind::Tet4, [12, 20], 1.4, 0.7),
        (ElementKind::Tet10, [6, 9], 2.2, 1.3),
    ];
    for (name, n, t, jitter) in orientations {
        let fr = Front::oriented(Point3::new(0.513, 0.479, 0.507), n, t);
        for (kind, divs, min_l2, min_en) in studies {
            let runs: Vec<Run> = divs
                .iter()
                .map(|&d| {
                    solve_about(
                        &fr,
                        d,
                        kind,
                        jitter,
                        FrontMode::Tip,
                        Some(0.2),
                        Blending::None,
                    )
                    .0
                })
                .collect();
            let lev = (divs[1] as f64 / divs[0] as f64).ln();
            let l2 = (runs[0].l2 / runs[1].l2).ln() / lev;
            let en = (runs[0].energy / runs[1].energy).ln() / lev;
            println!(
                "{name:24} {kind:?} n {:.2?} t {:.2?}: L2 {:.3e} → {:.3e} (order {l2:.2}), energy {:.3e} → {:.3e} (order {en:.2})",
                fr.n, fr.t, runs[0].l2, runs[1].l2, runs[0].energy, runs[1].energy
            );
            assert!(l2 >= min_l2, "{name} {kind:?}: L2 order {l2}");
            assert!(en >= min_en, "{name} {kind:?}: energy order {en}");
        }
    }
}

#[test]
#[ignore = "measurement: cargo test --release --test front random_fronts_orders_measure -- --ignored --nocapture"]
fn random_fronts_orders_measure() {
    // The random orientations of `fronts_at_any_angle_converge_alike` one
    // level further (Tet4 12 → 20 → 28, jittered 0.2 h), without and with
    // the ramp in blending elements. Measured (L2 / energy orders 20 → 28):
    // without 1.56 … 1.79 / 0.80 … 0.89 (12 → 20: 1.50 … 1.67 / 0.75 … 0.77),
    // slowly rising; with the ramp (all four branch functions on its ring,
    // one node gauged) 1.85 … 1.90 / 0.94 … 0.97, and errors at 28 2.4–2.8×
    // (L2) and 2.7–2.8× (energy) lower at 1.2× the DOFs; with the ring
    // holding F₂, F₃ (now) 1.85 … 1.91 / 0.94 … 0.98, L2 at 28 within 1 %
    // of those and energy 4–8 % above them, at 1.1× the DOFs. The
    // blending elements hold the rest: a finer tip quadrature (collapsed
    // rules of order 6, near-front cells refined twice) moved the errors at
    // 12 and 20 by ≤ 0.3 % and the orders not at all.
    let orientations: Vec<_> = random_orientations()
        .into_iter()
        .map(|(n, t)| Front::oriented(Point3::new(0.513, 0.479, 0.507), n, t))
        .collect();
    for (fr, blending) in orientations
        .iter()
        .flat_map(|fr| [(fr, Blending::None), (fr, Blending::Ramp)])
    {
        println!("{blending:?}");
        let divs = [12, 20, 28];
        let runs: Vec<Run> = divs
            .iter()
            .map(|&d| {
                let start = std::time::Instant::now();
                let r = solve_about(
                    fr,
                    d,
                    ElementKind::Tet4,
                    0.2,
                    FrontMode::Tip,
                    Some(0.2),
                    blending,
                )
                .0;
                println!(
                    "  {d}: L2 {:.3e} energy {:.3e} ({} DOFs, {} tip nodes, {:.1} s)",
                    r.l2,
                    r.energy,
                    r.dofs,
                    r.n_tip,
                    start.elapsed().as_secs_f64()
                );
                r
            })
            .collect();
        for k in 0..2 {
            let lev = (divs[k + 1] as f64 / divs[k] as f64).ln();
            println!(
                "n {:.2?} t {:.2?} {} → {}: L2 order {:.2}, energy order {:.2}",
                fr.n,
                fr.t,
                divs[k],
                divs[k + 1],
                (runs[k].l2 / runs[k + 1].l2).ln() / lev,
                (runs[k].energy / runs[k + 1].energy).ln() / lev
            );
        }
    }
}

#[test]
fn ramp_blending_solves_a_free_body() {
    // The seed's gravity beam (its front on the node plane x = 0.015, every
    // face free but the clamped bottom), Tet4, with the ramp: its tip
    // functions are linearly dependent (φ (F₀ − F₃) + ψ F₂ = 0 and
    // φ (F₁ − F₂) − ψ F₃ = 0 with every vertex of the ramped elements
    // carrying them), and nothing pinned them here: the factorisation
    // failed (not positive definite) at L0 and L1. The ring nodes (tip
    // nodes outside I) now carry F₀ and F₁ only (`model::ramp_fixes`),
    // which pins the dependence along the region's outer surface. Top
    // corner ux against X-FEM Tet10 at L1: 0.554 / 0.285 / 0.110 without the
    // ramp, 0.486 / 0.246 / 0.089 with it (L0 / L1 / L2; 1.31 / 1.13 / 1.04×
    // the DOFs). With all four on the ring and F₀, F₁ of one node prescribed
    // (before): 0.473 / 0.242 / 0.088 at 1.57 / 1.25 / 1.08× the DOFs.
    use xfem_cut::locate::Locator;
    use xfem_cut::study::fixtures::{beam_mesh, seed_beam};
    let patch = PlanarPatch {
        origin: Point3::new(0.0, 0.0, 0.1),
        u: Vector3::new(0.015, 0.0, 0.0),
        v: Vector3::new(0.0, 0.06, 0.0),
    };
    let top = Point3::new(0.0, 0.03, 0.2);
    let solve = |div: [usize; 3], tet10: bool, blending: Blending| {
        let mesh = beam_mesh(div, tet10);
        let input = CutInput {
            blending,
            ..CutInput::tip(&patch, 1e-4, None)
        };
        let cut = setup_cut(&mesh, &[input]).unwrap();
        let model = seed_beam(mesh, Formulation::Linear, Some(cut)).unwrap();
        let mut chol = Cholesky::new(&model.pattern).unwrap();
        let sol = solve_static(&model, &mut chol, &StaticOptions::default())
            .unwrap_or_else(|e| panic!("{div:?} {blending:?}: {e}"));
        assert!(
            sol.residual <= 1e-10,
            "{div:?} {blending:?}: {}",
            sol.residual
        );
        // The ramp holds F₂ and F₃ of its ring nodes (tip nodes outside I),
        // every component, and nothing else of the tip functions.
        let cut = model.cut.as_ref().expect("a cut");
        let first_tip = model.mesh.n_nodes() + cut.n_enriched;
        let held = model
            .prescribed
            .iter()
            .filter(|p| p.dof / 3 >= first_tip)
            .count();
        let ring = if blending == Blending::Ramp {
            (0..model.mesh.n_nodes())
                .filter(|&i| cut.tip[i].is_some() && !cut.ramp[i])
                .count()
        } else {
            0
        };
        assert_eq!(held, 6 * ring, "{div:?}");
        assert!(blending == Blending::None || ring > 0, "{div:?}");
        let (e, _) = Locator::new(&model.mesh).locate(&model.mesh, &top).unwrap();
        (model.displacement_at(&sol.d, e, &top, 1).x, model.n_free)
    };
    let (reference, _) = solve([4, 8, 27], true, Blending::None);
    for div in [[2, 4, 13], [4, 8, 27], [8, 16, 53]] {
        let (plain, n0) = solve(div, false, Blending::None);
        let (ramped, n1) = solve(div, false, Blending::Ramp);
        let (e0, e1) = (
            (plain - reference).abs() / reference,
            (ramped - reference).abs() / reference,
        );
        println!("{div:?}: top ux error {e0:.3e} ({n0} DOFs) without the ramp, {e1:.3e} ({n1} DOFs) with it");
        assert!(e1 < e0, "{div:?}: {e1} vs {e0}");
    }
}

/// A crack on a node layer whose front runs along a node line is a crack of
/// the conforming mesh: X-FEM on the uncut mesh (`front = "extend"`, the
/// plane through the nodes) equals FEM on the same mesh with the crack
/// face's nodes duplicated below it (front-line nodes shared), node for
/// node, seen from each side: Tet4 and Tet10, gravity and the top face
/// moved, linear and corotational.
#[test]
fn a_crack_on_a_node_layer_ending_on_a_node_line_equals_the_mesh_with_its_nodes_duplicated() {
    use common::{bar, model, solve};
    use xfem_cut::cut::DEFAULT_SNAP;
    let (z0, x_front) = (1.0, 0.5);
    let patch = PlanarPatch {
        origin: Point3::new(-0.1, -0.1, z0),
        u: Vector3::new(x_front + 0.1, 0.0, 0.0),
        v: Vector3::new(0.0, 1.2, 0.0),
    };
    let g = Vector3::new(3.0, -2.0, -9.81);
    let top = Vector3::new(0.05, 0.03, 0.04);
    for tet10 in [false, true] {
        let mesh = if tet10 {
            bar([2, 2, 4]).to_tet10()
        } else {
            bar([4, 4, 8])
        };
        // The cracked mesh: nodes on the layer behind the front line get a
        // twin, which the elements below the layer take instead.
        let on_face = |p: &Point3<f64>| p.z == z0 && p.x < x_front - 1e-12;
        let mut nodes = mesh.nodes.clone();
        let mut twin = vec![usize::MAX; mesh.n_nodes()];
        for (i, p) in mesh.nodes.iter().enumerate() {
            if on_face(p) {
                twin[i] = nodes.len();
                nodes.push(*p);
            }
        }
        let nn = mesh.kind.nodes();
        let mut cells = mesh.cells.clone();
        for e in 0..mesh.n_elements() {
            let conn = &mut cells[nn * e..nn * (e + 1)];
            let below = conn.iter().map(|&i| mesh.nodes[i].z).sum::<f64>() / (nn as f64) < z0;
            if below {
                for i in conn.iter_mut().filter(|i| twin[**i] != usize::MAX) {
                    *i = twin[*i];
                }
            }
        }
        let cracked = TetMesh {
            kind: mesh.kind,
            nodes,
            cells,
        };
        let cut = setup_cut(&mesh, &[CutInput::extend(&patch, DEFAULT_SNAP)]).unwrap();
        for formulation in [Formulation::Linear, Formulation::Corotational] {
            let x = model(&mesh, Some(cut.clone()), formulation, g, Some(top), false).unwrap();
            let f = model(&cracked, None, formulation, g, Some(top), false).unwrap();
            let (dx, df) = (solve(&x), solve(&f));
            let (mut worst, mut scale): (f64, f64) = (0.0, 0.0);
            for i in 0..mesh.n_nodes() {
                let up = Vector3::new(df[3 * i], df[3 * i + 1], df[3 * i + 2]);
                let j = if twin[i] == usize::MAX { i } else { twin[i] };
                let down = Vector3::new(df[3 * j], df[3 * j + 1], df[3 * j + 2]);
                for (side, want) in [(1i8, up), (-1, down)] {
                    let got = x.node_displacement(&dx, i, side);
                    worst = worst.max((got - want).norm());
                    scale = scale.max(want.norm());
                }
            }
            println!(
                "{:?} {formulation:?}: {} twins, X-FEM vs the cracked mesh {:.1e} of {scale:.2e}",
                mesh.kind,
                twin.iter().filter(|&&t| t != usize::MAX).count(),
                worst / scale
            );
            assert!(worst <= 1e-9 * scale, "{:e}", worst / scale);
        }
    }
}

/// A tip front whose elements reach another cut's nodes (a blade passing
/// within two elements of a cut made before: `free_slice` by two blades on
/// its coarsest mesh was refused): the elements holding its tip functions
/// keep its level sets while those nodes keep the other cut's side and
/// enrichment. The field there equals the field of the front's cut alone,
/// value and gradient, whatever the other cut's DOFs hold; the other cut's
/// elements see its own Heaviside functions as without the front.
#[test]
fn a_tip_front_beside_another_cut_evaluates_its_branch_functions_with_its_own_level_sets() {
    use common::{bar, model};
    use xfem_cut::cut::DEFAULT_SNAP;
    let through = PlanarPatch {
        origin: Point3::new(-0.1, -0.1, 0.55),
        u: Vector3::new(1.2, 0.0, 0.1),
        v: Vector3::new(0.0, 1.2, 0.0),
    };
    let partial = PlanarPatch {
        origin: Point3::new(-0.1, -0.1, 1.2),
        u: Vector3::new(0.55, 0.0, -0.03),
        v: Vector3::new(0.0, 1.2, 0.0),
    };
    let g = Vector3::new(0.0, 0.0, -9.81);
    for tet10 in [false, true] {
        let mesh = if tet10 {
            bar([3, 3, 6]).to_tet10()
        } else {
            bar([3, 3, 6])
        };
        let both = setup_cut(
            &mesh,
            &[
                CutInput::extend(&through, DEFAULT_SNAP),
                CutInput::tip(&partial, DEFAULT_SNAP, None),
            ],
        )
        .expect("a tip front two elements from another cut is allowed");
        let alone = setup_cut(&mesh, &[CutInput::tip(&partial, DEFAULT_SNAP, None)]).unwrap();
        let first = setup_cut(&mesh, &[CutInput::extend(&through, DEFAULT_SNAP)]).unwrap();
        assert!(
            !both.tip_levels.is_empty(),
            "the front's elements reach the other cut's nodes"
        );
        assert_eq!(both.n_tip, alone.n_tip);
        let build = |cut: &CutSetup| {
            model(
                &mesh,
                Some(cut.clone()),
                Formulation::Linear,
                g,
                None,
                false,
            )
            .unwrap()
        };
        let (mb, ma, mf) = (build(&both), build(&alone), build(&first));
        // A field on the front's cut alone: made-up standard and tip values;
        // the same in the model of both cuts, with made-up values of the
        // other cut's Heaviside DOFs too.
        let n = mesh.n_nodes();
        let value = |k: usize| ((k as f64) * 0.7390851).sin();
        let mut da = vec![0.0; ma.n_dofs()];
        let mut db: Vec<f64> = (0..mb.n_dofs()).map(|k| value(k + 17)).collect();
        for i in 0..n {
            for c in 0..3 {
                da[3 * i + c] = value(3 * i + c);
                db[3 * i + c] = da[3 * i + c];
            }
            if let (Some(ta), Some(tb)) = (alone.tip[i], both.tip[i]) {
                for b in 0..N_BRANCH {
                    for c in 0..3 {
                        let sa = n + alone.n_enriched + N_BRANCH * ta + b;
                        let sb = n + both.n_enriched + N_BRANCH * tb + b;
                        da[3 * sa + c] = value(1000 + 3 * sa + c);
                        db[3 * sb + c] = da[3 * sa + c];
                    }
                }
            }
        }
        // Largest difference; NaN (a branch function of an infinite ψ) stays.
        let mut worst: f64 = 0.0;
        let mut note = |d: f64| {
            if d.is_nan() || d > worst {
                worst = d
            }
        };
        for &e in both.tip_levels.keys() {
            let centre = mesh
                .vertices(e)
                .iter()
                .fold(Vector3::zeros(), |s, &i| s + mesh.nodes[i].coords)
                / 4.0;
            for &i in &mesh.vertices(e) {
                let x = Point3::from(centre * 0.7 + mesh.nodes[i].coords * 0.3);
                let (ua, ga) = ma.field_at(&da, e, &x, 0);
                let (ub, gb) = mb.field_at(&db, e, &x, 0);
                note((ua - ub).norm());
                note((ga - gb).norm());
            }
        }
        // The other cut's elements: its Heaviside field as without the front.
        let mut df = vec![0.0; mf.n_dofs()];
        for i in 0..n {
            for c in 0..3 {
                df[3 * i + c] = db[3 * i + c];
            }
            if let (Some(jf), Some(jb)) = (first.enriched[i], both.enriched[i]) {
                for c in 0..3 {
                    df[3 * (n + jf) + c] = db[3 * (n + jb) + c];
                }
            }
        }
        let mut cut_elements = 0;
        for e in 0..mesh.n_elements() {
            if matches!(first.elements[e], xfem_cut::cut::ElementCut::Uncut) {
                continue;
            }
            cut_elements += 1;
            for (x, _, side) in mf.field_points(e) {
                let (uf, gf) = mf.field_at(&df, e, &x, side);
                let (ub, gb) = mb.field_at(&db, e, &x, side);
                note((uf - ub).norm());
                note((gf - gb).norm());
            }
        }
        println!(
            "{:?}: {} elements hold the front's level sets beside the other cut's nodes; {cut_elements} elements of the other cut; largest difference {worst:.1e}",
            mesh.kind,
            both.tip_levels.len()
        );
        assert!(cut_elements > 0);
        assert!(worst <= 1e-12, "{worst:e}");
    }
}

/// A slice that two through cuts free from the clamped bar, holding a third
/// cut's tip front (its patch ends inside the slice on three sides), falls
/// with g at every node under the lumped mass: the tip functions' lumped
/// mass is diagonal, so in a floating part they take no gravity load
/// (`Model::lumped_load`). Under their consistent load, ρ g ∫ N_i (F_k −
/// F_k(x_i)), the worst node was 2.5e-5 of ½ g t² off it after 0.2 s (Tet4
/// linear; Tet10's probes through `xfem-cut run` up to 4.6e-5); now 1.9e-11
/// (Tet4 linear), 1.1e-12 (corotational), 4.0e-10 (Tet10), measured. The
/// part above the slice floats too and falls as well. Also with a wider
/// slice whose front's `tip_radius` takes the ramp (the ring's tip
/// functions lumped the same way): 1.8e-11 (linear), 1.1e-11
/// (corotational), 425 tip nodes.
#[test]
fn a_slice_holding_a_tip_front_falls_with_g_at_every_node() {
    let g = Vector3::new(3.0, 4.0, -9.81);
    // (element, levels, formulation, wide): `wide` a slice of 0.05 … 0.15
    // whose front takes tip_radius 0.022, 2.6 median edges, so the ramp
    // (its ring tip-enriched too).
    for (element, levels, formulation, wide) in [
        ("tet4", "[4, 8, 40]", "linear", false),
        ("tet4", "[4, 8, 40]", "corotational", false),
        ("tet10", "[2, 4, 40]", "linear", false),
        ("tet4", "[4, 8, 40]", "linear", true),
        ("tet4", "[4, 8, 40]", "corotational", true),
    ] {
        let (below, above, radius) = if wide {
            (0.0501, 0.1501, "tip_radius = 0.022\n")
        } else {
            (0.0801, 0.1201, "")
        };
        let text = format!(
            r#"name = "slice_with_a_front"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [{levels}]
element = "{element}"
[material]
young = 3.0e5
poisson = 0.35
density = 1070.0
[[cut]]
origin = [-0.01, -0.01, {below}]
u = [0.05, 0.0, 0.0]
v = [0.0, 0.08, 0.0]
[[cut]]
origin = [-0.01, -0.01, {above}]
u = [0.05, 0.0, 0.0]
v = [0.0, 0.08, 0.0]
[[cut]]
origin = [-0.01, 0.0301, 0.0913]
u = [0.0263, 0.0, 0.0]
v = [0.0, 0.0, 0.0174]
{radius}[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
[gravity]
acceleration = [{}, {}, {}]
[analysis]
type = "dynamic"
formulation = "{formulation}"
dt = 0.01
steps = 20
"#,
            g.x, g.y, g.z
        );
        let scene =
            xfem_cut::scene::Scene::parse(&text, std::path::Path::new("slice.toml")).unwrap();
        let r = xfem_cut::run::solve_scene(&scene, 0, None, false).unwrap();
        let c = r.model.cut.as_ref().unwrap();
        assert!(c.n_tip > 0, "{element}: the front is tip-enriched");
        assert_eq!(c.ramp.iter().any(|&r| r), wide, "{element} wide {wide}");
        let want = g * (0.5 * 0.2f64.powi(2));
        let (mut worst, mut tips) = (0.0f64, 0);
        for (i, p) in r.model.mesh.nodes.iter().enumerate() {
            // Nodes of the slice and of the part above it, off the cuts' elements.
            if !(below + 0.0059..=above - 0.0061).contains(&p.z) && p.z < above + 0.0059 {
                continue;
            }
            let u = r.model.node_displacement(&r.d, i, 1);
            worst = worst.max((u - want).norm() / want.norm());
            tips += usize::from(c.tip[i].is_some());
        }
        println!("{element} {formulation} wide {wide}: worst node {worst:e}, {tips} tip nodes among them");
        assert!(tips > 0);
        assert!(worst <= 1e-9, "{element} {formulation}: {worst:e}");
    }
}

/// Issue 11's rates on an unstructured mesh (interior nodes jittered by up
/// to 0.2 h, the exact study's "jittered"), Tet4, geometric R = 0.2: with
/// the plain blending the last pair (n = 16 → 24) gives L2 1.76 and energy
/// 0.85 (errors 4.24e-3 / 2.07e-3 and 0.148 / 0.105), short of the L2 1.8
/// the structured mesh reaches; with corrected X-FEM's ramp, L2 2.15e-3 /
/// 1.03e-3 and energy 0.0607 / 0.0416: orders 1.80 / 0.93, errors 2.0× /
/// 2.5× lower at 1.2× the DOFs (the plain blending is run here at n = 24
/// only; its n = 16 is the exact study's). Asserted: the
/// ramp's orders against the issue's 1.8 / 0.85, and its L2 error at n = 24
/// under the plain blending's by 1.5×.
#[test]
fn ramp_blending_keeps_the_rates_of_issue_11_on_a_jittered_mesh_tet4() {
    let (l2, en, runs) = study_blended(
        "tet4 jittered geometric R=0.2 ramp",
        &[16, 24],
        ElementKind::Tet4,
        0.2,
        FrontMode::Tip,
        Some(0.2),
        Blending::Ramp,
    );
    assert!(l2 >= 1.8, "L2 order {l2}");
    assert!(en >= 0.85, "energy order {en}");
    let plain = solve_blended(
        24,
        ElementKind::Tet4,
        0.2,
        FrontMode::Tip,
        Some(0.2),
        Blending::None,
    )
    .0;
    println!(
        "plain blending n 24: L2 {:.3e} energy {:.3e}",
        plain.l2, plain.energy
    );
    assert!(runs[1].l2 * 1.5 < plain.l2, "{} {}", runs[1].l2, plain.l2);
}

/// The seed's beam (1080 Tet4) with its cut shortened to x = 0.0137, the
/// front inside elements and tip-enriched (the `tip` group of
/// benches/cut.rs): `Cholesky::fill_reducing` keeps the candidate whose
/// numeric factorisation is estimated cheapest (`Cholesky::factor_cost`:
/// flops plus a cost per supernodal update pair). Here that is AMD: nested
/// dissection on the equation graph fills less (141588 entries in L against
/// 170712) but makes twice the update pairs (504 against 228), and in five
/// interleaved runs its factorisation took 3–9 % longer than AMD's (1.67–2.46
/// against 1.55–2.26 ms, `examples/ordering_cost.rs`). The rule before kept
/// the fewest entries and fails here.
#[test]
fn the_fill_reducing_ordering_keeps_its_cheapest_candidate_with_a_tip_front() {
    use xfem_cut::assembly::equation_shapes;
    use xfem_cut::solve::{Ordering, Parallelism, UPDATE_PAIR_COST};
    use xfem_cut::study::fixtures::{beam_mesh, seed_beam};
    let mesh = beam_mesh([3, 6, 10], false);
    let patch = PlanarPatch {
        origin: Point3::new(0.0, 0.0, 0.1),
        u: Vector3::new(0.0137, 0.0, 0.0),
        v: Vector3::new(0.0, 0.06, 0.0),
    };
    let cut = setup_cut(
        &mesh,
        &[CutInput::tip(&patch, xfem_cut::cut::DEFAULT_SNAP, None)],
    )
    .unwrap();
    assert!(cut.n_tip() > 0);
    let m = seed_beam(mesh, Formulation::Corotational, Some(cut)).unwrap();
    let shapes = equation_shapes(&m);
    let seq = Parallelism::SEQUENTIAL;
    let factor = Cholesky::fill_reducing(&m.pattern, Some(&shapes), seq).unwrap();
    // `run` prints this line: it names the ordering the run took.
    assert!(
        factor.describe().contains("AMD ordering, the cheapest"),
        "{}",
        factor.describe()
    );
    let candidate = |ordering: Ordering| Cholesky::with(&m.pattern, &ordering, seq).unwrap();
    let on_shapes = candidate(Ordering::nested_dissection(&m.pattern, Some(&shapes)).unwrap());
    let on_equations = candidate(Ordering::nested_dissection(&m.pattern, None).unwrap());
    let amd = candidate(Ordering::Amd);
    let row = |c: &Cholesky| {
        let (flops, pairs) = (c.factor_flops().unwrap(), c.update_pairs().unwrap());
        assert_eq!(
            c.factor_cost(),
            Some(flops + UPDATE_PAIR_COST * pairs as f64)
        );
        (c.factor_nnz(), pairs, c.factor_cost().unwrap())
    };
    let (chosen, s, e, a) = (row(&factor), row(&on_shapes), row(&on_equations), row(&amd));
    println!(
        "(nnz(L), pairs, cost): chosen {chosen:?}, ND shapes {s:?}, ND equations {e:?}, AMD {a:?}"
    );
    assert_eq!(chosen.2, s.2.min(e.2).min(a.2));
    // The equation graph still fills least: the choice is not by entries.
    assert!(e.0 < chosen.0, "{e:?} {chosen:?}");
    // Every supernode but the last updates at least one other.
    let supernodes = |c: &Cholesky| c.supernodes().unwrap();
    for c in [&factor, &on_shapes, &on_equations] {
        let (k, pairs) = (supernodes(c), c.update_pairs().unwrap());
        assert!(pairs >= k - 1 && pairs <= k * (k - 1) / 2, "{k} {pairs}");
    }
}

/// The exact near-front field's model on `mesh` (its boundary values),
/// geometric R = 0.2 with `blending`, with mass: the lumping tests'.
fn geometric_model_with_mass(mesh: &TetMesh, blending: Blending) -> Model {
    exact_model(
        &Front::new(),
        mesh,
        FrontMode::Tip,
        Some(0.2),
        blending,
        true,
    )
}

/// Tet10 with the ramp: a Heaviside function is N_k (1 − R_k) ψ_k, so its
/// lumped mass is (1 − R_k)² and its u–a coupling (1 − R_k) times the
/// plain function's (the lumping's ψ² and ψ times N_k's share). Compared
/// node by node with the same mesh and cut without the ramp, at the nodes
/// with 0 < R_k < 1 (mid-nodes between a vertex in I and a blending one,
/// R_k = ½) and R_k = 0. Before, the lumped masses left the factor out
/// (equal to the plain ones: 4× too heavy where R_k = ½) while the loads
/// and consistent masses, from the evaluated functions, had it.
#[test]
fn ramped_tet10_heaviside_functions_lump_their_ramp() {
    let mesh = mesh(4, ElementKind::Tet10, 0.0);
    let build = |blending| geometric_model_with_mass(&mesh, blending);
    let (plain, ramped) = (build(Blending::None), build(Blending::Ramp));
    let (pc, rc) = (plain.cut.as_ref().unwrap(), ramped.cut.as_ref().unwrap());
    let (pm, rm) = (
        plain.lumped_mass.as_ref().unwrap(),
        ramped.lumped_mass.as_ref().unwrap(),
    );
    let (pcpl, rcpl) = (
        plain.lumped_coupling.as_ref().unwrap(),
        ramped.lumped_coupling.as_ref().unwrap(),
    );
    let edges = mid_edges(&mesh);
    let nn = mesh.n_nodes();
    let (mut halves, mut zeros) = (0, 0);
    for (i, edge) in edges.iter().enumerate() {
        let (Some(jp), Some(jr)) = (pc.enriched[i], rc.enriched[i]) else {
            continue;
        };
        let r = match *edge {
            Some((a, b)) => 0.5 * (rc.ramp_at(a) + rc.ramp_at(b)),
            None => rc.ramp_at(i),
        };
        let c = 1.0 - r;
        let (mp, mr) = (pm[nn + jp], rm[nn + jr]);
        let (cp, cr) = (pcpl[jp], rcpl[jr]);
        assert!(
            (mr - c * c * mp).abs() <= 1e-9 * mp.abs(),
            "node {i} (R = {r}): lumped {mr:e} against {:e}",
            c * c * mp
        );
        assert!(
            (cr - c * cp).abs() <= 1e-9 * cp.abs().max(mp.abs()),
            "node {i} (R = {r}): coupling {cr:e} against {:e}",
            c * cp
        );
        if r == 0.5 {
            halves += 1;
        } else if r == 0.0 {
            zeros += 1;
        }
    }
    println!("compared {halves} Heaviside nodes with R = ½ and {zeros} with R = 0");
    assert!(halves > 0 && zeros > 0, "{halves} {zeros}");
}

/// Tet4 with the ramp: a Heaviside function is (1 − R(x)) ψ N_k, and the
/// lumped mass takes the seed's row-sum lumping of ψ N_k (ρ ψ² ∫N_k per
/// cell) with the ramp inside: ρ ψ² ∫h² N_k, and the u–a coupling ρ ψ ∫h N_k
/// (h = 1 − R). Compared node by node with those integrals over the
/// model's own field points. Before, the lumped masses left h out (those of
/// ψ N_k: up to 4× the ramped ones here) while the loads and consistent
/// masses had it.
#[test]
fn ramped_tet4_heaviside_functions_lump_their_ramp() {
    use xfem_cut::mesh::barycentric;
    let mesh = mesh(8, ElementKind::Tet4, 0.0);
    let model = geometric_model_with_mass(&mesh, Blending::Ramp);
    let cut = model.cut.as_ref().unwrap();
    let nn = mesh.n_nodes();
    let rho = MATERIAL.density;
    let (mut mass, mut coupling, mut plain) = (
        vec![0.0; cut.n_enriched],
        vec![0.0; cut.n_enriched],
        vec![0.0; cut.n_enriched],
    );
    for e in 0..mesh.n_elements() {
        let v = mesh.vertices(e);
        let points = mesh.vertex_points(e);
        for (x, w, side) in model.field_points(e) {
            if side == 0 {
                continue;
            }
            let l = barycentric(&points, &x).unwrap();
            let r: f64 = (0..4).filter(|&a| cut.ramp[v[a]]).map(|a| l[a]).sum();
            let h = 1.0 - r;
            for (a, &k) in v.iter().enumerate() {
                if let Some(j) = cut.enriched[k] {
                    let p = f64::from(side - cut.node_side[k]) / 2.0;
                    mass[j] += rho * w * p * p * h * h * l[a];
                    coupling[j] += rho * w * p * h * l[a];
                    plain[j] += rho * w * p * p * l[a];
                }
            }
        }
    }
    let lumped = model.lumped_mass.as_ref().unwrap();
    let lumped_coupling = model.lumped_coupling.as_ref().unwrap();
    let scale = plain.iter().cloned().fold(0.0, f64::max);
    let mut ramped = 0;
    for j in 0..cut.n_enriched {
        assert!(
            (lumped[nn + j] - mass[j]).abs() <= 1e-9 * scale,
            "Heaviside {j}: lumped {:e} against {:e} (without h {:e})",
            lumped[nn + j],
            mass[j],
            plain[j]
        );
        assert!(
            (lumped_coupling[j] - coupling[j]).abs() <= 1e-9 * scale,
            "Heaviside {j}: coupling {:e} against {:e}",
            lumped_coupling[j],
            coupling[j]
        );
        if mass[j] < 0.9 * plain[j] {
            ramped += 1;
        }
    }
    println!(
        "{} Heaviside nodes, {ramped} lighter than without h by 10 % or more",
        cut.n_enriched
    );
    assert!(ramped > 0);
}

/// The stress suite's `front-near` bar (1 × 1 × 2, 4 × 4 × 8 hexes; here
/// only the bottom clamped, gravity), its front at x = 0.5 + δ h inside the
/// face z = 1.125 or the node line z = 1 + δ h, geometric R = 0.3, Tet4,
/// the ramp forced (a case takes it from R = 2.5 median edges on,
/// `cut::RAMP_SPAN`, here 0.79): the Jacobi-scaled
/// condition estimate with the ramp against the plain blending's.
/// Measured: 1.06e4 / 8.84e3 (face), 1.76e4 / 1.85e4 and 1.39e4 / 1.20e4
/// (node line, δ = 1e-3, 1e-9). With all four branch functions on the ring
/// and F₀, F₁ of one node per region prescribed (before; still Tet10's
/// ramp, an option): 1.03e9 on the face. Asserted: ≤ 10× the plain
/// blending's.
#[test]
fn the_ramp_keeps_the_condition_of_the_plain_blending() {
    use xfem_cut::study::stress::condition_estimate;
    let h = 0.25;
    let rows = [(1.125, 1e-3), (1.0, 1e-3), (1.0, 1e-9)];
    for (z0, delta) in rows {
        let zc = if z0 == 1.0 { z0 + delta * h } else { z0 };
        let patch = PlanarPatch {
            origin: Point3::new(-0.5, -0.5, zc),
            u: Vector3::new(0.0, 2.0, 0.0),
            v: Vector3::new(1.0 + delta * h, 0.0, 0.0),
        };
        let mesh = common::bar([4, 4, 8]);
        let kappa = |blending| {
            let input = CutInput {
                blending,
                ..CutInput::tip(&patch, xfem_cut::cut::DEFAULT_SNAP, Some(0.3))
            };
            let cut = setup_cut(&mesh, &[input]).unwrap();
            let g = Vector3::new(0.0, 0.0, -9.81);
            let model =
                common::model(&mesh, Some(cut), Formulation::Linear, g, None, false).unwrap();
            let d = common::solve(&model);
            condition_estimate(&model, &d).expect("an estimate").1
        };
        let (plain, ramp) = (kappa(Blending::None), kappa(Blending::Ramp));
        println!("z {zc}: Jacobi-scaled κ {plain:.2e} plain, {ramp:.2e} ramp");
        assert!(ramp <= 10.0 * plain, "z {zc}: {ramp:e} vs {plain:e}");
    }
}

/// A scene's text in units `l`, `t` ([`scenes_in_units`]).
type SceneInUnits = fn(f64, f64) -> String;

/// Two dynamic scenes in units scaled from SI: every length × `l`, every
/// time × `t` (Young's modulus / l, density × t² / l³, gravity × l / t²,
/// Rayleigh's mass factor / t and stiffness factor × t). A plane with its
/// front inside Tet10 elements, and a Tet4 blade with a geometric tip
/// front sweeping while the top face is moved; corotational dynamics on
/// the default lagged factor, lumped mass, Rayleigh damping.
fn scenes_in_units() -> [(&'static str, SceneInUnits); 2] {
    fn fmt(v: [f64; 3], s: f64) -> String {
        format!("[{:?}, {:?}, {:?}]", v[0] * s, v[1] * s, v[2] * s)
    }
    fn tet10(l: f64, t: f64) -> String {
        format!(
            "name = \"units\"\n[body]\nbox = [[0.0, 0.0, 0.0], {}]\nlevels = [[2, 2, 5]]\n\
             element = \"tet10\"\n[material]\nyoung = {:?}\npoisson = 0.3\ndensity = {:?}\n\
             [[cut]]\norigin = {}\nu = {}\nv = {}\n\
             [[fix]]\nmin = [-inf, -inf, 0.0]\nmax = [inf, inf, 0.0]\ndisplacement = [0.0, 0.0, 0.0]\n\
             [gravity]\nacceleration = {}\n[analysis]\ntype = \"dynamic\"\n\
             formulation = \"corotational\"\ndt = {:?}\nsteps = 14\n\
             rayleigh = {{ mass = {:?}, stiffness = {:?} }}\n[[probe]]\npoints = [{}, {}, {}]\n",
            fmt([0.05, 0.03, 0.1], l),
            3e5 / l,
            1000.0 * t * t / (l * l * l),
            fmt([0.0244, -0.0028, 0.0622], l),
            fmt([0.0545, -0.0013, -0.0226], l),
            fmt([-0.00005, 0.0365, 0.0015], l),
            fmt([-2.7, -4.6, -8.4], l / (t * t)),
            0.01 * t,
            2.0 / t,
            0.001 * t,
            fmt([0.0353, 0.0097, 0.0886], l),
            fmt([0.0084, 0.0178, 0.0385], l),
            fmt([0.0492, 0.0042, 0.0880], l),
        )
    }
    fn blade(l: f64, t: f64) -> String {
        format!(
            "name = \"units\"\n[body]\nbox = [[0.0, 0.0, 0.0], {}]\nlevels = [[3, 3, 5]]\n\
             element = \"tet4\"\n[material]\nyoung = {:?}\npoisson = 0.0\ndensity = {:?}\n\
             [[cut]]\nblade = [{}, {}]\ntravel = {}\nstart = {:?}\nend = {:?}\ntip_radius = {:?}\n\
             [[fix]]\nmin = [-inf, -inf, 0.0]\nmax = [inf, inf, 0.0]\ndisplacement = [0.0, 0.0, 0.0]\n\
             [[fix]]\nmin = [-inf, -inf, {:?}]\nmax = [inf, inf, {:?}]\ndisplacement = {}\n\
             [gravity]\nacceleration = {}\n[analysis]\ntype = \"dynamic\"\n\
             formulation = \"corotational\"\ndt = {:?}\nsteps = 11\n\
             rayleigh = {{ mass = {:?}, stiffness = {:?} }}\n[[probe]]\npoints = [{}, {}, {}]\n",
            fmt([0.1, 0.06, 0.1], l),
            1e3 / l,
            1000.0 * t * t / (l * l * l),
            fmt([0.0182, -0.00065, 0.0647], l),
            fmt([0.0294, 0.0177, 0.0845], l),
            fmt([0.0255, 0.0070, -0.0193], l),
            0.02 * t,
            0.088 * t,
            0.024 * l,
            0.1 * l,
            0.1 * l,
            fmt([-0.00024, 0.00021, -0.00043], l),
            fmt([-6.7, 3.0, 5.6], l / (t * t)),
            0.01 * t,
            2.0 / t,
            0.001 * t,
            fmt([0.0375, 0.0076, 0.0678], l),
            fmt([0.0560, 0.0015, 0.0995], l),
            fmt([0.0821, 0.0007, 0.0946], l),
        )
    }
    [("Tet10 plane", tet10), ("Tet4 blade", blade)]
}

/// The probes of a scene's text (its files relative to the working directory).
fn scene_probes(text: &str) -> Vec<nalgebra::Vector3<f64>> {
    use xfem_cut::run::{probe_values, solve_scene};
    use xfem_cut::scene::Scene;
    let scene = Scene::parse(text, std::path::Path::new("units.toml")).unwrap();
    let result = solve_scene(&scene, 0, None, false).unwrap();
    probe_values(&scene, &result).unwrap()
}

/// A scene written in another unit of length ([`scenes_in_units`] with
/// l = s: the same body in mm instead of m for s = 1000) has every
/// displacement × s. With s a power of two the arithmetic scales exactly,
/// so the solutions agree to the bit, Newton's stopping decisions included.
/// They did not while the branch functions were √r: a tip DOF was a length
/// over √length, the Euclidean norms of Newton's relative residual and of
/// Anderson's mixing weighed the tip rows by √s against the others, and
/// Newton stopped at another iterate (s = 1024: 3.4e-8 of the largest
/// displacement in the Tet10 scene, 6.1e-10 in the Tet4 blade's). Over √h
/// ([`CutSetup::tip_scale`]) the tip DOFs are lengths like the others.
#[test]
fn a_scene_in_millimetres_solves_as_in_metres() {
    let s = 1024.0;
    for (name, scene) in scenes_in_units() {
        let metres = scene_probes(&scene(1.0, 1.0));
        let millimetres = scene_probes(&scene(s, 1.0));
        let largest = metres.iter().fold(0.0f64, |m, u| m.max(u.amax()));
        let worst = metres
            .iter()
            .zip(&millimetres)
            .fold(0.0f64, |m, (a, b)| m.max((a - b / s).amax()));
        println!(
            "{name}: largest displacement {largest:.3e}, in mm / {s} off by {:.1e}",
            worst / largest
        );
        assert!(largest > 0.0);
        assert!(worst <= 1e-12 * largest, "{name}: {:e}", worst / largest);
    }
}

/// The same scenes in another unit of time ([`scenes_in_units`] with t = s,
/// s = 1024: times in ~ms) give the same displacements, to the bit (every
/// operation scales by a power of two). They differed in the last bits
/// (3.5e-13 of the largest displacement in the Tet10 scene) where Rayleigh's stiffness
/// damping took the gradient of the velocity as F(v) − I, rounded against
/// the identity (`assembly::Gradient::Vector`).
#[test]
fn a_scene_in_milliseconds_solves_as_in_seconds() {
    let s = 1024.0;
    for (name, scene) in scenes_in_units() {
        let seconds = scene_probes(&scene(1.0, 1.0));
        let milliseconds = scene_probes(&scene(1.0, s));
        let largest = seconds.iter().fold(0.0f64, |m, u| m.max(u.amax()));
        let worst = seconds
            .iter()
            .zip(&milliseconds)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).amax()));
        println!(
            "{name}: largest displacement {largest:.3e}, in ms off by {:.1e}",
            worst / largest
        );
        assert!(largest > 0.0);
        assert_eq!(worst, 0.0, "{name}: {:e}", worst / largest);
    }
}

/// What limits Tet10's geometric rates (`examples/blending_zones.rs`): the
/// field's nodal interpolant (`WilliamsFront::interpolant`) is the field
/// itself in the elements all of whose vertices are tip-enriched, and in the
/// one-element blending layer, where the partial partition of unity
/// Σ_{k∈I} λ_k (gradient ~ 1/h) multiplies the branch functions, its energy
/// error converges at about 1.5, not the 2 of quadratic elements (measured
/// 1.43 from n = 8 to 12, 1.40 to 16). The one-element ramp of corrected
/// X-FEM, linear too, leaves that interpolant unchanged: the two spaces hold
/// the same function (their Galerkin solutions differ: the ramp frees the
/// ring's DOFs).
#[test]
fn tet10_blending_layer_interpolant_converges_at_about_one_and_a_half() {
    let fr = Front::new();
    let patch = fr.patch();
    let lame = Lame::from(MATERIAL);
    // Per zone (all vertices in I, some, none): the interpolant's relative
    // energy error; and its values at sampled points.
    let zones = |n: usize, blending: Blending| -> ([f64; 3], Vec<f64>) {
        let mesh = mesh(n, ElementKind::Tet10, 0.0);
        let input = CutInput {
            blending,
            ..CutInput::tip(&patch, 1e-3, Some(0.2))
        };
        let cut = setup_cut(&mesh, &[input]).unwrap();
        let in_i = |i: usize| {
            if cut.ramp.is_empty() {
                cut.tip[i].is_some()
            } else {
                cut.ramp[i]
            }
        };
        let kinds: Vec<usize> = (0..mesh.n_elements())
            .map(
                |e| match mesh.vertices(e).iter().filter(|&&i| in_i(i)).count() {
                    4 => 0,
                    0 => 2,
                    _ => 1,
                },
            )
            .collect();
        let fixed = boundary_values(&fr, &mesh, &cut);
        let model = xfem_cut::study::exact::linear_model(mesh, Some(cut), fixed).unwrap();
        let cut = model.cut.as_ref().unwrap();
        let d = fr.interpolant(&model.mesh, cut, model.n_shape);
        let (mut err, mut norm) = ([0.0; 3], 0.0);
        for (e, &zone) in kinds.iter().enumerate() {
            for (x, w, side) in model.field_points(e) {
                let (_, gi) = model.field_at(&d, e, &x, side);
                let (_, g) = fr.exact(&x, side);
                err[zone] += w * xfem_cut::study::exact::energy_density(&(gi - g), &lame);
                norm += w * xfem_cut::study::exact::energy_density(&g, &lame);
            }
        }
        let sampled: Vec<f64> = (0..model.mesh.n_elements())
            .step_by(7)
            .flat_map(|e| {
                model
                    .field_points(e)
                    .into_iter()
                    .take(3)
                    .map(|(x, _, side)| model.field_at(&d, e, &x, side).0.norm())
                    .collect::<Vec<_>>()
            })
            .collect();
        (err.map(|e| (e / norm).sqrt()), sampled)
    };
    let (coarse, _) = zones(8, Blending::None);
    let (fine, plain) = zones(12, Blending::None);
    eprintln!("interpolant energy errors (enriched, blending, standard): n = 8 {coarse:?}, n = 12 {fine:?}");
    assert!(
        coarse[0] < 1e-10 && fine[0] < 1e-10,
        "exact where every vertex is in I"
    );
    let order = (coarse[1] / fine[1]).ln() / 1.5f64.ln();
    assert!(
        (1.2..1.7).contains(&order),
        "blending layer: order {order:.2}"
    );
    // The ramp's space holds the same interpolant.
    let (ramped, ramped_values) = zones(12, Blending::Ramp);
    let largest = fine.iter().fold(0.0f64, |m, &e| m.max(e));
    for (a, b) in ramped.iter().zip(&fine) {
        assert!(
            (a - b).abs() <= 1e-9 * largest,
            "{ramped:?} against {fine:?}"
        );
    }
    for (a, b) in ramped_values.iter().zip(&plain) {
        assert!((a - b).abs() <= 1e-12 * b.max(1.0));
    }
}

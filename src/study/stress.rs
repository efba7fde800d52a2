//! The stability stress suite (`xfem-cut stress`): scenes at the edges of the
//! method's range, each with a pass/fail criterion stated next to what was
//! measured. Every scene is built from case-file text, so the suite goes
//! through the same public path as a user's scene.

use crate::assembly::{evaluate, Request, Rotations, Workspace};
use crate::corotation::polar_rotation;
use crate::dynamics::{Energies, Newmark};
use crate::io::IoError;
use crate::locate::Locator;
use crate::model::{Formulation, Model};
use crate::run::{evaluate_at, probe_values, solve_scene, RunResult};
use crate::scene::{Analysis, Scene};
use crate::solve::Cholesky;
use crate::study::fixtures::spin_upper_side;
use crate::study::StudyError;
use nalgebra::{Matrix3, Point3, Vector3};
use std::path::Path;
use std::time::Instant;

/// One line of the stress table (`stress.csv`: test,setting,measured,criterion,pass,seconds).
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct StressRow {
    /// The family (what is stressed).
    pub test: String,
    /// The setting within the family.
    pub setting: String,
    /// What was measured, in words and numbers.
    pub measured: String,
    /// The pass criterion.
    pub criterion: String,
    pub pass: bool,
    /// Wall time of the run (s).
    #[serde(serialize_with = "millis")]
    pub seconds: f64,
}

/// A family of stress tests: it runs its scenes and judges them.
type Family = fn() -> Vec<StressRow>;

/// The families of the suite, by short name.
pub const FAMILIES: [(&str, Family); 8] = [
    ("near-node", cut_near_nodes),
    ("front-near", front_near_mesh),
    ("poisson", poisson_ratio),
    ("dt", time_step),
    ("long", long_undamped),
    ("fragment", freed_fragment),
    ("rotation", large_rotation),
    ("inverted", inverted_element),
];

/// Runs the families whose name contains `only` (all if empty); `progress`
/// hears each row as it is done.
pub fn run_suite(only: &str, mut progress: impl FnMut(&StressRow)) -> Vec<StressRow> {
    let mut rows = Vec::new();
    for (_, family) in FAMILIES.iter().filter(|(name, _)| name.contains(only)) {
        for row in family() {
            progress(&row);
            rows.push(row);
        }
    }
    rows
}

/// Writes the rows as CSV (whole or not at all); fields with commas are quoted.
pub fn write_csv(path: &Path, rows: &[StressRow]) -> Result<(), IoError> {
    crate::io::csv::write_rows(path, rows)
}

/// Reads what [`write_csv`] wrote.
pub fn read_csv(path: &Path) -> Result<Vec<StressRow>, IoError> {
    crate::io::csv::read_rows(path, false)
}

/// Seconds with three decimals.
fn millis<S: serde::Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(&format_args!("{x:.3}"))
}

/// Estimates of the 2-norm condition number of the free system's tangent at
/// `d`, as (κ(K), κ(D^-½ K D^-½)) with D = diag K: power iteration for
/// λ_max, inverse iteration (with the Cholesky factor) for λ_min, 30 each.
/// Lower bounds, tight when the extreme eigenvalues are well separated; cheap
/// next to a solve. The scaled one is what a Jacobi-preconditioned CG sees and
/// what limits a direct solve's accuracy; tiny enriched supports inflate only κ(K).
pub fn condition_estimate(model: &Model, d: &[f64]) -> Option<(f64, f64)> {
    let n = model.n_free;
    if n == 0 {
        return None;
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
            update_rotations: model.formulation == Formulation::Corotational,
            exact_tangent: false,
        },
    );
    let mut chol = Cholesky::new(&model.pattern).ok()?;
    chol.factorize(&k).ok()?;
    let diag: Vec<f64> = (0..n)
        .map(|i| model.pattern.position(i, i).map_or(f64::NAN, |p| k[p]))
        .collect();
    let normalise = |x: &mut [f64]| {
        let s = x.iter().map(|v| v * v).sum::<f64>().sqrt();
        x.iter_mut().for_each(|v| *v /= s);
        s
    };
    // Spectrum ends of S K S with S = diag(scale).
    let mut kappa = |scale: &dyn Fn(usize) -> f64| -> f64 {
        // A start vector with a component along every eigenvector (almost surely).
        let start: Vec<f64> = (0..n)
            .map(|i| 1.0 + 0.5 * (i as f64 * 0.618).sin())
            .collect();
        let mut x = start.clone();
        normalise(&mut x);
        let mut y = vec![0.0; n];
        let mut lambda_max = 0.0;
        for _ in 0..30 {
            let sx: Vec<f64> = (0..n).map(|i| scale(i) * x[i]).collect();
            y.iter_mut().for_each(|v| *v = 0.0);
            model.pattern.sym_mul_add(&k, &sx, &mut y);
            (0..n).for_each(|i| y[i] *= scale(i));
            lambda_max = normalise(&mut y);
            std::mem::swap(&mut x, &mut y);
        }
        let mut x = start;
        normalise(&mut x);
        let mut mu = 0.0;
        for _ in 0..30 {
            (0..n).for_each(|i| x[i] /= scale(i));
            chol.solve_in_place(&mut x);
            (0..n).for_each(|i| x[i] /= scale(i));
            mu = normalise(&mut x);
        }
        lambda_max * mu
    };
    let plain = kappa(&|_| 1.0);
    let scaled = kappa(&|i| 1.0 / diag[i].sqrt());
    (plain.is_finite() && scaled.is_finite()).then_some((plain, scaled))
}

fn parse(name: &str, text: &str) -> Scene {
    // The texts below are ours: a parse failure is a bug of the suite, not user input.
    Scene::parse(text, Path::new(&format!("stress/{name}.toml")))
        .unwrap_or_else(|e| panic!("stress scene {name}: {e}"))
}

fn row(
    test: &str,
    setting: String,
    measured: String,
    criterion: &str,
    pass: bool,
    t: Instant,
) -> StressRow {
    StressRow {
        test: test.into(),
        setting,
        measured,
        criterion: criterion.into(),
        pass,
        seconds: t.elapsed().as_secs_f64(),
    }
}

/// The row of a run that failed with `e`: measured "error: {e}", not passed.
fn failed(
    test: &str,
    setting: String,
    criterion: &str,
    e: &dyn std::fmt::Display,
    t: Instant,
) -> StressRow {
    row(test, setting, format!("error: {e}"), criterion, false, t)
}

fn finite(r: &RunResult) -> bool {
    r.d.iter().all(|v| v.is_finite())
}

fn fmt_kappa(k: Option<(f64, f64)>) -> String {
    k.map_or("n/a".into(), |(k, s)| {
        format!("{k:.1e} (Jacobi-scaled {s:.1e})")
    })
}

/// The 1 × 1 × 2 bar (2 × 2 × 4 hexes, h = 0.5) cut across at z = `zc`.
fn bar(zc: f64, snap: Option<f64>, extra: &str) -> Scene {
    bar_of("tet4", zc, snap, extra)
}

/// [`bar`] of `element`s.
fn bar_of(element: &str, zc: f64, snap: Option<f64>, extra: &str) -> Scene {
    let snap = snap.map_or(String::new(), |s| format!("snap = {s:e}\n"));
    parse(
        "bar",
        &format!(
            r#"name = "bar"
[body]
box = [[0.0, 0.0, 0.0], [1.0, 1.0, 2.0]]
levels = [[2, 2, 4]]
element = "{element}"
[material]
young = 1.0e4
poisson = 0.3
density = 1000.0
[[cut]]
origin = [-0.5, -0.5, {zc}]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
{snap}{extra}"#
        ),
    )
}

const BOTTOM: &str = "[[fix]]\nmin = [-inf, -inf, 0.0]\nmax = [inf, inf, 0.0]\n";
const TOP: &str = "[[fix]]\nmin = [-inf, -inf, 2.0]\nmax = [inf, inf, 2.0]\n";
const GRAVITY_DOWN: &str = "[gravity]\nacceleration = [0.0, 0.0, -9.81]\n";

/// Cut planes at δ·h from a node layer, δ = 0 … 1e-12 … 1e-2, with the default
/// snapping (ε = 1e-4 h) and without it, Tet4 and Tet10. The two bars'
/// lengths change by δh, so their displacement (∝ L² under gravity) changes
/// by ≈ 2δh/L = δ relative: the bound is 3δ (+1e-10 for round-off).
/// Tet10's condition grows like 1/δ² once the plane leaves the layer (the
/// slivers beside it: [`crate::cut::SLIVER_LAMBDA`], whose drop a cut
/// through the bar cannot take); without snapping it no longer factorises
/// at δ = 1e-9, so its rows without snapping stop at 1e-6.
fn cut_near_nodes() -> Vec<StressRow> {
    const TEST: &str = "cut near a node layer";
    let h = 0.5;
    let extra = format!("{BOTTOM}{TOP}{GRAVITY_DOWN}[analysis]\ntype = \"static\"\n");
    // Sample points away from the cut (|z − 1| > 0.02 ≫ δh).
    let mut points = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            for k in 0..40 {
                let z = 0.025 + 0.05 * k as f64;
                if (z - 1.0).abs() > 0.02 {
                    points.push(Point3::new(0.1 + 0.2 * i as f64, 0.1 + 0.2 * j as f64, z));
                }
            }
        }
    }
    let field = |r: &RunResult| -> Vec<Vector3<f64>> {
        let loc = Locator::new(&r.model.mesh);
        points
            .iter()
            .map(|p| evaluate_at(&r.model, &loc, &r.d, p).unwrap_or(Vector3::repeat(f64::NAN)))
            .collect()
    };
    let mut rows = Vec::new();
    for (element, mark) in [("tet4", ""), ("tet10", ", tet10")] {
        let Ok(base) = solve_scene(&bar_of(element, 1.0, None, &extra), 0, None, false) else {
            let t = Instant::now();
            rows.push(row(
                TEST,
                format!("δ = 0{mark}"),
                "solve failed".into(),
                "runs",
                false,
                t,
            ));
            continue;
        };
        let u0 = field(&base);
        let scale = u0.iter().map(|u| u.norm()).fold(0.0, f64::max);
        let unsnapped: &[f64] = if element == "tet4" {
            &[1e-12, 1e-9, 1e-6, 1e-3]
        } else {
            &[1e-6, 1e-3]
        };
        for (snap, deltas) in [
            (None, &[0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1e-2][..]),
            (Some(0.0), unsnapped),
        ] {
            for &delta in deltas {
                let t = Instant::now();
                let zc = 1.0 + delta * h;
                let setting = format!(
                    "δ = {delta:e} h{}{mark}",
                    if snap.is_some() {
                        ", snapping off"
                    } else {
                        ", ε = 1e-4 h"
                    }
                );
                let criterion = "finite; ‖u − u(δ=0)‖∞ ≤ 3δ‖u‖∞ + 1e-10";
                match solve_scene(&bar_of(element, zc, snap, &extra), 0, None, false) {
                    Ok(r) => {
                        let u = field(&r);
                        let diff = u.iter().zip(&u0).map(|(a, b)| (a - b).norm()).fold(
                            0.0,
                            |m: f64, v| if v.is_nan() { f64::INFINITY } else { m.max(v) },
                        ) / scale;
                        let kappa = condition_estimate(&r.model, &r.d);
                        let pass = finite(&r) && diff <= 3.0 * delta + 1e-10;
                        rows.push(row(
                            TEST,
                            setting,
                            format!(
                                "rel. difference {diff:.1e}; enriched nodes {}; κ ≈ {}",
                                r.model.n_enriched(),
                                fmt_kappa(kappa)
                            ),
                            criterion,
                            pass,
                            t,
                        ));
                    }
                    Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
                }
            }
        }
    }
    rows
}

/// The seed's half-cut beam (level `div`), gravity along x, bottom clamped.
fn seed_beam(
    element: &str,
    poisson: f64,
    div: [usize; 3],
    probe: [f64; 3],
    analysis: &str,
) -> Scene {
    parse(
        "seed_beam",
        &format!(
            r#"name = "seed_beam"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.06, 0.2]]
levels = [[{}, {}, {}]]
element = "{element}"
[material]
young = 3.0e5
poisson = {poisson}
density = 1070.0
[[cut]]
origin = [0.0, 0.0, 0.1]
u = [0.015, 0.0, 0.0]
v = [0.0, 0.06, 0.0]
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
[[probe]]
points = [[{}, {}, {}]]
{analysis}"#,
            div[0], div[1], div[2], probe[0], probe[1], probe[2]
        ),
    )
}

/// The bar of [`front_near_mesh`]: 1 × 1 × 2, 4 × 4 × 8 hexes (h = 0.25),
/// both ends clamped, gravity; the cut plane z = `zc` from x = 0 to its
/// front x = `xf` (tip-enriched; `radius` a `tip_radius` line or empty).
fn front_bar(zc: f64, xf: f64, radius: &str, element: &str) -> Scene {
    parse(
        "front_bar",
        &format!(
            r#"name = "front_bar"
[body]
box = [[0.0, 0.0, 0.0], [1.0, 1.0, 2.0]]
levels = [[4, 4, 8]]
element = "{element}"
[material]
young = 1.0e4
poisson = 0.3
density = 1000.0
[[cut]]
origin = [-0.5, -0.5, {zc}]
u = [0.0, 2.0, 0.0]
v = [{v}, 0.0, 0.0]
front = "tip"
{radius}
{BOTTOM}{TOP}{GRAVITY_DOWN}[analysis]
type = "static"
"#,
            v = xf + 0.5
        ),
    )
}

/// A crack front (tip enrichment, topological and within 0.3 of the front)
/// δ·h from the mesh, δ = 1e-3 … 1e-12: beside a node line (the cut plane
/// δh above a node layer, the front δh beside a line of its nodes and
/// edges), beside a face (the cut plane mid-element, the front δh from the
/// face plane x = 0.5), and beside interior faces (the front on the centre
/// line of a row of hexahedra, which lies in faces between their tets, the
/// plane δh below it). The tip functions of nodes almost on the front are
/// almost zero and cells almost degenerate: the solve must stay finite and
/// accurate (relative residual), the front must keep its branch functions
/// (tip-enriched nodes), and the system's condition is reported. Where the
/// front lies on element faces, the elements behind it that it runs along
/// hold it (`cut::setup_cut`); beside interior faces, for δ between 1e-12
/// and 1e-9 of the largest element, neither the elements behind nor those
/// ahead held it before 5da8b11 (no tip node: the topological δ = 1e-9
/// rows, Tet4 and Tet10, failed).
fn front_near_mesh() -> Vec<StressRow> {
    const TEST: &str = "front near nodes, edges, faces";
    // 1 × 1 × 2 bar, 4 × 4 × 8 hexes (h = 0.25), both ends clamped, gravity;
    // Tet4, then Tet10 (its rows marked so).
    let h = 0.25;
    let criterion = "finite; relative residual ≤ 1e-8; tip-enriched nodes";
    let mut rows = Vec::new();
    for (element, mark) in [("tet4", ""), ("tet10", ", tet10")] {
        for (place, zc0, xf0) in [
            ("node line", 1.0, 0.5),
            ("face", 1.125, 0.5),
            ("interior faces", 1.125, 0.625),
        ] {
            for (enrichment, radius) in [("topological", ""), ("R = 0.3", "tip_radius = 0.3")] {
                for delta in [1e-3, 1e-6, 1e-9, 1e-12] {
                    let t = Instant::now();
                    let (zc, xf) = match place {
                        "node line" => (zc0 + delta * h, xf0 + delta * h),
                        "face" => (zc0, xf0 + delta * h),
                        _ => (zc0 - delta * h, xf0),
                    };
                    let setting = format!("{place}, δ = {delta:e} h, {enrichment}{mark}");
                    match solve_scene(&front_bar(zc, xf, radius, element), 0, None, false) {
                        Ok(r) => {
                            let kappa = condition_estimate(&r.model, &r.d);
                            let (heaviside, tip) = r
                                .model
                                .cut
                                .as_ref()
                                .map_or((0, 0), |c| (c.n_heaviside(), c.n_tip()));
                            rows.push(row(
                                TEST,
                                setting,
                                format!(
                                "{tip} tip, {heaviside} Heaviside nodes; residual {:.1e}; κ ≈ {}",
                                r.residual,
                                fmt_kappa(kappa)
                            ),
                                criterion,
                                finite(&r) && r.residual <= 1e-8 && tip > 0,
                                t,
                            ));
                        }
                        Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
                    }
                }
            }
        }
    }
    rows
}

/// ν from 0.3 to 0.499 on the cut beam under gravity, Tet4 and Tet10: the
/// solve must stay accurate (residual) while Tet4 locks (tip deflection
/// against Tet10's) and the system's condition grows like λ/μ.
fn poisson_ratio() -> Vec<StressRow> {
    const TEST: &str = "Poisson's ratio";
    let analysis = "[gravity]\nacceleration = [9.81, 0.0, 0.0]\n[analysis]\ntype = \"static\"\n";
    let mut rows = Vec::new();
    for nu in [0.3, 0.4, 0.45, 0.49, 0.499] {
        let mut tips = [0.0; 2];
        for (k, element) in ["tet10", "tet4"].into_iter().enumerate() {
            let t = Instant::now();
            let scene = seed_beam(element, nu, [2, 4, 13], [0.03, 0.03, 0.2], analysis);
            let criterion = "finite; relative residual ≤ 1e-10";
            let setting = format!("ν = {nu}, {element}");
            match solve_scene(&scene, 0, None, false) {
                Ok(r) => {
                    let tip = probe_values(&scene, &r).map_or(f64::NAN, |v| v[0].x);
                    tips[k] = tip;
                    let kappa = condition_estimate(&r.model, &r.d);
                    let locking = if k == 1 {
                        format!("; tip / Tet10 tip {:.3}", tips[1] / tips[0])
                    } else {
                        String::new()
                    };
                    rows.push(row(
                        TEST,
                        setting,
                        format!(
                            "tip ux {:.3} mm{locking}; residual {:.1e}; κ ≈ {}",
                            tip * 1e3,
                            r.residual,
                            fmt_kappa(kappa)
                        ),
                        criterion,
                        finite(&r) && r.residual <= 1e-10,
                        t,
                    ));
                }
                Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
            }
        }
    }
    rows
}

/// The cut beam's top-right edge bent over within `ramp`, corotational
/// Newmark with lumped X-FEM mass, for `time` seconds at step `dt`.
fn bend_dynamic(dt: f64, time: f64, rayleigh: (f64, f64), formulation: &str) -> Scene {
    let steps = (time / dt).round() as usize;
    let every = (steps / 400).max(1);
    seed_beam(
        "tet4",
        0.35,
        [2, 4, 13],
        [0.0, 0.03, 0.2],
        &format!(
            r#"[[fix]]
min = [0.03, -inf, 0.2]
max = [0.03, inf, 0.2]
displacement = [0.03, 0.0, -0.015]
[analysis]
type = "dynamic"
formulation = "{formulation}"
dt = {dt:e}
steps = {steps}
rayleigh = {{ mass = {}, stiffness = {} }}
ramp = 0.5
output_every = {every}
"#,
            rayleigh.0, rayleigh.1
        ),
    )
}

/// max E / E(first sample after the ramp) and the range of E after the ramp,
/// with E = kinetic + strain (no work enters once the prescribed edge stops).
fn energy_after_ramp(energies: &[(f64, Energies)], ramp: f64) -> (f64, f64) {
    let after: Vec<f64> = energies
        .iter()
        .filter(|(t, _)| *t >= ramp - 1e-12)
        .map(|(_, e)| e.kinetic + e.strain)
        .collect();
    let Some(&e0) = after.first() else {
        return (f64::NAN, f64::NAN);
    };
    let max = after.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min = after.iter().copied().fold(f64::INFINITY, f64::min);
    (max / e0, (max - min) / e0)
}

/// dt from 1e-4 to 0.1 s over the same second of simulated time: Newton
/// converges in every step, the damped energy never grows after the ramp,
/// and the tip displacement converges in dt.
fn time_step() -> Vec<StressRow> {
    const TEST: &str = "time step (cut beam, corotational, damped)";
    let criterion = "finite; Newton converged every step; E after ramp non-increasing (≤ 1 + 1e-6)";
    let mut rows = Vec::new();
    let mut finest: Option<Vector3<f64>> = None;
    for dt in [1e-4, 1e-3, 1e-2, 0.1] {
        let t = Instant::now();
        let scene = bend_dynamic(dt, 1.0, (0.1, 0.01), "corotational");
        let setting = format!("dt = {dt:e} s ({} steps)", (1.0 / dt).round());
        match solve_scene(&scene, 0, None, false) {
            Ok(r) => {
                let (growth, _) = energy_after_ramp(&r.energies, 0.5);
                let tip = probe_values(&scene, &r).map_or(Vector3::repeat(f64::NAN), |v| v[0]);
                let reference = *finest.get_or_insert(tip);
                let iters = r.iterations.iter().max().copied().unwrap_or(0);
                rows.push(row(
                    TEST,
                    setting,
                    format!(
                        "max Newton iterations {iters}; max E / E(0.5 s) {growth:.6}; tip at 1 s differs from dt = 1e-4 by {:.2e} relative",
                        (tip - reference).norm() / reference.norm()
                    ),
                    criterion,
                    finite(&r) && growth <= 1.0 + 1e-6,
                    t,
                ));
            }
            Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
        }
    }
    rows
}

/// 10⁴ undamped steps (100 s) of the cut beam after the bend: nothing enters
/// or leaves, so the energy must stay put — exactly (solver tolerance) for
/// linear Newmark, bounded for the corotational one.
fn long_undamped() -> Vec<StressRow> {
    const TEST: &str = "10⁴ steps, undamped (cut beam, dt = 0.01 s)";
    let mut rows = Vec::new();
    for (formulation, bound, criterion) in [
        (
            "linear",
            1e-6,
            "finite; (max E − min E) / E ≤ 1e-6 after the ramp",
        ),
        (
            "corotational",
            0.05,
            "finite; (max E − min E) / E ≤ 5% after the ramp",
        ),
    ] {
        let t = Instant::now();
        let scene = bend_dynamic(0.01, 100.0, (0.0, 0.0), formulation);
        let setting = format!("{formulation}, 10⁴ steps");
        match solve_scene(&scene, 0, None, false) {
            Ok(r) => {
                let (growth, range) = energy_after_ramp(&r.energies, 0.5);
                rows.push(row(
                    TEST,
                    setting,
                    format!(
                        "energy range {range:.2e} of E(0.5 s); max E / E(0.5 s) {growth:.6}; {:.2} ms/step",
                        r.timings.solve * 1e3 / r.timings.steps as f64
                    ),
                    criterion,
                    finite(&r) && range <= bound,
                    t,
                ));
            }
            Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
        }
    }
    rows
}

/// The fragment freed by a complete cut: falls with g; spun at 3 rad/s it
/// tumbles 206° without storing strain energy (corotational) while the linear
/// formulation shows the seed's ghost forces (figure 4).
fn freed_fragment() -> Vec<StressRow> {
    const TEST: &str = "freed fragment";
    let mut rows = Vec::new();
    let g = 9.81;
    for (zc, where_) in [(1.0, "cut on a node layer"), (1.3, "cut through elements")] {
        let t = Instant::now();
        let criterion = "every node above the cut at −g t²/2 (≤ 1e-6 relative)";
        let analysis = format!(
            "{BOTTOM}{GRAVITY_DOWN}[analysis]\ntype = \"dynamic\"\nformulation = \"corotational\"\ndt = 0.01\nsteps = 50\n"
        );
        let setting = format!("fall 0.5 s, {where_}");
        match solve_scene(&bar(zc, None, &analysis), 0, None, false) {
            Ok(r) => {
                let want = -0.5 * g * 0.25;
                let err = r
                    .model
                    .mesh
                    .nodes
                    .iter()
                    .enumerate()
                    .filter(|(_, p)| p.z > zc + 1e-9)
                    .map(|(i, _)| {
                        (r.model.node_displacement(&r.d, i, 1) - Vector3::new(0.0, 0.0, want))
                            .norm()
                    })
                    .fold(0.0, f64::max)
                    / want.abs();
                rows.push(row(
                    TEST,
                    setting,
                    format!("max relative deviation from free fall {err:.1e}"),
                    criterion,
                    finite(&r) && err <= 1e-6,
                    t,
                ));
            }
            Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
        }
    }
    for formulation in ["corotational", "linear"] {
        let t = Instant::now();
        let setting = format!("tumble 206° at 3 rad/s, {formulation}");
        let (criterion, contrast) = if formulation == "corotational" {
            ("max strain energy ≤ 1e-4 × kinetic; kinetic energy kept to 1e-3; nodes within 1e-3 of a rigid motion", false)
        } else {
            (
                "contrast: linear kinematics cannot rotate (nodes ≥ 0.1 off any rigid motion)",
                true,
            )
        };
        match tumble(formulation) {
            Ok(tb) => {
                let ratio = tb.max_strain / tb.kinetic.0;
                let kept = (tb.kinetic.1 - tb.kinetic.0).abs() <= 1e-3 * tb.kinetic.0;
                let pass = if contrast {
                    tb.deviation >= 0.1
                } else {
                    ratio <= 1e-4 && kept && tb.deviation <= 1e-3
                };
                rows.push(row(
                    TEST,
                    setting,
                    format!(
                        "max strain / kinetic {ratio:.1e}; kinetic {:.3e} → {:.3e} J; max distance from the best rigid fit {:.1e} (fragment size 1)",
                        tb.kinetic.0, tb.kinetic.1, tb.deviation
                    ),
                    criterion,
                    pass,
                    t,
                ));
            }
            Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
        }
    }
    rows
}

/// Largest distance of `after` from the rigid motion of `before` that fits best.
fn rigid_fit_residual(before: &[Vector3<f64>], after: &[Vector3<f64>]) -> f64 {
    let n = before.len() as f64;
    let cb = before.iter().sum::<Vector3<f64>>() / n;
    let ca = after.iter().sum::<Vector3<f64>>() / n;
    let h: Matrix3<f64> = before
        .iter()
        .zip(after)
        .map(|(b, a)| (a - ca) * (b - cb).transpose())
        .sum();
    let rot = polar_rotation(&h, &Matrix3::identity());
    before
        .iter()
        .zip(after)
        .map(|(b, a)| (a - ca - rot * (b - cb)).norm())
        .fold(0.0, f64::max)
}

/// What a tumbling fragment did.
struct Tumble {
    max_strain: f64,
    /// Kinetic energy at the start and the end.
    kinetic: (f64, f64),
    /// Largest distance of a fragment node from the exact rigid motion at the end.
    deviation: f64,
}

/// Spins the fragment above a complete cut at z = 1.3 about the y axis
/// through its centroid at 3 rad/s for 1.2 s (206°).
fn tumble(formulation: &str) -> Result<Tumble, StudyError> {
    let analysis = format!(
        "{BOTTOM}[analysis]\ntype = \"dynamic\"\nformulation = \"{formulation}\"\ndt = 0.01\nsteps = 120\n"
    );
    let mut scene = bar(1.3, None, &analysis);
    // Stiff enough that the centrifugal strain (ρω²L²/E ≈ 2e-5) is small.
    scene.material.young = 1e8;
    let mesh = scene.mesh(0)?;
    let (model, _plan) = scene.build(mesh)?;
    let chol = Cholesky::new(&model.pattern)?;
    let Analysis::Dynamic { options, .. } = scene.analysis else {
        return Err(StudyError::Precondition("not a dynamic scene".into()));
    };
    let mut nm = Newmark::new(&model, chol, options)?;
    // v = ω × (x − c) on the upper side's DOFs.
    let cut = model
        .cut
        .as_ref()
        .ok_or_else(|| StudyError::Precondition("the bar has no cut".into()))?;
    spin_upper_side(
        &model,
        cut,
        &mut nm.state.v,
        Vector3::new(0.0, 3.0, 0.0),
        Vector3::new(0.5, 0.5, 1.65),
    );
    let n_nodes = model.mesh.n_nodes();
    let e0 = nm.energies();
    let mut max_strain: f64 = 0.0;
    for _ in 0..options.steps {
        nm.step()?;
        max_strain = max_strain.max(nm.energies().strain);
    }
    if nm.state.d.iter().any(|v| !v.is_finite()) {
        return Err(StudyError::Precondition("non-finite state".into()));
    }
    // Distance from the best rigid fit (Kabsch): the discrete body's inertia
    // is not exactly that of the box (lumped masses), so it may precess; what
    // must hold is that it moves rigidly.
    let upper: Vec<usize> = (0..n_nodes).filter(|&i| cut.phi[i] >= 0.0).collect();
    let before: Vec<Vector3<f64>> = upper.iter().map(|&i| model.mesh.nodes[i].coords).collect();
    let after: Vec<Vector3<f64>> = upper
        .iter()
        .zip(&before)
        .map(|(&i, x)| x + model.node_displacement(&nm.state.d, i, 1))
        .collect();
    let deviation = rigid_fit_residual(&before, &after);
    Ok(Tumble {
        max_strain,
        kinetic: (e0.kinetic, nm.energies().kinetic),
        deviation,
    })
}

/// Fix entries that prescribe, node by node, the top face's rotation by
/// `angle` about the beam's axis (the seed's beam, level [2, 4, 13]).
fn twisted_top(angle: f64) -> String {
    let (nx, ny) = (2, 4);
    let (a, b, top) = (0.03, 0.06, 0.2);
    let c = Vector3::new(a / 2.0, b / 2.0, 0.0);
    let r = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), angle);
    let mut s = String::new();
    for i in 0..=nx {
        for j in 0..=ny {
            let p = Vector3::new(a * i as f64 / nx as f64, b * j as f64 / ny as f64, top);
            let u = r * (p - c) + c - p;
            s += &format!(
                "[[fix]]\nmin = [{:e}, {:e}, {top}]\nmax = [{:e}, {:e}, {top}]\ndisplacement = [{:e}, {:e}, 0.0]\n",
                p.x, p.y, p.x, p.y, u.x, u.y
            );
        }
    }
    s
}

/// Elements whose deformed volume is negative (their vertices' displacement
/// seen from the element's own side).
fn inverted_elements(m: &Model, d: &[f64]) -> usize {
    (0..m.mesh.n_elements())
        .filter(|&e| {
            let side = match m.cut.as_ref().map(|c| &c.elements[e]) {
                Some(crate::cut::ElementCut::Touched { side }) => *side,
                _ => 0,
            };
            let v = m.mesh.vertices(e);
            let x: Vec<Vector3<f64>> = v
                .iter()
                .map(|&i| m.mesh.nodes[i].coords + m.node_displacement(d, i, side))
                .collect();
            Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]).determinant() < 0.0
        })
        .count()
}

/// Whether every element's rotation from its deformed vertices is proper and finite.
fn proper_rotations(m: &Model, d: &[f64]) -> bool {
    (0..m.mesh.n_elements()).all(|e| {
        let v = m.mesh.vertices(e);
        let p: Vec<Vector3<f64>> = v.iter().map(|&i| m.mesh.nodes[i].coords).collect();
        let x: Vec<Vector3<f64>> = v
            .iter()
            .map(|&i| m.mesh.nodes[i].coords + m.node_displacement(d, i, 0))
            .collect();
        let dx = Matrix3::from_columns(&[x[1] - x[0], x[2] - x[0], x[3] - x[0]]);
        let dp = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        let Some(inv) = dp.try_inverse() else {
            return false;
        };
        let rot = polar_rotation(&(dx * inv), &Matrix3::identity());
        rot.iter().all(|v| v.is_finite()) && (rot.determinant() - 1.0).abs() < 1e-10
    })
}

/// The cut beam's top face twisted about the beam's axis, static corotational
/// Newton with load steps. The case file's proportional ramp moves the
/// prescribed nodes along the chord, which at 180° collapses the top face to
/// a point half-way; the 180° twist therefore follows the arc
/// ([`crate::statics::solve_static_along`]).
fn large_rotation() -> Vec<StressRow> {
    const TEST: &str = "large rotation (static corotational twist of the cut beam)";
    let criterion = "finite; Newton converged to relative residual ≤ 1e-10; proper rotations";
    let mut rows = Vec::new();
    for (degrees, steps, arc) in [(90.0f64, 20, false), (180.0, 20, true)] {
        let t = Instant::now();
        let angle = degrees.to_radians();
        let analysis = format!(
            "{}[analysis]\ntype = \"static\"\nformulation = \"corotational\"\nload_steps = {steps}\nmax_iterations = 100\n",
            twisted_top(angle)
        );
        let scene = seed_beam("tet4", 0.35, [2, 4, 13], [0.0, 0.03, 0.2], &analysis);
        let setting = format!(
            "twist {degrees}°, {steps} load steps along the {}",
            if arc { "arc" } else { "chord (case-file ramp)" }
        );
        match twist(&scene, angle, arc) {
            Ok((model, sol)) => {
                let total: usize = sol.iterations.iter().sum();
                let max = sol.iterations.iter().max().copied().unwrap_or(0);
                let kappa = condition_estimate(&model, &sol.d);
                let ok = sol.d.iter().all(|v| v.is_finite());
                rows.push(row(
                    TEST,
                    setting,
                    format!(
                        "Newton iterations {total} (max {max} per step); residual {:.1e}; inverted elements {}; κ ≈ {}",
                        sol.residual,
                        inverted_elements(&model, &sol.d),
                        fmt_kappa(kappa)
                    ),
                    criterion,
                    ok && sol.residual <= 1e-10 && proper_rotations(&model, &sol.d),
                    t,
                ));
            }
            Err(e) => rows.push(failed(TEST, setting, criterion, &e, t)),
        }
    }
    rows
}

/// Solves the twist scene, along the arc of the rotation `angle` of the top
/// face (z = 0.2) about the beam's axis if `arc`, else as the case file ramps.
fn twist(
    scene: &Scene,
    angle: f64,
    arc: bool,
) -> Result<(Model, crate::statics::StaticSolution), StudyError> {
    let mesh = scene.mesh(0)?;
    let (model, _plan) = scene.build(mesh)?;
    let mut chol = Cholesky::new(&model.pattern)?;
    let Analysis::Static(opts) = scene.analysis else {
        return Err(StudyError::Precondition("not a static scene".into()));
    };
    let centre = Vector3::new(0.015, 0.03, 0.0);
    let nodes = &model.mesh.nodes;
    let sol = crate::statics::solve_static_along(&model, &mut chol, &opts, |lambda, p| {
        let x = nodes[p.dof / 3].coords;
        if arc && x.z > 0.1 {
            let r = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), lambda * angle);
            (r * (x - centre) + centre - x)[p.dof % 3]
        } else {
            lambda * p.value
        }
    })
    .map_err(|e| StudyError::from(e).during(scene.file.display().to_string()))?;
    Ok((model, sol))
}

/// The case file of a unit cube (2 × 2 × 2 hexahedra, clamped at its
/// base) whose top-centre node is pushed down through the centre node by
/// 0.8, with `analysis` (its `[analysis]` table) appended: elements invert.
pub fn pushed_through_cube(analysis: &str) -> String {
    format!(
        r#"name = "cube"
[body]
box = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]
levels = [[2, 2, 2]]
[material]
young = 1.0e4
poisson = 0.3
density = 1000.0
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
[[fix]]
min = [0.5, 0.5, 1.0]
max = [0.5, 0.5, 1.0]
displacement = [0.0, 0.0, -0.8]
{analysis}"#
    )
}

/// A unit cube whose top-centre node is pushed through the centre node
/// ([`pushed_through_cube`]): elements invert. The polar decomposition must
/// still give proper rotations and the solvers finite states (static:
/// converged or a clear error).
fn inverted_element() -> Vec<StressRow> {
    const TEST: &str = "inverted elements";
    let cube = |analysis: &str| parse("cube", &pushed_through_cube(analysis));
    let criterion = "finite; converged (static) or every step converged (dynamic); proper rotations; ≥ 1 element inverted";
    let mut rows = Vec::new();
    for (setting, analysis) in [
        (
            "static, 20 load steps",
            "[analysis]\ntype = \"static\"\nformulation = \"corotational\"\nload_steps = 20\nmax_iterations = 100\n",
        ),
        (
            "dynamic, 1 s ramp, dt = 0.01 s",
            "[analysis]\ntype = \"dynamic\"\nformulation = \"corotational\"\ndt = 0.01\nsteps = 200\nramp = 1.0\nrayleigh = { mass = 0.1, stiffness = 0.01 }\n",
        ),
    ] {
        let t = Instant::now();
        match solve_scene(&cube(analysis), 0, None, false) {
            Ok(r) => {
                let inverted = inverted_elements(&r.model, &r.d);
                rows.push(row(
                    TEST,
                    setting.into(),
                    format!(
                        "inverted elements {inverted} of {}; max Newton iterations {}; residual {:.1e}",
                        r.model.mesh.n_elements(),
                        r.iterations.iter().max().copied().unwrap_or(0),
                        r.residual
                    ),
                    criterion,
                    finite(&r) && proper_rotations(&r.model, &r.d) && inverted >= 1,
                    t,
                ));
            }
            Err(e) => rows.push(failed(TEST, setting.into(), criterion, &e, t)),
        }
    }
    rows
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Tet10 front beside a node line: the faces the front crosses are
    /// lifted 1e-4 h off the layer, and the slivers they leave made the
    /// Jacobi-scaled condition 2.8e8 (δ = 1e-3) … 9.7e9 (δ ≥ 1e-6) before
    /// the vertices whose Heaviside functions live only there let them go
    /// ([`crate::cut::SLIVER_LAMBDA`]); the same front beside a face plane
    /// (no slivers) is 4.6e3 … 2.4e4.
    #[test]
    fn a_tet10_front_beside_a_node_line_is_conditioned_as_one_beside_a_face() {
        for radius in ["", "tip_radius = 0.3"] {
            for delta in [1e-3, 1e-6, 1e-12] {
                let r = solve_scene(
                    &front_bar(1.0 + delta * 0.25, 0.5 + delta * 0.25, radius, "tet10"),
                    0,
                    None,
                    false,
                )
                .unwrap();
                let (_, scaled) = condition_estimate(&r.model, &r.d).unwrap();
                println!("{radius:?} δ = {delta:e}: Jacobi-scaled κ {scaled:.2e}");
                assert!(scaled <= 1e5, "{radius:?} δ = {delta:e}: {scaled:e}");
            }
        }
    }

    #[test]
    fn csv_round_trips() {
        let rows = vec![StressRow {
            test: "a, b".into(),
            setting: "δ = 1e-3".into(),
            measured: "x".into(),
            criterion: "y".into(),
            pass: true,
            seconds: 1.5,
        }];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("s.csv");
        write_csv(&path, &rows).unwrap();
        let back = read_csv(&path).unwrap();
        assert_eq!(back[0].test, "a, b", "a comma is quoted, not replaced");
        assert!(back[0].pass);
        assert_eq!(back[0].seconds, 1.5);
    }

    #[test]
    fn condition_estimates_bound_the_exact_ones_from_below_and_closely() {
        // A 2 × 2 × 2 cube clamped at the bottom: dense eigenvalues are cheap.
        let s = parse(
            "c",
            &format!(
                "name = \"c\"\n[body]\nbox = [[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]\nlevels = [[2, 2, 2]]\n[material]\nyoung = 1.0\npoisson = 0.3\ndensity = 1.0\n{BOTTOM}[gravity]\nacceleration = [0.0, 0.0, -1.0]\n[analysis]\ntype = \"static\"\n"
            ),
        );
        let r = solve_scene(&s, 0, None, false).unwrap();
        let m = &r.model;
        let (kappa, scaled) = condition_estimate(m, &r.d).unwrap();
        let mut k = vec![0.0; m.pattern.nnz()];
        evaluate(
            m,
            &r.d,
            &mut Rotations::identity(m),
            &mut Workspace::new(m),
            Request {
                forces: None,
                tangent: Some(&mut k),
                update_rotations: false,
                exact_tangent: false,
            },
        );
        let n = m.n_free;
        let dense = nalgebra::DMatrix::from_fn(n, n, |i, j| {
            let (r, c) = if i >= j { (i, j) } else { (j, i) };
            m.pattern.position(r, c).map_or(0.0, |p| k[p])
        });
        let exact = |a: nalgebra::DMatrix<f64>| {
            let e = a.symmetric_eigenvalues();
            e.max() / e.min()
        };
        let d = nalgebra::DMatrix::from_fn(n, n, |i, j| {
            if i == j {
                1.0 / dense[(i, i)].sqrt()
            } else {
                0.0
            }
        });
        for (estimate, want) in [
            (kappa, exact(dense.clone())),
            (scaled, exact(&d * &dense * &d)),
        ] {
            assert!(
                estimate <= want * (1.0 + 1e-9) && estimate >= 0.9 * want,
                "estimate {estimate} vs exact {want}"
            );
        }
    }
}

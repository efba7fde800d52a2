//! Two threads solve as one: from 4k equations on (`SPLIT_FROM`), a run on two threads
//! factorises in two halves split at nested dissection's first separator
//! (`Cholesky::split`), one thread the whole factor. Checked on a cut
//! Tet10 beam whose front ends inside elements (tip-enriched dense groups
//! in the factor), static linear and corotational and a few dynamic
//! corotational steps.
use std::path::Path;
use xfem_cut::run::solve_scene_with;
use xfem_cut::scene::Scene;
use xfem_cut::solve::Parallelism;

fn scene(analysis: &str) -> Scene {
    let text = format!(
        r#"name = "threads"
description = "a cut Tet10 beam under gravity, the front inside elements"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.03, 0.12]]
levels = [[6, 6, 12]]
element = "tet10"
[material]
young = 3.0e5
poisson = 0.35
density = 1070.0
[[cut]]
origin = [0.0, 0.0, 0.061]
u = [0.0137, 0.0, 0.0]
v = [0.0, 0.03, 0.0]
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
displacement = [0.0, 0.0, 0.0]
[gravity]
acceleration = [9.81, 0.0, 0.0]
{analysis}"#
    );
    Scene::parse(&text, Path::new("threads.toml")).unwrap()
}

/// Largest difference of the two runs' displacements, relative to the
/// largest displacement.
fn one_against_two(scene: &Scene) -> f64 {
    let one = solve_scene_with(scene, 0, None, false, Parallelism::SEQUENTIAL).unwrap();
    let two = solve_scene_with(scene, 0, None, false, Parallelism::threads(2)).unwrap();
    assert!(
        one.model.n_free >= xfem_cut::solve::SPLIT_FROM,
        "{} equations",
        one.model.n_free
    );
    assert!(one.model.n_enriched() > 0);
    let scale = one.d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(scale > 0.0);
    one.d
        .iter()
        .zip(&two.d)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max)
        / scale
}

#[test]
fn a_static_linear_solve_on_two_threads_equals_one_thread() {
    let diff = one_against_two(&scene(
        "[analysis]\ntype = \"static\"\nformulation = \"linear\"\n",
    ));
    assert!(diff < 1e-10, "{diff:e}");
}

#[test]
fn a_static_corotational_solve_on_two_threads_equals_one_thread() {
    let diff = one_against_two(&scene(
        "[analysis]\ntype = \"static\"\nformulation = \"corotational\"\nload_steps = 2\n",
    ));
    assert!(diff < 1e-9, "{diff:e}");
}

#[test]
fn dynamic_corotational_steps_on_two_threads_equal_one_thread() {
    let diff = one_against_two(&scene(
        "[analysis]\ntype = \"dynamic\"\nformulation = \"corotational\"\ndt = 0.01\nsteps = 3\n",
    ));
    assert!(diff < 1e-9, "{diff:e}");
}

/// A blade sweeping a tip front through a Tet4 beam while it runs: on two
/// threads the steps' element loops, the events' integration of the
/// changed elements and the state's projection run side by side; the run
/// is the one thread's (the same events, the same energies at each).
#[test]
fn a_blade_sweep_on_two_threads_equals_one_thread() {
    for formulation in ["linear", "corotational"] {
        let text = format!(
            r#"name = "sweep-threads"
description = "a blade opening a cut in a Tet4 beam under gravity, the front tip-enriched"
[body]
box = [[0.0, 0.0, 0.0], [0.03, 0.03, 0.12]]
levels = [[4, 4, 8]]
element = "tet4"
[material]
young = 3.0e5
poisson = 0.35
density = 1070.0
[[cut]]
blade = [[0.0, -0.01, 0.061], [0.0, 0.04, 0.061]]
travel = [0.02, 0.0, 0.0]
start = 0.0
end = 0.06
[[fix]]
min = [-inf, -inf, 0.0]
max = [inf, inf, 0.0]
displacement = [0.0, 0.0, 0.0]
[gravity]
acceleration = [9.81, 0.0, 0.0]
[analysis]
type = "dynamic"
formulation = "{formulation}"
dt = 0.01
steps = 8
"#
        );
        let scene = Scene::parse(&text, Path::new("sweep-threads.toml")).unwrap();
        let one = solve_scene_with(&scene, 0, None, false, Parallelism::SEQUENTIAL).unwrap();
        let two = solve_scene_with(&scene, 0, None, false, Parallelism::threads(2)).unwrap();
        let (s1, s2) = (one.sweep.unwrap(), two.sweep.unwrap());
        assert!(s1.events.len() >= 4, "{} events", s1.events.len());
        assert_eq!(s1.events.len(), s2.events.len());
        assert!(one.model.cut.as_ref().is_some_and(|c| c.n_tip() > 0));
        assert!(s1.projections.iter().any(Option::is_some));
        let scale = one.d.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let diff = one
            .d
            .iter()
            .zip(&two.d)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
            / scale;
        println!(
            "{formulation}: {} events, displacements differ by {diff:.1e} (relative)",
            s1.events.len()
        );
        assert!(diff < 1e-10, "{formulation}: {diff:e}");
        for (a, b) in s1.events.iter().zip(&s2.events) {
            assert_eq!(a.dofs_after, b.dofs_after);
            let (ea, eb) = (
                a.after.strain + a.after.kinetic,
                b.after.strain + b.after.kinetic,
            );
            assert!((ea - eb).abs() <= 1e-10 * ea.abs().max(1e-30), "{ea} {eb}");
        }
    }
}

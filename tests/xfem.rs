#![allow(clippy::needless_range_loop)]
//! X-FEM cuts end to end: separation, free fall, patch tests through cut
//! elements, cuts near nodes.

use nalgebra::{Point3, Vector3};
use std::path::Path;
use xfem_cut::locate::Locator;
use xfem_cut::run::{evaluate_at, solve_scene, RunResult};
use xfem_cut::scene::Scene;

/// A 1 × 1 × 2 bar, `div` hexes, cut by the plane z = `zc` across the whole
/// section, `fixes` and `analysis` as TOML.
fn bar(div: [usize; 3], zc: f64, extra: &str) -> Scene {
    let text = format!(
        r#"
name = "bar"
[body]
box = [[0.0, 0.0, 0.0], [1.0, 1.0, 2.0]]
levels = [[{}, {}, {}]]
[material]
young = 1.0e4
poisson = 0.3
density = 1000.0
[[cut]]
origin = [-0.5, -0.5, {zc}]
u = [2.0, 0.0, 0.0]
v = [0.0, 2.0, 0.0]
{extra}
"#,
        div[0], div[1], div[2]
    );
    Scene::parse(&text, Path::new("bar.toml")).unwrap()
}

const BOTTOM: &str = "[[fix]]\nmin = [-inf, -inf, 0.0]\nmax = [inf, inf, 0.0]\n";
const TOP: &str = "[[fix]]\nmin = [-inf, -inf, 2.0]\nmax = [inf, inf, 2.0]\n";

fn value(r: &RunResult, x: Point3<f64>) -> Vector3<f64> {
    let loc = Locator::new(&r.model.mesh);
    evaluate_at(&r.model, &loc, &r.d, &x).unwrap()
}

/// Displacement at x seen from a side (+1 above the cut, −1 below).
fn value_on_side(r: &RunResult, x: Point3<f64>, side: i8) -> Vector3<f64> {
    let loc = Locator::new(&r.model.mesh);
    let (e, _) = loc.locate(&r.model.mesh, &x).unwrap();
    r.model.displacement_at(&r.d, e, &x, side)
}

#[test]
fn a_full_cut_on_a_node_layer_gives_two_independent_bars() {
    let gravity = "[gravity]\nacceleration = [0.0, 0.0, -9.81]\n[analysis]\ntype = \"static\"\n";
    let cut = solve_scene(
        &bar([2, 2, 4], 1.0, &format!("{BOTTOM}{TOP}{gravity}")),
        0,
        None,
        false,
    )
    .unwrap();
    // The two halves meshed and solved alone.
    let half = |lo: f64, fix: &str| {
        let text = format!(
            "name = \"half\"\n[body]\nbox = [[0.0, 0.0, {lo}], [1.0, 1.0, {}]]\nlevels = [[2, 2, 2]]\n[material]\nyoung = 1.0e4\npoisson = 0.3\ndensity = 1000.0\n{fix}{gravity}",
            lo + 1.0
        );
        solve_scene(
            &Scene::parse(&text, Path::new("half.toml")).unwrap(),
            0,
            None,
            false,
        )
        .unwrap()
    };
    let lower = half(0.0, BOTTOM);
    let upper = half(1.0, TOP);
    let mut max_err: f64 = 0.0;
    let mut scale: f64 = 0.0;
    for (part, side) in [(&lower, -1i8), (&upper, 1i8)] {
        for (i, p) in part.model.mesh.nodes.iter().enumerate() {
            let want = Vector3::new(part.d[3 * i], part.d[3 * i + 1], part.d[3 * i + 2]);
            // The same node in the cut bar, seen from this part's side.
            let j = cut
                .model
                .mesh
                .nodes
                .iter()
                .position(|q| (q - p).norm() < 1e-12)
                .unwrap();
            let got = cut.model.node_displacement(&cut.d, j, side);
            max_err = max_err.max((got - want).norm());
            scale = scale.max(want.norm());
        }
    }
    assert!(
        max_err <= 1e-10 * scale,
        "parts differ from the separate bars: {max_err:e} (scale {scale:e})"
    );
}

#[test]
fn a_static_scene_with_a_freed_part_is_refused() {
    let text = "[gravity]\nacceleration = [0.0, 0.0, -9.81]\n[analysis]\ntype = \"static\"\n";
    let scene = bar([2, 2, 4], 1.3, &format!("{BOTTOM}{text}"));
    let err = solve_scene(&scene, 0, None, false)
        .err()
        .expect("must be refused")
        .to_string();
    assert!(
        err.contains("floats free") && err.contains("bar.toml"),
        "{err}"
    );
}

#[test]
fn the_freed_part_falls_with_gravity() {
    let g = 9.81;
    for (zc, formulation) in [(1.0, "linear"), (1.3, "linear"), (1.3, "corotational")] {
        let analysis = format!("[gravity]\nacceleration = [0.0, 0.0, -{g}]\n[analysis]\ntype = \"dynamic\"\nformulation = \"{formulation}\"\ndt = 0.01\nsteps = 50\n");
        let r = solve_scene(
            &bar([2, 2, 4], zc, &format!("{BOTTOM}{analysis}")),
            0,
            None,
            false,
        )
        .unwrap();
        let t: f64 = 0.5;
        let want = -0.5 * g * t * t;
        // Every node strictly above the cut moves by the free-fall distance, rigidly.
        for (i, p) in r.model.mesh.nodes.iter().enumerate() {
            if p.z > zc + 1e-9 {
                let u = r.model.node_displacement(&r.d, i, 1);
                assert!(
                    (u.z - want).abs() <= 1e-6 * want.abs(),
                    "zc {zc} {formulation}: node at {p:?} has uz {} (free fall {want})",
                    u.z
                );
                assert!(u.x.abs() + u.y.abs() <= 1e-6 * want.abs());
            }
        }
        // Points just above the cut, inside cut elements, fall too.
        let u = value_on_side(&r, Point3::new(0.3, 0.6, zc + 1e-6), 1);
        assert!(
            (u.z - want).abs() <= 1e-6 * want.abs(),
            "zc {zc}: point above the cut has uz {}",
            u.z
        );
    }
}

#[test]
fn patch_test_through_cut_elements_translates_the_upper_part_exactly() {
    // Bottom fixed, top face moved by t: with a complete cut (mid-element) and
    // no load, the lower part stays at rest and the upper part translates.
    let t = Vector3::new(0.01, -0.02, 0.03);
    let top = format!(
        "[[fix]]\nmin = [-inf, -inf, 2.0]\nmax = [inf, inf, 2.0]\ndisplacement = [{}, {}, {}]\n",
        t.x, t.y, t.z
    );
    for zc in [1.3, 1.0, 1.0 + 1e-9, 1.0 + 1e-3 * 0.5] {
        let r = solve_scene(
            &bar(
                [2, 2, 4],
                zc,
                &format!("{BOTTOM}{top}[analysis]\ntype = \"static\"\n"),
            ),
            0,
            None,
            false,
        )
        .unwrap();
        for x in [
            Point3::new(0.2, 0.7, 0.2),
            Point3::new(0.4, 0.4, zc - 0.05),
            Point3::new(0.9, 0.1, zc - 1e-4),
        ] {
            let u = value_on_side(&r, x, -1);
            assert!(
                u.norm() <= 1e-12,
                "zc {zc}: lower part moved at {x:?}: {u:?}"
            );
        }
        for x in [
            Point3::new(0.2, 0.7, 1.9),
            Point3::new(0.4, 0.4, zc + 0.05),
            Point3::new(0.9, 0.1, zc + 1e-4),
        ] {
            let u = value_on_side(&r, x, 1);
            assert!(
                (u - t).norm() <= 1e-12 * t.norm(),
                "zc {zc}: upper part at {x:?}: {u:?}"
            );
        }
        // The probe rule: a point on the cut takes the + side.
        let on = value(&r, Point3::new(0.5, 0.5, zc));
        assert!((on - t).norm() <= 1e-10, "on the cut: {on:?}");
    }
}

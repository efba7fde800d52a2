//! The exact solutions on cuts and fronts through nodes: where a grid-aligned
//! incision puts them, and where three defects hid (the ramp on a node
//! layer, a front through a node, the traction on cut faces that are
//! element faces; README, "Engineering notes").
//!
//! Part 1, the near-front Williams field (`study::exact::WilliamsFront`) on
//! 14 planes and fronts of the structured unit box: node layers in x, y, z;
//! fronts on a node line, beside one, diagonal, anti-diagonal and oblique in
//! the layer; the diagonal planes x ± z, x ± y, x + y + z through nodes; two
//! of them also moved off the nodes; beside them the study's oblique front.
//! Per configuration the relative L2 and energy errors of Tet4 topological
//! (n = 8, 16), Tet4 `tip_radius` 0.2 without and with the ramp (n = 16),
//! Tet10 topological (n = 4), Tet10 `tip_radius` 0.2 without and with the
//! ramp (n = 6). A configuration through nodes should err about as its
//! counterpart moved off them.
//!
//! Part 2, the through cut's manufactured solution (`ThroughCut`, X-FEM
//! Heaviside, the traction on both cut faces) on planes through nodes and
//! moved off them: L2 and energy errors, Tet4 n = 8, 16 and Tet10 n = 4, 6
//! (the smooth rates 2 / 1 and 3 / 2).
//!
//! `cargo run --release --example node_planes` (about a minute on 2 cores).
use nalgebra::{Point3, Vector3};
use xfem_cut::assembly::field_load;
use xfem_cut::cut::{setup_cut, Blending, CutInput, FrontMode, DEFAULT_SNAP};
use xfem_cut::material::Lame;
use xfem_cut::mesh::ElementKind;
use xfem_cut::model::Model;
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};
use xfem_cut::study::exact::{
    linear_model, relative_errors, unit_box, ThroughCut, WilliamsFront, MATERIAL,
};

/// Solves `model` and returns its (L2, energy) errors against `exact`.
fn errors(
    model: &Model,
    exact: impl Fn(&Point3<f64>, i8) -> (Vector3<f64>, nalgebra::Matrix3<f64>),
) -> Result<(f64, f64), String> {
    let mut chol = Cholesky::new(&model.pattern).map_err(|e| e.to_string())?;
    let sol =
        solve_static(model, &mut chol, &StaticOptions::default()).map_err(|e| e.to_string())?;
    Ok(relative_errors(model, &sol.d, exact))
}

fn near_front() {
    let s2 = 0.5f64.sqrt();
    let (x, y, z) = (Vector3::x(), Vector3::y(), Vector3::z());
    let at = Point3::new;
    let configs: Vec<(&str, WilliamsFront)> = vec![
        ("oblique (the study's)", WilliamsFront::new()),
        (
            "layer z, front on a node line",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), z, y),
        ),
        (
            "layer z, front 0.01 beside it",
            WilliamsFront::oriented(at(0.51, 0.5, 0.5), z, y),
        ),
        (
            "layer z moved 0.013 off",
            WilliamsFront::oriented(at(0.51, 0.5, 0.513), z, y),
        ),
        (
            "layer z, front diagonal",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), z, Vector3::new(s2, s2, 0.0)),
        ),
        (
            "layer z, front anti-diagonal",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), z, Vector3::new(s2, -s2, 0.0)),
        ),
        (
            "layer z, front oblique",
            WilliamsFront::oriented(at(0.513, 0.5, 0.5), z, Vector3::new(0.3, 1.0, 0.0)),
        ),
        (
            "layer y, front along x",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), y, x),
        ),
        (
            "layer x, front along z",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), x, z),
        ),
        (
            "plane x + z",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), Vector3::new(1.0, 0.0, 1.0), y),
        ),
        (
            "plane x − z",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), Vector3::new(1.0, 0.0, -1.0), y),
        ),
        (
            "plane x + y, front along z",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), Vector3::new(1.0, 1.0, 0.0), z),
        ),
        (
            "plane x − y, front along z",
            WilliamsFront::oriented(at(0.5, 0.5, 0.5), Vector3::new(1.0, -1.0, 0.0), z),
        ),
        (
            "plane x + y + z",
            WilliamsFront::oriented(
                at(0.5, 0.5, 0.5),
                Vector3::new(1.0, 1.0, 1.0),
                Vector3::new(1.0, -1.0, 0.0),
            ),
        ),
        (
            "plane x + y + z moved 0.013 off",
            WilliamsFront::oriented(
                at(0.5, 0.5, 0.513),
                Vector3::new(1.0, 1.0, 1.0),
                Vector3::new(1.0, -1.0, 0.0),
            ),
        ),
    ];
    let variants: [(&str, ElementKind, usize, Option<f64>, Blending); 7] = [
        ("tet4 tip n8", ElementKind::Tet4, 8, None, Blending::None),
        ("tet4 tip n16", ElementKind::Tet4, 16, None, Blending::None),
        (
            "tet4 R0.2 n16",
            ElementKind::Tet4,
            16,
            Some(0.2),
            Blending::None,
        ),
        (
            "tet4 R0.2 ramp n16",
            ElementKind::Tet4,
            16,
            Some(0.2),
            Blending::Ramp,
        ),
        ("tet10 tip n4", ElementKind::Tet10, 4, None, Blending::None),
        (
            "tet10 R0.2 n6",
            ElementKind::Tet10,
            6,
            Some(0.2),
            Blending::None,
        ),
        (
            "tet10 R0.2 ramp n6",
            ElementKind::Tet10,
            6,
            Some(0.2),
            Blending::Ramp,
        ),
    ];
    println!("near-front field: L2 / energy error");
    for (name, front) in &configs {
        println!("  {name}");
        let patch = front.patch();
        for (variant, kind, div, radius, blending) in variants {
            let mesh = unit_box(div, kind, 0.0);
            let input = CutInput {
                surface: &patch,
                snap: DEFAULT_SNAP,
                front: FrontMode::Tip,
                tip_radius: radius,
                blending,
            };
            let run = setup_cut(&mesh, &[input])
                .map_err(|e| e.to_string())
                .and_then(|cut| {
                    let fixed = front.boundary_values(&mesh, &cut);
                    linear_model(mesh, Some(cut), fixed).map_err(|e| e.to_string())
                })
                .and_then(|model| errors(&model, |x, s| front.exact(x, s)));
            match run {
                Ok((l2, energy)) => println!("    {variant:20} {l2:.3e} / {energy:.3e}"),
                Err(e) => println!("    {variant:20} failed: {e}"),
            }
        }
    }
}

fn through_cut() {
    let lame = Lame::from(MATERIAL);
    let planes = [
        (
            "the study's plane",
            Point3::new(0.5, 0.47, 0.52),
            Vector3::new(0.3, 1.0, 0.2),
        ),
        ("layer z = 0.5", Point3::new(0.5, 0.5, 0.5), Vector3::z()),
        (
            "layer z moved 0.013 off",
            Point3::new(0.5, 0.5, 0.513),
            Vector3::z(),
        ),
        (
            "plane x = z",
            Point3::new(0.5, 0.5, 0.5),
            Vector3::new(1.0, 0.0, -1.0),
        ),
        (
            "plane x + z",
            Point3::new(0.5, 0.5, 0.5),
            Vector3::new(1.0, 0.0, 1.0),
        ),
        (
            "plane x + y + z",
            Point3::new(0.5, 0.5, 0.5),
            Vector3::new(1.0, 1.0, 1.0),
        ),
        (
            "plane x + y + z moved 0.013 off",
            Point3::new(0.5, 0.5, 0.513),
            Vector3::new(1.0, 1.0, 1.0),
        ),
    ];
    println!("through cut, manufactured: L2 / energy error");
    for (name, c, n) in planes {
        let tc = ThroughCut {
            c,
            n: n.normalize(),
            ..ThroughCut::new()
        };
        let patch = tc.patch();
        print!("  {name:32}");
        for (kind, div) in [
            (ElementKind::Tet4, 8),
            (ElementKind::Tet4, 16),
            (ElementKind::Tet10, 4),
            (ElementKind::Tet10, 6),
        ] {
            let mesh = unit_box(div, kind, 0.0);
            let run = setup_cut(&mesh, &[CutInput::extend(&patch, DEFAULT_SNAP)])
                .map_err(|e| e.to_string())
                .and_then(|cut| {
                    let fixed = tc.boundary_values(&mesh, &cut);
                    linear_model(mesh, Some(cut), fixed).map_err(|e| e.to_string())
                })
                .and_then(|mut model| {
                    let load = field_load(&model, |x, side, at| tc.load(x, side, at, &lame));
                    for (l, f) in model.load.iter_mut().zip(load) {
                        *l += f;
                    }
                    errors(&model, |x, s| tc.exact(x, s))
                });
            match run {
                Ok((l2, energy)) => print!(" | {} n{div} {l2:.2e} / {energy:.2e}", kind.name()),
                Err(e) => print!(" | {} n{div} failed: {e}", kind.name()),
            }
        }
        println!();
    }
}

fn main() {
    near_front();
    through_cut();
}

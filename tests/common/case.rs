//! Loads a case file with blades until the scene schema reads them: the
//! `[[cut]]` tables with `blade` become [`Blade`]s, the rest is read by
//! [`Scene::parse`]; the model builder applies the scene's fixes and gravity.

use nalgebra::Point3;
use std::path::Path;
use toml::{Table, Value};
use xfem_cut::blade::{Blade, CutItem, CutSet};
use xfem_cut::cut::{CutSetup, DEFAULT_SNAP};
use xfem_cut::mesh::TetMesh;
use xfem_cut::model::{Model, ModelError, ModelInput};
use xfem_cut::scene::{Analysis, Scene};

fn point(v: &Value) -> Point3<f64> {
    let a = v.as_array().expect("a point");
    let f = |k: usize| {
        a[k].as_float()
            .or(a[k].as_integer().map(|i| i as f64))
            .unwrap()
    };
    Point3::new(f(0), f(1), f(2))
}

fn float(v: &Value) -> f64 {
    v.as_float().or(v.as_integer().map(|i| i as f64)).unwrap()
}

/// The scene without its blades, and every cut (blades and patches) as a [`CutSet`].
pub fn load(path: &Path) -> (Scene, CutSet) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut table: Table = text.parse().unwrap();
    let mut items = Vec::new();
    if let Some(Value::Array(cuts)) = table.remove("cut") {
        for (index, c) in cuts.into_iter().enumerate() {
            let t = c.as_table().unwrap();
            if let Some(edge) = t.get("blade") {
                let e = edge.as_array().unwrap();
                let (a, b) = (point(&e[0]), point(&e[1]));
                let blade = if let Some(travel) = t.get("travel") {
                    let start = float(&t["start"]);
                    let end = float(&t["end"]);
                    Blade::straight(index, a, b, point(travel).coords, start, end).unwrap()
                } else {
                    let times: Vec<f64> =
                        t["times"].as_array().unwrap().iter().map(float).collect();
                    let path: Vec<[Point3<f64>; 2]> = t["path"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|e| {
                            let e = e.as_array().unwrap();
                            [point(&e[0]), point(&e[1])]
                        })
                        .collect();
                    Blade::new(index, times.into_iter().zip(path).collect()).unwrap()
                };
                items.push(CutItem::Blade(blade));
            } else if let Some(file) = t.get("surface") {
                let file = path.parent().unwrap().join(file.as_str().unwrap());
                let surface = xfem_cut::surface::TriangleSurface::read(&file).unwrap();
                items.push(CutItem::Surface(Box::new(surface)));
            } else {
                let patch = xfem_cut::cut::PlanarPatch {
                    origin: point(&t["origin"]),
                    u: point(&t["u"]).coords,
                    v: point(&t["v"]).coords,
                };
                items.push(CutItem::Surface(Box::new(patch)));
            }
        }
    }
    let scene = Scene::parse(&toml::to_string(&table).unwrap(), path).unwrap();
    (
        scene,
        CutSet {
            items,
            snap: DEFAULT_SNAP,
        },
    )
}

/// The scene's model of `mesh` with the cut `cut` (fixes selected as the scene does, gravity, mass if dynamic).
pub fn build(scene: &Scene, mesh: &TetMesh, cut: Option<CutSetup>) -> Result<Model, ModelError> {
    let (lo, hi) = mesh.bounding_box();
    let tol = 1e-9 * (hi - lo).norm();
    let mut fixed = Vec::new();
    for (i, p) in mesh.nodes.iter().enumerate() {
        let mut c = [None; 3];
        for fx in &scene.fixes {
            if (0..3).all(|k| p[k] >= fx.min[k] - tol && p[k] <= fx.max[k] + tol) {
                for k in 0..3 {
                    if fx.components[k] {
                        c[k] = Some(fx.displacement[k]);
                    }
                }
            }
        }
        if c.iter().any(Option::is_some) {
            fixed.push((i, c));
        }
    }
    Model::build(ModelInput {
        mesh: mesh.clone(),
        material: scene.material,
        formulation: scene.formulation,
        cut,
        fixed,
        gravity: scene.gravity,
        body_force: None,
        tractions: &[],
        need_mass: matches!(scene.analysis, Analysis::Dynamic { .. }),
    })
}

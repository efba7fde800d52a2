//! Where a case's L2 error against its fine reference sits, and the total
//! potential energy Π of the run and of the reference: the error's share and the volume-averaged error
//! u_ref − u_h in each tenth of the body along z, for FEM on the pre-cut
//! mesh or X-FEM on the uncut one (tip, extend or geometric tip R = 5 mm).
//!
//! Π separates what L2 alone cannot: with the same Dirichlet data a
//! conforming solution's Π is above the exact one by half its energy-norm
//! error squared, so of two runs on one body the lower Π is the more
//! accurate in energy (`extend` lengthens the cut, a different body).
//!
//! `cargo run --release --example error_map -- cases/bend_face.toml tip 3 [tet10] [R=0.02] [ramp=on|off]`
//! (needs `make refs`: the graded reference and the meshes L0…L4). `R=`
//! sets `geo`'s radius (m); `ramp=on|off` forces the blending elements'
//! treatment (the ramp of corrected X-FEM, or none) where a case takes
//! `cut::Blending::for_cut` (the ramp where a Tet4 R spans 2.5 median edges).
//! What `cut::RAMP_SPAN` was chosen from: each of `gravity`, `stretch_face`,
//! `bend_face`, `stretch` at L0…L4 with R = 1, 1.5, 2, 2.5, 3, 4 × the
//! level's characteristic length (12, 8, 6, 4.5, 3.5 mm), ramp on and off.
use nalgebra::{Point3, Vector3};
use std::path::Path;
use xfem_cut::cut::Blending;
use xfem_cut::locate::Locator;
use xfem_cut::mesh::ElementKind;
use xfem_cut::quadrature::DEGREE5;
use xfem_cut::run::solve_scene;
use xfem_cut::scene::{FrontMode, Scene};
use xfem_cut::study::converge::{potential_energy, reference_of, GEOMETRIC_TIP_RADIUS};
use xfem_cut::study::reference::{out_dir, read_reference};
use xfem_cut::study::verify::{side_of, Field};

const SLABS: usize = 10;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [case, variant, level, ..] = args.as_slice() else {
        eprintln!("usage: error_map CASE fem|tip|extend|geo LEVEL [tet10] [R=m] [ramp=on|off]");
        std::process::exit(2);
    };
    let level: usize = level.parse().expect("level");
    let mut scene = Scene::load(Path::new(case)).expect("case");
    let flags = &args[3..];
    if flags.iter().any(|s| s == "tet10") {
        scene.element = ElementKind::Tet10;
    }
    let radius = flags
        .iter()
        .find_map(|s| s.strip_prefix("R="))
        .map_or(GEOMETRIC_TIP_RADIUS, |r| r.parse().expect("R=<metres>"));
    let blending = flags
        .iter()
        .find_map(|s| s.strip_prefix("ramp="))
        .map(|r| match r {
            "on" => Blending::Ramp,
            "off" => Blending::None,
            _ => panic!("ramp=on|off"),
        });
    let (family, reference) = reference_of(&scene.name).expect("no fine reference: make refs");
    let family = if variant == "fem" {
        scene.cuts.clear();
        family
    } else {
        for c in &mut scene.cuts {
            c.front = Some(match variant.as_str() {
                "extend" => FrontMode::Extend,
                _ => FrontMode::Tip,
            });
            c.tip_radius = (variant == "geo").then_some(radius);
            c.blending = blending;
        }
        "beam_uncut".to_string()
    };
    let mesh = out_dir().join(format!("meshes/{family}/L{level}.msh"));
    let reference = read_reference(&reference).expect("reference");
    let field = Field {
        mesh: &reference.mesh,
        values: &reference.u,
    };
    let result = solve_scene(&scene, level, Some(&mesh), false).expect("solve");
    let model = &result.model;
    let energy = potential_energy(model, &result.d);
    let locator = Locator::new(&model.mesh);
    // Our field at x, on the side of `centroid` (of the reference element) in a cut element.
    let ours = |x: &Point3<f64>, centroid: &Point3<f64>| {
        let (e, l) = locator
            .locate(&model.mesh, x)
            .expect("point outside our mesh");
        let side = side_of(model, e, centroid, l);
        model.displacement_at(&result.d, e, x, side)
    };
    let rmesh = &reference.mesh;
    let z_max = rmesh.nodes.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    let z_min = rmesh.nodes.iter().map(|p| p.z).fold(f64::MAX, f64::min);
    // Per slab: error², volume, ∫(u_ref − u_h), ∫u_ref.
    let mut slabs = vec![(0.0, 0.0, Vector3::zeros(), Vector3::zeros()); SLABS];
    let (mut err2, mut norm2) = (0.0, 0.0);
    // The reference's Π: its strain energy less the work of gravity.
    let rho_g = scene.gravity.unwrap_or_default() * scene.material.density;
    let mut reference_pi = field.strain_energy(&model.lame);
    for e in 0..rmesh.n_elements() {
        let p = rmesh.vertex_points(e);
        let vol = rmesh.volume(e).abs();
        let centroid = Point3::from(p.iter().fold(Vector3::zeros(), |s, q| s + q.coords) / 4.0);
        let k = (((centroid.z - z_min) / (z_max - z_min) * SLABS as f64) as usize).min(SLABS - 1);
        for q in &DEGREE5 {
            let x = Point3::from(
                p.iter()
                    .zip(q.bary)
                    .fold(Vector3::zeros(), |s, (pi, l)| s + pi.coords * l),
            );
            let u_ref = field.at(e, &q.bary);
            reference_pi -= q.weight * vol * rho_g.dot(&u_ref);
            let diff = u_ref - ours(&x, &centroid);
            let w = q.weight * vol;
            err2 += w * diff.norm_squared();
            norm2 += w * u_ref.norm_squared();
            slabs[k].0 += w * diff.norm_squared();
            slabs[k].1 += w;
            slabs[k].2 += diff * w;
            slabs[k].3 += u_ref * w;
        }
    }
    println!(
        "{} {variant} {} L{level}: {} DOFs, L2 {:.4e}, Π {energy:.8e} J (reference's {reference_pi:.8e} J{})",
        scene.name,
        scene.element.name(),
        model.n_free,
        (err2 / norm2).sqrt(),
        if scene.tractions.is_empty() { "" } else { ", tractions left out" }
    );
    for (k, (e2, vol, diff, u)) in slabs.iter().enumerate() {
        let z0 = z_min + (z_max - z_min) * k as f64 / SLABS as f64;
        let (d, u) = (diff / *vol, u / *vol);
        println!(
            "  z {z0:.4}…: {:5.1} % of the error², mean u_ref − u_h ({:+.2e}, {:+.2e}, {:+.2e}), mean u_ref ({:+.2e}, {:+.2e}, {:+.2e})",
            100.0 * e2 / err2, d.x, d.y, d.z, u.x, u.y, u.z
        );
    }
}

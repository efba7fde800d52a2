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
//! `cargo run --release --example error_map -- cases/bend_face.toml tip 3 [tet10] [R=0.02] [ramp=on|off] [mesh=DIR] [ref=FILE]`
//! (needs `make refs`: the graded reference and the meshes L0…L4). `mesh=DIR`
//! runs X-FEM on `DIR/L<level>.msh` instead: e.g. the crack mesh
//! with its crack nodes not duplicated (`refs/crack_mesh_uncut.py H
//! DIR/L<level>.msh`, H the level's size in
//! `refs/out/meshes/beam_crack/L<level>.json`), on which X-FEM with the
//! extended front equals FEM on the pre-cut mesh and the tip front can be
//! set beside remeshed FEM on one mesh; with `--strip-edges HS` that mesh
//! is graded towards the face cases' strip edges, the cases' second
//! singular line. `ref=FILE` judges against another reference VTU (e.g.
//! one solved on a mesh graded otherwise). `R=`
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
use xfem_cut::study::one_mesh::{self, OneMeshRow};
use xfem_cut::study::ramp::{write_csv, RampRow};
use xfem_cut::study::reference::{out_dir, read_reference};
use xfem_cut::study::verify::{side_of, Field};

const SLABS: usize = 10;

/// One run against its reference: what `main` prints and the grid records.
struct Comparison {
    dofs: usize,
    median_edge: f64,
    l2: f64,
    energy: f64,
    reference_energy: f64,
    /// Per tenth of the body along z: its share of the error², the mean
    /// u_ref − u_h and the mean u_ref.
    slabs: Vec<(f64, Vector3<f64>, Vector3<f64>)>,
    z_range: (f64, f64),
}

/// `scene` (its cuts set up as `variant` asks) at `level` against its fine reference.
fn compare(
    mut scene: Scene,
    variant: &str,
    level: usize,
    radius: f64,
    blending: Option<Blending>,
    mesh_dir: Option<&Path>,
    reference_file: Option<&Path>,
) -> Comparison {
    let (family, reference) = reference_of(&scene.name).expect("no fine reference: make refs");
    let reference = reference_file.map_or(reference, Path::to_path_buf);
    let family = if variant == "fem" {
        scene.cuts.clear();
        family
    } else {
        for c in &mut scene.cuts {
            c.front = Some(match variant {
                "extend" => FrontMode::Extend,
                _ => FrontMode::Tip,
            });
            c.tip_radius = (variant == "geo").then_some(radius);
            c.blending = blending;
        }
        "beam_uncut".to_string()
    };
    // FEM keeps the pre-cut mesh (the cut is in it).
    let mesh = match mesh_dir.filter(|_| variant != "fem") {
        Some(dir) => dir.join(format!("L{level}.msh")),
        None => out_dir().join(format!("meshes/{family}/L{level}.msh")),
    };
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
    Comparison {
        dofs: model.n_free,
        median_edge: model.mesh.median_edge_length(),
        l2: (err2 / norm2).sqrt(),
        energy,
        reference_energy: reference_pi,
        slabs: slabs
            .iter()
            .map(|(e2, vol, diff, u)| (e2 / err2, diff / *vol, u / *vol))
            .collect(),
        z_range: (z_min, z_max),
    }
}

/// Cases, levels' characteristic lengths (m) and radii (× that length) of
/// the grid behind `cut::RAMP_SPAN`.
const GRID_CASES: [&str; 4] = ["gravity", "stretch_face", "bend_face", "stretch"];
const GRID_LENGTHS: [f64; 5] = [0.012, 0.008, 0.006, 0.0045, 0.0035];
const GRID_FACTORS: [f64; 6] = [1.0, 1.5, 2.0, 2.5, 3.0, 4.0];

/// Every case, level and radius of the grid, with and without the ramp
/// (Tet4); rows to `csv` (whole, at the end).
fn ramp_span(csv: &Path) {
    let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut rows = Vec::new();
    for case in GRID_CASES {
        let scene = Scene::load(&cases.join(format!("{case}.toml"))).expect("case");
        for (level, length) in GRID_LENGTHS.iter().enumerate() {
            for factor in GRID_FACTORS {
                let radius = factor * length;
                for ramp in [false, true] {
                    let blending = Some(if ramp { Blending::Ramp } else { Blending::None });
                    let c = compare(scene.clone(), "geo", level, radius, blending, None, None);
                    eprintln!(
                        "{case} L{level} R {:.2} mm ramp {ramp}: {} DOFs, L2 {:.4e}, Π − Π_ref {:.4e} J",
                        radius * 1e3,
                        c.dofs,
                        c.l2,
                        c.energy - c.reference_energy
                    );
                    rows.push(RampRow {
                        case: case.to_string(),
                        level,
                        median_edge_m: c.median_edge,
                        radius_m: radius,
                        ramp,
                        dofs: c.dofs,
                        l2_rel: c.l2,
                        potential_energy_j: c.energy,
                        reference_energy_j: c.reference_energy,
                    });
                }
            }
        }
    }
    write_csv(csv, &rows).expect("writing the CSV");
    eprintln!("wrote {}", csv.display());
}

/// The one-mesh comparison's meshes (`refs/out/meshes/<family>/L<k>.msh`,
/// written by `refs/crack_mesh_uncut.py`, `make report`) with the runs on
/// each (the variant `compare` takes, the row's name), its cases and levels
/// per element. The last holds no crack (X-FEM's front inside elements, as
/// in the study's X-FEM rows): the tip front alone runs there, beside the
/// FEM run on the crack mesh graded alike ([`one_mesh::fem_mesh`]).
type MeshRuns = (
    &'static str,
    &'static str,
    &'static [(&'static str, &'static str)],
);
const BOTH: &[(&str, &str)] = &[("extend", "FEM"), ("tip", "tip")];
const ONE_MESH_FAMILIES: [MeshRuns; 3] = [
    ("uniform", "beam_crack_shared", BOTH),
    ("strip edges", "beam_crack_shared_strips", BOTH),
    (
        one_mesh::UNCUT_STRIPS,
        "beam_uncut_strips",
        &[("tip", "tip")],
    ),
];
const ONE_MESH_CASES: [&str; 2] = ["bend_face", "stretch_face"];
/// (Tet4 to L4, a few seconds a run; Tet10 at L4 would hold about 270k DOFs.)
const ONE_MESH_LEVELS: [(ElementKind, &[usize]); 2] = [
    (ElementKind::Tet4, &[1, 2, 3, 4]),
    (ElementKind::Tet10, &[1, 2, 3]),
];

/// Every case, mesh family, element and level of the one-mesh comparison,
/// the extended front (FEM on that mesh) and the tip front (the tip front
/// alone on the uncut mesh); rows to `csv` (whole, at the end).
fn one_mesh(csv: &Path) {
    let cases = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases");
    let mut rows = Vec::new();
    for case in ONE_MESH_CASES {
        let mut scene = Scene::load(&cases.join(format!("{case}.toml"))).expect("case");
        for (mesh, family, variants) in ONE_MESH_FAMILIES {
            let dir = out_dir().join("meshes").join(family);
            for (element, levels) in ONE_MESH_LEVELS {
                scene.element = element;
                for &level in levels {
                    for &(variant, name) in variants {
                        let c = compare(scene.clone(), variant, level, 0.0, None, Some(&dir), None);
                        eprintln!(
                            "{case} {mesh} {} L{level} {name}: {} DOFs, L2 {:.4e}, Π {:.8e} J (reference's {:.8e} J)",
                            element.name(),
                            c.dofs,
                            c.l2,
                            c.energy,
                            c.reference_energy
                        );
                        rows.push(OneMeshRow {
                            case: case.to_string(),
                            mesh: mesh.to_string(),
                            element: element.name().to_string(),
                            level,
                            variant: name.to_string(),
                            dofs: c.dofs,
                            l2_rel: c.l2,
                            potential_energy_j: c.energy,
                            reference_energy_j: c.reference_energy,
                        });
                    }
                }
            }
        }
    }
    one_mesh::write_csv(csv, &rows).expect("writing the CSV");
    eprintln!("wrote {}", csv.display());
}

/// A study `make report` runs: its name, its CSV's default path, the run.
type Study = (&'static str, &'static str, fn(&Path));

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let studies: [Study; 2] = [
        ("ramp-span", "reports/data/ramp_span.csv", ramp_span),
        ("one-mesh", "reports/data/one_mesh.csv", one_mesh),
    ];
    if let Some((_, default, run)) = studies
        .iter()
        .find(|(name, ..)| args.first().is_some_and(|a| a == name))
    {
        let csv = match args.get(1..) {
            Some([flag, path, ..]) if flag == "--csv" => path.as_str(),
            _ => default,
        };
        run(Path::new(csv));
        return;
    }
    let [case, variant, level, ..] = args.as_slice() else {
        eprintln!("usage: error_map CASE fem|tip|extend|geo LEVEL [tet10] [R=m] [ramp=on|off] [mesh=DIR] [ref=FILE] | ramp-span [--csv FILE] | one-mesh [--csv FILE]");
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
    let mesh_dir = flags
        .iter()
        .find_map(|s| s.strip_prefix("mesh="))
        .map(Path::new);
    let reference_file = flags
        .iter()
        .find_map(|s| s.strip_prefix("ref="))
        .map(Path::new);
    let tractions = !scene.tractions.is_empty();
    let (name, element) = (scene.name.clone(), scene.element);
    let c = compare(
        scene,
        variant,
        level,
        radius,
        blending,
        mesh_dir,
        reference_file,
    );
    println!(
        "{name} {variant} {} L{level}: {} DOFs, L2 {:.4e}, Π {:.8e} J (reference's {:.8e} J{})",
        element.name(),
        c.dofs,
        c.l2,
        c.energy,
        c.reference_energy,
        if tractions {
            ", tractions left out"
        } else {
            ""
        }
    );
    let (z_min, z_max) = c.z_range;
    for (k, (share, d, u)) in c.slabs.iter().enumerate() {
        let z0 = z_min + (z_max - z_min) * k as f64 / SLABS as f64;
        println!(
            "  z {z0:.4}…: {:5.1} % of the error², mean u_ref − u_h ({:+.2e}, {:+.2e}, {:+.2e}), mean u_ref ({:+.2e}, {:+.2e}, {:+.2e})",
            100.0 * share, d.x, d.y, d.z, u.x, u.y, u.z
        );
    }
}

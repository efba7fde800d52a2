//! The convergence study behind `xfem-cut converge`: every variant of a case
//! at every level, its L2 error against the fine FEniCSx P2 reference, DOFs
//! and times, as CSV rows for the report.
//!
//! Variants: FEM on the gmsh pre-cut meshes (the "perfectly remeshed cut"),
//! X-FEM on the structured box levels of the case and on the unstructured
//! uncut gmsh meshes, each with Tet4 and Tet10. On the unstructured meshes
//! (where the front lies inside elements) the linear study runs the three
//! front treatments side by side: topological tip enrichment, the seed's
//! extended front, and geometric tip enrichment within
//! [`GEOMETRIC_TIP_RADIUS`].

use crate::assembly::{evaluate, Request, Rotations, Workspace};
use crate::cut::{CutSurface, PlanarPatch};
use crate::io::csv::{read_rows, sci, write_rows};
use crate::io::IoError;
use crate::locate::Locator;
use crate::mesh::ElementKind;
use crate::model::{Formulation, Model};
use crate::run::{evaluate_on_side, solve_scene};
use crate::scene::{BodyGeometry, FrontMode, Scene};
use crate::study::reference::{out_dir, read_reference, Reference};
use crate::study::verify::{l2_error, Field};
use crate::study::StudyError;
use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One run of the study: a row of `convergence.csv` (header [`CSV_HEADER`]).
#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub case: String,
    pub variant: String,
    pub element: &'static str,
    pub level: usize,
    /// Characteristic size: (volume / elements)^(1/3) of the mesh.
    #[serde(serialize_with = "sci")]
    pub h: f64,
    pub elements: usize,
    pub dofs: usize,
    /// Cut set-up, element data, pattern and symbolic factorisation (s).
    #[serde(rename = "precompute_s", serialize_with = "sci")]
    pub precompute: f64,
    /// Numeric factorisation and solve (s).
    #[serde(rename = "solve_s", serialize_with = "sci")]
    pub solve: f64,
    #[serde(rename = "l2_rel", serialize_with = "sci")]
    pub l2: f64,
    /// Relative error of the crack opening [u] = u(+) − u(−) sampled on the
    /// cut patch (NaN without a cut; rows of the first layout lack it).
    #[serde(rename = "opening_rel", serialize_with = "sci")]
    pub opening: f64,
    /// Largest probe error relative to the largest probe displacement (NaN without probes).
    #[serde(rename = "probe_rel", serialize_with = "sci")]
    pub probes: f64,
    /// Total potential energy Π = E_strain − f·u of the solution (J; NaN in
    /// rows of the layouts before it). With the same body and Dirichlet
    /// data, Π of a conforming solution exceeds the exact one by half its
    /// energy-norm error squared: of two runs, the lower Π is the more
    /// accurate in energy, whatever the L2 errors say.
    #[serde(rename = "potential_energy_j", serialize_with = "sci")]
    pub energy: f64,
}

pub const CSV_HEADER: &str =
    "case,variant,element,level,h,elements,dofs,precompute_s,solve_s,l2_rel,opening_rel,probe_rel,potential_energy_j";

/// A row as read, before its element name is checked (`Row` holds a `&'static str`).
#[derive(Deserialize)]
struct RowRecord {
    case: String,
    variant: String,
    element: String,
    level: usize,
    h: f64,
    elements: usize,
    dofs: usize,
    precompute_s: f64,
    solve_s: f64,
    l2_rel: f64,
    /// Rows of the first layout (10 fields) lack these two.
    opening_rel: Option<f64>,
    probe_rel: Option<f64>,
    /// Rows of the first two layouts (10 and 12 fields) lack it.
    potential_energy_j: Option<f64>,
}

impl<'de> Deserialize<'de> for Row {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Row, D::Error> {
        Row::try_from(RowRecord::deserialize(d)?).map_err(serde::de::Error::custom)
    }
}

/// A study row naming an element kind the study does not run.
#[derive(Debug, thiserror::Error)]
#[error("element must be tet4 or tet10, got {0:?}")]
pub struct UnknownElement(String);

impl TryFrom<RowRecord> for Row {
    type Error = UnknownElement;

    fn try_from(r: RowRecord) -> Result<Row, UnknownElement> {
        let element = match r.element.as_str() {
            "tet4" => "tet4",
            "tet10" => "tet10",
            other => return Err(UnknownElement(other.to_string())),
        };
        Ok(Row {
            case: r.case,
            variant: r.variant,
            element,
            level: r.level,
            h: r.h,
            elements: r.elements,
            dofs: r.dofs,
            precompute: r.precompute_s,
            solve: r.solve_s,
            l2: r.l2_rel,
            opening: r.opening_rel.unwrap_or(f64::NAN),
            probes: r.probe_rel.unwrap_or(f64::NAN),
            energy: r.potential_energy_j.unwrap_or(f64::NAN),
        })
    }
}

/// The pre-cut mesh family of a case and its fine reference, if `make refs` built one.
pub fn reference_of(case: &str) -> Option<(String, PathBuf)> {
    let dir = out_dir().join(case);
    let entries = std::fs::read_dir(&dir).ok()?;
    let mut found: Vec<(String, PathBuf)> = entries
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().to_string_lossy().to_string();
            let family = name.strip_suffix("_fine")?.to_string();
            let p2 = e.path().join("p2.vtu");
            p2.exists().then_some((family, p2))
        })
        .collect();
    found.sort();
    found.pop()
}

/// Meshes of a family at levels L0, L1, … that exist.
fn family_meshes(family: &str) -> Vec<PathBuf> {
    (0..10)
        .map(|k| out_dir().join(format!("meshes/{family}/L{k}.msh")))
        .take_while(|p| p.exists())
        .collect()
}

/// The corotational reference of a case: our corotational Tet10 FEM solve
/// on the finest pre-cut level whose DOFs fit `max_dofs` (the solver is
/// tested equal to scikit-fem's on L0 to 1e-14). Returns it and its level.
fn corotational_reference(
    base: &Scene,
    family: &str,
    max_dofs: usize,
    progress: &mut impl FnMut(&str),
) -> Result<(Reference, usize), StudyError> {
    let meshes = family_meshes(family);
    let mut chosen = None;
    for (k, path) in meshes.iter().enumerate() {
        let m = base.read_mesh(path)?;
        if 3 * m.to_tet10().n_nodes() <= max_dofs {
            chosen = Some(k);
        }
    }
    let level = chosen.filter(|&k| k >= 2).ok_or_else(|| {
        StudyError::Precondition(format!(
            "{}: the corotational study needs a pre-cut level ≥ L2 within {max_dofs} DOFs for its reference (raise --max-dofs or run `make refs`)",
            base.name
        ))
    })?;
    let mut scene = base.clone();
    scene.cuts.clear();
    scene.element = ElementKind::Tet10;
    scene.formulation = Formulation::Corotational;
    let t0 = Instant::now();
    let result = solve_scene(&scene, level, Some(&meshes[level]), false).map_err(|e| {
        StudyError::from(e).during(format!("{}: corotational reference", base.name))
    })?;
    let u = (0..result.model.mesh.n_nodes())
        .map(|i| result.model.node_displacement(&result.d, i, 0))
        .collect();
    progress(&format!(
        "{} reference: corotational Tet10 FEM pre-cut L{level}, {} DOFs, Newton iterations {:?} ({:.1} s)",
        base.name,
        result.model.n_free,
        result.iterations,
        t0.elapsed().as_secs_f64()
    ));
    Ok((
        Reference {
            mesh: result.model.mesh,
            u,
        },
        level,
    ))
}

/// Runs the study for one case; `progress` is told each finished run.
///
/// `corotational`: every variant is solved corotational (static Newton) and
/// compared with [`corotational_reference`]; only levels below the
/// reference's run.
pub fn converge_case(
    case_path: &Path,
    max_dofs: usize,
    corotational: bool,
    mut progress: impl FnMut(&str),
) -> Result<Vec<Row>, StudyError> {
    let base = Scene::load(case_path)?;
    let (family, ref_path) = reference_of(&base.name).ok_or_else(|| {
        StudyError::Precondition(format!(
            "{}: no fine reference in refs/out/{}/*_fine/p2.vtu (`make refs` makes them for the cases refs/make_refs.py names in FAMILY, the seed's beam; another case has none to converge against)",
            case_path.display(),
            base.name
        ))
    })?;
    let (reference, below) = if corotational {
        corotational_reference(&base, &family, max_dofs, &mut progress)?
    } else {
        (read_reference(&ref_path)?, usize::MAX)
    };
    let field = Field {
        mesh: &reference.mesh,
        values: &reference.u,
    };
    let mut rows = Vec::new();
    let ref_locator = Locator::new(&reference.mesh);
    let ref_at = |x: &Point3<f64>| {
        ref_locator
            .locate(&reference.mesh, x)
            .map(|(e, l)| field.at(e, &l))
    };
    // Points on the crack (inside the body), the side offset and the reference jumps there.
    let patch: Option<PlanarPatch> = base.patches().next().cloned();
    let offset = patch
        .as_ref()
        .map_or(Vector3::zeros(), |p| p.normal() * SIDE_OFFSET);
    let mut crack: Vec<(Point3<f64>, Vector3<f64>)> = Vec::new();
    if let Some(p) = &patch {
        let (ns, nt) = (12, 24);
        for i in 0..ns {
            for j in 0..nt {
                let x = p.origin
                    + p.u * ((i as f64 + 0.5) / ns as f64)
                    + p.v * ((j as f64 + 0.5) / nt as f64);
                if let (Some(a), Some(b)) = (ref_at(&(x + offset)), ref_at(&(x - offset))) {
                    crack.push((x, a - b));
                }
            }
        }
    }
    // Probes on the cut are read on its + side (as `run` does).
    // (point, on the cut, reference value)
    let probes: Vec<(Point3<f64>, bool, Vector3<f64>)> = base
        .probes
        .iter()
        .filter_map(|x| {
            let on_cut = patch.as_ref().is_some_and(|p| {
                let tol = 1e-9 * (p.u.norm() + p.v.norm());
                p.level_set(x).abs() < 1e-12 && p.contains(x, tol)
            });
            ref_at(&if on_cut { x + offset } else { *x }).map(|u| (*x, on_cut, u))
        })
        .collect();

    // (variant, element, level, mesh override, keep the cut, front treatment)
    let mut runs: Vec<Run> = Vec::new();
    for element in [ElementKind::Tet4, ElementKind::Tet10] {
        for (k, m) in family_meshes(&family).into_iter().enumerate() {
            runs.push(Run::new("FEM pre-cut", element, k, Some(m), None));
        }
        if !base.cuts.is_empty() {
            if let BodyGeometry::Box { levels, .. } = &base.geometry {
                for k in 0..levels.len() {
                    runs.push(Run::new(
                        "X-FEM structured",
                        element,
                        k,
                        None,
                        Some(Front::Case),
                    ));
                }
            }
            for (k, m) in family_meshes("beam_uncut").into_iter().enumerate() {
                // The linear study sets the three front treatments side by side
                // (the corotational one keeps the case's own).
                let fronts: &[Front] = if corotational {
                    &[Front::Case]
                } else {
                    &[Front::Tip, Front::Extend, Front::Geometric]
                };
                for &front in fronts {
                    runs.push(Run::new(
                        front.variant(),
                        element,
                        k,
                        Some(m.clone()),
                        Some(front),
                    ));
                }
            }
        }
    }
    // Whether the case's cut has a front inside the body (set by the first
    // tip-enriched run; without one the front variants are the same run).
    let mut has_front: Option<bool> = None;
    for Run {
        variant,
        element,
        level,
        mesh,
        front,
    } in runs
    {
        if level >= below {
            continue;
        }
        if matches!(front, Some(Front::Extend | Front::Geometric)) && has_front == Some(false) {
            continue;
        }
        let mut scene = base.clone();
        scene.element = element;
        if corotational {
            scene.formulation = Formulation::Corotational;
        }
        match front {
            None => scene.cuts.clear(),
            Some(f) => f.apply(&mut scene),
        }
        // Skip runs beyond the DOF budget (estimated from the mesh before solving).
        let t0 = Instant::now();
        let m = match &mesh {
            Some(p) => scene.read_mesh(p)?,
            None => scene.mesh(level)?,
        };
        let estimate = 3 * if element == ElementKind::Tet10 {
            m.to_tet10().n_nodes()
        } else {
            m.n_nodes()
        };
        if estimate > max_dofs {
            progress(&format!(
                "skip {} {variant} {} L{level}: ~{estimate} DOFs > {max_dofs}",
                base.name,
                element.name()
            ));
            continue;
        }
        let keep_cut = front.is_some();
        let result = solve_scene(&scene, level, mesh.as_deref(), false)?;
        let n_tip = result.model.cut.as_ref().map_or(0, |c| c.n_tip());
        if front == Some(Front::Tip) && has_front.is_none() {
            has_front = Some(n_tip > 0);
        }
        // Without a front the tip run is plain Heaviside X-FEM.
        let variant = if front == Some(Front::Tip) && has_front == Some(false) {
            "X-FEM unstructured".to_string()
        } else {
            variant
        };
        let wall = t0.elapsed().as_secs_f64();
        let t = result.timings;
        // Mesh reading is not precompute (FEniCSx times exclude it too).
        let precompute = t.precompute();
        let locator = Locator::new(&result.model.mesh);
        let err = l2_error(&field, &result.model, &result.d, &locator).map_err(|e| {
            StudyError::from(e).during(format!("{}: {variant} L{level}", base.name))
        })?;
        let ours = |x: &Point3<f64>, side: Option<i8>| {
            evaluate_on_side(&result.model, &locator, &result.d, x, side)
        };
        // Ours on each face of the cut exactly (FEM: its faces are the pre-cut
        // mesh's, read off the plane as the reference is).
        let opening = relative_error(crack.iter().map(|(x, jump)| {
            let mine = if keep_cut {
                ours(x, Some(1)).zip(ours(x, Some(-1)))
            } else {
                ours(&(x + offset), None).zip(ours(&(x - offset), None))
            };
            (mine.map(|(a, b)| a - b), *jump)
        }));
        let probe_error = {
            let scale = probes.iter().map(|(_, _, u)| u.norm()).fold(0.0, f64::max);
            probes
                .iter()
                .map(|(x, on_cut, u)| {
                    let v = match (on_cut, keep_cut) {
                        (true, true) => ours(x, Some(1)),
                        (true, false) => ours(&(x + offset), None),
                        (false, _) => ours(x, None),
                    };
                    v.map_or(f64::INFINITY, |v| (v - u).norm())
                })
                .fold(f64::NAN, f64::max)
                / scale
        };
        let mesh_ref = &result.model.mesh;
        let volume: f64 = (0..mesh_ref.n_elements()).map(|e| mesh_ref.volume(e)).sum();
        let row = Row {
            case: base.name.clone(),
            variant,
            element: element.name(),
            level,
            h: (volume / mesh_ref.n_elements() as f64).cbrt(),
            elements: mesh_ref.n_elements(),
            dofs: result.model.n_free,
            precompute,
            solve: t.solve,
            l2: err.relative,
            opening,
            probes: probe_error,
            energy: potential_energy(&result.model, &result.d),
        };
        progress(&format!(
            "{} {} {} L{}: {} DOFs, L2 {:.3e}, opening {:.3e}, probes {:.3e}, Π {:.6e} J, precompute {:.1} ms, solve {:.1} ms ({:.1} s)",
            row.case,
            row.variant,
            row.element,
            row.level,
            row.dofs,
            row.l2,
            row.opening,
            row.probes,
            row.energy,
            row.precompute * 1e3,
            row.solve * 1e3,
            wall
        ));
        rows.push(row);
    }
    Ok(rows)
}

/// One run of the study before it is solved.
struct Run {
    variant: String,
    element: ElementKind,
    level: usize,
    /// A gmsh mesh instead of the case's structured level.
    mesh: Option<PathBuf>,
    /// `None`: FEM (the cut removed, the mesh is pre-cut).
    front: Option<Front>,
}

impl Run {
    fn new(
        variant: &str,
        element: ElementKind,
        level: usize,
        mesh: Option<PathBuf>,
        front: Option<Front>,
    ) -> Run {
        Run {
            variant: variant.to_string(),
            element,
            level,
            mesh,
            front,
        }
    }
}

/// The tip radius of the geometric variant (m): a third of the seed beam's
/// ligament (15 mm), fixed as h → 0 as geometric enrichment needs.
pub const GEOMETRIC_TIP_RADIUS: f64 = 0.005;

/// The front treatment of an X-FEM run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Front {
    /// As the case file says.
    Case,
    /// Topological tip enrichment (the nodes of front elements).
    Tip,
    /// The seed's: the cut extended to the faces of the front elements.
    Extend,
    /// Tip enrichment of every node within [`GEOMETRIC_TIP_RADIUS`] of the front.
    Geometric,
}

impl Front {
    fn variant(self) -> &'static str {
        match self {
            Front::Case => "X-FEM unstructured",
            Front::Tip => "X-FEM unstructured, tip",
            Front::Extend => "X-FEM unstructured, extend",
            Front::Geometric => "X-FEM unstructured, geometric tip R=5 mm",
        }
    }

    /// Sets every cut of the scene to this treatment.
    fn apply(self, scene: &mut Scene) {
        let (mode, radius) = match self {
            Front::Case => return,
            Front::Tip => (FrontMode::Tip, None),
            Front::Extend => (FrontMode::Extend, None),
            Front::Geometric => (FrontMode::Tip, Some(GEOMETRIC_TIP_RADIUS)),
        };
        for cut in &mut scene.cuts {
            cut.front = Some(mode);
            cut.tip_radius = radius;
        }
    }
}

/// Total potential energy Π = E_strain(d) − f·d of displacements `d`
/// (corotational: the corotated strain energy).
pub fn potential_energy(model: &Model, d: &[f64]) -> f64 {
    let strain = evaluate(
        model,
        d,
        &mut Rotations::identity(model),
        &mut Workspace::new(model),
        Request {
            forces: None,
            tangent: None,
            update_rotations: model.formulation == Formulation::Corotational,
            exact_tangent: false,
        },
    );
    strain - model.load.iter().zip(d).map(|(f, u)| f * u).sum::<f64>()
}

/// Offset from the cut plane at which each side is read (m): far beyond the
/// locator's tolerance, far below any element size.
const SIDE_OFFSET: f64 = 1e-8;

/// sqrt(Σ|ours − ref|²) / sqrt(Σ|ref|²) over the pairs (a missing value of
/// ours counts as an infinite error); NaN when there are none.
fn relative_error(pairs: impl Iterator<Item = (Option<Vector3<f64>>, Vector3<f64>)>) -> f64 {
    let (mut num, mut den, mut n) = (0.0, 0.0, 0);
    for (mine, want) in pairs {
        num += mine.map_or(f64::INFINITY, |m| (m - want).norm_squared());
        den += want.norm_squared();
        n += 1;
    }
    if n == 0 {
        f64::NAN
    } else {
        (num / den).sqrt()
    }
}

/// Writes rows as CSV (whole or not at all), creating the folder.
pub fn write_csv(path: &Path, rows: &[Row]) -> Result<(), IoError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| IoError::os(dir, "create the folder", e))?;
    }
    write_rows(path, rows)
}

/// Reads rows written by [`write_csv`] (and rows of the first layout, 10 fields).
pub fn read_csv(path: &Path) -> Result<Vec<Row>, IoError> {
    read_rows(path, true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_and_old_rows_read_without_the_new_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.csv");
        let text = format!(
            "{CSV_HEADER}\ngravity,X-FEM unstructured,tet10,2,3e-3,100,300,1e-2,2e-2,5e-3,4e-2,6e-3,-2.5e-1\ngravity,FEM pre-cut,tet4,0,3e-3,100,300,1e-2,2e-2,5e-3\ngravity,FEM pre-cut,tet4,1,3e-3,100,300,1e-2,2e-2,5e-3,4e-2,6e-3\n"
        );
        std::fs::write(&p, &text).unwrap();
        let rows = read_csv(&p).unwrap();
        assert_eq!(
            (rows[0].opening, rows[0].probes, rows[0].energy),
            (4e-2, 6e-3, -0.25)
        );
        assert!(rows[1].opening.is_nan() && rows[1].probes.is_nan() && rows[1].energy.is_nan());
        assert_eq!((rows[2].probes, rows[2].energy.is_nan()), (6e-3, true));
        write_csv(&p, &rows[..1]).unwrap();
        let written = std::fs::read_to_string(&p).unwrap();
        assert_eq!(
            written,
            text.lines()
                .take(2)
                .map(|l| format!("{l}\n"))
                .collect::<String>()
        );
        std::fs::write(&p, format!("{CSV_HEADER}\ngravity,FEM pre-cut,tet4\n")).unwrap();
        let err = read_csv(&p).unwrap_err().to_string();
        assert!(err.contains("c.csv") && err.contains("line 2"), "{err}");
    }

    #[test]
    fn the_shipped_study_csvs_read_and_write_back_byte_for_byte() {
        let dir = tempfile::tempdir().unwrap();
        let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/data");
        for name in ["convergence.csv", "convergence_corot.csv"] {
            let rows = read_csv(&data.join(name)).unwrap();
            assert!(!rows.is_empty());
            write_csv(&dir.path().join(name), &rows).unwrap();
            assert_eq!(
                std::fs::read_to_string(dir.path().join(name)).unwrap(),
                std::fs::read_to_string(data.join(name)).unwrap(),
                "{name}"
            );
        }
        let rows = crate::study::stress::read_csv(&data.join("stress.csv")).unwrap();
        crate::study::stress::write_csv(&dir.path().join("stress.csv"), &rows).unwrap();
        assert_eq!(
            std::fs::read_to_string(dir.path().join("stress.csv")).unwrap(),
            std::fs::read_to_string(data.join("stress.csv")).unwrap()
        );
    }

    /// Π is stationary at the solution and there −½ f·u (loads only, no
    /// prescribed motion): the seed's gravity beam, its cut shortened so that
    /// the front lies inside elements, tip-enriched.
    #[test]
    fn potential_energy_is_least_at_the_solution() {
        let case = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/gravity.toml");
        let text = std::fs::read_to_string(&case).unwrap();
        let scene = Scene::parse(&text.replace("u = [0.015,", "u = [0.0137,"), &case).unwrap();
        let r = solve_scene(&scene, 0, None, false).unwrap();
        let (m, d) = (&r.model, &r.d);
        assert!(m.cut.as_ref().unwrap().n_tip() > 0);
        let pi = potential_energy(m, d);
        let work: f64 = m.load.iter().zip(d).map(|(f, u)| f * u).sum();
        assert!(
            (pi + 0.5 * work).abs() < 1e-9 * work.abs(),
            "Π {pi}, f·u {work}"
        );
        // A perturbation of every free DOF (enriched ones included).
        let scale = d.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let v: Vec<f64> = (0..d.len())
            .map(|i| {
                if m.equation[i] == crate::model::NONE {
                    0.0
                } else {
                    1e-3 * scale * (i as f64).sin()
                }
            })
            .collect();
        let at = |t: f64| {
            let x: Vec<f64> = d.iter().zip(&v).map(|(a, b)| a + t * b).collect();
            potential_energy(m, &x)
        };
        let (up, down) = (at(1.0) - pi, at(-1.0) - pi);
        assert!(up > 0.0 && down > 0.0, "{up} {down}");
        assert!(
            (up - down).abs() < 1e-6 * up,
            "first variation not zero: {up} {down}"
        );
    }

    #[test]
    fn relative_error_is_the_discrete_l2_ratio() {
        let x = Vector3::new(3.0, 0.0, 4.0);
        let pairs = [(Some(x * 1.1), x), (Some(x), x)];
        let e = relative_error(pairs.into_iter());
        assert!((e - (0.25f64 / 50.0).sqrt()).abs() < 1e-15);
        assert!(relative_error(std::iter::empty()).is_nan());
        assert!(relative_error([(None, x)].into_iter()).is_infinite());
    }
}

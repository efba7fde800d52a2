//! The convergence study behind `xfem-cut converge`: every variant of a case
//! at every level, its L2 error against the fine FEniCSx P2 reference, DOFs
//! and times, as CSV rows for the report.
//!
//! Variants: FEM on the gmsh pre-cut meshes (the "perfectly remeshed cut"),
//! X-FEM on the structured box levels of the case and on the unstructured
//! uncut gmsh meshes, each with Tet4 and Tet10.

use crate::cut::{CutSurface, PlanarPatch};
use crate::locate::Locator;
use crate::mesh::ElementKind;
use crate::model::Formulation;
use crate::run::{evaluate_at, solve_scene};
use crate::scene::{BodyGeometry, Scene};
use crate::study::reference::{out_dir, read_reference, Reference};
use crate::study::verify::{l2_error, Field};
use nalgebra::{Point3, Vector3};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One run of the study.
#[derive(Debug, Clone)]
pub struct Row {
    pub case: String,
    pub variant: String,
    pub element: &'static str,
    pub level: usize,
    /// Characteristic size: (volume / elements)^(1/3) of the mesh.
    pub h: f64,
    pub elements: usize,
    pub dofs: usize,
    /// Cut set-up, element data, pattern and symbolic factorisation (s).
    pub precompute: f64,
    /// Numeric factorisation and solve (s).
    pub solve: f64,
    pub l2: f64,
    /// Relative error of the crack opening [u] = u(+) − u(−) sampled on the
    /// cut patch (NaN without a cut).
    pub opening: f64,
    /// Largest probe error relative to the largest probe displacement (NaN without probes).
    pub probes: f64,
}

pub const CSV_HEADER: &str =
    "case,variant,element,level,h,elements,dofs,precompute_s,solve_s,l2_rel,opening_rel,probe_rel";

impl Row {
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{},{:e},{},{},{:e},{:e},{:e},{:e},{:e}",
            self.case,
            self.variant,
            self.element,
            self.level,
            self.h,
            self.elements,
            self.dofs,
            self.precompute,
            self.solve,
            self.l2,
            self.opening,
            self.probes
        )
    }

    pub fn parse(line: &str) -> Option<Row> {
        let f: Vec<&str> = line.split(',').collect();
        // Rows of the first layout (10 fields) had no opening and probe errors.
        if f.len() != 10 && f.len() != 12 {
            return None;
        }
        let extra = |k: usize| f.get(k).map_or(Some(f64::NAN), |v| v.parse().ok());
        Some(Row {
            case: f[0].to_string(),
            variant: f[1].to_string(),
            element: if f[2] == "tet10" { "tet10" } else { "tet4" },
            level: f[3].parse().ok()?,
            h: f[4].parse().ok()?,
            elements: f[5].parse().ok()?,
            dofs: f[6].parse().ok()?,
            precompute: f[7].parse().ok()?,
            solve: f[8].parse().ok()?,
            l2: f[9].parse().ok()?,
            opening: extra(10)?,
            probes: extra(11)?,
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
) -> Result<(Reference, usize), String> {
    let meshes = family_meshes(family);
    let mut chosen = None;
    for (k, path) in meshes.iter().enumerate() {
        let m = base.read_mesh(path).map_err(|e| e.to_string())?;
        if 3 * m.to_tet10().n_nodes() <= max_dofs {
            chosen = Some(k);
        }
    }
    let level = chosen.filter(|&k| k >= 2).ok_or_else(|| {
        format!(
            "{}: the corotational study needs a pre-cut level ≥ L2 within {max_dofs} DOFs for its reference (raise --max-dofs or run `make refs`)",
            base.name
        )
    })?;
    let mut scene = base.clone();
    scene.cuts.clear();
    scene.element = ElementKind::Tet10;
    scene.formulation = Formulation::Corotational;
    let t0 = Instant::now();
    let result = solve_scene(&scene, level, Some(&meshes[level]), false)
        .map_err(|e| format!("{}: corotational reference: {e}", base.name))?;
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
) -> Result<Vec<Row>, String> {
    let base = Scene::load(case_path).map_err(|e| e.to_string())?;
    let (family, ref_path) = reference_of(&base.name).ok_or_else(|| {
        format!(
            "{}: no fine reference in refs/out/{}/*_fine/p2.vtu (run `make refs`)",
            case_path.display(),
            base.name
        )
    })?;
    let (reference, below) = if corotational {
        corotational_reference(&base, &family, max_dofs, &mut progress)?
    } else {
        (
            read_reference(&ref_path).map_err(|e| e.to_string())?,
            usize::MAX,
        )
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
    let probes: Vec<(Point3<f64>, Vector3<f64>)> = base
        .probes
        .iter()
        .filter_map(|x| {
            let on_cut = patch
                .as_ref()
                .is_some_and(|p| p.level_set(x).abs() < 1e-12 && p.contains(x, 1e-9));
            let x = if on_cut { x + offset } else { *x };
            ref_at(&x).map(|u| (x, u))
        })
        .collect();

    // (variant, element, level, mesh override, keep the cut)
    let mut runs: Vec<(String, ElementKind, usize, Option<PathBuf>, bool)> = Vec::new();
    for element in [ElementKind::Tet4, ElementKind::Tet10] {
        for (k, m) in family_meshes(&family).into_iter().enumerate() {
            runs.push(("FEM pre-cut".into(), element, k, Some(m), false));
        }
        if !base.cuts.is_empty() {
            if let BodyGeometry::Box { levels, .. } = &base.geometry {
                for k in 0..levels.len() {
                    runs.push(("X-FEM structured".into(), element, k, None, true));
                }
            }
            for (k, m) in family_meshes("beam_uncut").into_iter().enumerate() {
                runs.push(("X-FEM unstructured".into(), element, k, Some(m), true));
            }
        }
    }
    for (variant, element, level, mesh, keep_cut) in runs {
        if level >= below {
            continue;
        }
        let mut scene = base.clone();
        scene.element = element;
        if corotational {
            scene.formulation = Formulation::Corotational;
        }
        if !keep_cut {
            scene.cuts.clear();
        }
        // Skip runs beyond the DOF budget (estimated from the mesh before solving).
        let t0 = Instant::now();
        let m = match &mesh {
            Some(p) => scene.read_mesh(p).map_err(|e| e.to_string())?,
            None => scene.mesh(level).map_err(|e| e.to_string())?,
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
        let result =
            solve_scene(&scene, level, mesh.as_deref(), false).map_err(|e| e.to_string())?;
        let wall = t0.elapsed().as_secs_f64();
        let t = result.timings;
        // Mesh reading is not precompute (FEniCSx times exclude it too).
        let precompute = t.cut + t.model + t.symbolic;
        let locator = Locator::new(&result.model.mesh);
        let err = l2_error(&field, &result.model, &result.d, &locator)
            .map_err(|e| format!("{}: {variant} L{level}: {e}", base.name))?;
        let ours = |x: &Point3<f64>| evaluate_at(&result.model, &locator, &result.d, x);
        let opening = relative_error(crack.iter().map(|(x, jump)| {
            let mine = ours(&(x + offset))
                .zip(ours(&(x - offset)))
                .map(|(a, b)| a - b);
            (mine, *jump)
        }));
        let probe_error = {
            let scale = probes.iter().map(|(_, u)| u.norm()).fold(0.0, f64::max);
            probes
                .iter()
                .map(|(x, u)| ours(x).map_or(f64::INFINITY, |v| (v - u).norm()))
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
        };
        progress(&format!(
            "{} {} {} L{}: {} DOFs, L2 {:.3e}, opening {:.3e}, probes {:.3e}, precompute {:.1} ms, solve {:.1} ms ({:.1} s)",
            row.case,
            row.variant,
            row.element,
            row.level,
            row.dofs,
            row.l2,
            row.opening,
            row.probes,
            row.precompute * 1e3,
            row.solve * 1e3,
            wall
        ));
        rows.push(row);
    }
    Ok(rows)
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

/// Writes rows as CSV (whole or not at all).
pub fn write_csv(path: &Path, rows: &[Row]) -> std::io::Result<()> {
    let mut s = String::from(CSV_HEADER);
    s.push('\n');
    for r in rows {
        let _ = writeln!(s, "{}", r.csv());
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let tmp = path.with_extension("csv.tmp");
    std::fs::write(&tmp, s)?;
    std::fs::rename(tmp, path)
}

/// Reads rows written by [`write_csv`].
pub fn read_csv(path: &Path) -> std::io::Result<Vec<Row>> {
    let text = std::fs::read_to_string(path)?;
    Ok(text.lines().skip(1).filter_map(Row::parse).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_and_old_rows_read_without_the_new_errors() {
        let line = "gravity,X-FEM unstructured,tet10,2,3e-3,100,300,1e-2,2e-2,5e-3,4e-2,6e-3";
        let r = Row::parse(line).unwrap();
        assert_eq!((r.opening, r.probes), (4e-2, 6e-3));
        assert_eq!(Row::parse(&r.csv()).unwrap().csv(), r.csv());
        let old = Row::parse("gravity,FEM pre-cut,tet4,0,3e-3,100,300,1e-2,2e-2,5e-3").unwrap();
        assert!(old.opening.is_nan() && old.probes.is_nan());
        assert!(Row::parse("gravity,FEM pre-cut,tet4").is_none());
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

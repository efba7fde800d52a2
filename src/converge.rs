//! The convergence study behind `xfem-cut converge`: every variant of a case
//! at every level, its L2 error against the fine FEniCSx P2 reference, DOFs
//! and times, as CSV rows for the report.
//!
//! Variants: FEM on the gmsh pre-cut meshes (the "perfectly remeshed cut"),
//! X-FEM on the structured box levels of the case and on the unstructured
//! uncut gmsh meshes, each with Tet4 and Tet10.

use crate::locate::Locator;
use crate::mesh::ElementKind;
use crate::reference::{out_dir, read_reference};
use crate::run::solve_scene;
use crate::scene::{BodyGeometry, Scene};
use crate::verify::{l2_error, Field};
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
}

pub const CSV_HEADER: &str =
    "case,variant,element,level,h,elements,dofs,precompute_s,solve_s,l2_rel";

impl Row {
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{},{:e},{},{},{:e},{:e},{:e}",
            self.case,
            self.variant,
            self.element,
            self.level,
            self.h,
            self.elements,
            self.dofs,
            self.precompute,
            self.solve,
            self.l2
        )
    }

    pub fn parse(line: &str) -> Option<Row> {
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != 10 {
            return None;
        }
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

/// Runs the study for one case; `progress` is told each finished run.
pub fn converge_case(
    case_path: &Path,
    max_dofs: usize,
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
    let reference = read_reference(&ref_path).map_err(|e| e.to_string())?;
    let field = Field {
        mesh: &reference.mesh,
        values: &reference.u,
    };
    let mut rows = Vec::new();

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
        let mut scene = base.clone();
        scene.element = element;
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
        };
        progress(&format!(
            "{} {} {} L{}: {} DOFs, L2 {:.3e}, precompute {:.1} ms, solve {:.1} ms ({:.1} s)",
            row.case,
            row.variant,
            row.element,
            row.level,
            row.dofs,
            row.l2,
            row.precompute * 1e3,
            row.solve * 1e3,
            wall
        ));
        rows.push(row);
    }
    Ok(rows)
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

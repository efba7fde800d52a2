//! The tip front beside remeshed FEM on one and the same mesh, with the
//! face cases' second singular line resolved or not. `bend_face` and
//! `stretch_face` move a strip of the top face; where the strip meets the
//! free face the solution is singular like at a crack front. The level
//! meshes leave that edge at their size, and there remeshed FEM's too-stiff
//! crack offsets the edge's too-stiff error (refs/README.md, "Why the strip
//! edges are graded"). `examples/error_map.rs one-mesh` solves each case on
//! gmsh's crack mesh with the crack's nodes shared (`refs/crack_mesh_uncut.py`:
//! X-FEM's extended front there is remeshed FEM to the last digit), uniform
//! and graded to h/4 at the strip edges, with the extended front ("FEM") and
//! the tip front, and writes one row per run against the FEniCSx reference.

use crate::io::IoError;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

/// The CSV `examples/error_map.rs one-mesh` writes, in `reports/`.
pub const CSV: &str = "data/one_mesh.csv";

/// One run on one mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OneMeshRow {
    pub case: String,
    /// "uniform" or "strip edges" (graded to h/4 there).
    pub mesh: String,
    pub element: String,
    pub level: usize,
    /// "FEM" (the extended front on the crack's mesh lines) or "tip".
    pub variant: String,
    pub dofs: usize,
    /// Relative L2 error against the reference.
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub l2_rel: f64,
    /// Π of the run and of the reference (J).
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub potential_energy_j: f64,
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub reference_energy_j: f64,
}

pub fn write_csv(path: &Path, rows: &[OneMeshRow]) -> Result<(), IoError> {
    crate::io::csv::write_rows(path, rows)
}

pub fn read_csv(path: &Path) -> Result<Vec<OneMeshRow>, IoError> {
    crate::io::csv::read_rows(path, false)
}

/// A FEM run and the tip front's on the same mesh.
#[derive(Debug, Clone, Copy)]
pub struct Pair<'a> {
    pub fem: &'a OneMeshRow,
    pub tip: &'a OneMeshRow,
}

impl Pair<'_> {
    /// The tip front's L2 error over FEM's: under 1, the tip front is closer.
    pub fn l2_ratio(&self) -> f64 {
        self.tip.l2_rel / self.fem.l2_rel
    }
}

/// The rows paired by case, mesh, element and level (in the rows' order).
pub fn pairs(rows: &[OneMeshRow]) -> Vec<Pair<'_>> {
    rows.iter()
        .filter(|r| r.variant == "FEM")
        .filter_map(|fem| {
            rows.iter()
                .find(|r| {
                    r.variant == "tip"
                        && r.case == fem.case
                        && r.mesh == fem.mesh
                        && r.element == fem.element
                        && r.level == fem.level
                })
                .map(|tip| Pair { fem, tip })
        })
        .collect()
}

/// The report's section, or `None` where the CSV was not written.
pub fn section(reports: &Path) -> Result<Option<String>, IoError> {
    let csv = reports.join(CSV);
    if !csv.exists() {
        return Ok(None);
    }
    let rows = read_csv(&csv)?;
    let mut md = String::from(
        "## One mesh: the tip front beside remeshed FEM, the strip edges resolved or not\n\n",
    );
    md.push_str("`bend_face` and `stretch_face` move a strip of the top face; where it meets the free face (x = 0.025 or 0.005, z = 0.2) the solution is singular like at a crack front. The study's levels leave that edge at their size; there remeshed FEM's too-stiff crack offsets the edge's too-stiff error, which on `bend_face` ranks it ahead of the tip front in L2. Here both run on one mesh per level: gmsh's crack mesh with the crack's nodes shared (`refs/crack_mesh_uncut.py`; FEM is X-FEM's extended front on it, equal to remeshed FEM to the last digit), uniform as the level or graded to h/4 at the strip edges (`--strip-edges`), against the same reference (`examples/error_map.rs one-mesh`). Grading the edge lowers every run's Π; the L2 ratio is the tip front's error over FEM's.\n\n");
    md.push_str("| case | mesh | element | level | DOFs: FEM / tip | L2: FEM / tip | L2 ratio | Π: FEM / tip (J) | reference Π (J) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for p in pairs(&rows) {
        let _ = writeln!(
            md,
            "| `{}` | {} | {} | L{} | {} / {} | {:.2} % / {:.2} % | {:.2} | {:.5} / {:.5} | {:.5} |",
            p.fem.case,
            p.fem.mesh,
            p.fem.element,
            p.fem.level,
            p.fem.dofs,
            p.tip.dofs,
            p.fem.l2_rel * 100.0,
            p.tip.l2_rel * 100.0,
            p.l2_ratio(),
            p.fem.potential_energy_j,
            p.tip.potential_energy_j,
            p.fem.reference_energy_j
        );
    }
    md.push('\n');
    Ok(Some(md))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(mesh: &str, variant: &str, l2: f64) -> OneMeshRow {
        OneMeshRow {
            case: "bend_face".into(),
            mesh: mesh.into(),
            element: "tet10".into(),
            level: 1,
            variant: variant.into(),
            dofs: 100,
            l2_rel: l2,
            potential_energy_j: 0.15,
            reference_energy_j: 0.145,
        }
    }

    #[test]
    fn runs_pair_by_mesh_and_the_section_lists_each_pair() {
        let rows = vec![
            row("uniform", "FEM", 0.01),
            row("uniform", "tip", 0.03),
            row("strip edges", "FEM", 0.02),
            row("strip edges", "tip", 0.005),
            row("strip edges", "FEM", 0.02),
        ];
        let p = pairs(&rows);
        assert_eq!(p.len(), 3);
        assert!((p[0].l2_ratio() - 3.0).abs() < 1e-12);
        assert!((p[1].l2_ratio() - 0.25).abs() < 1e-12);
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        assert!(section(dir.path()).unwrap().is_none());
        write_csv(&dir.path().join(CSV), &rows).unwrap();
        let md = section(dir.path()).unwrap().unwrap();
        assert_eq!(md.lines().filter(|l| l.starts_with("| `")).count(), 3);
        assert!(md.contains("| 1.00 % / 3.00 % | 3.00 |"), "{md}");
    }
}

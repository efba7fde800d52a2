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
//! the tip front, and the tip front on the body meshed without the crack and
//! graded alike ([`UNCUT_STRIPS`]: the front inside elements, the study's
//! setting for X-FEM, beside FEM on the graded crack mesh), and writes one
//! row per run against the FEniCSx reference.

use crate::io::IoError;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

/// The CSV `examples/error_map.rs one-mesh` writes, in `reports/`.
pub const CSV: &str = "data/one_mesh.csv";

/// The mesh of the tip front's runs on the body meshed without the crack,
/// graded to h/4 at the strip edges (`refs/crack_mesh_uncut.py --uncut`);
/// their FEM is the run on the crack mesh graded alike ("strip edges").
pub const UNCUT_STRIPS: &str = "strip edges, uncut";

/// The mesh of the FEM run a run on `mesh` is set beside.
pub fn fem_mesh(mesh: &str) -> &str {
    if mesh == UNCUT_STRIPS {
        "strip edges"
    } else {
        mesh
    }
}

/// One run on one mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OneMeshRow {
    pub case: String,
    /// "uniform", "strip edges" (graded to h/4 there) or [`UNCUT_STRIPS`].
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

/// Each tip run with the FEM run of its case, element and level on its
/// mesh ([`fem_mesh`]), in the tip runs' order.
pub fn pairs(rows: &[OneMeshRow]) -> Vec<Pair<'_>> {
    rows.iter()
        .filter(|r| r.variant == "tip")
        .filter_map(|tip| {
            rows.iter()
                .find(|r| {
                    r.variant == "FEM"
                        && r.case == tip.case
                        && r.mesh == fem_mesh(&tip.mesh)
                        && r.element == tip.element
                        && r.level == tip.level
                })
                .map(|fem| Pair { fem, tip })
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
    md.push_str("`bend_face` and `stretch_face` move a strip of the top face; where it meets the free face (x = 0.025 or 0.005, z = 0.2) the solution is singular like at a crack front. The study's levels leave that edge at their size; there remeshed FEM's too-stiff crack offsets the edge's too-stiff error, which on `bend_face` ranks it ahead of the tip front in L2. Here both run on one mesh per level: gmsh's crack mesh with the crack's nodes shared (`refs/crack_mesh_uncut.py`; FEM is X-FEM's extended front on it, equal to remeshed FEM to the last digit), uniform as the level or graded to h/4 at the strip edges (`--strip-edges`), against the same reference (`examples/error_map.rs one-mesh`). The rows on the mesh \"strip edges, uncut\" are the study's setting with the edge resolved: the tip front on the body meshed without the crack and graded alike (`--strip-edges … --uncut`), its front inside elements, beside remeshed FEM on the graded crack mesh (the FEM of the \"strip edges\" rows). Grading the edge lowers every run's Π; the L2 ratio is the tip front's error over FEM's.\n\n");
    md.push_str("| case | mesh | element | level | DOFs: FEM / tip | L2: FEM / tip | L2 ratio | Π: FEM / tip (J) | reference Π (J) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for p in pairs(&rows) {
        let _ = writeln!(
            md,
            "| `{}` | {} | {} | L{} | {} / {} | {:.2} % / {:.2} % | {:.2} | {:.5} / {:.5} | {:.5} |",
            p.fem.case,
            p.tip.mesh,
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
            row(UNCUT_STRIPS, "tip", 0.004),
        ];
        let mut alone = row("uniform", "tip", 0.5);
        alone.level = 2;
        let rows = [rows, vec![alone]].concat();
        let p = pairs(&rows);
        // The last tip run has no FEM run at its level: not paired.
        assert_eq!(p.len(), 3);
        assert!((p[0].l2_ratio() - 3.0).abs() < 1e-12);
        assert!((p[1].l2_ratio() - 0.25).abs() < 1e-12);
        // The uncut mesh's run beside FEM on the crack mesh graded alike.
        assert_eq!(p[2].fem.mesh, "strip edges");
        assert!((p[2].l2_ratio() - 0.2).abs() < 1e-12);
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        assert!(section(dir.path()).unwrap().is_none());
        write_csv(&dir.path().join(CSV), &rows).unwrap();
        let md = section(dir.path()).unwrap().unwrap();
        assert_eq!(md.lines().filter(|l| l.starts_with("| `")).count(), 3);
        assert!(md.contains("| 1.00 % / 3.00 % | 3.00 |"), "{md}");
        assert!(
            md.contains("| strip edges, uncut | tet10 | L1 | 100 / 100 | 2.00 % / 0.40 % | 0.20 |"),
            "{md}"
        );
    }
}

//! What the ramp of corrected X-FEM buys on the seed's beam as `tip_radius`
//! grows against the element size: the measurement behind
//! [`crate::cut::RAMP_SPAN`]. `examples/error_map.rs ramp-span` writes one
//! row per run (a case, a level, a radius, with or without the ramp) against
//! the FEniCSx references; the report pairs them and judges each pair by
//! the gap of the total potential energy Π to the reference's (half the
//! energy-norm error squared, which needs no accurate reference field).

use crate::io::IoError;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

/// The CSV `examples/error_map.rs ramp-span` writes, in `reports/`.
pub const CSV: &str = "data/ramp_span.csv";

/// One run: Tet4, geometric tip front of radius `radius_m`, its blending
/// elements ramped or not.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RampRow {
    pub case: String,
    pub level: usize,
    /// The mesh's median edge length (m, [`crate::mesh::TetMesh::median_edge_length`]).
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub median_edge_m: f64,
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub radius_m: f64,
    pub ramp: bool,
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

pub fn write_csv(path: &Path, rows: &[RampRow]) -> Result<(), IoError> {
    crate::io::csv::write_rows(path, rows)
}

pub fn read_csv(path: &Path) -> Result<Vec<RampRow>, IoError> {
    crate::io::csv::read_rows(path, false)
}

/// A run without the ramp and the same run with it.
#[derive(Debug, Clone, Copy)]
pub struct Pair<'a> {
    pub plain: &'a RampRow,
    pub ramp: &'a RampRow,
}

impl Pair<'_> {
    /// R over the mesh's median edge.
    pub fn span(&self) -> f64 {
        self.plain.radius_m / self.plain.median_edge_m
    }

    /// The ramp's gap of Π to the reference's over the plain run's.
    pub fn gap_ratio(&self) -> f64 {
        let gap = |r: &RampRow| r.potential_energy_j - r.reference_energy_j;
        gap(self.ramp) / gap(self.plain)
    }
}

/// The rows paired by case, level and radius (in the rows' order).
pub fn pairs(rows: &[RampRow]) -> Vec<Pair<'_>> {
    rows.iter()
        .filter(|r| !r.ramp)
        .filter_map(|plain| {
            rows.iter()
                .find(|r| {
                    r.ramp
                        && r.case == plain.case
                        && r.level == plain.level
                        && r.radius_m == plain.radius_m
                })
                .map(|ramp| Pair { plain, ramp })
        })
        .collect()
}

/// How the ramp did on one side of a span: runs, how many it narrowed the
/// gap in, the least, median and largest gap ratio.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tally {
    pub runs: usize,
    pub narrowed: usize,
    pub least: f64,
    pub median: f64,
    pub largest: f64,
}

/// The tally of the pairs whose span is at least `span` (`above`) or under it.
pub fn tally(pairs: &[Pair<'_>], span: f64, above: bool) -> Option<Tally> {
    let mut ratios: Vec<f64> = pairs
        .iter()
        .filter(|p| (p.span() >= span) == above)
        .map(Pair::gap_ratio)
        .collect();
    if ratios.is_empty() {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    Some(Tally {
        runs: ratios.len(),
        narrowed: ratios.iter().filter(|&&r| r < 1.0).count(),
        least: ratios[0],
        median: ratios[ratios.len() / 2],
        largest: ratios[ratios.len() - 1],
    })
}

/// The report's section, or `None` where the CSV was not written.
pub fn section(reports: &Path) -> Result<Option<String>, IoError> {
    let csv = reports.join(CSV);
    if !csv.exists() {
        return Ok(None);
    }
    let rows = read_csv(&csv)?;
    let pairs = pairs(&rows);
    let span = crate::cut::RAMP_SPAN;
    let mut md = String::from("## What the ramp buys on the beam, against R / h\n\n");
    let _ = writeln!(
        md,
        "The seed's beam, Tet4 on the unstructured meshes of the study, the front tip-enriched within R (`tip_radius`) with the blending elements ramped as corrected X-FEM does and without (`examples/error_map.rs ramp-span`, {} pairs). h is the mesh's median edge length; the gap is Π − Π_ref (half the energy-norm error squared, were the reference exact), and the ratio is the ramp's gap over the plain run's: under 1, the ramp is the more accurate in energy. A case takes the ramp from R = {span} h on (`cut::RAMP_SPAN`).\n",
        pairs.len()
    );
    for (above, label) in [(true, "R ≥"), (false, "R <")] {
        if let Some(t) = tally(&pairs, span, above) {
            let _ = writeln!(
                md,
                "- {label} {span} h: the ramp narrowed the gap in {} of {} runs; ratios {:.3} … {:.3}, median {:.3}.",
                t.narrowed, t.runs, t.least, t.largest, t.median
            );
        }
    }
    md.push_str("\n| case | level | h (mm) | R (mm) | R / h | DOFs: plain / ramp | L2: plain / ramp | gap ratio |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for p in &pairs {
        let _ = writeln!(
            md,
            "| `{}` | {} | {:.2} | {:.2} | {:.2} | {} / {} | {:.2} % / {:.2} % | {:.3} |",
            p.plain.case,
            p.plain.level,
            p.plain.median_edge_m * 1e3,
            p.plain.radius_m * 1e3,
            p.span(),
            p.plain.dofs,
            p.ramp.dofs,
            p.plain.l2_rel * 100.0,
            p.ramp.l2_rel * 100.0,
            p.gap_ratio()
        );
    }
    md.push('\n');
    Ok(Some(md))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(level: usize, radius_m: f64, ramp: bool, energy: f64) -> RampRow {
        RampRow {
            case: "gravity".into(),
            level,
            median_edge_m: 0.01,
            radius_m,
            ramp,
            dofs: 100 + usize::from(ramp),
            l2_rel: 0.1,
            potential_energy_j: energy,
            reference_energy_j: 1.0,
        }
    }

    #[test]
    fn pairs_are_judged_by_their_energy_gap_on_either_side_of_the_span() {
        let rows = vec![
            row(1, 0.03, false, 1.2),
            row(1, 0.03, true, 1.1),
            row(1, 0.01, false, 1.2),
            row(1, 0.01, true, 1.3),
            row(2, 0.01, true, 1.0),
        ];
        let p = pairs(&rows);
        assert_eq!(p.len(), 2);
        assert!((p[0].span() - 3.0).abs() < 1e-12);
        assert!((p[0].gap_ratio() - 0.5).abs() < 1e-12);
        let above = tally(&p, 2.5, true).unwrap();
        assert_eq!((above.runs, above.narrowed), (1, 1));
        let below = tally(&p, 2.5, false).unwrap();
        assert_eq!((below.runs, below.narrowed), (1, 0));
        assert!((below.largest - 1.5).abs() < 1e-12);
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        assert!(section(dir.path()).unwrap().is_none());
        write_csv(&dir.path().join(CSV), &rows).unwrap();
        assert_eq!(read_csv(&dir.path().join(CSV)).unwrap(), rows);
        let md = section(dir.path()).unwrap().unwrap();
        assert!(md.contains("narrowed the gap in 1 of 1 runs"), "{md}");
        assert!(
            md.contains("| `gravity` | 1 | 10.00 | 30.00 | 3.00 | 100 / 101 |"),
            "{md}"
        );
    }
}

//! `xfem-cut report`: reports/README.md with SVG plots from the study's CSV,
//! the FEniCSx manifests and criterion's own estimates.

use crate::io::IoError;
use crate::study::converge::{read_csv, Row};
use crate::study::exact;
use crate::study::reference::{out_dir, read_quality, ReferenceQuality, RESOLVED_FACTOR};
use crate::study::verify::observed_order;
use crate::study::StudyError;
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

const COLORS: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

type Series<'a> = BTreeMap<(String, &'static str), Vec<&'a Row>>;

fn series<'a>(rows: &'a [Row], case: &str) -> Series<'a> {
    let mut s: Series = BTreeMap::new();
    for r in rows.iter().filter(|r| r.case == case) {
        s.entry((r.variant.clone(), r.element)).or_default().push(r);
    }
    for v in s.values_mut() {
        v.sort_by_key(|r| r.dofs);
    }
    s
}

/// Observed order in h (least squares over the levels).
fn order(rows: &[&Row]) -> Option<f64> {
    let h: Vec<f64> = rows.iter().map(|r| r.h).collect();
    let e: Vec<f64> = rows.iter().map(|r| r.l2).collect();
    (rows.len() >= 2).then(|| observed_order(&h, &e)).flatten()
}

/// The graded references' sizes and own errors by case (`reports/data/references.csv`).
pub type Qualities = BTreeMap<String, ReferenceQuality>;

/// Reads `reports/data/references.csv`; empty when it is missing (no graded references yet).
pub fn qualities(reports: &Path) -> Result<Qualities, StudyError> {
    let path = reports.join("data/references.csv");
    if !path.exists() {
        return Ok(Qualities::new());
    }
    let q = read_quality(&path)?;
    Ok(q.into_iter().map(|q| (q.case.clone(), q)).collect())
}

/// The levels a reference resolves: error ≥ [`RESOLVED_FACTOR`] × its own
/// error (all of them when its own error is unknown).
pub fn resolved<'a>(rows: &[&'a Row], q: Option<&ReferenceQuality>) -> Vec<&'a Row> {
    rows.iter()
        .copied()
        .filter(|r| q.is_none_or(|q| q.resolves(r.l2)))
        .collect()
}

/// A series' order fitted over its resolved levels only, with those levels.
pub fn fitted_order<'a>(
    rows: &[&'a Row],
    q: Option<&ReferenceQuality>,
) -> (Option<f64>, Vec<&'a Row>) {
    let kept = resolved(rows, q);
    (order(&kept), kept)
}

/// The L2 rate theory expects as h → 0: a crack front limits FEM and
/// Heaviside X-FEM to O(h) (the r^½ singularity: O(h^½) in energy, O(h) in
/// L2 by duality); geometric tip enrichment restores the optimal rate; the
/// through-cut `slice` has no front (O(h²) Tet4, O(h³) Tet10); an edge load
/// has no limit to converge to.
pub fn expected_order(case: &str, variant: &str, element: &str) -> Option<f64> {
    let optimal = if element == "tet10" { 3.0 } else { 2.0 };
    match case {
        "stretch" | "bend" => None,
        "slice" => Some(optimal),
        _ if variant.contains("geometric") || variant.contains("radius") => Some(optimal),
        _ => Some(1.0),
    }
}

fn expected_text(case: &str, variant: &str, element: &str) -> String {
    expected_order(case, variant, element).map_or("– (edge load)".into(), |p| format!("{p:.0}"))
}

/// How far beyond FEM's finest level (in DOFs) [`fem_error_at`] extrapolates.
pub const FEM_EXTRAPOLATION: f64 = 1.25;

/// FEM's L2 error at `dofs` free DOFs (`fem` sorted by DOFs): log–log
/// interpolation between the FEM levels around it; below its coarsest level,
/// that level's error (FEM with more DOFs); up to [`FEM_EXTRAPOLATION`]×
/// its finest level's DOFs, the last two levels' slope extrapolated (FEM's
/// error falls with DOFs, so this favours FEM); `None` beyond.
pub fn fem_error_at(fem: &[&Row], dofs: usize) -> Option<f64> {
    let first = fem.first()?;
    if dofs <= first.dofs {
        return Some(first.l2);
    }
    let log_line = |a: &Row, b: &Row| {
        let t = (dofs as f64 / a.dofs as f64).ln() / (b.dofs as f64 / a.dofs as f64).ln();
        (a.l2.ln() + t * (b.l2.ln() - a.l2.ln())).exp()
    };
    if let Some(v) = fem
        .windows(2)
        .find_map(|w| (w[0].dofs <= dofs && dofs <= w[1].dofs).then(|| log_line(w[0], w[1])))
    {
        return Some(v);
    }
    match fem {
        [.., a, b] if (dofs as f64) <= FEM_EXTRAPOLATION * b.dofs as f64 => {
            Some(log_line(a, b).min(b.l2))
        }
        _ => None,
    }
}

/// How an X-FEM run compares with remeshed FEM at its DOFs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Verdict {
    /// Lower than FEM by more than the reference's own error.
    Lower,
    /// Higher than FEM by more than the reference's own error.
    Higher,
    /// Within the reference's own error of FEM's: the reference cannot tell.
    Unresolved,
    /// More DOFs than FEM's finest level.
    NoFem,
}

/// X-FEM's error `xfem` against FEM's `fem` at the same DOFs, `own` the
/// reference's own L2 error (0 when unknown).
pub fn verdict(xfem: f64, fem: Option<f64>, own: f64) -> Verdict {
    match fem {
        None => Verdict::NoFem,
        Some(f) if xfem + own < f => Verdict::Lower,
        Some(f) if xfem > f + own => Verdict::Higher,
        Some(_) => Verdict::Unresolved,
    }
}

/// Per X-FEM variant on the unstructured meshes and level: its L2 error
/// beside remeshed FEM's (same element) at the same DOFs, and the verdict.
fn against_remeshing(s: &Series<'_>, q: Option<&ReferenceQuality>) -> String {
    let own = q.map_or(0.0, |q| q.own_l2);
    let mut md = String::new();
    for ((variant, element), rows) in s {
        if !variant.starts_with("X-FEM unstructured") {
            continue;
        }
        let Some(fem) = s.get(&("FEM pre-cut".to_string(), *element)) else {
            continue;
        };
        if md.is_empty() {
            md.push_str("\nX-FEM on the unstructured uncut meshes against remeshed FEM (the pre-cut meshes) at the same number of free DOFs (FEM's error interpolated log–log between its levels; below its coarsest level, that level's; up to 1.25× its finest level's DOFs, extrapolated along its last two levels): \"lower\"/\"higher\" where the difference exceeds the reference's own L2 error, else \"unresolved\". In energy, with no reference: Π − Π_FEM against FEM at the same level (its DOFs in brackets); negative is the more accurate in energy (not for the extended front, a longer cut).\n\n| variant | element | level | DOFs | L2 error | FEM at these DOFs | ratio | verdict | Π − Π_FEM (J) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
        }
        for r in rows {
            let f = fem_error_at(fem, r.dofs);
            let v = match verdict(r.l2, f, own) {
                Verdict::Lower => "lower",
                Verdict::Higher => "higher",
                Verdict::Unresolved => "unresolved",
                Verdict::NoFem => "– (beyond FEM's finest level)",
            };
            let energy = fem
                .iter()
                .find(|f| f.level == r.level && f.energy.is_finite() && r.energy.is_finite())
                .map_or("–".into(), |f| {
                    format!("{:+.3e} ({} DOFs)", r.energy - f.energy, f.dofs)
                });
            let _ = writeln!(
                md,
                "| {variant} | {element} | {} | {} | {:.3e} | {} | {} | {v} | {energy} |",
                r.level,
                r.dofs,
                r.l2,
                f.map_or("–".into(), |f| format!("{f:.3e}")),
                f.map_or("–".into(), |f| format!("{:.2}", r.l2 / f)),
            );
        }
    }
    md
}

/// One line of a log–log plot.
struct Line {
    label: String,
    points: Vec<(f64, f64)>,
    color: RGBColor,
    thick: bool,
}

/// A plotting failure as a [`StudyError`] naming the file.
fn plot_error<E: std::error::Error + Send + Sync + 'static>(path: &Path, e: E) -> StudyError {
    StudyError::Plot {
        path: path.to_path_buf(),
        source: Box::new(e),
    }
}

/// The convergence rows of `s` as lines of L2 error against `x`.
fn plot(
    path: &Path,
    title: &str,
    xlabel: &str,
    s: &Series<'_>,
    x: impl Fn(&Row) -> f64,
) -> Result<(), StudyError> {
    // One colour per variant; Tet10 thick, Tet4 thin.
    let mut variants: Vec<&str> = s.keys().map(|(v, _)| v.as_str()).collect();
    variants.dedup();
    let lines: Vec<Line> = s
        .iter()
        .map(|((variant, element), rows)| Line {
            label: match order(rows) {
                Some(p) => format!("{variant} {element} (order {p:.2})"),
                None => format!("{variant} {element}"),
            },
            points: rows.iter().map(|r| (x(r), r.l2)).collect(),
            color: COLORS[variants.iter().position(|v| v == variant).unwrap_or(0) % COLORS.len()],
            thick: *element == "tet10",
        })
        .collect();
    draw_lines(
        path,
        title,
        xlabel,
        "relative L2 error",
        &lines,
        SeriesLabelPosition::LowerLeft,
    )
}

/// The one-mesh comparison's L2 errors against DOFs, one SVG per case
/// (`one_mesh_<case>.svg`: a colour per mesh and variant, Tet10 thick), and
/// the Markdown that shows them.
pub fn one_mesh_plots(reports: &Path) -> Result<String, StudyError> {
    use crate::study::one_mesh;
    let rows = one_mesh::read_csv(&reports.join(one_mesh::CSV))?;
    let mut cases: Vec<&str> = Vec::new();
    for r in &rows {
        if !cases.contains(&r.case.as_str()) {
            cases.push(&r.case);
        }
    }
    let mut md = String::new();
    for case in cases {
        let mut keys: Vec<(&str, &str, &str)> = Vec::new();
        for r in rows.iter().filter(|r| r.case == case) {
            let key = (r.mesh.as_str(), r.variant.as_str(), r.element.as_str());
            if !keys.contains(&key) {
                keys.push(key);
            }
        }
        // One colour per mesh and variant, in order of appearance.
        let mut kinds: Vec<(&str, &str)> = Vec::new();
        for &(m, v, _) in &keys {
            if !kinds.contains(&(m, v)) {
                kinds.push((m, v));
            }
        }
        let lines: Vec<Line> = keys
            .iter()
            .map(|&(mesh, variant, element)| Line {
                label: format!("{variant}, {mesh} mesh, {element}"),
                points: rows
                    .iter()
                    .filter(|r| {
                        (
                            r.case.as_str(),
                            r.mesh.as_str(),
                            r.variant.as_str(),
                            r.element.as_str(),
                        ) == (case, mesh, variant, element)
                    })
                    .map(|r| (r.dofs as f64, r.l2_rel))
                    .collect(),
                color: COLORS[kinds
                    .iter()
                    .position(|&k| k == (mesh, variant))
                    .unwrap_or(0)
                    % COLORS.len()],
                thick: element == "tet10",
            })
            .collect();
        let file = format!("one_mesh_{case}.svg");
        draw_lines(
            &reports.join(&file),
            &format!("{case}: the tip front and remeshed FEM, one mesh per level"),
            "DOFs",
            "relative L2 error",
            &lines,
            SeriesLabelPosition::LowerLeft,
        )?;
        let _ = writeln!(md, "![{case}: one mesh, L2 error against DOFs]({file})");
    }
    if !md.is_empty() {
        md.push('\n');
    }
    Ok(md)
}

/// A log–log SVG of `lines` (points ≤ 0 left out); nothing when none is left.
fn draw_lines(
    path: &Path,
    title: &str,
    xlabel: &str,
    ylabel: &str,
    lines: &[Line],
    legend: SeriesLabelPosition,
) -> Result<(), StudyError> {
    let pts: Vec<(f64, f64)> = lines
        .iter()
        .flat_map(|l| l.points.iter().copied())
        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
        .collect();
    if pts.is_empty() {
        return Ok(());
    }
    let err = |e| plot_error(path, e);
    let (xmin, xmax) = pts
        .iter()
        .fold((f64::INFINITY, 0f64), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (ymin, ymax) = pts
        .iter()
        .fold((f64::INFINITY, 0f64), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let root = SVGBackend::new(path, (720, 480)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (xmin * 0.8..xmax * 1.25).log_scale(),
            (ymin * 0.7..ymax * 1.4).log_scale(),
        )
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(xlabel)
        .y_desc(ylabel)
        .draw()
        .map_err(err)?;
    for line in lines {
        let c = line.color;
        let style = c.stroke_width(if line.thick { 2 } else { 1 });
        let data: Vec<(f64, f64)> = line
            .points
            .iter()
            .copied()
            .filter(|p| p.0 > 0.0 && p.1 > 0.0)
            .collect();
        chart
            .draw_series(LineSeries::new(data.clone(), style))
            .map_err(err)?
            .label(line.label.clone())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
        chart
            .draw_series(data.iter().map(|&p| Circle::new(p, 3, c.filled())))
            .map_err(err)?;
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(legend)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

/// FEniCSx assembly + solve seconds for `case`, `family_L<k>/p<degree>`.
fn fenicsx_time(case: &str, key: &str) -> Option<(f64, usize)> {
    let text = std::fs::read_to_string(out_dir().join(case).join("manifest.json")).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    let e = v.get(key)?;
    Some((
        e.get("assembly_s")?.as_f64()? + e.get("solve_s")?.as_f64()?,
        e.get("dofs")?.as_u64()? as usize,
    ))
}

/// Criterion medians (ns) of every benchmark under `target/criterion`.
fn criterion_medians(dir: &Path) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        let Ok(entries) = std::fs::read_dir(&d) else {
            continue;
        };
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() && p.file_name().is_some_and(|n| n != "report") {
                let est = p.join("new/estimates.json");
                if est.exists() {
                    let id = p.strip_prefix(dir).unwrap_or(&p).display().to_string();
                    if let Some(m) = std::fs::read_to_string(&est)
                        .ok()
                        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
                        .and_then(|v| v["median"]["point_estimate"].as_f64())
                    {
                        out.push((id, m));
                    }
                } else {
                    stack.push(p);
                }
            }
        }
    }
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

/// The cases of the rows, sorted, once each.
fn case_names(rows: &[Row]) -> Vec<String> {
    let mut cases: Vec<String> = rows.iter().map(|r| r.case.clone()).collect();
    cases.sort();
    cases.dedup();
    cases
}

/// Per case and variant: levels, observed order, finest error, fastest run ≤ 1 %.
fn summary_table(rows: &[Row], cases: &[String], quality: &Qualities) -> String {
    let mut md = String::from("| case | variant | element | levels (resolved) | observed order (resolved levels) | theory | finest error | fastest run with error ≤ 1 % |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for case in cases {
        for ((variant, element), rs) in &series(rows, case) {
            let (fit, kept) = fitted_order(rs, quality.get(case));
            let fastest = rs
                .iter()
                .filter(|r| r.l2 <= 0.01)
                .min_by(|a, b| (a.precompute + a.solve).total_cmp(&(b.precompute + b.solve)))
                .map_or("–".into(), |r| {
                    format!(
                        "L{} ({} DOFs): {:.1} ms",
                        r.level,
                        r.dofs,
                        (r.precompute + r.solve) * 1e3
                    )
                });
            let _ = writeln!(
                md,
                "| `{case}` | {variant} | {element} | {} ({}) | {} | {} | {} | {fastest} |",
                rs.len(),
                kept.len(),
                fit.map_or("–".into(), |p| format!("{p:.2}")),
                expected_text(case, variant, element),
                rs.last()
                    .map_or("–".into(), |r| format!("{:.2} %", r.l2 * 100.0))
            );
        }
    }
    md
}

/// The corotational study (`xfem-cut converge --corotational`), if it ran.
fn corotational_section(reports: &Path) -> Result<Option<String>, StudyError> {
    let path = reports.join("data/convergence_corot.csv");
    if !path.exists() {
        return Ok(None);
    }
    let rows = read_csv(&path)?;
    let cases = case_names(&rows);
    let mut md = String::from("## Corotational statics: convergence\n\nThe same variants solved corotational (static Newton on the exact tangent, 10 load steps), each against our corotational Tet10 FEM solution on the finest pre-cut level within 120k DOFs (`xfem-cut converge --corotational`; that solver equals scikit-fem's corotational P1 and P2 solutions on L0 to ~1e-14, `tests/references.rs`). Only levels below the reference's run. The reference is itself a discretisation (for the linear problem the same level, L3, is 0.4–1.3 % from the graded fine FEniCSx P2 solution), so errors below ~1 % and orders fitted over these three levels are indicative; loads and displacements are the cases' own, large enough for the linear solution to be off (`gravity`, structured level 2, Tet4 X-FEM: tip deflection 99.6 mm linear, 88.4 mm corotational, which also shortens the beam by 13–30 mm at the top). Times are wall-clock for 10 load steps of 3–4 Newton iterations (~35–40 numeric factorisations), measured while the machine also built and tested code, so read them as rough.\n\n");
    md.push_str(&summary_table(&rows, &cases, &Qualities::new()));
    md.push('\n');
    for case in &cases {
        let svg = format!("{case}_corot_error_dofs.svg");
        plot(
            &reports.join(&svg),
            &format!("{case} (corotational): error vs DOFs"),
            "free DOFs",
            &series(&rows, case),
            |r| r.dofs as f64,
        )?;
        let _ = writeln!(md, "![{case} corotational error vs DOFs]({svg})");
    }
    md.push('\n');
    Ok(Some(md))
}

/// Writes `reports/README.md` and its plots from `reports/data/convergence.csv`.
pub fn write_report(reports: &Path, criterion_dir: &Path, machine: &str) -> Result<(), StudyError> {
    let rows = read_csv(&reports.join("data/convergence.csv"))
        .map_err(|e| StudyError::from(e).during("the study (run `xfem-cut converge` first)"))?;
    let mut md = String::new();
    let _ = writeln!(md, "# xfem-cut: convergence and performance report\n");
    let _ = writeln!(md, "Generated by `make report` ({machine}). Errors are relative L2 errors against the fine FEniCSx P2 solution on a graded pre-cut mesh (`refs/out/<case>/*_fine/p2.vtu`: gmsh Distance + Threshold size fields, the element size at the crack front and at the free edges of the top-face strips that the `*_face` cases move (`slice`: at the clamped edges) ≤ 1/4 of the finest level's, the far field finer than the finest level), integrated with a degree-5 rule on every reference tetrahedron. The reference's own error is its difference from a second graded reference 1.4× coarser everywhere (same measures); a level whose error is below {RESOLVED_FACTOR}× that is marked unresolved and left out of the order fit. Opening error: the same relative error for the jump u(+) − u(−) at 12 × 24 points of the cut patch (inside the body), X-FEM read on each face of its cut exactly, the pre-cut meshes (FEM and the reference) 1e-8 m off the plane; probe error: the largest probe error over the largest probe displacement (probes on the cut read on its + side). Π: the total potential energy ½ a(u_h, u_h) − f·u_h of the solution (corotational: the corotated strain energy): on one body with the same Dirichlet data a conforming solution's Π exceeds the exact one by half its energy-norm error squared, so of two runs the lower Π is the more accurate in energy, which needs no reference (the extended front is a longer cut, another body). Orders are least-squares slopes of log(error) against log(h), h = (V / elements)^(1/3). Times are wall-clock on this machine: precompute = cut set-up + element data + pattern + symbolic factorisation; solve = numeric factorisation + solve.\n");
    // What of this report was not regenerated by the run that wrote it (a
    // partial `make report`), as the person who ran it wrote it down: at the
    // end of the page, so that a reader meets the summary first.
    let provenance = std::fs::read_to_string(reports.join("data/provenance.md"))
        .ok()
        .map(|text| text.trim().to_string())
        .filter(|text| !text.is_empty());
    if provenance.is_some() {
        let _ = writeln!(md, "Parts of this page were run again after the last whole `make report`, or checked and kept: the last section, \"Provenance\", says which, when and why the rest holds.\n");
    }
    let cases = case_names(&rows);
    let quality = qualities(reports)?;
    // One table over all cases first: what a reader asks before the details.
    md.push_str("## Summary\n\n");
    md.push_str(&summary_table(&rows, &cases, &quality));
    md.push('\n');
    for case in &cases {
        let s = series(&rows, case);
        let q = quality.get(case);
        let _ = writeln!(md, "## `{case}`\n");
        match q {
            Some(q) => {
                let _ = writeln!(md, "Reference: FEniCSx P2 on the graded `{}` mesh, {} DOFs, element size {:.2} mm at the {} and {:.1} mm far from it; its own error (against {} DOFs, {:.2} mm there): L2 {}, opening {}, probes {}. Levels with L2 error < {}: unresolved.\n",
                    q.family, q.dofs, q.front_h * 1e3, if case == "slice" { "clamped edges" } else { "crack front and the strip edges" }, q.far_h * 1e3,
                    q.coarse_dofs, q.coarse_front_h * 1e3, sci(q.own_l2), sci(q.own_opening), sci(q.own_probes), sci(RESOLVED_FACTOR * q.own_l2));
            }
            None => {
                let _ = writeln!(md, "Reference: its own error is unknown (no row in `reports/data/references.csv`; `make refs` writes it): every level is fitted.\n");
            }
        }
        if case == "slice" {
            let _ = writeln!(md, "The through-cut has no front; the theory column is the smooth rate (O(h²) Tet4, O(h³) Tet10). The clamped faces meet the free faces at right-angled edges, where the solution has mild singularities (r^λ, λ < 1): they, not the cut, limit the rates seen here, which is why the references are graded towards those edges.\n");
        }
        if case == "stretch" || case == "bend" {
            let _ = writeln!(md, "A Dirichlet condition on an edge (a line) is not well-posed in 3-D: as h → 0 the solutions converge, slowly (about 1/|log h|), to one that ignores the edge. The errors below are against a fine mesh that still feels the edge, so they say how close the levels are to that mesh, not to a limit; read the `*_face` variants for orders.\n");
        }
        let picture = format!("pictures/{case}.png");
        if reports.join(&picture).exists() {
            let _ = writeln!(md, "![{case}: X-FEM with the cut opened beside the reference]({picture})\n\nLeft: X-FEM, structured level 2, Tet4, deformed at true scale, the cut elements drawn as their sub-tets so the cut opens, coloured by |u − u_ref|; right: the graded FEniCSx P2 reference on the pre-cut mesh, coloured by |u| (`make pictures`, `refs/pictures.py`).\n");
        }
        let dofs_svg = format!("{case}_error_dofs.svg");
        let time_svg = format!("{case}_error_time.svg");
        plot(
            &reports.join(&dofs_svg),
            &format!("{case}: error vs DOFs"),
            "free DOFs",
            &s,
            |r| r.dofs as f64,
        )?;
        plot(
            &reports.join(&time_svg),
            &format!("{case}: error vs run time"),
            "precompute + solve (s)",
            &s,
            |r| r.precompute + r.solve,
        )?;
        let _ = writeln!(
            md,
            "![error vs DOFs]({dofs_svg})\n![error vs time]({time_svg})\n"
        );
        let _ = writeln!(md, "| variant | element | level | elements | DOFs | L2 error | opening error | probe error | Π (J) | precompute (ms) | solve (ms) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
        for ((variant, element), rs) in &s {
            for r in rs {
                let unresolved = if q.is_some_and(|q| !q.resolves(r.l2)) {
                    " (unresolved)"
                } else {
                    ""
                };
                let _ = writeln!(
                    md,
                    "| {variant} | {element} | {} | {} | {} | {:.3e}{unresolved} | {} | {} | {} | {:.1} | {:.1} |",
                    r.level,
                    r.elements,
                    r.dofs,
                    r.l2,
                    sci(r.opening),
                    sci(r.probes),
                    energy(r.energy),
                    r.precompute * 1e3,
                    r.solve * 1e3
                );
            }
        }
        let _ = writeln!(
            md,
            "\n| variant | element | observed order (resolved levels) | theory | order over all levels |\n| --- | --- | --- | --- | --- |"
        );
        for ((variant, element), rs) in &s {
            let (fit, kept) = fitted_order(rs, q);
            let levels: Vec<String> = kept.iter().map(|r| format!("L{}", r.level)).collect();
            let _ = writeln!(
                md,
                "| {variant} | {element} | {} | {} | {} |",
                fit.map_or("– (fewer than 2 resolved levels)".into(), |p| format!(
                    "{p:.2} ({})",
                    levels.join(", ")
                )),
                expected_text(case, variant, element),
                order(rs).map_or("–".into(), |p| format!("{p:.2}"))
            );
        }
        md.push_str(&against_remeshing(&s, q));
        // The fastest run under 1 % error.
        if let Some(best) = s
            .values()
            .flatten()
            .filter(|r| r.l2 <= 0.01)
            .min_by(|a, b| (a.precompute + a.solve).total_cmp(&(b.precompute + b.solve)))
        {
            let _ = writeln!(
                md,
                "\nFastest run with L2 error ≤ 1 %: {} {} level {} ({} DOFs, {:.3e}) in {:.1} ms.",
                best.variant,
                best.element,
                best.level,
                best.dofs,
                best.l2,
                (best.precompute + best.solve) * 1e3
            );
        } else {
            let _ = writeln!(md, "\nNo run reached 1 % L2 error.");
        }
        // Against FEniCSx on the same pre-cut meshes.
        let fem: Vec<&Row> = s
            .iter()
            .filter(|((v, _), _)| v == "FEM pre-cut")
            .flat_map(|(_, r)| r.iter().copied())
            .collect();
        if !fem.is_empty() {
            let _ = writeln!(md, "\nSame mesh, same problem, against FEniCSx (dolfinx 0.5.2, MUMPS, OpenBLAS; assembly + solve, JIT excluded):\n\n| element | level | DOFs (ours free / FEniCSx all) | ours (ms) | FEniCSx (ms) | speed-up |\n| --- | --- | --- | --- | --- | --- |");
            for r in fem {
                let family = reference_family(case);
                let key = format!(
                    "{family}_L{}/p{}",
                    r.level,
                    if r.element == "tet10" { 2 } else { 1 }
                );
                if let Some((t, dofs)) = fenicsx_time(case, &key) {
                    let ours = r.precompute + r.solve;
                    let _ = writeln!(
                        md,
                        "| {} | {} | {} / {} | {:.1} | {:.1} | {:.2}× |",
                        r.element,
                        r.level,
                        r.dofs,
                        dofs,
                        ours * 1e3,
                        t * 1e3,
                        t / ours
                    );
                }
            }
        }
        md.push('\n');
    }
    md.push_str(&exact_section(reports)?);
    if let Some(section) = crate::study::ramp::section(reports)? {
        md.push_str(&section);
    }
    if let Some(section) = crate::study::one_mesh::section(reports)? {
        md.push_str(&section);
        md.push_str(&one_mesh_plots(reports)?);
    }
    if let Some(section) = static_section(reports)? {
        md.push_str(&section);
    }
    if let Some(section) = sweep_section(reports)? {
        md.push_str(&section);
    }
    if let Some(section) = corotational_section(reports)? {
        md.push_str(&section);
    }
    let benches = benches_kept(reports, criterion_medians(criterion_dir))?;
    if let Some(table) = cut_cost(&benches) {
        md.push_str(&table);
    }
    if let Some(table) = tip_cost(&benches) {
        md.push_str(&table);
    }
    if !benches.is_empty() {
        let _ = writeln!(
            md,
            "## Benchmarks (criterion medians)\n\n| benchmark | median |\n| --- | --- |"
        );
        for (id, ns) in benches {
            let _ = writeln!(md, "| `{id}` | {:.3} ms |", ns * 1e-6);
        }
    }
    match crate::study::stress::read_csv(&reports.join("data/stress.csv")) {
        Ok(stress) => {
            let passed = stress.iter().filter(|r| r.pass).count();
            let _ = writeln!(
                md,
                "\n## Stability stress suite (`xfem-cut stress`): {passed} of {} pass\n\n| test | setting | measured | criterion | result | time (s) |\n| --- | --- | --- | --- | --- | --- |",
                stress.len()
            );
            for r in &stress {
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {} | {} | {:.1} |",
                    r.test,
                    r.setting,
                    r.measured,
                    r.criterion,
                    if r.pass { "pass" } else { "**FAIL**" },
                    r.seconds
                );
            }
            let _ = writeln!(md, "\nκ: 2-norm condition estimates of the free system's tangent (30 power + 30 inverse iterations); the Jacobi-scaled one is what limits a direct solve's accuracy. Cuts close to nodes make κ(K) explode through enriched DOFs with tiny support while the scaled κ stays put: the Cholesky solve stays accurate, snapping (ε = 1e-4 h by default) removes the tiny supports for iterative solvers.");
        }
        Err(e) => {
            let _ = writeln!(
                md,
                "\n## Stability stress suite\n\nNot run ({e}); `xfem-cut stress` writes it."
            );
        }
    }
    if let Some(text) = provenance {
        let _ = writeln!(
            md,
            "\n## Provenance: what was run again, and when\n\nFrom `reports/data/provenance.md`, newest last.\n\n{text}"
        );
    }
    let tmp = reports.join("README.md.tmp");
    std::fs::write(&tmp, md).map_err(|e| IoError::os(&tmp, "write", e))?;
    let readme = reports.join("README.md");
    std::fs::rename(&tmp, &readme).map_err(|e| IoError::os(&readme, "rename onto", e))?;
    Ok(())
}

/// One row of `data/static_vs_fenicsx.csv` (`refs/bench_static.py`).
#[derive(Debug, serde::Deserialize)]
struct StaticRow {
    element: String,
    h_mm: f64,
    cores: usize,
    dofs_ours_free: usize,
    dofs_fenicsx: usize,
    ours_s: f64,
    ours_peak_mb: f64,
    fenicsx_1rank_s: f64,
    fenicsx_1rank_peak_mb: f64,
    fenicsx_2ranks_s: Option<f64>,
    speedup: f64,
}

/// The static linear solve against FEniCSx at equal cores, 10k–400k DOFs
/// (`data/static_vs_fenicsx.csv`, written by `refs/bench_static.py`).
fn static_section(reports: &Path) -> Result<Option<String>, StudyError> {
    let csv = reports.join("data/static_vs_fenicsx.csv");
    if !csv.exists() {
        return Ok(None);
    }
    let rows: Vec<StaticRow> = crate::io::csv::read_rows(&csv, false)?;
    let mut md = String::from(
        "## Static solve against FEniCSx at equal cores

",
    );
    md.push_str("The `gravity` case without its cut (FEM) on pre-cut gmsh beam meshes of 10k to 400k DOFs, our Tet4 / Tet10 against FEniCSx P1 / P2 on the same mesh (`refs/bench_static.py`, run on a quiet machine). Ours: element data + pattern + ordering and symbolic factorisation + assembly, numeric factorisation and solve, with `XFEM_THREADS` = cores (numeric factorisation and element loops; on 2 cores the ordering and symbolic factorisation run beside the element scatter maps, and the factor is split at nested dissection's first separator into two halves factorised side by side); FEniCSx (dolfinx 0.5.2, MUMPS, OpenBLAS): assembly + solve as `refs/solve_fenicsx.py` times them (JIT excluded), one rank with `OPENBLAS_NUM_THREADS` = `OMP_NUM_THREADS` = cores, and on 2 cores also two MPI ranks of one thread; the speed-up is against the faster. Neither counts reading the mesh. Peak memory: the process's largest resident set (single-process runs).\n\n| element | h (mm) | DOFs (ours free / FEniCSx) | cores | ours (s) | ours peak (MB) | FEniCSx 1 rank (s) | FEniCSx peak (MB) | FEniCSx 2 ranks (s) | speed-up |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {} / {} | {} | {:.2} | {:.0} | {:.2} | {:.0} | {} | {:.2}× |",
            r.element,
            r.h_mm,
            r.dofs_ours_free,
            r.dofs_fenicsx,
            r.cores,
            r.ours_s,
            r.ours_peak_mb,
            r.fenicsx_1rank_s,
            r.fenicsx_1rank_peak_mb,
            r.fenicsx_2ranks_s
                .map_or("–".to_string(), |t| format!("{t:.2}")),
            r.speedup
        );
    }
    let low = rows.iter().map(|r| r.speedup).fold(f64::INFINITY, f64::min);
    let high = rows
        .iter()
        .map(|r| r.speedup)
        .fold(f64::NEG_INFINITY, f64::max);
    let _ = writeln!(
        md,
        "\nSpeed-up from {low:.2}× to {high:.2}× over these sizes and cores. `cargo run --release --example static_profile -- CASE MESH` splits one of our solves into its parts.\n"
    );
    Ok(Some(md))
}

/// The code-verification section: the exact-solution study
/// (`reports/data/exact.csv`, [`exact`]), a table per case with the orders
/// between successive levels, the last pair's orders against theory and an
/// error-vs-DOFs plot of L2 and energy errors.
/// The cost of a blade's sweep as a time series (`data/sweep_series.csv`,
/// written by `examples/sweep_series.rs`), redrawn as `sweep_series.svg`,
/// with its medians: a step between events, an event with the step after it
/// (which holds the refactorisation or the border's set-up).
fn sweep_section(reports: &Path) -> Result<Option<String>, StudyError> {
    let csv = reports.join("data/sweep_series.csv");
    if !csv.exists() {
        return Ok(None);
    }
    let rows = crate::study::sweep::read_csv(&csv)?;
    let svg = reports.join("sweep_series.svg");
    crate::study::sweep::plot(
        &svg,
        "seed beam, blade through the seed cut (linear Tet4)",
        &rows,
    )
    .map_err(|e| plot_error(&svg, e))?;
    let med = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let events: Vec<&crate::study::sweep::SweepRow> = rows.iter().filter(|r| r.event).collect();
    let plain = med(rows
        .iter()
        .filter(|r| !r.event)
        .map(|r| r.step_seconds)
        .collect());
    let event = med(rows
        .windows(2)
        .filter(|w| w[0].event)
        .map(|w| w[0].event_seconds + w[1].step_seconds)
        .collect());
    let mut md = String::from("## Cutting while it runs: the cost of a sweep\n\n");
    if reports.join(SWEEP_PICTURE).exists() {
        let _ = writeln!(
            md,
            "![cut_progressive: the blade and the cut opening behind it]({SWEEP_PICTURE})\n\n`cases/cut_progressive.toml` at level 1 (Tet4, tip front, linear, damped): five frames of `xfem-cut run`'s `.pvd` series at true scale, the blade's edge in red where it is (its `.vtu` line cell, moved with the body), the cut's faces drawn as the sub-tets of the elements it cuts, each displaced by its own side (`make pictures`, `refs/sweep_pictures.py`). The cut opens behind the edge and nowhere ahead of it; after the sweep (0.6 s) the damped beam settles with the cut open.\n"
        );
    }
    let _ = writeln!(
        md,
        "The seed's beam cut by a blade that sweeps the seed's cut during [0.1, 0.6] s (`examples/sweep_series.rs`, front extended through the elements it is in, linear Tet4, dt = 0.01 s): {} steps, {} cut events; median step {:.3} ms, median event with the step after it {:.3} ms ({:.1}×). Each event updates the model where the cut changed (`Model::update_cut`); where it only appended equations (here: every event) the steps after it solve on the last factor through a bordered solve (the Schur complement of the new equations; Woodbury where old equations changed) instead of refactorising (`solve::BorderedSolve`; refactorised once the border's steps have cost a factorisation, `dynamics::refresh_after`), so the step after an event holds the border's set-up, not a symbolic and numeric factorisation. `examples/sweep_series.rs refactorise` gives the refactorising run for comparison. Measured on the machine that wrote the CSV (2 shared cores: rough).\n\n![step time against simulated time, events marked](sweep_series.svg)\n",
        rows.len(),
        events.len(),
        plain * 1e3,
        event * 1e3,
        event / plain
    );
    md.push_str(&sweep_phases(reports, &rows)?);
    Ok(Some(md))
}

/// The frames of `cut_progressive` as its blade cuts (`make pictures`,
/// `refs/sweep_pictures.py`), relative to `reports/`.
const SWEEP_PICTURE: &str = "pictures/cut_progressive_sweep.png";

/// The sweep series of `examples/sweep_series.rs` the report knows: file
/// stem (in `data/`), front, formulation.
const SWEEP_SERIES: [(&str, &str, &str); 4] = [
    ("sweep_series", "extended", "linear"),
    ("sweep_series_corotational", "extended", "corotational"),
    ("sweep_series_tip", "tip", "linear"),
    ("sweep_series_tip_corotational", "tip", "corotational"),
];

/// Each sweep series present (the first, `rows`, read already) split into
/// its phases against the same run's uncut steps ([`crate::study::sweep::phases`]),
/// and a plot of each series but the first (drawn by [`sweep_section`]).
fn sweep_phases(
    reports: &Path,
    first: &[crate::study::sweep::SweepRow],
) -> Result<String, StudyError> {
    let mut md = String::new();
    let mut table = String::new();
    let mut plots = String::new();
    for (k, (stem, front, formulation)) in SWEEP_SERIES.iter().enumerate() {
        let csv = reports.join(format!("data/{stem}.csv"));
        let rows = if k == 0 {
            first.to_vec()
        } else if csv.exists() {
            crate::study::sweep::read_csv(&csv)?
        } else {
            continue;
        };
        let p = crate::study::sweep::phases(&rows, 0.1, 0.6);
        let ms = |s: f64| s * 1e3;
        let _ = writeln!(
            table,
            "| {front} | {formulation} | {} | {} | {:.3} | {:.3} ({:.1}×) | {:.3} ({:.1}×) | {:.3} | {:.3} ({:.2}×) |",
            p.sweep_steps,
            p.events,
            ms(p.uncut_step),
            ms(p.sweep_step),
            p.sweep_step / p.uncut_step,
            ms(p.event),
            p.event / p.uncut_step,
            ms(p.event_and_step),
            ms(p.after_step),
            p.after_step / p.uncut_step
        );
        if k > 0 {
            let svg = reports.join(format!("{stem}.svg"));
            crate::study::sweep::plot(
                &svg,
                &format!(
                    "seed beam, blade through the seed cut ({formulation} Tet4, {front} front)"
                ),
                &rows,
            )
            .map_err(|e| plot_error(&svg, e))?;
            let _ = writeln!(
                plots,
                "![step time against simulated time, {front} front, {formulation}]({stem}.svg)"
            );
        }
    }
    if table.lines().count() < 2 {
        return Ok(md);
    }
    md.push_str("\n### Each front and formulation, against the uncut steps before the blade\n\nThe same sweep (1080 Tet4, dt = 0.01 s, 70 steps: the beam uncut until the blade enters at 0.1 s) with the front extended and tip-enriched (`front = \"tip\"`, the default of a case file), linear and corotational (its steps on the lagged factor a case file defaults to, `dynamics::DEFAULT_LAGGED`; `examples/sweep_series.rs [corotational] [tip] --out reports`). Uncut step: the median step before 0.1 s (the first left out); sweep step: the mean wall time a step of [0.1, 0.6] s costs with its event; event: the median event's own time (set-up, model update with the state's projection, symbolic factorisation where the pattern changed), then with the step after it (linear: refactorised, or bordered on the last factor; corotational: on the lagged factor carried over where the event kept every equation, which a tip front moving inside its elements does, refactorised where the rate asks, else refactorised); after: the median step once the sweep is done (the cut complete, its front where the blade stopped). A tip front moves inside its elements at every step, so every step of its sweep ends in an event that integrates the elements holding branch functions again and projects the state; an extended front changes only when the blade enters new elements.\n\n| front | formulation | sweep steps | events | uncut step (ms) | sweep step (ms, × uncut) | event (ms, × uncut) | event + step after (ms) | step after (ms, × uncut) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    md.push_str(&table);
    if !plots.is_empty() {
        md.push('\n');
        md.push_str(&plots);
    }
    Ok(md)
}

fn exact_section(reports: &Path) -> Result<String, StudyError> {
    let mut md = String::from("## Code verification: exact solutions\n\nThe sections above are solution verification (against references computed by other software). This is the code-verification half: exact solutions of linear elasticity on the unit box (E = 1, ν = 0.3), imposed on the whole outer boundary, solved by the X-FEM code at several levels (structured, 6 tets per cube, n divisions per edge, h = 1/n; \"jittered\": interior nodes moved by up to 0.2 h; \"no ramp\": standard X-FEM in the blending elements; the others take a case's default, which with Tet4 and `tip_radius` R ramps them as corrected X-FEM does where R ≥ 2.5 h, h the median edge length, `cut::RAMP_SPAN`: here from n = 16 on, so a default's orders from n = 12 to 16 compare two methods, not a rate), with relative L2 and energy errors integrated on every integration cell (degree 5; collapsed rules at a front) against the exact field on each side of the cut. Orders are log(error ratio) / log(h ratio) between successive levels; the last pair's order is compared with the rate theory expects. Written by `xfem-cut converge --exact` (`src/study/exact.rs`); `tests/exact.rs` runs the same variants and asserts the orders.\n\n");
    let path = reports.join(exact::CSV);
    if !path.exists() {
        let _ = writeln!(
            md,
            "Not run: `xfem-cut converge --exact` writes `{}`.\n",
            exact::CSV
        );
        return Ok(md);
    }
    let rows = exact::read_csv(&path)?;
    let groups: Vec<Vec<&exact::Row>> = exact::by_variant(&rows)
        .into_iter()
        .filter(|g| !g[0].variant.starts_with(exact::SWEEP))
        .collect();
    let order_text = |p: Option<f64>| p.map_or("–".into(), |p| format!("{p:.2}"));
    let theory_text = |t: f64| {
        if t.is_nan() {
            "–".to_string()
        } else {
            format!("{t}")
        }
    };
    for case in [exact::Case::ThroughCut, exact::Case::NearFront] {
        let gs: Vec<&Vec<&exact::Row>> =
            groups.iter().filter(|g| g[0].case == case.name()).collect();
        if gs.is_empty() {
            continue;
        }
        let _ = writeln!(md, "### `{}`\n\n{}\n", case.name(), case.description());
        let svg = format!("exact_{}_error_dofs.svg", case.name());
        let mut lines = Vec::new();
        for (i, g) in gs.iter().enumerate() {
            let color = COLORS[i % COLORS.len()];
            let (l2, en) = exact::last_orders(g).unzip();
            let name = format!("{} {}", g[0].variant, g[0].element);
            lines.push(Line {
                label: format!("{name} L2 (order {})", order_text(l2)),
                points: g.iter().map(|r| (r.dofs as f64, r.l2)).collect(),
                color,
                thick: true,
            });
            lines.push(Line {
                label: format!("{name} energy (order {})", order_text(en)),
                points: g.iter().map(|r| (r.dofs as f64, r.energy)).collect(),
                color,
                thick: false,
            });
        }
        draw_lines(
            &reports.join(&svg),
            &format!("{}: error vs DOFs (thick: L2, thin: energy)", case.name()),
            "free DOFs",
            "relative error",
            &lines,
            SeriesLabelPosition::UpperRight,
        )?;
        let _ = writeln!(md, "![{} error vs DOFs]({svg})\n", case.name());
        let _ = writeln!(md, "| variant | element | observed L2 order (last pair) | theory | observed energy order | theory | within 0.2 of theory |\n| --- | --- | --- | --- | --- | --- | --- |");
        for g in &gs {
            let (l2, en) = exact::last_orders(g).unzip();
            let (tl2, ten) = (g[0].l2_theory, g[0].energy_theory);
            let met = |p: Option<f64>, t: f64| {
                p.zip((!t.is_nan()).then_some(t))
                    .map(|(p, t)| (p - t).abs() <= 0.2)
            };
            let verdict = match (met(l2, tl2), met(en, ten)) {
                (Some(true), Some(true)) => "yes",
                (None, None) => "–",
                _ => "**no**",
            };
            let _ = writeln!(
                md,
                "| {} | {} | {} | {} | {} | {} | {verdict} |",
                g[0].variant,
                g[0].element,
                order_text(l2),
                theory_text(tl2),
                order_text(en),
                theory_text(ten)
            );
        }
        let _ = writeln!(md, "\n| variant | element | n | elements | free DOFs | Heaviside / tip nodes | L2 error | energy error | L2 order | energy order | time (s) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
        for g in &gs {
            for (k, r) in g.iter().enumerate() {
                let (l2, en) = if k == 0 {
                    (None, None)
                } else {
                    exact::last_orders(&g[k - 1..=k]).unzip()
                };
                let _ = writeln!(
                    md,
                    "| {} | {} | {} | {} | {} | {} / {} | {:.3e} | {:.3e} | {} | {} | {:.1} |",
                    r.variant,
                    r.element,
                    r.divisions,
                    r.elements,
                    r.dofs,
                    r.heaviside,
                    r.tip,
                    r.l2,
                    r.energy,
                    order_text(l2),
                    order_text(en),
                    r.seconds
                );
            }
        }
        md.push('\n');
    }
    let sweep: Vec<&exact::Row> = rows
        .iter()
        .filter(|r| r.variant.starts_with(exact::SWEEP))
        .collect();
    if !sweep.is_empty() {
        md.push_str(&radius_sweep_section(reports, &sweep)?);
    }
    Ok(md)
}

/// What `tip_radius` buys ([`exact::radius_sweep`]): per element, the tip
/// nodes and DOFs (per unit length of front) and the DOFs added to the
/// extended front against the errors and the solve time, and a plot of the
/// errors against the free DOFs.
fn radius_sweep_section(reports: &Path, rows: &[&exact::Row]) -> Result<String, StudyError> {
    let length = exact::WilliamsFront::new().length_in_unit_box();
    let label = |r: &exact::Row| {
        r.variant
            .strip_prefix(exact::SWEEP)
            .map_or(r.variant.as_str(), |v| v.trim_start_matches(": "))
            .to_string()
    };
    let mut md = format!("### What `tip_radius` buys\n\nThe `near_front` case on one mesh per element (Tet4 n = 16, h = 0.0625; Tet10 n = 6, h = 0.167), its front ({length:.3} long in the box) extended to the element faces, tip-enriched topologically (the nodes of front elements, `front = \"tip\"`), and geometrically with `tip_radius` R (every node within R of the front; Tet4's blending elements ramped where R ≥ 2.5 h, as in a case). Tip DOFs: 3 components × 4 branch functions per tip node (those of nodes on the box's boundary take the exact field's values, not free), and per unit length of front; DOFs added: the free DOFs over the extended front's (tip nodes carry no Heaviside DOFs). Time: the whole solve (set-up, element data, factorisation), one thread. Written by `xfem-cut converge --exact` (`exact::radius_sweep`).\n\n");
    let svg = "exact_tip_radius_error_dofs.svg";
    let mut lines = Vec::new();
    for (i, kind) in ["tet4", "tet10"].into_iter().enumerate() {
        let mut pts: Vec<&&exact::Row> = rows.iter().filter(|r| r.element == kind).collect();
        if pts.is_empty() {
            continue;
        }
        pts.sort_by_key(|r| r.dofs);
        let color = COLORS[i % COLORS.len()];
        lines.push(Line {
            label: format!("{kind} L2 (extend, topological, R = 0.05 … 0.4)"),
            points: pts.iter().map(|r| (r.dofs as f64, r.l2)).collect(),
            color,
            thick: true,
        });
        lines.push(Line {
            label: format!("{kind} energy"),
            points: pts.iter().map(|r| (r.dofs as f64, r.energy)).collect(),
            color,
            thick: false,
        });
    }
    draw_lines(
        &reports.join(svg),
        "near_front: error vs DOFs as tip_radius grows (thick: L2, thin: energy)",
        "free DOFs",
        "relative error",
        &lines,
        SeriesLabelPosition::UpperRight,
    )?;
    let _ = writeln!(
        md,
        "![near_front errors against DOFs as tip_radius grows]({svg})\n"
    );
    let _ = writeln!(md, "| element | front | tip nodes | tip DOFs | tip DOFs per unit length of front | free DOFs | DOFs added to `extend` | L2 error | energy error | time (s) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for kind in ["tet4", "tet10"] {
        let base = rows
            .iter()
            .find(|r| r.element == kind && label(r) == "extend")
            .map(|r| r.dofs);
        for r in rows.iter().filter(|r| r.element == kind) {
            let tip_dofs = 3 * crate::front::N_BRANCH * r.tip;
            let added = base.map_or("–".to_string(), |b| {
                format!("{}", r.dofs as i64 - b as i64)
            });
            let _ = writeln!(
                md,
                "| {kind} | {} | {} | {tip_dofs} | {:.0} | {} | {added} | {:.3e} | {:.3e} | {:.2} |",
                label(r),
                r.tip,
                tip_dofs as f64 / length,
                r.dofs,
                r.l2,
                r.energy,
                r.seconds
            );
        }
    }
    md.push('\n');
    Ok(md)
}

/// Criterion medians kept in `reports/data/benches.csv` (id, median ns): those
/// `target/criterion` has replace the kept ones of the same id and are added to
/// the rest, so a partial `cargo bench` (one group) or a checkout that did not
/// run `make bench-report` keeps the last measured figures of the others.
fn benches_kept(
    reports: &Path,
    fresh: Vec<(String, f64)>,
) -> Result<Vec<(String, f64)>, StudyError> {
    let path = reports.join("data/benches.csv");
    let mut kept: Vec<(String, f64)> = match std::fs::read_to_string(&path) {
        Err(_) => Vec::new(),
        Ok(text) => text
            .lines()
            .skip(1)
            .filter(|l| !l.trim().is_empty())
            .map(|l| {
                l.rsplit_once(',')
                    .and_then(|(id, ns)| Some((id.to_string(), ns.trim().parse().ok()?)))
                    .ok_or_else(|| IoError::invalid(&path, format!("bad row `{l}`")))
            })
            .collect::<Result<_, _>>()?,
    };
    if fresh.is_empty() {
        return Ok(kept);
    }
    for (id, ns) in fresh {
        match kept.iter_mut().find(|(k, _)| *k == id) {
            Some(entry) => entry.1 = ns,
            None => kept.push((id, ns)),
        }
    }
    kept.sort_by(|a, b| a.0.cmp(&b.0));
    let mut text = String::from("id,median_ns\n");
    for (id, ns) in &kept {
        let _ = writeln!(text, "{id},{ns:e}");
    }
    crate::io::write_atomic(&path, |w| std::io::Write::write_all(w, text.as_bytes()))?;
    Ok(kept)
}

/// The median (ns) of the benchmark of `group` whose id holds every part
/// (criterion turns the `/` inside function names into `_` on disk).
fn median(benches: &[(String, f64)], group: &str, parts: &[&str]) -> Option<f64> {
    benches
        .iter()
        .find(|(id, _)| {
            let id = id.replace('_', "/");
            let segments: Vec<&str> = id.split('/').collect();
            segments.first() == Some(&group) && parts.iter().all(|p| segments.contains(p))
        })
        .map(|(_, ns)| *ns)
}

/// "tets (cut elements)" from the cut step's id (`…/1188tets-54cut`).
fn cut_counts(benches: &[(String, f64)], kind: &str, label: &str) -> String {
    benches
        .iter()
        .filter_map(|(id, _)| {
            let id = id.replace('_', "/");
            let segments: Vec<&str> = id.split('/').collect();
            let matches = segments.first() == Some(&"cut-step")
                && [kind, label, "linear-cut"]
                    .iter()
                    .all(|p| segments.contains(p));
            let (tets, cut) = segments
                .iter()
                .find_map(|s| s.strip_suffix("cut")?.split_once("tets-"))?;
            matches.then(|| format!("{tets} ({cut})"))
        })
        .next()
        .unwrap_or_else(|| "–".into())
}

/// The cut's cost from the `cut` bench: each precompute stage, the cut
/// set-up's share of it, and a step with the cut against one without on the same mesh.
fn cut_cost(benches: &[(String, f64)]) -> Option<String> {
    let mut md = String::from("## What the cut costs (criterion medians, bench `cut`)\n\nThe seed's half-cut beam, bottom clamped, gravity. Precompute = mesh + cut set-up (level set, classification, sub-tets, enrichment map) + element data and pattern + symbolic factorisation; the numeric factorisation is paid per step in corotational runs.\n\n| size | element | tets (cut) | mesh (ms) | cut set-up (ms) | element data (ms) | symbolic (ms) | numeric (ms) | cut set-up / precompute | linear step cut / uncut (ms) | corotational step cut / uncut (ms) |\n| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
    let mut any = false;
    for (label, kind) in [("1k", "tet4"), ("10k", "tet4"), ("1k", "tet10")] {
        let stage = |s: &str| median(benches, "precompute-split", &[s, kind, label]);
        let (Some(mesh), Some(cut), Some(data), Some(sym), Some(num)) = (
            stage("mesh"),
            stage("cut-setup"),
            stage("element-data"),
            stage("symbolic"),
            stage("numeric"),
        ) else {
            continue;
        };
        let step = |f: &str| -> String {
            let cut = median(benches, "cut-step", &[&format!("{f}-cut"), kind, label]);
            let uncut = median(benches, "cut-step", &[&format!("{f}-uncut"), kind, label]);
            match (cut, uncut) {
                (Some(c), Some(u)) => format!("{:.3} / {:.3} = {:.2}×", c * 1e-6, u * 1e-6, c / u),
                _ => "–".into(),
            }
        };
        any = true;
        let _ = writeln!(
            md,
            "| {label} | {kind} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.1} % | {} | {} |",
            cut_counts(benches, kind, label),
            mesh * 1e-6,
            cut * 1e-6,
            data * 1e-6,
            sym * 1e-6,
            num * 1e-6,
            100.0 * cut / (mesh + cut + data + sym),
            step("linear"),
            step("corotational")
        );
    }
    md.push('\n');
    any.then_some(md)
}

/// A step with the front tip-enriched (topological) against the same cut
/// extended, from the `tip` group of bench `cut`: one Newton iteration,
/// and the step a scene runs (Newton to its tolerance on the default
/// lagged factor); and the front's set-up against the whole precompute.
fn tip_cost(benches: &[(String, f64)]) -> Option<String> {
    let mut md = String::from("## What tip enrichment costs a step (criterion medians, bench `cut`, group `tip`)\n\nThe seed's beam with its cut shortened to x = 0.0137 m, so that the front lies inside elements, tip-enriched (topological) against the same cut extended to the element faces; issue 11 asks for ≤ 1.3× a step and a front set-up ≤ 10 % of the precompute. One iteration: one Newmark step of one Newton iteration (linear: on the constant factor; corotational: refactorised). Scene step: what a corotational scene runs, Newton to 1e-8 on the default lagged factor (`dynamics::DEFAULT_LAGGED`), the mean over the first 30 steps of the beam swinging from rest under gravity. Set-up: level sets, classification and sub-tets (`cut::setup_cut`), against itself plus the model built on it (element data and pattern; the symbolic factorisation left out, which makes the share larger). With the tip quadrature: the same plus the rules of the cells of every element with a tip-enriched node (collapsed onto the front, polar or refined near it; `Model::field_points_into`, as the precompute integrates on them), which is issue 11's front set-up (level sets, classification, tip quadrature). The integration on those rules is in the model's element data: the last column puts that precompute beside the extended front's, which is what the tip front's collapsed rules and refined blending cells cost before the first step (and what a cut event pays again on the elements holding branch functions). The tip elements are one dense group per side: their tip DOFs couple densely in the factor (what remains of the linear ratio: the linear step's forces are one product with the stiffness assembled once), and a corotational step's forces and exact tangent cost O(m²) a group in the element's m shape functions.\n\n| size | element | linear, one iteration: tip / extend (ms) | corotational, one iteration: tip / extend (ms) | corotational scene step: tip / extend (ms) | tip front set-up / precompute | with the tip quadrature / precompute | precompute: tip / extend (ms) |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n");
    let mut any = false;
    for (label, kind) in [("1k", "tet4"), ("10k", "tet4"), ("1k", "tet10")] {
        let ratio = |step: &str| -> Option<String> {
            let tip = median(benches, "tip", &[&format!("{step}-tip"), kind, label])?;
            let ext = median(benches, "tip", &[&format!("{step}-extend"), kind, label])?;
            Some(format!(
                "{:.3} / {:.3} = {:.2}×",
                tip * 1e-6,
                ext * 1e-6,
                tip / ext
            ))
        };
        let setup = || -> Option<String> {
            let setup = median(benches, "tip", &["setup-tip", kind, label])?;
            let rest = median(benches, "tip", &["precompute-tip", kind, label])?;
            Some(format!(
                "{:.2} / {:.2} ms = {:.1} %",
                setup * 1e-6,
                (setup + rest) * 1e-6,
                100.0 * setup / (setup + rest)
            ))
        };
        // Issue 11's front set-up: level sets, classification and the tip
        // quadrature (the rules, not the integration on them).
        let with_quadrature = || -> Option<String> {
            let setup = median(benches, "tip", &["setup-tip", kind, label])?;
            let rules = median(benches, "tip", &["quadrature-tip", kind, label])?;
            let rest = median(benches, "tip", &["precompute-tip", kind, label])?;
            Some(format!(
                "{:.2} / {:.2} ms = {:.1} %",
                (setup + rules) * 1e-6,
                (setup + rest) * 1e-6,
                100.0 * (setup + rules) / (setup + rest)
            ))
        };
        let precompute = || -> Option<String> {
            let tip = median(benches, "tip", &["setup-tip", kind, label])?
                + median(benches, "tip", &["precompute-tip", kind, label])?;
            let ext = median(benches, "tip", &["setup-extend", kind, label])?
                + median(benches, "tip", &["precompute-extend", kind, label])?;
            Some(format!(
                "{:.2} / {:.2} = {:.1}×",
                tip * 1e-6,
                ext * 1e-6,
                tip / ext
            ))
        };
        let cells = [
            ratio("step-linear"),
            ratio("step-corotational"),
            ratio("scene-step-corotational"),
            setup(),
            with_quadrature(),
            precompute(),
        ];
        if cells.iter().all(Option::is_none) {
            continue;
        }
        any = true;
        let cells = cells.map(|c| c.unwrap_or_else(|| "–".to_string()));
        let _ = writeln!(md, "| {label} | {kind} | {} |", cells.join(" | "));
    }
    md.push('\n');
    any.then_some(md)
}

/// Π with the digits that tell runs apart (their differences are ~1e-3 of
/// it); "–" where the study did not record it.
fn energy(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.6e}")
    } else {
        "–".to_string()
    }
}

/// A relative error for a table; "–" where it does not apply (NaN).
fn sci(v: f64) -> String {
    if v.is_nan() {
        "–".into()
    } else {
        format!("{v:.3e}")
    }
}

fn reference_family(case: &str) -> String {
    crate::study::converge::reference_of(case).map_or_else(|| "beam_crack".into(), |(f, _)| f)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(level: usize, h: f64, l2: f64) -> Row {
        Row {
            case: "gravity".into(),
            variant: "FEM pre-cut".into(),
            element: "tet4",
            level,
            h,
            elements: 1,
            dofs: 10 * (level + 1),
            precompute: 0.0,
            solve: 0.0,
            l2,
            opening: f64::NAN,
            probes: f64::NAN,
            energy: f64::NAN,
        }
    }

    fn quality(own_l2: f64) -> ReferenceQuality {
        ReferenceQuality {
            case: "gravity".into(),
            family: "beam_crack".into(),
            dofs: 1,
            front_h: 1e-3,
            far_h: 3e-3,
            coarse_dofs: 1,
            coarse_front_h: 1.4e-3,
            own_l2,
            own_opening: f64::NAN,
            own_probes: f64::NAN,
        }
    }

    #[test]
    fn unresolved_levels_are_left_out_of_the_order_fit() {
        // Errors exactly O(h) down to the third level, then flattened by the reference's own
        // error: fitted over all levels the order is lower, over the resolved ones it is 1.
        let rows = [
            row(0, 8e-3, 0.08),
            row(1, 4e-3, 0.04),
            row(2, 2e-3, 0.02),
            row(3, 1e-3, 0.012),
            row(4, 5e-4, 0.011),
        ];
        let refs: Vec<&Row> = rows.iter().collect();
        let all = order(&refs).unwrap();
        assert!(all < 0.9, "all levels: {all}");
        let q = quality(0.005);
        let (fit, kept) = fitted_order(&refs, Some(&q));
        assert_eq!(kept.iter().map(|r| r.level).collect::<Vec<_>>(), [0, 1, 2]);
        assert!((fit.unwrap() - 1.0).abs() < 1e-12, "resolved: {fit:?}");
        // Without a known own error every level is kept.
        assert_eq!(fitted_order(&refs, None).1.len(), 5);
        // One resolved level is no fit.
        assert!(fitted_order(&refs, Some(&quality(0.02))).0.is_none());
    }

    #[test]
    fn benchmarks_are_kept_when_criterion_has_none_or_some() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        assert!(benches_kept(dir.path(), Vec::new()).unwrap().is_empty());
        let fresh = vec![(
            "cut-step/linear-cut_tet4_1188tets-54cut/1k".to_string(),
            1.5e5,
        )];
        assert_eq!(benches_kept(dir.path(), fresh.clone()).unwrap(), fresh);
        assert_eq!(benches_kept(dir.path(), Vec::new()).unwrap(), fresh);
        // A partial run (one other group) replaces its own ids and keeps the rest.
        let partial = vec![
            ("a-tip/step".to_string(), 2.0e5),
            (fresh[0].0.clone(), 1.25e5),
        ];
        let merged = benches_kept(dir.path(), partial).unwrap();
        assert_eq!(
            merged,
            vec![
                ("a-tip/step".to_string(), 2.0e5),
                (fresh[0].0.clone(), 1.25e5)
            ]
        );
        assert_eq!(
            benches_kept(dir.path(), vec![("z".to_string(), 1.0)])
                .unwrap()
                .len(),
            3
        );
        std::fs::write(
            dir.path().join("data/benches.csv"),
            "id,median_ns\nx,notanumber\n",
        )
        .unwrap();
        assert!(benches_kept(dir.path(), Vec::new()).is_err());
    }

    #[test]
    fn theory_rates_per_case() {
        assert_eq!(expected_order("gravity", "FEM pre-cut", "tet10"), Some(1.0));
        assert_eq!(
            expected_order("slice", "X-FEM structured", "tet4"),
            Some(2.0)
        );
        assert_eq!(expected_order("slice", "FEM pre-cut", "tet10"), Some(3.0));
        assert_eq!(expected_order("bend", "FEM pre-cut", "tet4"), None);
    }

    /// The study's CSV against the graded references' own errors (both committed in
    /// reports/data): every case has its reference's own error, and on every row whose
    /// order is fitted the finest fitted level's error is ≥ 3× that own error.
    #[test]
    fn every_fitted_row_is_resolved_by_its_reference() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = read_csv(&reports.join("data/convergence.csv")).unwrap();
        let quality = qualities(&reports).unwrap();
        let cases = case_names(&rows);
        assert!(!cases.is_empty());
        let mut fitted = 0;
        for case in &cases {
            let q = quality
                .get(case)
                .unwrap_or_else(|| panic!("{case}: no own error in reports/data/references.csv"));
            assert!(q.own_l2 > 0.0 && q.own_l2.is_finite(), "{case}: {q:?}");
            for ((variant, element), rs) in &series(&rows, case) {
                let (fit, kept) = fitted_order(rs, Some(q));
                let Some(p) = fit else { continue };
                let finest = kept.iter().min_by(|a, b| a.h.total_cmp(&b.h)).unwrap();
                eprintln!(
                    "{case} {variant} {element}: order {p:.2} over {} levels, finest L{} error {:.3e} = {:.1}× own {:.3e}",
                    kept.len(),
                    finest.level,
                    finest.l2,
                    finest.l2 / q.own_l2,
                    q.own_l2
                );
                assert!(
                    finest.l2 >= RESOLVED_FACTOR * q.own_l2,
                    "{case} {variant} {element}"
                );
                fitted += 1;
            }
        }
        assert!(fitted > 0, "no row fitted");
    }

    /// Issue 11's check on the seed beam (the committed study against the graded
    /// references): X-FEM with tip enrichment (topological and geometric) on the
    /// unstructured uncut meshes has a lower L2 error than remeshed FEM at the same
    /// DOFs at L2 and L3 — lower by more than the reference's own error — for Tet4
    /// and Tet10, and its error falls at every refinement the reference resolves.
    ///
    /// `gravity` and `stretch_face`. `bend_face` does not meet it (its own test
    /// below says what it meets): there tip-enriched Tet4 stalls at 6.1–6.2 % from
    /// L3 to L4 while remeshed FEM reaches 4.5–4.7 % and the extended front
    /// 3.4–3.9 %, and Tet10 at L2 is 2.69 % against FEM's 1.04 %; the level meshes
    /// leave the strip's free edge unresolved, whose error remeshed FEM's stiff
    /// crack offsets (refs/README.md, "Why the strip edges are graded"). With
    /// that edge graded in both meshes Tet10 meets it there too (the one-mesh
    /// comparison's uncut rows, tested below).
    #[test]
    fn tip_enriched_xfem_beats_remeshed_fem_on_the_seed_beam() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = read_csv(&reports.join("data/convergence.csv")).unwrap();
        let quality = qualities(&reports).unwrap();
        for case in ["gravity", "stretch_face"] {
            let q = quality.get(case).unwrap();
            let s = series(&rows, case);
            for element in ["tet4", "tet10"] {
                let fem = &s[&("FEM pre-cut".to_string(), element)];
                for variant in [
                    "X-FEM unstructured, tip",
                    "X-FEM unstructured, geometric tip R=5 mm",
                ] {
                    let tip = &s[&(variant.to_string(), element)];
                    for level in [2, 3] {
                        let r = tip
                            .iter()
                            .find(|r| r.level == level)
                            .unwrap_or_else(|| panic!("{case} {variant} {element}: no L{level}"));
                        let f = fem_error_at(fem, r.dofs);
                        eprintln!(
                            "{case} {variant} {element} L{level}: {} DOFs, L2 {:.3e}, FEM there {f:?}, own {:.3e}",
                            r.dofs, r.l2, q.own_l2
                        );
                        assert_eq!(
                            verdict(r.l2, f, q.own_l2),
                            Verdict::Lower,
                            "{case} {variant} {element} L{level}"
                        );
                    }
                    let kept = resolved(tip, Some(q));
                    assert!(
                        kept.windows(2).all(|w| w[1].l2 < w[0].l2),
                        "{case} {variant} {element}: not falling over the resolved levels"
                    );
                }
            }
        }
    }

    /// In energy, which needs no reference: on the three well-posed cases of
    /// the seed's beam, tip-enriched X-FEM (topological and within 5 mm) has a
    /// lower total potential energy Π than remeshed FEM at every level, Tet4
    /// and Tet10, so it is the more accurate in the energy norm (same body,
    /// same Dirichlet data), `bend_face` included, where its L2 error against
    /// the reference is the higher one (Tet4: 6.20 % against 4.69 % at L4).
    /// X-FEM has at most 6.7 % more DOFs (Tet4, L0: that mesh has faces in
    /// z = 0.1 the front crosses, whose nodes are lifted off the plane, 3
    /// tip nodes more) and up to 4 % fewer (Tet10) than FEM at the same level.
    #[test]
    fn tip_enriched_xfem_has_the_lower_energy_than_remeshed_fem_at_every_level() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = read_csv(&reports.join("data/convergence.csv")).unwrap();
        for case in ["gravity", "stretch_face", "bend_face"] {
            let s = series(&rows, case);
            for element in ["tet4", "tet10"] {
                let fem = &s[&("FEM pre-cut".to_string(), element)];
                for variant in [
                    "X-FEM unstructured, tip",
                    "X-FEM unstructured, geometric tip R=5 mm",
                ] {
                    let tip = &s[&(variant.to_string(), element)];
                    assert!(
                        tip.len() >= 4,
                        "{case} {variant} {element}: {} levels",
                        tip.len()
                    );
                    for r in tip {
                        let f = fem.iter().find(|f| f.level == r.level).unwrap();
                        eprintln!(
                            "{case} {variant} {element} L{}: Π {:.6e} ({} DOFs) against FEM {:.6e} ({} DOFs)",
                            r.level, r.energy, r.dofs, f.energy, f.dofs
                        );
                        assert!(
                            r.energy < f.energy,
                            "{case} {variant} {element} L{}: Π {} ≥ FEM's {}",
                            r.level,
                            r.energy,
                            f.energy
                        );
                        // At most 8.3 % more DOFs (`gravity` Tet4 L0: 2160 against 1995;
                        // its front also held by the elements it runs along behind it).
                        assert!(r.dofs as f64 <= 1.09 * f.dofs as f64, "{} DOFs", r.dofs);
                    }
                }
            }
        }
    }

    /// `bend_face` (the top strip pushed over and down): tip enrichment opens
    /// the cut closer to the reference than the extended front at every level
    /// (Tet4 and Tet10), and Tet4's closer than remeshed FEM's too (2.9–5.3× from
    /// L1 on). Against the reference graded towards the strip's free edge
    /// as well (refs/README.md, "Why the strip edges are graded") remeshed
    /// FEM's Tet10 opening is the closer from L1 on, and the extended front's
    /// Tet10 L2 error the lower at L1 and L3: on the level meshes, which leave that edge
    /// unresolved, the stiff crack of remeshed FEM and of the extended front
    /// offsets the stiff strip edge (the reference graded at the crack front
    /// only had said the opposite: tip Tet10 below the extended front in L2
    /// at every level, its opening the closest).
    #[test]
    fn tip_enrichment_on_bend_face_opens_the_cut_closest_to_the_reference() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = read_csv(&reports.join("data/convergence.csv")).unwrap();
        let s = series(&rows, "bend_face");
        let get = |v: &str, e: &'static str| &s[&(v.to_string(), e)];
        for element in ["tet4", "tet10"] {
            let tip = get("X-FEM unstructured, tip", element);
            let extend = get("X-FEM unstructured, extend", element);
            let fem = get("FEM pre-cut", element);
            for (t, x) in tip.iter().zip(extend.iter()) {
                assert_eq!(t.level, x.level);
                let f = fem.iter().find(|f| f.level == t.level).unwrap();
                eprintln!(
                    "bend_face {element} L{}: opening tip {:.3e}, extend {:.3e}, FEM {:.3e}; L2 tip {:.3e}, extend {:.3e}, FEM {:.3e}",
                    t.level, t.opening, x.opening, f.opening, t.l2, x.l2, f.l2
                );
                assert!(t.opening < x.opening, "{element} L{}", t.level);
                if element == "tet4" {
                    assert!(t.opening < f.opening, "L{}", t.level);
                }
            }
        }
    }

    /// The one-mesh comparison (reports/data/one_mesh.csv, `examples/error_map.rs
    /// one-mesh`): on gmsh's crack mesh with the crack's nodes shared, graded to
    /// h/4 at the face cases' strip edges, tip-enriched Tet10 errs in L2 at most
    /// 0.6× remeshed FEM on the same mesh (L1, L2 and L3, `bend_face` and
    /// `stretch_face`; measured 0.44 / 0.52 / 0.42 and 0.13 / 0.16 / 0.19; at
    /// L3 the tip front's 2.2e-3 on `stretch_face` nears its reference's own
    /// 1.7e-3, FEM's 1.2e-2 does not), where on the uniform
    /// meshes `bend_face`'s FEM is the closer (ratio 2.7: FEM's stiff crack offsets
    /// the unresolved edge). The tip front's Π is below FEM's on every mesh, Tet4
    /// and Tet10, and grading the edge lowers every run's Π. (Tet4 on `bend_face`
    /// stays above FEM in L2 when graded too, 1.5×: its bulk error in bending.)
    ///
    /// Issue 11's own comparison with the edge resolved: the tip front on the
    /// body meshed *without* the crack and graded alike (its front inside
    /// elements, as in the study), beside FEM on the graded crack mesh. Tet10
    /// errs at most half FEM's L2 error at L1, L2 and L3 on fewer DOFs
    /// (`bend_face` 0.44 / 0.46 / 0.38, `stretch_face` 0.13 / 0.13 / 0.16; 0.5–1.0 %
    /// fewer DOFs), its error falling at every level; Tet4 (L1–L4, 1.2–2.7 % more
    /// DOFs) on `stretch_face` below FEM at every level (0.87 / 0.85 / 0.93 /
    /// 0.90), on `bend_face` behind it (1.34 / 1.20 / 1.05 / 1.12), its error
    /// falling at every level too.
    #[test]
    fn resolving_the_strip_edges_puts_the_tip_front_ahead_of_remeshed_fem_on_one_mesh() {
        use crate::study::one_mesh;
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = one_mesh::read_csv(&reports.join(one_mesh::CSV)).unwrap();
        let pairs = one_mesh::pairs(&rows);
        // Every tip run has its FEM run.
        assert_eq!(
            pairs.len(),
            rows.iter().filter(|r| r.variant == "tip").count()
        );
        let (mut tet10_graded, mut uncut) = (0, 0);
        for p in &pairs {
            let (f, t) = (p.fem, p.tip);
            eprintln!(
                "{} {} {} L{}: L2 FEM {:.3e}, tip {:.3e} ({:.2}); Π FEM {:.6}, tip {:.6}; DOFs {} / {}",
                f.case,
                t.mesh,
                f.element,
                f.level,
                f.l2_rel,
                t.l2_rel,
                p.l2_ratio(),
                f.potential_energy_j,
                t.potential_energy_j,
                f.dofs,
                t.dofs
            );
            assert!(
                t.potential_energy_j < f.potential_energy_j,
                "{} {} {} L{}",
                f.case,
                t.mesh,
                f.element,
                f.level
            );
            if f.element == "tet10" && t.mesh == "strip edges" {
                assert!(p.l2_ratio() <= 0.6, "{} L{}", f.case, f.level);
                tet10_graded += 1;
            }
            if t.mesh == one_mesh::UNCUT_STRIPS {
                uncut += 1;
                assert_eq!(f.mesh, "strip edges");
                // Tet10 on fewer DOFs; Tet4 on at most 3 % more (its tip DOFs
                // outweigh the nodes the crack's faces add to FEM's mesh).
                let more = if f.element == "tet10" { 1.0 } else { 1.03 };
                assert!(
                    t.dofs as f64 <= more * f.dofs as f64,
                    "{} {} L{}",
                    f.case,
                    f.element,
                    f.level
                );
                let ratio = p.l2_ratio();
                match (f.element.as_str(), f.case.as_str()) {
                    ("tet10", _) => assert!(ratio <= 0.5, "{} L{}: {ratio}", f.case, f.level),
                    ("tet4", "stretch_face") => assert!(ratio < 1.0, "L{}: {ratio}", f.level),
                    // Tet4 on `bend_face`: behind FEM at every level, by 5–34 %.
                    _ => assert!((1.0..1.35).contains(&ratio), "L{}: {ratio}", f.level),
                }
                // Its error falls at every level.
                if let Some(prev) = rows.iter().find(|r| {
                    r.mesh == t.mesh
                        && (&r.case, &r.element, r.level + 1) == (&t.case, &t.element, t.level)
                }) {
                    assert!(
                        t.l2_rel < prev.l2_rel,
                        "{} {} L{}",
                        t.case,
                        t.element,
                        t.level
                    );
                }
            }
            for r in [f, t] {
                let uniform = rows
                    .iter()
                    .find(|u| {
                        u.mesh == "uniform"
                            && (&u.case, &u.element, u.level, &u.variant)
                                == (&r.case, &r.element, r.level, &r.variant)
                    })
                    .unwrap();
                if r.mesh == "strip edges" {
                    assert!(r.potential_energy_j < uniform.potential_energy_j);
                }
            }
        }
        assert_eq!(uncut, 14, "both cases, Tet4 L1–L4 and Tet10 L1–L3");
        assert_eq!(tet10_graded, 6, "L1–L3 of both cases");
        let md = one_mesh::section(&reports).unwrap().unwrap();
        assert_eq!(
            md.lines().filter(|l| l.starts_with("| `")).count(),
            pairs.len()
        );
        let readme = std::fs::read_to_string(reports.join("README.md")).unwrap();
        assert!(readme.contains("## One mesh: the tip front beside remeshed FEM"));
    }

    /// The one-mesh comparison's plots: one SVG per case from the committed
    /// CSV, and the page's lines that show them.
    #[test]
    fn the_one_mesh_comparison_is_plotted_per_case() {
        use crate::study::one_mesh;
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        std::fs::copy(reports.join(one_mesh::CSV), dir.path().join(one_mesh::CSV)).unwrap();
        let md = one_mesh_plots(dir.path()).unwrap();
        for case in ["bend_face", "stretch_face"] {
            let svg =
                std::fs::read_to_string(dir.path().join(format!("one_mesh_{case}.svg"))).unwrap();
            assert!(svg.contains("<svg") && svg.contains("tip, strip edges, uncut mesh, tet10"));
            assert!(md.contains(&format!("](one_mesh_{case}.svg)")), "{md}");
            // The committed page shows it.
            let page = std::fs::read_to_string(reports.join("README.md")).unwrap();
            assert!(page.contains(&format!("](one_mesh_{case}.svg)")));
            assert!(reports.join(format!("one_mesh_{case}.svg")).exists());
        }
    }

    /// The committed page opens with its method and summary; what was run
    /// again since the last whole `make report` closes it.
    #[test]
    fn the_page_opens_with_its_summary_and_ends_with_its_provenance() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let readme = std::fs::read_to_string(reports.join("README.md")).unwrap();
        let at = |heading: &str| readme.find(heading).unwrap_or_else(|| panic!("{heading}"));
        let summary = at("\n## Summary\n");
        let provenance = at("\n## Provenance: what was run again, and when\n");
        assert!(summary < provenance);
        let first = std::fs::read_to_string(reports.join("data/provenance.md")).unwrap();
        let first = first.lines().next().unwrap();
        assert!(readme.find(first).unwrap() > provenance);
        assert!(
            readme[provenance + 1..].find("\n## ").is_none(),
            "no section after the provenance"
        );
    }

    #[test]
    fn fem_error_is_interpolated_and_extrapolated_only_a_little() {
        let row = |dofs: usize, l2: f64| Row {
            case: "c".into(),
            variant: "FEM pre-cut".into(),
            element: "tet4",
            level: 0,
            h: 1.0,
            elements: 1,
            dofs,
            precompute: 0.0,
            solve: 0.0,
            l2,
            opening: f64::NAN,
            probes: f64::NAN,
            energy: f64::NAN,
        };
        let (a, b) = (row(1000, 0.1), row(8000, 0.025));
        let fem = [&a, &b];
        assert_eq!(fem_error_at(&fem, 500), Some(0.1));
        // Halfway in log DOFs: the geometric mean.
        let mid = fem_error_at(&fem, 2828).unwrap();
        assert!((mid - 0.05).abs() < 1e-4, "{mid}");
        let beyond = fem_error_at(&fem, 10_000).unwrap();
        assert!(beyond < 0.025 && beyond > 0.02, "{beyond}");
        assert_eq!(fem_error_at(&fem, 10_001), None);
        assert_eq!(verdict(0.01, Some(0.02), 0.005), Verdict::Lower);
        assert_eq!(verdict(0.018, Some(0.02), 0.005), Verdict::Unresolved);
        assert_eq!(verdict(0.03, Some(0.02), 0.005), Verdict::Higher);
        assert_eq!(verdict(0.03, None, 0.005), Verdict::NoFem);
    }

    /// The committed static-solve comparison (`refs/bench_static.py`): Tet4
    /// and Tet10 on 1 and 2 cores from ~10k to ~400k DOFs, each speed-up the
    /// faster FEniCSx run over ours, and the report shows every row.
    #[test]
    fn the_static_comparison_covers_10k_to_400k_dofs_on_1_and_2_cores() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows: Vec<StaticRow> =
            crate::io::csv::read_rows(&reports.join("data/static_vs_fenicsx.csv"), false).unwrap();
        for element in ["tet4", "tet10"] {
            for cores in [1, 2] {
                let dofs: Vec<usize> = rows
                    .iter()
                    .filter(|r| r.element == element && r.cores == cores)
                    .map(|r| r.dofs_fenicsx)
                    .collect();
                let (lo, hi) = (dofs.iter().min().unwrap(), dofs.iter().max().unwrap());
                assert!(
                    *lo <= 16_000 && *hi >= 330_000,
                    "{element} {cores}: {dofs:?}"
                );
            }
        }
        for r in &rows {
            let best = r
                .fenicsx_2ranks_s
                .map_or(r.fenicsx_1rank_s, |t| t.min(r.fenicsx_1rank_s));
            assert!(
                (best / r.ours_s - r.speedup).abs() < 2e-3 * r.speedup,
                "{r:?}"
            );
            assert!(r.ours_peak_mb > 0.0 && r.fenicsx_1rank_peak_mb > 0.0 && r.h_mm > 0.0);
            assert!(r.dofs_ours_free <= r.dofs_fenicsx);
        }
        let section = static_section(&reports).unwrap().unwrap();
        assert_eq!(
            section.lines().filter(|l| l.starts_with("| tet")).count(),
            rows.len()
        );
    }

    /// The pictures of every case exist, are PNGs of some size and the report shows them.
    #[test]
    fn pictures_exist_and_the_report_shows_them() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let readme = std::fs::read_to_string(reports.join("README.md")).unwrap();
        for case in [
            "gravity",
            "stretch",
            "bend",
            "stretch_face",
            "bend_face",
            "slice",
        ] {
            let name = format!("pictures/{case}.png");
            let bytes =
                std::fs::read(reports.join(&name)).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(
                bytes.starts_with(b"\x89PNG\r\n\x1a\n"),
                "{name} is not a PNG"
            );
            assert!(bytes.len() > 50_000, "{name}: only {} bytes", bytes.len());
            assert!(
                readme.contains(&format!("]({name})")),
                "README.md does not show {name}"
            );
        }
    }

    /// The committed exact-solution study (reports/data/exact.csv) through the
    /// report's section: every variant of both cases is there, the through-cut
    /// orders are within 0.2 of theory (issue 14), the near-front geometric
    /// Tet4 orders of a case's default (the ramp from n = 16 on) meet issue
    /// 11's ≥ 1.8 / ≥ 0.85, and the section shows its plots. Standard X-FEM
    /// ("no ramp") gave 1.85 / 0.84 over n = 24 → 32 (the blending elements'
    /// error), which the report and README say; it is held to ≥ 1.8 / ≥ 0.8
    /// so that a change that lowers it further fails.
    #[test]
    fn the_committed_exact_study_meets_its_orders_and_the_report_shows_it() {
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = exact::read_csv(&reports.join(exact::CSV)).unwrap();
        let (groups, sweep): (Vec<_>, Vec<_>) = exact::by_variant(&rows)
            .into_iter()
            .partition(|g| !g[0].variant.starts_with(exact::SWEEP));
        assert_eq!(groups.len(), exact::study_variants().len());
        // The tip_radius sweep: one row per variant, each there.
        assert_eq!(sweep.len(), exact::radius_sweep().len());
        assert!(sweep.iter().all(|g| g.len() == 1));
        let sweep: Vec<&exact::Row> = sweep.iter().map(|g| g[0]).collect();
        if let Err(e) = exact::check_radius_sweep(&sweep) {
            panic!("{e}");
        }
        for g in &groups {
            let (l2, en) = exact::last_orders(g).unwrap();
            let r = g[0];
            eprintln!(
                "{} {} {}: orders {l2:.2} / {en:.2} (theory {} / {})",
                r.case, r.variant, r.element, r.l2_theory, r.energy_theory
            );
            if r.case == "through_cut" {
                assert!((l2 - r.l2_theory).abs() <= 0.2 && (en - r.energy_theory).abs() <= 0.2);
            }
            if r.case == "near_front" && r.element == "tet4" && r.variant.starts_with("geometric") {
                let energy = if r.variant.contains("no ramp") {
                    0.8
                } else {
                    0.85
                };
                assert!(l2 >= 1.8 && en >= energy, "{}: {l2} {en}", r.variant);
            }
        }
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("data")).unwrap();
        std::fs::copy(reports.join(exact::CSV), dir.path().join(exact::CSV)).unwrap();
        let md = exact_section(dir.path()).unwrap();
        for case in ["through_cut", "near_front"] {
            let svg = format!("exact_{case}_error_dofs.svg");
            assert!(md.contains(&format!("]({svg})")), "{case}");
            assert!(std::fs::metadata(dir.path().join(&svg)).unwrap().len() > 5_000);
        }
        assert!(md.contains("](exact_tip_radius_error_dofs.svg)"));
        assert!(
            std::fs::metadata(dir.path().join("exact_tip_radius_error_dofs.svg"))
                .unwrap()
                .len()
                > 5_000
        );
        // One table row per sweep variant, with its tip DOFs per unit length.
        let length = exact::WilliamsFront::new().length_in_unit_box();
        for r in &sweep {
            let per_length = (12 * r.tip) as f64 / length;
            assert!(
                md.contains(&format!("| {} | {} | {per_length:.0} |", r.tip, 12 * r.tip)),
                "{} {}",
                r.variant,
                r.element
            );
        }
        let readme = std::fs::read_to_string(reports.join("README.md")).unwrap();
        assert!(readme.contains("### `through_cut`") && readme.contains("### `near_front`"));
        assert!(readme.contains("### What `tip_radius` buys"));
    }

    /// The committed measurement behind `cut::RAMP_SPAN`
    /// (reports/data/ramp_span.csv, `examples/error_map.rs ramp-span`):
    /// every pair of runs with R ≥ 2.5 h narrowed the gap of Π to the
    /// reference's with the ramp, and the report's section tabulates every
    /// pair with that tally.
    #[test]
    fn the_committed_ramp_span_backs_the_rule_and_the_report_shows_it() {
        use crate::study::ramp;
        let reports = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports");
        let rows = ramp::read_csv(&reports.join(ramp::CSV)).unwrap();
        let pairs = ramp::pairs(&rows);
        assert_eq!(2 * pairs.len(), rows.len());
        let above = ramp::tally(&pairs, crate::cut::RAMP_SPAN, true).unwrap();
        assert!(above.runs >= 30, "{above:?}");
        assert_eq!(above.narrowed, above.runs, "{above:?}");
        let below = ramp::tally(&pairs, crate::cut::RAMP_SPAN, false).unwrap();
        assert!(below.narrowed < below.runs, "{below:?}");
        let md = ramp::section(&reports).unwrap().unwrap();
        assert_eq!(
            md.lines().filter(|l| l.starts_with("| `")).count(),
            pairs.len()
        );
        assert!(md.contains(&format!(
            "the ramp narrowed the gap in {} of {} runs",
            above.runs, above.runs
        )));
        let readme = std::fs::read_to_string(reports.join("README.md")).unwrap();
        assert!(readme.contains("## What the ramp buys on the beam, against R / h"));
    }

    #[test]
    fn cut_counts_and_medians_are_read_from_criterion_ids() {
        // Ids as criterion_medians returns them (`/` inside names became `_`).
        let benches = vec![
            (
                "cut-step/linear-uncut_tet4_10800tets-0cut/10k".to_string(),
                1.0e6,
            ),
            (
                "cut-step/linear-cut_tet4_10800tets-216cut/10k".to_string(),
                1.2e6,
            ),
            (
                "cut-step/linear-cut_tet10_1188tets-54cut/1k".to_string(),
                2.0e6,
            ),
        ];
        assert_eq!(cut_counts(&benches, "tet4", "10k"), "10800 (216)");
        assert_eq!(cut_counts(&benches, "tet10", "1k"), "1188 (54)");
        assert_eq!(cut_counts(&benches, "tet4", "1k"), "–");
        assert_eq!(
            median(&benches, "cut-step", &["linear-cut", "tet4", "10k"]),
            Some(1.2e6)
        );
        assert_eq!(
            median(&benches, "cut-step", &["linear-uncut", "tet4", "10k"]),
            Some(1.0e6)
        );
    }

    #[test]
    fn the_tip_cost_table_puts_each_step_and_the_set_up_beside_the_extended_front() {
        let id = |name: &str, front: &str| format!("tip/{name}-{front}_tet4_1080tets-21tip/1k");
        let benches = vec![
            (id("step-linear", "tip"), 0.2e6),
            (id("step-linear", "extend"), 0.1e6),
            (id("scene-step-corotational", "tip"), 6.0e6),
            (id("scene-step-corotational", "extend"), 2.4e6),
            ("tip/setup-tip_tet4_1080tets/1k".to_string(), 0.5e6),
            ("tip/precompute-tip_tet4_1080tets/1k".to_string(), 4.5e6),
            ("tip/setup-extend_tet4_1080tets/1k".to_string(), 0.1e6),
            ("tip/precompute-extend_tet4_1080tets/1k".to_string(), 0.9e6),
            ("tip/quadrature-tip_tet4_1080tets/1k".to_string(), 0.25e6),
        ];
        let md = tip_cost(&benches).expect("a row");
        let row = md
            .lines()
            .find(|l| l.starts_with("| 1k | tet4 |"))
            .expect("the 1k Tet4 row");
        assert_eq!(
            row,
            "| 1k | tet4 | 0.200 / 0.100 = 2.00× | – | 6.000 / 2.400 = 2.50× | 0.50 / 5.00 ms = 10.0 % | 0.75 / 5.00 ms = 15.0 % | 5.00 / 1.00 = 5.0× |"
        );
        assert!(!md.contains("| 10k |"), "{md}");
        assert!(tip_cost(&[]).is_none());
    }

    #[test]
    fn the_sweep_section_summarises_the_committed_series_and_draws_it() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("data")).unwrap();
        let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("reports/data/sweep_series.csv");
        std::fs::copy(&committed, dir.path().join("data/sweep_series.csv")).unwrap();
        let alone = sweep_section(dir.path()).unwrap().expect("a section");
        assert!(!alone.contains("### Each front"), "{alone}");
        // With the other committed series: a row and a plot each, the tip
        // front's sweep an event at nearly every step.
        for (stem, _, _) in &SWEEP_SERIES[1..] {
            let from = committed.with_file_name(format!("{stem}.csv"));
            std::fs::copy(&from, dir.path().join(format!("data/{stem}.csv"))).unwrap();
        }
        let md = sweep_section(dir.path()).unwrap().expect("a section");
        for (stem, front, formulation) in &SWEEP_SERIES {
            assert!(
                md.contains(&format!("| {front} | {formulation} | ")),
                "{md}"
            );
            if *stem != "sweep_series" {
                assert!(md.contains(&format!("({stem}.svg)")), "{md}");
                let svg = std::fs::metadata(dir.path().join(format!("{stem}.svg"))).unwrap();
                assert!(svg.len() > 1000);
            }
        }
        let tip = crate::study::sweep::read_csv(&committed.with_file_name("sweep_series_tip.csv"))
            .unwrap();
        let p = crate::study::sweep::phases(&tip, 0.1, 0.6);
        assert!(p.events + 1 >= p.sweep_steps, "{p:?}");
        assert!(p.uncut_step > 0.0 && p.sweep_step > p.uncut_step, "{p:?}");
        println!("{md}");
        let rows = crate::study::sweep::read_csv(&committed).unwrap();
        let events = rows.iter().filter(|r| r.event).count();
        assert!(events > 0);
        assert!(
            md.contains(&format!("{} steps, {events} cut events", rows.len())),
            "{md}"
        );
        assert!(md.contains("(sweep_series.svg)"));
        // The frames of the blade appear where `make pictures` drew them.
        assert!(!md.contains(SWEEP_PICTURE));
        std::fs::create_dir_all(dir.path().join("pictures")).unwrap();
        std::fs::write(dir.path().join(SWEEP_PICTURE), b"png").unwrap();
        let with = sweep_section(dir.path()).unwrap().expect("a section");
        assert!(with.contains(&format!("]({SWEEP_PICTURE})")));
        assert!(Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("reports")
            .join(SWEEP_PICTURE)
            .exists());
        let svg = std::fs::metadata(dir.path().join("sweep_series.svg")).unwrap();
        assert!(svg.len() > 1000);
        assert!(sweep_section(&dir.path().join("nothing"))
            .unwrap()
            .is_none());
    }
}

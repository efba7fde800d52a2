//! CSV files through the `csv` crate and serde, one way for all of them:
//! [`write_rows`] / [`read_rows`] for any record type (a header from its
//! field names), and the probe results `probes.csv` (`x,y,z,ux,uy,uz`, one
//! row per probe: reference position in, displacement out). Numbers are
//! written with [`sci`] in Rust's shortest round-trip form (`{:e}`), so
//! reading them back is exact.

use super::{read_bytes, write_atomic, IoError};
use nalgebra::{Point3, Vector3};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize, Serializer};
use std::path::Path;

/// The header line of a probe file.
pub const PROBES_HEADER: &str = "x,y,z,ux,uy,uz";

/// Serialises an `f64` as `{:e}` (shortest round-trip, scientific): use with
/// `#[serde(serialize_with = "crate::io::csv::sci")]`.
pub fn sci<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(&format_args!("{x:e}"))
}

/// Writes `rows` with a header from the record's field names; atomically.
pub fn write_rows<T: Serialize>(path: &Path, rows: &[T]) -> Result<(), IoError> {
    write_atomic(path, |w| {
        let mut out = csv::WriterBuilder::new()
            .terminator(csv::Terminator::Any(b'\n'))
            .from_writer(w);
        for r in rows {
            out.serialize(r).map_err(std::io::Error::other)?;
        }
        out.flush()
    })
}

/// Reads the rows of a CSV with a header naming `T`'s fields; an error names
/// the file and the line. With `flexible`, rows may lack trailing fields
/// (older layouts; their `Option` fields read as `None`).
pub fn read_rows<T: DeserializeOwned>(path: &Path, flexible: bool) -> Result<Vec<T>, IoError> {
    let bytes = read_bytes(path)?;
    let mut reader = csv::ReaderBuilder::new()
        .flexible(flexible)
        .trim(csv::Trim::All)
        .from_reader(bytes.as_slice());
    reader
        .deserialize()
        .map(|r| {
            r.map_err(|e| {
                let line = e.position().map_or(0, |p| p.line());
                let what = match e.kind() {
                    csv::ErrorKind::Deserialize { err, .. } => err.to_string(),
                    _ => e.to_string(),
                };
                IoError::invalid(path, format!("line {line}: {}", what.replace('\n', " ")))
            })
        })
        .collect()
}

/// One row of `probes.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
struct ProbeRow {
    #[serde(serialize_with = "sci")]
    x: f64,
    #[serde(serialize_with = "sci")]
    y: f64,
    #[serde(serialize_with = "sci")]
    z: f64,
    #[serde(serialize_with = "sci")]
    ux: f64,
    #[serde(serialize_with = "sci")]
    uy: f64,
    #[serde(serialize_with = "sci")]
    uz: f64,
}

/// Writes one row per probe: its reference position and displacement; atomically.
pub fn write_probes_csv(
    path: &Path,
    points: &[Point3<f64>],
    displacements: &[Vector3<f64>],
) -> Result<(), IoError> {
    if points.len() != displacements.len() {
        return Err(IoError::invalid(
            path,
            format!(
                "{} probe points but {} displacements",
                points.len(),
                displacements.len()
            ),
        ));
    }
    let rows: Vec<ProbeRow> = points
        .iter()
        .zip(displacements)
        .map(|(p, u)| ProbeRow {
            x: p.x,
            y: p.y,
            z: p.z,
            ux: u.x,
            uy: u.y,
            uz: u.z,
        })
        .collect();
    if rows.is_empty() {
        // A header alone: the csv crate writes none without a record.
        return write_atomic(path, |w| {
            use std::io::Write;
            writeln!(w, "{PROBES_HEADER}")
        });
    }
    write_rows(path, &rows)
}

/// Reads a probe file written by [`write_probes_csv`] (or any CSV with that
/// header and six numbers per row): the points and displacements.
#[allow(clippy::type_complexity)]
pub fn read_probes_csv(path: &Path) -> Result<(Vec<Point3<f64>>, Vec<Vector3<f64>>), IoError> {
    let bytes = read_bytes(path)?;
    let header = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
    let header: String = String::from_utf8_lossy(header)
        .chars()
        .filter(|c| !c.is_whitespace())
        .collect();
    if header != PROBES_HEADER {
        return Err(IoError::invalid(
            path,
            format!("header is `{header}`, expected `{PROBES_HEADER}`"),
        ));
    }
    let rows: Vec<ProbeRow> = read_rows(path, false)?;
    Ok(rows
        .iter()
        .map(|r| (Point3::new(r.x, r.y, r.z), Vector3::new(r.ux, r.uy, r.uz)))
        .unzip())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probes_round_trip_to_the_last_bit() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("probes.csv");
        let points = vec![
            Point3::new(0.0, 0.03, 0.2),
            Point3::new(0.1 + 0.2, -0.0, 1e-310),
        ];
        let disp = vec![
            Vector3::new(1.0 / 3.0, -2e-17, 123456789.12345679),
            Vector3::new(f64::MIN_POSITIVE, f64::MAX, -7.0),
        ];
        write_probes_csv(&p, &points, &disp).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text.lines().next(), Some("x,y,z,ux,uy,uz"));
        assert_eq!(
            text.lines().nth(1),
            Some("0e0,3e-2,2e-1,3.333333333333333e-1,-2e-17,1.2345678912345679e8")
        );
        assert_eq!(text.lines().count(), 3);
        let (q, u) = read_probes_csv(&p).unwrap();
        assert_eq!(q, points);
        assert_eq!(u, disp);
        write_probes_csv(&p, &[], &[]).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "x,y,z,ux,uy,uz\n");
        assert_eq!(read_probes_csv(&p).unwrap().0.len(), 0);
    }

    #[test]
    fn mismatched_lengths_and_bad_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("probes.csv");
        assert!(write_probes_csv(&p, &[Point3::origin()], &[]).is_err());
        assert!(!p.exists());
        for (text, says) in [
            ("x,y,z\n", "header"),
            ("x,y,z,ux,uy,uz\n1,2,3,4,5\n", "line 2"),
            ("x,y,z,ux,uy,uz\n1,2,3,4,5,6\n1,2,3,4,5,a\n", "line 3"),
        ] {
            std::fs::write(&p, text).unwrap();
            let err = read_probes_csv(&p).unwrap_err().to_string();
            assert!(err.contains("probes.csv") && err.contains(says), "{err}");
            assert_eq!(err.lines().count(), 1, "{err}");
        }
    }
}

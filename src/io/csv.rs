//! Probe results: `probes.csv` with the header `x,y,z,ux,uy,uz`, one row per
//! probe (reference position in, displacement out), numbers in Rust's
//! shortest round-trip form (`{:e}`), so reading them back is exact.

use super::{read_bytes, write_atomic, IoError};
use nalgebra::{Point3, Vector3};
use std::io::Write;
use std::path::Path;

/// The header line of a probe file.
pub const PROBES_HEADER: &str = "x,y,z,ux,uy,uz";

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
    write_atomic(path, |w| {
        writeln!(w, "{PROBES_HEADER}")?;
        for (p, u) in points.iter().zip(displacements) {
            writeln!(
                w,
                "{:e},{:e},{:e},{:e},{:e},{:e}",
                p.x, p.y, p.z, u.x, u.y, u.z
            )?;
        }
        Ok(())
    })
}

/// Reads a probe file written by [`write_probes_csv`] (or any CSV with that
/// header and six numbers per row): the points and displacements.
#[allow(clippy::type_complexity)]
pub fn read_probes_csv(path: &Path) -> Result<(Vec<Point3<f64>>, Vec<Vector3<f64>>), IoError> {
    let bytes = read_bytes(path)?;
    let text =
        std::str::from_utf8(&bytes).map_err(|_| IoError::invalid(path, "is not UTF-8 text"))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let header: String = lines
        .next()
        .map(|(_, l)| l.chars().filter(|c| !c.is_whitespace()).collect())
        .unwrap_or_default();
    if header != PROBES_HEADER {
        return Err(IoError::invalid(
            path,
            format!("header is `{header}`, expected `{PROBES_HEADER}`"),
        ));
    }
    let (mut points, mut displacements) = (Vec::new(), Vec::new());
    for (i, line) in lines {
        let v: Vec<f64> = line
            .split(',')
            .map(|s| s.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .ok()
            .filter(|v: &Vec<f64>| v.len() == 6)
            .ok_or_else(|| IoError::invalid(path, format!("line {}: expected 6 numbers", i + 1)))?;
        points.push(Point3::new(v[0], v[1], v[2]));
        displacements.push(Vector3::new(v[3], v[4], v[5]));
    }
    Ok((points, displacements))
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
        assert_eq!(text.lines().count(), 3);
        let (q, u) = read_probes_csv(&p).unwrap();
        assert_eq!(q, points);
        assert_eq!(u, disp);
    }

    #[test]
    fn mismatched_lengths_and_bad_files_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("probes.csv");
        assert!(write_probes_csv(&p, &[Point3::origin()], &[]).is_err());
        assert!(!p.exists());
        for text in [
            "x,y,z\n",
            "x,y,z,ux,uy,uz\n1,2,3,4,5\n",
            "x,y,z,ux,uy,uz\n1,2,3,4,5,a\n",
        ] {
            std::fs::write(&p, text).unwrap();
            let err = read_probes_csv(&p).unwrap_err().to_string();
            assert!(err.contains("probes.csv"), "{err}");
        }
    }
}

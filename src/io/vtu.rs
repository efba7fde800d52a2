//! Reading VTU files with ASCII data arrays (as meshio writes them with
//! `binary=False`, and as [`crate::output`] writes them), through quick-xml.

use super::IoError;
use quick_xml::events::Event;
use quick_xml::Reader;
use std::collections::HashMap;
use std::path::Path;

/// The arrays of one VTU piece.
#[derive(Debug, Clone, Default)]
pub struct VtuData {
    /// Point coordinates, 3 per point.
    pub points: Vec<f64>,
    pub connectivity: Vec<usize>,
    pub offsets: Vec<usize>,
    pub types: Vec<u8>,
    /// Point data arrays by name: (components, values).
    pub point_data: HashMap<String, (usize, Vec<f64>)>,
}

impl VtuData {
    pub fn n_points(&self) -> usize {
        self.points.len() / 3
    }

    /// Node ids of cell `c`.
    pub fn cell(&self, c: usize) -> &[usize] {
        let start = if c == 0 { 0 } else { self.offsets[c - 1] };
        &self.connectivity[start..self.offsets[c]]
    }
}

pub fn read_vtu(path: &Path) -> Result<VtuData, IoError> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::new(path, e.to_string()))?;
    let mut reader = Reader::from_str(&text);
    let mut data = VtuData::default();
    // (section, name, components) of the DataArray being read.
    let mut section = String::new();
    let mut current: Option<(String, String, usize)> = None;
    let mut body = String::new();
    loop {
        match reader.read_event() {
            Err(e) => {
                return Err(IoError::new(
                    path,
                    format!("XML error at byte {}: {e}", reader.buffer_position()),
                ))
            }
            Ok(Event::Eof) => break,
            Ok(Event::Start(e)) => {
                let tag = String::from_utf8_lossy(e.name().as_ref()).to_string();
                if tag == "DataArray" {
                    let mut name = String::new();
                    let mut comps = 1usize;
                    let mut format = String::from("ascii");
                    for a in e.attributes().flatten() {
                        let v = String::from_utf8_lossy(&a.value).to_string();
                        match a.key.as_ref() {
                            b"Name" => name = v,
                            b"NumberOfComponents" => comps = v.parse().unwrap_or(1),
                            b"format" => format = v,
                            _ => {}
                        }
                    }
                    if format != "ascii" {
                        return Err(IoError::new(path, format!("DataArray `{name}` is in `{format}` format; only ascii is read (write with meshio binary=False)")));
                    }
                    current = Some((section.clone(), name, comps));
                    body.clear();
                } else {
                    section = tag;
                }
            }
            Ok(Event::Text(t)) => {
                if current.is_some() {
                    body.push_str(&String::from_utf8_lossy(t.as_ref()));
                }
            }
            Ok(Event::End(e)) => {
                if e.name().as_ref() == b"DataArray" {
                    let Some((sec, name, comps)) = current.take() else {
                        continue;
                    };
                    let bad =
                        |what: &str| IoError::new(path, format!("DataArray `{name}`: {what}"));
                    let floats = || -> Result<Vec<f64>, IoError> {
                        body.split_ascii_whitespace()
                            .map(|w| {
                                w.parse::<f64>()
                                    .map_err(|_| bad(&format!("not a number: {w}")))
                            })
                            .collect()
                    };
                    let ints = || -> Result<Vec<usize>, IoError> {
                        body.split_ascii_whitespace()
                            .map(|w| {
                                w.parse::<usize>()
                                    .map_err(|_| bad(&format!("not an index: {w}")))
                            })
                            .collect()
                    };
                    match (sec.as_str(), name.as_str()) {
                        ("Points", _) => data.points = floats()?,
                        ("Cells", "connectivity") => data.connectivity = ints()?,
                        ("Cells", "offsets") => data.offsets = ints()?,
                        ("Cells", "types") => {
                            data.types = ints()?.into_iter().map(|t| t as u8).collect()
                        }
                        ("PointData", _) => {
                            let values = floats()?;
                            data.point_data.insert(name.clone(), (comps, values));
                        }
                        _ => {}
                    }
                }
            }
            Ok(_) => {}
        }
    }
    if data.points.is_empty() || data.offsets.is_empty() {
        return Err(IoError::new(path, "no points or no cells"));
    }
    if data.offsets.last() != Some(&data.connectivity.len())
        || data.connectivity.iter().any(|&i| i >= data.n_points())
    {
        return Err(IoError::new(path, "inconsistent cell connectivity"));
    }
    for (name, (comps, v)) in &data.point_data {
        if v.len() != comps * data.n_points() {
            return Err(IoError::new(
                path,
                format!(
                    "point data `{name}` has {} values for {} points",
                    v.len(),
                    data.n_points()
                ),
            ));
        }
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_a_meshio_ascii_quadratic_tet() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/meshio_tet10_ascii.vtu");
        let d = read_vtu(&p).unwrap();
        assert_eq!(d.n_points(), 10);
        assert_eq!(d.cell(0), &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]);
        assert_eq!(d.types, vec![24]);
        let (comps, u) = &d.point_data["u"];
        assert_eq!(*comps, 3);
        for (a, b) in u.iter().zip(&d.points) {
            assert!((a - 2.0 * b).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_broken_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.vtu");
        std::fs::write(&p, "<VTKFile><UnstructuredGrid><Piece><Points><DataArray format=\"binary\">AAAA</DataArray>").unwrap();
        assert!(read_vtu(&p).unwrap_err().to_string().contains("x.vtu"));
        std::fs::write(&p, "not xml at all <<<").unwrap();
        assert!(read_vtu(&p).is_err());
    }
}

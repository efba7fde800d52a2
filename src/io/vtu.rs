//! VTK unstructured grids (`.vtu`) and time-series collections (`.pvd`).
//!
//! Written: one piece, inline data arrays, either base64 binary (a UInt64 byte
//! count then the little-endian values, encoded as one stream — what VTK and
//! meshio write uncompressed) or ASCII at full precision. Points and fields
//! are Float64, connectivity and offsets Int64, types UInt8.
//!
//! Read: what we write, and what meshio 5 writes with `binary=False` (ASCII)
//! or with `compression=None` (uncompressed binary, UInt32 or UInt64 headers,
//! either byte order). Compressed and appended data are refused with an error
//! saying so.

use super::{read_bytes, write_atomic, IoError};
use crate::mesh::{ElementKind, TetMesh};
use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig, STANDARD};
use base64::engine::DecodePaddingMode;
use base64::Engine as _;
use nalgebra::Point3;
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// VTK cell type of a linear triangle.
pub const VTK_TRIANGLE: u8 = 5;
/// VTK cell type of a linear tetrahedron.
pub const VTK_TETRA: u8 = 10;
/// VTK cell type of a 6-node triangle.
pub const VTK_QUADRATIC_TRIANGLE: u8 = 22;
/// VTK cell type of a 10-node tetrahedron (our Tet10 order).
pub const VTK_QUADRATIC_TETRA: u8 = 24;

/// One piece of an unstructured grid, laid out as in the file.
///
/// Fields are keyed by name, each `(components, values)` with
/// `values.len() == components × count` (interleaved: x0 y0 z0 x1 …).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VtuData {
    /// Point coordinates, 3 per point.
    pub points: Vec<f64>,
    /// Node indices of all cells, concatenated.
    pub connectivity: Vec<usize>,
    /// End of each cell in `connectivity` (VTK offsets: the first cell is
    /// `connectivity[0..offsets[0]]`).
    pub offsets: Vec<usize>,
    /// VTK cell type of each cell ([`VTK_TETRA`], [`VTK_QUADRATIC_TETRA`], …).
    pub types: Vec<u8>,
    pub point_data: BTreeMap<String, (usize, Vec<f64>)>,
    pub cell_data: BTreeMap<String, (usize, Vec<f64>)>,
}

impl VtuData {
    /// The nodes and elements of `mesh` (tetra or quadratic tetra), no fields.
    pub fn from_mesh(mesh: &TetMesh) -> VtuData {
        let n = mesh.kind.nodes();
        let vtk_type = match mesh.kind {
            ElementKind::Tet4 => VTK_TETRA,
            ElementKind::Tet10 => VTK_QUADRATIC_TETRA,
        };
        VtuData {
            points: mesh.nodes.iter().flat_map(|p| [p.x, p.y, p.z]).collect(),
            connectivity: mesh.cells.clone(),
            offsets: (1..=mesh.n_elements()).map(|e| e * n).collect(),
            types: vec![vtk_type; mesh.n_elements()],
            ..VtuData::default()
        }
    }

    pub fn n_points(&self) -> usize {
        self.points.len() / 3
    }

    pub fn n_cells(&self) -> usize {
        self.offsets.len()
    }

    /// Coordinates of point `i`.
    pub fn point(&self, i: usize) -> Point3<f64> {
        Point3::new(
            self.points[3 * i],
            self.points[3 * i + 1],
            self.points[3 * i + 2],
        )
    }

    /// Node ids of cell `c`.
    pub fn cell(&self, c: usize) -> &[usize] {
        let start = if c == 0 { 0 } else { self.offsets[c - 1] };
        &self.connectivity[start..self.offsets[c]]
    }

    /// Appends a cell of VTK type `vtk_type` with the nodes `nodes`.
    pub fn push_cell(&mut self, vtk_type: u8, nodes: &[usize]) {
        self.connectivity.extend_from_slice(nodes);
        self.offsets.push(self.connectivity.len());
        self.types.push(vtk_type);
    }

    /// Why the arrays do not describe a valid grid, if they do not.
    pub fn check(&self) -> Result<(), GridError> {
        if !self.points.len().is_multiple_of(3) {
            return Err(GridError::Coordinates(self.points.len()));
        }
        if self.types.len() != self.offsets.len() {
            return Err(GridError::CellTypes {
                types: self.types.len(),
                offsets: self.offsets.len(),
            });
        }
        if self.offsets.windows(2).any(|w| w[1] < w[0])
            || self.offsets.last().copied().unwrap_or(0) != self.connectivity.len()
        {
            return Err(GridError::Offsets(self.connectivity.len()));
        }
        let n = self.n_points();
        if let Some(&point) = self.connectivity.iter().find(|&&i| i >= n) {
            return Err(GridError::Point { point, points: n });
        }
        for (kind, fields, count) in [
            ("point", &self.point_data, n),
            ("cell", &self.cell_data, self.n_cells()),
        ] {
            for (name, (comps, values)) in fields {
                if *comps == 0 || values.len() != comps * count {
                    return Err(GridError::Field {
                        kind,
                        name: name.clone(),
                        values: values.len(),
                        comps: *comps,
                        count,
                    });
                }
            }
        }
        Ok(())
    }
}

/// Why a [`VtuData`]'s arrays do not describe a valid grid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GridError {
    #[error("{0} point coordinates is not a multiple of 3")]
    Coordinates(usize),
    #[error("{types} cell types for {offsets} cell offsets")]
    CellTypes { types: usize, offsets: usize },
    #[error("cell offsets do not end each cell in the connectivity ({0} entries)")]
    Offsets(usize),
    #[error("a cell uses point {point}, but there are {points} points")]
    Point { point: usize, points: usize },
    #[error("{kind} data `{name}` has {values} values, expected {comps} × {count}")]
    Field {
        kind: &'static str,
        name: String,
        values: usize,
        comps: usize,
        count: usize,
    },
}

#[derive(Clone, Copy, PartialEq)]
enum Encoding {
    Binary,
    Ascii,
}

/// Writes `data` as a VTU with inline base64 binary arrays (compact and fast;
/// read by ParaView, meshio and [`read_vtu`]), atomically.
pub fn write_vtu(path: &Path, data: &VtuData) -> Result<(), IoError> {
    write_vtu_encoded(path, data, Encoding::Binary)
}

/// Writes `data` as a VTU with ASCII arrays at full precision (shortest
/// round-trip decimal form), atomically. For small files meant for reading.
pub fn write_vtu_ascii(path: &Path, data: &VtuData) -> Result<(), IoError> {
    write_vtu_encoded(path, data, Encoding::Ascii)
}

fn write_vtu_encoded(path: &Path, data: &VtuData, enc: Encoding) -> Result<(), IoError> {
    data.check().map_err(|e| IoError::grid(path, e))?;
    if let Some(name) = data
        .point_data
        .keys()
        .chain(data.cell_data.keys())
        .find(|n| n.is_empty() || n.contains(['"', '<', '>', '&']))
    {
        return Err(IoError::invalid(
            path,
            format!("field name `{name}` is empty or holds one of \" < > &"),
        ));
    }
    write_atomic(path, |w| {
        w.write_all(
            b"<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" \
              byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>\n",
        )?;
        writeln!(
            w,
            "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
            data.n_points(),
            data.n_cells()
        )?;
        for (tag, fields) in [
            ("PointData", &data.point_data),
            ("CellData", &data.cell_data),
        ] {
            writeln!(w, "<{tag}>")?;
            for (name, (comps, values)) in fields {
                array_start(w, "Float64", name, *comps, enc)?;
                write_f64(w, values, enc)?;
                w.write_all(b"\n</DataArray>\n")?;
            }
            writeln!(w, "</{tag}>")?;
        }
        w.write_all(b"<Points>\n")?;
        array_start(w, "Float64", "Points", 3, enc)?;
        write_f64(w, &data.points, enc)?;
        w.write_all(b"\n</DataArray>\n</Points>\n<Cells>\n")?;
        array_start(w, "Int64", "connectivity", 1, enc)?;
        write_i64(w, &data.connectivity, enc)?;
        w.write_all(b"\n</DataArray>\n")?;
        array_start(w, "Int64", "offsets", 1, enc)?;
        write_i64(w, &data.offsets, enc)?;
        w.write_all(b"\n</DataArray>\n")?;
        array_start(w, "UInt8", "types", 1, enc)?;
        write_u8(w, &data.types, enc)?;
        w.write_all(b"\n</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
    })
}

fn array_start(
    w: &mut impl Write,
    ty: &str,
    name: &str,
    comps: usize,
    enc: Encoding,
) -> std::io::Result<()> {
    let format = match enc {
        Encoding::Binary => "binary",
        Encoding::Ascii => "ascii",
    };
    // One component is VTK's default; meshio then reads a flat array, as it writes.
    if comps == 1 {
        writeln!(
            w,
            "<DataArray type=\"{ty}\" Name=\"{name}\" format=\"{format}\">"
        )
    } else {
        writeln!(
            w,
            "<DataArray type=\"{ty}\" Name=\"{name}\" NumberOfComponents=\"{comps}\" format=\"{format}\">"
        )
    }
}

/// Base64 of the UInt64 byte count followed by the values, one stream.
fn write_base64<const K: usize>(
    w: &mut impl Write,
    n: usize,
    mut value_bytes: impl FnMut(usize) -> [u8; K],
) -> std::io::Result<()> {
    let mut enc = base64::write::EncoderWriter::new(w, &STANDARD);
    enc.write_all(&((n * K) as u64).to_le_bytes())?;
    let mut buf = Vec::with_capacity(3 * 4096);
    for i in 0..n {
        buf.extend_from_slice(&value_bytes(i));
        if buf.len() >= 3 * 4096 - K {
            enc.write_all(&buf)?;
            buf.clear();
        }
    }
    enc.write_all(&buf)?;
    enc.finish()?;
    Ok(())
}

fn write_f64(w: &mut impl Write, values: &[f64], enc: Encoding) -> std::io::Result<()> {
    match enc {
        Encoding::Binary => write_base64(w, values.len(), |i| values[i].to_le_bytes()),
        Encoding::Ascii => {
            for (i, v) in values.iter().enumerate() {
                let sep = if i % 3 == 2 { '\n' } else { ' ' };
                write!(w, "{v:e}{sep}")?;
            }
            Ok(())
        }
    }
}

fn write_i64(w: &mut impl Write, values: &[usize], enc: Encoding) -> std::io::Result<()> {
    match enc {
        Encoding::Binary => write_base64(w, values.len(), |i| (values[i] as i64).to_le_bytes()),
        Encoding::Ascii => write_ascii_ints(w, values.iter().copied()),
    }
}

fn write_u8(w: &mut impl Write, values: &[u8], enc: Encoding) -> std::io::Result<()> {
    match enc {
        Encoding::Binary => write_base64(w, values.len(), |i| [values[i]]),
        Encoding::Ascii => write_ascii_ints(w, values.iter().map(|&t| t as usize)),
    }
}

fn write_ascii_ints(
    w: &mut impl Write,
    values: impl Iterator<Item = usize>,
) -> std::io::Result<()> {
    for (i, v) in values.enumerate() {
        let sep = if i % 16 == 15 { '\n' } else { ' ' };
        write!(w, "{v}{sep}")?;
    }
    Ok(())
}

/// Scalar type of a data array.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Scalar {
    F32,
    F64,
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    I64,
    U64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "Float32" => Scalar::F32,
            "Float64" => Scalar::F64,
            "Int8" => Scalar::I8,
            "UInt8" => Scalar::U8,
            "Int16" => Scalar::I16,
            "UInt16" => Scalar::U16,
            "Int32" => Scalar::I32,
            "UInt32" => Scalar::U32,
            "Int64" => Scalar::I64,
            "UInt64" => Scalar::U64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::F32 | Scalar::I32 | Scalar::U32 => 4,
            Scalar::F64 | Scalar::I64 | Scalar::U64 => 8,
        }
    }

    fn is_float(self) -> bool {
        matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// File-wide settings from the `VTKFile` element.
struct FileFormat {
    big_endian: bool,
    /// Bytes of the binary block header (UInt32: 4, UInt64: 8).
    header_bytes: usize,
}

/// One `DataArray` as found in the file, not yet decoded.
struct RawArray {
    section: String,
    name: String,
    ty: Scalar,
    comps: usize,
    binary: bool,
    body: Vec<u8>,
}

impl RawArray {
    fn describe(&self) -> String {
        format!("{} DataArray `{}`", self.section, self.name)
    }

    /// The values, converted one by one: `float` for floating-point types,
    /// `int` (exact) for integer types.
    fn values<R>(
        &self,
        f: &FileFormat,
        float: impl Fn(f64) -> Option<R>,
        int: impl Fn(i128) -> Option<R>,
    ) -> Result<Vec<R>, String> {
        let bad = || format!("{}: a value out of range for its use", self.describe());
        if !self.binary {
            let text = std::str::from_utf8(&self.body)
                .map_err(|_| format!("{}: not ASCII text", self.describe()))?;
            return text
                .split_ascii_whitespace()
                .map(|w| {
                    let v = if self.ty.is_float() {
                        w.parse::<f64>().ok().map(&float)
                    } else {
                        w.parse::<i128>().ok().map(&int)
                    };
                    match v {
                        None => Err(format!("{}: `{w}` is not a {:?}", self.describe(), self.ty)),
                        Some(None) => Err(bad()),
                        Some(Some(x)) => Ok(x),
                    }
                })
                .collect();
        }
        let (bytes, start) =
            decode_base64_block(&self.body, f).map_err(|m| format!("{}: {m}", self.describe()))?;
        let data = &bytes[start..];
        if !data.len().is_multiple_of(self.ty.size()) {
            return Err(format!(
                "{}: {} bytes is not a whole number of {:?} values",
                self.describe(),
                data.len(),
                self.ty
            ));
        }
        let be = f.big_endian;
        macro_rules! convert {
            ($t:ty, $to:expr) => {{
                const K: usize = std::mem::size_of::<$t>();
                let mut out = Vec::with_capacity(data.len() / K);
                for c in data.chunks_exact(K) {
                    let mut a = [0u8; K];
                    a.copy_from_slice(c);
                    let x = if be {
                        <$t>::from_be_bytes(a)
                    } else {
                        <$t>::from_le_bytes(a)
                    };
                    out.push($to(x).ok_or_else(bad)?);
                }
                Ok(out)
            }};
        }
        match self.ty {
            Scalar::F64 => convert!(f64, &float),
            Scalar::F32 => convert!(f32, |x: f32| float(x as f64)),
            Scalar::I8 => convert!(i8, |x: i8| int(x as i128)),
            Scalar::U8 => convert!(u8, |x: u8| int(x as i128)),
            Scalar::I16 => convert!(i16, |x: i16| int(x as i128)),
            Scalar::U16 => convert!(u16, |x: u16| int(x as i128)),
            Scalar::I32 => convert!(i32, |x: i32| int(x as i128)),
            Scalar::U32 => convert!(u32, |x: u32| int(x as i128)),
            Scalar::I64 => convert!(i64, |x: i64| int(x as i128)),
            Scalar::U64 => convert!(u64, |x: u64| int(x as i128)),
        }
    }

    fn floats(&self, f: &FileFormat) -> Result<Vec<f64>, String> {
        self.values(f, Some, |i| Some(i as f64))
    }

    fn indices(&self, f: &FileFormat) -> Result<Vec<usize>, String> {
        if self.ty.is_float() {
            return Err(format!(
                "{}: has type {:?}, expected an integer type",
                self.describe(),
                self.ty
            ));
        }
        self.values(f, |_| None, |i| usize::try_from(i).ok())
            .map_err(|m| m.replace("a value out of range for its use", "a negative index"))
    }
}

/// Decodes an uncompressed inline binary block: a byte-count header, then
/// the data. VTK and meshio encode both as one base64 stream; some writers
/// encode the header on its own (padded), so both are accepted.
/// Returns the decoded bytes and where the data starts in them.
fn decode_base64_block(body: &[u8], f: &FileFormat) -> Result<(Vec<u8>, usize), String> {
    let lenient = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new()
            .with_decode_padding_mode(DecodePaddingMode::Indifferent)
            .with_decode_allow_trailing_bits(true),
    );
    let trimmed = body.trim_ascii();
    let owned: Vec<u8>;
    let clean: &[u8] = if trimmed.iter().any(u8::is_ascii_whitespace) {
        owned = trimmed
            .iter()
            .copied()
            .filter(|c| !c.is_ascii_whitespace())
            .collect();
        &owned
    } else {
        trimmed
    };
    let hb = f.header_bytes;
    let header_len = |h: &[u8]| -> usize {
        let v = match (hb, f.big_endian) {
            (4, false) => u32::from_le_bytes([h[0], h[1], h[2], h[3]]) as u64,
            (4, true) => u32::from_be_bytes([h[0], h[1], h[2], h[3]]) as u64,
            (_, false) => u64::from_le_bytes([h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7]]),
            (_, true) => u64::from_be_bytes([h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7]]),
        };
        usize::try_from(v).unwrap_or(usize::MAX)
    };
    if let Ok(all) = lenient.decode(clean) {
        if all.len() >= hb && all.len() - hb == header_len(&all[..hb]) {
            return Ok((all, hb));
        }
    }
    let header_chars = hb.div_ceil(3) * 4;
    if clean.len() >= header_chars {
        if let (Ok(h), Ok(data)) = (
            lenient.decode(&clean[..header_chars]),
            lenient.decode(&clean[header_chars..]),
        ) {
            if h.len() == hb && header_len(&h) == data.len() {
                return Ok((data, 0));
            }
        }
    }
    Err(format!(
        "not an uncompressed base64 block with a {}-byte header",
        hb
    ))
}

fn attributes(path: &Path, e: &BytesStart) -> Result<BTreeMap<String, String>, IoError> {
    let mut map = BTreeMap::new();
    for a in e.attributes() {
        let a = a.map_err(|err| IoError::invalid(path, format!("XML attribute: {err}")))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a
            .unescape_value()
            .map_err(|err| IoError::invalid(path, format!("XML attribute `{key}`: {err}")))?;
        map.insert(key, value.into_owned());
    }
    Ok(map)
}

fn count_attribute(
    path: &Path,
    attrs: &BTreeMap<String, String>,
    key: &str,
) -> Result<Option<usize>, IoError> {
    attrs
        .get(key)
        .map(|v| {
            v.trim()
                .parse()
                .map_err(|_| IoError::invalid(path, format!("{key}=\"{v}\" is not a count")))
        })
        .transpose()
}

/// Reads a VTU file (one piece, inline ASCII or uncompressed base64 arrays).
pub fn read_vtu(path: &Path) -> Result<VtuData, IoError> {
    let bytes = read_bytes(path)?;
    let mut reader = Reader::from_reader(bytes.as_slice());
    let mut format = FileFormat {
        big_endian: false,
        header_bytes: 4,
    };
    let mut seen_vtkfile = false;
    let mut pieces = 0;
    let mut declared: (Option<usize>, Option<usize>) = (None, None);
    let mut section = String::new();
    let mut current: Option<RawArray> = None;
    let mut arrays: Vec<RawArray> = Vec::new();
    let mut depth = 0usize;
    loop {
        let event = reader.read_event().map_err(|e| {
            IoError::invalid(
                path,
                format!("XML error near byte {}: {e}", reader.buffer_position()),
            )
        })?;
        let (start, empty) = match &event {
            Event::Start(e) => (Some(e), false),
            Event::Empty(e) => (Some(e), true),
            _ => (None, false),
        };
        if let Some(e) = start {
            if !empty {
                depth += 1;
            }
            let tag = e.name();
            let attrs = attributes(path, e)?;
            match tag.as_ref() {
                b"VTKFile" => {
                    seen_vtkfile = true;
                    let ty = attrs.get("type").map_or("", String::as_str);
                    if ty != "UnstructuredGrid" {
                        return Err(IoError::unsupported(
                            path,
                            format!("VTKFile type `{ty}` (only UnstructuredGrid)"),
                        ));
                    }
                    format.big_endian =
                        attrs.get("byte_order").map(String::as_str) == Some("BigEndian");
                    format.header_bytes = match attrs.get("header_type").map(String::as_str) {
                        None | Some("UInt32") => 4,
                        Some("UInt64") => 8,
                        Some(other) => {
                            return Err(IoError::unsupported(
                                path,
                                format!("header_type `{other}`"),
                            ))
                        }
                    };
                    if let Some(c) = attrs.get("compressor") {
                        return Err(IoError::unsupported(
                            path,
                            format!(
                                "compressed data ({c}); write it with meshio's \
                                 compression=None or binary=False"
                            ),
                        ));
                    }
                }
                b"Piece" => {
                    pieces += 1;
                    if pieces > 1 {
                        return Err(IoError::unsupported(path, "more than one Piece"));
                    }
                    declared = (
                        count_attribute(path, &attrs, "NumberOfPoints")?,
                        count_attribute(path, &attrs, "NumberOfCells")?,
                    );
                }
                b"AppendedData" => {
                    return Err(IoError::unsupported(
                        path,
                        "appended data (only inline ascii or binary arrays)",
                    ))
                }
                b"DataArray" => {
                    if current.is_some() {
                        return Err(IoError::invalid(path, "DataArray inside a DataArray"));
                    }
                    let name = attrs.get("Name").cloned().unwrap_or_default();
                    let ty_name = attrs.get("type").map_or("", String::as_str);
                    let ty = Scalar::parse(ty_name).ok_or_else(|| {
                        IoError::unsupported(
                            path,
                            format!("DataArray `{name}` has type `{ty_name}`"),
                        )
                    })?;
                    let comps = count_attribute(path, &attrs, "NumberOfComponents")?.unwrap_or(1);
                    let binary = match attrs.get("format").map_or("ascii", String::as_str) {
                        "ascii" => false,
                        "binary" => true,
                        other => {
                            return Err(IoError::unsupported(
                                path,
                                format!(
                                    "DataArray `{name}` has format `{other}` \
                                     (only inline ascii or binary)"
                                ),
                            ))
                        }
                    };
                    let array = RawArray {
                        section: section.clone(),
                        name,
                        ty,
                        comps,
                        binary,
                        body: Vec::new(),
                    };
                    if empty {
                        arrays.push(array);
                    } else {
                        current = Some(array);
                    }
                }
                other if !empty => section = String::from_utf8_lossy(other).into_owned(),
                _ => {}
            }
            continue;
        }
        match event {
            Event::Text(t) => {
                if let Some(a) = current.as_mut() {
                    a.body.extend_from_slice(t.as_ref());
                }
            }
            Event::CData(t) => {
                if let Some(a) = current.as_mut() {
                    a.body.extend_from_slice(t.as_ref());
                }
            }
            Event::End(e) => {
                depth = depth.saturating_sub(1);
                if e.name().as_ref() == b"DataArray" {
                    if let Some(a) = current.take() {
                        arrays.push(a);
                    }
                } else {
                    section.clear();
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    if depth != 0 {
        return Err(IoError::invalid(
            path,
            "ends inside an element (truncated?)",
        ));
    }
    if !seen_vtkfile || pieces == 0 {
        return Err(IoError::invalid(
            path,
            "not a VTU file (no VTKFile or no Piece)",
        ));
    }

    let mut data = VtuData::default();
    let err = |m: String| IoError::invalid(path, m);
    let mut have = (false, false);
    for a in &arrays {
        match (a.section.as_str(), a.name.as_str()) {
            ("Points", _) => {
                if a.comps != 3 {
                    return Err(err(format!("Points have {} components, not 3", a.comps)));
                }
                data.points = a.floats(&format).map_err(err)?;
                have.0 = true;
            }
            ("Cells", "connectivity") => data.connectivity = a.indices(&format).map_err(err)?,
            ("Cells", "offsets") => {
                data.offsets = a.indices(&format).map_err(err)?;
                have.1 = true;
            }
            ("Cells", "types") => {
                data.types = a
                    .indices(&format)
                    .map_err(err)?
                    .into_iter()
                    .map(|t| u8::try_from(t).map_err(|_| err(format!("cell type {t}"))))
                    .collect::<Result<_, _>>()?
            }
            ("PointData", _) => {
                data.point_data
                    .insert(a.name.clone(), (a.comps, a.floats(&format).map_err(err)?));
            }
            ("CellData", _) => {
                data.cell_data
                    .insert(a.name.clone(), (a.comps, a.floats(&format).map_err(err)?));
            }
            _ => {}
        }
    }
    let (n_points, n_cells) = declared;
    if !have.0 && n_points.unwrap_or(0) > 0 {
        return Err(err("no Points array".into()));
    }
    if !have.1 && n_cells.unwrap_or(0) > 0 {
        return Err(err("no Cells offsets array".into()));
    }
    if n_points.is_some_and(|n| n != data.n_points()) || !data.points.len().is_multiple_of(3) {
        return Err(err(format!(
            "NumberOfPoints is {n_points:?} but there are {} coordinates",
            data.points.len()
        )));
    }
    if n_cells.is_some_and(|n| n != data.n_cells()) {
        return Err(err(format!(
            "NumberOfCells is {n_cells:?} but there are {} offsets",
            data.n_cells()
        )));
    }
    data.check().map_err(|e| IoError::grid(path, e))?;
    Ok(data)
}

fn escape_attribute(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('"', "&quot;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// Writes a ParaView collection (`.pvd`) listing `(time, file)` frames, the
/// files relative to the `.pvd`'s folder; atomically.
pub fn write_pvd<P: AsRef<Path>>(path: &Path, frames: &[(f64, P)]) -> Result<(), IoError> {
    let mut entries = Vec::with_capacity(frames.len());
    for (t, file) in frames {
        let file = file.as_ref();
        if !t.is_finite() {
            return Err(IoError::invalid(
                path,
                format!("frame {} has time {t}", file.display()),
            ));
        }
        let name = file.to_str().ok_or_else(|| {
            IoError::invalid(path, format!("frame path {} is not UTF-8", file.display()))
        })?;
        entries.push((*t, escape_attribute(name)));
    }
    write_atomic(path, |w| {
        w.write_all(
            b"<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" \
              byte_order=\"LittleEndian\">\n<Collection>\n",
        )?;
        for (t, name) in &entries {
            writeln!(
                w,
                "<DataSet timestep=\"{t:e}\" group=\"\" part=\"0\" file=\"{name}\"/>"
            )?;
        }
        w.write_all(b"</Collection>\n</VTKFile>\n")
    })
}

/// Reads a `.pvd` collection: `(time, file)` per `DataSet`, in file order, the
/// files as written (relative to the `.pvd`'s folder).
pub fn read_pvd(path: &Path) -> Result<Vec<(f64, PathBuf)>, IoError> {
    let bytes = read_bytes(path)?;
    let mut reader = Reader::from_reader(bytes.as_slice());
    let mut frames = Vec::new();
    let mut collection = false;
    loop {
        match reader.read_event() {
            Err(e) => {
                return Err(IoError::invalid(
                    path,
                    format!("XML error near byte {}: {e}", reader.buffer_position()),
                ))
            }
            Ok(Event::Eof) => break,
            Ok(Event::Start(e)) | Ok(Event::Empty(e)) => match e.name().as_ref() {
                b"VTKFile" => {
                    let attrs = attributes(path, &e)?;
                    collection = attrs.get("type").map(String::as_str) == Some("Collection");
                }
                b"DataSet" => {
                    let attrs = attributes(path, &e)?;
                    let t = attrs.get("timestep").map_or("0", String::as_str);
                    let t: f64 = t.trim().parse().map_err(|_| {
                        IoError::invalid(path, format!("DataSet timestep `{t}` is not a number"))
                    })?;
                    let file = attrs
                        .get("file")
                        .ok_or_else(|| IoError::invalid(path, "DataSet without a file"))?;
                    frames.push((t, PathBuf::from(file)));
                }
                _ => {}
            },
            Ok(_) => {}
        }
    }
    if !collection {
        return Err(IoError::invalid(path, "not a VTKFile of type Collection"));
    }
    Ok(frames)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::box_mesh;

    fn fixture(name: &str) -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures")
            .join(name)
    }

    /// A Tet10 box with a triangle, point data `u` and `T`, cell data `cut`,
    /// values that need all 17 digits.
    fn sample() -> VtuData {
        let mesh = box_mesh(Point3::origin(), Point3::new(0.3, 0.1, 0.7), [2, 1, 3]).to_tet10();
        let mut d = VtuData::from_mesh(&mesh);
        d.push_cell(VTK_TRIANGLE, &[0, 1, 2]);
        let u: Vec<f64> = d
            .points
            .iter()
            .enumerate()
            .map(|(i, x)| (x + 0.1).sin() / 3.0 - 1e-300 * i as f64)
            .collect();
        let t: Vec<f64> = (0..d.n_points()).map(|i| (i as f64).sqrt()).collect();
        let cut: Vec<f64> = (0..d.n_cells()).map(|c| (c % 4) as f64).collect();
        d.point_data.insert("u".into(), (3, u));
        d.point_data.insert("T".into(), (1, t));
        d.cell_data.insert("cut".into(), (1, cut));
        d
    }

    #[test]
    fn binary_and_ascii_round_trip_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let d = sample();
        for (name, write) in [
            (
                "b.vtu",
                write_vtu as fn(&Path, &VtuData) -> Result<(), IoError>,
            ),
            ("a.vtu", write_vtu_ascii),
        ] {
            let p = dir.path().join(name);
            write(&p, &d).unwrap();
            let back = read_vtu(&p).unwrap();
            assert_eq!(back, d, "{name}");
        }
    }

    #[test]
    fn empty_grid_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("e.vtu");
        write_vtu(&p, &VtuData::default()).unwrap();
        assert_eq!(read_vtu(&p).unwrap(), VtuData::default());
    }

    #[test]
    fn inconsistent_data_is_not_written() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.vtu");
        let mut d = sample();
        d.connectivity[3] = d.n_points();
        let err = write_vtu(&p, &d).unwrap_err().to_string();
        assert!(err.contains("x.vtu") && err.contains("point"), "{err}");
        let mut d = sample();
        d.point_data.get_mut("u").unwrap().1.pop();
        assert!(write_vtu(&p, &d).is_err());
        let mut d = sample();
        d.cell_data
            .insert("bad\"name".into(), (1, vec![0.0; d.n_cells()]));
        assert!(write_vtu(&p, &d).is_err());
        assert!(!p.exists());
    }

    #[test]
    fn reads_a_meshio_ascii_quadratic_tet() {
        let d = read_vtu(&fixture("meshio_tet10_ascii.vtu")).unwrap();
        assert_eq!(d.n_points(), 10);
        assert_eq!(d.cell(0), &[0, 1, 2, 3, 4, 5, 6, 7, 8, 9]);
        assert_eq!(d.types, vec![VTK_QUADRATIC_TETRA]);
        let (comps, u) = &d.point_data["u"];
        assert_eq!(*comps, 3);
        for (a, b) in u.iter().zip(&d.points) {
            assert!((a - 2.0 * b).abs() < 1e-12);
        }
    }

    #[test]
    fn reads_a_meshio_uncompressed_binary_file() {
        // meshio 5.0 `write(..., binary=True, compression=None)`: UInt32 headers,
        // Int64 connectivity, Float64 points, point data `u` = 2 x, cell data `id`.
        let d = read_vtu(&fixture("meshio_tet10_binary.vtu")).unwrap();
        let ascii = read_vtu(&fixture("meshio_tet10_ascii.vtu")).unwrap();
        assert_eq!(d.points, ascii.points);
        assert_eq!(d.connectivity, ascii.connectivity);
        assert_eq!(d.types, ascii.types);
        assert_eq!(d.point_data["u"].1.len(), 30);
        for (a, b) in d.point_data["u"].1.iter().zip(&d.points) {
            assert_eq!(*a, 2.0 * b);
        }
        assert_eq!(d.cell_data["id"], (1, vec![7.0]));
    }

    #[test]
    fn header_encoded_apart_and_big_endian_are_read() {
        // Header base64-encoded on its own (padded), then the data.
        let values = [1.5f64, -2.25, 3.0];
        let data: Vec<u8> = values.iter().flat_map(|v| v.to_be_bytes()).collect();
        let body = format!(
            "{}{}",
            STANDARD.encode((data.len() as u32).to_be_bytes()),
            STANDARD.encode(&data)
        );
        let text = format!(
            "<VTKFile type=\"UnstructuredGrid\" byte_order=\"BigEndian\"><UnstructuredGrid>\
             <Piece NumberOfPoints=\"1\" NumberOfCells=\"0\"><Points>\
             <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">\n  {body}\n\
             </DataArray></Points><Cells/></Piece></UnstructuredGrid></VTKFile>"
        );
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("be.vtu");
        std::fs::write(&p, text).unwrap();
        assert_eq!(read_vtu(&p).unwrap().points, values);
    }

    #[test]
    fn refuses_compressed_appended_and_broken_files_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.vtu");
        let good = std::fs::read_to_string(fixture("meshio_tet10_ascii.vtu")).unwrap();
        let cases: Vec<(String, &str)> = vec![
            (
                good.replace(
                    "byte_order=\"LittleEndian\"",
                    "byte_order=\"LittleEndian\" compressor=\"vtkZLibDataCompressor\"",
                ),
                "compress",
            ),
            (
                good.replacen("format=\"ascii\"", "format=\"appended\" offset=\"0\"", 1),
                "appended",
            ),
            ("not xml at all <<<".into(), "x.vtu"),
            (String::new(), "not a VTU"),
            (
                good.replacen("NumberOfPoints=\"10\"", "NumberOfPoints=\"11\"", 1),
                "NumberOfPoints",
            ),
            (good.replace("UnstructuredGrid\"", "PolyData\""), "PolyData"),
            (good.replacen("5.00000000000e-01", "five", 1), "five"),
            (
                good.replacen("Name=\"types\"", "Name=\"typos\"", 1),
                "types",
            ),
            (
                good.replacen(
                    "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n1",
                    "<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n-1",
                    1,
                ),
                "negative",
            ),
            (
                "<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece><Points>\
                 <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"binary\">AAAA\
                 </DataArray></Points></Piece></UnstructuredGrid></VTKFile>"
                    .into(),
                "base64",
            ),
        ];
        for (text, what) in cases {
            std::fs::write(&p, &text).unwrap();
            let err = read_vtu(&p).unwrap_err().to_string();
            assert!(err.contains("x.vtu"), "{err}");
            assert!(err.contains(what), "expected `{what}` in: {err}");
        }
    }

    #[test]
    fn truncated_files_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.vtu");
        write_vtu(&p, &sample()).unwrap();
        let full = std::fs::read(&p).unwrap();
        for cut in (0..full.len()).step_by(97) {
            std::fs::write(&p, &full[..cut]).unwrap();
            assert!(read_vtu(&p).is_err());
        }
    }

    #[test]
    fn pvd_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("result.pvd");
        let frames = vec![
            (0.0, PathBuf::from("frames/result_00000.vtu")),
            (0.1 + 0.2, PathBuf::from("frames/a&b \"1\".vtu")),
        ];
        write_pvd(&p, &frames).unwrap();
        assert_eq!(read_pvd(&p).unwrap(), frames);
        assert!(write_pvd(&p, &[(f64::NAN, "x.vtu")]).is_err());
        assert_eq!(
            read_pvd(&p).unwrap(),
            frames,
            "a failed write keeps the old file"
        );
    }
}

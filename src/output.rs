//! Run outputs: `result.vtu` with the opened cut (seed figures 7b/8), a `.pvd`
//! series for dynamic runs, written whole or not at all.
//!
//! Uncut elements are written as they are; cut elements as their sub-tets,
//! each displaced by u + ψa of its side, so the crack opens in the picture.

use crate::cut::ElementCut;
use crate::mesh::ElementKind;
use crate::model::Model;
use crate::run::{RunError, RunResult};
use crate::scene::Scene;
use nalgebra::{Point3, Vector3};
use std::fmt::Write as _;
use std::path::Path;

/// Writes `text` to `path` through a temporary file and a rename.
pub fn write_atomic(path: &Path, text: &str) -> Result<(), RunError> {
    let tmp = path.with_extension(format!(
        "{}.tmp",
        path.extension().and_then(|e| e.to_str()).unwrap_or("")
    ));
    std::fs::write(&tmp, text).map_err(|e| RunError::Output(format!("{}: {e}", tmp.display())))?;
    std::fs::rename(&tmp, path).map_err(|e| RunError::Output(format!("{}: {e}", path.display())))
}

/// Points, cells and per-point displacement of the deformed-state picture.
struct Picture {
    points: Vec<Point3<f64>>,
    disp: Vec<Vector3<f64>>,
    /// (VTK type, connectivity)
    cells: Vec<(u8, Vec<usize>)>,
    /// Per cell: 0 uncut, 1 touched, 2 cut, 3 cut with the front inside (extended).
    cut_flag: Vec<u8>,
}

fn picture(model: &Model, d: &[f64]) -> Picture {
    let mesh = &model.mesh;
    let mut pic = Picture {
        points: mesh.nodes.clone(),
        disp: Vec::new(),
        cells: Vec::new(),
        cut_flag: Vec::new(),
    };
    pic.disp = (0..mesh.n_nodes())
        .map(|i| model.node_displacement(d, i, 0))
        .collect();
    let vtk_type = match mesh.kind {
        ElementKind::Tet4 => 10,
        ElementKind::Tet10 => 24,
    };
    for e in 0..mesh.n_elements() {
        let info = model.cut.as_ref().map(|c| &c.elements[e]);
        match info {
            Some(ElementCut::Cut { sub_tets, partial }) => {
                for s in sub_tets {
                    let mut conn = Vec::with_capacity(4);
                    for p in &s.vertices {
                        pic.points.push(*p);
                        pic.disp.push(model.displacement_at(d, e, p, s.side));
                        conn.push(pic.points.len() - 1);
                    }
                    pic.cells.push((10, conn));
                    pic.cut_flag.push(if *partial { 3 } else { 2 });
                }
            }
            Some(ElementCut::Touched { side }) => {
                let mut conn = Vec::new();
                for &i in mesh.element(e) {
                    pic.points.push(mesh.nodes[i]);
                    pic.disp.push(model.node_displacement(d, i, *side));
                    conn.push(pic.points.len() - 1);
                }
                pic.cells.push((vtk_type, conn));
                pic.cut_flag.push(1);
            }
            _ => {
                pic.cells.push((vtk_type, mesh.element(e).to_vec()));
                pic.cut_flag.push(0);
            }
        }
    }
    pic
}

fn vtu_text(pic: &Picture) -> String {
    let mut s = String::with_capacity(64 * pic.points.len() + 32 * pic.cells.len());
    let _ = writeln!(s, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n<UnstructuredGrid>");
    let _ = writeln!(
        s,
        "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        pic.points.len(),
        pic.cells.len()
    );
    s.push_str(
        "<Points>\n<DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n",
    );
    for p in &pic.points {
        let _ = writeln!(s, "{:e} {:e} {:e}", p.x, p.y, p.z);
    }
    s.push_str("</DataArray>\n</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n");
    for (_, c) in &pic.cells {
        for i in c {
            let _ = write!(s, "{i} ");
        }
        s.push('\n');
    }
    s.push_str("</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n");
    let mut off = 0;
    for (_, c) in &pic.cells {
        off += c.len();
        let _ = write!(s, "{off} ");
    }
    s.push_str("\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n");
    for (t, _) in &pic.cells {
        let _ = write!(s, "{t} ");
    }
    s.push_str("\n</DataArray>\n</Cells>\n<PointData Vectors=\"u\">\n<DataArray type=\"Float64\" Name=\"u\" NumberOfComponents=\"3\" format=\"ascii\">\n");
    for u in &pic.disp {
        let _ = writeln!(s, "{:e} {:e} {:e}", u.x, u.y, u.z);
    }
    s.push_str("</DataArray>\n</PointData>\n<CellData>\n<DataArray type=\"UInt8\" Name=\"cut\" format=\"ascii\">\n");
    for f in &pic.cut_flag {
        let _ = write!(s, "{f} ");
    }
    s.push_str("\n</DataArray>\n</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    s
}

/// Writes `result.vtu` (last state) and, for a dynamic run, `result.pvd` with
/// one `frames/result_K.vtu` per kept frame.
pub fn write_result(_scene: &Scene, result: &RunResult, out: &Path) -> Result<(), RunError> {
    let model = &result.model;
    if !result.frames.is_empty() {
        let dir = out.join("frames");
        std::fs::create_dir_all(&dir)
            .map_err(|e| RunError::Output(format!("{}: {e}", dir.display())))?;
        let mut pvd = String::from("<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n");
        for (k, (t, d)) in result.frames.iter().enumerate() {
            let name = format!("frames/result_{k:05}.vtu");
            write_atomic(&out.join(&name), &vtu_text(&picture(model, d)))?;
            let _ = writeln!(pvd, "<DataSet timestep=\"{t:e}\" file=\"{name}\"/>");
        }
        pvd.push_str("</Collection>\n</VTKFile>\n");
        write_atomic(&out.join("result.pvd"), &pvd)?;
    }
    write_atomic(
        &out.join("result.vtu"),
        &vtu_text(&picture(model, &result.d)),
    )
}

/// Writes `probes.csv`: header `x,y,z,ux,uy,uz`, one row per probe.
pub fn write_probes(
    path: &Path,
    points: &[Point3<f64>],
    values: &[Vector3<f64>],
) -> Result<(), RunError> {
    let mut s = String::from("x,y,z,ux,uy,uz\n");
    for (p, u) in points.iter().zip(values) {
        let _ = writeln!(
            s,
            "{:e},{:e},{:e},{:e},{:e},{:e}",
            p.x, p.y, p.z, u.x, u.y, u.z
        );
    }
    write_atomic(path, &s)
}

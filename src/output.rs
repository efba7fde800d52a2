//! Run outputs: `result.vtu` with the opened cut (seed figures 7b/8), a `.pvd`
//! series for dynamic runs, written whole or not at all.
//!
//! Uncut elements are written as they are; cut elements as their sub-tets,
//! each displaced by u + ψa of its side, so the crack opens in the picture.

use crate::cut::ElementCut;
use crate::io::{write_probes_csv, write_pvd, write_vtu, VtuData};
use crate::mesh::ElementKind;
use crate::model::Model;
use crate::run::{RunError, RunResult};
use crate::scene::Scene;
use nalgebra::{Point3, Vector3};
use std::path::{Path, PathBuf};

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
                    // Positively oriented, as VTK expects (a split keeps
                    // the element's canonical order, either orientation).
                    let mut vertices = s.vertices;
                    if crate::mesh::tet_volume(&vertices) < 0.0 {
                        vertices.swap(1, 2);
                    }
                    for p in &vertices {
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

fn vtu_data(pic: &Picture) -> VtuData {
    let mut data = VtuData {
        points: pic.points.iter().flat_map(|p| [p.x, p.y, p.z]).collect(),
        ..VtuData::default()
    };
    for (t, c) in &pic.cells {
        data.push_cell(*t, c);
    }
    data.point_data.insert(
        "u".into(),
        (3, pic.disp.iter().flat_map(|u| [u.x, u.y, u.z]).collect()),
    );
    data.cell_data.insert(
        "cut".into(),
        (1, pic.cut_flag.iter().map(|&f| f64::from(f)).collect()),
    );
    data
}

/// Writes `result.vtu` (last state) and, for a dynamic run, `result.pvd` with
/// one `frames/result_K.vtu` per kept frame; each file whole or not at all.
/// Then removes what an earlier run into `out` left that this one did not
/// write ([`remove_stale_series`]): those files, which it returns.
pub fn write_result(
    _scene: &Scene,
    result: &RunResult,
    out: &Path,
) -> Result<Vec<PathBuf>, RunError> {
    let frames = result.progressive_frames.len().max(result.frames.len());
    write_series(result, out)?;
    remove_stale_series(out, frames)
}

/// An earlier run's series in `out` beyond the `frames` frames just
/// written: `frames/result_K.vtu` for K ≥ `frames`, and `result.pvd` and
/// the emptied `frames/` where none was written (a static run after a
/// dynamic one). Left there, they passed for this run's: a viewer opening
/// `result.pvd` played the earlier motion, and one opening the frames as a
/// file series mixed the two runs. Only names this program writes are
/// touched. Returns the files removed.
pub fn remove_stale_series(out: &Path, frames: usize) -> Result<Vec<PathBuf>, RunError> {
    let mut removed = Vec::new();
    let mut remove = |path: PathBuf| -> Result<(), RunError> {
        std::fs::remove_file(&path)
            .map_err(|e| crate::io::IoError::os(&path, "remove an earlier run's file", e))?;
        removed.push(path);
        Ok(())
    };
    let dir = out.join("frames");
    if let Ok(entries) = std::fs::read_dir(&dir) {
        let mut stale: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .filter(|e| {
                let name = e.file_name();
                let k = name
                    .to_str()
                    .and_then(|n| n.strip_prefix("result_"))
                    .and_then(|n| n.strip_suffix(".vtu"))
                    .filter(|k| k.len() >= 5 && k.bytes().all(|b| b.is_ascii_digit()))
                    .and_then(|k| k.parse::<usize>().ok());
                k.is_some_and(|k| k >= frames) && e.file_type().is_ok_and(|t| t.is_file())
            })
            .map(|e| e.path())
            .collect();
        stale.sort();
        for path in stale {
            remove(path)?;
        }
        if frames == 0 {
            // Only where nothing else is in it.
            let _ = std::fs::remove_dir(&dir);
        }
    }
    let pvd = out.join("result.pvd");
    if frames == 0 && pvd.is_file() {
        remove(pvd)?;
    }
    Ok(removed)
}

/// [`write_result`]'s files.
fn write_series(result: &RunResult, out: &Path) -> Result<(), RunError> {
    if !result.progressive_frames.is_empty() {
        return write_progressive(out, &result.progressive_frames);
    }
    let model = &result.model;
    if !result.frames.is_empty() {
        let dir = out.join("frames");
        std::fs::create_dir_all(&dir)
            .map_err(|e| crate::io::IoError::os(&dir, "create the folder", e))?;
        let mut series = Vec::with_capacity(result.frames.len());
        for (k, (t, d)) in result.frames.iter().enumerate() {
            let name = format!("frames/result_{k:05}.vtu");
            write_vtu(&out.join(&name), &vtu_data(&picture(model, d)))?;
            series.push((*t, name));
        }
        write_pvd(&out.join("result.pvd"), &series)?;
    }
    write_vtu(
        &out.join("result.vtu"),
        &vtu_data(&picture(model, &result.d)),
    )
    .map_err(RunError::from)
}

/// Writes `probes.csv`: header `x,y,z,ux,uy,uz`, one row per probe.
pub fn write_probes(
    path: &Path,
    points: &[Point3<f64>],
    values: &[Vector3<f64>],
) -> Result<(), RunError> {
    Ok(write_probes_csv(path, points, values)?)
}

/// VTK line cell (a blade's edge in the progressive series).
const VTK_LINE: u8 = 3;

/// One frame of a progressive cut: the picture of `model` (the cut as it is
/// at that time: opened behind the blade, extended through the front
/// elements) plus each blade edge as a line cell with `cut` flag 4 and zero
/// displacement (the edge is drawn where it is, in space).
pub fn progressive_frame(model: &Model, d: &[f64], edges: &[[Point3<f64>; 2]]) -> VtuData {
    let mut pic = picture(model, d);
    for e in edges {
        let k = pic.points.len();
        pic.points.extend_from_slice(e);
        pic.disp.extend([Vector3::zeros(), Vector3::zeros()]);
        pic.cells.push((VTK_LINE, vec![k, k + 1]));
        pic.cut_flag.push(4);
    }
    vtu_data(&pic)
}

/// Writes a progressive run's frames (each its own model's picture, from
/// [`progressive_frame`]) as `frames/result_K.vtu` and `result.pvd`, and the
/// last frame as `result.vtu`; each file whole or not at all.
pub fn write_progressive(out: &Path, frames: &[(f64, VtuData)]) -> Result<(), RunError> {
    let dir = out.join("frames");
    std::fs::create_dir_all(&dir)
        .map_err(|e| crate::io::IoError::os(&dir, "create the folder", e))?;
    let mut series = Vec::with_capacity(frames.len());
    for (k, (t, data)) in frames.iter().enumerate() {
        let name = format!("frames/result_{k:05}.vtu");
        write_vtu(&out.join(&name), data)?;
        series.push((*t, name));
    }
    write_pvd(&out.join("result.pvd"), &series)?;
    if let Some((_, last)) = frames.last() {
        write_vtu(&out.join("result.vtu"), last)?;
    }
    Ok(())
}

//! The references written by `refs/` (layout in `refs/README.md`): meshes in
//! `refs/out/meshes/<family>/L<k>.msh`, solutions in
//! `refs/out/<case>/<family>_L<k>/{p1,p2,corot_p1,corot_p2}.vtu` on the same
//! node numbering (P2: the mesh vertices first, then one mid-node per edge).

use crate::io::{read_vtu, IoError};
use crate::mesh::{ElementKind, TetMesh, TET10_EDGES};
use nalgebra::{Point3, Vector3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The folder `refs/out` of this checkout.
pub fn out_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("refs/out")
}

/// A reference solution: its mesh (Tet4 or Tet10) and nodal displacements.
pub struct Reference {
    pub mesh: TetMesh,
    pub u: Vec<Vector3<f64>>,
}

/// Reads a reference VTU (10: tetra, 24: quadratic tetra; point data `u`).
pub fn read_reference(path: &Path) -> Result<Reference, IoError> {
    let d = read_vtu(path)?;
    let kind = match d.types.first() {
        Some(10) => ElementKind::Tet4,
        Some(24) => ElementKind::Tet10,
        other => {
            return Err(IoError::new(
                path,
                format!("cell type {other:?} is not a tetrahedron"),
            ))
        }
    };
    if d.types.iter().any(|&t| Some(&t) != d.types.first()) {
        return Err(IoError::new(path, "mixed cell types"));
    }
    let (comps, u) = d
        .point_data
        .get("u")
        .ok_or_else(|| IoError::new(path, "no point data `u`"))?;
    if *comps != 3 {
        return Err(IoError::new(path, "point data `u` must have 3 components"));
    }
    let nodes = d
        .points
        .chunks(3)
        .map(|p| Point3::new(p[0], p[1], p[2]))
        .collect();
    let u = u
        .chunks(3)
        .map(|p| Vector3::new(p[0], p[1], p[2]))
        .collect();
    let mut mesh = TetMesh {
        kind,
        nodes,
        cells: d.connectivity,
    };
    mesh.orient_positively();
    Ok(Reference { mesh, u })
}

/// Why two meshes are not the same mesh (element by element, node by node).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SameMeshError {
    #[error("meshes differ: ours {ours} {ours_kind}, reference {reference} {reference_kind}")]
    Meshes {
        ours: usize,
        ours_kind: &'static str,
        reference: usize,
        reference_kind: &'static str,
    },
    #[error("element {0} has other vertices in the reference")]
    Vertices(usize),
    #[error("edge {edge:?} of element {element} missing in the reference")]
    Edge {
        element: usize,
        edge: (usize, usize),
    },
}

/// Relative difference ‖u_ours − u_ref‖ / ‖u_ref‖ over the nodes of the same
/// mesh: `ours` is our mesh (read from the same `.msh`, Tet4 or Tet10 made
/// from it) with nodal displacements `d` (first 3 × n_nodes entries). Nodes
/// are matched through topology — vertices by index, mid-nodes by the vertex
/// pair of their edge — never by coordinates (crack nodes coincide).
pub fn same_mesh_difference(
    ours: &TetMesh,
    d: &[f64],
    reference: &Reference,
) -> Result<f64, SameMeshError> {
    if ours.kind != reference.mesh.kind || ours.n_elements() != reference.mesh.n_elements() {
        return Err(SameMeshError::Meshes {
            ours: ours.n_elements(),
            ours_kind: ours.kind.name(),
            reference: reference.mesh.n_elements(),
            reference_kind: reference.mesh.kind.name(),
        });
    }
    let edge_key = |m: &TetMesh, e: usize, k: usize| {
        let v = m.vertices(e);
        let (a, b) = TET10_EDGES[k];
        (v[a].min(v[b]), v[a].max(v[b]))
    };
    // Our node index → reference node index.
    let mut map: HashMap<usize, usize> = HashMap::new();
    for e in 0..ours.n_elements() {
        let (oc, rc) = (ours.element(e), reference.mesh.element(e));
        let mut ov = oc[..4].to_vec();
        let mut rv = rc[..4].to_vec();
        ov.sort_unstable();
        rv.sort_unstable();
        if ov != rv {
            return Err(SameMeshError::Vertices(e));
        }
        for &i in &oc[..4] {
            map.insert(i, i);
        }
        if ours.kind == ElementKind::Tet10 {
            let ref_edges: HashMap<(usize, usize), usize> = (0..6)
                .map(|k| (edge_key(&reference.mesh, e, k), rc[4 + k]))
                .collect();
            for k in 0..6 {
                let key = edge_key(ours, e, k);
                let r = *ref_edges.get(&key).ok_or(SameMeshError::Edge {
                    element: e,
                    edge: key,
                })?;
                map.insert(oc[4 + k], r);
            }
        }
    }
    let (mut diff, mut norm) = (0.0, 0.0);
    for (&i, &r) in &map {
        let mine = Vector3::new(d[3 * i], d[3 * i + 1], d[3 * i + 2]);
        diff += (mine - reference.u[r]).norm_squared();
        norm += reference.u[r].norm_squared();
    }
    Ok((diff / norm).sqrt())
}

/// A graded fine reference and its own error, one row of
/// `reports/data/references.csv` (written by `refs/make_refs.py` from the
/// manifests): the fine graded P2 solution against the one 1.4× coarser
/// everywhere, measured like the study's rows (L2, opening, probes).
#[derive(Debug, Clone, PartialEq)]
pub struct ReferenceQuality {
    pub case: String,
    pub family: String,
    pub dofs: usize,
    /// Element size on the singular curves (crack front; `slice`: the clamped edges), m.
    pub front_h: f64,
    /// Far-field element size, m.
    pub far_h: f64,
    pub coarse_dofs: usize,
    pub coarse_front_h: f64,
    /// ‖u_fine − u_coarse‖ / ‖u_fine‖ (L2), the reference's error estimate.
    pub own_l2: f64,
    /// The same for the crack opening (NaN without a cut).
    pub own_opening: f64,
    /// Largest probe difference over the largest probe displacement (NaN without probes).
    pub own_probes: f64,
}

pub const QUALITY_HEADER: &str =
    "case,family,dofs,front_h,far_h,coarse_dofs,coarse_front_h,own_l2,own_opening,own_probes";

/// A level whose error is below this multiple of the reference's own error
/// is "unresolved": the reference cannot tell its error apart.
pub const RESOLVED_FACTOR: f64 = 3.0;

impl ReferenceQuality {
    pub fn parse(line: &str) -> Option<ReferenceQuality> {
        let f: Vec<&str> = line.trim().split(',').collect();
        if f.len() != 10 {
            return None;
        }
        let num = |k: usize| -> Option<f64> {
            match f[k] {
                "" | "nan" | "None" => Some(f64::NAN),
                v => v.parse().ok(),
            }
        };
        Some(ReferenceQuality {
            case: f[0].to_string(),
            family: f[1].to_string(),
            dofs: f[2].parse().ok()?,
            front_h: num(3)?,
            far_h: num(4)?,
            coarse_dofs: f[5].parse().ok()?,
            coarse_front_h: num(6)?,
            own_l2: num(7)?,
            own_opening: num(8)?,
            own_probes: num(9)?,
        })
    }

    /// Whether an L2 error is resolved by this reference (≥ [`RESOLVED_FACTOR`] × its own error).
    pub fn resolves(&self, l2: f64) -> bool {
        l2 >= RESOLVED_FACTOR * self.own_l2
    }
}

/// Reads `reports/data/references.csv` (header line first; bad lines are an error).
pub fn read_quality(path: &Path) -> Result<Vec<ReferenceQuality>, IoError> {
    let text = std::fs::read_to_string(path).map_err(|e| IoError::os(path, "reading", e))?;
    let mut lines = text.lines();
    if lines.next().map(str::trim) != Some(QUALITY_HEADER) {
        return Err(IoError::new(
            path,
            format!("the header must be `{QUALITY_HEADER}`"),
        ));
    }
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            ReferenceQuality::parse(l)
                .ok_or_else(|| IoError::invalid(path, format!("bad row `{l}`")))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quality_rows_parse_and_bad_files_are_errors() {
        let q = ReferenceQuality::parse(
            "slice,slice_precut,300000,8e-4,3.2e-3,150000,1.12e-3,2e-3,nan,1.5e-3",
        )
        .unwrap();
        assert_eq!((q.dofs, q.coarse_dofs), (300000, 150000));
        assert!(q.own_opening.is_nan() && q.own_probes == 1.5e-3);
        assert!(q.resolves(6e-3) && !q.resolves(5.9e-3));
        assert!(ReferenceQuality::parse("slice,slice_precut,3").is_none());
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("references.csv");
        std::fs::write(&path, "case,dofs\n").unwrap();
        assert!(read_quality(&path).is_err());
        std::fs::write(&path, format!("{QUALITY_HEADER}\nslice,x,1\n")).unwrap();
        let e = read_quality(&path).unwrap_err().to_string();
        assert!(e.contains("bad row"), "{e}");
    }
}

//! gmsh MSH 4.1 (ASCII or binary) through the `mshio` crate.

use super::IoError;
use crate::mesh::{ElementKind, TetMesh};
use mshio::mshfile::ElementType;
use nalgebra::Point3;
use std::collections::HashMap;
use std::path::Path;

/// A mesh read from gmsh, with the map from gmsh node tags to our node indices.
#[derive(Debug, Clone)]
pub struct MshMesh {
    pub mesh: TetMesh,
    /// gmsh node tag → node index (nodes are numbered in file order).
    pub node_index: HashMap<u64, usize>,
    /// `$PhysicalNames`: (dimension, tag, name).
    pub physical_names: Vec<(i32, i32, String)>,
}

/// gmsh's 10-node tetrahedron numbers its edges (0,1) (1,2) (2,0) (3,0) (3,2) (3,1);
/// ours (VTK) (0,1) (1,2) (0,2) (0,3) (1,3) (2,3): our node k is gmsh's node GMSH_TET10[k].
const GMSH_TET10: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];

/// Reads the tetrahedra of a gmsh MSH 4.1 file (lower-dimensional elements are skipped).
pub fn read_msh(path: &Path) -> Result<MshMesh, IoError> {
    let bytes = std::fs::read(path).map_err(|e| IoError::new(path, e.to_string()))?;
    let file = mshio::parse_msh_bytes(&bytes).map_err(|e| {
        let text = format!("{e}");
        IoError::new(
            path,
            format!(
                "not a readable MSH 4.1 file: {}",
                text.lines().next().unwrap_or("parse error")
            ),
        )
    })?;
    let nodes = file
        .data
        .nodes
        .as_ref()
        .ok_or_else(|| IoError::new(path, "no $Nodes section"))?;
    let elements = file
        .data
        .elements
        .as_ref()
        .ok_or_else(|| IoError::new(path, "no $Elements section"))?;

    // Nodes in file order. Dense tags (min..=max, no gaps) are sequential across blocks.
    let mut points = Vec::with_capacity(nodes.num_nodes as usize);
    let mut node_index: HashMap<u64, usize> = HashMap::with_capacity(nodes.num_nodes as usize);
    let mut next_tag = nodes.min_node_tag;
    for block in &nodes.node_blocks {
        let mut tags: Vec<(u64, usize)> = match &block.node_tags {
            Some(map) => map.iter().map(|(&t, &i)| (t, i)).collect(),
            None => (0..block.nodes.len())
                .map(|i| (next_tag + i as u64, i))
                .collect(),
        };
        tags.sort_unstable_by_key(|&(_, i)| i);
        next_tag += block.nodes.len() as u64;
        for (tag, i) in tags {
            let n = &block.nodes[i];
            if !(n.x.is_finite() && n.y.is_finite() && n.z.is_finite()) {
                return Err(IoError::new(
                    path,
                    format!("node {tag} has a non-finite coordinate"),
                ));
            }
            node_index.insert(tag, points.len());
            points.push(Point3::new(n.x, n.y, n.z));
        }
    }

    let mut kind = None;
    let mut cells = Vec::new();
    for block in &elements.element_blocks {
        let (k, order): (ElementKind, &[usize]) = match block.element_type {
            ElementType::Tet4 => (ElementKind::Tet4, &[0, 1, 2, 3]),
            ElementType::Tet10 => (ElementKind::Tet10, &GMSH_TET10),
            _ if block.entity_dim < 3 => continue,
            other => {
                return Err(IoError::new(
                    path,
                    format!(
                    "unsupported volume element type {other:?} (only 4- and 10-node tetrahedra)"
                ),
                ))
            }
        };
        if kind.is_some_and(|kk| kk != k) {
            return Err(IoError::new(path, "mixes 4- and 10-node tetrahedra"));
        }
        kind = Some(k);
        for el in &block.elements {
            if el.nodes.len() != k.nodes() {
                return Err(IoError::new(
                    path,
                    format!(
                        "element {} has {} nodes, expected {}",
                        el.element_tag,
                        el.nodes.len(),
                        k.nodes()
                    ),
                ));
            }
            for &g in order {
                let tag = el.nodes[g];
                let i = node_index.get(&tag).ok_or_else(|| {
                    IoError::new(
                        path,
                        format!("element {} references missing node {tag}", el.element_tag),
                    )
                })?;
                cells.push(*i);
            }
        }
    }
    let kind = kind.ok_or_else(|| IoError::new(path, "contains no tetrahedra"))?;
    let mut mesh = TetMesh {
        kind,
        nodes: points,
        cells,
    };
    for e in 0..mesh.n_elements() {
        if mesh.volume(e) == 0.0 {
            return Err(IoError::new(
                path,
                format!("tetrahedron {e} is degenerate (zero volume)"),
            ));
        }
    }
    mesh.orient_positively();
    Ok(MshMesh {
        mesh,
        node_index,
        physical_names: physical_names(&bytes),
    })
}

/// `$PhysicalNames` (ASCII even in binary files), which mshio skips.
fn physical_names(bytes: &[u8]) -> Vec<(i32, i32, String)> {
    let text = String::from_utf8_lossy(bytes);
    let Some(start) = text.find("$PhysicalNames") else {
        return Vec::new();
    };
    let Some(end) = text[start..].find("$EndPhysicalNames") else {
        return Vec::new();
    };
    text[start..start + end]
        .lines()
        .skip(2)
        .filter_map(|l| {
            let mut it = l.splitn(3, ' ');
            let dim = it.next()?.trim().parse().ok()?;
            let tag = it.next()?.trim().parse().ok()?;
            let name = it.next()?.trim().trim_matches('"').to_string();
            Some((dim, tag, name))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_TETS: &str = r#"$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
1
3 7 "body"
$EndPhysicalNames
$Nodes
1 5 1 20
3 1 0 5
1
5
10
11
20
0 0 0
1 0 0
0 1 0
0 0 1
1 1 1
$EndNodes
$Elements
1 2 1 2
3 1 4 2
1 1 5 10 11
2 5 11 10 20
$EndElements
"#;

    #[test]
    fn reads_tets_with_sparse_tags_and_fixes_orientation() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.msh");
        std::fs::write(&p, TWO_TETS).unwrap();
        let m = read_msh(&p).unwrap();
        assert_eq!(m.mesh.kind, ElementKind::Tet4);
        assert_eq!(m.mesh.n_nodes(), 5);
        assert_eq!(m.mesh.n_elements(), 2);
        assert!((0..2).all(|e| m.mesh.volume(e) > 0.0));
        assert_eq!(m.node_index[&20], 4);
        assert_eq!(m.physical_names, vec![(3, 7, "body".to_string())]);
    }

    #[test]
    fn bad_files_give_errors_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.msh");
        for text in [
            TWO_TETS.replace("2 5 11 10 20", "2 5 11 10 99"),
            "garbage".to_string(),
            TWO_TETS
                .replace("3 1 4 2", "3 1 2 2")
                .replace("1 1 5 10 11\n2 5 11 10 20", "1 1 5 10\n2 5 11 10"),
        ] {
            std::fs::write(&p, &text).unwrap();
            let err = read_msh(&p).unwrap_err().to_string();
            assert!(err.contains("m.msh"), "{err}");
        }
        assert!(read_msh(&dir.path().join("missing.msh")).is_err());
    }
}

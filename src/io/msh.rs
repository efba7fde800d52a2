//! gmsh MSH 4.1 meshes (ASCII or binary) through the `mshio` crate, plus the
//! `$PhysicalNames` section, which `mshio` skips.
//!
//! Only 3-D 4- and 10-node tetrahedra become elements; points, lines and
//! triangles (boundary and physical-group elements) are skipped, and any
//! other volume element is an error rather than a silent hole in the body.

use super::{read_bytes, IoError};
use crate::mesh::{ElementKind, Straightened, TetMesh};
use mshio::mshfile::ElementType;
use nalgebra::Point3;
use std::collections::HashMap;
use std::path::Path;

/// One entry of `$PhysicalNames`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PhysicalName {
    /// Dimension of the group (0 points … 3 volumes).
    pub dim: i32,
    pub tag: i32,
    pub name: String,
}

/// A tetrahedral mesh read from gmsh, with what is needed to go back to gmsh's
/// numbering and to its physical groups.
#[derive(Debug, Clone)]
pub struct MshMesh {
    /// Nodes in file order, numbered 0..n, those no tetrahedron uses left
    /// out; tets in file order, positively oriented.
    pub mesh: TetMesh,
    /// gmsh node tag → node index in `mesh` (the nodes it keeps).
    pub node_index: HashMap<u64, usize>,
    /// `$PhysicalNames`, in file order (empty when the section is absent).
    pub physical_names: Vec<PhysicalName>,
    /// Per element of `mesh`: the tag of the gmsh volume entity it belongs to.
    pub element_entity: Vec<i32>,
    /// Volume entity tag → its physical tags (from `$Entities`).
    pub entity_physical: HashMap<i32, Vec<i32>>,
    /// What the reader changed.
    pub notes: MeshNotes,
}

/// What [`read_msh`] changed in a file's mesh, for the plan to say.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct MeshNotes {
    /// The Tet10 mid-nodes moved onto their edges' midpoints (a curved
    /// body's mesh of order 2: elements here are straight-sided).
    pub straightened: Straightened,
    /// Nodes no tetrahedron uses, left out.
    pub unused_nodes: usize,
    /// 4-node tetrahedra made 10-node ones for a Tet10 scene (mid-nodes
    /// added at the edges' midpoints; set by the scene, not the reader).
    pub promoted: bool,
}

impl MshMesh {
    /// Physical tags of element `e` (empty when its volume is in no physical group).
    pub fn physical_tags(&self, e: usize) -> &[i32] {
        self.element_entity
            .get(e)
            .and_then(|t| self.entity_physical.get(t))
            .map_or(&[], |v| v.as_slice())
    }

    /// The tag of the physical group called `name` of dimension `dim`.
    pub fn physical_tag(&self, dim: i32, name: &str) -> Option<i32> {
        self.physical_names
            .iter()
            .find(|p| p.dim == dim && p.name == name)
            .map(|p| p.tag)
    }

    /// The elements in the 3-D physical group `tag`, in order.
    pub fn elements_in_physical(&self, tag: i32) -> Vec<usize> {
        (0..self.element_entity.len())
            .filter(|&e| self.physical_tags(e).contains(&tag))
            .collect()
    }
}

/// gmsh numbers the 10-node tetrahedron's edges (0,1) (1,2) (2,0) (3,0) (3,2) (3,1)
/// (node 8 on edge 2–3, node 9 on edge 1–3); ours (VTK) (0,1) (1,2) (0,2) (0,3)
/// (1,3) (2,3). Our node k is gmsh's node `GMSH_TET10[k]`.
const GMSH_TET10: [usize; 10] = [0, 1, 2, 3, 4, 5, 6, 7, 9, 8];
const GMSH_TET4: [usize; 4] = [0, 1, 2, 3];

/// Reads the tetrahedra of a gmsh MSH 4.1 file (ASCII or binary).
///
/// Nodes keep the file's order and are renumbered 0..n (`node_index` maps
/// back); nodes no tet uses are left out, Tet10 mid-nodes off their edges
/// put at the midpoints ([`MshMesh::notes`]). Errors: no tetrahedra, 4- and
/// 10-node tets mixed, a referenced node tag that is missing, a node tag
/// given twice, a non-finite coordinate, a tet of zero volume, a volume
/// element other than a tet, a node that is the mid-node of two edges.
///
/// Node tags are read in any order, with or without gaps
/// ([`with_node_tags_kept`]).
pub fn read_msh(path: &Path) -> Result<MshMesh, IoError> {
    parse_msh(&read_bytes(path)?, path)
}

/// [`read_msh`] on the bytes of a file already read; `path` names it in errors.
pub fn parse_msh(bytes: &[u8], path: &Path) -> Result<MshMesh, IoError> {
    let file = parse_file(bytes).map_err(|message| IoError::invalid(path, message))?;
    if file.header.version < 4.1 || file.header.version >= 5.0 {
        return Err(IoError::unsupported(
            path,
            format!("MSH version {} (only 4.1 is read)", file.header.version),
        ));
    }
    let nodes = file
        .data
        .nodes
        .as_ref()
        .ok_or_else(|| IoError::invalid(path, "no $Nodes section"))?;
    let elements = file
        .data
        .elements
        .as_ref()
        .ok_or_else(|| IoError::invalid(path, "no $Elements section"))?;
    let (mut points, mut node_index) =
        read_nodes(nodes).map_err(|message| IoError::invalid(path, message))?;

    let mut kind = None;
    let mut cells = Vec::new();
    let mut element_entity = Vec::new();
    for block in &elements.element_blocks {
        if block.entity_dim < 3 {
            continue;
        }
        let (k, order): (ElementKind, &[usize]) = match block.element_type {
            ElementType::Tet4 => (ElementKind::Tet4, &GMSH_TET4),
            ElementType::Tet10 => (ElementKind::Tet10, &GMSH_TET10),
            other => {
                return Err(IoError::unsupported(
                    path,
                    format!(
                    "volume element type {other:?} in entity {} (only 4- and 10-node tetrahedra)",
                    block.entity_tag
                ),
                ))
            }
        };
        if kind.is_some_and(|kk| kk != k) {
            return Err(IoError::unsupported(
                path,
                "mixes 4- and 10-node tetrahedra",
            ));
        }
        kind = Some(k);
        cells.reserve(block.elements.len() * k.nodes());
        for el in &block.elements {
            if el.nodes.len() != k.nodes() {
                return Err(IoError::invalid(
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
                    IoError::invalid(
                        path,
                        format!("element {} references missing node {tag}", el.element_tag),
                    )
                })?;
                cells.push(*i);
            }
            element_entity.push(block.entity_tag);
        }
    }
    let kind = kind.ok_or_else(|| IoError::invalid(path, "contains no tetrahedra"))?;
    // Nodes no tetrahedron uses (say, of a surface saved in the same file)
    // carry nothing of the body: left with DOFs, they made every static
    // system singular.
    let mut used = vec![false; points.len()];
    for &i in &cells {
        used[i] = true;
    }
    let unused_nodes = used.iter().filter(|&&u| !u).count();
    if unused_nodes > 0 {
        let mut renumbered = vec![usize::MAX; points.len()];
        let mut kept = Vec::with_capacity(points.len() - unused_nodes);
        for (i, p) in points.iter().enumerate() {
            if used[i] {
                renumbered[i] = kept.len();
                kept.push(*p);
            }
        }
        for c in &mut cells {
            *c = renumbered[*c];
        }
        node_index.retain(|_, i| {
            *i = renumbered[*i];
            *i != usize::MAX
        });
        points = kept;
    }
    let mut mesh = TetMesh {
        kind,
        nodes: points,
        cells,
    };
    if let Some(e) = (0..mesh.n_elements()).find(|&e| mesh.volume(e) == 0.0) {
        return Err(IoError::invalid(
            path,
            format!("tetrahedron {e} (in file order) is degenerate: zero volume"),
        ));
    }
    mesh.orient_positively();
    let straightened = mesh.straighten_edges().map_err(|node| {
        let tag = node_index
            .iter()
            .find_map(|(&tag, &i)| (i == node).then_some(tag))
            .unwrap_or_default();
        IoError::invalid(
            path,
            format!("node {tag} is the mid-node of two edges (or a mid-node and a vertex)"),
        )
    })?;

    let entity_physical = file
        .data
        .entities
        .as_ref()
        .map(|ent| {
            ent.volumes
                .iter()
                .map(|v| (v.tag, v.physical_tags.clone()))
                .collect()
        })
        .unwrap_or_default();
    Ok(MshMesh {
        mesh,
        node_index,
        physical_names: physical_names(path, bytes)?,
        element_entity,
        entity_physical,
        notes: MeshNotes {
            straightened,
            unused_nodes,
            promoted: false,
        },
    })
}

/// The version a file's `$MeshFormat` section gives (its first word, as
/// written: "4.1", "2.2"), where the file starts with one.
fn format_version(bytes: &[u8]) -> Option<String> {
    let head = &bytes[..bytes.len().min(256)];
    let text = String::from_utf8_lossy(head);
    let mut lines = text.lines().map(str::trim);
    if lines.next()? != "$MeshFormat" {
        return None;
    }
    lines.next()?.split_whitespace().next().map(str::to_string)
}

/// mshio's parse of a file's bytes, its node tags kept
/// ([`with_node_tags_kept`]); its failure, or a panic in it (a third-party
/// parser of untrusted bytes: say, an arithmetic overflow on a hostile
/// header), as one line.
pub(crate) fn parse_file(bytes: &[u8]) -> Result<mshio::MshFile<u64, i32, f64>, String> {
    if let Some(version) = format_version(bytes).filter(|v| !v.starts_with("4.1")) {
        return Err(format!(
            "an MSH {version} file, and only MSH 4.1 is read: save it as 4.1 (`gmsh FILE -save -format msh41 -o NEW.msh`, or Mesh.MshFileVersion = 4.1 before writing)"
        ));
    }
    let tagged = with_node_tags_kept(bytes);
    let bytes = tagged.as_deref().unwrap_or(bytes);
    let parsed = std::panic::catch_unwind(|| {
        mshio::parse_msh_bytes(bytes).map_err(|e| {
            // mshio's message: "During parsing...", the contexts ("in node
            // section," …, the innermost naming the fault), the error, then
            // a hex dump: all but the first and the dump, on one line.
            let text = e.to_string();
            let lines: Vec<&str> = text
                .lines()
                .map(str::trim)
                .take_while(|l| !l.starts_with("Hex dump"))
                .filter(|l| !l.is_empty() && *l != "During parsing...")
                .collect();
            format!("not a readable MSH 4.1 file: {}", lines.join(" "))
        })
    });
    match parsed {
        Ok(result) => result,
        Err(_) => Err("not a readable MSH 4.1 file (the parser gave up)".into()),
    }
}

/// A file's nodes in file order and its node tag → index.
pub(crate) type FileNodes = (Vec<Point3<f64>>, HashMap<u64, usize>);

/// The [`FileNodes`] of a parsed file; a tag given twice or a non-finite
/// coordinate is the error's one line.
pub(crate) fn read_nodes(nodes: &mshio::Nodes<u64, i32, f64>) -> Result<FileNodes, String> {
    let n_nodes = usize::try_from(nodes.num_nodes).unwrap_or(0);
    let mut points = Vec::with_capacity(n_nodes.min(1 << 24));
    let mut node_index: HashMap<u64, usize> = HashMap::with_capacity(n_nodes.min(1 << 24));
    let mut next_tag = nodes.min_node_tag;
    for block in &nodes.node_blocks {
        let n = block.nodes.len();
        let tags: Vec<u64> = match &block.node_tags {
            Some(map) => {
                if map.len() != n || map.values().any(|&i| i >= n) {
                    return Err(format!(
                        "a node block of entity {} gives a node tag twice",
                        block.entity_tag
                    ));
                }
                let mut tags = vec![0; n];
                for (&tag, &i) in map {
                    tags[i] = tag;
                }
                tags
            }
            None => (next_tag..next_tag.saturating_add(n as u64)).collect(),
        };
        next_tag = next_tag.saturating_add(n as u64);
        for (tag, p) in tags.into_iter().zip(&block.nodes) {
            if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
                return Err(format!("node {tag} has a non-finite coordinate"));
            }
            if node_index.insert(tag, points.len()).is_some() {
                return Err(format!("node tag {tag} appears twice"));
            }
            points.push(Point3::new(p.x, p.y, p.z));
        }
    }
    Ok((points, node_index))
}

/// The file's bytes with the `$Nodes` header's largest node tag one higher,
/// so that mshio keeps every block's node tags: it drops them when the tags
/// are min..=max without gaps (max − min = count − 1), and nodes are then
/// numbered in block order, which is the tags' order only when the blocks
/// and the tags within them come in ascending order (a file with block
/// tags 4 5, then 1 2 3, was read with its nodes renumbered: wrong
/// coordinates at every element). `None` where the header is not where the
/// format puts it (mshio then reads the file as it is, or names its fault).
fn with_node_tags_kept(bytes: &[u8]) -> Option<Vec<u8>> {
    let format_at = find(bytes, b"$MeshFormat")? + b"$MeshFormat".len();
    let format_line = bytes[format_at..]
        .split(|&b| b == b'\n')
        .find(|l| !l.iter().all(u8::is_ascii_whitespace))?;
    let format = std::str::from_utf8(format_line).ok()?;
    let mut fields = format.split_whitespace().skip(1);
    let binary = fields.next()? == "1";
    let size: usize = fields.next()?.parse().ok()?;
    // The section after the (binary) entities: its header's four numbers
    // start on the line after `$Nodes`.
    let after = find(bytes, b"$EndEntities").unwrap_or(format_at);
    let nodes = after + find(&bytes[after..], b"$Nodes")? + b"$Nodes".len();
    let start = nodes + bytes[nodes..].iter().position(|&b| b == b'\n')? + 1;
    if binary {
        // One int (1) after the format line gives the byte order.
        let one_at = format_at + find(&bytes[format_at..], format_line)? + format_line.len() + 1;
        let little = *bytes.get(one_at)? == 1;
        if !matches!(size, 4 | 8) {
            return None;
        }
        let mut out = bytes.to_vec();
        let slot = out.get_mut(start + 3 * size..start + 4 * size)?;
        // + 1 from the least significant byte on, carrying while a byte overflows.
        if !little {
            slot.reverse();
        }
        let overflow = slot.iter_mut().all(|b| {
            let (sum, carry) = b.overflowing_add(1);
            *b = sum;
            carry
        });
        if !little {
            slot.reverse();
        }
        if overflow {
            return None;
        }
        Some(out)
    } else {
        let end = start + bytes[start..].iter().position(|&b| b == b'\n')?;
        let line = std::str::from_utf8(&bytes[start..end]).ok()?;
        let numbers: Vec<u64> = line
            .split_whitespace()
            .map(|w| w.parse().ok())
            .collect::<Option<_>>()?;
        let [blocks, count, min, max] = numbers[..] else {
            return None;
        };
        let header = format!("{blocks} {count} {min} {}", max.checked_add(1)?);
        let mut out = Vec::with_capacity(bytes.len() + 2);
        out.extend_from_slice(&bytes[..start]);
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(&bytes[end..]);
        Some(out)
    }
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}

/// `$PhysicalNames` (ASCII text even in binary files; it comes before the
/// first section that may hold binary data, `$Entities` or `$Nodes`).
fn physical_names(path: &Path, bytes: &[u8]) -> Result<Vec<PhysicalName>, IoError> {
    let head_end = [&b"$Entities"[..], b"$PartitionedEntities", b"$Nodes"]
        .iter()
        .filter_map(|m| find(bytes, m))
        .min()
        .unwrap_or(bytes.len());
    let head = &bytes[..head_end];
    let Some(start) = find(head, b"$PhysicalNames") else {
        return Ok(Vec::new());
    };
    let body = &head[start + b"$PhysicalNames".len()..];
    let end = find(body, b"$EndPhysicalNames")
        .ok_or_else(|| IoError::invalid(path, "$PhysicalNames has no $EndPhysicalNames"))?;
    let text = std::str::from_utf8(&body[..end])
        .map_err(|_| IoError::invalid(path, "$PhysicalNames is not UTF-8 text"))?;
    let mut lines = text.lines().map(str::trim).filter(|l| !l.is_empty());
    let bad = |line: &str| IoError::invalid(path, format!("bad $PhysicalNames line `{line}`"));
    let count_line = lines.next().unwrap_or("");
    let count: usize = count_line.parse().map_err(|_| bad(count_line))?;
    let mut names = Vec::with_capacity(count.min(1 << 16));
    for line in lines {
        let mut it = line.splitn(3, char::is_whitespace);
        let dim = it
            .next()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| bad(line))?;
        let tag = it
            .next()
            .and_then(|s| s.parse().ok())
            .ok_or_else(|| bad(line))?;
        let name = it.next().map(str::trim).ok_or_else(|| bad(line))?;
        let name = name
            .strip_prefix('"')
            .and_then(|n| n.strip_suffix('"'))
            .ok_or_else(|| bad(line))?;
        names.push(PhysicalName {
            dim,
            tag,
            name: name.to_string(),
        });
    }
    if names.len() != count {
        return Err(IoError::invalid(
            path,
            format!(
                "$PhysicalNames announces {count} names but holds {}",
                names.len()
            ),
        ));
    }
    Ok(names)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TET10_EDGES;

    fn fixture(name: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures")
            .join(name)
    }

    /// An older MSH version (gmsh's 2.2, still common) is refused saying
    /// which version it is and how to save it as 4.1.
    #[test]
    fn an_msh_2_2_file_is_refused_with_how_to_save_it_as_4_1() {
        let dir = tempfile::tempdir().unwrap();
        let text = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 2 0 1 1 2 3 4\n$EndElements\n";
        let message = read_msh(&write(&dir, text)).err().unwrap().to_string();
        assert!(
            message.contains("an MSH 2.2 file") && message.contains("-format msh41"),
            "{message}"
        );
        assert_eq!(
            format_version(b"$MeshFormat\n4.1 0 8\n"),
            Some("4.1".into())
        );
        assert_eq!(format_version(b"solid x\n"), None);
    }

    fn write(dir: &tempfile::TempDir, text: &str) -> std::path::PathBuf {
        let p = dir.path().join("m.msh");
        std::fs::write(&p, text).unwrap();
        p
    }

    /// Mid-nodes sit at the middle of their edges (straight-sided tets).
    fn assert_midnodes_on_edges(m: &TetMesh, tol: f64) {
        for e in 0..m.n_elements() {
            let c = m.element(e);
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                let mid = (m.nodes[c[a]].coords + m.nodes[c[b]].coords) * 0.5;
                let off = (m.nodes[c[4 + k]].coords - mid).norm();
                assert!(off <= tol, "element {e}, mid-node {}: off by {off}", 4 + k);
            }
        }
    }

    /// Two tets, node tags with gaps (1 5 10 11 20), the second one negatively
    /// oriented as written, a triangle to skip and physical groups.
    const TWO_TETS: &str = r#"$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
2 3 "bottom face"
3 7 "body"
$EndPhysicalNames
$Entities
0 0 1 1
4 0 0 0 1 1 0 1 3 0
2 0 0 0 1 1 1 1 7 0
$EndEntities
$Nodes
1 5 1 20
3 2 0 5
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
2 3 1 9
2 4 2 1
9 1 5 10
3 2 4 2
1 1 5 10 11
2 5 11 10 20
$EndElements
"#;

    #[test]
    fn reads_tets_with_sparse_tags_fixes_orientation_and_skips_triangles() {
        let dir = tempfile::tempdir().unwrap();
        let m = read_msh(&write(&dir, TWO_TETS)).unwrap();
        assert_eq!(m.mesh.kind, ElementKind::Tet4);
        assert_eq!(m.mesh.n_nodes(), 5);
        assert_eq!(m.mesh.n_elements(), 2);
        // Written as 5 11 10 20 (negative): vertices 1 and 2 swapped.
        assert!(tet_is_negative(&m.mesh, [1, 3, 2, 4]));
        assert_eq!(m.mesh.element(1), &[1, 2, 3, 4]);
        assert_eq!(m.mesh.element(0), &[0, 1, 2, 3]);
        assert!((0..2).all(|e| m.mesh.volume(e) > 0.0));
        let tags = [1, 5, 10, 11, 20];
        for (i, t) in tags.iter().enumerate() {
            assert_eq!(m.node_index[t], i);
        }
        assert_eq!(
            m.physical_names,
            vec![
                PhysicalName {
                    dim: 2,
                    tag: 3,
                    name: "bottom face".into()
                },
                PhysicalName {
                    dim: 3,
                    tag: 7,
                    name: "body".into()
                }
            ]
        );
        assert_eq!(m.physical_tag(3, "body"), Some(7));
        assert_eq!(m.physical_tags(0), &[7]);
        assert_eq!(m.elements_in_physical(7), vec![0, 1]);
    }

    /// Node tags 1..=5 without gaps, their blocks and the tags within a
    /// block out of order: the same two tets as [`TWO_TETS`] (tags 1 5 10
    /// 11 20 there, 1 2 3 4 5 here).
    const DENSE_TAGS_OUT_OF_ORDER: &str = r#"$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
2 5 1 5
3 2 0 2
5
4
1 1 1
0 0 1
3 1 0 3
3
1
2
0 1 0
0 0 0
1 0 0
$EndNodes
$Elements
1 2 1 2
3 1 4 2
1 1 2 3 4
2 2 4 3 5
$EndElements
"#;

    #[test]
    fn node_tags_without_gaps_in_any_block_order_keep_their_coordinates() {
        let dir = tempfile::tempdir().unwrap();
        let m = read_msh(&write(&dir, DENSE_TAGS_OUT_OF_ORDER)).unwrap();
        let want = [
            (1, [0.0, 0.0, 0.0]),
            (2, [1.0, 0.0, 0.0]),
            (3, [0.0, 1.0, 0.0]),
            (4, [0.0, 0.0, 1.0]),
            (5, [1.0, 1.0, 1.0]),
        ];
        for (tag, x) in want {
            assert_eq!(
                m.mesh.nodes[m.node_index[&tag]],
                Point3::from(x),
                "tag {tag}"
            );
        }
        let sparse = read_msh(&write(&dir, TWO_TETS)).unwrap();
        let volumes = |m: &MshMesh| (0..2).map(|e| m.mesh.volume(e)).collect::<Vec<_>>();
        assert_eq!(volumes(&m), volumes(&sparse));
        // The binary header's largest tag is raised in place, byte order kept.
        let binary = std::fs::read(fixture("gmsh_cube_tet4_binary.msh")).unwrap();
        let raised = with_node_tags_kept(&binary).unwrap();
        assert_eq!(raised.len(), binary.len());
        let at = (0..binary.len()).find(|&i| binary[i] != raised[i]).unwrap();
        assert_eq!(raised[at], binary[at] + 1);
        assert!(binary[at + 1..] == raised[at + 1..]);
        // With a carry, in either byte order: 255 → 256.
        for little in [true, false] {
            let mut head = b"$MeshFormat\n4.1 1 8\n".to_vec();
            let one = if little {
                1i32.to_le_bytes()
            } else {
                1i32.to_be_bytes()
            };
            head.extend_from_slice(&one);
            head.extend_from_slice(b"\n$EndMeshFormat\n$Nodes\n");
            let at = head.len();
            for v in [1u64, 255, 1, 255] {
                head.extend(if little {
                    v.to_le_bytes()
                } else {
                    v.to_be_bytes()
                });
            }
            let raised = with_node_tags_kept(&head).unwrap();
            let max: [u8; 8] = raised[at + 24..at + 32].try_into().unwrap();
            let max = if little {
                u64::from_le_bytes(max)
            } else {
                u64::from_be_bytes(max)
            };
            assert_eq!(max, 256, "little-endian {little}");
            assert_eq!(raised[..at + 24], head[..at + 24]);
        }
    }

    #[test]
    fn nodes_no_tetrahedron_uses_are_left_out() {
        // TWO_TETS with a sixth node (tag 7) in a block of its own, used by
        // no element.
        let text = TWO_TETS
            .replace(
                "$Nodes\n1 5 1 20\n",
                "$Nodes\n2 6 1 20\n0 9 0 1\n7\n5 5 5\n",
            )
            .replace("$Entities\n0 0 1 1\n", "$Entities\n1 0 1 1\n9 5 5 5 0\n");
        let dir = tempfile::tempdir().unwrap();
        let m = read_msh(&write(&dir, &text)).unwrap();
        let plain = read_msh(&write(&dir, TWO_TETS)).unwrap();
        assert_eq!(m.notes.unused_nodes, 1);
        assert_eq!(plain.notes.unused_nodes, 0);
        assert_eq!(m.mesh.nodes, plain.mesh.nodes);
        assert_eq!(m.mesh.cells, plain.mesh.cells);
        assert_eq!(m.node_index, plain.node_index);
        assert!(!m.node_index.contains_key(&7));
    }

    fn tet_is_negative(m: &TetMesh, v: [usize; 4]) -> bool {
        crate::mesh::tet_volume(&v.map(|i| m.nodes[i])) < 0.0
    }

    /// One 10-node tet in gmsh's order (node 8 on edge 2–3, node 9 on 1–3),
    /// written negatively oriented (vertices 1 and 2 exchanged).
    const ONE_TET10: &str = r#"$MeshFormat
4.1 0 8
$EndMeshFormat
$Nodes
1 10 1 10
3 1 0 10
1
2
3
4
5
6
7
8
9
10
0 0 0
0 1 0
1 0 0
0 0 1
0 0.5 0
0.5 0.5 0
0.5 0 0
0 0 0.5
0.5 0 0.5
0 0.5 0.5
$EndNodes
$Elements
1 1 1 1
3 1 11 1
1 1 2 3 4 5 6 7 8 9 10
$EndElements
"#;

    #[test]
    fn tet10_from_gmsh_order_is_vtk_order_and_positive() {
        let dir = tempfile::tempdir().unwrap();
        let m = read_msh(&write(&dir, ONE_TET10)).unwrap();
        assert_eq!(m.mesh.kind, ElementKind::Tet10);
        assert!(m.mesh.volume(0) > 0.0);
        assert_midnodes_on_edges(&m.mesh, 0.0);
        assert!(m.physical_names.is_empty() && m.physical_tags(0).is_empty());
    }

    #[test]
    fn curved_tet10_mid_nodes_are_put_on_their_edges_and_a_shared_one_refused() {
        // A cylinder meshed by gmsh with order 2 (mid-nodes of boundary edges
        // on the cylinder) and its twin with `Mesh.SecondOrderLinear = 1`.
        let curved = read_msh(&fixture("gmsh_cylinder_tet10_curved.msh")).unwrap();
        let straight = read_msh(&fixture("gmsh_cylinder_tet10_straight.msh")).unwrap();
        assert!(
            curved.notes.straightened.mid_nodes > 0 && curved.notes.straightened.largest > 1e-4
        );
        assert_eq!(straight.notes, MeshNotes::default());
        assert_midnodes_on_edges(&curved.mesh, 1e-15);
        assert_eq!(curved.mesh.cells, straight.mesh.cells);
        for (p, q) in curved.mesh.nodes.iter().zip(&straight.mesh.nodes) {
            assert!((p - q).norm() <= 1e-15, "{p} {q}");
        }
        // A vertex given as a mid-node: one line naming the node.
        let dir = tempfile::tempdir().unwrap();
        let bad = ONE_TET10.replace("1 1 2 3 4 5 6 7 8 9 10", "1 1 2 3 4 5 6 7 8 9 1");
        let err = read_msh(&write(&dir, &bad)).unwrap_err().to_string();
        assert!(
            err.contains("node 1 is the mid-node of two edges") && !err.contains('\n'),
            "{err}"
        );
    }

    #[test]
    fn gmsh_written_tet10_ascii_and_binary_agree() {
        // Unit cube meshed by gmsh 4.8 with order 2, physical volume "body" (tag 1)
        // and physical surface "bottom" (tag 2): see tests/fixtures/README.md.
        let a = read_msh(&fixture("gmsh_cube_tet10_ascii.msh")).unwrap();
        let b = read_msh(&fixture("gmsh_cube_tet10_binary.msh")).unwrap();
        for m in [&a, &b] {
            assert_eq!(m.mesh.kind, ElementKind::Tet10);
            assert!(m.mesh.n_elements() > 0);
            assert!((0..m.mesh.n_elements()).all(|e| m.mesh.volume(e) > 0.0));
            let total: f64 = (0..m.mesh.n_elements()).map(|e| m.mesh.volume(e)).sum();
            assert!((total - 1.0).abs() < 1e-12, "volume {total}");
            assert_midnodes_on_edges(&m.mesh, 1e-12);
            let body = m.physical_tag(3, "body").unwrap();
            assert_eq!(m.elements_in_physical(body).len(), m.mesh.n_elements());
            assert!(m.physical_tag(2, "bottom").is_some());
        }
        // gmsh writes ASCII coordinates with 16 digits, binary ones exactly.
        assert_eq!(a.mesh.n_nodes(), b.mesh.n_nodes());
        for (p, q) in a.mesh.nodes.iter().zip(&b.mesh.nodes) {
            assert!((p - q).norm() < 1e-15);
        }
        assert_eq!(a.mesh.cells, b.mesh.cells);
        assert_eq!(a.node_index, b.node_index);
        assert_eq!(a.physical_names, b.physical_names);
    }

    #[test]
    fn gmsh_written_tet4_binary_reads() {
        let m = read_msh(&fixture("gmsh_cube_tet4_binary.msh")).unwrap();
        assert_eq!(m.mesh.kind, ElementKind::Tet4);
        let total: f64 = (0..m.mesh.n_elements()).map(|e| m.mesh.volume(e)).sum();
        assert!((total - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_files_give_clear_errors_not_panics() {
        let dir = tempfile::tempdir().unwrap();
        let cases: Vec<(String, &str)> = vec![
            (
                TWO_TETS.replace("2 5 11 10 20", "2 5 11 10 99"),
                "missing node 99",
            ),
            ("garbage".into(), "not a readable MSH"),
            (String::new(), "not a readable MSH"),
            // Only the triangle: no tets.
            (
                TWO_TETS
                    .replace("2 3 1 9", "1 1 9 9")
                    .replace("3 2 4 2\n1 1 5 10 11\n2 5 11 10 20\n", ""),
                "no tetrahedra",
            ),
            (TWO_TETS.replace("0 0 1\n1 1 1", "0 0 1\n1 1 nan"), ""),
            (TWO_TETS.replace("\n11\n20\n", "\n11\n11\n"), "twice"),
            (
                TWO_TETS.replace("1 0 0\n0 1 0", "1 0 0\n2 0 0"),
                "zero volume",
            ),
            (
                TWO_TETS.replace("3 7 \"body\"", "3 7 body"),
                "$PhysicalNames",
            ),
            (
                TWO_TETS.replace("$PhysicalNames\n2", "$PhysicalNames\n3"),
                "announces",
            ),
            (TWO_TETS.replace("4.1 0 8", "2.2 0 8"), ""),
            // Parametric nodes (gmsh's `Mesh.SaveParametric = 1`).
            (
                TWO_TETS.replace("3 2 0 5", "3 2 1 5"),
                "in node entity block (1 of 1), in Parsing of parametric nodes is not supported yet",
            ),
        ];
        for (text, what) in cases {
            let p = write(&dir, &text);
            let err = read_msh(&p).unwrap_err().to_string();
            assert!(err.contains("m.msh") && !err.contains('\n'), "{err}");
            assert!(err.contains(what), "expected `{what}` in: {err}");
        }
        let err = read_msh(&dir.path().join("missing.msh")).unwrap_err();
        assert!(matches!(err, IoError::Os { .. }), "{err}");
    }

    #[test]
    fn truncated_files_never_panic() {
        let dir = tempfile::tempdir().unwrap();
        for source in [
            TWO_TETS.as_bytes().to_vec(),
            std::fs::read(fixture("gmsh_cube_tet4_binary.msh")).unwrap(),
        ] {
            for cut in (0..source.len()).step_by(7) {
                let p = dir.path().join("t.msh");
                std::fs::write(&p, &source[..cut]).unwrap();
                let _ = read_msh(&p);
            }
        }
    }
}

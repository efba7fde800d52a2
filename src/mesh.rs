//! Tetrahedral meshes: the structured box mesher, Tet4 → Tet10 upgrade, and
//! the geometric queries the rest of the solver needs.
//!
//! Node ordering of a Tet10 (the VTK `QUADRATIC_TETRA` order, also used in
//! `refs/out`): vertices 0–3, then the edge mid-nodes
//! 4:(0,1) 5:(1,2) 6:(0,2) 7:(0,3) 8:(1,3) 9:(2,3).

use nalgebra::{Matrix3, Point3, Vector3};
use std::collections::HashMap;

/// Element kind of a mesh: linear or quadratic tetrahedra.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ElementKind {
    Tet4,
    Tet10,
}

impl ElementKind {
    /// Nodes per element.
    pub const fn nodes(self) -> usize {
        match self {
            ElementKind::Tet4 => 4,
            ElementKind::Tet10 => 10,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ElementKind::Tet4 => "tet4",
            ElementKind::Tet10 => "tet10",
        }
    }
}

/// Vertex pairs of the six Tet10 edge mid-nodes, in node order 4..10.
pub const TET10_EDGES: [(usize, usize); 6] = [(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)];

/// Tet10 mid-nodes off their edge's midpoint by more than this fraction of
/// the edge's length are moved onto it ([`TetMesh::straighten_edges`]):
/// gmsh writes ASCII coordinates with 16 digits, a straight edge's mid-node
/// is off by round-off.
pub const MID_NODE_TOUCH: f64 = 1e-9;

/// What [`TetMesh::straighten_edges`] moved.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Straightened {
    /// Mid-nodes moved onto their edges' midpoints.
    pub mid_nodes: usize,
    /// The largest move (length units of the mesh).
    pub largest: f64,
    /// The largest move over its edge's length.
    pub largest_relative: f64,
}

/// A tetrahedral mesh. `cells` holds `kind.nodes()` node indices per element,
/// flattened; the first four of each element are its vertices, positively
/// oriented (`(x1−x0)×(x2−x0)·(x3−x0) > 0`). Tet10 elements are
/// straight-sided, their mid-nodes at their edges' midpoints (the gmsh reader
/// puts them there: [`TetMesh::straighten_edges`]).
#[derive(Debug, Clone)]
pub struct TetMesh {
    pub kind: ElementKind,
    pub nodes: Vec<Point3<f64>>,
    pub cells: Vec<usize>,
}

impl TetMesh {
    pub fn n_elements(&self) -> usize {
        self.cells.len() / self.kind.nodes()
    }

    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Node indices of element `e`.
    pub fn element(&self, e: usize) -> &[usize] {
        let n = self.kind.nodes();
        &self.cells[e * n..(e + 1) * n]
    }

    /// The four vertex indices of element `e`.
    pub fn vertices(&self, e: usize) -> [usize; 4] {
        let c = self.element(e);
        [c[0], c[1], c[2], c[3]]
    }

    /// The four vertex positions of element `e`.
    pub fn vertex_points(&self, e: usize) -> [Point3<f64>; 4] {
        self.vertices(e).map(|i| self.nodes[i])
    }

    /// Element `e`'s vertex indices in ascending order: the order its
    /// integration cells are built in (splits by a cut, refinements towards
    /// a front, collapsed rules), so that neither the listing of its nodes
    /// nor the handedness of the coordinates changes its quadrature.
    pub fn canonical_vertices(&self, e: usize) -> [usize; 4] {
        let mut v = self.vertices(e);
        v.sort_unstable();
        v
    }

    /// The positions of [`TetMesh::canonical_vertices`].
    pub fn canonical_points(&self, e: usize) -> [Point3<f64>; 4] {
        self.canonical_vertices(e).map(|i| self.nodes[i])
    }

    /// Signed volume of element `e` (straight-sided).
    pub fn volume(&self, e: usize) -> f64 {
        tet_volume(&self.vertex_points(e))
    }

    /// Axis-aligned bounding box of all nodes.
    pub fn bounding_box(&self) -> (Point3<f64>, Point3<f64>) {
        let mut lo = Point3::from([f64::INFINITY; 3]);
        let mut hi = Point3::from([f64::NEG_INFINITY; 3]);
        for p in &self.nodes {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        (lo, hi)
    }

    /// Characteristic element size: the longest edge of element `e`.
    pub fn element_size(&self, e: usize) -> f64 {
        let p = self.vertex_points(e);
        let mut h: f64 = 0.0;
        for i in 0..4 {
            for j in i + 1..4 {
                h = h.max((p[i] - p[j]).norm());
            }
        }
        h
    }

    /// The median over the elements of their mean edge length (vertex to
    /// vertex): the size h of a mesh meant as uniform. gmsh's meshes of the
    /// seed's beam at characteristic lengths 12 … 3.5 mm measure 0.91 …
    /// 1.30 of it; the unit box of n divisions (6 tets a cube), 1.26 / n.
    /// NaN for a mesh without elements.
    pub fn median_edge_length(&self) -> f64 {
        let mut sizes: Vec<f64> = (0..self.n_elements())
            .map(|e| {
                let p = self.vertex_points(e);
                let mut sum = 0.0;
                for i in 0..4 {
                    for j in i + 1..4 {
                        sum += (p[i] - p[j]).norm();
                    }
                }
                sum / 6.0
            })
            .collect();
        if sizes.is_empty() {
            return f64::NAN;
        }
        let mid = sizes.len() / 2;
        *sizes.select_nth_unstable_by(mid, f64::total_cmp).1
    }

    /// Reorders the vertices of negatively oriented elements (swaps vertices
    /// 1 and 2, and the mid-nodes that go with them) so every volume is positive.
    pub fn orient_positively(&mut self) {
        let n = self.kind.nodes();
        for e in 0..self.n_elements() {
            if self.volume(e) < 0.0 {
                let c = &mut self.cells[e * n..(e + 1) * n];
                c.swap(1, 2);
                if n == 10 {
                    // edges (0,1)<->(0,2), (1,3)<->(2,3); (1,2) and (0,3) stay.
                    c.swap(4, 6);
                    c.swap(8, 9);
                }
            }
        }
    }

    /// Puts every Tet10 mid-node at the midpoint of its edge. Elements here
    /// are straight-sided: their gradients, cut and integration cells come
    /// from their vertices. A mid-node off its edge (gmsh's order 2 on a
    /// curved body places it on the curved boundary) is a point no element
    /// map holds, yet the corotational local displacements Rᵀ(x + d) − x
    /// read it: a rigid rotation then left residual strains, and a static
    /// corotational solve on a curved cylinder moved its probes by 0.3 %
    /// and took 5 Newton iterations a load step instead of 2. Mid-nodes off
    /// by at most [`MID_NODE_TOUCH`] of their edge stay where they are.
    /// A Tet4 mesh is left alone. `Err(node)`: a node that is the mid-node of
    /// two different edges, or a mid-node and a vertex.
    pub fn straighten_edges(&mut self) -> Result<Straightened, usize> {
        let mut done = Straightened::default();
        if self.kind != ElementKind::Tet10 {
            return Ok(done);
        }
        const VERTEX: (usize, usize) = (usize::MAX, usize::MAX);
        const UNSEEN: (usize, usize) = (usize::MAX, 0);
        let mut edge_of = vec![UNSEEN; self.n_nodes()];
        for e in 0..self.n_elements() {
            for &v in &self.element(e)[..4] {
                edge_of[v] = VERTEX;
            }
        }
        for e in 0..self.n_elements() {
            let c = self.element(e);
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                let key = (c[a].min(c[b]), c[a].max(c[b]));
                let mid = c[4 + k];
                match edge_of[mid] {
                    UNSEEN => edge_of[mid] = key,
                    seen if seen == key => {}
                    _ => return Err(mid),
                }
            }
        }
        for (mid, &(a, b)) in edge_of.iter().enumerate() {
            if (a, b) == VERTEX || (a, b) == UNSEEN {
                continue;
            }
            let midpoint = Point3::from((self.nodes[a].coords + self.nodes[b].coords) * 0.5);
            let off = (self.nodes[mid] - midpoint).norm();
            let length = (self.nodes[b] - self.nodes[a]).norm();
            if off > MID_NODE_TOUCH * length {
                self.nodes[mid] = midpoint;
                done.mid_nodes += 1;
                if off > done.largest {
                    done.largest = off;
                }
                done.largest_relative = done.largest_relative.max(off / length);
            }
        }
        Ok(done)
    }

    /// The first Tet10 mid-node off its edge's midpoint by more than
    /// [`MID_NODE_TOUCH`] of the edge: (node, distance, edge length).
    pub fn curved_mid_node(&self) -> Option<(usize, f64, f64)> {
        if self.kind != ElementKind::Tet10 {
            return None;
        }
        (0..self.n_elements()).find_map(|e| {
            let c = self.element(e);
            TET10_EDGES.iter().enumerate().find_map(|(k, &(a, b))| {
                let (pa, pb) = (self.nodes[c[a]], self.nodes[c[b]]);
                let off =
                    (self.nodes[c[4 + k]] - Point3::from((pa.coords + pb.coords) * 0.5)).norm();
                let length = (pb - pa).norm();
                (off > MID_NODE_TOUCH * length).then_some((c[4 + k], off, length))
            })
        })
    }

    /// Tet10 mesh with straight edges: a mid-node on every edge, shared
    /// between the elements around it. A Tet10 mesh is returned unchanged.
    pub fn to_tet10(&self) -> TetMesh {
        if self.kind == ElementKind::Tet10 {
            return self.clone();
        }
        let mut nodes = self.nodes.clone();
        let mut edge_node: HashMap<(usize, usize), usize> = HashMap::new();
        let mut cells = Vec::with_capacity(self.n_elements() * 10);
        for e in 0..self.n_elements() {
            let v = self.vertices(e);
            cells.extend_from_slice(&v);
            for &(a, b) in &TET10_EDGES {
                let key = (v[a].min(v[b]), v[a].max(v[b]));
                let id = *edge_node.entry(key).or_insert_with(|| {
                    nodes.push(Point3::from(
                        (nodes[key.0].coords + nodes[key.1].coords) * 0.5,
                    ));
                    nodes.len() - 1
                });
                cells.push(id);
            }
        }
        TetMesh {
            kind: ElementKind::Tet10,
            nodes,
            cells,
        }
    }

    /// The Tet4 mesh of the vertices (mid-nodes dropped, node numbering kept).
    pub fn corner_cells(&self) -> Vec<[usize; 4]> {
        (0..self.n_elements()).map(|e| self.vertices(e)).collect()
    }

    /// Boundary faces (vertex triples, outward oriented) with their element,
    /// sorted by their vertices.
    pub fn boundary_faces(&self) -> Vec<([usize; 3], usize)> {
        // Every element face by its sorted vertices (a, b, c), bucketed by a
        // (a counting sort), each bucket sorted by (b, c): a face met once is
        // on the boundary. (Sorting all faces' packed keys took 78 ms on
        // 328k Tet4, a hash map of them 0.23 s.) Node and face numbers as
        // u32 where they fit: half the memory the buckets move.
        if self.n_nodes() <= u32::MAX as usize && 4 * self.n_elements() <= u32::MAX as usize {
            self.faces_met_once::<u32>()
        } else {
            self.faces_met_once::<usize>()
        }
    }

    /// [`TetMesh::boundary_faces`] with node and face numbers stored as `I`.
    fn faces_met_once<I: FaceIndex>(&self) -> Vec<([usize; 3], usize)> {
        let n_faces = 4 * self.n_elements();
        let sorted_face = |e: usize, f: &[usize; 3]| {
            let v = self.vertices(e);
            let mut key = [v[f[0]], v[f[1]], v[f[2]]];
            key.sort_unstable();
            key
        };
        let mut start = vec![0usize; self.n_nodes() + 1];
        for e in 0..self.n_elements() {
            for f in &TET_FACES {
                start[sorted_face(e, f)[0] + 1] += 1;
            }
        }
        for i in 0..self.n_nodes() {
            start[i + 1] += start[i];
        }
        let mut next = start.clone();
        let zero = I::from_usize(0);
        let mut rest = vec![(zero, zero, zero); n_faces];
        for e in 0..self.n_elements() {
            for (k, f) in TET_FACES.iter().enumerate() {
                let key = sorted_face(e, f);
                rest[next[key[0]]] = (
                    I::from_usize(key[1]),
                    I::from_usize(key[2]),
                    I::from_usize(4 * e + k),
                );
                next[key[0]] += 1;
            }
        }
        let mut faces = Vec::new();
        for a in 0..self.n_nodes() {
            let bucket = &mut rest[start[a]..start[a + 1]];
            bucket.sort_unstable();
            for (i, &(b, c, face)) in bucket.iter().enumerate() {
                let same = |j: Option<usize>| {
                    j.and_then(|j| bucket.get(j))
                        .is_some_and(|x| (x.0, x.1) == (b, c))
                };
                if !same(i.checked_sub(1)) && !same(Some(i + 1)) {
                    let face = face.to_usize();
                    let (e, f) = (face / 4, TET_FACES[face % 4]);
                    let v = self.vertices(e);
                    faces.push(([v[f[0]], v[f[1]], v[f[2]]], e));
                }
            }
        }
        faces.sort_unstable();
        faces
    }
}

/// Node and face numbers as [`TetMesh::boundary_faces`] stores them.
trait FaceIndex: Copy + Ord {
    fn from_usize(i: usize) -> Self;
    fn to_usize(self) -> usize;
}

impl FaceIndex for u32 {
    fn from_usize(i: usize) -> u32 {
        i as u32
    }
    fn to_usize(self) -> usize {
        self as usize
    }
}

impl FaceIndex for usize {
    fn from_usize(i: usize) -> usize {
        i
    }
    fn to_usize(self) -> usize {
        self
    }
}

/// Faces of a tetrahedron (local vertex indices), each oriented outward for a
/// positively oriented element.
pub const TET_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Signed volume of a tetrahedron.
pub fn tet_volume(p: &[Point3<f64>; 4]) -> f64 {
    let m = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    m.determinant() / 6.0
}

/// Barycentric coordinates of `x` in the tetrahedron `p`.
pub fn barycentric(p: &[Point3<f64>; 4], x: &Point3<f64>) -> Option<[f64; 4]> {
    Some(BarycentricMap::new(p)?.at(x))
}

/// The affine map from points to the barycentric coordinates of one
/// tetrahedron, inverted once for many points ([`barycentric`] per point
/// inverts the same matrix each time; the coordinates are bit for bit the same).
#[derive(Debug, Clone, Copy)]
pub struct BarycentricMap {
    origin: Point3<f64>,
    inverse: Matrix3<f64>,
}

impl BarycentricMap {
    /// `None` for a degenerate tetrahedron.
    pub fn new(p: &[Point3<f64>; 4]) -> Option<BarycentricMap> {
        let m = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
        Some(BarycentricMap {
            origin: p[0],
            inverse: m.try_inverse()?,
        })
    }

    /// Barycentric coordinates of `x`.
    pub fn at(&self, x: &Point3<f64>) -> [f64; 4] {
        let l = self.inverse * (x - self.origin);
        [1.0 - l.x - l.y - l.z, l.x, l.y, l.z]
    }
}

/// Structured mesh of the box `[lo, hi]` with `div` hexahedra per axis, each
/// split into six tetrahedra around its main diagonal (Kuhn / Freudenthal
/// split), so neighbouring hexes share conforming faces. All volumes positive.
pub fn box_mesh(lo: Point3<f64>, hi: Point3<f64>, div: [usize; 3]) -> TetMesh {
    let [nx, ny, nz] = div;
    let h = Vector3::new(
        (hi.x - lo.x) / nx as f64,
        (hi.y - lo.y) / ny as f64,
        (hi.z - lo.z) / nz as f64,
    );
    let id = |i: usize, j: usize, k: usize| i + (nx + 1) * (j + (ny + 1) * k);
    let mut nodes = Vec::with_capacity((nx + 1) * (ny + 1) * (nz + 1));
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                // The last layer is placed exactly on `hi` (no round-off drift).
                let c = |n: usize, d: usize, l: f64, u: f64, s: f64| {
                    if n == d {
                        u
                    } else {
                        l + n as f64 * s
                    }
                };
                nodes.push(Point3::new(
                    c(i, nx, lo.x, hi.x, h.x),
                    c(j, ny, lo.y, hi.y, h.y),
                    c(k, nz, lo.z, hi.z, h.z),
                ));
            }
        }
    }
    // The six paths from corner (0,0,0) to (1,1,1), one axis at a time.
    const PATHS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let mut cells = Vec::with_capacity(nx * ny * nz * 24);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                for path in PATHS {
                    let mut c = [i, j, k];
                    let mut tet = [id(c[0], c[1], c[2]); 4];
                    for (s, &axis) in path.iter().enumerate() {
                        c[axis] += 1;
                        tet[s + 1] = id(c[0], c[1], c[2]);
                    }
                    cells.extend_from_slice(&tet);
                }
            }
        }
    }
    let mut mesh = TetMesh {
        kind: ElementKind::Tet4,
        nodes,
        cells,
    };
    mesh.orient_positively();
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mesh_volumes_are_positive_and_add_up() {
        let m = box_mesh(Point3::origin(), Point3::new(1.0, 2.0, 3.0), [2, 3, 4]);
        assert_eq!(m.n_elements(), 2 * 3 * 4 * 6);
        assert_eq!(m.n_nodes(), 3 * 4 * 5);
        let total: f64 = (0..m.n_elements()).map(|e| m.volume(e)).sum();
        assert!((0..m.n_elements()).all(|e| m.volume(e) > 0.0));
        assert!((total - 6.0).abs() < 1e-12);
    }

    #[test]
    fn box_mesh_is_conforming() {
        // Every interior face is shared by exactly two elements: the boundary
        // faces are then exactly the 2 triangles per boundary quad.
        let m = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [3, 2, 2]);
        let b = m.boundary_faces();
        assert_eq!(b.len(), 2 * 2 * (3 * 2 + 2 * 2 + 3 * 2));
        // The faces a count of every face finds (a hash map), each outward:
        // its element's fourth vertex lies behind it.
        let mut count = std::collections::HashMap::new();
        for e in 0..m.n_elements() {
            let v = m.vertices(e);
            for f in TET_FACES {
                let mut key = f.map(|k| v[k]);
                key.sort_unstable();
                count.entry(key).or_insert((0, [0; 3], e)).0 += 1;
                count.get_mut(&key).unwrap().1 = f.map(|k| v[k]);
            }
        }
        let mut once: Vec<([usize; 3], usize)> = count
            .values()
            .filter(|(n, _, _)| *n == 1)
            .map(|&(_, f, e)| (f, e))
            .collect();
        once.sort_unstable();
        assert_eq!(once, b);
        // Numbers stored as usize (meshes beyond u32) find the same faces.
        assert_eq!(m.faces_met_once::<usize>(), b);
        for (f, e) in &b {
            let p = f.map(|i| m.nodes[i]);
            let other = m.vertices(*e).into_iter().find(|i| !f.contains(i)).unwrap();
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            assert!(n.dot(&(m.nodes[other] - p[0])) < 0.0, "{f:?} of {e}");
        }
    }

    #[test]
    fn tet10_shares_edge_nodes() {
        let m = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [1, 1, 1]);
        let q = m.to_tet10();
        // A cube split into 6 tets has 19 edges: 12 sides, 6 face diagonals, 1 main diagonal.
        assert_eq!(q.n_nodes(), 8 + 19);
        for e in 0..q.n_elements() {
            let c = q.element(e);
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                let mid = (q.nodes[c[a]].coords + q.nodes[c[b]].coords) * 0.5;
                assert!((q.nodes[c[4 + k]].coords - mid).norm() < 1e-15);
            }
        }
    }

    #[test]
    fn orientation_fix_keeps_tet10_midnodes_on_their_edges() {
        let m = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [1, 1, 1]);
        let mut q = m.to_tet10();
        // Flip every element, then fix it again.
        for e in 0..q.n_elements() {
            let c = &mut q.cells[e * 10..e * 10 + 10];
            c.swap(1, 2);
            c.swap(4, 6);
            c.swap(8, 9);
        }
        assert!((0..q.n_elements()).all(|e| q.volume(e) < 0.0));
        q.orient_positively();
        for e in 0..q.n_elements() {
            assert!(q.volume(e) > 0.0);
            let c = q.element(e);
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                let mid = (q.nodes[c[a]].coords + q.nodes[c[b]].coords) * 0.5;
                assert!((q.nodes[c[4 + k]].coords - mid).norm() < 1e-15);
            }
        }
    }

    #[test]
    fn straightening_puts_mid_nodes_at_their_edges_and_refuses_a_node_on_two_edges() {
        let straight = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [2, 1, 1]).to_tet10();
        assert_eq!(straight.curved_mid_node(), None);
        let mut q = straight.clone();
        assert_eq!(q.straighten_edges(), Ok(Straightened::default()));
        // Bow two mid-nodes out, and one by round-off (left where it is).
        let n4 = straight.n_nodes() - 1;
        let (a, b) = (straight.element(0)[4], straight.element(3)[9]);
        q.nodes[a].x += 0.05;
        q.nodes[b].z -= 0.2;
        q.nodes[n4].y *= 1.0 + 1e-14;
        assert!(q.curved_mid_node().is_some());
        let done = q.straighten_edges().unwrap();
        assert_eq!(done.mid_nodes, 2);
        assert!((done.largest - 0.2).abs() < 1e-12, "{done:?}");
        assert_eq!(q.curved_mid_node(), None);
        for (p, r) in q.nodes.iter().zip(&straight.nodes) {
            assert!((p - r).norm() <= 1e-14);
        }
        // A mid-node given to another edge of another element.
        let mut bad = straight.clone();
        let other = bad.element(1)[5];
        bad.cells[4] = other;
        let want = other;
        assert!(bad.cells[..4].iter().all(|&v| v != want));
        assert_eq!(bad.straighten_edges(), Err(want));
        // Tet4: nothing to do.
        let mut t4 = box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [1, 1, 1]);
        assert_eq!(t4.straighten_edges(), Ok(Straightened::default()));
    }
}

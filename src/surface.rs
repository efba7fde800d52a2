//! Cut surfaces from triangle meshes (ASCII/binary STL, gmsh `.msh`
//! triangles): the level set Λ of seed eq. (72)–(73) as the signed distance
//! to the triangles, found through an R-tree (no scan over all triangles per
//! node).
//!
//! Rules:
//! - The closest point c of x on the surface is found in the R-tree. Where c
//!   lies inside a triangle, on an inner edge or at an inner vertex, Λ(x) =
//!   ±|x − c|, the sign that of (x − c)·n for the angle-weighted
//!   pseudo-normal n of that feature (Bærentzen & Aanæs 2005), so the sign is
//!   right on both sides of edges and vertices of a curved surface.
//! - Where c lies on the surface's boundary (a boundary edge or vertex), Λ(x)
//!   = (x − c)·n: the distance to the tangent plane there, i.e. the surface
//!   extended across its boundary by its tangent planes. For a flat surface
//!   this is the distance to its plane everywhere, the same Λ as the planar
//!   patch of [`crate::cut::PlanarPatch`], which is what makes a patch written
//!   as triangles give the same cut set-up.
//! - `overlaps` and `contains` are the patch's tests done in the plane of each
//!   triangle near the points, in lengths (separating axes and edge lines in
//!   orthonormal plane coordinates, one touch for every surface:
//!   [`crate::cut::SECTION_TOUCH`]), so a section polygon overlaps the
//!   surface when it overlaps one of its triangles. (A section overlapping
//!   the surface by a few touches only at a corner where several triangles
//!   meet can overlap each of them by less: taken for touching there.)
//! - `boundary` is the boundary edges of the triangle mesh (edges of one
//!   triangle): the front, where inside the body.

use crate::cut::{convex_contains, convex_overlap, CutSurface, PlaneFrame};
use nalgebra::{Point3, Vector3};
use rstar::{PointDistance, RTree, RTreeObject, AABB};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    #[error("{file}: cannot read: {source}")]
    Read {
        file: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: {message}")]
    Invalid { file: PathBuf, message: String },
    #[error("{file}: unsupported surface format (expected .stl or .msh)")]
    Format { file: PathBuf },
}

/// A point's closest point on a surface: its triangle, the point, where on
/// the triangle.
type Closest = (usize, Point3<f64>, Feature);

/// Where the closest point lies on a triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Feature {
    Face,
    /// Local edge k: vertices k and (k+1) % 3.
    Edge(usize),
    /// Local vertex k.
    Vertex(usize),
}

/// A triangle in the R-tree.
#[derive(Debug, Clone)]
struct Tri {
    index: usize,
    p: [Point3<f64>; 3],
}

impl RTreeObject for Tri {
    type Envelope = AABB<[f64; 3]>;
    fn envelope(&self) -> Self::Envelope {
        let lo = [0, 1, 2].map(|k| self.p.iter().map(|q| q[k]).fold(f64::INFINITY, f64::min));
        let hi = [0, 1, 2].map(|k| {
            self.p
                .iter()
                .map(|q| q[k])
                .fold(f64::NEG_INFINITY, f64::max)
        });
        AABB::from_corners(lo, hi)
    }
}

impl PointDistance for Tri {
    fn distance_2(&self, point: &[f64; 3]) -> f64 {
        let x = Point3::from(*point);
        let (c, _) = closest_point(&self.p, &x);
        (x - c).norm_squared()
    }
}

/// Closest point of triangle `p` to `x` and the feature it lies on
/// (Ericson, Real-Time Collision Detection, 5.1.5).
fn closest_point(p: &[Point3<f64>; 3], x: &Point3<f64>) -> (Point3<f64>, Feature) {
    let (a, b, c) = (p[0], p[1], p[2]);
    let ab = b - a;
    let ac = c - a;
    let ap = x - a;
    let d1 = ab.dot(&ap);
    let d2 = ac.dot(&ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = x - b;
    let d3 = ab.dot(&bp);
    let d4 = ac.dot(&bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Feature::Edge(0));
    }
    let cp = x - c;
    let d5 = ab.dot(&cp);
    let d6 = ac.dot(&cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let denom = 1.0 / (va + vb + vc);
    let v = vb * denom;
    let w = vc * denom;
    (a + ab * v + ac * w, Feature::Face)
}

/// The boundary edges' sides: chains of boundary edges that continue each
/// other in a straight line (at a vertex with two boundary edges, opposite
/// directions within 1e-9 rad). Returns each boundary edge's side, each
/// side's neighbours (the sides at its ends, itself included), and each
/// boundary vertex's boundary edges.
#[allow(clippy::type_complexity)]
fn boundary_sides(
    vertices: &[Point3<f64>],
    edges: &HashMap<(usize, usize), (Vector3<f64>, bool)>,
) -> (
    HashMap<(usize, usize), usize>,
    Vec<Vec<usize>>,
    HashMap<usize, Vec<(usize, usize)>>,
) {
    let mut boundary: Vec<(usize, usize)> = edges
        .iter()
        .filter(|(_, &(_, b))| b)
        .map(|(&k, _)| k)
        .collect();
    boundary.sort_unstable();
    let index: HashMap<(usize, usize), usize> =
        boundary.iter().enumerate().map(|(n, &k)| (k, n)).collect();
    let mut at: HashMap<usize, Vec<(usize, usize)>> = HashMap::new();
    for &(i, j) in &boundary {
        at.entry(i).or_default().push((i, j));
        at.entry(j).or_default().push((i, j));
    }
    // Union–find over collinear continuations.
    let mut parent: Vec<usize> = (0..boundary.len()).collect();
    fn root(parent: &mut [usize], mut a: usize) -> usize {
        while parent[a] != a {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        a
    }
    for (&v, es) in &at {
        if let [e, f] = es.as_slice() {
            let other = |(i, j): (usize, usize)| if i == v { j } else { i };
            let (a, b) = (
                vertices[other(*e)] - vertices[v],
                vertices[other(*f)] - vertices[v],
            );
            if a.dot(&b) < 0.0 && a.cross(&b).norm() <= 1e-9 * a.norm() * b.norm() {
                let (ra, rb) = (root(&mut parent, index[e]), root(&mut parent, index[f]));
                parent[ra] = rb;
            }
        }
    }
    let mut id = HashMap::new();
    let mut side = vec![0; boundary.len()];
    for n in 0..boundary.len() {
        let r = root(&mut parent, n);
        let next = id.len();
        side[n] = *id.entry(r).or_insert(next);
    }
    let mut neighbours: Vec<Vec<usize>> = (0..id.len()).map(|s| vec![s]).collect();
    for es in at.values() {
        for e in es {
            for f in es {
                let (se, sf) = (side[index[e]], side[index[f]]);
                if !neighbours[se].contains(&sf) {
                    neighbours[se].push(sf);
                }
            }
        }
    }
    let side_of = boundary
        .iter()
        .enumerate()
        .map(|(n, &k)| (k, side[n]))
        .collect();
    (side_of, neighbours, at)
}

/// The triangles wound alike across every edge two of them share (each
/// such edge traversed once each way), so that their normals, and with
/// them the sign of φ, agree: an STL whose triangles are wound either way
/// (a surface drawn or exported without care, or solids joined from files
/// of both conventions) is the surface its consistent twin is. Each
/// connected part keeps the winding most of its triangles have. Errors: a
/// surface that cannot be wound alike (one-sided, as a Möbius strip).
/// Edges in more than two triangles are left to [`TriangleSurface::new`]'s
/// check.
fn oriented(mut triangles: Vec<[usize; 3]>) -> Result<Vec<[usize; 3]>, String> {
    // Per edge (low, high): its triangles, and whether each runs low → high.
    let mut by_edge: HashMap<(usize, usize), Vec<(usize, bool)>> = HashMap::new();
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (i, j) = (tri[k], tri[(k + 1) % 3]);
            by_edge.entry(edge_key(i, j)).or_default().push((t, i < j));
        }
    }
    let mut flip: Vec<Option<bool>> = vec![None; triangles.len()];
    for first in 0..triangles.len() {
        if flip[first].is_some() {
            continue;
        }
        flip[first] = Some(false);
        let mut part = vec![first];
        let mut queue = vec![first];
        while let Some(t) = queue.pop() {
            let tri = triangles[t];
            for k in 0..3 {
                let (i, j) = (tri[k], tri[(k + 1) % 3]);
                let shared = &by_edge[&edge_key(i, j)];
                if shared.len() != 2 {
                    continue;
                }
                let forward =
                    |u: usize, f: bool| shared.iter().find(|s| s.0 == u).map(|s| s.1 != f);
                let t_flip = flip[t].unwrap_or(false);
                for &(u, _) in shared.iter().filter(|s| s.0 != t) {
                    // Wound alike: the two run the edge opposite ways.
                    let want = forward(t, t_flip) == forward(u, false);
                    match flip[u] {
                        None => {
                            flip[u] = Some(want);
                            part.push(u);
                            queue.push(u);
                        }
                        Some(f) if f != want => {
                            return Err(format!(
                                "triangles {t} and {u} cannot be wound alike (a one-sided surface)"
                            ));
                        }
                        Some(_) => {}
                    }
                }
            }
        }
        let flipped = part.iter().filter(|&&t| flip[t] == Some(true)).count();
        if 2 * flipped > part.len() {
            for &t in &part {
                flip[t] = flip[t].map(|f| !f);
            }
        }
    }
    for (tri, f) in triangles.iter_mut().zip(flip) {
        if f == Some(true) {
            tri.swap(1, 2);
        }
    }
    Ok(triangles)
}

/// A point's coordinates as bits (a key for exact lookups).
fn bits(p: &Point3<f64>) -> [u64; 3] {
    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
}

fn edge_key(i: usize, j: usize) -> (usize, usize) {
    (i.min(j), i.max(j))
}

/// A cut surface given as triangles (open or closed, manifold: every edge in
/// one or two triangles).
#[derive(Debug, Clone)]
pub struct TriangleSurface {
    pub vertices: Vec<Point3<f64>>,
    pub triangles: Vec<[usize; 3]>,
    /// Unit normal per triangle ((p1 − p0) × (p2 − p0), normalised).
    normals: Vec<Vector3<f64>>,
    /// Pseudo-normal per edge (sum of its triangles' normals) and whether it is a boundary edge.
    edges: HashMap<(usize, usize), (Vector3<f64>, bool)>,
    /// Angle-weighted pseudo-normal per vertex, and whether it is on the boundary.
    vertex_normals: Vec<Vector3<f64>>,
    vertex_on_boundary: Vec<bool>,
    /// Per boundary edge: the unit direction in its triangle's plane,
    /// normal to the edge, into the triangle (the side the surface is on).
    inward: HashMap<(usize, usize), Vector3<f64>>,
    /// Vertex index by its coordinates' bits (front segments are given as
    /// points).
    vertex_at: HashMap<[u64; 3], usize>,
    /// Per boundary edge: its side, a chain of collinear boundary edges (a
    /// planar patch written as many triangles has its four sides back).
    side_of: HashMap<(usize, usize), usize>,
    /// Per side: the sides meeting it at its two ends, itself included.
    side_neighbours: Vec<Vec<usize>>,
    /// Per boundary vertex: its boundary edges.
    boundary_at: HashMap<usize, Vec<(usize, usize)>>,
    tree: RTree<Tri>,
}

impl TriangleSurface {
    /// Builds the surface; `file` names the source in errors. Errors: no
    /// triangle, a non-finite coordinate, a degenerate triangle, an edge in
    /// more than two triangles.
    pub fn new(
        vertices: Vec<Point3<f64>>,
        triangles: Vec<[usize; 3]>,
        file: &Path,
    ) -> Result<TriangleSurface, SurfaceError> {
        let invalid = |message: String| SurfaceError::Invalid {
            file: file.to_path_buf(),
            message,
        };
        if triangles.is_empty() {
            return Err(invalid("contains no triangles".into()));
        }
        if let Some(i) = vertices
            .iter()
            .position(|p| !p.iter().all(|c| c.is_finite()))
        {
            return Err(invalid(format!("vertex {i} has a non-finite coordinate")));
        }
        let scale = {
            let (mut lo, mut hi) = (vertices[0], vertices[0]);
            for p in &vertices {
                lo = lo.inf(p);
                hi = hi.sup(p);
            }
            (hi - lo).norm()
        };
        if let Some(t) = triangles
            .iter()
            .position(|tri| tri.iter().any(|&i| i >= vertices.len()))
        {
            return Err(invalid(format!("triangle {t} references a missing vertex")));
        }
        let triangles = oriented(triangles).map_err(invalid)?;
        let mut normals = Vec::with_capacity(triangles.len());
        let mut vertex_normals = vec![Vector3::zeros(); vertices.len()];
        let mut count: HashMap<(usize, usize), (Vector3<f64>, usize)> = HashMap::new();
        let mut inward: HashMap<(usize, usize), Vector3<f64>> = HashMap::new();
        for (t, tri) in triangles.iter().enumerate() {
            let p = tri.map(|i| vertices[i]);
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            if n.norm() <= 1e-14 * scale * scale {
                return Err(invalid(format!("triangle {t} is degenerate (zero area)")));
            }
            let n = n.normalize();
            normals.push(n);
            for k in 0..3 {
                let (i, j, l) = (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]);
                let e = count.entry(edge_key(i, j)).or_insert((Vector3::zeros(), 0));
                e.0 += n;
                e.1 += 1;
                // Into the triangle from edge (i, j): towards vertex l.
                let along = vertices[j] - vertices[i];
                let mut w = n.cross(&along).normalize();
                if w.dot(&(vertices[l] - vertices[i])) < 0.0 {
                    w = -w;
                }
                inward.insert(edge_key(i, j), w);
                // Angle at vertex i.
                let (u, w) = (vertices[j] - vertices[i], vertices[l] - vertices[i]);
                let angle = u.angle(&w);
                vertex_normals[i] += angle * n;
            }
        }
        let mut vertex_on_boundary = vec![false; vertices.len()];
        let mut edges = HashMap::with_capacity(count.len());
        for (&(i, j), &(n, c)) in &count {
            if c > 2 {
                return Err(invalid(format!(
                    "edge {i}–{j} is shared by {c} triangles (the surface must be a manifold)"
                )));
            }
            if c == 1 {
                vertex_on_boundary[i] = true;
                vertex_on_boundary[j] = true;
            }
            edges.insert((i, j), (n, c == 1));
        }
        inward.retain(|k, _| edges[k].1);
        let vertex_at = vertices
            .iter()
            .enumerate()
            .map(|(i, p)| (bits(p), i))
            .collect();
        let (side_of, side_neighbours, boundary_at) = boundary_sides(&vertices, &edges);
        for n in &mut vertex_normals {
            if n.norm() > 0.0 {
                *n = n.normalize();
            }
        }
        let tree = RTree::bulk_load(
            triangles
                .iter()
                .enumerate()
                .map(|(index, tri)| Tri {
                    index,
                    p: tri.map(|i| vertices[i]),
                })
                .collect(),
        );
        Ok(TriangleSurface {
            vertices,
            triangles,
            normals,
            edges,
            vertex_normals,
            vertex_on_boundary,
            inward,
            vertex_at,
            side_of,
            side_neighbours,
            boundary_at,
            tree,
        })
    }

    /// Reads an ASCII or binary STL (`.stl`) or the triangles of a gmsh MSH 4.1 file (`.msh`).
    pub fn read(path: &Path) -> Result<TriangleSurface, SurfaceError> {
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("stl") => read_stl(path),
            Some("msh") => read_msh_triangles(path),
            _ => Err(SurfaceError::Format {
                file: path.to_path_buf(),
            }),
        }
    }

    pub fn n_triangles(&self) -> usize {
        self.triangles.len()
    }

    /// The closest point on the surface, its triangle and feature.
    fn closest(&self, x: &Point3<f64>) -> Closest {
        let tri = self
            .tree
            .nearest_neighbor(&[x.x, x.y, x.z])
            .expect("a surface has triangles");
        let (c, f) = closest_point(&tri.p, x);
        (tri.index, c, f)
    }

    /// Whether x is inside the half-plane (in its triangle's plane) of
    /// every front segment on one of the sides `near` (see
    /// `behind_front`). `None` where a front segment is not a boundary edge
    /// of this surface.
    fn inside_front_sides(
        &self,
        x: &Point3<f64>,
        front: &[[Point3<f64>; 2]],
        near: &[usize],
    ) -> Option<bool> {
        for seg in front {
            let (i, j) = (
                self.vertex_at.get(&bits(&seg[0]))?,
                self.vertex_at.get(&bits(&seg[1]))?,
            );
            let key = edge_key(*i, *j);
            if !near.contains(self.side_of.get(&key)?) {
                continue;
            }
            if (x - seg[0]).dot(self.inward.get(&key)?) < 0.0 {
                return Some(false);
            }
        }
        Some(true)
    }

    /// φ at x from its closest point on the surface: the signed distance,
    /// past the boundary the tangent-plane extension across it.
    fn level_set_from(&self, x: &Point3<f64>, (t, c, feature): Closest) -> f64 {
        let tri = self.triangles[t];
        let (normal, boundary) = match feature {
            Feature::Face => (self.normals[t], false),
            Feature::Edge(k) => self.edges[&edge_key(tri[k], tri[(k + 1) % 3])],
            Feature::Vertex(k) => (self.vertex_normals[tri[k]], self.vertex_on_boundary[tri[k]]),
        };
        let r = x - c;
        if boundary {
            // The tangent-plane extension across the boundary.
            let n = normal.normalize();
            n.dot(&r)
        } else {
            let d = r.norm();
            if normal.dot(&r) >= 0.0 {
                d
            } else {
                -d
            }
        }
    }

    /// Whether x is behind the front, from its closest point on the surface.
    fn behind_front_from(
        &self,
        x: &Point3<f64>,
        front: &[[Point3<f64>; 2]],
        (t, _, feature): Closest,
    ) -> bool {
        let tri = self.triangles[t];
        // The boundary edges the closest feature holds (none: behind).
        let at: Vec<(usize, usize)> = match feature {
            Feature::Face => return true,
            Feature::Edge(k) => {
                let key = edge_key(tri[k], tri[(k + 1) % 3]);
                if !self.edges[&key].1 {
                    return true;
                }
                vec![key]
            }
            Feature::Vertex(k) => match self.boundary_at.get(&tri[k]) {
                Some(edges) => edges.clone(),
                None => return true,
            },
        };
        // Closest to the boundary: behind unless past the line (in its
        // triangle's plane) of a front segment on the sides there or on
        // the sides meeting them. The surface runs on across its other
        // boundary (outside the body), so past it is behind, unless also
        // past a front side meeting it; a side holding front is front along
        // its whole line, its pieces outside the body too. That is the
        // planar patch's rule (inside the half-planes of its front edges),
        // where the closest edge's kind alone made ψ change sign inside the
        // body: a skewed patch has a non-front edge's strip reach back past
        // a front edge's line, and a side written as several edges has
        // pieces outside the body that are not front.
        let mut near: Vec<usize> = Vec::new();
        for key in &at {
            if let Some(&side) = self.side_of.get(key) {
                near.extend(&self.side_neighbours[side]);
            }
        }
        self.inside_front_sides(x, front, &near)
            .unwrap_or_else(|| self.contains(x, 0.0))
    }

    /// Triangles whose bounding boxes meet the box [lo − pad, hi + pad].
    fn near(&self, lo: Point3<f64>, hi: Point3<f64>, pad: f64) -> impl Iterator<Item = &Tri> + '_ {
        let env = AABB::from_corners(
            [lo.x - pad, lo.y - pad, lo.z - pad],
            [hi.x + pad, hi.y + pad, hi.z + pad],
        );
        self.tree.locate_in_envelope_intersecting(&env)
    }
}

impl CutSurface for TriangleSurface {
    fn level_set(&self, x: &Point3<f64>) -> f64 {
        self.level_set_from(x, self.closest(x))
    }

    /// Whether a triangle's bounding box meets the cube of half-side
    /// `reach` about x (a box query that stops at the first hit; a nearest
    /// triangle search costs several times more far from the surface).
    fn may_reach(&self, x: &Point3<f64>, reach: f64) -> bool {
        if !reach.is_finite() {
            return true;
        }
        self.near(*x, *x, reach).next().is_some()
    }

    fn level_set_behind(&self, x: &Point3<f64>, front: &[[Point3<f64>; 2]]) -> (f64, bool) {
        let closest = self.closest(x);
        (
            self.level_set_from(x, closest),
            self.behind_front_from(x, front, closest),
        )
    }

    fn overlaps(&self, poly: &[Point3<f64>], reach: f64, touch: f64) -> bool {
        if poly.is_empty() {
            return false;
        }
        let (mut lo, mut hi) = (poly[0], poly[0]);
        for p in poly {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        // Candidates within the polygon's size and its reach: a section of
        // the interpolated, snapped level set can lie a snap off the
        // triangles, more than a small polygon's size.
        let round_off = 1e-12 * (hi.coords.norm() + 1.0);
        let pad = (hi - lo).norm() + reach + round_off;
        // (A section has 3 or 4 corners: its plane coordinates on the stack.)
        let mut stack = [(0.0, 0.0); 8];
        let mut heap = Vec::new();
        let pts: &mut [(f64, f64)] = if poly.len() <= stack.len() {
            &mut stack[..poly.len()]
        } else {
            heap.resize(poly.len(), (0.0, 0.0));
            &mut heap
        };
        let mut overlaps = |tri: &Tri| {
            let a = tri.p[0];
            let frame = PlaneFrame::new(a, &(tri.p[1] - a), &(tri.p[2] - a));
            for (q, x) in pts.iter_mut().zip(poly) {
                *q = frame.at(x);
            }
            convex_overlap(pts, &tri.p.map(|x| frame.at(&x)), touch)
        };
        // The triangles meeting the section's own box first: where the
        // section lies on the surface one of them overlaps it, and the
        // padded query (a superset, so the same answer) runs only where none
        // does. (The padded box of a 4 mm section of a 7200-triangle incision
        // holds hundreds of triangles, tested in the tree's order: a quarter
        // of the cut set-up on 40k Tet4.)
        self.near(lo, hi, reach + round_off).any(&mut overlaps)
            || self.near(lo, hi, pad).any(overlaps)
    }

    fn contains(&self, x: &Point3<f64>, tol: f64) -> bool {
        let (t, c, feature) = self.closest(x);
        let tri = self.triangles[t];
        let on_boundary = match feature {
            Feature::Face => false,
            Feature::Edge(k) => self.edges[&edge_key(tri[k], tri[(k + 1) % 3])].1,
            Feature::Vertex(k) => self.vertex_on_boundary[tri[k]],
        };
        if !on_boundary {
            return true;
        }
        // Near the boundary: in some triangle, or within `tol` of it in its plane.
        let pad = 2.0 * (x - c).norm() + tol + 1e-12 * (x.coords.norm() + 1.0);
        self.near(*x, *x, pad).any(|tri| {
            let a = tri.p[0];
            let frame = PlaneFrame::new(a, &(tri.p[1] - a), &(tri.p[2] - a));
            convex_contains(&tri.p.map(|y| frame.at(&y)), frame.at(x), tol)
        })
    }

    /// Behind the front where the closest point is inside the surface or on
    /// an edge or vertex inside it; nearest its boundary, unless past the
    /// line of a front side there or beside it (see `behind_front_from`).
    fn behind_front(&self, x: &Point3<f64>, front: &[[Point3<f64>; 2]]) -> bool {
        self.behind_front_from(x, front, self.closest(x))
    }

    fn boundary(&self) -> Vec<[Point3<f64>; 2]> {
        let mut out: Vec<(usize, usize)> = self
            .edges
            .iter()
            .filter(|(_, &(_, b))| b)
            .map(|(&k, _)| k)
            .collect();
        out.sort_unstable();
        out.into_iter()
            .map(|(i, j)| [self.vertices[i], self.vertices[j]])
            .collect()
    }
}

/// A triangle surface that measures its level sets at every node (the
/// default [`CutSurface::may_reach`]): the set-up without stand-ins, to
/// compare with (tests) and to time against (benches).
pub struct EveryNode<'a>(pub &'a TriangleSurface);

impl CutSurface for EveryNode<'_> {
    fn level_set(&self, x: &Point3<f64>) -> f64 {
        self.0.level_set(x)
    }
    fn overlaps(&self, poly: &[Point3<f64>], reach: f64, touch: f64) -> bool {
        self.0.overlaps(poly, reach, touch)
    }
    fn contains(&self, x: &Point3<f64>, tol: f64) -> bool {
        self.0.contains(x, tol)
    }
    fn boundary(&self) -> Vec<[Point3<f64>; 2]> {
        self.0.boundary()
    }
    fn behind_front(&self, x: &Point3<f64>, front: &[[Point3<f64>; 2]]) -> bool {
        self.0.behind_front(x, front)
    }
    fn level_set_behind(&self, x: &Point3<f64>, front: &[[Point3<f64>; 2]]) -> (f64, bool) {
        self.0.level_set_behind(x, front)
    }
}

fn read_stl(path: &Path) -> Result<TriangleSurface, SurfaceError> {
    let read_err = |source| SurfaceError::Read {
        file: path.to_path_buf(),
        source,
    };
    let bytes = std::fs::read(path).map_err(read_err)?;
    // stl_io reads the first solid of an ASCII file and stops: each solid
    // is read on its own, and the vertices they share are joined.
    let mut single: Vec<stl_io::Vertex> = Vec::new();
    let mut joined: HashMap<[u32; 3], usize> = HashMap::new();
    let mut triangles: Vec<[usize; 3]> = Vec::new();
    for solid in ascii_solids(&bytes) {
        let mesh = read_one_stl(path, solid)?;
        let index: Vec<usize> = mesh
            .vertices
            .iter()
            .map(|v| {
                *joined.entry(v.0.map(f32::to_bits)).or_insert_with(|| {
                    single.push(*v);
                    single.len() - 1
                })
            })
            .collect();
        triangles.extend(mesh.faces.iter().map(|f| f.vertices.map(|i| index[i])));
    }
    let mut vertices: Vec<Point3<f64>> = single
        .iter()
        .map(|v| Point3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
        .collect();
    if let Some(exact) = ascii_vertices_f64(path, &single, &triangles) {
        vertices = exact;
    }
    TriangleSurface::new(vertices, triangles, path)
}

/// The solids of an ASCII STL (`solid` … `endsolid`, one after another),
/// each from its `solid` line to its `endsolid` line; the whole file where
/// it holds one, or is binary.
fn ascii_solids(bytes: &[u8]) -> Vec<&[u8]> {
    let whole = vec![bytes];
    let Ok(text) = std::str::from_utf8(bytes) else {
        return whole;
    };
    if !text.trim_start().starts_with("solid") {
        return whole;
    }
    let mut solids = Vec::new();
    let (mut start, mut at) = (0, 0);
    for line in text.split_inclusive('\n') {
        at += line.len();
        if line.trim_start().starts_with("endsolid") {
            solids.push(&bytes[start..at]);
            start = at;
        }
    }
    if solids.len() < 2 || !text[start..].trim().is_empty() {
        return whole;
    }
    solids
}

/// One solid (or a binary file) through stl_io, its faults in our words.
fn read_one_stl(path: &Path, bytes: &[u8]) -> Result<stl_io::IndexedMesh, SurfaceError> {
    stl_io::read_stl(&mut std::io::Cursor::new(bytes)).map_err(|e| {
        let empty = std::fs::metadata(path).is_ok_and(|m| m.len() == 0);
        let message = if empty {
            "the file is empty".to_string()
        } else if e.to_string().contains("expected finite") {
            // stl_io's words for a coordinate it read as NaN or infinity.
            "a vertex coordinate is not a finite number (NaN or infinity)".to_string()
        } else if e.kind() == std::io::ErrorKind::UnexpectedEof {
            // stl_io reads what is not ASCII as binary and runs off its end.
            "neither an ASCII STL (solid … endsolid) nor a complete binary one (80-byte header, triangle count, 50 bytes a triangle)".to_string()
        } else {
            format!("not a readable STL file: {e}")
        };
        SurfaceError::Invalid {
            file: path.to_path_buf(),
            message,
        }
    })
}

/// An ASCII STL's vertices at the precision written (`stl_io` reads single
/// precision, the binary format's: a patch 0.4 m long then moved its plane by
/// 3e-8 m). The file's `vertex` lines in order, three a facet as `stl_io`
/// read them, each checked to round to the single-precision value it read;
/// `None` (keep those) for a binary file or any mismatch.
fn ascii_vertices_f64(
    path: &Path,
    single: &[stl_io::Vertex],
    triangles: &[[usize; 3]],
) -> Option<Vec<Point3<f64>>> {
    let text = std::fs::read_to_string(path).ok()?;
    let mut lines = text
        .lines()
        .map(str::trim_start)
        .filter(|l| l.starts_with("vertex"));
    let mut exact: Vec<Option<Point3<f64>>> = vec![None; single.len()];
    for t in triangles {
        for &i in t {
            let mut words = lines.next()?.split_whitespace().skip(1);
            let mut p = [0.0; 3];
            for (c, x) in p.iter_mut().enumerate() {
                *x = words.next()?.parse::<f64>().ok()?;
                if *x as f32 != single[i][c] {
                    return None;
                }
            }
            exact[i].get_or_insert(Point3::from(p));
        }
    }
    if lines.next().is_some() {
        return None;
    }
    exact.into_iter().collect()
}

/// The triangles of a gmsh MSH 4.1 file (every entity; quadrangles split in
/// two, elements of higher order by their corners), through `mshio`.
fn read_msh_triangles(path: &Path) -> Result<TriangleSurface, SurfaceError> {
    let invalid = |message: String| SurfaceError::Invalid {
        file: path.to_path_buf(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|source| SurfaceError::Read {
        file: path.to_path_buf(),
        source,
    })?;
    let file = crate::io::msh::parse_file(&bytes).map_err(invalid)?;
    let nodes = file
        .data
        .nodes
        .as_ref()
        .ok_or_else(|| invalid("no $Nodes section".into()))?;
    let elements = file
        .data
        .elements
        .as_ref()
        .ok_or_else(|| invalid("no $Elements section".into()))?;
    let (vertices, index) = crate::io::msh::read_nodes(nodes).map_err(invalid)?;
    use mshio::ElementType as T;
    let mut triangles = Vec::new();
    for block in &elements.element_blocks {
        // Triangles and quadrangles of any order by their corners (gmsh
        // lists them first): a second-order incision is taken flat between
        // its vertices, as Tet10 elements are straight-sided; a quadrangle
        // is split along its diagonal 0–2.
        let corners = match block.element_type {
            T::Tri3 | T::Tri6 | T::Tri9 | T::Tri10 => 3,
            T::Qua4 | T::Qua8 | T::Qua9 => 4,
            _ => continue,
        };
        for el in &block.elements {
            let mut c = [0; 4];
            for k in 0..corners {
                let tag = *el.nodes.get(k).ok_or_else(|| {
                    invalid(format!(
                        "surface element {} has fewer than {corners} nodes",
                        el.element_tag
                    ))
                })?;
                c[k] = *index.get(&tag).ok_or_else(|| {
                    invalid(format!(
                        "surface element {} references missing node {tag}",
                        el.element_tag
                    ))
                })?;
            }
            triangles.push([c[0], c[1], c[2]]);
            if corners == 4 {
                triangles.push([c[0], c[2], c[3]]);
            }
        }
    }
    let (vertices, triangles) = joined(&vertices, &triangles);
    TriangleSurface::new(vertices, triangles, path)
}

/// The vertices the triangles use, those at the same position joined into
/// one (as an STL's are): a file whose triangles each have nodes of their
/// own (a triangle soup, as an STL converted by meshio is written) is the
/// same surface as one whose triangles share them, not one whose every
/// edge is a boundary.
fn joined(
    vertices: &[Point3<f64>],
    triangles: &[[usize; 3]],
) -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
    let mut at: HashMap<[u64; 3], usize> = HashMap::new();
    let mut kept = Vec::new();
    let mut index = vec![usize::MAX; vertices.len()];
    let joined = triangles
        .iter()
        .map(|t| {
            t.map(|i| {
                if index[i] == usize::MAX {
                    index[i] = *at.entry(bits(&vertices[i])).or_insert_with(|| {
                        kept.push(vertices[i]);
                        kept.len() - 1
                    });
                }
                index[i]
            })
        })
        .collect();
    (kept, joined)
}

/// Writes `triangles` as an ASCII STL (fixtures, blades' swept strips).
pub fn ascii_stl(vertices: &[Point3<f64>], triangles: &[[usize; 3]]) -> String {
    let mut s = String::from("solid surface\n");
    for tri in triangles {
        let p = tri.map(|i| vertices[i]);
        let n = (p[1] - p[0]).cross(&(p[2] - p[0])).normalize();
        s += &format!(
            "  facet normal {:e} {:e} {:e}\n    outer loop\n",
            n.x, n.y, n.z
        );
        for q in p {
            s += &format!("      vertex {:e} {:e} {:e}\n", q.x, q.y, q.z);
        }
        s += "    endloop\n  endfacet\n";
    }
    s += "endsolid surface\n";
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cut::PlanarPatch;

    fn square() -> (PlanarPatch, TriangleSurface) {
        let patch = PlanarPatch {
            origin: Point3::new(-0.5, -0.5, 1.15625),
            u: Vector3::new(1.125, 0.0, 0.0),
            v: Vector3::new(0.0, 2.0, 0.0),
        };
        let o = patch.origin;
        let v = vec![o, o + patch.u, o + patch.u + patch.v, o + patch.v];
        let s = TriangleSurface::new(v, vec![[0, 1, 2], [0, 2, 3]], Path::new("square")).unwrap();
        (patch, s)
    }

    #[test]
    fn a_flat_surface_has_the_level_set_of_its_plane_everywhere() {
        let (patch, s) = square();
        for &x in &[
            Point3::new(0.1, 0.2, 1.3),
            Point3::new(0.9, 0.2, 0.7),  // beyond the front, below
            Point3::new(3.0, -2.0, 1.2), // beyond a corner
            Point3::new(0.0, 0.0, 1.15625),
        ] {
            let (a, b) = (patch.level_set(&x), s.level_set(&x));
            assert!((a - b).abs() <= 1e-15, "{x:?}: {a} vs {b}");
        }
        assert_eq!(s.boundary().len(), 4);
        assert!(s.contains(&Point3::new(0.6, 0.0, 1.15625), 1e-9));
        assert!(!s.contains(&Point3::new(0.7, 0.0, 1.15625), 1e-9));
    }

    #[test]
    fn pseudo_normals_sign_a_folded_surface_right() {
        // Two triangles folded along the x axis (a roof): points above the ridge are +, below −.
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(1.0, 1.0, -0.5),
            Point3::new(0.0, -1.0, -0.5),
        ];
        let s = TriangleSurface::new(v, vec![[0, 1, 2], [1, 0, 3]], Path::new("roof")).unwrap();
        assert!(s.level_set(&Point3::new(0.5, 0.0, 0.3)) > 0.0);
        assert!(s.level_set(&Point3::new(0.5, 0.0, -0.3)) < 0.0);
        // Below the ridge, nearer the ridge than either face plane's foot inside its face.
        assert!(s.level_set(&Point3::new(0.5, 0.01, -0.01)) < 0.0);
        assert!((s.level_set(&Point3::new(0.5, 0.0, 0.3)) - 0.3).abs() < 1e-14);
    }

    #[test]
    fn a_closed_surface_has_the_signed_distance_inside_and_out() {
        // Octahedron |x| + |y| + |z| = 1, outward normals: negative inside.
        let v: Vec<Point3<f64>> = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ]
        .iter()
        .map(|c| Point3::from(*c))
        .collect();
        let mut tris = Vec::new();
        for (x, y) in [(0, 2), (2, 1), (1, 3), (3, 0)] {
            tris.push([x, y, 4]);
            tris.push([y, x, 5]);
        }
        let s = TriangleSurface::new(v, tris, Path::new("octahedron")).unwrap();
        assert!(s.boundary().is_empty());
        let d = 1.0 / 3f64.sqrt();
        assert!((s.level_set(&Point3::origin()) + d).abs() < 1e-15);
        assert!((s.level_set(&Point3::new(1.0, 1.0, 1.0)) - 2.0 * d).abs() < 1e-15);
        // Beyond a vertex and an edge: distance to them, positive.
        assert!((s.level_set(&Point3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-15);
        assert!((s.level_set(&Point3::new(1.0, 1.0, 0.0)) - 0.5f64.sqrt()).abs() < 1e-15);
        assert!(s.level_set(&Point3::new(0.99, 0.0, 0.0)) < 0.0);
    }

    #[test]
    fn non_manifold_and_empty_surfaces_are_errors() {
        let v = vec![
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, -1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        ];
        let e = TriangleSurface::new(
            v.clone(),
            vec![[0, 1, 2], [0, 1, 3], [0, 1, 4]],
            Path::new("fan.stl"),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("fan.stl") && e.contains("3 triangles"), "{e}");
        let e = TriangleSurface::new(v, vec![], Path::new("x.stl"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("no triangles"), "{e}");
    }
}

//! The crack front: the second level set ψ (signed distance to the front
//! measured in the cut surface, negative behind it), the branch functions of
//! the tip enrichment, and quadrature rules collapsed towards the front.
//!
//! Local polar coordinates (METHODS.md): r = √(φ² + ψ²), θ = atan2(φ, ψ), so
//! the cut faces are θ = ±π and the front is r = 0. The branch functions
//! F₁..₄ = √r {sin θ/2, cos θ/2, sin θ/2 sin θ, cos θ/2 sin θ} span the leading
//! (Williams) term of the near-front field; F₁ jumps across the cut.

use crate::mesh::{barycentric, TetMesh};
use nalgebra::{Point3, Vector3};
use rstar::primitives::{GeomWithData, Rectangle};
use rstar::{RTree, AABB};

/// Number of branch functions per tip-enriched node.
pub const N_BRANCH: usize = 4;

/// Values of F₁..₄ at polar coordinates (r, θ).
pub fn branch_values(r: f64, theta: f64) -> [f64; N_BRANCH] {
    let sr = r.sqrt();
    let (s2, c2) = (0.5 * theta).sin_cos();
    let st = theta.sin();
    [sr * s2, sr * c2, sr * s2 * st, sr * c2 * st]
}

/// θ for the level set values (φ, ψ) seen from side `side` of the cut: on the
/// cut (φ = 0, ψ < 0) θ = side·π, so F₁ jumps exactly across the cut faces;
/// φ of the wrong sign (round-off on a cut face) is taken as 0 of that side.
pub fn polar_angle(phi: f64, psi: f64, side: i8) -> f64 {
    let phi = match side {
        1 if phi > 0.0 => phi,
        1 => 0.0,
        -1 if phi < 0.0 => phi,
        -1 => -0.0,
        _ => phi,
    };
    phi.atan2(psi)
}

/// Values and gradients of F₁..₄ at a point where the (linear) level sets
/// have values φ, ψ and gradients ∇φ, ∇ψ, on side `side`:
/// ∇F = ∂F/∂r ∇r + ∂F/∂θ ∇θ, ∇r = (φ∇φ + ψ∇ψ)/r, ∇θ = (ψ∇φ − φ∇ψ)/r².
/// θ as [`polar_angle`], its sines and cosines from φ/r and ψ/r (the half
/// angles without cancellation: cos θ/2 = √((1 + cos θ)/2) where cos θ ≥ 0,
/// sin θ/2 = sin θ / (2 cos θ/2); the other way round where cos θ < 0):
/// no atan2, sine or cosine per point, [`branch_values`] ∘ [`polar_angle`]
/// to round-off (test below).
pub fn branch_with_gradients(
    phi: f64,
    psi: f64,
    grad_phi: &Vector3<f64>,
    grad_psi: &Vector3<f64>,
    side: i8,
) -> ([f64; N_BRANCH], [Vector3<f64>; N_BRANCH]) {
    let r = (phi * phi + psi * psi).sqrt();
    if r == 0.0 {
        return ([0.0; N_BRANCH], [Vector3::zeros(); N_BRANCH]);
    }
    // θ from φ on the side's half plane (φ of the wrong sign, round-off on
    // a cut face, is 0 of that side); r from φ as it is.
    let on_side = match side {
        1 if phi > 0.0 => phi,
        1 => 0.0,
        -1 if phi < 0.0 => phi,
        -1 => -0.0,
        _ => phi,
    };
    let r_side = (on_side * on_side + psi * psi).sqrt();
    let (st, ct) = if r_side > 0.0 {
        (on_side / r_side, psi / r_side)
    } else {
        (0.0, 1.0)
    };
    // θ/2 ∈ [−π/2, π/2]: cos θ/2 ≥ 0, sin θ/2 of θ's sign (φ's, −0 included).
    let (s2, c2) = if ct >= 0.0 {
        let c2 = (0.5 * (1.0 + ct)).sqrt();
        (0.5 * st / c2, c2)
    } else {
        let s2 = (0.5 * (1.0 - ct)).sqrt().copysign(on_side);
        (s2, 0.5 * st / s2)
    };
    let sr = r.sqrt();
    let values = [sr * s2, sr * c2, sr * s2 * st, sr * c2 * st];
    let dr = (grad_phi * phi + grad_psi * psi) / r;
    let dtheta = (grad_phi * psi - grad_psi * phi) / (r * r);
    // (∂F/∂r, ∂F/∂θ) per branch function.
    let partial = [
        (s2 / (2.0 * sr), 0.5 * sr * c2),
        (c2 / (2.0 * sr), -0.5 * sr * s2),
        (s2 * st / (2.0 * sr), sr * (0.5 * c2 * st + s2 * ct)),
        (c2 * st / (2.0 * sr), sr * (-0.5 * s2 * st + c2 * ct)),
    ];
    (values, partial.map(|(a, b)| dr * a + dtheta * b))
}

/// The part of the boundary segments of a cut surface that is crack front:
/// the segments running through the body — through the interior of an
/// element, or along its faces and edges inside the body (a front on mesh
/// faces, e.g. a cut ending on a node line); segments on the body's outer
/// faces or outside it are not front.
pub fn front_segments(mesh: &TetMesh, boundary: &[[Point3<f64>; 2]]) -> Vec<[Point3<f64>; 2]> {
    front_segments_with(mesh, boundary, &element_boxes(mesh))
}

/// [`front_segments`] with the elements' bounding boxes ([`element_boxes`]).
pub fn front_segments_with(
    mesh: &TetMesh,
    boundary: &[[Point3<f64>; 2]],
    boxes: &[(Point3<f64>, Point3<f64>)],
) -> Vec<[Point3<f64>; 2]> {
    // The body's outer faces, in an R*-tree of their bounding boxes: a
    // segment piece on them is not front.
    let outer: Vec<[Point3<f64>; 3]> = mesh
        .boundary_faces()
        .into_iter()
        .map(|(f, _)| f.map(|j| mesh.nodes[j]))
        .collect();
    let tree = RTree::bulk_load(
        outer
            .iter()
            .enumerate()
            .map(|(k, t)| {
                let (lo, hi) = (t[0].inf(&t[1]).inf(&t[2]), t[0].sup(&t[1]).sup(&t[2]));
                GeomWithData::new(Rectangle::from_corners(lo.into(), hi.into()), k)
            })
            .collect(),
    );
    let on_outer = |x: &Point3<f64>, tol: f64| {
        let near = AABB::from_corners(
            [x.x - tol, x.y - tol, x.z - tol],
            [x.x + tol, x.y + tol, x.z + tol],
        );
        tree.locate_in_envelope_intersecting(&near)
            .any(|t| triangle_distance(x, &outer[t.data]) <= tol)
    };
    let spans: Vec<_> = boundary
        .iter()
        .map(|seg| (seg[0].inf(&seg[1]), seg[0].sup(&seg[1])))
        .collect();
    let mut front = vec![false; boundary.len()];
    for_each_box_meeting(boxes, &spans, |e, k| {
        if !front[k] {
            let (lo, hi) = boxes[e];
            let tol = 1e-9 * (hi - lo).norm();
            front[k] = segment_piece_midpoint(&mesh.vertex_points(e), &boundary[k])
                .is_some_and(|m| !on_outer(&m, tol));
        }
    });
    boundary
        .iter()
        .zip(&front)
        .filter(|(_, &f)| f)
        .map(|(seg, _)| *seg)
        .collect()
}

/// Calls `visit(e, k)` for every element box `e` of `boxes` that meets the
/// query box `k` of `queries` (closed boxes, lower and upper corner), once
/// per pair: one pass over the elements, the queries binned in a grid over
/// their union. (Scanning every element per query took 0.14 s for the 240
/// boundary segments of a 7200-triangle surface on 328k Tet4.)
fn for_each_box_meeting(
    boxes: &[(Point3<f64>, Point3<f64>)],
    queries: &[(Point3<f64>, Point3<f64>)],
    mut visit: impl FnMut(usize, usize),
) {
    let Some(first) = queries.first() else {
        return;
    };
    let (lo, hi) = queries
        .iter()
        .fold(*first, |(a, b), (l, h)| (a.inf(l), b.sup(h)));
    // About two queries a cell, at most 64 cells an axis.
    let n = ((queries.len() as f64 / 2.0).cbrt().ceil() as usize).clamp(1, 64);
    let size = (hi - lo) / n as f64;
    let cell = |x: f64, c: usize| -> usize {
        if size[c] > 0.0 {
            (((x - lo[c]) / size[c]).floor().max(0.0) as usize).min(n - 1)
        } else {
            0
        }
    };
    let range = |a: &Point3<f64>, b: &Point3<f64>| -> [(usize, usize); 3] {
        [0, 1, 2].map(|c| (cell(a[c], c), cell(b[c], c)))
    };
    let mut bins: Vec<Vec<usize>> = vec![Vec::new(); n * n * n];
    for (k, (a, b)) in queries.iter().enumerate() {
        let r = range(a, b);
        for i in r[0].0..=r[0].1 {
            for j in r[1].0..=r[1].1 {
                for l in r[2].0..=r[2].1 {
                    bins[(i * n + j) * n + l].push(k);
                }
            }
        }
    }
    let meets = |(a, b): &(Point3<f64>, Point3<f64>), (c, d): &(Point3<f64>, Point3<f64>)| {
        (0..3).all(|i| a[i] <= d[i] && c[i] <= b[i])
    };
    // The last element each query was offered to (a query spans several bins).
    let mut seen = vec![usize::MAX; queries.len()];
    for (e, b) in boxes.iter().enumerate() {
        if !meets(b, &(lo, hi)) {
            continue;
        }
        let r = range(&b.0, &b.1);
        for i in r[0].0..=r[0].1 {
            for j in r[1].0..=r[1].1 {
                for l in r[2].0..=r[2].1 {
                    for &k in &bins[(i * n + j) * n + l] {
                        if seen[k] != e && meets(b, &queries[k]) {
                            seen[k] = e;
                            visit(e, k);
                        }
                    }
                }
            }
        }
    }
}

/// Each element's bounding box (lower, upper corner).
pub fn element_boxes(mesh: &TetMesh) -> Vec<(Point3<f64>, Point3<f64>)> {
    (0..mesh.n_elements())
        .map(|e| {
            let p = mesh.vertex_points(e);
            let lo = p.iter().fold(p[0], |a, b| a.inf(b));
            let hi = p.iter().fold(p[0], |a, b| a.sup(b));
            (lo, hi)
        })
        .collect()
}

/// The front segments with every end where the front leaves the body (the
/// segment continued a little beyond it is in no element) carried on along
/// the segment, by the body's diagonal: the front's continuation outside the
/// body. ψ and the distances to the front are taken to these, so that how
/// far the user's surface runs on outside the body changes nothing inside
/// it (a segment that ends just outside would otherwise give the nodes
/// near the body's face their distance to its end, not to its line).
pub fn extend_front_exits(mesh: &TetMesh, front: &[[Point3<f64>; 2]]) -> Vec<[Point3<f64>; 2]> {
    extend_front_exits_with(mesh, front, &element_boxes(mesh))
}

/// [`extend_front_exits`] with the elements' bounding boxes ([`element_boxes`]).
pub fn extend_front_exits_with(
    mesh: &TetMesh,
    front: &[[Point3<f64>; 2]],
    boxes: &[(Point3<f64>, Point3<f64>)],
) -> Vec<[Point3<f64>; 2]> {
    let (lo, hi) = mesh.bounding_box();
    let diagonal = (hi - lo).norm();
    let step = 1e-6 * diagonal;
    // Each segment's ends continued a step beyond it, and whether they are
    // in the body (in some closed element).
    let ends: Vec<Point3<f64>> = front
        .iter()
        .flat_map(|seg| {
            let d = seg[1] - seg[0];
            let len = d.norm();
            let dir = if len == 0.0 { d } else { d / len };
            [seg[0] - dir * step, seg[1] + dir * step]
        })
        .collect();
    let points: Vec<_> = ends.iter().map(|x| (*x, *x)).collect();
    let mut in_body = vec![false; ends.len()];
    for_each_box_meeting(boxes, &points, |e, k| {
        if !in_body[k] {
            in_body[k] = barycentric(&mesh.vertex_points(e), &ends[k])
                .is_some_and(|l| l.iter().all(|&v| v >= -1e-12));
        }
    });
    front
        .iter()
        .enumerate()
        .map(|(k, seg)| {
            let d = seg[1] - seg[0];
            let len = d.norm();
            if len == 0.0 {
                return *seg;
            }
            let dir = d / len;
            let mut out = *seg;
            if !in_body[2 * k] {
                out[0] = seg[0] - dir * diagonal;
            }
            if !in_body[2 * k + 1] {
                out[1] = seg[1] + dir * diagonal;
            }
            out
        })
        .collect()
}

/// The midpoint of the piece of segment `seg` inside the closed tet `p`
/// (every barycentric coordinate above −1e-9), if that piece has a
/// positive length.
fn segment_piece_midpoint(p: &[Point3<f64>; 4], seg: &[Point3<f64>; 2]) -> Option<Point3<f64>> {
    let (la, lb) = (barycentric(p, &seg[0])?, barycentric(p, &seg[1])?);
    let eps = 1e-9;
    let (mut t0, mut t1) = (0.0f64, 1.0f64);
    for k in 0..4 {
        // λ_k(t) = la + t (lb − la) ≥ −eps.
        let (a, d) = (la[k] + eps, lb[k] - la[k]);
        if d.abs() < 1e-300 {
            if a < 0.0 {
                return None;
            }
        } else if d > 0.0 {
            t0 = t0.max(-a / d);
        } else {
            t1 = t1.min(-a / d);
        }
    }
    (t1 - t0 > 1e-12).then(|| seg[0] + (seg[1] - seg[0]) * (0.5 * (t0 + t1)))
}

/// Distance from `x` to the triangle `t`.
pub fn triangle_distance(x: &Point3<f64>, t: &[Point3<f64>; 3]) -> f64 {
    let n = (t[1] - t[0]).cross(&(t[2] - t[0]));
    let area2 = n.norm_squared();
    if area2 > 0.0 {
        // Inside the prism over the triangle: the distance to its plane.
        let inside = (0..3).all(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            (b - a).cross(&(x - a)).dot(&n) >= 0.0
        });
        if inside {
            return n.dot(&(x - t[0])).abs() / area2.sqrt();
        }
    }
    (0..3)
        .map(|k| segment_distance(x, &[t[k], t[(k + 1) % 3]]))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `x` to the segment `seg`.
pub fn segment_distance(x: &Point3<f64>, seg: &[Point3<f64>; 2]) -> f64 {
    let d = seg[1] - seg[0];
    let len2 = d.norm_squared();
    let t = if len2 > 0.0 {
        ((x - seg[0]).dot(&d) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (x - (seg[0] + d * t)).norm()
}

/// The bounding boxes of segments in an R-tree: whether any segment may
/// come within a distance of a point, without measuring to each.
pub struct SegmentBoxes {
    tree: RTree<Rectangle<[f64; 3]>>,
}

impl SegmentBoxes {
    pub fn new(segments: &[[Point3<f64>; 2]]) -> SegmentBoxes {
        let boxes = segments
            .iter()
            .map(|s| Rectangle::from_corners(s[0].inf(&s[1]).into(), s[0].sup(&s[1]).into()))
            .collect();
        SegmentBoxes {
            tree: RTree::bulk_load(boxes),
        }
    }

    /// Whether a segment's box meets the cube of half-side `reach` about x
    /// (`true` for an infinite reach).
    pub fn may_reach(&self, x: &Point3<f64>, reach: f64) -> bool {
        if !reach.is_finite() {
            return true;
        }
        let near = AABB::from_corners(
            [x.x - reach, x.y - reach, x.z - reach],
            [x.x + reach, x.y + reach, x.z + reach],
        );
        self.tree
            .locate_in_envelope_intersecting(&near)
            .next()
            .is_some()
    }
}

/// Distance from `x` to the nearest front segment (∞ without front).
pub fn front_distance(x: &Point3<f64>, front: &[[Point3<f64>; 2]]) -> f64 {
    front
        .iter()
        .map(|s| segment_distance(x, s))
        .fold(f64::INFINITY, f64::min)
}

/// ψ at `x` from φ(x), the distance d to the front and whether the surface
/// contains the foot of x: ψ = ∓√(d² − φ²) (exact for a plane and a straight
/// front, where d² = φ² + ψ²), negative where the surface contains x.
pub fn front_level_set(phi: f64, distance: f64, inside: bool) -> f64 {
    let a = (distance * distance - phi * phi).max(0.0).sqrt();
    if inside {
        -a
    } else {
        a
    }
}

/// One Gauss–Legendre rule on [0, 1]: points and weights (summing to 1).
/// Rules of up to 16 points are computed once (the collapsed and polar
/// rules ask for them at every cell: 1.5 % of a tip event).
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    const CACHED: usize = 16;
    static RULES: std::sync::OnceLock<Vec<Vec<(f64, f64)>>> = std::sync::OnceLock::new();
    if n <= CACHED {
        return RULES.get_or_init(|| (0..=CACHED).map(gauss_legendre_computed).collect())[n]
            .clone();
    }
    gauss_legendre_computed(n)
}

fn gauss_legendre_computed(n: usize) -> Vec<(f64, f64)> {
    // Nodes by Newton on the Legendre polynomial, mapped from [−1, 1].
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut x = (std::f64::consts::PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
        let mut dp = 1.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            if n == 1 {
                p0 = 1.0;
                p1 = x;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        out.push((0.5 * (1.0 - x), 0.5 * w));
    }
    out
}

/// The radial direction of the collapsed rules: Gauss in σ with ρ = σ²
/// (weight 2σ), so that every r^(k/2) near the front (√r fields, 1/√r
/// gradients, 1/r stiffness integrands, with r ∝ ρ) becomes a polynomial in σ.
fn radial_rule(n: usize) -> Vec<(f64, f64)> {
    gauss_legendre(n)
        .into_iter()
        .map(|(s, w)| (s * s, 2.0 * s * w))
        .collect()
}

/// A quadrature point in physical space with its weight (a volume).
#[derive(Debug, Clone, Copy)]
pub struct PhysicalPoint {
    pub x: Point3<f64>,
    pub weight: f64,
}

/// The 14-point degree-5 rule ([`crate::quadrature::DEGREE5`]) on a tet.
pub fn degree5_rule(cell: &[Point3<f64>; 4]) -> impl Iterator<Item = PhysicalPoint> + '_ {
    let v = crate::mesh::tet_volume(cell).abs();
    crate::quadrature::DEGREE5
        .iter()
        .map(move |q| PhysicalPoint {
            x: Point3::from(
                cell.iter()
                    .zip(q.bary)
                    .fold(Vector3::zeros(), |s, (p, l)| s + p.coords * l),
            ),
            weight: q.weight * v,
        })
}

/// Rule on the tet (p, q, c, d) collapsed onto its edge pq:
/// x(t, s, ρ) = (1−ρ)((1−t)p + tq) + ρ((1−s)c + sd), Jacobian
/// ρ(1−ρ)·6V, tensor Gauss with `n` points per direction and ρ = σ² (see
/// [`radial_rule`]). Integrands like 1/dist(x, pq) or 1/√dist become smooth.
pub fn edge_collapsed_rule(
    p: Point3<f64>,
    q: Point3<f64>,
    c: Point3<f64>,
    d: Point3<f64>,
    n: usize,
) -> Vec<PhysicalPoint> {
    let six_v = (q - p).cross(&(d - c)).dot(&(c - p)).abs();
    let g = gauss_legendre(n);
    let radial = radial_rule(n);
    let mut out = Vec::with_capacity(n * n * n);
    for &(t, wt) in &g {
        for &(s, ws) in &g {
            for &(rho, wr) in &radial {
                let a = p + (q - p) * t;
                let b = c + (d - c) * s;
                let x = a + (b - a) * rho;
                out.push(PhysicalPoint {
                    x,
                    weight: wt * ws * wr * rho * (1.0 - rho) * six_v,
                });
            }
        }
    }
    out
}

/// Duffy rule on the tet (p, a, b, c) collapsed onto its vertex p:
/// x = p + u((a − p) + v((b − a) + w(c − b))), Jacobian u² v · 6V, u = σ².
pub fn vertex_collapsed_rule(
    p: Point3<f64>,
    a: Point3<f64>,
    b: Point3<f64>,
    c: Point3<f64>,
    n: usize,
) -> Vec<PhysicalPoint> {
    let six_v = (a - p).cross(&(b - p)).dot(&(c - p)).abs();
    let g = gauss_legendre(n);
    let radial = radial_rule(n);
    let mut out = Vec::with_capacity(n * n * n);
    for &(u, wu) in &radial {
        for &(v, wv) in &g {
            for &(w, ww) in &g {
                let x = p + ((a - p) + ((b - a) + (c - b) * w) * v) * u;
                out.push(PhysicalPoint {
                    x,
                    weight: wu * wv * ww * u * u * v * six_v,
                });
            }
        }
    }
    out
}

/// Quadrature on an integration cell `v` of an element near the front: the
/// vertices where both level sets vanish (`on_front`) decide the rule — an
/// edge-collapsed rule for a front edge, a Duffy rule for a front vertex, and
/// the tensor rule mapped by Duffy (degree ≥ 2n − 1 in each direction) else.
pub fn cell_rule(v: &[Point3<f64>; 4], on_front: [bool; 4], n: usize) -> Vec<PhysicalPoint> {
    let front: Vec<usize> = (0..4).filter(|&k| on_front[k]).collect();
    let rest: Vec<usize> = (0..4).filter(|&k| !on_front[k]).collect();
    match front.len() {
        2 => edge_collapsed_rule(v[front[0]], v[front[1]], v[rest[0]], v[rest[1]], n),
        1 => vertex_collapsed_rule(v[front[0]], v[rest[0]], v[rest[1]], v[rest[2]], n),
        _ => vertex_collapsed_rule(v[0], v[1], v[2], v[3], n),
    }
}

/// Quadrature on a cell the front passes near but not through (gap g,
/// small against the cell), for integrands that vary on the scale of the
/// distance r to the front (1/r tip stiffness, 1/√r gradients, √r fields)
/// times polynomials. With y = (φ, ψ), both linear over the cell, and z
/// along the front (∇φ × ∇ψ), ∫_cell f dx = ∫∫ (∫ f dz) dy / |∇φ × ∇ψ|,
/// and r = |y|. The cell's image in the y plane is split into the
/// triangles over which the fibre (the cell's points of one y) ends on
/// the same two faces ([`image_triangles`]); each triangle is a fan of
/// Duffy triangles from its point nearest the front, with Gauss panels
/// graded geometrically towards that point (in the radial direction, on
/// the scale of its distance to the front) and towards the foot of that
/// point on the far edge (in the angular direction, on the scale of its
/// distance to that edge); `n` Gauss points per panel in both, `n_z` along
/// the fibre. Exact for polynomials of degree min(2n − 3, 2n_z − 1) (the
/// Duffy Jacobian and the fibre's length take one each). ∫ 1/r over cells
/// 1e-3 … 0.1 of their size from the front: ≤ 4.3e-5 relative error with
/// n = 4, where one red refinement and the degree-5 rule erred by up to
/// 2.6e-2 (test
/// `model::tests::a_front_near_a_cell_is_integrated_in_polar_coordinates`).
/// None when the level sets' gradients are parallel over the cell, or a
/// degenerate image lost part of the cell (the weights' sum checked
/// against its volume).
pub fn polar_rule(
    cell: &[Point3<f64>; 4],
    ls: &[[f64; 2]; 4],
    n: usize,
    n_z: usize,
) -> Option<Vec<PhysicalPoint>> {
    use nalgebra::{Matrix3, Vector2};
    let e = Matrix3::from_columns(&[cell[1] - cell[0], cell[2] - cell[0], cell[3] - cell[0]]);
    let e_inv = e.try_inverse()?;
    let grad = |k: usize| {
        e_inv.transpose()
            * Vector3::new(
                ls[1][k] - ls[0][k],
                ls[2][k] - ls[0][k],
                ls[3][k] - ls[0][k],
            )
    };
    let (gf, gg) = (grad(0), grad(1));
    let along = gf.cross(&gg);
    let det = along.norm();
    if det.is_nan() || det <= 1e-12 * gf.norm() * gg.norm() {
        return None;
    }
    // x(y, z) = X₀ + M⁻¹ (y − y₀, z); its barycentric coordinates 1…3 are
    // E⁻¹ M⁻¹ (y − y₀, z), affine in z along a fibre.
    let m_inv = Matrix3::from_rows(&[gf.transpose(), gg.transpose(), (along / det).transpose()])
        .try_inverse()?;
    let bary = e_inv * m_inv;
    let fibre = |dy: Vector2<f64>| {
        let (mut z0, mut z1) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut rest, mut rest_z) = (1.0, 0.0);
        let mut clip = |a: f64, c: f64| {
            if c > 0.0 {
                z0 = z0.max(-a / c);
            } else if c < 0.0 {
                z1 = z1.min(-a / c);
            }
        };
        for row in 0..3 {
            let a = bary[(row, 0)] * dy.x + bary[(row, 1)] * dy.y;
            let c = bary[(row, 2)];
            rest -= a;
            rest_z -= c;
            clip(a, c);
        }
        clip(rest, rest_z);
        (z1 > z0).then_some((z0, z1))
    };
    let y0 = Vector2::new(ls[0][0], ls[0][1]);
    let gauss = gauss_legendre(n);
    let gauss_z = gauss_legendre(n_z);
    let mut out = Vec::new();
    for tri in image_triangles(ls) {
        let (near, edge) = nearest_on_triangle(&tri);
        let gap = near.norm();
        // The fan from `near`: the far edge of the vertex, or the two
        // triangles beside the point on an edge.
        let fans: Vec<[Vector2<f64>; 2]> = match edge {
            Some(i) => vec![
                [tri[(i + 1) % 3], tri[(i + 2) % 3]],
                [tri[(i + 2) % 3], tri[i]],
            ],
            None => {
                let i = (0..3)
                    .min_by(|&i, &j| (tri[i] - near).norm().total_cmp(&(tri[j] - near).norm()))
                    .unwrap_or(0);
                vec![[tri[(i + 1) % 3], tri[(i + 2) % 3]]]
            }
        };
        for [a, b] in fans {
            let ab = b - a;
            let area2 = cross2(a - near, b - near).abs();
            if area2 <= 1e-14 * ab.norm_squared() {
                continue;
            }
            // y = near + u (a + v (b − a) − near), Jacobian u · area2.
            let foot = ((near - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0);
            let height = (a + ab * foot - near).norm() / ab.norm();
            // (An edge at half its length or more needs no grading.)
            let sides: &[(f64, f64)] = if height >= 0.5 {
                &[(0.0, 1.0)]
            } else {
                &[(foot, 0.0), (foot, 1.0)]
            };
            let v_panels = sides.iter().copied().flat_map(|(from, to)| {
                let side = (to - from).abs();
                let panels = if side > 0.0 {
                    graded_panels(height / side)
                } else {
                    Vec::new()
                };
                panels
                    .into_iter()
                    .map(move |(p0, p1)| (from + (to - from) * p0, from + (to - from) * p1))
            });
            for (v0, v1) in v_panels {
                for &(gv, wv) in &gauss {
                    let v = v0 + (v1 - v0) * gv;
                    let end = a + ab * v;
                    let w_v = wv * (v1 - v0).abs() * area2;
                    for (u0, u1) in graded_panels(gap / (end - near).norm()) {
                        for &(gu, wu) in &gauss {
                            let u = u0 + (u1 - u0) * gu;
                            let dy = near + (end - near) * u - y0;
                            let Some((z0, z1)) = fibre(dy) else {
                                continue;
                            };
                            let w = w_v * wu * (u1 - u0) * u * (z1 - z0) / det;
                            for &(gz, wz) in &gauss_z {
                                let z = z0 + (z1 - z0) * gz;
                                out.push(PhysicalPoint {
                                    x: cell[0] + m_inv * Vector3::new(dy.x, dy.y, z),
                                    weight: w * wz,
                                });
                            }
                        }
                    }
                }
            }
        }
    }
    // A degenerate image (vertices' images collinear, within round-off)
    // can lose a triangle: the weights must add up to the volume.
    let volume = e.determinant().abs() / 6.0;
    let total: f64 = out.iter().map(|q| q.weight).sum();
    if (total - volume).abs() > 1e-9 * volume {
        return None;
    }
    Some(out)
}

fn cross2(a: nalgebra::Vector2<f64>, b: nalgebra::Vector2<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

/// The triangles of a cell's image in the (φ, ψ) plane over which the
/// fibre (the cell's points of one (φ, ψ)) enters and leaves through the
/// same faces: the arrangement of the images of its six edges, a fan of
/// three from the vertex whose image lies inside the others' triangle, or
/// of four from the crossing of the image's diagonals.
fn image_triangles(ls: &[[f64; 2]; 4]) -> Vec<[nalgebra::Vector2<f64>; 3]> {
    use nalgebra::Vector2;
    let y: [Vector2<f64>; 4] = ls.map(|l| Vector2::new(l[0], l[1]));
    // Orientations within round-off of zero (images on a line, or the
    // same image for an edge along the front) count as zero.
    let eps = 1e-12 * level_diameter(ls).powi(2);
    let orient = |a: usize, b: usize, c: usize| {
        let o = cross2(y[b] - y[a], y[c] - y[a]);
        if o.abs() <= eps {
            0.0
        } else {
            o
        }
    };
    let others = |i: usize| -> [usize; 3] { [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4] };
    let inner = (0..4).find(|&i| {
        let o = others(i);
        let s = [
            orient(o[0], o[1], i),
            orient(o[1], o[2], i),
            orient(o[2], o[0], i),
        ];
        s.iter().all(|&v| v >= 0.0) || s.iter().all(|&v| v <= 0.0)
    });
    if let Some(i) = inner {
        let o = others(i);
        return (0..3).map(|t| [y[i], y[o[t]], y[o[(t + 1) % 3]]]).collect();
    }
    // Convex position: the diagonals (a, b) and (c, d) cross at m.
    let crossing = [[0, 1, 2, 3], [0, 2, 1, 3], [0, 3, 1, 2]]
        .into_iter()
        .find(|&[a, b, c, d]| {
            orient(a, b, c) * orient(a, b, d) < 0.0 && orient(c, d, a) * orient(c, d, b) < 0.0
        });
    let Some([a, b, c, d]) = crossing else {
        return Vec::new();
    };
    let t = orient(c, d, a) / (orient(c, d, a) - orient(c, d, b));
    let m = y[a] + (y[b] - y[a]) * t;
    [(a, c), (c, b), (b, d), (d, a)]
        .map(|(p, q)| [m, y[p], y[q]])
        .to_vec()
}

/// Panels of [0, 1] graded geometrically (ratio 4) from 0 for a function
/// that varies on the scale `delta` there: [0, δ], [δ, 4δ], …; one panel
/// for δ ≥ 1/2.
fn graded_panels(delta: f64) -> Vec<(f64, f64)> {
    let mut edges = vec![0.0];
    let mut b = delta;
    while delta > 0.0 && b < 0.5 {
        edges.push(b);
        b *= 4.0;
    }
    edges.push(1.0);
    edges.windows(2).map(|w| (w[0], w[1])).collect()
}

/// The point of a triangle nearest the origin, with the index i of the
/// edge (tri[i], tri[i + 1]) it lies inside of (None: at a vertex).
fn nearest_on_triangle(
    tri: &[nalgebra::Vector2<f64>; 3],
) -> (nalgebra::Vector2<f64>, Option<usize>) {
    let mut best = (tri[0], None, tri[0].norm());
    for (i, v) in tri.iter().enumerate() {
        if v.norm() < best.2 {
            best = (*v, None, v.norm());
        }
        let d = tri[(i + 1) % 3] - v;
        let t = -v.dot(&d) / d.norm_squared();
        if t > 1e-9 && t < 1.0 - 1e-9 {
            let p = v + d * t;
            if p.norm() < best.2 {
                best = (p, Some(i), p.norm());
            }
        }
    }
    (best.0, best.1)
}

/// Distance from the front (φ = ψ = 0) to a cell whose vertices carry the
/// level-set values `ls` = (φ, ψ), both linear over it: the distance from
/// the origin to the convex hull of the vertex images in the (φ, ψ) plane
/// (0 when the front passes through the cell).
pub fn front_gap(ls: &[[f64; 2]; 4]) -> f64 {
    front_nearest(ls).0
}

/// The point of a cell's level-set image (the convex hull of its vertices'
/// (φ, ψ)) nearest the front, the origin of the (φ, ψ) plane, with its
/// distance [`front_gap`]: the origin itself where the front passes
/// through the cell.
pub fn front_nearest(ls: &[[f64; 2]; 4]) -> (f64, [f64; 2]) {
    let cross = |a: [f64; 2], b: [f64; 2], c: [f64; 2]| {
        (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
    };
    let o = [0.0, 0.0];
    for t in [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]] {
        let (a, b, c) = (ls[t[0]], ls[t[1]], ls[t[2]]);
        let (s1, s2, s3) = (cross(a, b, o), cross(b, c, o), cross(c, a, o));
        let has_neg = s1 < 0.0 || s2 < 0.0 || s3 < 0.0;
        let has_pos = s1 > 0.0 || s2 > 0.0 || s3 > 0.0;
        if !(has_neg && has_pos) && cross(a, b, c) != 0.0 {
            return (0.0, o);
        }
    }
    let mut best = (f64::INFINITY, o);
    for i in 0..4 {
        for j in i + 1..4 {
            let (a, b) = (ls[i], ls[j]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let len2 = d[0] * d[0] + d[1] * d[1];
            let t = if len2 > 0.0 {
                (-(a[0] * d[0] + a[1] * d[1]) / len2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let p = [a[0] + t * d[0], a[1] + t * d[1]];
            let dist = p[0].hypot(p[1]);
            if dist < best.0 {
                best = (dist, p);
            }
        }
    }
    best
}

/// The diameter of a cell's level-set image: the largest distance between
/// its vertices' (φ, ψ).
pub fn level_diameter(ls: &[[f64; 2]; 4]) -> f64 {
    (0..4)
        .flat_map(|a| (a + 1..4).map(move |b| (a, b)))
        .map(|(a, b)| (ls[a][0] - ls[b][0]).hypot(ls[a][1] - ls[b][1]))
        .fold(0.0, f64::max)
}

/// The eight children of a tet by edge midpoints (Bey's red refinement;
/// the inner octahedron split along the diagonal m02–m13), with their
/// vertices' values of any field linear over the tet.
pub fn red_children<T: Copy>(
    v: &[Point3<f64>; 4],
    f: &[T; 4],
    mid: impl Fn(T, T) -> T,
) -> [([Point3<f64>; 4], [T; 4]); 8] {
    let m = |a: usize, b: usize| {
        (
            Point3::from((v[a].coords + v[b].coords) * 0.5),
            mid(f[a], f[b]),
        )
    };
    let (v0, v1, v2, v3) = ((v[0], f[0]), (v[1], f[1]), (v[2], f[2]), (v[3], f[3]));
    let (m01, m02, m03, m12, m13, m23) = (m(0, 1), m(0, 2), m(0, 3), m(1, 2), m(1, 3), m(2, 3));
    let t = |a: (Point3<f64>, T), b: (Point3<f64>, T), c: (Point3<f64>, T), d: (Point3<f64>, T)| {
        ([a.0, b.0, c.0, d.0], [a.1, b.1, c.1, d.1])
    };
    [
        t(v0, m01, m02, m03),
        t(m01, v1, m12, m13),
        t(m02, m12, v2, m23),
        t(m03, m13, m23, v3),
        t(m01, m02, m03, m13),
        t(m01, m02, m12, m13),
        t(m02, m03, m13, m23),
        t(m02, m12, m13, m23),
    ]
}

/// A quadrature rule appending a cell's points.
pub type LeafRule = dyn Fn(&[Point3<f64>; 4], &mut Vec<PhysicalPoint>);

/// Quadrature on a cell that does not touch the front but may lie close to
/// it (level sets `ls` at its vertices): red-refined towards the front
/// while a piece's gap to the front is under `gap_ratio` times its own
/// level-set diameter (at most `depth` times), `leaf` on each piece. The
/// √r-type integrands of the tip functions are near-singular in a cell the
/// front passes close to; on the pieces they are smoother relative to the
/// piece, so the fixed leaf rule errs less.
pub fn near_front_rule(
    cell: &[Point3<f64>; 4],
    ls: &[[f64; 2]; 4],
    depth: usize,
    gap_ratio: f64,
    leaf: &LeafRule,
    out: &mut Vec<PhysicalPoint>,
) {
    let diam = level_diameter(ls);
    // (A gap within 1e-9 of the threshold counts as on it: on structured
    // meshes it often is, exactly, and round-off, moved with the scene,
    // chose the rule: 2e-4 in a tip element's mean gradient, 1e-6 at the
    // probes.)
    if depth == 0 || front_gap(ls) >= gap_ratio * diam * (1.0 - 1e-9) {
        leaf(cell, out);
        return;
    }
    let mid = |a: [f64; 2], b: [f64; 2]| [(a[0] + b[0]) * 0.5, (a[1] + b[1]) * 0.5];
    for (c, l) in red_children(cell, ls, mid) {
        near_front_rule(&c, &l, depth - 1, gap_ratio, leaf, out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`polar_rule`] (n = 4, n_z = 3) integrates quintics exactly over
    /// cells the front passes at 1e-3 … 0.3 of their size, among them one
    /// with an edge along the front (two vertices of one image, three on a
    /// line: a tip element's cell beside a cut on a node layer, whose
    /// image the rule lost before its orientations were snapped); level
    /// sets with parallel gradients over a cell (its image a segment) get
    /// None, and the cell its red refinement.
    #[test]
    fn the_polar_rule_is_exact_for_polynomials_of_its_degree() {
        let mut seed = 7u64;
        let mut unit = move || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        type Case = ([Point3<f64>; 4], [[f64; 2]; 4]);
        let mut cases: Vec<Case> = Vec::new();
        for k in 0..30 {
            let cell: [Point3<f64>; 4] =
                std::array::from_fn(|_| Point3::new(unit(), unit(), unit()));
            // Level sets with the front (φ = ψ = 0) at a gap beside the cell.
            let gap = [1e-3, 1e-2, 0.3][k % 3];
            let ls0: [[f64; 2]; 4] = std::array::from_fn(|_| [unit(), unit()]);
            let (g0, star) = front_nearest(&ls0);
            let diam = level_diameter(&ls0);
            let scale = if g0 > 0.0 { gap * diam / g0 } else { 0.0 };
            let shift = if g0 > 0.0 {
                [star[0] * (1.0 - scale), star[1] * (1.0 - scale)]
            } else {
                [diam * (1.0 + gap), 0.0]
            };
            cases.push((cell, ls0.map(|l| [l[0] - shift[0], l[1] - shift[1]])));
        }
        // The node-layer cell (its values from a run).
        let layer = [
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(0.4, 0.1, 0.0),
            Point3::new(0.1, 0.5, 0.05),
            Point3::new(0.1, 0.5, 0.6),
        ];
        cases.push((
            layer,
            [
                [0.011255497841079256, -0.008152427999945868],
                [0.008265169755833078, -1.734723475976807e-18],
                [0.0008336161670007056, -8.673617379884035e-19],
                [0.0008336161670007061, -2.6020852139652106e-18],
            ],
        ));
        let flat = [[0.2, 0.1], [0.4, 0.2], [0.3, 0.15], [0.5, 0.25]];
        assert!(polar_rule(&cases[0].0, &flat, 4, 3).is_none());
        for (cell, ls) in cases {
            let c = Vector3::new(unit(), unit(), unit());
            let f = |x: &Point3<f64>| (1.0 + c.dot(&x.coords)).powi(5);
            let exact: f64 = degree5_rule(&cell).map(|q| q.weight * f(&q.x)).sum();
            let rule = polar_rule(&cell, &ls, 4, 3).expect("level sets not parallel");
            let got: f64 = rule.iter().map(|q| q.weight * f(&q.x)).sum();
            let scale: f64 = rule.iter().map(|q| (q.weight * f(&q.x)).abs()).sum();
            assert!(
                (got - exact).abs() <= 1e-12 * scale,
                "{ls:?}: {got} against {exact}"
            );
        }
    }

    #[test]
    fn branch_functions_satisfy_two_linear_identities_in_the_level_sets() {
        // φ (F₀ − F₃) + ψ F₂ = 0 and φ (F₁ − F₂) − ψ F₃ = 0 at every (φ, ψ)
        // on either side: with affine level sets these are dependences of
        // the tip functions wherever every vertex of an element carries them
        // (the ramp; `model::ramp_fixes`).
        let mut seed = 99u64;
        let mut unit = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let g = Vector3::zeros();
        for _ in 0..200 {
            let (phi, psi) = (unit() * 0.03, unit() * 0.03);
            let side = if phi >= 0.0 { 1 } else { -1 };
            let (f, _) = branch_with_gradients(phi, psi, &g, &g, side);
            let scale = (phi * phi + psi * psi).sqrt().powf(1.5);
            let one = phi * (f[0] - f[3]) + psi * f[2];
            let two = phi * (f[1] - f[2]) - psi * f[3];
            assert!(one.abs() <= 1e-14 * scale, "{phi} {psi}: {one:e}");
            assert!(two.abs() <= 1e-14 * scale, "{phi} {psi}: {two:e}");
        }
    }

    #[test]
    fn branch_gradients_match_finite_differences() {
        // Linear level sets with oblique gradients, at points on both sides and behind/ahead of the front.
        let gphi = Vector3::new(0.2, 1.1, -0.3);
        let gpsi = Vector3::new(0.9, -0.1, 0.4);
        let (p0, s0) = (0.013, -0.021);
        let eval = |x: &Vector3<f64>, side: i8| {
            branch_with_gradients(p0 + gphi.dot(x), s0 + gpsi.dot(x), &gphi, &gpsi, side)
        };
        for (x, side) in [
            (Vector3::new(0.1, 0.2, 0.3), 1),
            (Vector3::new(-0.1, -0.2, 0.05), -1),
            (Vector3::new(0.3, -0.05, 0.0), 1),
        ] {
            let (_, g) = eval(&x, side);
            let h = 1e-6;
            for c in 0..3 {
                let mut e = Vector3::zeros();
                e[c] = h;
                let (fp, _) = eval(&(x + e), side);
                let (fm, _) = eval(&(x - e), side);
                for k in 0..N_BRANCH {
                    let fd = (fp[k] - fm[k]) / (2.0 * h);
                    assert!(
                        (fd - g[k][c]).abs() <= 1e-7 * (1.0 + g[k][c].abs()),
                        "F{} dir {c}: fd {fd} vs {}",
                        k + 1,
                        g[k][c]
                    );
                }
            }
        }
    }

    #[test]
    fn branch_gradients_equal_the_angle_formulas_to_round_off() {
        // The values of branch_values ∘ polar_angle, and the gradients of the
        // chain rule with θ's sine and cosine, on circles around the front,
        // the crack faces (φ = ±0 behind it) and the line ahead included.
        let (gphi, gpsi) = (Vector3::new(0.3, 1.0, -0.2), Vector3::new(1.0, -0.1, 0.4));
        let mut worst: f64 = 0.0;
        for r in [1e-9, 1e-3, 0.7, 20.0] {
            for k in 0..=720 {
                let theta = -std::f64::consts::PI + std::f64::consts::PI * k as f64 / 360.0;
                let (phi, psi) = (r * theta.sin(), r * theta.cos());
                for (phi, side) in [(phi, 0), (phi, 1), (phi, -1), (0.0, 1), (-0.0, -1)] {
                    let (v, g) = branch_with_gradients(phi, psi, &gphi, &gpsi, side);
                    let th = polar_angle(phi, psi, side);
                    let rr = phi.hypot(psi);
                    let want = branch_values(rr, th);
                    let sr = rr.sqrt();
                    let (s2, c2) = (0.5 * th).sin_cos();
                    let (st, ct) = th.sin_cos();
                    let dr = (gphi * phi + gpsi * psi) / rr;
                    let dt = (gphi * psi - gpsi * phi) / (rr * rr);
                    let partial = [
                        (s2 / (2.0 * sr), 0.5 * sr * c2),
                        (c2 / (2.0 * sr), -0.5 * sr * s2),
                        (s2 * st / (2.0 * sr), sr * (0.5 * c2 * st + s2 * ct)),
                        (c2 * st / (2.0 * sr), sr * (-0.5 * s2 * st + c2 * ct)),
                    ];
                    for b in 0..N_BRANCH {
                        worst = worst.max((v[b] - want[b]).abs() / sr);
                        let gw = dr * partial[b].0 + dt * partial[b].1;
                        worst = worst.max((g[b] - gw).norm() * sr);
                    }
                }
            }
        }
        assert!(worst < 1e-14, "{worst:e}");
    }

    #[test]
    fn branch_values_jump_only_in_f1_across_the_cut() {
        let r = 0.25;
        let up = branch_values(r, polar_angle(0.0, -r, 1));
        let down = branch_values(r, polar_angle(0.0, -r, -1));
        assert!((up[0] - 0.5).abs() < 1e-15 && (down[0] + 0.5).abs() < 1e-15);
        for k in 1..N_BRANCH {
            assert!((up[k] - down[k]).abs() < 1e-15, "F{}", k + 1);
        }
        // Ahead of the front (θ = 0) every branch function but F₂ = √r vanishes.
        let ahead = branch_values(r, polar_angle(0.0, r, 1));
        assert_eq!(ahead[0], 0.0);
        assert!((ahead[1] - 0.5).abs() < 1e-15);
    }

    #[test]
    fn gauss_legendre_integrates_degree_2n_minus_1() {
        // Cached (up to 16 points) and computed past it.
        for n in 1..=20 {
            let g = gauss_legendre(n);
            assert_eq!(g, gauss_legendre_computed(n), "n {n}");
            for k in 0..2 * n {
                let q: f64 = g.iter().map(|&(x, w)| w * x.powi(k as i32)).sum();
                assert!((q - 1.0 / (k as f64 + 1.0)).abs() < 1e-14, "n {n} x^{k}");
            }
        }
    }

    /// ∫_T 1/dist(x, line) over the tet with the front on its edge: the value is
    /// known in closed form for T = {0, e_x, e_y, e_z} and the line = the z axis
    /// through edge (0, e_z): ∫ dz ∫∫_{x+y ≤ 1−z} 1/√(x²+y²) = ∫ (1−z) dz · c,
    /// c = ∫∫_{x+y≤1} 1/ρ = ∫_0^{π/2} dθ/(cos θ + sin θ) = √2 ln(1 + √2).
    #[test]
    fn collapsed_rules_integrate_an_inverse_distance_exactly() {
        let o = Point3::origin();
        let (ex, ey, ez) = (
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
            Point3::new(0.0, 0.0, 1.0),
        );
        let exact = 0.5 * 2f64.sqrt() * (1.0 + 2f64.sqrt()).ln();
        let f = |x: &Point3<f64>| 1.0 / x.x.hypot(x.y);
        let integrate =
            |rule: &[PhysicalPoint]| -> f64 { rule.iter().map(|q| q.weight * f(&q.x)).sum() };
        let mut errors = Vec::new();
        for n in [3, 4, 6, 8] {
            let rule = cell_rule(&[o, ex, ey, ez], [true, false, false, true], n);
            let vol: f64 = rule.iter().map(|q| q.weight).sum();
            assert!((vol - 1.0 / 6.0).abs() < 1e-15);
            errors.push((integrate(&rule) - exact).abs() / exact);
        }
        println!("edge-collapsed 1/r relative errors n = 3, 4, 6, 8: {errors:?}");
        // Smooth in (t, s, ρ): exponential convergence (the angular factor
        // 1/|(1−s, s)| is what is left), 2.5e-7 at n = 8.
        assert!(errors.windows(2).all(|w| w[1] < 0.2 * w[0]), "{errors:?}");
        assert!(errors[3] < 1e-6, "{errors:?}");
        // The standard degree-5 rule on the same tet: far less accurate.
        let p = [o, ex, ey, ez];
        let std: f64 = degree5_rule(&p).map(|q| q.weight * f(&q.x)).sum();
        let std_err = (std - exact).abs() / exact;
        println!("degree-5 Walkington rule, same integral: {std_err:.2e}");
        assert!(std_err > 100.0 * errors[3]);
        // Vertex-collapsed: 1/|x| over the same tet, front vertex at the origin;
        // ∫_T 1/|x| = ∫_{S²∩octant} ∫_0^{ρ(ω)} ρ dρ dω with the plane x+y+z = 1
        // checked against a tensor rule on the octant (smooth integrand there).
        let g = |x: &Point3<f64>| 1.0 / x.coords.norm();
        let vr = cell_rule(&[o, ex, ey, ez], [true, false, false, false], 10);
        let duffy: f64 = vr.iter().map(|q| q.weight * g(&q.x)).sum();
        // ∫_octant (1/2) ρ_max(ω)² dω with ρ_max = 1/(ωx+ωy+ωz), by spherical Gauss.
        let gl = gauss_legendre(40);
        let mut sphere = 0.0;
        for &(a, wa) in &gl {
            for &(b, wb) in &gl {
                let (th, ph) = (
                    a * std::f64::consts::FRAC_PI_2,
                    b * std::f64::consts::FRAC_PI_2,
                );
                let w = Vector3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                let rmax = 1.0 / (w.x + w.y + w.z);
                sphere +=
                    wa * wb * std::f64::consts::FRAC_PI_2.powi(2) * th.sin() * 0.5 * rmax * rmax;
            }
        }
        println!("vertex-collapsed 1/|x|: {duffy} vs {sphere}");
        assert!((duffy - sphere).abs() < 1e-7 * sphere);
    }

    #[test]
    fn psi_of_a_plane_and_straight_front_is_the_in_plane_distance() {
        let seg = [Point3::new(-5.0, 0.0, 0.0), Point3::new(5.0, 0.0, 0.0)];
        // Plane z = 0, cut on y < 0, front the x axis.
        for (x, want) in [
            (Point3::new(0.3, -0.2, 0.1), -0.2),
            (Point3::new(0.3, 0.4, -0.3), 0.4),
        ] {
            let d = segment_distance(&x, &seg);
            let psi = front_level_set(x.z, d, x.y < 0.0);
            assert!((psi - want).abs() < 1e-15, "{psi} vs {want}");
        }
    }

    #[test]
    fn red_children_tile_the_tet_and_front_gap_is_the_plane_distance() {
        let v = [
            Point3::new(0.1, 0.0, 0.0),
            Point3::new(1.0, 0.2, 0.0),
            Point3::new(0.3, 0.9, 0.1),
            Point3::new(0.2, 0.3, 1.1),
        ];
        let vol = crate::mesh::tet_volume(&v).abs();
        let kids = red_children(&v, &v.map(|p| p.coords), |a, b| (a + b) * 0.5);
        let total: f64 = kids
            .iter()
            .map(|(c, _)| crate::mesh::tet_volume(c).abs())
            .sum();
        assert!((total - vol).abs() < 1e-14 * vol, "{total} {vol}");
        for (c, f) in &kids {
            assert!(crate::mesh::tet_volume(c).abs() > 0.05 * vol);
            for k in 0..4 {
                assert!((c[k].coords - f[k]).norm() < 1e-15);
            }
        }
        // Level sets φ = y − 0.5, ψ = x − 2: the front x = 2, y = 0.5 lies
        // beside the tet; its gap is the (φ, ψ) distance of the nearest
        // point, vertex 1 (φ, ψ) = (−0.3, −1.0).
        let ls = v.map(|p| [p.y - 0.5, p.x - 2.0]);
        let gap = front_gap(&ls);
        assert!((gap - 0.3f64.hypot(1.0)).abs() < 1e-12, "{gap}");
        let through = v.map(|p| [p.y - 0.3, p.x - 0.4]);
        assert_eq!(front_gap(&through), 0.0);
    }
}

//! Blades and progressive cuts: a cutting edge a–b moving through the body
//! while a dynamic scene runs; at time t the cut is the surface the edge has
//! swept since its start.
//!
//! - A straight sweep (two keyframes, the edge translated) sweeps the planar
//!   patch origin = a, u = b − a, v = a(t) − a; when complete v = travel, the
//!   patch a `[[cut]]` with those keys gives. A path sweeps a ruled strip of
//!   triangles between consecutive edges ([`TriangleSurface`]).
//! - A *cut event* is a step after which the cut set-up differs (elements
//!   newly cut or touched, nodes newly enriched). The set-up is rebuilt and
//!   the model updated where it changed ([`Model::update_cut`]: only the
//!   elements whose cut or enrichment changed are integrated again); the
//!   Newmark state is mapped onto the new DOFs:
//!   standard DOFs keep their values, enriched DOFs of nodes that were
//!   enriched before keep theirs, new shifted-enrichment DOFs start at zero
//!   displacement, velocity and acceleration. Since Nᵢ(H − Hᵢ)·0 = 0 (seed
//!   eq. 58–59) the field, its velocity and both energies are unchanged
//!   (METHODS.md, "Blades"). The symbolic factorisation is redone only when
//!   the pattern changed; a linear scene refactorises at events only, and
//!   not even there where the events only appended equations: its steps
//!   then solve on the last factor through a [`BorderedSolve`] until the
//!   border outgrows [`crate::dynamics::border_limit`] ([`EventSolve`]).
//! - A static scene takes the completed sweep ([`CutSet::completed`]).

use crate::assembly::Rotations;
use crate::cut::{
    setup_cut, CutError, CutInput, CutSetup, CutSurface, ElementCut, FrontMode, PlanarPatch,
};
use crate::dynamics::{
    DynamicError, DynamicOptions, Energies, EventSolve, LinearFactor, LinearForces, Newmark, State,
};
use crate::mesh::TetMesh;
use crate::model::{same_element_cut, same_element_model, Model, ModelError, TipFit, TipFits};
#[cfg(doc)]
use crate::solve::BorderedSolve;
use crate::solve::{Cholesky, Parallelism, SolveError};
use crate::surface::TriangleSurface;
use nalgebra::{Matrix3, Point3, Vector3};
use std::path::Path;
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum BladeError {
    #[error("cut[{index}]: key `{key}`: {message}")]
    Key {
        index: usize,
        key: &'static str,
        message: String,
    },
    /// `key`: the blade's own key, `blade` for a straight sweep, `path`
    /// for keyframes ([`Blade::key`]).
    #[error("cut[{index}]: key `{key}`: the blade never meets the body (its completed sweep cuts no element)")]
    Misses { index: usize, key: &'static str },
    #[error("cut[{index}]: key `{key}`: its swept surface meets cut[{other}] in element {element} or at its nodes: cuts must not intersect and must be at least one element apart")]
    Meets {
        index: usize,
        key: &'static str,
        other: usize,
        element: usize,
    },
    #[error("cut[{index}]: key `surface`: {source}")]
    Surface {
        index: usize,
        #[source]
        source: crate::surface::SurfaceError,
    },
    #[error(transparent)]
    Cut(#[from] CutError),
    #[error(transparent)]
    Model(#[from] ModelError),
    #[error(transparent)]
    Solve(#[from] SolveError),
    #[error(transparent)]
    Dynamic(#[from] DynamicError),
}

/// A cutting edge a–b given at keyframe times, linear in between.
#[derive(Debug, Clone)]
pub struct Blade {
    keyframes: Vec<(f64, [Point3<f64>; 2])>,
    /// A straight sweep's travel as given (the two keyframes hold a and
    /// a + travel, whose difference can differ from it in the last bits).
    travel: Option<Vector3<f64>>,
    /// Index of its `[[cut]]` in the scene (for errors).
    pub index: usize,
    /// `event_travel` (m): during a sweep, a cut event only once the edge
    /// has moved this far since the last one (or passed its end); `None`:
    /// at every step the cut grows ([`event_due`]).
    pub event_travel: Option<f64>,
}

impl Blade {
    /// A blade from keyframes (time, [a, b]). Errors name the key: fewer than
    /// two keyframes or times not strictly increasing (`times`; with travel:
    /// `end` ≤ `start`), a non-finite value or an edge of zero length (`blade`).
    pub fn new(index: usize, keyframes: Vec<(f64, [Point3<f64>; 2])>) -> Result<Blade, BladeError> {
        let err = |key, message: String| BladeError::Key {
            index,
            key,
            message,
        };
        if keyframes.len() < 2 {
            return Err(err(
                "times",
                format!(
                    "{} keyframe(s): a blade needs at least two",
                    keyframes.len()
                ),
            ));
        }
        let straight_pair = keyframes.len() == 2;
        for (k, (t, e)) in keyframes.iter().enumerate() {
            if !t.is_finite() || !e.iter().all(|p| p.iter().all(|c| c.is_finite())) {
                return Err(err("blade", format!("keyframe {k} is not finite")));
            }
            let len = (e[1] - e[0]).norm();
            if len == 0.0 {
                return Err(err(
                    "blade",
                    format!("the edge at keyframe {k} has zero length"),
                ));
            }
        }
        for k in 1..keyframes.len() {
            let (t0, t1) = (keyframes[k - 1].0, keyframes[k].0);
            if t1 <= t0 {
                let (key, message) = if straight_pair {
                    ("end", format!("end = {t1} must be after start = {t0}"))
                } else {
                    (
                        "times",
                        format!(
                            "keyframes out of order: times[{k}] = {t1} ≤ times[{}] = {t0}",
                            k - 1
                        ),
                    )
                };
                return Err(err(key, message));
            }
        }
        let blade = Blade {
            keyframes,
            travel: None,
            index,
            event_travel: None,
        };
        // A path's completed strip must be a surface (every prefix of it then is).
        if !blade.is_straight() {
            blade
                .check_forward()
                .map_err(|message| err("path", message))?;
            blade.strip(blade.end()).map_err(|e| {
                err(
                    "path",
                    format!("the swept strip is not a valid surface: {e}"),
                )
            })?;
        }
        Ok(blade)
    }

    /// A straight sweep: the edge a–b moves by `travel` between `start` and
    /// `end`; completed, it is the patch origin = a, u = b − a, v = travel.
    pub fn straight(
        index: usize,
        a: Point3<f64>,
        b: Point3<f64>,
        travel: Vector3<f64>,
        start: f64,
        end: f64,
    ) -> Result<Blade, BladeError> {
        Blade::from_keyframes(
            index,
            vec![(start, [a, b]), (end, [a + travel, b + travel])],
            Some(travel),
        )
    }

    /// A blade from a scene's keyframes and, for a straight sweep, its
    /// `travel` as given (the two keyframes are then (start, [a, b]) and
    /// (end, [a + travel, b + travel])).
    pub fn from_keyframes(
        index: usize,
        keyframes: Vec<(f64, [Point3<f64>; 2])>,
        travel: Option<Vector3<f64>>,
    ) -> Result<Blade, BladeError> {
        let mut blade = Blade::new(index, keyframes)?;
        if blade.keyframes.len() == 2 {
            blade.travel = travel;
        }
        Ok(blade)
    }

    /// The case file's key that gives this blade's motion: `blade` for a
    /// straight sweep (`blade` + `travel`), `path` for keyframes (with or
    /// without `blade` as the first).
    pub fn key(&self) -> &'static str {
        if self.travel.is_some() {
            "blade"
        } else {
            "path"
        }
    }

    pub fn start(&self) -> f64 {
        self.keyframes[0].0
    }

    pub fn end(&self) -> f64 {
        self.keyframes[self.keyframes.len() - 1].0
    }

    /// The edge at time t (clamped to the first and last keyframes).
    pub fn edge_at(&self, t: f64) -> [Point3<f64>; 2] {
        let k = &self.keyframes;
        if t <= k[0].0 {
            return k[0].1;
        }
        for w in k.windows(2) {
            let ((t0, e0), (t1, e1)) = (w[0], w[1]);
            if t <= t1 {
                let s = (t - t0) / (t1 - t0);
                return [0, 1].map(|i| e0[i] + (e1[i] - e0[i]) * s);
            }
        }
        k[k.len() - 1].1
    }

    /// A path whose edge turns back over the surface it has swept (an end
    /// moving backwards within a segment, or the edge reversing at a
    /// keyframe) folds its strip onto itself: the swept surface is then not
    /// the strip, and the level set's sign flips where the strip faces the
    /// other way. Consecutive triangles of the completed strip share an edge;
    /// the strip folds where they meet at a dihedral angle under
    /// [`FOLD_ANGLE`] (a flat strip: 180°; a U-turn through a side of the
    /// body: two 90° bends, which are fine).
    fn check_forward(&self) -> Result<(), String> {
        let [a0, b0] = self.keyframes[0].1;
        let scale = (b0 - a0).norm();
        let mut last: Option<[Point3<f64>; 3]> = None;
        for (k, w) in self.keyframes.windows(2).enumerate() {
            let ([a0, b0], [a1, b1]) = (w[0].1, w[1].1);
            // Within the segment: both ends move forward (or stay), forward
            // being the mean motion across the edge.
            let e = (b0 - a0).normalize();
            let across = |v: Vector3<f64>| v - e * v.dot(&e);
            let (va, vb) = (a1 - a0, b1 - b0);
            let f = across(va + vb);
            let stays = |v: Vector3<f64>| v.norm() <= 1e-12 * scale;
            if f.norm() > 1e-12 * scale && [va, vb].iter().any(|&v| !stays(v) && v.dot(&f) < 0.0) {
                return Err(format!(
                    "the edge turns back over the surface it has swept between keyframes {k} and {} (one end moves backwards): give keyframes along which every point of the edge moves forward",
                    k + 1
                ));
            }
            for tri in [[a0, b0, b1], [a0, b1, a1]] {
                let area = (tri[1] - tri[0]).cross(&(tri[2] - tri[0])).norm();
                if area <= 1e-12 * scale * scale {
                    continue;
                }
                if let Some(angle) = last.and_then(|prev| dihedral(&prev, &tri)) {
                    if angle < FOLD_ANGLE {
                        return Err(format!(
                            "the edge turns back over the surface it has swept by keyframe {} (the strip folds to {:.0}°: an end moves backwards, or the edge reverses): give keyframes along which every point of the edge moves forward",
                            k + 1,
                            angle.to_degrees()
                        ));
                    }
                }
                last = Some(tri);
            }
        }
        Ok(())
    }

    /// Whether the sweep is a translation of the edge between two keyframes.
    fn is_straight(&self) -> bool {
        if self.keyframes.len() != 2 {
            return false;
        }
        if self.travel.is_some() {
            return true;
        }
        let [a0, b0] = self.keyframes[0].1;
        let [a1, b1] = self.keyframes[1].1;
        let (u0, u1) = (b0 - a0, b1 - a1);
        (u1 - u0).norm() <= 1e-12 * u0.norm()
    }

    /// The surface swept up to time t; `None` before the edge has moved.
    pub fn swept(&self, t: f64) -> Option<Swept> {
        let t = t.min(self.end());
        if t <= self.start() {
            return None;
        }
        let [a0, b0] = self.keyframes[0].1;
        if self.is_straight() {
            let (t0, [a1, _]) = (self.keyframes[0].0, self.keyframes[1].1);
            let t1 = self.keyframes[1].0;
            let travel = self.travel.unwrap_or(a1 - a0);
            let full = PlanarPatch {
                origin: a0,
                u: b0 - a0,
                v: travel,
            };
            if t >= t1 {
                return Some(Swept::Patch(full));
            }
            let v = travel * ((t - t0) / (t1 - t0));
            if v.norm() == 0.0 {
                return None;
            }
            let part = PlanarPatch {
                origin: a0,
                u: b0 - a0,
                v,
            };
            return Some(Swept::Growing(GrowingPatch { full, part }));
        }
        // A prefix of the completed strip, which `new` checked.
        self.strip(t)
            .ok()
            .flatten()
            .map(|s| Swept::Strip(Box::new(s)))
    }

    /// The strip swept by time t: between consecutive keyframes [a0, b0] and
    /// [a1, b1] the triangles [a0, b0, b1] and [a0, b1, a1] (the completed
    /// strip), and in the segment the edge is in, the part of them up to the
    /// current parameter σ, which the piecewise-linear map of the segment's
    /// parameter square onto those two triangles carries from σ' ≤ σ: so
    /// every prefix is a subset of every later one and of the completed
    /// strip, and a cut once made stays where it is (a strip whose diagonal
    /// followed the moving edge turned the part already cut wherever the
    /// segment is twisted, and with it the sides of nodes already enriched).
    /// Its front in that segment runs A(σ) – D(σ) – B(σ), bent at the
    /// diagonal point D(σ) = a0 + σ (b1 − a0): the edge itself where the
    /// segment is planar (a rotation or translation in its plane), within
    /// the segment's twist of it otherwise. `None` while it has no area.
    fn strip(&self, t: f64) -> Result<Option<TriangleSurface>, crate::surface::SurfaceError> {
        let [a0, b0] = self.keyframes[0].1;
        let scale = (b0 - a0).norm();
        let mut vertices: Vec<Point3<f64>> = Vec::new();
        let mut triangles = Vec::new();
        let mut push = |p: [Point3<f64>; 3]| {
            let area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
            if area > 1e-12 * scale * scale {
                let base = vertices.len();
                vertices.extend_from_slice(&p);
                triangles.push([base, base + 1, base + 2]);
            }
        };
        for w in self.keyframes.windows(2) {
            let ((t0, [a0, b0]), (t1, [a1, b1])) = (w[0], w[1]);
            if t <= t0 {
                break;
            }
            if t >= t1 {
                push([a0, b0, b1]);
                push([a0, b1, a1]);
                continue;
            }
            let s = (t - t0) / (t1 - t0);
            let at = |p: Point3<f64>, q: Point3<f64>| p + (q - p) * s;
            let (a, b, d) = (at(a0, a1), at(b0, b1), at(a0, b1));
            push([a0, b0, b]);
            push([a0, b, d]);
            push([a0, d, a]);
        }
        if triangles.is_empty() {
            return Ok(None);
        }
        let (vertices, triangles) = weld(vertices, triangles);
        TriangleSurface::new(vertices, triangles, Path::new("blade")).map(Some)
    }
}

/// Merges bit-identical vertices of a triangle soup (the strip's triangles
/// share corners computed once), so that its shared edges are interior.
fn weld(
    vertices: Vec<Point3<f64>>,
    triangles: Vec<[usize; 3]>,
) -> (Vec<Point3<f64>>, Vec<[usize; 3]>) {
    let mut index: std::collections::HashMap<[u64; 3], usize> = std::collections::HashMap::new();
    let mut kept = Vec::new();
    let mut map = Vec::with_capacity(vertices.len());
    for p in &vertices {
        let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
        let k = *index.entry(key).or_insert_with(|| {
            kept.push(*p);
            kept.len() - 1
        });
        map.push(k);
    }
    let triangles = triangles.into_iter().map(|t| t.map(|i| map[i])).collect();
    (kept, triangles)
}

/// The smallest dihedral angle at which two consecutive triangles of a
/// path's strip may meet (radians; 45°): below it the strip folds back onto
/// what it has swept.
pub const FOLD_ANGLE: f64 = std::f64::consts::FRAC_PI_4;

/// The dihedral angle (0 … π) between two triangles sharing an edge (two
/// bit-identical corners), `None` if they share none.
fn dihedral(p: &[Point3<f64>; 3], q: &[Point3<f64>; 3]) -> Option<f64> {
    let shared: Vec<Point3<f64>> = p.iter().filter(|x| q.contains(x)).copied().collect();
    let [s0, s1] = shared[..] else {
        return None;
    };
    let apex = |t: &[Point3<f64>; 3]| t.iter().find(|x| **x != s0 && **x != s1).copied();
    let (r, t) = (apex(p)?, apex(q)?);
    let e = (s1 - s0).normalize();
    let off = |x: Point3<f64>| {
        let w = x - s0;
        w - e * w.dot(&e)
    };
    let (u, v) = (off(r), off(t));
    let c = u.dot(&v) / (u.norm() * v.norm());
    c.is_finite().then(|| c.clamp(-1.0, 1.0).acos())
}

/// A blade's swept surface at some time.
#[derive(Debug, Clone)]
pub enum Swept {
    /// A completed straight sweep: the patch origin = a, u = b − a, v = travel.
    Patch(PlanarPatch),
    /// A straight sweep under way.
    Growing(GrowingPatch),
    /// A path's ruled strip (boxed: a triangle surface carries its index).
    Strip(Box<TriangleSurface>),
}

impl Swept {
    pub fn surface(&self) -> &dyn CutSurface {
        match self {
            Swept::Patch(p) => p,
            Swept::Growing(g) => g,
            Swept::Strip(s) => s.as_ref(),
        }
    }

    /// The swept surface, owned.
    pub fn into_surface(self) -> Box<dyn CutSurface> {
        match self {
            Swept::Patch(p) => Box::new(p),
            Swept::Growing(g) => Box::new(g),
            Swept::Strip(s) => s,
        }
    }
}

/// A straight sweep under way: the patch swept so far (`part`, v = the
/// travel so far) with the level set of the completed one (`full`). Both
/// planes are the same, but u × (c v) normalised differs from u × v in the
/// last bits: taking Λ from `full` keeps it, and so the sub-tets, bit for
/// bit the same at every step, so that a step changes the set-up only where
/// the patch has reached new elements.
#[derive(Debug, Clone)]
pub struct GrowingPatch {
    pub full: PlanarPatch,
    pub part: PlanarPatch,
}

impl CutSurface for GrowingPatch {
    fn level_set(&self, x: &Point3<f64>) -> f64 {
        self.full.level_set(x)
    }

    fn overlaps(&self, poly: &[Point3<f64>], reach: f64, touch: f64) -> bool {
        self.part.overlaps(poly, reach, touch)
    }

    fn contains(&self, x: &Point3<f64>, tol: f64) -> bool {
        self.part.contains(x, tol)
    }

    fn boundary(&self) -> Vec<[Point3<f64>; 2]> {
        self.part.boundary()
    }

    fn behind_front(&self, x: &Point3<f64>, front: &[[Point3<f64>; 2]]) -> bool {
        self.part.behind_front(x, front)
    }
}

/// One `[[cut]]` of a scene: a surface given up front, or a blade.
pub enum CutItem {
    Surface(Box<dyn CutSurface>),
    Blade(Blade),
}

/// The cuts of a scene, in scene order (their index names them in errors).
pub struct CutSet {
    pub items: Vec<CutItem>,
    pub snap: f64,
    /// How every front is treated: [`FrontMode::Extend`] (the cut extended
    /// through front elements) or [`FrontMode::Tip`] (branch functions at
    /// the nodes of front elements; the front moves with the blade, so
    /// every step of a sweep is a cut event).
    pub front: FrontMode,
    /// Per item, what its `[[cut]]` table says (its own `snap`, `front` and
    /// `tip_radius`); items beyond it take `snap` and `front` above and no
    /// radius (sets built in code).
    pub options: Vec<CutOptions>,
}

/// How one cut of a [`CutSet`] is set up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutOptions {
    pub snap: f64,
    pub front: FrontMode,
    /// `Some(R)`: tip-enrich every node within R of the front (geometric).
    pub tip_radius: Option<f64>,
    /// The blending elements' treatment; `None`: a case's default
    /// ([`crate::cut::Blending::for_cut`]). No case key sets it: studies
    /// and examples compare the treatments with it.
    pub blending: Option<crate::cut::Blending>,
}

impl CutOptions {
    /// What the set-up takes on a mesh of `kind`.
    pub fn blending(&self, kind: crate::mesh::ElementKind) -> crate::cut::Blending {
        self.blending
            .unwrap_or_else(|| crate::cut::Blending::for_cut(self.front, self.tip_radius, kind))
    }
}

impl CutSet {
    /// The cuts of a scene: its patches, its surfaces read from their files,
    /// its blades; each set up with its own keys (`CutSpec::options`), as the
    /// static set-up takes them.
    pub fn from_scene(scene: &crate::scene::Scene) -> Result<CutSet, BladeError> {
        use crate::scene::CutGeometry;
        let mut items = Vec::with_capacity(scene.cuts.len());
        for (index, c) in scene.cuts.iter().enumerate() {
            items.push(match &c.geometry {
                CutGeometry::Patch(p) => CutItem::Surface(Box::new(p.clone())),
                CutGeometry::Surface(path) => CutItem::Surface(Box::new(
                    TriangleSurface::read(path)
                        .map_err(|source| BladeError::Surface { index, source })?,
                )),
                CutGeometry::Blade { keyframes, travel } => CutItem::Blade(Blade {
                    event_travel: c.event_travel,
                    ..Blade::from_keyframes(index, keyframes.clone(), *travel)?
                }),
            });
        }
        // Each cut as its table says (as the static set-up takes them:
        // `CutSpec::input`); the set's own snap and front are cut[0]'s.
        let options: Vec<CutOptions> = scene
            .cuts
            .iter()
            .map(crate::scene::CutSpec::options)
            .collect();
        let (snap, front) = options
            .first()
            .map_or((crate::cut::DEFAULT_SNAP, FrontMode::Tip), |o| {
                (o.snap, o.front)
            });
        Ok(CutSet {
            items,
            snap,
            front,
            options,
        })
    }

    /// How item `k` is set up.
    pub fn options(&self, k: usize) -> CutOptions {
        self.options.get(k).copied().unwrap_or(CutOptions {
            snap: self.snap,
            front: self.front,
            tip_radius: None,
            blending: None,
        })
    }

    pub fn blades(&self) -> impl Iterator<Item = &Blade> {
        self.items.iter().filter_map(|c| match c {
            CutItem::Blade(b) => Some(b),
            CutItem::Surface(_) => None,
        })
    }

    /// The earliest start and latest end of its blades.
    pub fn sweep_span(&self) -> Option<(f64, f64)> {
        self.blades().fold(None, |acc, b| {
            Some(match acc {
                None => (b.start(), b.end()),
                Some((s, e)) => (s.min(b.start()), e.max(b.end())),
            })
        })
    }

    /// The edges of the blades cutting at time t (start ≤ t ≤ end), for output.
    pub fn edges_at(&self, t: f64) -> Vec<[Point3<f64>; 2]> {
        self.blades()
            .filter(|b| b.start() <= t && t <= b.end())
            .map(|b| b.edge_at(t))
            .collect()
    }

    /// The cut set-up at time t: each blade's swept surface so far; a blade
    /// whose surface does not yet cut the body is left out.
    pub fn setup_at(&self, mesh: &TetMesh, t: f64) -> Result<Option<CutSetup>, BladeError> {
        self.setup(mesh, t, false)
    }

    /// The set-up with every blade's sweep complete (static scenes, and the
    /// check of a scene's blades before it runs): a blade that cuts nothing
    /// or meets another cut is an error naming it.
    pub fn completed(&self, mesh: &TetMesh) -> Result<Option<CutSetup>, BladeError> {
        self.setup(mesh, f64::INFINITY, true)
    }

    fn setup(&self, mesh: &TetMesh, t: f64, strict: bool) -> Result<Option<CutSetup>, BladeError> {
        let swept: Vec<Option<Swept>> = self
            .items
            .iter()
            .map(|c| match c {
                CutItem::Blade(b) => b.swept(t),
                CutItem::Surface(_) => None,
            })
            .collect();
        // (scene index, surface) of what takes part.
        let mut parts: Vec<(usize, &dyn CutSurface)> = Vec::new();
        for (k, c) in self.items.iter().enumerate() {
            match c {
                CutItem::Surface(s) => parts.push((k, s.as_ref())),
                CutItem::Blade(b) => {
                    if let Some(s) = &swept[k] {
                        parts.push((k, s.surface()));
                    } else if strict {
                        return Err(BladeError::Misses {
                            index: k,
                            key: b.key(),
                        });
                    }
                }
            }
        }
        loop {
            if parts.is_empty() {
                return Ok(None);
            }
            let inputs: Vec<CutInput<'_>> = parts
                .iter()
                .map(|p| {
                    let o = self.options(p.0);
                    CutInput {
                        surface: p.1,
                        snap: o.snap,
                        front: o.front,
                        tip_radius: o.tip_radius,
                        blending: o.blending(mesh.kind),
                    }
                })
                .collect();
            match setup_cut(mesh, &inputs) {
                Ok(s) => return Ok(Some(s)),
                Err(CutError::Misses(j)) => {
                    let k = parts[j].0;
                    match (&self.items[k], strict) {
                        (CutItem::Blade(_), false) => {
                            parts.remove(j);
                        }
                        (CutItem::Blade(b), true) => {
                            return Err(BladeError::Misses {
                                index: k,
                                key: b.key(),
                            })
                        }
                        (CutItem::Surface(_), _) => return Err(CutError::Misses(k).into()),
                    }
                }
                Err(CutError::Meet {
                    first,
                    second,
                    element,
                }) => {
                    let (a, b) = (parts[first].0, parts[second].0);
                    let (index, other) = if matches!(self.items[b], CutItem::Blade(_)) {
                        (b, a)
                    } else {
                        (a, b)
                    };
                    let key = match &self.items[index] {
                        CutItem::Blade(blade) => blade.key(),
                        CutItem::Surface(_) => "blade",
                    };
                    return Err(BladeError::Meets {
                        index,
                        key,
                        other,
                        element,
                    });
                }
                Err(CutError::Degenerate(j)) => return Err(CutError::Degenerate(parts[j].0).into()),
            }
        }
    }
}

/// Which steps can change the cut set-up, so that the others skip the check.
///
/// A straight sweep keeps its plane, so the snapped level set and each
/// crossed element's section polygon are fixed; only the patch grows, along
/// t (the travel coordinate of the completed patch, t = f at fraction f of
/// the sweep). An element's classification (seed section 5.2 rules in
/// [`crate::cut`]) can then change only where f passes
/// - the lowest t of its polygon inside the strip 0 ≤ s ≤ 1 (it becomes cut),
/// - the highest t of its polygon (it stops containing the front),
/// - the lowest t of a face lying in the plane inside the strip (the face
///   opens: a node on the cut may become enriched);
///
/// the enrichment follows the classification. These critical fractions are
/// computed once; a step is checked only when (f_prev, f_now] holds one (with
/// a 1e-6 margin). A path's strip moves, so every step of its sweep is checked.
struct SweepIndex {
    straight: Vec<StraightSweep>,
    /// Sweep spans of the other blades.
    paths: Vec<(f64, f64)>,
}

/// A straight blade's span and the sorted fractions at which its set-up may change.
struct StraightSweep {
    start: f64,
    end: f64,
    critical: Vec<f64>,
}

/// Clips the convex polygon `pts` (s, t) to lo ≤ s ≤ hi; returns its t range.
fn clipped_t_range(pts: &[(f64, f64)], lo: f64, hi: f64) -> Option<(f64, f64)> {
    let mut poly = pts.to_vec();
    for (bound, keep_above) in [(lo, true), (hi, false)] {
        let inside = |p: &(f64, f64)| {
            if keep_above {
                p.0 >= bound
            } else {
                p.0 <= bound
            }
        };
        let mut out = Vec::with_capacity(poly.len() + 2);
        for k in 0..poly.len() {
            let (a, b) = (poly[k], poly[(k + 1) % poly.len()]);
            if inside(&a) {
                out.push(a);
            }
            if inside(&a) != inside(&b) && a.0 != b.0 {
                let w = (bound - a.0) / (b.0 - a.0);
                out.push((bound, a.1 + w * (b.1 - a.1)));
            }
        }
        poly = out;
        if poly.is_empty() {
            return None;
        }
    }
    let tmin = poly.iter().map(|p| p.1).fold(f64::INFINITY, f64::min);
    let tmax = poly.iter().map(|p| p.1).fold(f64::NEG_INFINITY, f64::max);
    Some((tmin, tmax))
}

/// The t range of the convex polygon `pts` (s, t) inside the strip
/// 0 ≤ s ≤ 1 from the fraction the patch first overlaps it: its lowest t,
/// or 0 where the polygon reaches behind the blade's start (the edge starts
/// inside the body: the patch [0, 1] × [0, f] meets it from the first
/// step). `None` where the strip misses it or it lies wholly behind the
/// start (never swept).
fn swept_onset(pts: &[(f64, f64)]) -> Option<(f64, f64)> {
    let (lo, hi) = clipped_t_range(pts, 0.0, 1.0)?;
    (hi >= 0.0).then_some((lo.max(0.0), hi))
}

impl SweepIndex {
    fn new(cuts: &CutSet, mesh: &TetMesh) -> SweepIndex {
        let mut h = vec![f64::INFINITY; mesh.n_nodes()];
        for e in 0..mesh.n_elements() {
            let he = mesh.element_size(e);
            for &i in mesh.element(e) {
                h[i] = h[i].min(he);
            }
        }
        let mut straight = Vec::new();
        let mut paths = Vec::new();
        for b in cuts.blades() {
            let options = cuts.options(b.index);
            let straight_patch = match b.swept(b.end()) {
                Some(Swept::Patch(p)) if options.front == FrontMode::Extend => Some(p),
                _ => None,
            };
            let Some(p) = straight_patch else {
                // A path, or a tip front (ψ moves with the edge): every step.
                paths.push((b.start(), b.end()));
                continue;
            };
            // The level set snapped as the set-up does it.
            let phi: Vec<f64> = mesh
                .nodes
                .iter()
                .zip(&h)
                .map(|(x, hi)| {
                    let f = p.level_set(x);
                    if f.abs() < options.snap * hi {
                        0.0
                    } else {
                        f
                    }
                })
                .collect();
            let mut critical = Vec::new();
            for e in 0..mesh.n_elements() {
                let v = mesh.vertices(e);
                let f = v.map(|i| phi[i]);
                let crossed = f.iter().any(|&x| x > 0.0) && f.iter().any(|&x| x < 0.0);
                if crossed {
                    let poly = crate::cut::section_polygon(&mesh.vertex_points(e), &f);
                    let st: Vec<(f64, f64)> = poly.iter().map(|x| p.coordinates(x)).collect();
                    if let Some((onset, _)) = swept_onset(&st) {
                        critical.push(onset);
                        critical.push(st.iter().map(|c| c.1).fold(f64::NEG_INFINITY, f64::max));
                    }
                }
                for face in crate::mesh::TET_FACES {
                    let tri = face.map(|k| v[k]);
                    if tri.iter().all(|&j| phi[j] == 0.0) {
                        // An extended front opens such a face once the patch
                        // overlaps it ([`crate::cut`]).
                        let st: Vec<(f64, f64)> =
                            tri.iter().map(|&j| p.coordinates(&mesh.nodes[j])).collect();
                        if let Some((onset, _)) = swept_onset(&st) {
                            critical.push(onset);
                        }
                    }
                }
            }
            critical.retain(|c| c.is_finite());
            critical.sort_by(f64::total_cmp);
            straight.push(StraightSweep {
                start: b.start(),
                end: b.end(),
                critical,
            });
        }
        SweepIndex { straight, paths }
    }

    /// Whether the set-up may differ between times t0 < t1.
    fn may_change(&self, t0: f64, t1: f64) -> bool {
        let active = |start: f64, end: f64| t1 > start && t0 < end;
        if self.paths.iter().any(|&(s, e)| active(s, e)) {
            return true;
        }
        let margin = 1e-6;
        self.straight.iter().any(|sw| {
            if !active(sw.start, sw.end) {
                return false;
            }
            let frac = |t: f64| ((t - sw.start) / (sw.end - sw.start)).clamp(0.0, 1.0);
            let (f0, f1) = (frac(t0) - margin, frac(t1) + margin);
            let k = sw.critical.partition_point(|&c| c < f0);
            k < sw.critical.len() && sw.critical[k] <= f1
        })
    }
}

/// Whether two set-ups give the same model (enrichment, sides of enriched
/// nodes, element classification and sub-tets, these and the front's
/// level set to round-off: see [`close_element_cut`] and [`close_levels`]).
pub fn same_setup(a: Option<&CutSetup>, b: Option<&CutSetup>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.enriched == b.enriched
                && a.tip == b.tip
                && close_levels(&a.front_level, &b.front_level)
                && a.enriched
                    .iter()
                    .zip(a.node_side.iter().zip(&b.node_side))
                    .all(|(e, (x, y))| e.is_none() || x == y)
                && a.elements.len() == b.elements.len()
                && a.elements
                    .iter()
                    .zip(&b.elements)
                    .all(|(x, y)| close_element_cut(x, y))
        }
        _ => false,
    }
}

/// Whether two fronts' level sets ψ are the same to round-off: within
/// [`SAME_POINT`] of the largest |ψ| (a length of the body's size). A
/// path's sides are measured from its strip's segments, which end at the
/// current edge: once the edge has left the body a step moves nothing
/// inside it, but ψ moves by ~1e-17 m; an exact comparison made that step
/// an event, whose projection onto the same functions (the rates' damped
/// fit of then) changed the kinetic energy by 1e-3 and the
/// trajectory by 1e-4 (a random Tet10 sweep as a straight three-keyframe
/// path against the same travel, found by the CLI fuzz).
fn close_levels(a: &[f64], b: &[f64]) -> bool {
    if a.len() != b.len() {
        return false;
    }
    // (A node of a second cut's set-up holds ψ = ∞: equal only to itself.)
    let scale = a
        .iter()
        .chain(b)
        .filter(|x| x.is_finite())
        .fold(0.0, |m: f64, x| m.max(x.abs()));
    a.iter().zip(b).all(|(x, y)| {
        x == y || (x.is_finite() && y.is_finite() && (x - y).abs() <= SAME_POINT * scale)
    })
}

/// Sub-tet vertices this close (relative to their coordinates and their
/// sub-tet's extent) are the same point.
const SAME_POINT: f64 = 1e-12;

/// Whether two element classifications are the same, their sub-tets' vertices
/// to round-off ([`SAME_POINT`]). A path's strip is measured from triangles
/// that change at every step, so a step that swept nothing new (a straight
/// path's strip grows in its own plane) moves the sub-tets by ~1e-17 m: an
/// exact comparison made an event of every such step (15 instead of 6 in a
/// random 300-element sweep), each integrating the cut elements again for
/// the same model.
fn close_element_cut(a: &ElementCut, b: &ElementCut) -> bool {
    match (a, b) {
        (
            ElementCut::Cut {
                sub_tets: s,
                partial: p,
            },
            ElementCut::Cut {
                sub_tets: t,
                partial: q,
            },
        ) => {
            p == q
                && s.len() == t.len()
                && s.iter().zip(t).all(|(x, y)| {
                    let extent = x
                        .vertices
                        .iter()
                        .map(|v| (v - x.vertices[0]).amax() + v.coords.amax())
                        .fold(0.0, f64::max);
                    x.side == y.side
                        && x.vertices
                            .iter()
                            .zip(&y.vertices)
                            .all(|(v, w)| (v - w).amax() <= SAME_POINT * extent)
                })
        }
        _ => crate::model::same_element_cut(a, b),
    }
}

/// Maps a state of `old` onto the DOFs of `new` (the same mesh, a grown
/// cut): standard DOFs keep their values, enriched DOFs of nodes enriched in
/// both keep theirs, new enriched DOFs start at zero. Where an enriched
/// node's side Hᵢ flips (a path's strip moved), uᵢ' = uᵢ − Hᵢ aᵢ keeps the
/// field: uᵢ + (H − Hᵢ)/2 aᵢ = uᵢ' + (H + Hᵢ)/2 aᵢ. With a tip front, a
/// node's tip block is kept while it stays tip-enriched; a node the front
/// has passed (tip → Heaviside) starts its Heaviside DOFs at zero and drops
/// its tip DOFs; then [`project_tip_change`] fits the DOFs whose meaning
/// changed (every tip block, the Heaviside DOFs of nodes tip-enriched
/// before) to the old field, for d, v and a; the event's energies show what
/// remains. Rotations start at the identity (corotational steps recompute
/// them from d).
pub fn map_state(old: &Model, new: &Model, state: &State) -> State {
    map_state_reported(old, new, state).0
}

/// [`map_state`], with what its projection did (`None`: nothing to project).
pub fn map_state_reported(old: &Model, new: &Model, state: &State) -> (State, Option<Projection>) {
    map_state_reported_with(old, new, state, Parallelism::SEQUENTIAL)
}

/// [`map_state_reported`], its projection on `parallelism`'s threads.
pub fn map_state_reported_with(
    old: &Model,
    new: &Model,
    state: &State,
    parallelism: Parallelism,
) -> (State, Option<Projection>) {
    map_state_fitted_with(old, new, state, &TipFits::new(), parallelism)
}

/// [`map_state_reported_with`] with the integrals `fits` of the elements
/// that [`Model::update_cut_fitted_with`] took on its way from `old` (whose
/// field `state` is) to `new`: the projection evaluates the old field and
/// the new functions only on the other elements (the same fit up to
/// round-off: the same points, summed in another order).
pub fn map_state_fitted_with(
    old: &Model,
    new: &Model,
    state: &State,
    fits: &TipFits,
    parallelism: Parallelism,
) -> (State, Option<Projection>) {
    let mut cache = ProjectionCache::default();
    map_state_fitted_cached(old, new, state, fits, parallelism, &mut cache)
}

/// The symbolic factorisation of `model`'s system in a sweep, at its start
/// and at each event that changes the pattern: from
/// [`NESTED_DISSECTION_FROM`](crate::solve::NESTED_DISSECTION_FROM)
/// equations on, METIS nested dissection on the shape-function graph (what
/// [`Cholesky::fill_reducing`] takes there for a scene without blades);
/// below, AMD (the cheapest analysis, and at 1k Tet4 the cheapest factor
/// too: the rule's other candidates would each cost an event another
/// analysis).
pub fn sweep_factor(model: &Model) -> Result<Cholesky, SolveError> {
    if model.pattern.n >= crate::solve::NESTED_DISSECTION_FROM {
        let shapes = crate::assembly::equation_shapes(model);
        Cholesky::nested_dissection(&model.pattern, Some(&shapes), Parallelism::SEQUENTIAL)
    } else {
        Cholesky::new(&model.pattern)
    }
}

/// What a sweep's projections keep from one event to the next: the Gram
/// system's symbolic factorisation, taken again where the next event's
/// Gram has the same pattern (the same fitted functions coupled alike: a
/// front moving inside the elements it holds). Its analysis (AMD and the
/// symbolic factorisation) took as long as the numeric factorisation at
/// the events of `examples/tip_event.rs`: 0.6–0.9 against 1.1 ms (483
/// equations, 1k Tet4), 2.4–3.6 against 3.2–3.7 ms (1500, 1k Tet10).
#[derive(Default)]
pub struct ProjectionCache {
    gram: Option<Cholesky>,
    /// Projections whose Gram took the symbolic factorisation kept.
    pub reused: usize,
}

/// [`map_state_fitted_with`] keeping what the next event's projection can
/// take again in `cache` (the same projection, to the bit).
pub fn map_state_fitted_cached(
    old: &Model,
    new: &Model,
    state: &State,
    fits: &TipFits,
    parallelism: Parallelism,
    cache: &mut ProjectionCache,
) -> (State, Option<Projection>) {
    let mut mapped = map_state_unprojected(old, new, state);
    let report = project_fitted(old, new, state, &mut mapped, fits, parallelism, cache);
    // Enriched DOFs prescribed at a fixed node hold zero (a fit may have set
    // the prescribed components of a partly fixed shape function).
    let first_enriched = 3 * new.mesh.n_nodes();
    for p in new.prescribed.iter().filter(|p| p.dof >= first_enriched) {
        mapped.d[p.dof] = p.value;
        mapped.v[p.dof] = 0.0;
        mapped.a[p.dof] = 0.0;
    }
    (mapped, report)
}

/// How a Gram system of [`project_tip_change`] was solved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GramSolve {
    /// Cholesky of the Jacobi-scaled matrix, its pivots well above round-off.
    Cholesky,
    /// A pseudo-inverse of the scaled matrix (symmetric eigen-decomposition):
    /// `dropped` directions with eigenvalues under [`GRAM_RANK_TOL`] × the
    /// largest (functions nearly dependent on the others) got no coefficient.
    Pseudo { dropped: usize },
}

/// What the projection at a cut event did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// Scalar shape functions fitted (3 DOFs each).
    pub fitted: usize,
    /// How the Gram system (the displacement's, velocity's and
    /// acceleration's, one energy-weighted norm) was solved.
    pub solve: GramSolve,
    /// Smallest over largest eigenvalue (pseudo-inverse) or squared pivot
    /// (Cholesky) of the scaled Gram matrix.
    pub conditioning: f64,
}

/// Relative eigenvalue (or squared Cholesky pivot) of a Jacobi-scaled Gram
/// matrix under which its functions count as dependent: the scaled matrix
/// has unit diagonal, so 1e-12 leaves six digits of a double in the fit.
pub const GRAM_RANK_TOL: f64 = 1e-12;

/// Weight of the strain term of the displacement's fit, in units of the
/// element size h squared: the fit minimises over each element
/// ∫ |e|² + (h²/4) ε(e):C:ε(e) / μ (e = u_new − u_old), so the strain
/// the new field carries is the old one's, not only its displacement (an
/// L² fit of branch functions times quadratic shapes matches u to 1e-3 and
/// leaves 20 % of the strain energy of a Tet10 front element behind), and
/// weighted as the energy weighs it: with |∇e|² in its place (the H¹ fit
/// this replaced), a nearly incompressible body (ν = 0.49, λ/μ = 49)
/// took the misfit's volume change at 1/49 of its energy and changed the
/// energy at an event by up to 78 % (7.8 % at ν = 0.3).
const GRADIENT_WEIGHT: f64 = 0.25;

/// Least-squares projection at a cut event where DOFs change meaning (a
/// tip front moved: its branch functions follow it, and nodes it passed
/// turn from tip- to Heaviside-enriched; METHODS.md, "Blades"). The fitted
/// DOFs F are every tip block of `new`, the Heaviside DOFs of nodes
/// tip-enriched in `old`, and every other free shape function of the
/// elements holding tip functions in `old` or `new` (where the field
/// changed); the others keep their mapped values. Over the elements holding
/// an F shape function (the quadrature points of [`Model::field_points`],
/// side by side) F minimises, for the displacement, the velocity and the
/// acceleration alike, the energy-weighted misfit ∫ |e|² + β ε(e):C:ε(e)/μ
/// (β = [`GRADIENT_WEIGHT`] h² per element, e = u_new − u_old, v_new −
/// v_old or a_new − a_old; one system for the three components, which the
/// strain couples): G a_F = the same form of the shape functions against
/// r = u_old − Σ_{b∉F} φ_b a_b. One projection P for the three fields
/// keeps the state consistent: P v is the rate of P u, P a that of P v.
/// The rates take the strain term too: with
/// the L² misfit alone (and a Tikhonov damping of 1e-7 against nearly
/// dependent functions) the velocity of a Heaviside function whose other
/// side is a corner of 1e-6 of its elements, where it and its neighbours'
/// functions are O(δ²), was fitted by coefficients of 1e4 m/s where the
/// body moved at 0.4 m/s: the kinetic energy stayed, but the corner's
/// strain rate inverted it within the next step (a soft Tet10 gmsh beam
/// whose blade frees its top, Newton failed at t = 0.19 s; with the strain
/// term it runs, and needs no damping). The Gram matrix is scaled to unit
/// diagonal and solved by Cholesky, or where its pivots reach round-off by
/// a pseudo-inverse ([`GramSolve`]); the returned [`Projection`] says
/// which. Nothing is done (`None`) without
/// tip nodes (shifted Heaviside DOFs starting at zero keep the field
/// exactly). A field the new space holds on those elements (a linear one,
/// say) is reproduced to round-off.
pub fn project_tip_change(
    old: &Model,
    new: &Model,
    state: &State,
    mapped: &mut State,
) -> Option<Projection> {
    project_tip_change_with(old, new, state, mapped, Parallelism::SEQUENTIAL)
}

/// What [`project_tip_change`] integrates on one element: its fitted
/// functions (local index, slot), the strain term's weight β, the L² and
/// gradient Gram products (nl × nl; 3nl × 3nl, ∫ ∂_c φ_i ∂_d φ_j at
/// (3i + c, 3j + d)) and the right-hand sides of the displacement, the
/// velocity and the acceleration (3 nl each).
struct ElementFit {
    local: Vec<(usize, usize)>,
    beta: f64,
    l2: nalgebra::DMatrix<f64>,
    g2: nalgebra::DMatrix<f64>,
    rhs: [Vec<f64>; 3],
}

/// [`project_tip_change`] with the elements integrated on `parallelism`'s
/// threads (the same fit whatever their number: each element's terms are
/// computed alone and added in element order).
pub fn project_tip_change_with(
    old: &Model,
    new: &Model,
    state: &State,
    mapped: &mut State,
    parallelism: Parallelism,
) -> Option<Projection> {
    let mut cache = ProjectionCache::default();
    project_fitted(
        old,
        new,
        state,
        mapped,
        &TipFits::new(),
        parallelism,
        &mut cache,
    )
}

/// The shape functions a projection at a cut event from `old` to `new`
/// fits (ids in `new`, in the fit's order): every tip block of `new`, the
/// Heaviside functions of nodes tip-enriched in `old`, and every other free
/// function of the elements holding tip functions in `old` or `new`.
/// Without a tip front in either: the free functions of the elements whose
/// field the mapping changed ([`changed_heaviside_elements`]). `None` where
/// nothing changed.
fn fitted_functions(old: &Model, new: &Model, state: &State, mapped: &State) -> Option<Vec<usize>> {
    let (Some(oc), Some(nc)) = (&old.cut, &new.cut) else {
        return None;
    };
    if oc.n_tip == 0 && nc.n_tip == 0 {
        let (mut marked, mut fitted) = (vec![false; new.n_shape], Vec::new());
        for e in changed_heaviside_elements(old, new, state, mapped) {
            push_free_functions(new, e, &mut marked, &mut fitted);
        }
        return (!fitted.is_empty()).then_some(fitted);
    }
    let n_nodes = new.mesh.n_nodes();
    let mut fitted = Vec::new();
    // A shape function whose three components are prescribed (an enriched
    // one of a fixed node: zero) takes no part in the fit.
    let held = |s: usize| (0..3).all(|c| new.equation[3 * s + c] == crate::model::NONE);
    for i in 0..n_nodes {
        if let Some(t) = nc.tip.get(i).copied().flatten() {
            for b in 0..crate::front::N_BRANCH {
                let s = n_nodes + nc.n_enriched + crate::front::N_BRANCH * t + b;
                if !held(s) {
                    fitted.push(s);
                }
            }
        }
        if let (Some(j), Some(_)) = (nc.enriched[i], oc.tip.get(i).copied().flatten()) {
            if !held(n_nodes + j) {
                fitted.push(n_nodes + j);
            }
        }
    }
    if fitted.is_empty() {
        return None;
    }
    // The other free shape functions of the elements whose field changed
    // (holding tip functions before or after): fitting only the DOFs that
    // changed meaning leaves the strain of the old front's branch functions
    // to them alone (a Tet10 event then changed the energy by 22 %, 0.3 %
    // with these).
    let mut marked = vec![false; new.n_shape];
    for &s in &fitted {
        marked[s] = true;
    }
    for e in 0..new.mesh.n_elements() {
        let conn = new.mesh.element(e);
        if nc.holds_tip(conn) || oc.holds_tip(conn) {
            push_free_functions(new, e, &mut marked, &mut fitted);
        }
    }
    Some(fitted)
}

/// Appends to `fitted` the free shape functions of element `e` of `new`
/// not yet `marked` (a function with a prescribed component takes no part
/// in a fit), and marks them.
fn push_free_functions(new: &Model, e: usize, marked: &mut [bool], fitted: &mut Vec<usize>) {
    for &s in new.element_shapes(e) {
        let s = s as usize;
        let free = (0..3).all(|c| new.equation[3 * s + c] != crate::model::NONE);
        if free && !marked[s] {
            marked[s] = true;
            fitted.push(s);
        }
    }
}

/// The elements whose field the mapping to `new` changed at an event
/// without a tip front: those holding a node enriched in `old` with a
/// nonzero DOF and either whose cut changed (cells, side) or where such a
/// node's enrichment was dropped, and where the old field (`state`) and
/// the mapped one differ at a field point by more than [`KEPT_FIELD`] of
/// the largest DOF of d, v or a. A straight sweep only adds enrichment
/// that starts at zero, and cuts elements whose nodes held none (the plane
/// crossed them outside the patch): none, and nothing evaluated. (At the
/// 1k Tet4 / 10k Tet4 / 1k Tet10 events of bench `blade` the check adds
/// 0.01 / 0.06 / 0.02 ms to the state's map; evaluating every element
/// whose model changed added 0.18 / 0.56 / 0.27 ms.) A path's strip whose
/// extension to the element faces turns with it (`front = "extend"`)
/// drops enrichment and recuts elements: before, their DOFs were dropped
/// and the field left as it fell (a blade along a V-shaped path: the
/// energy rose 8e3-fold (Tet4) and 4e4-fold (Tet10) at the turning event;
/// fitted, 56- and 53-fold, the opening of the turned extension healing;
/// `tests/blade.rs`).
fn changed_heaviside_elements(
    old: &Model,
    new: &Model,
    state: &State,
    mapped: &State,
) -> Vec<usize> {
    let (Some(oc), Some(nc)) = (&old.cut, &new.cut) else {
        return Vec::new();
    };
    let dropped: Vec<bool> = oc
        .enriched
        .iter()
        .zip(&nc.enriched)
        .map(|(a, b)| a.is_some() && b.is_none())
        .collect();
    let scale = |x: &[f64]| x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tol = [&state.d, &state.v, &state.a].map(|x| KEPT_FIELD * scale(x));
    let value = |x: &[f64], ids: &[u32], vals: &[f64]| {
        ids.iter()
            .zip(vals)
            .fold(Vector3::zeros(), |acc, (&s, &w)| {
                let s = 3 * s as usize;
                acc + Vector3::new(x[s], x[s + 1], x[s + 2]) * w
            })
    };
    // A node enriched in `old` whose enriched DOFs hold something: without
    // one, an element's old field is its standard part, which the mapped
    // field keeps (new enriched DOFs start at zero), whatever its cut became.
    let n_nodes = new.mesh.n_nodes();
    let active: Vec<bool> = oc
        .enriched
        .iter()
        .map(|j| {
            j.is_some_and(|j| {
                let s = 3 * (n_nodes + j);
                [&state.d, &state.v, &state.a]
                    .iter()
                    .any(|x| x[s..s + 3].iter().any(|&v| v != 0.0))
            })
        })
        .collect();
    let mut points = Vec::new();
    (0..new.mesh.n_elements())
        .filter(|&e| {
            let conn = new.mesh.element(e);
            // Its cells the same and no active node's enrichment dropped:
            // the same functions (a new enriched DOF starts at zero, a
            // flipped side is mapped exactly).
            conn.iter().any(|&i| active[i])
                && (conn.iter().any(|&i| dropped[i] && active[i])
                    || !same_element_cut(&oc.elements[e], &nc.elements[e]))
        })
        .filter(|&e| {
            let (ids, old_ids) = (new.element_shapes(e), old.element_shapes(e));
            let (ev_new, ev_old) = (new.element_evaluator(e), old.element_evaluator(e));
            new.field_points_into(e, &ev_new, &mut points);
            let (mut vals, mut grads) = (vec![0.0; ids.len()], vec![Vector3::zeros(); ids.len()]);
            let (mut old_vals, mut old_grads) = (
                vec![0.0; old_ids.len()],
                vec![Vector3::zeros(); old_ids.len()],
            );
            points.iter().any(|&(x, _, side)| {
                ev_new.eval(&x, side, &mut vals, &mut grads);
                ev_old.eval(&x, ev_old.side_at(&x, side), &mut old_vals, &mut old_grads);
                [
                    (&state.d, &mapped.d),
                    (&state.v, &mapped.v),
                    (&state.a, &mapped.a),
                ]
                .iter()
                .zip(&tol)
                .any(|((o, n), &tol)| {
                    (value(o, old_ids, &old_vals) - value(n, ids, &vals)).amax() > tol
                })
            })
        })
        .collect()
}

/// How far, relative to the largest DOF, a field may move at an event
/// without a tip front before [`changed_heaviside_elements`] counts its
/// element as changed (round-off of the shifted enrichment's mapping).
const KEPT_FIELD: f64 = 1e-12;

/// [`project_tip_change_with`], an element's integrals taken from `fits`
/// where it has them ([`map_state_fitted_with`]).
fn project_fitted(
    old: &Model,
    new: &Model,
    state: &State,
    mapped: &mut State,
    fits: &TipFits,
    parallelism: Parallelism,
    cache: &mut ProjectionCache,
) -> Option<Projection> {
    let fitted = fitted_functions(old, new, state, mapped)?;
    let mut slot = vec![usize::MAX; new.n_shape];
    for (k, &s) in fitted.iter().enumerate() {
        slot[s] = k;
    }
    let nf = fitted.len();
    // λ/μ of the strain term.
    let ratio = new.lame.lambda / new.lame.mu;
    // The Gram matrix (3 nf: component c of function k at 3k + c) and the
    // right-hand sides of d, v and a.
    // Fitted functions sharing an element couple: the Gram
    // is sparse (a dense one of 3 nf = 1,500 took 35 ms to factorise).
    let local_slots = |e: usize| -> Vec<usize> {
        new.element_shapes(e)
            .iter()
            .map(|&s| slot[s as usize])
            .filter(|&k| k != usize::MAX)
            .collect()
    };
    let mut below = vec![Vec::new(); nf];
    for e in 0..new.mesh.n_elements() {
        let ks = local_slots(e);
        for &a in &ks {
            for &b in &ks {
                if a > b {
                    below[b].push(a);
                }
            }
        }
    }
    let mut gram_d = BlockGram::new(below);
    let mut rhs = [vec![0.0; 3 * nf], vec![0.0; 3 * nf], vec![0.0; 3 * nf]];
    // Per element holding a fitted function, side by side: its fitted
    // functions (local index, slot), their Grams' products and right-hand
    // sides; added below in element order.
    let elements: Vec<usize> = (0..new.mesh.n_elements())
        .filter(|&e| {
            new.element_shapes(e)
                .iter()
                .any(|&s| slot[s as usize] != usize::MAX)
        })
        .collect();
    let fits = parallelism.map(elements.len(), |k| {
        let e = elements[k];
        let at = ElementAt::new(new, e, &slot);
        if let Some(fit) = fits.get(&e) {
            return fitted_element(fit, at, &*mapped);
        }
        let old_ids = old.element_shapes(e);
        let unchanged = same_element_model(&new.mesh, old.cut.as_ref(), new.cut.as_ref(), e);
        if unchanged {
            unchanged_element(new, at, old_ids, state, &*mapped)
        } else {
            evaluated_element(old, new, at, state, &*mapped)
        }
    });
    for fit in fits {
        let (local, beta, l2, g2) = (&fit.local, fit.beta, &fit.l2, &fit.g2);
        for (i, &(_, sa)) in local.iter().enumerate() {
            for (total, own) in rhs.iter_mut().zip(&fit.rhs) {
                for c in 0..3 {
                    total[3 * sa + c] += own[3 * i + c];
                }
            }
            for (j, &(_, sb)) in local.iter().enumerate() {
                // The lower triangle (component c of function k is 3k + c).
                if sa < sb {
                    continue;
                }
                let trace: f64 = (0..3).map(|k| g2[(3 * i + k, 3 * j + k)]).sum();
                let block = gram_d.block(sa, sb);
                for ci in 0..3 {
                    for cj in 0..3 {
                        if sa == sb && ci < cj {
                            continue;
                        }
                        let mut v = beta
                            * (ratio * g2[(3 * i + ci, 3 * j + cj)] + g2[(3 * i + cj, 3 * j + ci)]);
                        if ci == cj {
                            v += l2[(i, j)] + beta * trace;
                        }
                        gram_d.add(block, ci, cj, v);
                    }
                }
            }
        }
    }
    let (x, how, conditioning) = gram_d.solve(rhs.into(), cache);
    for (k, &s) in fitted.iter().enumerate() {
        for c in 0..3 {
            mapped.d[3 * s + c] = x[0][3 * k + c];
            mapped.v[3 * s + c] = x[1][3 * k + c];
            mapped.a[3 * s + c] = x[2][3 * k + c];
        }
    }
    Some(Projection {
        fitted: nf,
        solve: how,
        conditioning,
    })
}

/// What the projection knows of an element holding a fitted function: its
/// index, shape functions (`Model::element_shapes`), fitted ones (local
/// index, slot), the strain term's weight β and λ/μ, and every shape
/// function's slot (`usize::MAX`: not fitted).
struct ElementAt<'a> {
    e: usize,
    ids: &'a [u32],
    local: Vec<(usize, usize)>,
    beta: f64,
    ratio: f64,
    slot: &'a [usize],
}

impl<'a> ElementAt<'a> {
    /// Element `e` of the new model `new`, its functions' slots `slot`
    /// (β = [`GRADIENT_WEIGHT`] h²).
    fn new(new: &'a Model, e: usize, slot: &'a [usize]) -> ElementAt<'a> {
        let ids = new.element_shapes(e);
        let local = ids
            .iter()
            .enumerate()
            .filter(|&(_, &s)| slot[s as usize] != usize::MAX)
            .map(|(a, &s)| (a, slot[s as usize]))
            .collect();
        let h = new.mesh.element_size(e);
        ElementAt {
            e,
            ids,
            local,
            beta: GRADIENT_WEIGHT * h * h,
            ratio: new.lame.lambda / new.lame.mu,
            slot,
        }
    }
}

/// An element's [`ElementFit`] from the old field and the new functions
/// evaluated at its points (`Model::field_points`).
fn evaluated_element(
    old: &Model,
    new: &Model,
    at: ElementAt<'_>,
    state: &State,
    mapped: &State,
) -> ElementFit {
    let ElementAt {
        e,
        ids,
        local,
        beta,
        ratio,
        slot,
    } = at;
    let dof = |x: &[f64], s: u32| {
        let s = s as usize;
        Vector3::new(x[3 * s], x[3 * s + 1], x[3 * s + 2])
    };
    let old_ids = old.element_shapes(e);
    let (ev_new, ev_old) = (new.element_evaluator(e), old.element_evaluator(e));
    let mut points = Vec::new();
    new.field_points_into(e, &ev_new, &mut points);
    let (mut vals, mut grads) = (vec![0.0; ids.len()], vec![Vector3::zeros(); ids.len()]);
    let (mut old_vals, mut old_grads) = (
        vec![0.0; old_ids.len()],
        vec![Vector3::zeros(); old_ids.len()],
    );
    // The fitted functions' values (nl rows) and gradients (3 nl rows:
    // component c of function i at row 3i + c) at the points (a column
    // each), for the Grams as products A W Aᵀ.
    let (nl, np) = (local.len(), points.len());
    let mut a_val = nalgebra::DMatrix::<f64>::zeros(nl, np);
    let mut a_grad = nalgebra::DMatrix::<f64>::zeros(3 * nl, np);
    let mut weights = Vec::with_capacity(np);
    let mut rhs = [vec![0.0; 3 * nl], vec![0.0; 3 * nl], vec![0.0; 3 * nl]];
    for (q, &(x, w, side)) in points.iter().enumerate() {
        ev_new.eval(&x, side, &mut vals, &mut grads);
        // The old field on the side x lies on in the old element.
        ev_old.eval(&x, ev_old.side_at(&x, side), &mut old_vals, &mut old_grads);
        // Residuals r of d, v and a and their gradients ∇r (row c = ∇r_c).
        let mut r = [Vector3::zeros(); 3];
        let mut gr = [Matrix3::zeros(); 3];
        for (a, &s) in old_ids.iter().enumerate() {
            for (f, x) in [&state.d, &state.v, &state.a].into_iter().enumerate() {
                let xa = dof(x, s);
                r[f] += xa * old_vals[a];
                gr[f] += xa * old_grads[a].transpose();
            }
        }
        for (a, &s) in ids.iter().enumerate() {
            if slot[s as usize] == usize::MAX {
                for (f, x) in [&mapped.d, &mapped.v, &mapped.a].into_iter().enumerate() {
                    let xa = dof(x, s);
                    r[f] -= xa * vals[a];
                    gr[f] -= xa * grads[a].transpose();
                }
            }
        }
        weights.push(w);
        for (i, &(a, _)) in local.iter().enumerate() {
            let (va, ga) = (w * vals[a], grads[a] * w);
            for f in 0..3 {
                // ε(r):C:ε(φ e_c)/μ = (λ/μ) div r ∂_c φ + (∇r + ∇rᵀ)_c · ∇φ.
                let strain = (gr[f] + gr[f].transpose()) * ga * beta;
                let div = gr[f].trace() * ratio;
                for c in 0..3 {
                    rhs[f][3 * i + c] += va * r[f][c] + strain[c] + beta * div * ga[c];
                }
            }
            for c in 0..3 {
                a_grad[(3 * i + c, q)] = grads[a][c];
            }
            a_val[(i, q)] = vals[a];
        }
    }
    // Σ_q w_q φ_a φ_b and Σ_q w_q ∂_i φ_a ∂_j φ_b, one product each.
    let weighted = |a: &nalgebra::DMatrix<f64>| {
        let mut aw = a.clone();
        for (mut col, &w) in aw.column_iter_mut().zip(&weights) {
            col *= w;
        }
        aw
    };
    let l2 = weighted(&a_val) * a_val.transpose();
    let g2 = weighted(&a_grad) * a_grad.transpose();
    ElementFit {
        local,
        beta,
        l2,
        g2,
        rhs,
    }
}

/// [`evaluated_element`] where the element's shape functions and cells are
/// the same in the old and the new model (`same_element_model`; `old_ids`
/// its old shape ids, in the same local order): the old field is then
/// Σ_b u_b φ_b in the new functions, and its integrals are the Grams of
/// all the element's functions times the old values (the elements around
/// the front's, which hold a fitted node function but no branch function:
/// their old functions were evaluated and the residual summed at every
/// point, 270 of 450 elements at the 1k-Tet10 event of `examples/tip_event`).
fn unchanged_element(
    new: &Model,
    at: ElementAt<'_>,
    old_ids: &[u32],
    state: &State,
    mapped: &State,
) -> ElementFit {
    let (e, m) = (at.e, at.ids.len());
    let ev = new.element_evaluator(e);
    let mut points = Vec::new();
    new.field_points_into(e, &ev, &mut points);
    let (mut vals, mut grads) = (vec![0.0; m], vec![Vector3::zeros(); m]);
    // Values (m rows) and gradients (row 3a + i: ∂_i φ_a) at the points.
    let np = points.len();
    let mut a_val = nalgebra::DMatrix::<f64>::zeros(m, np);
    let mut a_grad = nalgebra::DMatrix::<f64>::zeros(3 * m, np);
    let mut weighted = (a_val.clone(), a_grad.clone());
    for (q, &(x, w, side)) in points.iter().enumerate() {
        ev.eval(&x, side, &mut vals, &mut grads);
        for a in 0..m {
            a_val[(a, q)] = vals[a];
            weighted.0[(a, q)] = w * vals[a];
            for i in 0..3 {
                a_grad[(3 * a + i, q)] = grads[a][i];
                weighted.1[(3 * a + i, q)] = w * grads[a][i];
            }
        }
    }
    let l2 = &weighted.0 * a_val.transpose();
    let g = &weighted.1 * a_grad.transpose();
    // The old u, v and a (row b, three columns each), and their integrals
    // against each function: values = L2 X; strain (row 3a + c, field f) =
    // Σ_b,d X_b,d ((λ/μ) g(3a+c, 3b+d) + g(3a+d, 3b+c) + δ_cd tr g_ab).
    let x = nalgebra::DMatrix::from_fn(m, 9, |b, fc| {
        let (field, c) = (fc / 3, fc % 3);
        let xs = [&state.d, &state.v, &state.a][field];
        xs[3 * old_ids[b] as usize + c]
    });
    let values = &l2 * &x;
    let mut strain = nalgebra::DMatrix::<f64>::zeros(3 * m, 3);
    for a in 0..m {
        for b in 0..m {
            let trace: f64 = (0..3).map(|k| g[(3 * a + k, 3 * b + k)]).sum();
            for c in 0..3 {
                for d in 0..3 {
                    let mut k = at.ratio * g[(3 * a + c, 3 * b + d)] + g[(3 * a + d, 3 * b + c)];
                    if c == d {
                        k += trace;
                    }
                    for f in 0..3 {
                        strain[(3 * a + c, f)] += k * x[(b, 3 * f + d)];
                    }
                }
            }
        }
    }
    let fit = TipFit {
        l2,
        gradients: g,
        values,
        strain,
    };
    fitted_element(&fit, at, mapped)
}

/// An element's [`ElementFit`] from the integrals a model update took
/// ([`TipFit`]): its functions `ids` (`local` the fitted ones with their
/// slots), the Grams restricted to the fitted functions, and the
/// right-hand sides: the old field's integrals less the Grams' products
/// with the mapped values of the functions not fitted.
fn fitted_element(fit: &TipFit, at: ElementAt<'_>, mapped: &State) -> ElementFit {
    let ElementAt {
        ids,
        local,
        beta,
        ratio,
        slot,
        ..
    } = at;
    let nl = local.len();
    let g = &fit.gradients;
    // The Gram's entry (a c, b d).
    let kd = |a: usize, c: usize, b: usize, d: usize| {
        let mut v = beta * (ratio * g[(3 * a + c, 3 * b + d)] + g[(3 * a + d, 3 * b + c)]);
        if c == d {
            let trace: f64 = (0..3).map(|k| g[(3 * a + k, 3 * b + k)]).sum();
            v += fit.l2[(a, b)] + beta * trace;
        }
        v
    };
    let not_fitted: Vec<usize> = (0..ids.len())
        .filter(|&b| slot[ids[b] as usize] == usize::MAX)
        .collect();
    let mut rhs = [vec![0.0; 3 * nl], vec![0.0; 3 * nl], vec![0.0; 3 * nl]];
    for (i, &(a, _)) in local.iter().enumerate() {
        let fields = [&mapped.d, &mapped.v, &mapped.a];
        for (f, rhs) in rhs.iter_mut().enumerate() {
            for c in 0..3 {
                rhs[3 * i + c] = fit.values[(a, 3 * f + c)] + beta * fit.strain[(3 * a + c, f)];
            }
            for &b in &not_fitted {
                let s = ids[b] as usize;
                for c in 0..3 {
                    for d in 0..3 {
                        rhs[3 * i + c] -= kd(a, c, b, d) * fields[f][3 * s + d];
                    }
                }
            }
        }
    }
    // The fitted functions' rows and columns of the element's Grams (all
    // of them, in order, where none is prescribed: a copy).
    let (l2, g2) = if local.iter().enumerate().all(|(i, &(a, _))| i == a) && nl == ids.len() {
        (fit.l2.clone(), g.clone())
    } else {
        let rows: Vec<usize> = local.iter().map(|&(a, _)| a).collect();
        let rows3: Vec<usize> = rows.iter().flat_map(|&a| 3 * a..3 * a + 3).collect();
        (
            fit.l2.select_rows(&rows).select_columns(&rows),
            g.select_rows(&rows3).select_columns(&rows3),
        )
    };
    ElementFit {
        local,
        beta,
        l2,
        g2,
        rhs,
    }
}

/// A symmetric matrix of 3 × 3 blocks (function pairs) on a sparse
/// pattern, its lower triangle stored: column 3b + j holds rows 3b + j …
/// 3b + 2 of the diagonal block, then the three rows of each function a > b
/// coupled to b, in increasing order.
struct BlockGram {
    pattern: crate::solve::Pattern,
    values: Vec<f64>,
    /// Per function b, the functions a > b coupled to it (sorted).
    below: Vec<Vec<usize>>,
}

/// Where block (a, b), a ≥ b, of a [`BlockGram`] lies: b and, for a > b,
/// a's rank among the functions coupled below b.
#[derive(Clone, Copy)]
struct BlockAt {
    b: usize,
    rank: Option<usize>,
}

impl BlockGram {
    fn new(mut below: Vec<Vec<usize>>) -> BlockGram {
        let nf = below.len();
        let mut cols = Vec::with_capacity(3 * nf);
        for (b, rows) in below.iter_mut().enumerate() {
            rows.sort_unstable();
            rows.dedup();
            for j in 0..3 {
                let mut col: Vec<usize> = (3 * b + j..3 * b + 3).collect();
                col.extend(rows.iter().flat_map(|&a| 3 * a..3 * a + 3));
                cols.push(col);
            }
        }
        let pattern = crate::solve::Pattern::from_entries(3 * nf, cols);
        let values = vec![0.0; pattern.nnz()];
        BlockGram {
            pattern,
            values,
            below,
        }
    }

    /// Block (a, b), a ≥ b (a coupled to b).
    fn block(&self, a: usize, b: usize) -> BlockAt {
        BlockAt {
            b,
            rank: (a > b).then(|| {
                self.below[b]
                    .binary_search(&a)
                    .expect("functions sharing an element are coupled")
            }),
        }
    }

    /// Adds v to entry (3a + i, 3b + j) of block `at` (i ≥ j on the diagonal).
    fn add(&mut self, at: BlockAt, i: usize, j: usize, v: f64) {
        let start = self.pattern.col_ptr[3 * at.b + j];
        let k = match at.rank {
            None => start + i - j,
            Some(r) => start + (3 - j) + 3 * r + i,
        };
        self.values[k] += v;
    }

    /// Solves G x = b as [`solve_gram`] does: scaled to unit diagonal, by
    /// sparse Cholesky when its smallest squared pivot over the largest is
    /// above [`GRAM_RANK_TOL`]; else the dense [`solve_gram`] (pseudo-inverse).
    fn solve(
        self,
        b: Vec<Vec<f64>>,
        cache: &mut ProjectionCache,
    ) -> (Vec<Vec<f64>>, GramSolve, f64) {
        let p = &self.pattern;
        let n = p.n;
        // Column c starts with its diagonal entry.
        let scale: Vec<f64> = (0..n)
            .map(|c| {
                let d = self.values[p.col_ptr[c]];
                if d > 0.0 {
                    1.0 / d.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let mut scaled = self.values.clone();
        for c in 0..n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                scaled[k] *= scale[p.row_idx[k]] * scale[c];
            }
            if scale[c] == 0.0 {
                scaled[p.col_ptr[c]] = 1.0;
            }
        }
        let kept = cache
            .gram
            .take()
            .filter(|c| c.pattern().col_ptr == p.col_ptr && c.pattern().row_idx == p.row_idx);
        if kept.is_some() {
            cache.reused += 1;
        }
        if let Some(mut chol) = kept.map_or_else(|| crate::solve::Cholesky::new(p).ok(), Some) {
            let factored = chol.factorize(&scaled).is_ok();
            let chol = cache.gram.insert(chol);
            if factored {
                let (lo, hi) = chol
                    .pivots()
                    .iter()
                    .fold((f64::INFINITY, 0.0f64), |(l, h), &x| (l.min(x), h.max(x)));
                let ratio = (lo / hi).powi(2);
                if ratio > GRAM_RANK_TOL {
                    let x = b
                        .iter()
                        .map(|b| {
                            let mut y: Vec<f64> =
                                b.iter().zip(&scale).map(|(x, s)| x * s).collect();
                            chol.solve_in_place(&mut y);
                            for (y, s) in y.iter_mut().zip(&scale) {
                                *y *= s;
                            }
                            y
                        })
                        .collect();
                    return (x, GramSolve::Cholesky, ratio);
                }
            }
        }
        // Nearly dependent functions: the dense pseudo-inverse.
        let mut dense = nalgebra::DMatrix::<f64>::zeros(n, n);
        for c in 0..n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                let r = p.row_idx[k];
                dense[(r, c)] = self.values[k];
                dense[(c, r)] = self.values[k];
            }
        }
        let columns = b.len();
        let b = nalgebra::DMatrix::from_fn(n, columns, |r, c| b[c][r]);
        let (x, how, ratio) = solve_gram(dense, b);
        let x = (0..columns)
            .map(|c| x.column(c).iter().copied().collect())
            .collect();
        (x, how, ratio)
    }
}

/// Solves the symmetric positive semi-definite Gram system G x = b: scaled
/// to unit diagonal (S G S y = S b, x = S y, S = diag(G)^-½), by Cholesky
/// (faer's dense one, on one thread) when its smallest squared pivot over
/// the largest is above [`GRAM_RANK_TOL`], else by the pseudo-inverse over
/// the eigenvalues above it. Also returns that ratio (smallest eigenvalue over largest for the
/// pseudo-inverse). A function with zero norm (zero diagonal) gets zero.
fn solve_gram(
    mut g: nalgebra::DMatrix<f64>,
    mut b: nalgebra::DMatrix<f64>,
) -> (nalgebra::DMatrix<f64>, GramSolve, f64) {
    let n = g.nrows();
    let scale: Vec<f64> = (0..n)
        .map(|i| {
            let d = g[(i, i)];
            if d > 0.0 {
                1.0 / d.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    for j in 0..n {
        for i in 0..n {
            g[(i, j)] *= scale[i] * scale[j];
        }
        // A zero function: a unit row and column keep the matrix regular.
        if scale[j] == 0.0 {
            g[(j, j)] = 1.0;
        }
    }
    for i in 0..n {
        for c in 0..b.ncols() {
            b[(i, c)] *= scale[i];
        }
    }
    let unscale = |mut y: nalgebra::DMatrix<f64>| {
        for i in 0..n {
            for c in 0..y.ncols() {
                y[(i, c)] *= scale[i];
            }
        }
        y
    };
    if let Some((l, ratio)) = dense_cholesky(&g) {
        if ratio > GRAM_RANK_TOL {
            return (unscale(dense_llt_solve(&l, &b)), GramSolve::Cholesky, ratio);
        }
    }
    let eig = g.symmetric_eigen();
    let top = eig.eigenvalues.max();
    let cut = GRAM_RANK_TOL * top;
    let mut dropped = 0;
    let mut lowest = f64::INFINITY;
    // x = V diag(1/λ) Vᵀ b over the kept eigenvalues.
    let mut vtb = eig.eigenvectors.transpose() * &b;
    for (k, &lambda) in eig.eigenvalues.iter().enumerate() {
        let inv = if lambda > cut {
            lowest = lowest.min(lambda);
            1.0 / lambda
        } else {
            dropped += 1;
            0.0
        };
        for c in 0..vtb.ncols() {
            vtb[(k, c)] *= inv;
        }
    }
    let y = &eig.eigenvectors * vtb;
    (unscale(y), GramSolve::Pseudo { dropped }, lowest / top)
}

/// The Cholesky factor L of G (faer's dense one, on one thread; the lower
/// triangle), with the smallest squared pivot over the largest; `None`
/// where G is not numerically positive definite.
fn dense_cholesky(g: &nalgebra::DMatrix<f64>) -> Option<(faer::Mat<f64>, f64)> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt;
    let n = g.nrows();
    let mut l = faer::Mat::<f64>::from_fn(n, n, |i, j| if i >= j { g[(i, j)] } else { 0.0 });
    let par = faer::Par::Seq;
    let mut mem = MemBuffer::new(llt::factor::cholesky_in_place_scratch::<f64>(
        n,
        par,
        Default::default(),
    ));
    llt::factor::cholesky_in_place(
        l.as_mut(),
        Default::default(),
        par,
        MemStack::new(&mut mem),
        Default::default(),
    )
    .ok()?;
    let (lo, hi) = (0..n)
        .map(|i| l[(i, i)])
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    Some((l, (lo / hi).powi(2)))
}

/// L Lᵀ y = b with the factor of [`dense_cholesky`] (one thread).
fn dense_llt_solve(l: &faer::Mat<f64>, b: &nalgebra::DMatrix<f64>) -> nalgebra::DMatrix<f64> {
    use faer::dyn_stack::{MemBuffer, MemStack};
    use faer::linalg::cholesky::llt;
    let (n, m) = (l.nrows(), b.ncols());
    let par = faer::Par::Seq;
    let mut x = faer::Mat::<f64>::from_fn(n, m, |i, j| b[(i, j)]);
    let mut mem = MemBuffer::new(llt::solve::solve_in_place_scratch::<f64>(n, m, par));
    llt::solve::solve_in_place_with_conj(
        l.as_ref(),
        faer::Conj::No,
        x.as_mut(),
        par,
        MemStack::new(&mut mem),
    );
    nalgebra::DMatrix::from_fn(n, m, |i, j| x[(i, j)])
}

/// [`map_state`] without the projection: DOFs that change meaning keep
/// their values (tip blocks) or start at zero (tip → Heaviside).
pub fn map_state_unprojected(old: &Model, new: &Model, state: &State) -> State {
    let n_nodes = new.mesh.n_nodes();
    let n = new.n_dofs();
    let map = |x: &[f64]| -> Vec<f64> {
        let mut y = vec![0.0; n];
        y[..3 * n_nodes].copy_from_slice(&x[..3 * n_nodes]);
        if let (Some(oc), Some(nc)) = (&old.cut, &new.cut) {
            for i in 0..n_nodes {
                if let (Some(jo), Some(jn)) = (oc.enriched[i], nc.enriched[i]) {
                    let (so, sn) = (n_nodes + jo, n_nodes + jn);
                    for c in 0..3 {
                        y[3 * sn + c] = x[3 * so + c];
                    }
                    if oc.node_side[i] != nc.node_side[i] {
                        let h = f64::from(oc.node_side[i]);
                        for c in 0..3 {
                            y[3 * i + c] -= h * x[3 * so + c];
                        }
                    }
                }
                // Tip blocks (4 branch functions × 3) of nodes tip-enriched in
                // both keep their values (their functions follow the moved
                // front, so the field changes: the event reports the energy jump).
                if let (Some(to), Some(tn)) = (
                    oc.tip.get(i).copied().flatten(),
                    nc.tip.get(i).copied().flatten(),
                ) {
                    let so = n_nodes + oc.n_enriched + crate::front::N_BRANCH * to;
                    let sn = n_nodes + nc.n_enriched + crate::front::N_BRANCH * tn;
                    y[3 * sn..3 * (sn + crate::front::N_BRANCH)]
                        .copy_from_slice(&x[3 * so..3 * (so + crate::front::N_BRANCH)]);
                }
            }
        }
        y
    };
    State {
        time: state.time,
        d: map(&state.d),
        v: map(&state.v),
        a: map(&state.a),
        rotations: Rotations::identity(new),
    }
}

/// One cut event.
#[derive(Debug, Clone)]
pub struct Event {
    /// The step after which the cut grew, and its time.
    pub step: usize,
    pub time: f64,
    pub dofs_before: usize,
    pub dofs_after: usize,
    pub enriched_before: usize,
    pub enriched_after: usize,
    /// Energies just before and just after the event (same displacement and velocity).
    pub before: Energies,
    pub after: Energies,
    /// Whether the sparsity pattern changed (a symbolic factorisation was
    /// redone, unless the steps solved bordered on the old factor).
    pub pattern_changed: bool,
    /// The border k of the [`BorderedSolve`] the steps after the event
    /// solved with on an earlier factor; `None`: refactorised, or lagged.
    pub border: Option<usize>,
    /// Corotational on a lagged factor: the steps after the event began on
    /// the factor of the steps before it (the same equations, the pattern
    /// unchanged), refactorised only when their rate asked for it.
    pub lagged: bool,
    /// Elements integrated again ([`Model::update_cut`]).
    pub changed_elements: usize,
    /// Seconds of the model update (with the projection's integrals of the
    /// elements holding tip functions, which it takes as it integrates
    /// them: [`Model::update_cut_fitted_with`]) and of the symbolic
    /// factorisation (both in `seconds`; the numeric factorisation or the
    /// border's set-up is in the next step's time).
    pub model_seconds: f64,
    pub symbolic_seconds: f64,
    /// Seconds spent in the event (set-up, model, state map, symbolic).
    pub seconds: f64,
}

/// What a progressive run measured.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    pub start: f64,
    pub end: f64,
    /// The run's last time (steps × dt): before `end` where the run stops
    /// with the blades still cutting (their cut is where they were then).
    pub run_end: f64,
    pub events: Vec<Event>,
    pub dofs_first: usize,
    pub dofs_last: usize,
    /// Symbolic and numeric factorisations over the run.
    pub symbolic: usize,
    pub factorisations: usize,
    /// Borders left between events for a factorisation of their own (their
    /// steps had cost one: [`crate::dynamics::refresh_after`]).
    pub refreshed: usize,
    /// Seconds in events, and in steps (each step's Newton solve).
    pub event_seconds: f64,
    pub step_seconds: f64,
    /// Seconds spent checking whether the cut grew, and the steps at which
    /// the set-up was rebuilt to check (the others could not change it).
    pub check_seconds: f64,
    pub checks: usize,
    /// Per step: (time, seconds of the step, whether an event followed it).
    pub series: Vec<(f64, f64, bool)>,
    /// Per event (in order): what its projection did (`None`: nothing changed meaning).
    pub projections: Vec<Option<Projection>>,
    /// Projections whose Gram system took the last one's symbolic
    /// factorisation (the same pattern, [`ProjectionCache`]).
    pub gram_analyses_kept: usize,
    /// How the last model's factorisation was held ([`Cholesky::describe`]:
    /// its equations, entries in L and ordering, [`sweep_factor`]'s).
    pub factor: Option<String>,
}

impl Event {
    /// |ΔE| / E of kinetic + strain energy across the event (0 where both are 0).
    pub fn energy_jump(&self) -> f64 {
        let total = |x: &Energies| x.kinetic + x.strain;
        let before = total(&self.before);
        if before == 0.0 {
            return (total(&self.after) - before).abs();
        }
        (total(&self.after) - before).abs() / before
    }
}

impl Sweep {
    /// Events after which the steps solved bordered on an earlier factor,
    /// and the largest border among them.
    pub fn bordered_events(&self) -> (usize, usize) {
        self.events
            .iter()
            .filter_map(|e| e.border)
            .fold((0, 0), |(n, k), b| (n + 1, k.max(b)))
    }

    /// The end of the time the blades cut in this run: `end`, or the run's
    /// end where that comes first.
    pub fn cut_until(&self) -> f64 {
        self.end.min(self.run_end)
    }

    /// " (…)" where the run ends before the blades do, else empty.
    fn stopped_early(&self) -> String {
        if self.run_end < self.end {
            format!(
                " (the run ends at {:.4} s, with the blades still cutting: the cut is as far as they came)",
                self.run_end
            )
        } else {
            String::new()
        }
    }

    /// The largest [`Event::energy_jump`] of the sweep (with a tip front the
    /// field changes at every event: [`project_tip_change`] fits it).
    pub fn largest_energy_jump(&self) -> f64 {
        self.events
            .iter()
            .map(Event::energy_jump)
            .fold(0.0, f64::max)
    }
}

impl Sweep {
    /// "; N events projected (…)" where DOFs changed meaning, else empty.
    fn projection_summary(&self) -> String {
        let done: Vec<&Projection> = self.projections.iter().flatten().collect();
        if done.is_empty() {
            return String::new();
        }
        let pseudo = |g: GramSolve| match g {
            GramSolve::Cholesky => None,
            GramSolve::Pseudo { dropped } => Some(dropped),
        };
        let (mut n_pseudo, mut dropped) = (0, 0);
        for p in &done {
            if let Some(d) = pseudo(p.solve) {
                n_pseudo += 1;
                dropped = dropped.max(d);
            }
        }
        let fitted = done.iter().map(|p| p.fitted).max().unwrap_or(0);
        let conditioning = done
            .iter()
            .map(|p| p.conditioning)
            .fold(f64::INFINITY, f64::min);
        format!(
            "; {} events projected (up to {fitted} functions fitted, scaled Gram conditioning down to {conditioning:.1e}; {n_pseudo} by pseudo-inverse, up to {dropped} dependent directions dropped; {} on the last Gram's symbolic factorisation)",
            done.len(),
            self.gram_analyses_kept
        )
    }
}

impl std::fmt::Display for Sweep {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let patterns = self.events.iter().filter(|e| e.pattern_changed).count();
        let (bordered, border) = self.bordered_events();
        let lagged = self.events.iter().filter(|e| e.lagged).count();
        write!(
            f,
            "sweep {:.4} → {:.4} s{}: {} cut events ({} changed the pattern, {} set-ups checked; {} solved bordered on an earlier factor (border up to {}, {} refactorised later), {} went on with the lagged factor, {} refactorised), DOFs {} → {}, {} symbolic / {} numeric factorisations, {:.3} s in events, {:.3} s checking, {:.3} s in steps, largest energy change at an event {:.1e}{}",
            self.start,
            self.end,
            self.stopped_early(),
            self.events.len(),
            patterns,
            self.checks,
            bordered,
            border,
            self.refreshed,
            lagged,
            self.events.len() - bordered - lagged,
            self.dofs_first,
            self.dofs_last,
            self.symbolic,
            self.factorisations,
            self.event_seconds,
            self.check_seconds,
            self.step_seconds,
            self.largest_energy_jump(),
            self.projection_summary()
        )
    }
}

/// The end of a progressive run: the last model and state, and the sweep.
pub struct Progressive {
    pub model: Model,
    pub state: State,
    pub sweep: Sweep,
}

/// Runs a dynamic scene whose cuts may grow: `build` makes the model of the
/// mesh with a cut set-up (the scene's loads, fixes, material);
/// `observe(step, model, integrator)` sees the start and every step: the
/// state is `integrator.state`, `integrator.energies()` its energies (frames,
/// probes, energy series).
/// Starts at rest with the acceleration of the loads.
pub fn run_dynamic(
    cuts: &CutSet,
    mesh: &TetMesh,
    build: &dyn Fn(Option<CutSetup>) -> Result<Model, ModelError>,
    opts: DynamicOptions,
    observe: impl FnMut(usize, &Model, &mut Newmark<'_>),
) -> Result<Progressive, BladeError> {
    run_dynamic_with(cuts, mesh, build, opts, Parallelism::SEQUENTIAL, observe)
}

/// Whether a sweep takes a cut event at time `t` where its cut grew, the
/// last one at `last`: always, unless every blade gives `event_travel`
/// (a modelled front that lags the blade, for fewer events) and none has
/// moved that far since `last` (either end of its edge) nor passed its end.
/// A set without blades (built in code) is always due.
pub fn event_due(cuts: &CutSet, last: f64, t: f64) -> bool {
    let mut blades = cuts.blades().peekable();
    blades.peek().is_none()
        || blades.any(|b| match b.event_travel {
            None => true,
            Some(reach) => {
                let (from, to) = (b.edge_at(last), b.edge_at(t));
                (last < b.end() && t >= b.end())
                    || (0..2).any(|k| (to[k] - from[k]).norm() >= reach)
            }
        })
}

/// [`run_dynamic`] on `parallelism`'s threads: the steps' element loops
/// (forces, tangents, rotations) and, at each cut event, the integration
/// of the changed elements and the projection's (the same run whatever
/// their number, up to the order of the step's force sums).
pub fn run_dynamic_with(
    cuts: &CutSet,
    mesh: &TetMesh,
    build: &dyn Fn(Option<CutSetup>) -> Result<Model, ModelError>,
    opts: DynamicOptions,
    parallelism: Parallelism,
    mut observe: impl FnMut(usize, &Model, &mut Newmark<'_>),
) -> Result<Progressive, BladeError> {
    // The scene's blades must cut the body and keep clear of the other cuts.
    cuts.completed(mesh)?;
    let (start, end) = cuts.sweep_span().unwrap_or((0.0, 0.0));
    // The projections' Gram analysis, kept from one event to the next.
    let mut projection_cache = ProjectionCache::default();
    let mut sweep = Sweep {
        start,
        end,
        run_end: opts.dt * opts.steps as f64,
        ..Sweep::default()
    };
    let index = SweepIndex::new(cuts, mesh);
    let mut model = build(cuts.setup_at(mesh, 0.0)?)?;
    sweep.dofs_first = model.n_dofs();
    let mut factor = LinearFactor {
        chol: sweep_factor(&model)?,
        values: None,
        border: None,
        lagged: None,
    };
    sweep.symbolic = 1;
    let linear = model.formulation == crate::model::Formulation::Linear;
    let bordered = linear && matches!(opts.event_solve, EventSolve::Bordered { .. });
    let mut carried: Option<(State, Event)> = None;
    // A linear model's stiffness carried over the last event.
    let mut forces: Option<LinearForces> = None;
    let mut step = 0;
    // The time of the last cut event (the blades' `event_travel` is
    // measured from there), and where steps were not due for one, the start
    // of the sweep the model has not been checked against.
    let mut last_event = 0.0;
    let mut unchecked_since: Option<f64> = None;
    loop {
        let mut nm = Newmark::on_factor(&model, factor, opts)?;
        if parallelism.n_threads() > 1 {
            nm.set_parallelism(parallelism);
        }
        if let Some(f) = forces.take() {
            nm.set_linear_forces(f);
        }
        let after_event = carried.is_some();
        // A reused factorisation keeps counting: count this model's part only.
        let counted = nm.factorisations();
        match carried.take() {
            None => {
                nm.initialise_acceleration()?;
                observe(0, &model, &mut nm);
            }
            Some((state, mut event)) => {
                nm.state = state;
                let t = Instant::now();
                event.after = nm.energies();
                event.seconds += t.elapsed().as_secs_f64();
                sweep.event_seconds += event.seconds;
                sweep.events.push(event);
            }
        }
        let grown = loop {
            if step == opts.steps {
                break None;
            }
            let t = Instant::now();
            nm.step()?;
            let step_time = t.elapsed().as_secs_f64();
            sweep.step_seconds += step_time;
            step += 1;
            observe(step, &model, &mut nm);
            let t = Instant::now();
            let t_now = nm.state.time;
            let since = unchecked_since.unwrap_or(t_now - opts.dt);
            let due = event_due(cuts, last_event, t_now);
            let setup = if due && index.may_change(since, t_now) {
                sweep.checks += 1;
                let s = cuts.setup_at(mesh, t_now)?;
                (!same_setup(model.cut.as_ref(), s.as_ref())).then_some(s)
            } else {
                None
            };
            unchecked_since = (!due).then_some(since);
            sweep.check_seconds += t.elapsed().as_secs_f64();
            sweep
                .series
                .push((nm.state.time, step_time, setup.is_some()));
            if let Some(s) = setup {
                last_event = t_now;
                break Some(s);
            }
        };
        // How the steps after the event solved (the first step decided).
        sweep.symbolic += nm.symbolic_factorisations();
        sweep.refreshed += nm.refreshes();
        if after_event {
            if let Some(e) = sweep.events.last_mut() {
                e.border = nm.border();
            }
        }
        let Some(setup) = grown else {
            sweep.factorisations += nm.factorisations() - counted;
            let state = nm.state.clone();
            sweep.dofs_last = model.n_dofs();
            sweep.factor = Some(nm.factor_description());
            return Ok(Progressive {
                model,
                state,
                sweep,
            });
        };
        // A cut event.
        let t = Instant::now();
        let before = nm.energies();
        sweep.factorisations += nm.factorisations() - counted;
        let state = nm.state.clone();
        let old_forces = nm.take_linear_forces();
        let old = nm.into_factor();
        let t_model = Instant::now();
        // Only the elements the grown cut changed are integrated again
        // (a model with a varying body force is built again: its equations
        // are numbered afresh).
        // The projection's integrals of the elements the update integrated.
        let mut fits = TipFits::new();
        // Whether every old free equation keeps its number and none is new
        // (a front moving inside the elements it holds): a corotational
        // scene's lagged factor is then one of the same equations.
        let mut same_equations = false;
        let (new_model, changed_elements, renumbered) = if model.body_force {
            let m = build(setup)?;
            let n = m.mesh.n_elements();
            (m, n, true)
        } else {
            let (m, stats, update, tip_fits) =
                model.update_cut_fitted_with(setup, &state, parallelism)?;
            // The stiffness moved over and mended where the elements changed.
            forces = old_forces.map(|f| f.updated(&model, &m, &update));
            fits = tip_fits;
            same_equations = update.keeps_every_equation(m.n_free);
            (m, stats.changed_elements, stats.dropped_equations > 0)
        };
        let model_seconds = t_model.elapsed().as_secs_f64();
        let (mapped, projection) = map_state_fitted_cached(
            &model,
            &new_model,
            &state,
            &fits,
            parallelism,
            &mut projection_cache,
        );
        sweep.projections.push(projection);
        sweep.gram_analyses_kept = projection_cache.reused;
        let pattern_changed = new_model.pattern.col_ptr != model.pattern.col_ptr
            || new_model.pattern.row_idx != model.pattern.row_idx;
        let t_symbolic = Instant::now();
        // Equations only appended since the factor: the next steps may solve
        // on it (bordered); otherwise a factor of the new pattern.
        factor = if bordered && !renumbered && old.values.is_some() {
            old
        } else {
            let p = old.chol.pattern();
            let same =
                p.col_ptr == new_model.pattern.col_ptr && p.row_idx == new_model.pattern.row_idx;
            let chol = if same {
                old.chol
            } else {
                sweep.symbolic += 1;
                sweep_factor(&new_model)?
            };
            LinearFactor {
                chol,
                values: None,
                border: None,
                lagged: old.lagged.filter(|_| same && same_equations),
            }
        };
        let symbolic_seconds = t_symbolic.elapsed().as_secs_f64();
        let event = Event {
            step,
            time: state.time,
            dofs_before: model.n_dofs(),
            dofs_after: new_model.n_dofs(),
            enriched_before: model.n_enriched(),
            enriched_after: new_model.n_enriched(),
            before,
            after: Energies::default(),
            pattern_changed,
            border: None,
            lagged: factor.lagged.is_some(),
            changed_elements,
            model_seconds,
            symbolic_seconds,
            seconds: t.elapsed().as_secs_f64(),
        };
        model = new_model;
        carried = Some((mapped, event));
    }
}

/// K + c M on a model's pattern (linear stiffness at rest, consistent mass):
/// the shape of K_eff a linear Newmark step factorises, for the bordered-solve
/// test and bench.
pub fn stiffness_plus_mass(model: &Model, c: f64) -> Vec<f64> {
    use crate::assembly::{evaluate, Request, Workspace};
    let mut k = vec![0.0; model.pattern.nnz()];
    let mut f = vec![0.0; model.n_dofs()];
    let d = vec![0.0; model.n_dofs()];
    evaluate(
        model,
        &d,
        &mut Rotations::identity(model),
        &mut Workspace::new(model),
        Request {
            forces: Some(&mut f),
            tangent: Some(&mut k),
            update_rotations: false,
            exact_tangent: false,
        },
    );
    if let Some(m) = &model.consistent_mass {
        for (kv, mv) in k.iter_mut().zip(m) {
            *kv += c * mv;
        }
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_straight_sweep_is_the_patch_and_a_path_a_strip_ending_at_the_edge() {
        let (a, b) = (Point3::new(0.1, -0.2, 0.3), Point3::new(0.4, 0.9, 0.2));
        let travel = Vector3::new(0.05, 0.02, -0.3);
        let blade = Blade::straight(0, a, b, travel, 1.0, 3.0).unwrap();
        assert!(blade.swept(1.0).is_none());
        let Some(Swept::Patch(p)) = blade.swept(5.0) else {
            panic!("a straight sweep is a patch")
        };
        assert_eq!((p.origin, p.u), (a, b - a));
        assert!((p.v - travel).norm() <= 1e-15);
        let Some(Swept::Growing(h)) = blade.swept(2.0) else {
            panic!("a growing patch")
        };
        assert!((h.part.v - travel * 0.5).norm() <= 1e-15);
        let x = Point3::new(0.3, 0.1, -0.2);
        assert_eq!(h.level_set(&x), p.level_set(&x));
        let e = blade.edge_at(2.0);
        assert!((e[0] - (a + travel * 0.5)).norm() <= 1e-15);

        // A path: three keyframes; half-way through the second segment the strip
        // has the first segment's two triangles and three of the partial one
        // (its front bent at the diagonal point, here the edge's midpoint).
        let k = |x: f64, z: f64| [Point3::new(x, 0.0, z), Point3::new(x, 1.0, z)];
        let path = Blade::new(
            3,
            vec![(0.0, k(0.0, 0.0)), (1.0, k(1.0, 0.0)), (2.0, k(2.0, 1.0))],
        )
        .unwrap();
        let Some(Swept::Strip(s)) = path.swept(1.5) else {
            panic!("a path sweeps a strip")
        };
        assert_eq!(s.n_triangles(), 5);
        let edge = path.edge_at(1.5);
        let on_boundary = |p: Point3<f64>| s.boundary().iter().any(|seg| seg.contains(&p));
        assert!(on_boundary(edge[0]) && on_boundary(edge[1]));
        // Positive on the side (b − a) × travel points to (here −z), at the distance to the plane z = 0.
        let n = (edge[1] - edge[0]).cross(&Vector3::new(1.0, 0.0, 0.0));
        let x = Point3::new(0.5, 0.5, 0.0) + n * 0.1;
        assert!(s.level_set(&x) > 0.0 && (s.level_set(&x) - 0.1 * n.norm()).abs() < 1e-14);
    }

    #[test]
    fn a_twisted_path_cuts_once_what_it_cuts_every_prefix_lies_in_the_later_strips() {
        // Each segment twisted (the edge turns out of the plane of its
        // motion): a strip whose diagonal followed the edge moved the part
        // already cut by 2.1e-2 here.
        let path = Blade::new(
            0,
            vec![
                (
                    0.0,
                    [Point3::new(0.0, 0.0, 0.0), Point3::new(0.0, 1.0, 0.0)],
                ),
                (
                    1.0,
                    [Point3::new(0.5, 0.0, 0.1), Point3::new(0.4, 1.0, -0.2)],
                ),
                (
                    2.0,
                    [Point3::new(1.0, 0.1, 0.3), Point3::new(0.9, 1.1, 0.5)],
                ),
            ],
        )
        .unwrap();
        let times = [0.2, 0.5, 0.9, 1.0, 1.3, 1.7, 2.0];
        let strips: Vec<TriangleSurface> = times
            .iter()
            .map(|&t| match path.swept(t) {
                Some(Swept::Strip(s)) => *s,
                _ => panic!("a path sweeps a strip"),
            })
            .collect();
        let distance = |x: &Point3<f64>, s: &TriangleSurface| {
            (0..s.n_triangles())
                .map(|k| crate::front::triangle_distance(x, &s.triangles[k].map(|i| s.vertices[i])))
                .fold(f64::INFINITY, f64::min)
        };
        for (i, earlier) in strips.iter().enumerate() {
            for later in &strips[i..] {
                for k in 0..earlier.n_triangles() {
                    let tri = earlier.triangles[k].map(|i| earlier.vertices[i]);
                    // Its corners and centroid lie on the later strip.
                    let centroid =
                        Point3::from((tri[0].coords + tri[1].coords + tri[2].coords) / 3.0);
                    for x in tri.iter().chain(std::iter::once(&centroid)) {
                        assert!(
                            distance(x, later) <= 1e-14,
                            "{x} is {} off",
                            distance(x, later)
                        );
                    }
                }
            }
        }
        // The edge's ends are on the front; within a twisted segment its
        // middle is off it by less than the twist.
        let s = &strips[4];
        let e = path.edge_at(1.3);
        let on_boundary = |p: Point3<f64>| s.boundary().iter().any(|seg| seg.contains(&p));
        assert!(on_boundary(e[0]) && on_boundary(e[1]));
    }

    /// An element that a tip event leaves as it was (the front's
    /// neighbours holding a fitted node function) takes its part of the
    /// projection from its Grams times the old values
    /// ([`unchanged_element`]): the same as the old field evaluated at each
    /// of its points ([`evaluated_element`]), Grams and right-hand sides, to
    /// round-off (Tet4 and Tet10, the seed's blade half-way, a field that is
    /// no field of either space).
    #[test]
    fn an_unchanged_elements_fit_is_its_grams_times_the_old_values() {
        use crate::assembly::Rotations;
        use crate::cut::FrontMode;
        use crate::model::Formulation;
        use crate::study::fixtures::{beam_mesh, seed_beam, seed_blade};
        for tet10 in [false, true] {
            let mesh = beam_mesh([2, 4, 8], tet10);
            let cuts = CutSet {
                front: FrontMode::Tip,
                ..seed_blade(0.0, 1.0)
            };
            let old = seed_beam(
                mesh.clone(),
                Formulation::Linear,
                cuts.setup_at(&mesh, 0.5).unwrap(),
            )
            .unwrap();
            let (new, _) = old.update_cut(cuts.setup_at(&mesh, 0.53).unwrap()).unwrap();
            let field = |scale: f64, phase: f64| -> Vec<f64> {
                (0..old.n_dofs())
                    .map(|i| scale * (0.37 * i as f64 + phase).sin())
                    .collect()
            };
            let state = State {
                time: 0.5,
                d: field(1e-3, 0.0),
                v: field(-2e-2, 1.0),
                a: field(0.5, 2.0),
                rotations: Rotations::identity(&old),
            };
            let mapped = map_state_unprojected(&old, &new, &state);
            let fitted = fitted_functions(&old, &new, &state, &mapped).expect("the front moved");
            let mut slot = vec![usize::MAX; new.n_shape];
            for (k, &s) in fitted.iter().enumerate() {
                slot[s] = k;
            }
            let (mut compared, mut worst) = (0, 0.0f64);
            for e in 0..new.mesh.n_elements() {
                let at = ElementAt::new(&new, e, &slot);
                if at.local.is_empty()
                    || !same_element_model(&new.mesh, old.cut.as_ref(), new.cut.as_ref(), e)
                {
                    continue;
                }
                let by_grams = unchanged_element(&new, at, old.element_shapes(e), &state, &mapped);
                let at = ElementAt::new(&new, e, &slot);
                let by_points = evaluated_element(&old, &new, at, &state, &mapped);
                let differ = |x: &[f64], y: &[f64]| {
                    let scale = x.iter().fold(0.0f64, |s, v| s.max(v.abs()));
                    let d = x
                        .iter()
                        .zip(y)
                        .fold(0.0f64, |s, (a, b)| s.max((a - b).abs()));
                    d / scale
                };
                worst = worst
                    .max(differ(by_grams.l2.as_slice(), by_points.l2.as_slice()))
                    .max(differ(by_grams.g2.as_slice(), by_points.g2.as_slice()));
                for (x, y) in by_grams.rhs.iter().zip(&by_points.rhs) {
                    worst = worst.max(differ(x, y));
                }
                compared += 1;
            }
            println!("tet10 {tet10}: {compared} unchanged elements, largest relative difference {worst:.1e}");
            assert!(compared >= 10, "{compared}");
            assert!(worst <= 1e-12, "{worst:e}");
        }
    }
}

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
//!   the model built again; the Newmark state is mapped onto the new DOFs:
//!   standard DOFs keep their values, enriched DOFs of nodes that were
//!   enriched before keep theirs, new shifted-enrichment DOFs start at zero
//!   displacement, velocity and acceleration. Since Nᵢ(H − Hᵢ)·0 = 0 (seed
//!   eq. 58–59) the field, its velocity and both energies are unchanged
//!   (METHODS.md, "Blades"). The symbolic factorisation is redone only when
//!   the pattern changed; a linear scene refactorises at events only.
//! - A static scene takes the completed sweep ([`CutSet::completed`]).

use crate::assembly::Rotations;
use crate::cut::{setup_cut, CutError, CutInput, CutSetup, CutSurface, ElementCut, PlanarPatch};
use crate::dynamics::{DynamicError, DynamicOptions, Energies, Newmark, State};
use crate::mesh::TetMesh;
use crate::model::{Model, ModelError};
use crate::solve::{Cholesky, SolveError};
use crate::surface::TriangleSurface;
use nalgebra::{Point3, Vector3};
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
    #[error("cut[{index}]: key `blade`: the blade never meets the body (its completed sweep cuts no element)")]
    Misses { index: usize },
    #[error("cut[{index}]: key `blade`: its swept surface meets cut[{other}] in element {element} or at its nodes: cuts must not intersect and must be at least one element apart")]
    Meets {
        index: usize,
        other: usize,
        element: usize,
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
    /// Index of its `[[cut]]` in the scene (for errors).
    pub index: usize,
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
        Ok(Blade { keyframes, index })
    }

    /// A straight sweep: the edge a–b moves by `travel` between `start` and `end`.
    pub fn straight(
        index: usize,
        a: Point3<f64>,
        b: Point3<f64>,
        travel: Vector3<f64>,
        start: f64,
        end: f64,
    ) -> Result<Blade, BladeError> {
        Blade::new(
            index,
            vec![(start, [a, b]), (end, [a + travel, b + travel])],
        )
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

    /// Whether the sweep is a translation of the edge between two keyframes.
    fn is_straight(&self) -> bool {
        if self.keyframes.len() != 2 {
            return false;
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
            let travel = a1 - a0;
            let v = if t >= t1 {
                travel
            } else {
                travel * ((t - t0) / (t1 - t0))
            };
            if v.norm() == 0.0 {
                return None;
            }
            return Some(Swept::Patch(PlanarPatch {
                origin: a0,
                u: b0 - a0,
                v,
            }));
        }
        // Ruled strip: the edges at the keyframes passed and at t.
        let mut edges: Vec<[Point3<f64>; 2]> = self
            .keyframes
            .iter()
            .take_while(|(tk, _)| *tk < t)
            .map(|(_, e)| *e)
            .collect();
        edges.push(self.edge_at(t));
        let mut vertices = Vec::with_capacity(2 * edges.len());
        for e in &edges {
            vertices.extend_from_slice(e);
        }
        let scale = (b0 - a0).norm();
        let mut triangles = Vec::new();
        for k in 0..edges.len() - 1 {
            let (a, b, c, d) = (2 * k, 2 * k + 1, 2 * k + 3, 2 * k + 2);
            for tri in [[a, b, c], [a, c, d]] {
                let p = tri.map(|i| vertices[i]);
                let area = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
                if area > 1e-12 * scale * scale {
                    triangles.push(tri);
                }
            }
        }
        if triangles.is_empty() {
            return None;
        }
        TriangleSurface::new(vertices, triangles, Path::new("blade"))
            .ok()
            .map(Swept::Strip)
    }
}

/// A blade's swept surface at some time.
#[derive(Debug, Clone)]
pub enum Swept {
    Patch(PlanarPatch),
    Strip(TriangleSurface),
}

impl Swept {
    pub fn surface(&self) -> &dyn CutSurface {
        match self {
            Swept::Patch(p) => p,
            Swept::Strip(s) => s,
        }
    }

    /// The swept surface, owned.
    pub fn into_surface(self) -> Box<dyn CutSurface> {
        match self {
            Swept::Patch(p) => Box::new(p),
            Swept::Strip(s) => Box::new(s),
        }
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
}

impl CutSet {
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
                CutItem::Blade(_) => {
                    if let Some(s) = &swept[k] {
                        parts.push((k, s.surface()));
                    } else if strict {
                        return Err(BladeError::Misses { index: k });
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
                .map(|p| CutInput::extend(p.1, self.snap))
                .collect();
            match setup_cut(mesh, &inputs) {
                Ok(s) => return Ok(Some(s)),
                Err(CutError::Misses(j)) => {
                    let k = parts[j].0;
                    match (&self.items[k], strict) {
                        (CutItem::Blade(_), false) => {
                            parts.remove(j);
                        }
                        (CutItem::Blade(_), true) => return Err(BladeError::Misses { index: k }),
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
                    return Err(BladeError::Meets {
                        index,
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
/// A straight sweep keeps its plane: an element's classification can change
/// only while the growing patch passes over it, i.e. when the range of its
/// vertices' patch coordinate t (along the travel, in the completed patch)
/// meets the new strip [f_prev, f_now]. Elements the plane does not reach
/// (all vertices on one side, farther than twice the snapping distance)
/// never change. A path's strip moves, so every step of its sweep is checked.
struct SweepIndex {
    straight: Vec<StraightSweep>,
    /// Sweep spans of the other blades.
    paths: Vec<(f64, f64)>,
}

/// A straight blade's span and the (t_min, t_max) of the elements its plane reaches, sorted.
struct StraightSweep {
    start: f64,
    end: f64,
    ranges: Vec<(f64, f64)>,
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
            let Some(Swept::Patch(p)) = b.swept(b.end()) else {
                paths.push((b.start(), b.end()));
                continue;
            };
            let phi: Vec<f64> = mesh
                .nodes
                .iter()
                .zip(&h)
                .map(|(x, hi)| {
                    let f = p.level_set(x);
                    if f.abs() < 2.0 * cuts.snap * hi {
                        0.0
                    } else {
                        f
                    }
                })
                .collect();
            let mut ranges = Vec::new();
            for e in 0..mesh.n_elements() {
                let v = mesh.vertices(e);
                let lo = v.iter().map(|&i| phi[i]).fold(f64::INFINITY, f64::min);
                let hi = v.iter().map(|&i| phi[i]).fold(f64::NEG_INFINITY, f64::max);
                if lo > 0.0 || hi < 0.0 {
                    continue;
                }
                let st: Vec<(f64, f64)> =
                    v.iter().map(|&i| p.coordinates(&mesh.nodes[i])).collect();
                let smin = st.iter().map(|c| c.0).fold(f64::INFINITY, f64::min);
                let smax = st.iter().map(|c| c.0).fold(f64::NEG_INFINITY, f64::max);
                if smax < -1e-6 || smin > 1.0 + 1e-6 {
                    continue;
                }
                let tmin = st.iter().map(|c| c.1).fold(f64::INFINITY, f64::min);
                let tmax = st.iter().map(|c| c.1).fold(f64::NEG_INFINITY, f64::max);
                ranges.push((tmin, tmax));
            }
            ranges.sort_by(|a, b| a.0.total_cmp(&b.0));
            straight.push(StraightSweep {
                start: b.start(),
                end: b.end(),
                ranges,
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
            sw.ranges
                .iter()
                .take_while(|r| r.0 <= f1)
                .any(|r| r.1 >= f0)
        })
    }
}

/// Whether two set-ups give the same model (enrichment, sides of enriched
/// nodes, element classification and sub-tets).
pub fn same_setup(a: Option<&CutSetup>, b: Option<&CutSetup>) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(a), Some(b)) => {
            a.enriched == b.enriched
                && a.enriched
                    .iter()
                    .zip(a.node_side.iter().zip(&b.node_side))
                    .all(|(e, (x, y))| e.is_none() || x == y)
                && a.elements.len() == b.elements.len()
                && a.elements
                    .iter()
                    .zip(&b.elements)
                    .all(|(x, y)| same_element(x, y))
        }
        _ => false,
    }
}

fn same_element(a: &ElementCut, b: &ElementCut) -> bool {
    match (a, b) {
        (ElementCut::Uncut, ElementCut::Uncut) => true,
        (ElementCut::Touched { side: x }, ElementCut::Touched { side: y }) => x == y,
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
                && s.iter()
                    .zip(t)
                    .all(|(x, y)| x.side == y.side && x.vertices == y.vertices)
        }
        _ => false,
    }
}

/// Maps a state of `old` onto the DOFs of `new` (the same mesh, a grown
/// cut): standard DOFs keep their values, enriched DOFs of nodes enriched in
/// both keep theirs, new enriched DOFs start at zero. Where an enriched
/// node's side Hᵢ flips (a path's strip moved), uᵢ' = uᵢ − Hᵢ aᵢ keeps the
/// field: uᵢ + (H − Hᵢ)/2 aᵢ = uᵢ' + (H + Hᵢ)/2 aᵢ. Rotations start at the
/// identity (corotational steps recompute them from d).
pub fn map_state(old: &Model, new: &Model, state: &State) -> State {
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
    /// Whether the sparsity pattern changed (symbolic factorisation redone).
    pub pattern_changed: bool,
    /// Seconds spent in the event (set-up, model, state map, symbolic).
    pub seconds: f64,
}

/// What a progressive run measured.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    pub start: f64,
    pub end: f64,
    pub events: Vec<Event>,
    pub dofs_first: usize,
    pub dofs_last: usize,
    /// Symbolic and numeric factorisations over the run.
    pub symbolic: usize,
    pub factorisations: usize,
    /// Seconds in events, and in steps (each step's Newton solve).
    pub event_seconds: f64,
    pub step_seconds: f64,
    /// Seconds spent checking whether the cut grew, and the steps at which
    /// the set-up was rebuilt to check (the others could not change it).
    pub check_seconds: f64,
    pub checks: usize,
    /// Per step: (time, seconds of the step, whether an event followed it).
    pub series: Vec<(f64, f64, bool)>,
}

impl std::fmt::Display for Sweep {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let patterns = self.events.iter().filter(|e| e.pattern_changed).count();
        write!(
            f,
            "sweep {:.4} → {:.4} s: {} cut events ({} changed the pattern, {} set-ups checked), DOFs {} → {}, {} symbolic / {} numeric factorisations, {:.3} s in events, {:.3} s checking, {:.3} s in steps",
            self.start,
            self.end,
            self.events.len(),
            patterns,
            self.checks,
            self.dofs_first,
            self.dofs_last,
            self.symbolic,
            self.factorisations,
            self.event_seconds,
            self.check_seconds,
            self.step_seconds
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
    mut observe: impl FnMut(usize, &Model, &mut Newmark<'_>),
) -> Result<Progressive, BladeError> {
    // The scene's blades must cut the body and keep clear of the other cuts.
    cuts.completed(mesh)?;
    let (start, end) = cuts.sweep_span().unwrap_or((0.0, 0.0));
    let mut sweep = Sweep {
        start,
        end,
        ..Sweep::default()
    };
    let index = SweepIndex::new(cuts, mesh);
    let mut model = build(cuts.setup_at(mesh, 0.0)?)?;
    sweep.dofs_first = model.n_dofs();
    let mut chol = Cholesky::new(&model.pattern)?;
    sweep.symbolic = 1;
    let mut carried: Option<(State, Event)> = None;
    let mut step = 0;
    loop {
        let mut nm = Newmark::new(&model, chol, opts)?;
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
            let setup = if index.may_change(t_now - opts.dt, t_now) {
                sweep.checks += 1;
                let s = cuts.setup_at(mesh, t_now)?;
                (!same_setup(model.cut.as_ref(), s.as_ref())).then_some(s)
            } else {
                None
            };
            sweep.check_seconds += t.elapsed().as_secs_f64();
            sweep
                .series
                .push((nm.state.time, step_time, setup.is_some()));
            if let Some(s) = setup {
                break Some(s);
            }
        };
        let Some(setup) = grown else {
            sweep.factorisations += nm.factorisations() - counted;
            let state = nm.state.clone();
            sweep.dofs_last = model.n_dofs();
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
        let old_chol = nm.into_cholesky();
        let new_model = build(setup)?;
        let mapped = map_state(&model, &new_model, &state);
        let pattern_changed = new_model.pattern.col_ptr != model.pattern.col_ptr
            || new_model.pattern.row_idx != model.pattern.row_idx;
        chol = if pattern_changed {
            sweep.symbolic += 1;
            Cholesky::new(&new_model.pattern)?
        } else {
            old_chol
        };
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
            seconds: t.elapsed().as_secs_f64(),
        };
        model = new_model;
        carried = Some((mapped, event));
    }
}

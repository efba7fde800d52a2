//! Implicit Newmark time stepping (seed section 3.5/5.1) with Rayleigh damping
//! and lumped (eq. 81–82) or consistent mass.
//!
//! Displacement form: a(d) = c₀(d − dₙ) − c₁vₙ − c₂aₙ, v(d) = vₙ + Δt((1−γ)aₙ + γa(d)),
//! residual r(d) = f_ext − f_int(d) − M a(d) − Dₙ v(d) with the damping
//! matrix of the step Dₙ = α M + β_R Rₙ K Rₙᵀ: K the rest stiffness, Rₙ the
//! element rotations at the start of the step, held over the step (linear:
//! Rₙ = I, D = α M + β_R K). Newton matrix, the exact derivative −dr/dd:
//! K_eff = K_t(d) + (c₀ + α γ/(βΔt)) M + β_R γ/(βΔt) Rₙ K Rₙᵀ, symmetric.
//! Holding the rotations over the step is what makes the damping's tangent
//! exact and symmetric (with R = R(d) it would gain d(R K Rᵀ v)/dd, which is
//! unsymmetric); Dₙ is positive semi-definite and annihilates every rigid
//! velocity (Rₙᵀ of a rigid field is rigid), so it dissipates and never damps
//! a rigid motion. Linear scenes factorise K_eff once; corotational scenes
//! re-assemble K_t each iteration (the exact tangent of the corotational
//! forces by default) and reuse the symbolic factorisation. After the first
//! step a step allocates nothing (`tests/alloc.rs` counts).

use crate::assembly::{
    add_linear_elements, evaluate, evaluate_damped, gather_free, tangent_product, Request,
    Rotations, Workspace,
};
use crate::corotation::polar_rotation;
use crate::model::{CutUpdate, Formulation, Model, NONE};
use crate::solve::{BorderedSolve, Cholesky, Pattern, Pcg, SolveError, BORDER_TOLERANCE};
use crate::statics::norm;
use nalgebra::{Matrix3, Vector3};

/// How the Newton systems of a corotational step are solved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinearSolver {
    /// Numeric refactorisation every iteration (symbolic once).
    Direct,
    /// CG preconditioned by the last factorisation; refactorise only when CG
    /// needs more than `max_cg` iterations.
    Pcg { tolerance: f64, max_cg: usize },
    /// CG preconditioned by the last factorisation warped by per-node
    /// rotations: P⁻¹ = S A_f⁻¹ Sᵀ, S = blockdiag(R_s R_{s,f}ᵀ) over the shape
    /// functions s (R_s: the weighted polar mean of the rotations of the groups
    /// that s touches, now; R_{s,f}: at the factorisation), so that a rigid
    /// rotation of the rest state leaves the preconditioner exact for the
    /// lumped mass (R M Rᵀ = M). Refactorise only when CG needs more than `max_cg`.
    WarpedPcg { tolerance: f64, max_cg: usize },
    /// Modified Newton on a lagged factorisation: K_eff is factorised at the
    /// first iterate of every `every`-th step and kept for the steps between
    /// (`every` = 1: once a step), and refactorised at the current iterate
    /// when Newton has done `refactor_after` iterations on one factor within
    /// a step, or as soon as one iteration on it reduced the residual by less
    /// than the factor `max_rate` (r_{k+1} > max_rate · r_k: the factor has
    /// drifted too far from the tangent to be worth iterating on; `1.0` or
    /// more: never for that reason). An iteration without refactorisation
    /// assembles no tangent: forces, residual and two triangular solves.
    /// With `anderson` = m > 0 an iteration on a factor that follows one
    /// which reduced the residual by less than 10× is Anderson-accelerated
    /// over the last m of the step's iterations on that factor (see
    /// [`Anderson`]); 0: plain modified Newton.
    Lagged {
        every: usize,
        refactor_after: usize,
        max_rate: f64,
        anderson: usize,
    },
}

/// The `linear_solver = "lagged"` of a case file, and the default of
/// corotational dynamic scenes: modified Newton on the last factorisation
/// of the exact tangent, refactorised at the current iterate when an
/// iteration on it reduced the residual by less than 5× or after 12
/// iterations on it, never for its age alone; an iteration that reduced it
/// by less than 10× (but 5× or more) is followed by an Anderson-accelerated
/// one (history 5, [`Anderson`]). Measured with `examples/step_profile.rs`
/// (the beam that gravity swings from rest, mean of 100 steps, 30 at 10k,
/// one thread) and `examples/fast_step.rs` (`bend_dynamic` L0, 300 steps)
/// against the plain modified Newton that was the default before it
/// (refactorised below 10× or after 8 iterations): the seed's cut with a
/// tip front 5.78 → 5.20 ms a step at 1k Tet4 (5.17 → 5.52 Newton
/// iterations, 1.11 → 0.97 factorisations) and 64.3 → 59.9 ms at 10k
/// (1.33 → 1.17 factorisations); extended 2.54 → 2.38 ms at 1k, 46.1 →
/// 44.3 ms at 10k; uncut 1k 2.14 → 2.12 ms; `bend_dynamic` 1.34 → 1.33 ms
/// (2.16 → 2.27 iterations, 0.087 → 0.057 factorisations). Accelerating
/// every iteration and refactorising below 2× saved more on the swinging
/// beam (1k tip 4.96 ms, 10k 54.5 ms) but cost `bend_dynamic` 12 %
/// (2.95 iterations a step: where iterations converge fast, Anderson's
/// secant estimate is mostly their nonlinearity).
pub const DEFAULT_LAGGED: LinearSolver = LinearSolver::Lagged {
    every: usize::MAX,
    refactor_after: 12,
    max_rate: 0.2,
    anderson: 5,
};

/// The last iterations a step may take ([`DynamicOptions::max_iterations`])
/// are Newton's, refactorised each, whatever the linear solver: a lagged
/// factor never fails a step that Newton would finish, and
/// `max_iterations = 1` stays the linearly implicit step on the current
/// tangent.
const NEWTON_TAIL: usize = 3;

/// Copies `from` into `to`, reusing `to`'s buffers.
fn copy_state(to: &mut State, from: &State) {
    to.time = from.time;
    for (t, f) in [
        (&mut to.d, &from.d),
        (&mut to.v, &from.v),
        (&mut to.a, &from.a),
    ] {
        t.clear();
        t.extend_from_slice(f);
    }
    to.rotations.0.clear();
    to.rotations.0.extend_from_slice(&from.rotations.0);
}

/// Halvings of a corotational time step whose Newton iterations fail before
/// the step gives up ([`Newmark::step`]): sub-steps down to 1/16 of it.
pub const MAX_STEP_HALVINGS: usize = 4;

/// The share of the body's volume inverted (det F ≤ 0) beyond which halves
/// of a failed step count as a body collapsing, not a step too large, and
/// rescue nothing ([`Newmark::step`]). Below it lie the slivers a cut leaves
/// (sides of a few 1e-3 of one element, which a soft scene can turn inside
/// out while the body around them is sound); one element of a 1k-element
/// mesh lies above it.
pub const COLLAPSED_FRACTION: f64 = 1e-4;

/// How a linear scene's first step after a cut event solves its grown K_eff
/// (`blade::run_dynamic` hands the integrator the factor of the previous one).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventSolve {
    /// Refactorise (numeric; symbolic too where the pattern grew).
    Refactorise,
    /// Where the events since the factor only appended equations, solve on
    /// that factor through a [`BorderedSolve`] while its border k stays
    /// within [`border_limit`] (`max_border` and 2 nnz(L) / n); refactorise
    /// otherwise (dropped DOFs, a tip front whose branch functions change
    /// most old equations, a border too large), and start the next border
    /// from the new factor. A border whose steps have cost a factorisation
    /// ([`refresh_after`]) is refactorised at the next step.
    Bordered { max_border: usize },
}

/// The largest border a [`EventSolve::Bordered`] builds on a factor of order
/// `n` with `factor_nnz` non-zeros in L: its product with the n × k matrix
/// Z reads n k values a step, at most what a solve on the factor reads
/// (2 nnz(L)), so k ≤ 2 nnz(L) / n; and `max_border`.
pub fn border_limit(max_border: usize, n: usize, factor_nnz: usize) -> usize {
    max_border.min(2 * factor_nnz / n.max(1))
}

/// The default [`EventSolve`]: bordered, k ≤ 256. On the seed blade
/// (`examples/border_costs.rs`, one factor under every later event) the
/// set-up of a Schur border of k = 78 (36 columns solved) on the 10k Tet4
/// beam cost 34 ms against 56 ms numeric + 19 ms symbolic, of k = 78 (24
/// solved) on the 1k Tet10 beam 31 ms against 87 + 38 ms; whole sweeps
/// (`examples/sweep_series.rs`) reach k = 24, 117 and 102 on the 1k, 10k
/// Tet4 and 1k Tet10 beams.
pub const DEFAULT_EVENT_SOLVE: EventSolve = EventSolve::Bordered { max_border: 256 };

/// An integrator's factorisation handed across a cut event
/// ([`Newmark::into_factor`], [`Newmark::on_factor`]).
pub struct LinearFactor {
    pub chol: Cholesky,
    /// The K_eff that `chol` holds (lower CSC on `chol.pattern()`); `None`
    /// where it holds something else (a corotational tangent, the mass of
    /// the initial acceleration) or nothing yet.
    pub values: Option<Vec<f64>>,
    /// The border the integrator solved with on `chol`, if any: the next
    /// one on the same factor reuses its columns ([`BorderedSolve::grown`]).
    pub border: Option<BorderedSolve>,
    /// Corotational on a lagged factor ([`LinearSolver::Lagged`]): `chol`
    /// holds a factorisation of an earlier step's K_eff, begun this many
    /// steps ago; `None` where it holds none.
    pub lagged: Option<usize>,
}

/// The factor a linear step solves on after cut events, and the matrix it holds.
struct Base {
    pattern: Pattern,
    values: Vec<f64>,
    /// The previous integrator's border on the same factor.
    previous: Option<BorderedSolve>,
    /// Built by the first step (`None` before, or where it refactorised).
    solve: Option<BorderedSolve>,
    /// Solves done on the border, and after how many it is refactorised
    /// ([`refresh_after`]).
    steps: usize,
    refresh_after: usize,
}

impl Base {
    fn refresh_due(&self) -> bool {
        self.solve.is_some() && self.steps >= self.refresh_after
    }
}

/// Numeric factorisations cost about this many solves on the factor
/// (measured on the seed beam by `examples/border_costs.rs`: 12–20 at 1k Tet4, about 12 at 10k).
const FACTORISATION_IN_SOLVES: usize = 12;

/// Steps after which a border of size k on a factor of order `n` with
/// `factor_nnz` non-zeros in L has cost the steps about one numeric
/// factorisation (the ski-rental rule: then refactorise, at most twice the
/// better choice). A step's product with the n × k matrix Z reads n k
/// values, a solve 2 nnz(L); the dense product may run at half the solve's
/// speed per value (Woodbury borders, `examples/border_costs.rs`: +0.2 to
/// +0.9 solves a step at k = 42–156; Schur borders +0.0 to +0.15 at
/// k = 18–78), so the border is taken to add n k / nnz(L) solves a step
/// (conservative: it refreshes early rather than late) and to pay a
/// factorisation after
/// nnz(L) · [`FACTORISATION_IN_SOLVES`] / (n k) steps.
pub fn refresh_after(border: usize, n: usize, factor_nnz: usize) -> usize {
    if border == 0 {
        return usize::MAX;
    }
    (factor_nnz * FACTORISATION_IN_SOLVES).div_ceil(n.max(1) * border)
}

/// Mass matrix used in the time integration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MassKind {
    Lumped,
    Consistent,
}

#[derive(Debug, Clone, Copy)]
pub struct DynamicOptions {
    pub dt: f64,
    pub steps: usize,
    pub beta: f64,
    pub gamma: f64,
    /// α of the damping Dₙ = α M + β_R Rₙ K Rₙᵀ (see the module comment).
    pub rayleigh_mass: f64,
    /// β_R of the damping Dₙ = α M + β_R Rₙ K Rₙᵀ (Rₙ: the rotations at the step's start).
    pub rayleigh_stiffness: f64,
    /// Time over which prescribed displacements ramp up (0: at once).
    pub ramp: f64,
    pub mass: MassKind,
    /// Newton tolerance (relative residual) and iteration cap per step.
    pub tolerance: f64,
    pub max_iterations: usize,
    pub linear_solver: LinearSolver,
    /// Corotational Newton on the exact tangent c₀M + c₁D + K_exact (the
    /// rotation's derivative included, as statics uses), falling back to
    /// R K Rᵀ in an iteration where that is not positive definite; false:
    /// R K Rᵀ throughout (the seed's).
    pub exact_tangent: bool,
    /// Linear scenes: how the first step after a cut event solves (a
    /// scene's default: [`DEFAULT_EVENT_SOLVE`]).
    pub event_solve: EventSolve,
}

impl Default for DynamicOptions {
    fn default() -> Self {
        DynamicOptions {
            dt: 0.01,
            steps: 100,
            beta: 0.25,
            gamma: 0.5,
            rayleigh_mass: 0.0,
            rayleigh_stiffness: 0.0,
            ramp: 0.0,
            mass: MassKind::Lumped,
            tolerance: 1e-8,
            max_iterations: 20,
            linear_solver: LinearSolver::Direct,
            exact_tangent: true,
            event_solve: DEFAULT_EVENT_SOLVE,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum DynamicError {
    #[error(transparent)]
    Solve(#[from] SolveError),
    #[error("the model has no mass: build it with mass for a dynamic scene")]
    NoMass,
    #[error("the state became non-finite at step {0}")]
    NotFinite(usize),
    #[error("Newton did not converge at step {step} (t = {time:.6} s): relative residual {residual:e}{}", inverted_hint(*inverted, *inverted_volume, STEP_REMEDIES))]
    NoConvergence {
        step: usize,
        time: f64,
        residual: f64,
        /// Integration groups with det F ≤ 0 at the last iterate.
        inverted: usize,
        /// Their reference volume over the body's
        /// ([`crate::assembly::inverted_fraction`]): slivers of cut elements
        /// or a body that folds.
        inverted_volume: f64,
    },
}

/// The remedies a failed time step's message names where groups inverted.
const STEP_REMEDIES: &str =
    "a smaller dt, a ramp, stiffness damping (analysis.rayleigh.stiffness) or a stiffer material";

/// What a failed step's (or load step's) message adds where elements
/// inverted: how many groups, how much of the body they are (a few slivers
/// of cut elements, 1e-5 of it, or a body that folds, a few per cent), and
/// the `remedies` of the analysis.
pub(crate) fn inverted_hint(inverted: usize, volume: f64, remedies: &str) -> String {
    if inverted == 0 {
        return String::new();
    }
    let percent = 100.0 * volume;
    let percent = if percent >= 0.01 {
        format!("{percent:.2}")
    } else {
        format!("{percent:.1e}")
    };
    format!(
        "; {inverted} integration groups inverted (det F <= 0; {percent} % of the body's volume at the last iterate): {remedies} may let the mesh follow"
    )
}

/// The state of the body at one time.
#[derive(Debug, Clone)]
pub struct State {
    pub time: f64,
    pub d: Vec<f64>,
    pub v: Vec<f64>,
    pub a: Vec<f64>,
    pub rotations: Rotations,
}

/// The time a step of `dt` from `t` ends at: n·dt where t + dt is within
/// round-off of that multiple of the step (a run from 0 then has its step n
/// at n·dt to the last bit, where summing dt drifted: 1.49999999999999 s
/// after 300 steps of 5 ms), else t + dt.
pub fn next_time(t: f64, dt: f64) -> f64 {
    let sum = t + dt;
    let n = (sum / dt).round();
    let grid = n * dt;
    if (grid - sum).abs() <= 1e-9 * dt {
        grid
    } else {
        sum
    }
}

/// Energies of a state.
#[derive(Debug, Clone, Copy, Default)]
pub struct Energies {
    pub kinetic: f64,
    pub strain: f64,
    /// Work of the external (body) forces: f_extᵀ d.
    pub external_work: f64,
}

/// Per-step counters.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepReport {
    /// Newton iterations (linear solves) of the step (with sub-steps: theirs
    /// and those of the failed attempts before them).
    pub iterations: usize,
    /// Final relative residual.
    pub residual: f64,
    /// Numeric factorisations of the step (failed attempts included).
    pub factorisations: usize,
    /// CG iterations of the step (PCG mode).
    pub cg_iterations: usize,
    /// Iterations where the exact tangent was not positive definite and R K Rᵀ was used.
    pub fallbacks: usize,
    /// Sub-steps beyond one: a corotational step whose Newton iterations
    /// failed was taken again as two halves (each halved again where it
    /// failed, down to 1/2^[`MAX_STEP_HALVINGS`] of the step).
    pub substeps: usize,
}

/// Per-step figures of a run, collected step by step (what `run` reports:
/// per-step time median and max, Newton and CG iterations, factorisations).
#[derive(Debug, Clone, Default)]
pub struct StepStats {
    seconds: Vec<f64>,
    newton: Vec<usize>,
    cg: usize,
    factorisations: usize,
    fallbacks: usize,
    substeps: usize,
}

/// The summary of a [`StepStats`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepSummary {
    pub steps: usize,
    pub seconds_median: f64,
    pub seconds_max: f64,
    pub newton_mean: f64,
    pub newton_max: usize,
    pub cg_per_step: f64,
    pub factorisations_per_step: f64,
    /// Iterations that fell back from the exact tangent to R K Rᵀ.
    pub fallbacks: usize,
    /// Sub-steps taken beyond one a step, over all steps ([`StepReport::substeps`]).
    pub substeps: usize,
}

impl StepStats {
    /// Room for `steps` steps (so that recording allocates nothing).
    pub fn with_capacity(steps: usize) -> StepStats {
        StepStats {
            seconds: Vec::with_capacity(steps),
            newton: Vec::with_capacity(steps),
            ..StepStats::default()
        }
    }

    /// Records one step: its report and its wall time.
    pub fn record(&mut self, report: &StepReport, seconds: f64) {
        self.seconds.push(seconds);
        self.newton.push(report.iterations);
        self.cg += report.cg_iterations;
        self.factorisations += report.factorisations;
        self.fallbacks += report.fallbacks;
        self.substeps += report.substeps;
    }

    /// Newton iterations of each recorded step.
    pub fn newton_iterations(&self) -> &[usize] {
        &self.newton
    }

    pub fn summary(&self) -> StepSummary {
        let steps = self.seconds.len();
        let mut sorted = self.seconds.clone();
        sorted.sort_by(f64::total_cmp);
        let median = match steps {
            0 => 0.0,
            n if n % 2 == 1 => sorted[n / 2],
            n => 0.5 * (sorted[n / 2 - 1] + sorted[n / 2]),
        };
        let per_step = |x: usize| {
            if steps == 0 {
                0.0
            } else {
                x as f64 / steps as f64
            }
        };
        StepSummary {
            steps,
            seconds_median: median,
            seconds_max: sorted.last().copied().unwrap_or(0.0),
            newton_mean: per_step(self.newton.iter().sum()),
            newton_max: self.newton.iter().copied().max().unwrap_or(0),
            cg_per_step: per_step(self.cg),
            factorisations_per_step: per_step(self.factorisations),
            fallbacks: self.fallbacks,
            substeps: self.substeps,
        }
    }
}

impl std::fmt::Display for StepSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} steps: {:.3} ms a step (median), {:.3} ms max; Newton {:.2} a step (max {}), CG {:.1} a step, {:.2} factorisations a step",
            self.steps,
            self.seconds_median * 1e3,
            self.seconds_max * 1e3,
            self.newton_mean,
            self.newton_max,
            self.cg_per_step,
            self.factorisations_per_step
        )?;
        if self.fallbacks > 0 {
            write!(f, ", {} R K Rᵀ fallbacks", self.fallbacks)?;
        }
        if self.substeps > 0 {
            write!(
                f,
                ", {} sub-steps where Newton failed on a whole step",
                self.substeps
            )?;
        }
        Ok(())
    }
}

/// The mass matrix as the step uses it: a product y = M x and the entries
/// that add c M into K_eff, both precomputed once (seed eq. 81–82 for the
/// lumped X-FEM mass).
struct MassOperator {
    kind: MassKind,
    /// Lumped: (CSC position, mass) of each free diagonal and u–a coupling entry.
    entries: Vec<(usize, f64)>,
    /// Consistent: gather/scatter buffers of the free–free product.
    xf: Vec<f64>,
    yf: Vec<f64>,
}

impl MassOperator {
    fn new(model: &Model, kind: MassKind) -> MassOperator {
        let mut entries = Vec::new();
        if kind == MassKind::Lumped {
            let lumped = model.lumped_mass.as_ref().expect("checked by the caller");
            let pos = |r: u32, q: u32| {
                let (r, q) = (r.max(q) as usize, r.min(q) as usize);
                model
                    .pattern
                    .position(r, q)
                    .expect("the diagonal and u_i–a_i are in the pattern")
            };
            for (s, &ms) in lumped.iter().enumerate() {
                for c in 0..3 {
                    let eq = model.equation[3 * s + c];
                    if eq != NONE {
                        entries.push((pos(eq, eq), ms));
                    }
                }
            }
            if let (Some(cut), Some(coupling)) = (&model.cut, &model.lumped_coupling) {
                for (i, e) in cut.enriched.iter().enumerate() {
                    if let Some(j) = *e {
                        let sa = model.mesh.n_nodes() + j;
                        for c in 0..3 {
                            let (r, q) = (model.equation[3 * sa + c], model.equation[3 * i + c]);
                            if r != NONE && q != NONE {
                                entries.push((pos(r, q), coupling[j]));
                            }
                        }
                    }
                }
            }
        }
        let n = if kind == MassKind::Consistent {
            model.n_free
        } else {
            0
        };
        MassOperator {
            kind,
            entries,
            xf: vec![0.0; n],
            yf: vec![0.0; n],
        }
    }

    /// y = M x (all DOFs).
    fn product(&mut self, m: &Model, x: &[f64], y: &mut [f64]) {
        match self.kind {
            MassKind::Lumped => {
                let lumped = m.lumped_mass.as_ref().expect("checked in new");
                for (s, ms) in lumped.iter().enumerate() {
                    for c in 0..3 {
                        y[3 * s + c] = ms * x[3 * s + c];
                    }
                }
                // Side-wise lumping couples u_i and a_i of each enriched node.
                if let (Some(cut), Some(coupling)) = (&m.cut, &m.lumped_coupling) {
                    for (i, e) in cut.enriched.iter().enumerate() {
                        if let Some(j) = *e {
                            let sa = m.mesh.n_nodes() + j;
                            for c in 0..3 {
                                y[3 * i + c] += coupling[j] * x[3 * sa + c];
                                y[3 * sa + c] += coupling[j] * x[3 * i + c];
                            }
                        }
                    }
                }
            }
            MassKind::Consistent => {
                // Free–free block only: prescribed DOFs move with zero acceleration after the ramp.
                let values = m
                    .consistent_mass
                    .as_ref()
                    .expect("built with the lumped mass");
                gather_free(m, x, &mut self.xf);
                self.yf.fill(0.0);
                m.pattern.sym_mul_add(values, &self.xf, &mut self.yf);
                y.fill(0.0);
                for (dof, &eq) in m.equation.iter().enumerate() {
                    if eq != NONE {
                        y[dof] = self.yf[eq as usize];
                    }
                }
            }
        }
    }

    /// keff += factor M on the pattern.
    fn add_to(&self, m: &Model, factor: f64, keff: &mut [f64]) {
        match self.kind {
            MassKind::Lumped => {
                for &(pos, mass) in &self.entries {
                    keff[pos] += factor * mass;
                }
            }
            MassKind::Consistent => {
                let values = m
                    .consistent_mass
                    .as_ref()
                    .expect("built with the lumped mass");
                for (k, mv) in keff.iter_mut().zip(values) {
                    *k += factor * mv;
                }
            }
        }
    }
}

/// Per-shape-function rotations warping a factorisation (see [`LinearSolver::WarpedPcg`]).
struct Warp {
    /// Σ w_g R_g over the groups touching each shape function (scratch).
    sum: Vec<Matrix3<f64>>,
    /// R_s now.
    now: Vec<Matrix3<f64>>,
    /// R_s at the last factorisation.
    at_factor: Vec<Matrix3<f64>>,
    /// R_s R_{s,f}ᵀ.
    relative: Vec<Matrix3<f64>>,
    full: Vec<f64>,
    free: Vec<f64>,
}

impl Warp {
    fn new(model: &Model) -> Warp {
        let n = model.n_dofs() / 3;
        Warp {
            sum: vec![Matrix3::zeros(); n],
            now: vec![Matrix3::identity(); n],
            at_factor: vec![Matrix3::identity(); n],
            relative: vec![Matrix3::identity(); n],
            full: vec![0.0; model.n_dofs()],
            free: vec![0.0; model.n_free],
        }
    }

    /// R_s from the group rotations (the previous R_s as the polar guess).
    fn update(&mut self, model: &Model, rot: &Rotations) {
        self.sum.fill(Matrix3::zeros());
        for el in &model.elements {
            let shapes = &model.shape_ids[el.shapes.clone()];
            for g in el.groups.clone() {
                let wr = rot.0[g] * model.groups[g].weight.abs();
                for &s in shapes {
                    self.sum[s as usize] += wr;
                }
            }
        }
        for (now, sum) in self.now.iter_mut().zip(&self.sum) {
            if sum.norm() > 0.0 {
                *now = polar_rotation(sum, now);
            }
        }
        for (i, rel) in self.relative.iter_mut().enumerate() {
            *rel = self.now[i] * self.at_factor[i].transpose();
        }
    }

    /// x ← G Q Gᵀ x (free equations; Q = blockdiag(relative) or its transpose).
    fn apply(&mut self, model: &Model, x: &mut [f64], transpose: bool) {
        self.full.fill(0.0);
        for (dof, &eq) in model.equation.iter().enumerate() {
            if eq != NONE {
                self.full[dof] = x[eq as usize];
            }
        }
        for (s, q) in self.relative.iter().enumerate() {
            let v = Vector3::new(self.full[3 * s], self.full[3 * s + 1], self.full[3 * s + 2]);
            let w = if transpose { q.tr_mul(&v) } else { q * v };
            self.full[3 * s..3 * s + 3].copy_from_slice(w.as_slice());
        }
        gather_free(model, &self.full, &mut self.free);
        x.copy_from_slice(&self.free);
    }
}

/// A Newmark integrator borrowing the model; all buffers allocated once.
pub struct Newmark<'m> {
    model: &'m Model,
    opts: DynamicOptions,
    /// External force at full load: the model's, or with the lumped mass
    /// [`Model::lumped_load`] where that differs (Tet10 parts that float free).
    load: Vec<f64>,
    chol: Cholesky,
    ws: Workspace,
    mass: MassOperator,
    /// CSC position of each free equation's diagonal.
    diagonal: Vec<usize>,
    keff: Vec<f64>,
    f_int: Vec<f64>,
    d_old: Vec<f64>,
    r_full: Vec<f64>,
    r_free: Vec<f64>,
    kv: Vec<f64>,
    mv: Vec<f64>,
    a_new: Vec<f64>,
    v_new: Vec<f64>,
    /// Rotations scratch for [`Newmark::energies`].
    rot_scratch: Rotations,
    /// The rotations Rₙ at the start of the step (the damping's).
    rot_start: Rotations,
    /// β_R's stiffness Rₙ K Rₙᵀ of the step (lower CSC values; empty
    /// unless corotational with stiffness damping), assembled when a step
    /// first needs its Newton matrix.
    damping_k: Vec<f64>,
    /// Whether `damping_k` is that of the current step's Rₙ.
    damping_current: bool,
    /// Steps begun since the last factorisation (the lagged factor's age).
    steps_since_factor: usize,
    /// ‖f_ext‖ (a residual scale).
    load_norm: f64,
    /// f_ε / tolerance ([`crate::statics::residual_scale_floor`]): the smallest
    /// residual scale, so that a residual at the forces' round-off level
    /// meets the tolerance (a body at rest under a tiny load, or moved
    /// rigidly, has forces near zero and ‖r‖/‖f‖ near 1 whatever Newton does).
    round_off: f64,
    /// Whether a factorisation of K_eff exists (current for linear scenes, maybe stale for PCG).
    factored: bool,
    pcg: Pcg,
    warp: Option<Warp>,
    dx: Vec<f64>,
    /// Linear, after a cut event: the previous factor and its matrix.
    base: Option<Base>,
    /// Symbolic factorisations done by the integrator (a base it could not border on).
    symbolic: usize,
    /// Borders left for a factorisation of their own ([`refresh_after`]).
    refreshed: usize,
    /// The border built by the first step, if any.
    built_border: Option<usize>,
    pub state: State,
    /// Strain energy of the current state.
    pub strain_energy: f64,
    last_report: Option<StepReport>,
    /// The state before a step that failed, per halving depth (see [`Newmark::step`]).
    saved: Vec<State>,
    /// Linear formulation: the assembled stiffness the step's internal
    /// forces come from (no element loop per step).
    linear: Option<LinearForces>,
    /// Corotational on a lagged factor: Anderson acceleration of the
    /// iterations on one factor, and the free part of the iterate.
    anderson: Option<Anderson>,
    x_free: Vec<f64>,
}

/// The linear formulation's internal forces from the assembled stiffness
/// (built once per model): on the free equations
/// f = K_ff d_f + λ K_fp p̄ and the strain energy
/// ½ d_f·K_ff d_f + λ d_f·K_fp p̄ + λ² ½ p̄·K_pp p̄, where the prescribed
/// displacements are d_p = λ p̄ (every step sets them so). One sparse
/// product instead of a pass over the elements, whose dense tip groups
/// hold (3m)² values each (six times nnz(K) at 1k Tet4 with the front
/// tip-enriched). Carried across a cut event by [`LinearForces::updated`].
pub struct LinearForces {
    /// K_ff on the model's pattern (lower triangle).
    k: Vec<f64>,
    /// K_fp p̄ on the free equations.
    prescribed: Vec<f64>,
    /// ½ p̄·K_pp p̄.
    prescribed_energy: f64,
    /// The first prescribed DOF with a non-zero value, and that value: λ = d[dof] / value.
    scale_dof: Option<(usize, f64)>,
    d_free: Vec<f64>,
    kd: Vec<f64>,
}

impl LinearForces {
    fn new(model: &Model, ws: &mut Workspace) -> LinearForces {
        let n = model.n_dofs();
        let mut k = vec![0.0; model.pattern.nnz()];
        let mut f = vec![0.0; n];
        let mut rot = Rotations::identity(model);
        // One pass at d = p̄: the tangent K (the same at any d) and the forces
        // K p̄, whose free rows are K_fp p̄ (d_f = 0), with the energy ½ p̄·K_pp p̄.
        let mut pbar = vec![0.0; n];
        for p in &model.prescribed {
            pbar[p.dof] = p.value;
        }
        let prescribed_energy = evaluate(
            model,
            &pbar,
            &mut rot,
            ws,
            Request {
                forces: Some(&mut f),
                tangent: Some(&mut k),
                update_rotations: false,
                exact_tangent: false,
            },
        );
        let mut prescribed = vec![0.0; model.n_free];
        gather_free(model, &f, &mut prescribed);
        LinearForces {
            k,
            prescribed,
            prescribed_energy,
            scale_dof: model
                .prescribed
                .iter()
                .find(|p| p.value != 0.0)
                .map(|p| (p.dof, p.value)),
            d_free: vec![0.0; model.n_free],
            kd: vec![0.0; model.n_free],
        }
    }

    /// These forces for `new`, the model [`Model::update_cut_mapped`] made
    /// from `old` (whose forces these are) with `update`: the old stiffness
    /// moved to the new positions, the changed elements' old blocks taken
    /// out and their new ones added — a pass over the changed elements
    /// instead of all. Equal to [`LinearForces::new`] on `new` to round-off.
    pub fn updated(self, old: &Model, new: &Model, update: &CutUpdate) -> LinearForces {
        debug_assert_eq!(self.k.len(), old.pattern.nnz());
        let pbar = |m: &Model| {
            let mut p = vec![0.0; m.n_dofs()];
            for q in &m.prescribed {
                p[q.dof] = q.value;
            }
            p
        };
        let mut k = vec![0.0; new.pattern.nnz()];
        for (&v, &q) in self.k.iter().zip(&update.position) {
            if q != NONE {
                k[q as usize] += v;
            }
        }
        let mut prescribed = vec![0.0; new.n_free];
        for (&v, &q) in self.prescribed.iter().zip(&update.equation) {
            if q != NONE {
                prescribed[q as usize] += v;
            }
        }
        // The changed elements' old blocks out: assembled on the old pattern
        // (zeroed pages, touched only there), taken out where their scatter maps point.
        let (mut f_old, mut k_old) = (vec![0.0; old.n_dofs()], vec![0.0; old.pattern.nnz()]);
        let e_old = add_linear_elements(
            old,
            &pbar(old),
            &update.changed,
            &mut Workspace::new(old),
            &mut f_old,
            &mut k_old,
        );
        for &e in &update.changed {
            let el = &old.elements[e];
            let m = el.shapes.len();
            for &p in &old.scatter[el.scatter..el.scatter + 9 * m * m] {
                if p == NONE {
                    continue;
                }
                let (v, q) = (
                    std::mem::take(&mut k_old[p as usize]),
                    update.position[p as usize],
                );
                if v != 0.0 && q != NONE {
                    k[q as usize] -= v;
                }
            }
        }
        for (dof, &eq) in old.equation.iter().enumerate() {
            if eq != NONE {
                let q = update.equation[eq as usize];
                if q != NONE {
                    prescribed[q as usize] -= f_old[dof];
                }
            }
        }
        // Their new blocks in, straight onto the new pattern.
        let mut f_new = vec![0.0; new.n_dofs()];
        let e_new = add_linear_elements(
            new,
            &pbar(new),
            &update.changed,
            &mut Workspace::new(new),
            &mut f_new,
            &mut k,
        );
        for (dof, &eq) in new.equation.iter().enumerate() {
            if eq != NONE {
                prescribed[eq as usize] += f_new[dof];
            }
        }
        LinearForces {
            k,
            prescribed,
            prescribed_energy: self.prescribed_energy - e_old + e_new,
            scale_dof: self.scale_dof,
            d_free: vec![0.0; new.n_free],
            kd: vec![0.0; new.n_free],
        }
    }

    /// The internal forces at `d` into `f` (free DOFs; zero at prescribed
    /// ones, whose reactions the step does not need); returns the strain energy.
    fn forces(&mut self, model: &Model, d: &[f64], f: &mut [f64]) -> f64 {
        gather_free(model, d, &mut self.d_free);
        self.kd.fill(0.0);
        model
            .pattern
            .sym_mul_add(&self.k, &self.d_free, &mut self.kd);
        let lambda = self.scale_dof.map_or(0.0, |(dof, value)| d[dof] / value);
        let mut energy = lambda * lambda * self.prescribed_energy;
        for ((kd, x), g) in self.kd.iter_mut().zip(&self.d_free).zip(&self.prescribed) {
            energy += 0.5 * x * *kd + lambda * x * g;
            *kd += lambda * g;
        }
        for (dof, &eq) in model.equation.iter().enumerate() {
            f[dof] = if eq == NONE {
                0.0
            } else {
                self.kd[eq as usize]
            };
        }
        energy
    }
}

impl<'m> Newmark<'m> {
    /// Starts at rest (d = v = a = 0) at t = 0.
    pub fn new(
        model: &'m Model,
        chol: Cholesky,
        opts: DynamicOptions,
    ) -> Result<Newmark<'m>, DynamicError> {
        if model.lumped_mass.is_none() {
            return Err(DynamicError::NoMass);
        }
        let n = model.n_dofs();
        let diagonal = (0..model.n_free)
            .map(|eq| {
                model
                    .pattern
                    .position(eq, eq)
                    .expect("diagonal is in the pattern")
            })
            .collect();
        let load = match opts.mass {
            MassKind::Lumped => model.lumped_load(),
            MassKind::Consistent => None,
        }
        .unwrap_or_else(|| model.load.clone());
        let load_norm = norm(&load);
        Ok(Newmark {
            model,
            opts,
            load,
            chol,
            ws: Workspace::new(model),
            mass: MassOperator::new(model, opts.mass),
            diagonal,
            keff: vec![0.0; model.pattern.nnz()],
            f_int: vec![0.0; n],
            d_old: vec![0.0; n],
            r_full: vec![0.0; n],
            r_free: vec![0.0; model.n_free],
            kv: vec![0.0; n],
            mv: vec![0.0; n],
            a_new: vec![0.0; n],
            v_new: vec![0.0; n],
            rot_scratch: Rotations::identity(model),
            rot_start: Rotations::identity(model),
            damping_k: if model.formulation == Formulation::Corotational
                && opts.rayleigh_stiffness != 0.0
            {
                vec![0.0; model.pattern.nnz()]
            } else {
                Vec::new()
            },
            damping_current: false,
            steps_since_factor: 0,
            load_norm,
            round_off: crate::statics::residual_scale_floor(model, opts.tolerance),
            factored: false,
            pcg: Pcg::new(model.n_free),
            warp: matches!(opts.linear_solver, LinearSolver::WarpedPcg { .. })
                .then(|| Warp::new(model)),
            dx: vec![0.0; model.n_free],
            base: None,
            symbolic: 0,
            refreshed: 0,
            built_border: None,
            state: State {
                time: 0.0,
                d: vec![0.0; n],
                v: vec![0.0; n],
                a: vec![0.0; n],
                rotations: Rotations::identity(model),
            },
            strain_energy: 0.0,
            last_report: None,
            saved: Vec::new(),
            linear: None,
            anderson: match opts.linear_solver {
                LinearSolver::Lagged { anderson, .. }
                    if anderson > 0 && model.formulation != Formulation::Linear =>
                {
                    Some(Anderson::new(model.n_free, anderson))
                }
                _ => None,
            },
            x_free: vec![0.0; model.n_free],
        })
    }

    /// Runs the element loops on `parallelism`'s threads (the factorisation's
    /// threads are the [`Cholesky`]'s, set where it is built).
    pub fn set_parallelism(&mut self, parallelism: crate::solve::Parallelism) {
        self.ws = Workspace::with_parallelism(self.model, parallelism);
    }

    /// The options the integrator runs with.
    pub fn options(&self) -> &DynamicOptions {
        &self.opts
    }

    /// Starts at rest on the factor of an earlier integrator on the same mesh
    /// (a cut event: `factor` holds the previous K_eff, maybe on a smaller
    /// pattern). A linear scene with [`EventSolve::Bordered`] keeps it and
    /// its first step solves the grown K_eff on it ([`BorderedSolve`]) where
    /// it can; otherwise the symbolic factorisation is redone here where the
    /// pattern differs. A corotational scene on a lagged factor
    /// ([`LinearSolver::Lagged`]) whose `factor` holds one (`lagged`) on the
    /// model's pattern iterates on it, as on any lagged factor: modified
    /// Newton, refactorised where its rate or count asks for it. The caller
    /// vouches that the old equations kept their numbers when it passes
    /// `values` or `lagged`.
    pub fn on_factor(
        model: &'m Model,
        factor: LinearFactor,
        opts: DynamicOptions,
    ) -> Result<Newmark<'m>, DynamicError> {
        let mut nm = Newmark::new(model, factor.chol, opts)?;
        let bordered = matches!(opts.event_solve, EventSolve::Bordered { .. });
        let linear = model.formulation == Formulation::Linear;
        match factor.values {
            Some(values) if bordered && linear => {
                nm.base = Some(Base {
                    pattern: nm.chol.pattern().clone(),
                    values,
                    previous: factor.border,
                    solve: None,
                    steps: 0,
                    refresh_after: usize::MAX,
                });
            }
            _ => nm.match_pattern()?,
        }
        if let (Some(age), LinearSolver::Lagged { .. }, false) =
            (factor.lagged, opts.linear_solver, linear)
        {
            // match_pattern kept the factor only where the pattern is the model's.
            if nm.symbolic == 0 {
                nm.factored = true;
                nm.steps_since_factor = age;
            }
        }
        Ok(nm)
    }

    /// Drops the base, if any, and with it the factor's old pattern.
    fn drop_base(&mut self) -> Result<(), SolveError> {
        if self.base.take().is_some() {
            self.match_pattern()?;
        }
        Ok(())
    }

    /// Makes the factorisation one of the model's pattern (symbolic analysis
    /// redone where it differs; the counter kept).
    fn match_pattern(&mut self) -> Result<(), SolveError> {
        let p = self.chol.pattern();
        let same =
            p.col_ptr == self.model.pattern.col_ptr && p.row_idx == self.model.pattern.row_idx;
        if !same {
            let counted = self.chol.factorisations;
            self.chol = crate::blade::sweep_factor(self.model)?;
            self.chol.factorisations = counted;
            self.symbolic += 1;
        }
        Ok(())
    }

    /// The first step's bordered solve on the base ([`Newmark::on_factor`]),
    /// if the grown K_eff allows one within the border limit.
    fn try_border(&mut self) -> bool {
        let EventSolve::Bordered { max_border } = self.opts.event_solve else {
            return false;
        };
        let Some(base) = self.base.as_mut() else {
            return false;
        };
        let limit = border_limit(max_border, base.pattern.n, self.chol.factor_nnz());
        base.solve = BorderedSolve::grown_within(
            base.previous.take(),
            &mut self.chol,
            &base.pattern,
            &base.values,
            &self.model.pattern,
            &self.keff,
            BORDER_TOLERANCE,
            limit,
        );
        self.built_border = base.solve.as_ref().map(BorderedSolve::border);
        if let Some(b) = &base.solve {
            base.refresh_after = refresh_after(b.border(), base.pattern.n, self.chol.factor_nnz());
        }
        base.solve.is_some()
    }

    /// Size of the border the first step built on the base and the steps
    /// solved with (until a refresh, [`Newmark::refreshes`]); `None`: they
    /// solved on their own factor.
    pub fn border(&self) -> Option<usize> {
        self.built_border
    }

    /// Symbolic factorisations this integrator did ([`Newmark::on_factor`]).
    pub fn symbolic_factorisations(&self) -> usize {
        self.symbolic
    }

    /// Times the steps left a border for their own factor ([`refresh_after`]).
    pub fn refreshes(&self) -> usize {
        self.refreshed
    }

    /// The linear forces this integrator assembled (its model's), if any:
    /// to carry across a cut event ([`LinearForces::updated`]).
    pub fn take_linear_forces(&mut self) -> Option<LinearForces> {
        self.linear.take()
    }

    /// Gives the integrator its model's linear forces (from
    /// [`LinearForces::updated`] at a cut event) instead of assembling them
    /// at its first step.
    pub fn set_linear_forces(&mut self, forces: LinearForces) {
        debug_assert_eq!(forces.k.len(), self.model.pattern.nnz());
        debug_assert_eq!(forces.prescribed.len(), self.model.n_free);
        self.linear = Some(forces);
    }

    /// Ends the integrator, handing its factorisation to the next one across
    /// a cut event ([`Newmark::on_factor`]), with the K_eff it holds.
    pub fn into_factor(self) -> LinearFactor {
        let linear = self.model.formulation == Formulation::Linear;
        let (values, border) = match self.base {
            Some(base) => (Some(base.values), base.solve.or(base.previous)),
            None if linear && self.factored => (Some(self.keff), None),
            None => (None, None),
        };
        let lagged = (!linear
            && self.factored
            && matches!(self.opts.linear_solver, LinearSolver::Lagged { .. }))
        .then_some(self.steps_since_factor);
        LinearFactor {
            chol: self.chol,
            values,
            border,
            lagged,
        }
    }

    /// Ends the integrator, handing back its factorisation (symbolic analysis
    /// and buffers) to start another on the same pattern without redoing them
    /// (after [`Newmark::on_factor`] with a border: the factor of the base's
    /// pattern, not the model's; [`Newmark::into_factor`] says which).
    pub fn into_cholesky(self) -> Cholesky {
        self.chol
    }

    /// Ends the integration, giving back the state and the factorisation
    /// (a progressive cut maps the state onto its new model and keeps the
    /// symbolic analysis where the pattern did not change).
    pub fn into_parts(self) -> (State, Cholesky) {
        (self.state, self.chol)
    }

    /// Sets the acceleration consistent with the current state: M a = f_ext − f_int − D v
    /// on the free DOFs (the lumped mass is diagonal; a consistent mass is factorised once for it).
    pub fn initialise_acceleration(&mut self) -> Result<(), DynamicError> {
        let model = self.model;
        self.strain_energy = evaluate(
            model,
            &self.state.d,
            &mut self.state.rotations,
            &mut self.ws,
            Request {
                forces: Some(&mut self.f_int),
                tangent: None,
                update_rotations: model.formulation == Formulation::Corotational,
                exact_tangent: false,
            },
        );
        for i in 0..self.r_full.len() {
            self.r_full[i] = self.load[i] - self.f_int[i];
        }
        gather_free(model, &self.r_full, &mut self.r_free);
        // M a = r on the free DOFs: M on the pattern (the lumped one has
        // u–a couplings at enriched nodes), factorised once for this.
        self.drop_base()?;
        self.keff.fill(0.0);
        self.mass.add_to(model, 1.0, &mut self.keff);
        // Zero-mass DOFs (none in practice) would make M singular: give them unit mass.
        for &pos in &self.diagonal {
            if self.keff[pos] <= 0.0 {
                self.keff[pos] = 1.0;
            }
        }
        self.chol.factorize(&self.keff)?;
        self.chol.solve_in_place(&mut self.r_free);
        self.factored = false;
        for (dof, &eq) in model.equation.iter().enumerate() {
            if eq != NONE {
                self.state.a[dof] = self.r_free[eq as usize];
            }
        }
        Ok(())
    }

    pub fn factorisations(&self) -> usize {
        self.chol.factorisations
    }

    /// How its factorisation is held ([`Cholesky::describe`]).
    pub fn factor_description(&self) -> String {
        self.chol.describe()
    }

    /// CG iterations done so far (PCG mode).
    pub fn cg_iterations(&self) -> usize {
        self.pcg.iterations
    }

    /// Energies of the current state (the strain energy is evaluated afresh).
    pub fn energies(&mut self) -> Energies {
        self.rot_scratch.0.copy_from_slice(&self.state.rotations.0);
        self.strain_energy = evaluate(
            self.model,
            &self.state.d,
            &mut self.rot_scratch,
            &mut self.ws,
            Request {
                forces: None,
                tangent: None,
                update_rotations: self.model.formulation == Formulation::Corotational,
                exact_tangent: false,
            },
        );
        self.mass.product(self.model, &self.state.v, &mut self.mv);
        let kinetic = 0.5 * dot(&self.state.v, &self.mv);
        let external_work = dot(&self.load, &self.state.d);
        Energies {
            kinetic,
            strain: self.strain_energy,
            external_work,
        }
    }

    /// Ramp factor of prescribed displacements at time t.
    fn ramp(&self, t: f64) -> f64 {
        if self.opts.ramp > 0.0 {
            (t / self.opts.ramp).min(1.0)
        } else {
            1.0
        }
    }

    /// dλ/dt of the ramp at time t: 1/ramp inside it, 0 after it (and at
    /// its end, where the prescribed motion stops).
    fn ramp_rate(&self, t: f64) -> f64 {
        let ramp = self.opts.ramp;
        if ramp > 0.0 && t < ramp * (1.0 - 1e-12) {
            1.0 / ramp
        } else {
            0.0
        }
    }

    /// a(d), v(d) of the Newmark scheme into `a_new`, `v_new`.
    fn kinematics(&mut self, d: &[f64]) {
        let o = self.opts;
        let dt = o.dt;
        let c0 = 1.0 / (o.beta * dt * dt);
        let c1 = 1.0 / (o.beta * dt);
        let c2 = 1.0 / (2.0 * o.beta) - 1.0;
        let s = &self.state;
        for i in 0..d.len() {
            self.a_new[i] = c0 * (d[i] - self.d_old[i]) - c1 * s.v[i] - c2 * s.a[i];
            self.v_new[i] = s.v[i] + dt * ((1.0 - o.gamma) * s.a[i] + o.gamma * self.a_new[i]);
        }
        // Prescribed DOFs move as prescribed: d = λ(t) p̄, v = λ'(t) p̄, a = 0
        // (λ is linear in the ramp and constant after it). Newmark's own
        // v and a of a DOF whose motion has a kink ring for ever (the
        // trapezoidal rule flips v each step once d stops), and the
        // stiffness damping β_R K v would feed that ringing into the body.
        let rate = self.ramp_rate(s.time + dt);
        for p in &self.model.prescribed {
            self.v_new[p.dof] = rate * p.value;
            self.a_new[p.dof] = 0.0;
        }
    }

    /// Advances one time step. A corotational step whose Newton iterations
    /// fail (or leave the finite numbers) is taken again from the state
    /// before it (which a failed step leaves recoverable: nothing is copied
    /// before a step) as two steps of half the size, each halved again where it
    /// fails, down to 1/2^[`MAX_STEP_HALVINGS`] of the step. The whole
    /// step's failure is returned when that fails too, or when the halves
    /// end with more than [`COLLAPSED_FRACTION`] of the body inverted (a
    /// column collapsing onto its clamp is reported, not carried on
    /// inverted). (A top face moved by 4 % of the
    /// beam in one step, ν = 0.49, Tet10: Newton failed at the second step;
    /// in halves it runs.)
    pub fn step(&mut self) -> Result<StepReport, DynamicError> {
        let report = self.step_halving(0)?;
        self.last_report = Some(report);
        Ok(report)
    }

    fn step_halving(&mut self, depth: usize) -> Result<StepReport, DynamicError> {
        let can_halve = self.model.formulation != Formulation::Linear
            && self.opts.max_iterations > 1
            && depth < MAX_STEP_HALVINGS;
        if !can_halve {
            return self.step_inner();
        }
        let (factor_start, cg_start) = (self.chol.factorisations, self.pcg.iterations);
        let failure = match self.step_inner() {
            Err(e @ (DynamicError::NoConvergence { .. } | DynamicError::NotFinite(_))) => e,
            other => return other,
        };
        // Nothing is copied before a step: a failed one left t, v and a as
        // they were and dₙ, Rₙ in `d_old`, `rot_start` (`begin_step`).
        self.state.d.clear();
        self.state.d.extend_from_slice(&self.d_old);
        self.state.rotations.0.copy_from_slice(&self.rot_start.0);
        self.save_state(depth);
        // The failed attempt's iterations count (NoConvergence: all it may take).
        let wasted = match failure {
            DynamicError::NoConvergence { .. } => self.opts.max_iterations,
            _ => 0,
        };
        let dt = self.opts.dt;
        self.opts.dt = 0.5 * dt;
        // K_eff holds c₀ M = M / (β Δt²): a factor of another Δt is stale.
        self.factored = false;
        let halves = self.step_halving(depth + 1).and_then(|a| {
            let b = self.step_halving(depth + 1)?;
            Ok(StepReport {
                iterations: wasted + a.iterations + b.iterations,
                residual: b.residual,
                factorisations: self.chol.factorisations - factor_start,
                cg_iterations: self.pcg.iterations - cg_start,
                fallbacks: a.fallbacks + b.fallbacks,
                substeps: a.substeps + b.substeps + 1,
            })
        });
        self.opts.dt = dt;
        self.factored = false;
        // Halves that end with inverted elements (a body collapsing, not a
        // step too large) rescue nothing: the whole step's failure stands.
        // Slivers of cut elements turned inside out are no collapse (a
        // step that converges with them goes on as well): only more than
        // COLLAPSED_FRACTION of the body's volume inverted counts.
        match halves {
            Ok(report)
                if crate::assembly::inverted_fraction(self.model, &self.state.d)
                    <= COLLAPSED_FRACTION =>
            {
                Ok(report)
            }
            _ => {
                self.restore_state(depth);
                Err(failure)
            }
        }
    }

    /// Keeps the state before the step that failed at halving depth
    /// `depth`, to go back to if its halves fail too.
    fn save_state(&mut self, depth: usize) {
        while self.saved.len() <= depth {
            self.saved.push(self.state.clone());
        }
        copy_state(&mut self.saved[depth], &self.state);
    }

    fn restore_state(&mut self, depth: usize) {
        copy_state(&mut self.state, &self.saved[depth]);
    }

    /// The counters of the last step taken, if any.
    pub fn last_report(&self) -> Option<StepReport> {
        self.last_report
    }

    fn step_inner(&mut self) -> Result<StepReport, DynamicError> {
        let model = self.model;
        let o = self.opts;
        let t_new = next_time(self.state.time, o.dt);
        let linear = model.formulation == Formulation::Linear;
        let exact = o.exact_tangent && !linear;
        let step_no = (t_new / o.dt).round() as usize;
        let (factor_start, cg_start) = (self.chol.factorisations, self.pcg.iterations);
        // A border whose steps have cost a factorisation: refactorise now.
        if linear && self.base.as_ref().is_some_and(Base::refresh_due) {
            self.drop_base()?;
            self.factored = false;
            self.refreshed += 1;
        }
        let mut d = self.begin_step(t_new);
        let mut report = StepReport::default();
        // Lagged factor: iterations of this step on the current factor, and
        // the residual before the last of them.
        let mut on_this_factor = 0;
        let mut before_last = f64::INFINITY;
        loop {
            let residual = self.residual(&d);
            report.residual = residual;
            let need_tangent = match o.linear_solver {
                LinearSolver::Lagged {
                    every,
                    refactor_after,
                    max_rate,
                    ..
                } if !linear => {
                    !self.factored
                        || (report.iterations == 0 && self.steps_since_factor >= every)
                        || on_this_factor >= refactor_after
                        || (on_this_factor > 0 && residual > max_rate * before_last)
                        || o.max_iterations.saturating_sub(report.iterations) <= NEWTON_TAIL
                }
                _ => !linear || !self.factored,
            };
            // The last iteration's rate on this factor (slow: accelerate).
            let slow = on_this_factor > 0 && residual > ANDERSON_RATE * before_last;
            before_last = residual;
            if !residual.is_finite() {
                return Err(DynamicError::NotFinite(step_no));
            }
            let converged = residual <= o.tolerance || (linear && report.iterations == 1);
            if converged {
                break;
            }
            if report.iterations >= o.max_iterations {
                // One iteration is the linearly implicit scheme; more ask for convergence.
                if o.max_iterations > 1 {
                    return Err(DynamicError::NoConvergence {
                        step: step_no,
                        time: t_new,
                        residual,
                        inverted: crate::assembly::inverted_groups(model, &d),
                        inverted_volume: crate::assembly::inverted_fraction(model, &d),
                    });
                }
                break;
            }
            if need_tangent {
                self.assemble_tangent(&d, exact);
            }
            if let Some(w) = self.warp.as_mut() {
                w.update(model, &self.state.rotations);
            }
            let solved = match (o.linear_solver, need_tangent && self.factored && !linear) {
                (LinearSolver::Pcg { tolerance, max_cg }, true) => {
                    let chol = &mut self.chol;
                    self.pcg.solve(
                        &model.pattern,
                        &self.keff,
                        |z| chol.solve_in_place(z),
                        &self.r_free,
                        &mut self.dx,
                        tolerance,
                        max_cg,
                    )
                }
                (LinearSolver::WarpedPcg { tolerance, max_cg }, true) => {
                    let (chol, warp) = (&mut self.chol, self.warp.as_mut().expect("warped"));
                    self.pcg.solve(
                        &model.pattern,
                        &self.keff,
                        |z| {
                            warp.apply(model, z, true);
                            chol.solve_in_place(z);
                            warp.apply(model, z, false);
                        },
                        &self.r_free,
                        &mut self.dx,
                        tolerance,
                        max_cg,
                    )
                }
                _ => false,
            };
            if solved {
                self.r_free.copy_from_slice(&self.dx);
            }
            if !solved {
                // Linear after a cut event: on the old factor where it borders.
                let bordered = need_tangent && linear && self.try_border();
                if need_tangent && !bordered {
                    self.drop_base()?;
                    match self.chol.factorize(&self.keff) {
                        Err(SolveError::NotPositiveDefinite) if exact => {
                            // Away from a stable state (compression, buckling)
                            // the exact tangent can be indefinite: this
                            // iteration takes R K Rᵀ in place of K_exact.
                            report.fallbacks += 1;
                            self.assemble_tangent(&d, false);
                            self.chol.factorize(&self.keff)?;
                        }
                        other => other?,
                    }
                }
                if need_tangent {
                    self.factored = true;
                    self.steps_since_factor = 0;
                    on_this_factor = 0;
                    if let Some(w) = self.warp.as_mut() {
                        w.at_factor.copy_from_slice(&w.now);
                        w.relative.fill(Matrix3::identity());
                    }
                }
                match self.base.as_mut() {
                    Some(Base {
                        solve: Some(border),
                        steps,
                        ..
                    }) => {
                        border.solve_in_place(&mut self.chol, &mut self.r_free);
                        *steps += 1;
                    }
                    _ => self.chol.solve_in_place(&mut self.r_free),
                }
            }
            if let Some(aa) = self.anderson.as_mut() {
                if need_tangent || report.iterations == 0 {
                    aa.reset();
                }
                gather_free(model, &d, &mut self.x_free);
                aa.accelerate(&self.x_free, &mut self.r_free, slow && !need_tangent);
            }
            for (dof, &eq) in model.equation.iter().enumerate() {
                if eq != NONE {
                    d[dof] += self.r_free[eq as usize];
                }
            }
            report.iterations += 1;
            on_this_factor += 1;
            // Linear: the solve is exact. One iteration: the linearly implicit scheme.
            if linear || o.max_iterations == 1 {
                break;
            }
        }
        if d.iter().any(|x| !x.is_finite()) {
            return Err(DynamicError::NotFinite(step_no));
        }
        // Kinematics of the final iterate (the loop may stop right after an update).
        self.kinematics(&d);
        std::mem::swap(&mut self.state.v, &mut self.v_new);
        std::mem::swap(&mut self.state.a, &mut self.a_new);
        self.state.d = d;
        self.state.time = t_new;
        self.steps_since_factor += 1;
        report.factorisations = self.chol.factorisations - factor_start;
        report.cg_iterations = self.pcg.iterations - cg_start;
        Ok(report)
    }

    /// Starts the step to `t_new`: keeps dₙ and the rotations Rₙ and
    /// returns the predictor (dₙ with the prescribed DOFs at their new values).
    fn begin_step(&mut self, t_new: f64) -> Vec<f64> {
        let model = self.model;
        self.d_old.copy_from_slice(&self.state.d);
        let ramp = self.ramp(t_new);
        let mut d = std::mem::take(&mut self.state.d);
        for p in &model.prescribed {
            d[p.dof] = ramp * p.value;
        }
        self.rot_start.0.copy_from_slice(&self.state.rotations.0);
        self.damping_current = false;
        d
    }

    /// The step's residual at the iterate `d` (free equations, into
    /// `r_free`), relative to its force scale, the rotations updated to `d`:
    ///
    /// r(d) = f_ext − f_int(d) − M a(d) − D v(d), D = α M + β_R Rₙ K Rₙᵀ,
    ///
    /// with the damping stiffness on the rotations Rₙ of the step's start
    /// (constant over the step), so that −dr/dd = K_t(d) + c₀ M + γ/(βΔt) D
    /// exactly, symmetric (K_t: the exact tangent, or R K Rᵀ):
    /// [`Newmark::assemble_tangent`]. Forces only: the iterate that meets the
    /// tolerance assembles no tangent.
    fn residual(&mut self, d: &[f64]) -> f64 {
        let model = self.model;
        let o = self.opts;
        let linear = model.formulation == Formulation::Linear;
        if linear && self.linear.is_none() {
            self.linear = Some(LinearForces::new(model, &mut self.ws));
        }
        if let Some(lf) = self.linear.as_mut() {
            self.strain_energy = lf.forces(model, d, &mut self.f_int);
        } else {
            self.strain_energy = evaluate(
                model,
                d,
                &mut self.state.rotations,
                &mut self.ws,
                Request {
                    forces: Some(&mut self.f_int),
                    tangent: None,
                    update_rotations: !linear,
                    exact_tangent: false,
                },
            );
        }
        self.kinematics(d);
        // r = f_ext − f_int − M a − D v.
        self.mass.product(model, &self.a_new, &mut self.mv);
        for i in 0..d.len() {
            self.r_full[i] = self.load[i] - self.f_int[i] - self.mv[i];
        }
        // Force scale of the residual: loads, internal and inertial forces,
        // not below their round-off level.
        let scale = self
            .load_norm
            .max(norm(&self.f_int))
            .max(norm(&self.mv))
            .max(self.round_off);
        if o.rayleigh_mass != 0.0 {
            self.mass.product(model, &self.v_new, &mut self.mv);
            for i in 0..d.len() {
                self.r_full[i] -= o.rayleigh_mass * self.mv[i];
            }
        }
        if o.rayleigh_stiffness != 0.0 {
            self.kv.fill(0.0);
            tangent_product(
                model,
                &self.v_new,
                &self.rot_start,
                &mut self.ws,
                &mut self.kv,
            );
            for i in 0..d.len() {
                self.r_full[i] -= o.rayleigh_stiffness * self.kv[i];
            }
        }
        gather_free(model, &self.r_full, &mut self.r_free);
        let r_norm = norm(&self.r_free);
        if r_norm == 0.0 {
            0.0
        } else {
            r_norm / scale
        }
    }

    /// keff += c₀ M + γ/(βΔt) (α M + β_R Rₙ K Rₙᵀ): the Newton matrix of
    /// [`Newmark::residual`] (dv/dd = γ/(βΔt), da/dd = c₀).
    fn complete_tangent(&mut self) {
        let o = self.opts;
        if !self.damping_k.is_empty() && !self.damping_current {
            // Rₙ K Rₙᵀ: with the rotations held, the displacement is not used.
            evaluate(
                self.model,
                &self.d_old,
                &mut self.rot_start,
                &mut self.ws,
                Request {
                    forces: None,
                    tangent: Some(&mut self.damping_k),
                    update_rotations: false,
                    exact_tangent: false,
                },
            );
            self.damping_current = true;
        }
        let c_v = o.gamma / (o.beta * o.dt);
        let c0 = 1.0 / (o.beta * o.dt * o.dt);
        self.mass
            .add_to(self.model, c0 + o.rayleigh_mass * c_v, &mut self.keff);
        let beta_v = o.rayleigh_stiffness * c_v;
        for (k, kd) in self.keff.iter_mut().zip(&self.damping_k) {
            *k += beta_v * kd;
        }
    }

    /// keff = −dr/dd at `d` (after [`Newmark::residual`] at `d`, whose
    /// rotations it uses): K_t — the exact tangent when `exact`, else R K Rᵀ
    /// (the fallback of an indefinite exact tangent) — completed by
    /// [`Newmark::complete_tangent`].
    fn assemble_tangent(&mut self, d: &[f64], exact: bool) {
        let o = self.opts;
        // Linear: Rₙ = I, the damping stiffness is K, added in the same pass.
        let damping_in_pass = if self.model.formulation == Formulation::Linear {
            o.rayleigh_stiffness * o.gamma / (o.beta * o.dt)
        } else {
            0.0
        };
        if let Some(lf) = self.linear.as_ref() {
            // Linear: (1 + β_R γ/(βΔt)) K from the stiffness the forces hold,
            // not another pass over the elements.
            let scale = 1.0 + damping_in_pass;
            for (k, &kk) in self.keff.iter_mut().zip(&lf.k) {
                *k = scale * kk;
            }
        } else {
            evaluate_damped(
                self.model,
                d,
                &mut self.state.rotations,
                &mut self.ws,
                Request {
                    forces: None,
                    tangent: Some(&mut self.keff),
                    update_rotations: false,
                    exact_tangent: exact,
                },
                damping_in_pass,
            );
        }
        self.complete_tangent();
    }

    /// The residual r(d) of the next step (free equations, not scaled) and
    /// its Newton matrix −dr/dd (lower CSC values on the model's pattern) at
    /// the iterate `d`, without taking the step: what the step's Newton
    /// iterations solve with, for checking the tangent by finite differences.
    /// Allocates; leaves the state as it was.
    pub fn newton_system(&mut self, d: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let saved = (self.state.d.clone(), self.state.rotations.clone());
        let t_new = next_time(self.state.time, self.opts.dt);
        let predictor = self.begin_step(t_new);
        self.state.d = predictor;
        self.residual(d);
        let exact = self.opts.exact_tangent && self.model.formulation != Formulation::Linear;
        self.assemble_tangent(d, exact);
        let out = (self.r_free.clone(), self.keff.clone());
        (self.state.d, self.state.rotations) = saved;
        out
    }
}

/// An iteration on one factor that reduced the residual below this
/// fraction takes the plain correction next: where iterations converge
/// fast, Anderson's secant estimate is mostly their nonlinearity, and it
/// cost `bend_dynamic` iterations (see [`DEFAULT_LAGGED`]).
const ANDERSON_RATE: f64 = 0.1;

/// The deepest Anderson history (a larger `anderson` is taken as this).
pub const ANDERSON_MAX: usize = 8;

/// Anderson acceleration (type II, undamped; Walker & Ni 2011) of the
/// fixed-point map x ↦ x + P⁻¹ r(x) that modified Newton iterates on one
/// factor P: the next correction is f − Σ γᵢ (ΔXᵢ + ΔFᵢ), γ minimising
/// |f − Σ γᵢ ΔFᵢ| over the last `depth` differences of iterates X and
/// corrections F (the normal equations, by Cholesky; a pivot at round-off
/// leaves that step plain). On a linear map it is GMRES preconditioned by
/// P in exact arithmetic; here it speeds up the linear rate of iterations
/// on a factor taken a step or an iterate earlier (a few iterations and
/// factorisations fewer in 100 steps: see [`DEFAULT_LAGGED`]), so a factor
/// serves longer. The history starts anew with every step and
/// every factorisation (the map changed). Preallocated: no allocation a step.
struct Anderson {
    depth: usize,
    dx: Vec<Vec<f64>>,
    df: Vec<Vec<f64>>,
    x_prev: Vec<f64>,
    f_prev: Vec<f64>,
    /// Differences held (≤ depth), the slot of the next, and whether a previous pair exists.
    count: usize,
    next: usize,
    has_prev: bool,
}

impl Anderson {
    fn new(n: usize, depth: usize) -> Anderson {
        let depth = depth.clamp(1, ANDERSON_MAX);
        Anderson {
            depth,
            dx: vec![vec![0.0; n]; depth],
            df: vec![vec![0.0; n]; depth],
            x_prev: vec![0.0; n],
            f_prev: vec![0.0; n],
            count: 0,
            next: 0,
            has_prev: false,
        }
    }

    fn reset(&mut self) {
        self.count = 0;
        self.next = 0;
        self.has_prev = false;
    }

    /// Takes the iterate `x` and its correction `f` (P⁻¹ r(x)) into the
    /// history and, with `apply`, turns `f` into the accelerated correction.
    fn accelerate(&mut self, x: &[f64], f: &mut [f64], apply: bool) {
        if self.has_prev {
            let k = self.next;
            for i in 0..x.len() {
                self.dx[k][i] = x[i] - self.x_prev[i];
                self.df[k][i] = f[i] - self.f_prev[i];
            }
            self.next = (k + 1) % self.depth;
            self.count = (self.count + 1).min(self.depth);
        }
        self.x_prev.copy_from_slice(x);
        self.f_prev.copy_from_slice(f);
        self.has_prev = true;
        let m = self.count;
        if m == 0 || !apply {
            return;
        }
        // Normal equations (ΔFᵀΔF) γ = ΔFᵀ f, by Cholesky; a pivot at
        // round-off (dependent differences) leaves the step unaccelerated.
        let mut a = [[0.0; ANDERSON_MAX]; ANDERSON_MAX];
        let mut g = [0.0; ANDERSON_MAX];
        for i in 0..m {
            for j in 0..=i {
                a[i][j] = dot(&self.df[i], &self.df[j]);
            }
            g[i] = dot(&self.df[i], f);
        }
        for j in 0..m {
            let mut p = a[j][j];
            for k in 0..j {
                p -= a[j][k] * a[j][k];
            }
            if p <= 1e-14 * a[j][j].max(f64::MIN_POSITIVE) || !p.is_finite() {
                return;
            }
            let p = p.sqrt();
            a[j][j] = p;
            for i in j + 1..m {
                let mut v = a[i][j];
                for k in 0..j {
                    v -= a[i][k] * a[j][k];
                }
                a[i][j] = v / p;
            }
        }
        for i in 0..m {
            let mut v = g[i];
            for k in 0..i {
                v -= a[i][k] * g[k];
            }
            g[i] = v / a[i][i];
        }
        for i in (0..m).rev() {
            let mut v = g[i];
            for k in i + 1..m {
                v -= a[k][i] * g[k];
            }
            g[i] = v / a[i][i];
        }
        for (i, &gamma) in g.iter().enumerate().take(m) {
            for (fj, (xj, dj)) in f.iter_mut().zip(self.dx[i].iter().zip(&self.df[i])) {
                *fj -= gamma * (xj + dj);
            }
        }
    }
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::Material;
    use crate::mesh::box_mesh;
    use crate::model::ModelInput;
    use nalgebra::{Point3, Rotation3};

    /// Anderson acceleration of x ↦ x + P⁻¹ (b − A x) with a poor P (the
    /// diagonal of a strongly coupled SPD A): the plain iteration is still
    /// 1e-1 off after 40 iterations (measured 9.6e-2), the accelerated one
    /// with a history of n solves the n × n system to round-off within
    /// n + 2 (it is GMRES on P⁻¹A in exact arithmetic; measured 3.7e-16);
    /// a history at round-off (a repeated difference) leaves a step plain,
    /// not NaN.
    #[test]
    fn anderson_solves_a_linear_fixed_point_the_plain_iteration_cannot() {
        let n = 6;
        let a = nalgebra::DMatrix::<f64>::from_fn(n, n, |i, j| {
            if i == j {
                4.0 + i as f64
            } else {
                3.5 / (1.0 + (i as f64 - j as f64).abs())
            }
        });
        assert!(a.clone().cholesky().is_some());
        let b = nalgebra::DVector::<f64>::from_fn(n, |i, _| (i as f64 + 1.0).sin());
        let exact = a.clone().cholesky().unwrap().solve(&b);
        let run = |depth: usize, iterations: usize| -> f64 {
            let mut aa = (depth > 0).then(|| Anderson::new(n, depth));
            let mut x = vec![0.0; n];
            for _ in 0..iterations {
                let xv = nalgebra::DVector::from_column_slice(&x);
                let r = &b - &a * &xv;
                let mut f: Vec<f64> = (0..n).map(|i| r[i] / a[(i, i)]).collect();
                if let Some(aa) = aa.as_mut() {
                    aa.accelerate(&x, &mut f, true);
                }
                for (xi, fi) in x.iter_mut().zip(&f) {
                    *xi += fi;
                }
            }
            (nalgebra::DVector::from_column_slice(&x) - &exact).norm() / exact.norm()
        };
        let plain = run(0, 40);
        let accelerated = run(n, n + 2);
        println!(
            "plain (40 iterations) {plain:e}, Anderson({n}) ({} iterations) {accelerated:e}",
            n + 2
        );
        assert!(plain > 1e-2, "{plain:e}");
        assert!(accelerated < 1e-10, "{accelerated:e}");
        // Dependent differences: the same iterate and correction twice.
        let mut aa = Anderson::new(n, 3);
        let x = vec![1.0; n];
        let mut f = vec![0.5; n];
        aa.accelerate(&x, &mut f, true);
        let mut g = vec![0.5; n];
        aa.accelerate(&x, &mut g, true);
        assert_eq!(g, vec![0.5; n]);
    }

    /// A free block falling under gravity, lumped mass.
    fn free_block() -> Model {
        Model::build(ModelInput {
            mesh: box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.1), [2, 3, 4]),
            material: Material {
                young: 3e5,
                poisson: 0.35,
                density: 1070.0,
            },
            formulation: Formulation::Corotational,
            cut: None,
            fixed: Vec::new(),
            gravity: Some(Vector3::new(0.0, 0.0, -9.81)),
            body_force: None,
            tractions: &[],
            need_mass: true,
        })
        .unwrap()
    }

    /// The linear step's forces from the assembled stiffness equal the
    /// element loop's (free DOFs) and so does the strain energy, with tip
    /// groups (a front inside elements, Tet10) and prescribed displacements
    /// d_p = λ p̄ (bottom clamped, top pulled), for a deformed state.
    #[test]
    fn linear_forces_from_the_assembled_stiffness_equal_the_element_loop() {
        use crate::cut::{setup_cut, CutInput, PlanarPatch, DEFAULT_SNAP};
        let mesh = box_mesh(Point3::origin(), Point3::new(0.03, 0.06, 0.1), [3, 3, 5]).to_tet10();
        let patch = PlanarPatch {
            origin: Point3::new(-0.01, -0.01, 0.047),
            u: Vector3::new(0.027, 0.0, 0.004),
            v: Vector3::new(0.0, 0.08, 0.0),
        };
        let cut = setup_cut(&mesh, &[CutInput::tip(&patch, DEFAULT_SNAP, None)]).unwrap();
        assert!(cut.n_tip > 0);
        let fixed = mesh
            .nodes
            .iter()
            .enumerate()
            .filter_map(|(i, p)| {
                if p.z == 0.0 {
                    Some((i, [Some(0.0); 3]))
                } else if (p.z - 0.1).abs() < 1e-12 {
                    Some((i, [Some(0.002), None, Some(-0.001)]))
                } else {
                    None
                }
            })
            .collect();
        let model = Model::build(ModelInput {
            mesh,
            material: Material {
                young: 3e5,
                poisson: 0.35,
                density: 1070.0,
            },
            formulation: Formulation::Linear,
            cut: Some(cut),
            fixed,
            gravity: Some(Vector3::new(0.0, 0.0, -9.81)),
            body_force: None,
            tractions: &[],
            need_mass: true,
        })
        .unwrap();
        let lambda = 0.37;
        let mut d: Vec<f64> = (0..model.n_dofs())
            .map(|i| 1e-3 * (0.71 * i as f64).sin())
            .collect();
        for p in &model.prescribed {
            d[p.dof] = lambda * p.value;
        }
        let mut ws = Workspace::new(&model);
        let mut lf = LinearForces::new(&model, &mut ws);
        let mut f_sparse = vec![0.0; model.n_dofs()];
        let e_sparse = lf.forces(&model, &d, &mut f_sparse);
        let mut f_loop = vec![0.0; model.n_dofs()];
        let e_loop = evaluate(
            &model,
            &d,
            &mut Rotations::identity(&model),
            &mut ws,
            Request {
                forces: Some(&mut f_loop),
                tangent: None,
                update_rotations: false,
                exact_tangent: false,
            },
        );
        let scale = f_loop.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (dof, &eq) in model.equation.iter().enumerate() {
            if eq != NONE {
                assert!(
                    (f_sparse[dof] - f_loop[dof]).abs() <= 1e-12 * scale,
                    "dof {dof}: {} vs {}",
                    f_sparse[dof],
                    f_loop[dof]
                );
            }
        }
        assert!(
            (e_sparse - e_loop).abs() <= 1e-12 * e_loop.abs(),
            "{e_sparse} vs {e_loop}"
        );
        // The step's Newton matrix, (1 + β_R γ/(βΔt)) K from those stiffness
        // values plus the mass terms, equals the element pass's (Rayleigh
        // mass and stiffness damping, lumped mass).
        let opts = DynamicOptions {
            rayleigh_mass: 0.3,
            rayleigh_stiffness: 0.02,
            ..DynamicOptions::default()
        };
        let mut nm = Newmark::new(&model, Cholesky::new(&model.pattern).unwrap(), opts).unwrap();
        let (_, keff) = nm.newton_system(&d);
        let c_v = opts.gamma / (opts.beta * opts.dt);
        let mut by_pass = vec![0.0; model.pattern.nnz()];
        evaluate_damped(
            &model,
            &d,
            &mut Rotations::identity(&model),
            &mut ws,
            Request {
                forces: None,
                tangent: Some(&mut by_pass),
                update_rotations: false,
                exact_tangent: false,
            },
            opts.rayleigh_stiffness * c_v,
        );
        nm.mass.add_to(
            &model,
            1.0 / (opts.beta * opts.dt * opts.dt) + opts.rayleigh_mass * c_v,
            &mut by_pass,
        );
        let scale = by_pass.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (p, (a, b)) in keff.iter().zip(&by_pass).enumerate() {
            assert!((a - b).abs() <= 1e-12 * scale, "entry {p}: {a} vs {b}");
        }
    }

    /// Carried over every cut event of a blade sweep, the linear forces
    /// (stiffness, K_fp p̄ and ½ p̄·K_pp p̄) equal those assembled afresh on
    /// the new model: Tet4 and Tet10, the front extended (equations only
    /// appended) and tip-enriched (tip DOFs dropped, equations renumbered),
    /// the top face pulled and nodes of the cut elements moved (prescribed
    /// values not zero where the elements change).
    #[test]
    fn linear_forces_carried_over_cut_events_equal_a_fresh_assembly() {
        use crate::cut::FrontMode;
        use crate::study::fixtures::{beam_mesh, seed_blade, BEAM_MATERIAL};
        for (tet10, front) in [
            (false, FrontMode::Extend),
            (false, FrontMode::Tip),
            (true, FrontMode::Tip),
        ] {
            let mesh = beam_mesh([6, 3, 9], tet10);
            let fixed: Vec<_> = mesh
                .nodes
                .iter()
                .enumerate()
                .filter_map(|(i, p)| {
                    if p.z.abs() < 1e-12 {
                        Some((i, [Some(0.0); 3]))
                    } else if (p.z - 0.2).abs() < 1e-12 {
                        Some((i, [Some(0.004), None, Some(-0.002)]))
                    } else if p.x.abs() < 1e-12 && (p.z - 0.1).abs() < 0.03 {
                        // In the elements the blade changes: their K_fp p̄ changes too.
                        Some((i, [None, Some(0.001), None]))
                    } else {
                        None
                    }
                })
                .collect();
            let mut cuts = seed_blade(0.0, 1.0);
            cuts.front = front;
            let build = |t: f64| {
                Model::build(ModelInput {
                    mesh: mesh.clone(),
                    material: BEAM_MATERIAL,
                    formulation: Formulation::Linear,
                    cut: cuts.setup_at(&mesh, t).unwrap(),
                    fixed: fixed.clone(),
                    gravity: None,
                    body_force: None,
                    tractions: &[],
                    need_mass: true,
                })
                .unwrap()
            };
            let mut model = build(0.1);
            let mut forces = LinearForces::new(&model, &mut Workspace::new(&model));
            let (mut events, mut dropped) = (0, 0);
            for k in 3..=20 {
                let setup = cuts.setup_at(&mesh, 0.05 * k as f64).unwrap();
                if crate::blade::same_setup(model.cut.as_ref(), setup.as_ref()) {
                    continue;
                }
                let (next, stats, update) = model.update_cut_mapped(setup).unwrap();
                forces = forces.updated(&model, &next, &update);
                let fresh = LinearForces::new(&next, &mut Workspace::new(&next));
                let scale = fresh.k.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for (p, (a, b)) in forces.k.iter().zip(&fresh.k).enumerate() {
                    assert!(
                        (a - b).abs() <= 1e-12 * scale,
                        "{tet10} {front:?} entry {p}: {a} vs {b}"
                    );
                }
                let scale = fresh.prescribed.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                assert!(scale > 0.0);
                for (a, b) in forces.prescribed.iter().zip(&fresh.prescribed) {
                    assert!(
                        (a - b).abs() <= 1e-12 * scale,
                        "{tet10} {front:?}: {a} vs {b}"
                    );
                }
                assert!(
                    (forces.prescribed_energy - fresh.prescribed_energy).abs()
                        <= 1e-12 * fresh.prescribed_energy.abs()
                );
                events += 1;
                dropped += stats.dropped_equations;
                model = next;
            }
            assert!(events >= 3, "{tet10} {front:?}: {events} events");
            if front == FrontMode::Tip {
                assert!(dropped > 0, "{tet10}: no tip DOF dropped");
            }
        }
    }

    /// The report of a step from the block rigidly rotated by 60° (with a
    /// deforming velocity), after a first step at rest that factorised K_eff there.
    fn cg_after_rotation(model: &Model, linear_solver: LinearSolver) -> (StepReport, f64) {
        let opts = DynamicOptions {
            linear_solver,
            ..DynamicOptions::default()
        };
        let mut nm = Newmark::new(model, Cholesky::new(&model.pattern).unwrap(), opts).unwrap();
        nm.initialise_acceleration().unwrap();
        assert!(nm.step().unwrap().factorisations >= 1);
        let r = Rotation3::from_axis_angle(&Vector3::y_axis(), 60f64.to_radians()).into_inner();
        for (i, p) in model.mesh.nodes.iter().enumerate() {
            let u = r * p.coords - p.coords;
            nm.state.d[3 * i..3 * i + 3].copy_from_slice(u.as_slice());
        }
        // A deforming velocity: the step's right-hand side is not rigid.
        for (i, p) in model.mesh.nodes.iter().enumerate() {
            let v = Vector3::new((37.0 * p.x).sin(), (23.0 * p.y).cos(), (11.0 * p.z).sin());
            nm.state.v[3 * i..3 * i + 3].copy_from_slice((v * 0.01).as_slice());
        }
        nm.state.rotations.0.fill(r);
        let report = nm.step().unwrap();
        (report, report.residual)
    }

    /// For a rigid rotation of the rest state with lumped mass, K_eff = Q
    /// K_eff(rest) Qᵀ (R M Rᵀ = M, the tangents rotate with the body), so the
    /// warped rest factor is the exact inverse: CG converges in one iteration
    /// per Newton iteration, where the unwarped (lagged) factor needs many.
    #[test]
    fn step_stats_summarise_medians_maxima_and_rates() {
        let mut stats = StepStats::with_capacity(4);
        for (k, (iterations, seconds)) in [(3, 0.004), (5, 0.010), (4, 0.002), (4, 0.006)]
            .into_iter()
            .enumerate()
        {
            let report = StepReport {
                iterations,
                factorisations: iterations,
                cg_iterations: 10 * k,
                fallbacks: usize::from(k == 2),
                ..StepReport::default()
            };
            stats.record(&report, seconds);
        }
        let s = stats.summary();
        assert_eq!(s.steps, 4);
        assert_eq!(s.seconds_median, 0.005);
        assert_eq!(s.seconds_max, 0.010);
        assert_eq!((s.newton_mean, s.newton_max), (4.0, 5));
        assert_eq!((s.cg_per_step, s.factorisations_per_step), (15.0, 4.0));
        assert_eq!(s.fallbacks, 1);
        assert_eq!(stats.newton_iterations(), &[3, 5, 4, 4]);
        assert_eq!(
            s.to_string(),
            "4 steps: 5.000 ms a step (median), 10.000 ms max; Newton 4.00 a step (max 5), CG 15.0 a step, 4.00 factorisations a step, 1 R K Rᵀ fallbacks"
        );
        assert_eq!(StepStats::default().summary().steps, 0);
    }

    #[test]
    fn the_warped_rest_factor_is_exact_for_a_rigid_rotation() {
        let model = free_block();
        let pcg = |warped: bool| {
            let (tolerance, max_cg) = (1e-10, 200);
            if warped {
                LinearSolver::WarpedPcg { tolerance, max_cg }
            } else {
                LinearSolver::Pcg { tolerance, max_cg }
            }
        };
        let (warped, _) = cg_after_rotation(&model, pcg(true));
        let (lagged, _) = cg_after_rotation(&model, pcg(false));
        println!("after a 60° rotation: warped {warped:?}, lagged {lagged:?}");
        assert_eq!(warped.factorisations, 0);
        assert!(warped.iterations >= 1);
        assert!(warped.cg_iterations <= 2 * warped.iterations, "{warped:?}");
        assert!(
            lagged.cg_iterations > 5 * warped.cg_iterations,
            "{lagged:?}"
        );
    }
}

//! One run of a scene at one level: build, solve, evaluate probes, write outputs.

use crate::blade::{run_dynamic_with, BladeError, CutSet, Sweep};
use crate::dynamics::DynamicOptions;
use crate::dynamics::{DynamicError, Energies, Newmark};
use crate::dynamics::{StepStats, StepSummary};
use crate::io::VtuData;
use crate::locate::Locator;
use crate::mesh::TetMesh;
use crate::model::Model;
use crate::plan::Plan;
use crate::scene::{Analysis, Scene, SceneError};
use crate::solve::{Cholesky, Parallelism, SolveError};
use crate::statics::{solve_static_observed, NewtonProgress, StaticError, StaticOptions};
use nalgebra::{Point3, Vector3};
use std::path::Path;
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("{file}: {source}")]
    Solve { file: String, source: SolveError },
    #[error("{file}: {source}")]
    Static { file: String, source: StaticError },
    #[error("{file}: {source}")]
    Dynamic { file: String, source: DynamicError },
    #[error("{file}: key `probe[{table}].points`: point {index} at ({x}, {y}, {z}) lies outside the body")]
    ProbeOutside {
        file: String,
        /// The `[[probe]]` table and the point's place in its `points`.
        table: usize,
        index: usize,
        x: f64,
        y: f64,
        z: f64,
    },
    #[error("{file}: {source}")]
    Blade {
        file: String,
        #[source]
        source: BladeError,
    },
    #[error("writing output: {0}")]
    Output(#[from] crate::io::IoError),
}

/// Timings of a run (seconds).
#[derive(Debug, Clone, Copy, Default)]
pub struct Timings {
    pub mesh: f64,
    pub cut: f64,
    pub model: f64,
    pub symbolic: f64,
    /// The symbolic factorisation ran on another thread while the model was
    /// built: `model` (its wall time) holds it, and the precompute is
    /// `model` alone.
    pub symbolic_beside: bool,
    /// Static: the whole solve. Dynamic: all steps.
    pub solve: f64,
    pub steps: usize,
}

impl Timings {
    /// Cut set-up, element data and pattern, ordering and symbolic
    /// factorisation, as wall time (the symbolic factorisation counted once
    /// where it ran beside the build).
    pub fn precompute(&self) -> f64 {
        self.cut
            + self.model
            + if self.symbolic_beside {
                0.0
            } else {
                self.symbolic
            }
    }
}

/// A finished run: the model, its solution and what was measured.
pub struct RunResult {
    pub model: Model,
    pub plan: Plan,
    pub d: Vec<f64>,
    pub timings: Timings,
    pub iterations: Vec<usize>,
    pub residual: f64,
    pub factorisations: usize,
    /// Static: load steps halved because Newton did not finish them.
    pub cutbacks: usize,
    /// Dynamic runs: (time, displacement) frames kept for output.
    pub frames: Vec<(f64, Vec<f64>)>,
    pub energies: Vec<(f64, Energies)>,
    /// Dynamic runs: per-step time, Newton and CG iterations, factorisations.
    pub steps: Option<StepSummary>,
    /// A blade's sweep: [`RunResult::steps`] split into the steps that end
    /// while a blade cuts (t in (start, end] of the sweep) and the others.
    pub steps_while_cutting: Option<[StepSummary; 2]>,
    /// A dynamic scene with blades: the sweep, and its frames drawn each with
    /// the model of its time (the cut as it was, the blade edges as lines).
    pub sweep: Option<Sweep>,
    pub progressive_frames: Vec<(f64, VtuData)>,
    /// How the system was factorised ([`Cholesky::describe`]); a blade's
    /// sweep: its last model's (a symbolic factorisation per pattern,
    /// [`crate::blade::sweep_factor`]).
    pub factor: Option<String>,
}

/// Solves `scene` at `level` (or on `mesh_override`) on one thread (the
/// figures the report quotes are per core).
pub fn solve_scene(
    scene: &Scene,
    level: usize,
    mesh_override: Option<&Path>,
    keep_frames: bool,
) -> Result<RunResult, RunError> {
    solve_scene_with(
        scene,
        level,
        mesh_override,
        keep_frames,
        Parallelism::SEQUENTIAL,
    )
}

/// [`solve_scene`] with the numeric factorisations and the element loops
/// (forces, tangents) of static and dynamic scenes on `parallelism`'s threads
/// (a blade's sweep: its steps' element loops, and at each cut event the
/// changed elements' integration and the state's projection).
pub fn solve_scene_with(
    scene: &Scene,
    level: usize,
    mesh_override: Option<&Path>,
    keep_frames: bool,
    parallelism: Parallelism,
) -> Result<RunResult, RunError> {
    solve_scene_observed(
        scene,
        level,
        mesh_override,
        keep_frames,
        parallelism,
        &mut |_| {},
    )
}

/// Where a run is, as [`solve_scene_observed`] reports it.
#[derive(Debug, Clone, Copy)]
pub enum Progress<'a> {
    /// The plan, once the model is built and before the solve. A blade's
    /// sweep builds its models as it runs: its plan is the model's at the
    /// start ([`Plan::at_start`]; the result holds the last model's).
    Planned(&'a Plan),
    /// A static scene: each residual its Newton iterations evaluate.
    Newton(NewtonProgress),
    /// A dynamic scene: step `step` of `steps` done, at `time`.
    Step {
        step: usize,
        steps: usize,
        time: f64,
    },
}

/// [`solve_scene_with`], telling `observe` where it is (for the CLI's
/// progress line: a soft corotational scene's Newton can take minutes).
pub fn solve_scene_observed(
    scene: &Scene,
    level: usize,
    mesh_override: Option<&Path>,
    keep_frames: bool,
    parallelism: Parallelism,
    observe: &mut dyn FnMut(Progress<'_>),
) -> Result<RunResult, RunError> {
    let file = scene.file.display().to_string();
    let t0 = Instant::now();
    let (mesh, notes) = match mesh_override {
        Some(p) => {
            let (m, mut notes) = scene.read_mesh_noted(p)?;
            if scene.element == crate::mesh::ElementKind::Tet10 {
                notes.promoted = m.kind == crate::mesh::ElementKind::Tet4;
                (m.to_tet10(), notes)
            } else {
                (m, notes)
            }
        }
        None => scene.mesh_noted(level)?,
    };
    let t_mesh = t0.elapsed().as_secs_f64();
    check_probes(scene, &mesh)?;
    if let (
        true,
        Analysis::Dynamic {
            options,
            output_every,
        },
    ) = (scene.has_blade(), &scene.analysis)
    {
        // The plan names the mesh as it was read, before the sweep and after it.
        let name_mesh = |plan: &mut Plan| {
            if let Some(p) = mesh_override {
                plan.mesh_from(p);
            }
            plan.mesh_notes(&notes);
        };
        let mut result = solve_progressive(
            scene,
            mesh,
            Progressive {
                options: *options,
                output_every: *output_every,
                keep_frames,
                parallelism,
            },
            &name_mesh,
            observe,
        )?;
        result.timings.mesh = t_mesh;
        name_mesh(&mut result.plan);
        return Ok(result);
    }
    // The fill-reducing rule of `Cholesky::fill_reducing` (METIS nested
    // dissection on the node graph from 10k equations, else the cheapest of
    // it, nested dissection on the equation graph and AMD; split in halves
    // on two threads), on another thread while
    // the model's scatter maps are built when there are two.
    let threads = parallelism.n_threads();
    let (model, mut plan, (chol, t_symbolic)) =
        scene.build_beside(mesh, threads, |pattern, shapes| {
            let t = Instant::now();
            let chol = Cholesky::fill_reducing(pattern, Some(shapes), parallelism);
            (chol, t.elapsed().as_secs_f64())
        })?;
    let chol = chol.map_err(|source| RunError::Solve {
        file: file.clone(),
        source,
    })?;
    if let Some(p) = mesh_override {
        plan.mesh_from(p);
    }
    plan.mesh_notes(&notes);
    observe(Progress::Planned(&plan));
    let beside = threads > 1;
    let factor = chol.describe();
    let mut timings = Timings {
        mesh: t_mesh,
        cut: plan.times[1],
        // One thread: the symbolic factorisation ran within the build, after the pattern.
        model: plan.times[0] + plan.times[2] - if beside { 0.0 } else { t_symbolic },
        symbolic: t_symbolic,
        symbolic_beside: beside,
        solve: 0.0,
        steps: 0,
    };
    let t2 = Instant::now();
    match &scene.analysis {
        Analysis::Static(opts) => {
            let mut chol = chol;
            let opts = StaticOptions {
                parallelism,
                ..*opts
            };
            let sol = solve_static_observed(
                &model,
                &mut chol,
                &opts,
                |lambda, p| lambda * p.value,
                &mut |p| observe(Progress::Newton(p)),
            )
            .map_err(|source| RunError::Static {
                file: file.clone(),
                source,
            })?;
            timings.solve = t2.elapsed().as_secs_f64();
            Ok(RunResult {
                model,
                plan,
                d: sol.d,
                timings,
                iterations: sol.iterations,
                residual: sol.residual,
                factorisations: sol.factorisations,
                cutbacks: sol.cutbacks,
                frames: Vec::new(),
                energies: Vec::new(),
                steps: None,
                steps_while_cutting: None,
                sweep: None,
                progressive_frames: Vec::new(),
                factor: Some(factor),
            })
        }
        Analysis::Dynamic {
            options,
            output_every,
        } => {
            let mut nm =
                Newmark::new(&model, chol, *options).map_err(|source| RunError::Dynamic {
                    file: file.clone(),
                    source,
                })?;
            nm.set_parallelism(parallelism);
            // Start at rest in the reference state with the acceleration of the loads (gravity).
            nm.initialise_acceleration()
                .map_err(|source| RunError::Dynamic {
                    file: file.clone(),
                    source,
                })?;
            let mut frames = Vec::new();
            let mut energies = Vec::new();
            let mut iterations = Vec::with_capacity(options.steps);
            let mut residual: f64 = 0.0;
            let mut stats = StepStats::with_capacity(options.steps);
            if keep_frames {
                frames.push((0.0, nm.state.d.clone()));
            }
            energies.push((0.0, nm.energies()));
            for step in 1..=options.steps {
                let t_step = Instant::now();
                let r = nm.step().map_err(|source| RunError::Dynamic {
                    file: file.clone(),
                    source,
                })?;
                stats.record(&r, t_step.elapsed().as_secs_f64());
                observe(Progress::Step {
                    step,
                    steps: options.steps,
                    time: nm.state.time,
                });
                iterations.push(r.iterations);
                residual = residual.max(r.residual);
                if step % output_every == 0 || step == options.steps {
                    if keep_frames {
                        frames.push((nm.state.time, nm.state.d.clone()));
                    }
                    energies.push((nm.state.time, nm.energies()));
                }
            }
            timings.solve = t2.elapsed().as_secs_f64();
            timings.steps = options.steps;
            let d = nm.state.d.clone();
            let factorisations = nm.factorisations();
            drop(nm);
            Ok(RunResult {
                model,
                plan,
                d,
                timings,
                iterations,
                residual,
                factorisations,
                cutbacks: 0,
                frames,
                energies,
                steps: Some(stats.summary()),
                steps_while_cutting: None,
                sweep: None,
                progressive_frames: Vec::new(),
                factor: Some(factor),
            })
        }
    }
}

/// A dynamic scene whose blades cut while it runs ([`crate::blade::run_dynamic`]):
/// the model is rebuilt at each cut event with the scene's selections.
/// How a blade's dynamic scene runs ([`solve_progressive`]).
struct Progressive {
    options: DynamicOptions,
    output_every: usize,
    keep_frames: bool,
    parallelism: Parallelism,
}

/// A dynamic scene with a blade: its models are built as the sweep runs.
/// The plan of the model at the start comes first (`Progress::Planned`,
/// its sizes marked as the start's), the result holds the last model's.
fn solve_progressive(
    scene: &Scene,
    mesh: TetMesh,
    run: Progressive,
    name_mesh: &dyn Fn(&mut Plan),
    observe: &mut dyn FnMut(Progress<'_>),
) -> Result<RunResult, RunError> {
    let Progressive {
        options,
        output_every,
        keep_frames,
        parallelism,
    } = run;
    let file = scene.file.display().to_string();
    let blade_err = |source| RunError::Blade {
        file: file.clone(),
        source,
    };
    scene.check_mesh_memory(&mesh)?;
    let t0 = Instant::now();
    let cuts = CutSet::from_scene(scene).map_err(blade_err)?;
    let (fixed, tractions) = scene.selections(&mesh)?;
    let t_setup = t0.elapsed().as_secs_f64();
    let build = |cut: Option<crate::cut::CutSetup>| {
        scene.model_input(mesh.clone(), cut, fixed.clone(), &tractions)
    };
    let mut frames = Vec::new();
    let mut energies = Vec::new();
    let mut iterations = Vec::with_capacity(options.steps);
    let mut residual: f64 = 0.0;
    let mut factorisations = 0;
    let mut reports = Vec::with_capacity(options.steps);
    let t2 = Instant::now();
    let result = run_dynamic_with(
        &cuts,
        &mesh,
        &build,
        options,
        parallelism,
        |step, model, nm| {
            if step == 0 {
                let mut plan = Plan::new(scene, model, mesh.n_elements(), [t_setup, 0.0, 0.0]);
                plan.at_start = true;
                name_mesh(&mut plan);
                observe(Progress::Planned(&plan));
            }
            if step > 0 {
                observe(Progress::Step {
                    step,
                    steps: options.steps,
                    time: nm.state.time,
                });
                if let Some(r) = nm.last_report() {
                    iterations.push(r.iterations);
                    residual = residual.max(r.residual);
                    factorisations += r.factorisations;
                    reports.push(r);
                }
            }
            if step % output_every == 0 || step == options.steps {
                if keep_frames {
                    let edges = cuts.edges_at(nm.state.time);
                    frames.push((
                        nm.state.time,
                        crate::output::progressive_frame(model, &nm.state.d, &edges),
                    ));
                }
                energies.push((nm.state.time, nm.energies()));
            }
        },
    )
    .map_err(blade_err)?;
    let solve = t2.elapsed().as_secs_f64();
    let n_elements = mesh.n_elements();
    let plan = Plan::new(scene, &result.model, n_elements, [t_setup, 0.0, 0.0]);
    // Each step's report beside its wall time (the sweep's series: one
    // entry a step, in order), all steps and split by the sweep's window.
    let (mut all, mut cutting, mut other) = (
        StepStats::with_capacity(reports.len()),
        StepStats::default(),
        StepStats::default(),
    );
    let (start, end) = (result.sweep.start, result.sweep.end);
    for (r, &(time, seconds, _)) in reports.iter().zip(&result.sweep.series) {
        all.record(r, seconds);
        let during = time > start && time <= end + 1e-9 * options.dt;
        if during { &mut cutting } else { &mut other }.record(r, seconds);
    }
    Ok(RunResult {
        plan,
        d: result.state.d.clone(),
        model: result.model,
        timings: Timings {
            // The caller's.
            mesh: 0.0,
            cut: result.sweep.event_seconds,
            model: t_setup,
            symbolic: 0.0,
            symbolic_beside: false,
            solve,
            steps: options.steps,
        },
        iterations,
        residual,
        factorisations: result.sweep.factorisations,
        cutbacks: 0,
        frames: Vec::new(),
        energies,
        steps: Some(all.summary()),
        steps_while_cutting: Some([cutting.summary(), other.summary()]),
        factor: result.sweep.factor.clone(),
        sweep: Some(result.sweep),
        progressive_frames: frames,
    })
}

/// Displacement at reference point `x`: located in the mesh; in a cut element
/// the side is the sign of the level set there (on the cut, to round-off:
/// the + side). A
/// point on a cut that runs along element faces is looked up in an element of
/// that side.
pub fn evaluate_at(
    model: &Model,
    locator: &Locator,
    d: &[f64],
    x: &Point3<f64>,
) -> Option<Vector3<f64>> {
    evaluate_on_side(model, locator, d, x, None)
}

/// A point whose interpolated level set is within this fraction of its
/// element's size plus its largest coordinate is on the cut surface
/// ([`evaluate_on_side`]).
const ON_SURFACE: f64 = 1e-12;

/// As [`evaluate_at`], on the given side of the cut (+1 or −1) instead of
/// the sign of the interpolated level set: a point on the cut plane reads
/// either face of the cut exactly, even where nodes snapped onto the plane
/// tilt the interpolated level set by up to the snapping distance.
pub fn evaluate_on_side(
    model: &Model,
    locator: &Locator,
    d: &[f64],
    x: &Point3<f64>,
    side: Option<i8>,
) -> Option<Vector3<f64>> {
    let (e, bary) = locator.locate(&model.mesh, x)?;
    let Some(cut) = &model.cut else {
        return Some(model.displacement_at(d, e, x, 0));
    };
    let level = |e: usize, bary: &[f64; 4]| -> f64 {
        model
            .mesh
            .vertices(e)
            .iter()
            .zip(bary)
            .map(|(&i, l)| cut.phi[i] * l)
            .sum()
    };
    // On the surface (within round-off of the point's coordinates and the
    // element's size): the + side. A point written as o + s u + t v of an
    // oblique patch lands within ~1e-18 m of it on either side, and read
    // the − side about one time in three.
    let on_surface = ON_SURFACE * (model.mesh.element_size(e) + x.coords.amax());
    let side: i8 = side.unwrap_or(if level(e, &bary) >= -on_surface {
        1
    } else {
        -1
    });
    // Whether element e's field is the one of `side` (a cut element holds both).
    let serves = |e: usize| match &cut.elements[e] {
        crate::cut::ElementCut::Cut { .. } => true,
        crate::cut::ElementCut::Touched { side: s } => *s == side,
        crate::cut::ElementCut::Uncut => model
            .mesh
            .vertices(e)
            .iter()
            .all(|&i| cut.phi[i] * f64::from(side) >= 0.0),
    };
    let e = if serves(e) {
        e
    } else {
        locator
            .locate_with(&model.mesh, x, serves)
            .map_or(e, |(e, _)| e)
    };
    Some(model.displacement_at(d, e, x, side))
}

/// Probe displacements of a finished run.
/// Refuses a probe outside the body before the solve (its value would be
/// asked for only after it, when the run's time is spent).
fn check_probes(scene: &Scene, mesh: &TetMesh) -> Result<(), RunError> {
    if scene.probes.is_empty() {
        return Ok(());
    }
    let locator = Locator::new(mesh);
    match scene
        .probes
        .iter()
        .position(|p| locator.locate(mesh, p).is_none())
    {
        Some(index) => {
            let p = scene.probes[index];
            let (table, index) = scene.probe_key(index);
            Err(RunError::ProbeOutside {
                file: scene.file.display().to_string(),
                table,
                index,
                x: p.x,
                y: p.y,
                z: p.z,
            })
        }
        None => Ok(()),
    }
}

pub fn probe_values(scene: &Scene, result: &RunResult) -> Result<Vec<Vector3<f64>>, RunError> {
    let locator = Locator::new(&result.model.mesh);
    scene
        .probes
        .iter()
        .enumerate()
        .map(|(index, p)| {
            let (table, index) = scene.probe_key(index);
            evaluate_at(&result.model, &locator, &result.d, p).ok_or(RunError::ProbeOutside {
                file: scene.file.display().to_string(),
                table,
                index,
                x: p.x,
                y: p.y,
                z: p.z,
            })
        })
        .collect()
}

/// A run that ended (or passed an output frame) with part of the body
/// turned inside out: how many integration groups had det F ≤ 0, the share
/// of the body's volume they are ([`crate::assembly::inverted_fraction`]),
/// and the time of the first frame where that share passed
/// [`COLLAPSED_FRACTION`](crate::dynamics::COLLAPSED_FRACTION) (`None`:
/// the static equilibrium, or a sweep's last state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inversion {
    pub groups: usize,
    pub fraction: f64,
    pub time: Option<f64>,
    pub formulation: crate::model::Formulation,
}

impl std::fmt::Display for Inversion {
    /// One line, for the warning `xfem-cut run` prints.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let when = match self.time {
            Some(t) => format!("by the output frame at t = {t:.6} s"),
            None => "in the state the solve ended with".to_string(),
        };
        let why = match self.formulation {
            crate::model::Formulation::Linear => {
                "linear elasticity assumes small strains, and displacement gradients this large lie outside it"
            }
            crate::model::Formulation::Corotational => {
                "corotational elasticity has no barrier against inversion (and there is no contact), so the body can pass through itself or its supports"
            }
        };
        write!(
            f,
            "{} integration groups inverted (det F <= 0; {:.3} % of the body's volume) {when}: {why}; this state is not physical (a stiffer material, smaller loads or more support)",
            self.groups,
            self.fraction * 100.0
        )
    }
}

/// Whether `result` left more than
/// [`COLLAPSED_FRACTION`](crate::dynamics::COLLAPSED_FRACTION) of the body
/// inverted: in the final state, or in an output frame before it (a
/// dynamic scene without blades keeps its frames on its one model). The
/// slivers of cut elements a soft scene turns inside out lie below that
/// share; a body collapsing onto its clamp or tipping through it (a soft
/// top-heavy body under gravity, which a corotational Newton converges on
/// like any other equilibrium) lies far above it.
pub fn inversion(result: &RunResult) -> Option<Inversion> {
    use crate::assembly::{inverted_fraction, inverted_groups};
    use crate::dynamics::COLLAPSED_FRACTION;
    let model = &result.model;
    let at = |d: &[f64], time: Option<f64>| {
        let fraction = inverted_fraction(model, d);
        (fraction > COLLAPSED_FRACTION).then(|| Inversion {
            groups: inverted_groups(model, d),
            fraction,
            time,
            formulation: model.formulation,
        })
    };
    let frames = if result.sweep.is_none() {
        &result.frames[..]
    } else {
        &[]
    };
    frames
        .iter()
        .filter(|(_, d)| d.len() == model.n_dofs())
        .find_map(|(t, d)| at(d, Some(*t)))
        .or_else(|| at(&result.d, None))
}

//! Static equilibrium: one solve for the linear formulation, Newton with load
//! steps for the corotational one (seed section 3.7).

use crate::assembly::{evaluate, gather_free, scatter_free_add, Request, Rotations, Workspace};
use crate::model::{Formulation, Model};
use crate::solve::{Cholesky, Parallelism, SolveError};

/// Halvings of a nominal load step before a static solve gives up: a load
/// step down to 1/256 of `load_steps`' increment.
pub const MAX_CUTBACKS: u32 = 8;

/// Options of the static solve.
#[derive(Debug, Clone, Copy)]
pub struct StaticOptions {
    /// Load steps (corotational only; the linear solve needs one).
    pub load_steps: usize,
    /// Relative residual tolerance of Newton.
    pub tolerance: f64,
    pub max_iterations: usize,
    /// Corotational Newton on the exact tangent (the rotation's derivative
    /// included: quadratic convergence, and the geometric stiffness a slender
    /// body in bending needs); where that tangent is not positive definite
    /// (past a buckling load) the smallest shift μ diag|K| that factorises,
    /// and R K Rᵀ only where none does; false: R K Rᵀ throughout (the seed's).
    pub exact_tangent: bool,
    /// Threads of the element loops (forces, tangents); the factorisation's
    /// are the `Cholesky`'s own.
    pub parallelism: Parallelism,
}

impl Default for StaticOptions {
    fn default() -> Self {
        StaticOptions {
            load_steps: 10,
            tolerance: 1e-10,
            max_iterations: 50,
            exact_tangent: true,
            parallelism: Parallelism::SEQUENTIAL,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum StaticError {
    #[error(transparent)]
    Solve(#[from] SolveError),
    #[error("Newton did not converge at load fraction {lambda}: relative residual {residual:e} after {iterations} iterations ({cutbacks} load steps halved before){}", crate::dynamics::inverted_hint(*inverted, *inverted_volume, "more load steps (analysis.load_steps) or a stiffer material"))]
    NoConvergence {
        /// The load fraction λ the failed load step aimed at.
        lambda: f64,
        /// Load steps halved before this failure.
        cutbacks: usize,
        iterations: usize,
        residual: f64,
        /// Integration groups with det F ≤ 0 at the last iterate, and their
        /// share of the body's volume.
        inverted: usize,
        inverted_volume: f64,
    },
    #[error("the solution is not finite (NaN or inf)")]
    NotFinite,
}

/// Result of a static solve.
#[derive(Debug, Clone)]
pub struct StaticSolution {
    /// Displacement, all DOFs (standard and enriched).
    pub d: Vec<f64>,
    /// Newton iterations per accepted load step.
    pub iterations: Vec<usize>,
    /// Final relative residual ‖r_free‖ / max(‖f_ext‖, ‖f_int‖, f_ε / tol)
    /// ([`force_round_off`]: a residual at the round-off level of the
    /// forces counts as converged).
    pub residual: f64,
    /// Strain energy at the solution.
    pub energy: f64,
    /// Numeric factorisations performed.
    pub factorisations: usize,
    /// Load steps that failed (no convergence, not finite, no positive
    /// definite matrix) and were halved; `iterations` has the accepted ones.
    pub cutbacks: usize,
    pub rotations: Rotations,
}

/// Solves the static problem; `chol` holds the symbolic factorisation of the model's pattern.
/// Loads and prescribed displacements grow in proportion over the load steps.
pub fn solve_static(
    model: &Model,
    chol: &mut Cholesky,
    opts: &StaticOptions,
) -> Result<StaticSolution, StaticError> {
    solve_static_along(model, chol, opts, |lambda, p| lambda * p.value)
}

/// [`solve_static`] with the prescribed displacement of each DOF at load
/// fraction λ given by `prescribed(λ, p)` (e.g. along an arc for a prescribed
/// rotation, where the proportional chord would collapse the body half-way).
pub fn solve_static_along(
    model: &Model,
    chol: &mut Cholesky,
    opts: &StaticOptions,
    prescribed: impl Fn(f64, &crate::model::Prescribed) -> f64,
) -> Result<StaticSolution, StaticError> {
    solve_static_observed(model, chol, opts, prescribed, &mut |_| {})
}

/// Where a static solve is: each Newton iteration's load fraction λ (of a
/// load step, halved ones too), the iteration within the step (0: the
/// residual before the first solve) and its relative residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonProgress {
    pub lambda: f64,
    pub iteration: usize,
    pub residual: f64,
}

/// [`solve_static_along`], telling `observe` each residual it evaluates
/// (for a progress display: a soft corotational scene can take minutes).
pub fn solve_static_observed(
    model: &Model,
    chol: &mut Cholesky,
    opts: &StaticOptions,
    prescribed: impl Fn(f64, &crate::model::Prescribed) -> f64,
    observe: &mut dyn FnMut(NewtonProgress),
) -> Result<StaticSolution, StaticError> {
    let n = model.n_dofs();
    let linear = model.formulation == Formulation::Linear;
    let steps = if linear { 1 } else { opts.load_steps.max(1) };
    let mut d = vec![0.0; n];
    let mut f_int = vec![0.0; n];
    let mut r_free = vec![0.0; model.n_free];
    let mut r_full = vec![0.0; n];
    let mut start = vec![0.0; n];
    let load_norm = norm(&model.load);
    let round_off = residual_scale_floor(model, opts.tolerance);
    let mut tangent = vec![0.0; model.pattern.nnz()];
    let mut shifted = Vec::new();
    let mut rot = Rotations::identity(model);
    let mut ws = Workspace::with_parallelism(model, opts.parallelism);
    let mut iterations = Vec::with_capacity(steps);
    let mut residual = f64::INFINITY;
    let factor_start = chol.factorisations;
    let mut energy = 0.0;
    // The load path in units of 1/(steps·2^MAX_CUTBACKS): the nominal steps
    // land on k/steps exactly; a load step that fails is halved (the state
    // before it restored), and the increment doubles back after each success.
    let unit = 1usize << MAX_CUTBACKS;
    let total = steps * unit;
    let (mut done, mut increment) = (0usize, unit);
    let mut cutbacks = 0;
    let (mut saved_d, mut saved_rot) = (d.clone(), rot.clone());
    while done < total {
        let target = (done + increment).min(total);
        let lambda = target as f64 / total as f64;
        let last = target == total;
        saved_d.copy_from_slice(&d);
        saved_rot.0.copy_from_slice(&rot.0);
        for p in &model.prescribed {
            d[p.dof] = prescribed(lambda, p);
        }
        let mut attempt = || -> Result<usize, StaticError> {
            let mut it = 0;
            loop {
                // For the linear formulation the tangent is constant: assemble and factorise once.
                let want_tangent = !linear || chol.factorisations == factor_start;
                energy = evaluate(
                    model,
                    &d,
                    &mut rot,
                    &mut ws,
                    Request {
                        forces: Some(&mut f_int),
                        tangent: want_tangent.then_some(&mut tangent[..]),
                        update_rotations: !linear,
                        exact_tangent: opts.exact_tangent,
                    },
                );
                for ((r, l), f) in r_full.iter_mut().zip(&model.load).zip(&f_int) {
                    *r = lambda * l - f;
                }
                gather_free(model, &r_full, &mut r_free);
                let scale = load_norm.max(norm(&f_int)).max(round_off);
                let r_norm = norm(&r_free);
                residual = if r_norm == 0.0 { 0.0 } else { r_norm / scale };
                observe(NewtonProgress {
                    lambda,
                    iteration: it,
                    residual,
                });
                if !residual.is_finite() {
                    return Err(StaticError::NotFinite);
                }
                // Intermediate load steps only need to stay close to the path.
                let tolerance = if last {
                    opts.tolerance
                } else {
                    opts.tolerance.max(1e-6)
                };
                if residual <= tolerance || (linear && it == 1) {
                    break;
                }
                if it == opts.max_iterations {
                    return Err(StaticError::NoConvergence {
                        lambda,
                        cutbacks,
                        iterations: it,
                        residual,
                        inverted: crate::assembly::inverted_groups(model, &d),
                        inverted_volume: crate::assembly::inverted_fraction(model, &d),
                    });
                }
                if want_tangent {
                    if let Err(e) = chol.factorize(&tangent) {
                        if linear || !opts.exact_tangent {
                            return Err(e.into());
                        }
                        // Not positive definite away from a stable equilibrium
                        // (compression, buckling): this iteration takes the exact
                        // tangent shifted by μ diag|K| (the smallest μ = 10⁻⁴…10²
                        // that factorises: a descent direction for Π that keeps
                        // the geometric softening, so Newton can walk off a
                        // saddle into a buckled state), else R K Rᵀ.
                        if chol.factorize_shifted(&tangent, &mut shifted).is_none() {
                            evaluate(
                                model,
                                &d,
                                &mut rot,
                                &mut ws,
                                Request {
                                    forces: None,
                                    tangent: Some(&mut tangent),
                                    update_rotations: false,
                                    exact_tangent: false,
                                },
                            );
                            chol.factorize(&tangent)?;
                        }
                    }
                }
                chol.solve_in_place(&mut r_free);
                if linear {
                    scatter_free_add(model, &r_free, &mut d);
                } else {
                    // Backtracking: far from the solution a full step can
                    // overshoot. The corotational forces derive from a potential,
                    // Π = strain energy − λ f·d, and the step is a descent direction
                    // for it (the tangent is positive definite), so a step is taken
                    // when it lowers Π, or the residual norm (near the solution Π's
                    // change is below its round-off). The residual norm alone is a
                    // poor merit: it is dominated by stiff modes, and on a slender
                    // beam in bending it rejected good steps.
                    let before = residual * scale;
                    let potential = |energy: f64, d: &[f64]| energy - lambda * dot(&model.load, d);
                    let before_potential = potential(energy, &d);
                    start.copy_from_slice(&d);
                    let mut alpha = 1.0;
                    for _ in 0..8 {
                        d.copy_from_slice(&start);
                        for (dof, &eq) in model.equation.iter().enumerate() {
                            if eq != crate::model::NONE {
                                d[dof] += alpha * r_free[eq as usize];
                            }
                        }
                        let trial_energy = evaluate(
                            model,
                            &d,
                            &mut rot,
                            &mut ws,
                            Request {
                                forces: Some(&mut f_int),
                                tangent: None,
                                update_rotations: true,
                                exact_tangent: false,
                            },
                        );
                        let trial: f64 = model
                            .equation
                            .iter()
                            .enumerate()
                            .filter(|(_, &eq)| eq != crate::model::NONE)
                            .map(|(dof, _)| (lambda * model.load[dof] - f_int[dof]).powi(2))
                            .sum::<f64>()
                            .sqrt();
                        if trial < before || potential(trial_energy, &d) < before_potential {
                            break;
                        }
                        alpha *= 0.5;
                    }
                }
                it += 1;
            }
            Ok(it)
        };
        match attempt() {
            Ok(it) => {
                iterations.push(it);
                done = target;
                increment = (2 * increment).min(unit);
            }
            Err(
                StaticError::NoConvergence { .. }
                | StaticError::NotFinite
                | StaticError::Solve(SolveError::NotPositiveDefinite),
            ) if !linear && increment > 1 => {
                d.copy_from_slice(&saved_d);
                rot.0.copy_from_slice(&saved_rot.0);
                increment /= 2;
                cutbacks += 1;
            }
            Err(e) => return Err(e),
        }
    }
    if d.iter().any(|v| !v.is_finite()) {
        return Err(StaticError::NotFinite);
    }
    Ok(StaticSolution {
        d,
        iterations,
        residual,
        energy,
        factorisations: chol.factorisations - factor_start,
        cutbacks,
        rotations: rot,
    })
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The round-off level f_ε of ‖f_int‖: an element's forces sum stresses
/// of the strain sym(RᵀF) − I, which is exact only to about ε (F ≈ I), so
/// each force carries ~ε (λ + 2μ) h² of noise; 10 ε (λ + 2μ) h_max² √n in
/// all (a prescribed rigid translation of a 500-DOF beam stalls at 2.4e-13
/// N, under a tenth of this 1.6e-11). A residual this small is as
/// converged as arithmetic allows. Where
/// the forces themselves vanish at the solution (a rigid motion prescribed
/// with no load), ‖r‖ / ‖f_int‖ stays near 1 whatever Newton does, and a
/// solve with only that measure never converged.
pub fn force_round_off(model: &Model) -> f64 {
    let mesh = &model.mesh;
    let h = (0..mesh.n_elements())
        .map(|e| mesh.element_size(e))
        .fold(0.0, f64::max);
    let modulus = model.lame.lambda + 2.0 * model.lame.mu;
    10.0 * f64::EPSILON * modulus * h * h * (model.n_free as f64).sqrt()
}

/// The smallest force scale of a relative residual with this tolerance:
/// f_ε / tolerance ([`force_round_off`]), so that a residual at the round-off
/// level meets it (0 for a tolerance that is not positive).
pub fn residual_scale_floor(model: &Model, tolerance: f64) -> f64 {
    if tolerance > 0.0 {
        force_round_off(model) / tolerance
    } else {
        0.0
    }
}

pub fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

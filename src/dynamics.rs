//! Implicit Newmark time stepping (seed section 3.5/5.1) with Rayleigh damping
//! D = α M + β K and lumped (eq. 81–82) or consistent mass.
//!
//! Displacement form: a(d) = c₀(d − dₙ) − c₁vₙ − c₂aₙ, v(d) = vₙ + Δt((1−γ)aₙ + γa(d)),
//! residual r(d) = f_ext − f_int(d) − M a(d) − D v(d), Newton matrix
//! K_eff = (1 + β_R γ/(βΔt)) K_t + (1/(βΔt²) + α γ/(βΔt)) M.
//! Linear scenes factorise K_eff once; corotational scenes re-assemble K_t
//! each iteration and reuse the symbolic factorisation.

use crate::assembly::{evaluate, gather_free, tangent_product, Request, Rotations, Workspace};
use crate::model::{Formulation, Model, NONE};
use crate::solve::{Cholesky, Pcg, SolveError};
use crate::statics::norm;

/// How the Newton systems of a corotational step are solved.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinearSolver {
    /// Numeric refactorisation every iteration (symbolic once).
    Direct,
    /// CG preconditioned by the last factorisation; refactorise only when CG
    /// needs more than `max_cg` iterations.
    Pcg { tolerance: f64, max_cg: usize },
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
    pub rayleigh_mass: f64,
    pub rayleigh_stiffness: f64,
    /// Time over which prescribed displacements ramp up (0: at once).
    pub ramp: f64,
    pub mass: MassKind,
    /// Newton tolerance (relative residual) and iteration cap per step.
    pub tolerance: f64,
    pub max_iterations: usize,
    pub linear_solver: LinearSolver,
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
    #[error("Newton did not converge at step {step}: relative residual {residual:e}")]
    NoConvergence { step: usize, residual: f64 },
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
    pub iterations: usize,
    pub residual: f64,
}

/// A Newmark integrator borrowing the model; all buffers allocated once.
pub struct Newmark<'m> {
    model: &'m Model,
    opts: DynamicOptions,
    chol: Cholesky,
    ws: Workspace,
    tangent: Vec<f64>,
    keff: Vec<f64>,
    f_int: Vec<f64>,
    r_full: Vec<f64>,
    r_free: Vec<f64>,
    kv: Vec<f64>,
    mv: Vec<f64>,
    a_new: Vec<f64>,
    v_new: Vec<f64>,
    /// Whether a factorisation of K_eff exists (current for linear scenes, maybe stale for PCG).
    factored: bool,
    pcg: Pcg,
    dx: Vec<f64>,
    pub state: State,
    /// Strain energy of the current state.
    pub strain_energy: f64,
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
        Ok(Newmark {
            model,
            opts,
            chol,
            ws: Workspace::new(model),
            tangent: vec![0.0; model.pattern.nnz()],
            keff: vec![0.0; model.pattern.nnz()],
            f_int: vec![0.0; n],
            r_full: vec![0.0; n],
            r_free: vec![0.0; model.n_free],
            kv: vec![0.0; n],
            mv: vec![0.0; n],
            a_new: vec![0.0; n],
            v_new: vec![0.0; n],
            factored: false,
            pcg: Pcg::new(model.n_free),
            dx: vec![0.0; model.n_free],
            state: State {
                time: 0.0,
                d: vec![0.0; n],
                v: vec![0.0; n],
                a: vec![0.0; n],
                rotations: Rotations::identity(model),
            },
            strain_energy: 0.0,
        })
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
            self.r_full[i] = model.load[i] - self.f_int[i];
        }
        gather_free(model, &self.r_full, &mut self.r_free);
        // M a = r on the free DOFs: M on the pattern (the lumped one has
        // u–a couplings at enriched nodes), factorised once for this.
        self.keff.fill(0.0);
        self.add_mass_to_keff(1.0);
        // Zero-mass DOFs (none in practice) would make M singular: give them unit mass.
        for eq in 0..model.n_free {
            let pos = model
                .pattern
                .position(eq, eq)
                .expect("diagonal is in the pattern");
            if self.keff[pos] <= 0.0 {
                self.keff[pos] = 1.0;
            }
        }
        let mass = std::mem::take(&mut self.keff);
        let result = self.chol.factorize(&mass);
        self.keff = mass;
        result?;
        self.chol.solve_in_place(&mut self.r_free);
        self.factored = false;
        for (dof, &eq) in model.equation.iter().enumerate() {
            if eq != NONE {
                self.state.a[dof] = self.r_free[eq as usize];
            }
        }
        Ok(())
    }

    /// Ends the integration, giving back the state and the factorisation
    /// (a progressive cut maps the state onto its new model and keeps the
    /// symbolic analysis where the pattern did not change).
    pub fn into_parts(self) -> (State, Cholesky) {
        (self.state, self.chol)
    }

    pub fn factorisations(&self) -> usize {
        self.chol.factorisations
    }

    /// CG iterations done so far (PCG mode).
    pub fn cg_iterations(&self) -> usize {
        self.pcg.iterations
    }

    /// y = M x (all DOFs).
    fn mass_product(&self, x: &[f64], y: &mut [f64]) {
        let m = self.model;
        match self.opts.mass {
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
                let mut xf = vec![0.0; m.n_free];
                gather_free(m, x, &mut xf);
                let mut yf = vec![0.0; m.n_free];
                m.pattern.sym_mul_add(values, &xf, &mut yf);
                y.fill(0.0);
                for (dof, &eq) in m.equation.iter().enumerate() {
                    if eq != NONE {
                        y[dof] = yf[eq as usize];
                    }
                }
            }
        }
    }

    /// Energies of the current state (the strain energy is evaluated afresh).
    pub fn energies(&mut self) -> Energies {
        let mut rot = self.state.rotations.clone();
        self.strain_energy = evaluate(
            self.model,
            &self.state.d,
            &mut rot,
            &mut self.ws,
            Request {
                forces: None,
                tangent: None,
                update_rotations: self.model.formulation == Formulation::Corotational,
                exact_tangent: false,
            },
        );
        let mut mv = std::mem::take(&mut self.mv);
        self.mass_product(&self.state.v, &mut mv);
        let kinetic = 0.5
            * self
                .state
                .v
                .iter()
                .zip(&mv)
                .map(|(a, b)| a * b)
                .sum::<f64>();
        self.mv = mv;
        let external_work = self
            .model
            .load
            .iter()
            .zip(&self.state.d)
            .map(|(a, b)| a * b)
            .sum();
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

    /// Advances one time step.
    pub fn step(&mut self) -> Result<StepReport, DynamicError> {
        let model = self.model;
        let o = self.opts;
        let dt = o.dt;
        let c0 = 1.0 / (o.beta * dt * dt);
        let c1 = 1.0 / (o.beta * dt);
        let c2 = 1.0 / (2.0 * o.beta) - 1.0;
        let t_new = self.state.time + dt;
        let linear = model.formulation == Formulation::Linear;
        let ramp = self.ramp(t_new);
        let step_no = (t_new / dt).round() as usize;

        // Predictor: d stays, prescribed DOFs take their new values.
        let d_old = self.state.d.clone();
        let mut d = std::mem::take(&mut self.state.d);
        for p in &model.prescribed {
            d[p.dof] = ramp * p.value;
        }
        let k_factor = 1.0 + o.rayleigh_stiffness * o.gamma / (o.beta * dt);
        let m_factor = c0 + o.rayleigh_mass * o.gamma / (o.beta * dt);
        let mut report = StepReport::default();
        loop {
            let need_tangent = !linear || !self.factored;
            self.strain_energy = evaluate(
                model,
                &d,
                &mut self.state.rotations,
                &mut self.ws,
                Request {
                    forces: Some(&mut self.f_int),
                    tangent: need_tangent.then_some(&mut self.tangent[..]),
                    update_rotations: !linear,
                    exact_tangent: false,
                },
            );
            for i in 0..d.len() {
                self.a_new[i] =
                    c0 * (d[i] - d_old[i]) - c1 * self.state.v[i] - c2 * self.state.a[i];
                self.v_new[i] = self.state.v[i]
                    + dt * ((1.0 - o.gamma) * self.state.a[i] + o.gamma * self.a_new[i]);
            }
            // r = f_ext − f_int − M a − D v, D v = α M v + β K_t v.
            let mut ma = std::mem::take(&mut self.mv);
            self.mass_product(&self.a_new, &mut ma);
            for i in 0..d.len() {
                self.r_full[i] = model.load[i] - self.f_int[i] - ma[i];
            }
            // Force scale of the residual: loads, internal and inertial forces.
            let scale = norm(&model.load).max(norm(&self.f_int)).max(norm(&ma));
            if o.rayleigh_mass != 0.0 {
                self.mass_product(&self.v_new, &mut ma);
                for i in 0..d.len() {
                    self.r_full[i] -= o.rayleigh_mass * ma[i];
                }
            }
            self.mv = ma;
            if o.rayleigh_stiffness != 0.0 {
                self.kv.fill(0.0);
                tangent_product(
                    model,
                    &self.v_new,
                    &self.state.rotations,
                    &mut self.ws,
                    &mut self.kv,
                );
                for i in 0..d.len() {
                    self.r_full[i] -= o.rayleigh_stiffness * self.kv[i];
                }
            }
            gather_free(model, &self.r_full, &mut self.r_free);
            let r_norm = norm(&self.r_free);
            let residual = if r_norm == 0.0 { 0.0 } else { r_norm / scale };
            report.residual = residual;
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
                        residual,
                    });
                }
                break;
            }
            if need_tangent {
                // K_eff on the pattern: tangent scaled, plus mass.
                for (k, t) in self.keff.iter_mut().zip(&self.tangent) {
                    *k = k_factor * t;
                }
                self.add_mass_to_keff(m_factor);
            }
            let solved = match (o.linear_solver, need_tangent && self.factored && !linear) {
                (LinearSolver::Pcg { tolerance, max_cg }, true) => {
                    let ok = self.pcg.solve(
                        &model.pattern,
                        &self.keff,
                        &mut self.chol,
                        &self.r_free,
                        &mut self.dx,
                        tolerance,
                        max_cg,
                    );
                    if ok {
                        self.r_free.copy_from_slice(&self.dx);
                    }
                    ok
                }
                _ => false,
            };
            if !solved {
                if need_tangent {
                    self.chol.factorize(&self.keff)?;
                    self.factored = true;
                }
                self.chol.solve_in_place(&mut self.r_free);
            }
            for (dof, &eq) in model.equation.iter().enumerate() {
                if eq != NONE {
                    d[dof] += self.r_free[eq as usize];
                }
            }
            report.iterations += 1;
            // Linear: the solve is exact. One iteration: the linearly implicit scheme.
            if linear || o.max_iterations == 1 {
                break;
            }
        }
        // Kinematics of the final iterate (the loop may stop right after an update).
        for i in 0..d.len() {
            self.a_new[i] = c0 * (d[i] - d_old[i]) - c1 * self.state.v[i] - c2 * self.state.a[i];
            self.v_new[i] = self.state.v[i]
                + dt * ((1.0 - o.gamma) * self.state.a[i] + o.gamma * self.a_new[i]);
        }
        std::mem::swap(&mut self.state.v, &mut self.v_new);
        std::mem::swap(&mut self.state.a, &mut self.a_new);
        self.state.d = d;
        self.state.time = t_new;
        if self.state.d.iter().any(|x| !x.is_finite()) {
            return Err(DynamicError::NotFinite(step_no));
        }
        Ok(report)
    }

    fn add_mass_to_keff(&mut self, factor: f64) {
        let model = self.model;
        match self.opts.mass {
            MassKind::Lumped => {
                let lumped = model.lumped_mass.as_ref().expect("checked in new");
                for (s, ms) in lumped.iter().enumerate() {
                    for c in 0..3 {
                        let eq = model.equation[3 * s + c];
                        if eq != NONE {
                            let eq = eq as usize;
                            let pos = model
                                .pattern
                                .position(eq, eq)
                                .expect("diagonal is in the pattern");
                            self.keff[pos] += factor * ms;
                        }
                    }
                }
                if let (Some(cut), Some(coupling)) = (&model.cut, &model.lumped_coupling) {
                    for (i, e) in cut.enriched.iter().enumerate() {
                        if let Some(j) = *e {
                            let sa = model.mesh.n_nodes() + j;
                            for c in 0..3 {
                                let (r, q) =
                                    (model.equation[3 * sa + c], model.equation[3 * i + c]);
                                if r != NONE && q != NONE {
                                    let (r, q) = (r.max(q) as usize, r.min(q) as usize);
                                    let pos = model
                                        .pattern
                                        .position(r, q)
                                        .expect("u_i and a_i share elements");
                                    self.keff[pos] += factor * coupling[j];
                                }
                            }
                        }
                    }
                }
            }
            MassKind::Consistent => {
                let values = model
                    .consistent_mass
                    .as_ref()
                    .expect("built with the lumped mass");
                for (k, mv) in self.keff.iter_mut().zip(values) {
                    *k += factor * mv;
                }
            }
        }
    }
}

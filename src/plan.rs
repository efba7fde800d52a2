//! What a run does, and what it skips and why: built from the options the run
//! actually uses (mass kind, linear solver, formulation, analysis).

use crate::dynamics::{EventSolve, LinearSolver, MassKind};
use crate::io::MeshNotes;
use crate::model::{Formulation, Model};
use crate::scene::{Analysis, BodyGeometry, Scene};
use std::fmt;

/// One stage of a run: its name, whether it runs, and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Stage {
    pub name: String,
    pub run: bool,
    pub why: String,
}

/// What a run does, and what it skips and why.
#[derive(Debug, Clone)]
pub struct Plan {
    pub stages: Vec<Stage>,
    pub elements: usize,
    pub nodes: usize,
    pub dofs: usize,
    /// Heaviside-enriched nodes (3 DOFs each).
    pub heaviside: usize,
    /// Tip-enriched nodes (branch functions, 12 DOFs each).
    pub tip: usize,
    pub free: usize,
    /// The cut set-up's nodes with measured level sets, of how many
    /// ([`crate::cut::CutSetup::measured`]).
    pub level_sets: (usize, usize),
    /// Seconds: selections, cut set-up, element data + pattern.
    pub times: [f64; 3],
    /// A blade's plan printed before its sweep: the sizes are the model's at
    /// the start (its events grow it; the sweep's summary says how far).
    pub at_start: bool,
}

/// Frames a dynamic run keeps for output (the initial state, every
/// `output_every` steps, and the last); 0 for a static run.
pub fn frames_kept(analysis: &Analysis) -> usize {
    match analysis {
        Analysis::Static(_) => 0,
        Analysis::Dynamic {
            options,
            output_every,
        } => {
            let every = options.steps / output_every;
            1 + every + usize::from(options.steps % output_every != 0)
        }
    }
}

impl Plan {
    /// The run solves on this gmsh mesh instead of the case's own (`--mesh`).
    pub fn mesh_from(&mut self, path: &std::path::Path) {
        if let Some(stage) = self.stages.iter_mut().find(|s| s.name == "mesh") {
            let kind = stage.why.split(' ').next().unwrap_or_default().to_string();
            stage.why = format!("{kind} gmsh file {}, given by --mesh", path.display());
        }
    }

    /// What the mesh file's reader changed, said in the mesh stage: a Tet4
    /// file's elements made Tet10 ones for a Tet10 scene, Tet10 mid-nodes
    /// moved onto their edges (elements are straight-sided), nodes no
    /// tetrahedron uses left out.
    pub fn mesh_notes(&mut self, notes: &MeshNotes) {
        let Some(stage) = self.stages.iter_mut().find(|s| s.name == "mesh") else {
            return;
        };
        if notes.promoted {
            stage.why = format!(
                "{}; its 4-node tetrahedra made 10-node ones (mid-nodes at the edges' midpoints)",
                stage.why
            );
        }
        let s = &notes.straightened;
        if s.mid_nodes > 0 {
            stage.why = format!(
                "{}; {} mid-nodes off their edges (up to {:.2e} m, {:.1} % of the edge) put at the midpoints: elements are straight-sided",
                stage.why,
                s.mid_nodes,
                s.largest,
                100.0 * s.largest_relative
            );
        }
        if notes.unused_nodes > 0 {
            stage.why = format!(
                "{}; {} node{} no tetrahedron uses left out",
                stage.why,
                notes.unused_nodes,
                if notes.unused_nodes == 1 { "" } else { "s" }
            );
        }
    }

    pub fn new(scene: &Scene, model: &Model, elements: usize, times: [f64; 3]) -> Plan {
        let corot = scene.formulation == Formulation::Corotational;
        let cut = !scene.cuts.is_empty();
        let dynamic = match &scene.analysis {
            Analysis::Static(_) => None,
            Analysis::Dynamic { options, .. } => Some(options),
        };
        let mut s: Vec<Stage> = Vec::new();
        let mut add = |name: &str, run: bool, why: &str| {
            s.push(Stage {
                name: name.to_string(),
                run,
                why: why.to_string(),
            })
        };
        add(
            "mesh",
            true,
            &format!(
                "{} {}",
                model.mesh.kind.name(),
                match scene.geometry {
                    BodyGeometry::Box { .. } => "structured box",
                    BodyGeometry::Meshes(_) => "gmsh file",
                }
            ),
        );
        // A blade in a dynamic scene cuts while it runs: the set-up, the
        // element data and the pattern are made again at its cut events.
        let blades: Vec<&crate::scene::CutSpec> = scene
            .cuts
            .iter()
            .filter(|c| matches!(c.geometry, crate::scene::CutGeometry::Blade { .. }))
            .collect();
        let progressive = dynamic.is_some() && !blades.is_empty();
        // A blade's tip front (the default) moves inside its elements: its
        // DOFs change meaning at each event.
        let tip_blade = progressive
            && blades
                .iter()
                .any(|c| c.front != Some(crate::scene::FrontMode::Extend));
        // Blending elements ramped where `Blending::for_cut` says so on this
        // mesh (a Tet4 `tip_radius` of `cut::RAMP_SPAN` elements or more);
        // a radius under that says why not. Per cut: what it asks, and what
        // this mesh makes of it.
        let blendings: Vec<(crate::cut::Blending, crate::cut::Blending)> = scene
            .cuts
            .iter()
            .map(|c| {
                let o = c.options();
                let asked = o.blending(model.mesh.kind);
                (asked, asked.resolve(&model.mesh, o.tip_radius))
            })
            .collect();
        let ramped = blendings
            .iter()
            .any(|&(_, b)| b == crate::cut::Blending::Ramp);
        let under_span = blendings.iter().any(|&(asked, b)| {
            asked == crate::cut::Blending::Auto && b == crate::cut::Blending::None
        });
        let h = || model.mesh.median_edge_length();
        let ramp = if ramped {
            format!(
                "; tip_radius >= {} h (h = {:.3e} m, the median edge): blending elements ramped (corrected X-FEM), the ring's tip nodes carry branch functions {:?} of 0-3",
                crate::cut::RAMP_SPAN,
                h(),
                crate::model::ring_free_branches(model.mesh.kind)
            )
        } else if under_span {
            format!(
                "; tip_radius < {} h (h = {:.3e} m, the median edge): blending elements not ramped (standard X-FEM)",
                crate::cut::RAMP_SPAN,
                h()
            )
        } else {
            String::new()
        };
        add(
            "cut set-up (level set, classification, sub-tets, enrichment)",
            cut,
            &match (cut, progressive) {
                (true, true) => format!("the scene has a blade: at the start, then near the blade at each step its swept surface may have grown{ramp}"),
                (true, false) => format!("the scene has [[cut]]{ramp}"),
                (false, _) => "no cut in the scene".to_string(),
            },
        );
        let (data, pattern) = if progressive {
            (
                "at the start, then for the elements each cut event changes",
                "at the start, then at each cut event that changes the pattern",
            )
        } else {
            ("once", "once")
        };
        add("element data (gradients, integration groups)", true, data);
        add("sparsity pattern + symbolic factorisation", true, pattern);
        // Which parts take their lumped mass times g (`Model::lumped_load`).
        let floating = || match (progressive, model.floating_parts()) {
            (true, _) => "parts a blade frees: from the event that frees them".to_string(),
            (false, 0) => "no part floats free here".to_string(),
            (false, n) => format!("{n} part(s) float free here"),
        };
        // Tip functions: the model's, or those a blade's tip front will hold
        // while its edge is inside the body (its models are built as it
        // runs; the plan says what the run does from its start).
        let holds_tip = model.cut.as_ref().is_some_and(|c| c.n_tip > 0) || tip_blade;
        match dynamic.map(|o| o.mass) {
            Some(MassKind::Lumped) if model.mesh.kind == crate::mesh::ElementKind::Tet10 => add(
                "mass (lumped, eq. 81-82)",
                true,
                &format!(
                    "dynamic scene; Tet10: HRZ (cut elements: per side of the cut, balanced to the element's node masses); a part that floats free takes its lumped mass times g as its gravity load (none on tip functions: their lumped mass is diagonal) and falls with g, held parts keep the consistent load ({})",
                    floating()
                ),
            ),
            Some(MassKind::Lumped) if holds_tip => add(
                "mass (lumped, eq. 81-82)",
                true,
                &format!(
                    "dynamic scene; tip functions: diagonal lumped mass, no coupling; in a part that floats free they take no gravity load, so that it falls with g ({})",
                    floating()
                ),
            ),
            Some(MassKind::Lumped) => add("mass (lumped, eq. 81-82)", true, "dynamic scene"),
            Some(MassKind::Consistent) => add(
                "mass (consistent, on the stiffness pattern)",
                true,
                "dynamic scene, mass = \"consistent\"",
            ),
            None => add("mass", false, "static scene: no mass"),
        }
        let tet10 = model.mesh.kind == crate::mesh::ElementKind::Tet10;
        add(
            "rotations (polar decomposition per group)",
            corot,
            &match (corot, cut, tet10) {
                (false, _, _) => "linear scene: R = I".to_string(),
                (true, false, _) => "corotational".to_string(),
                (true, true, false) => format!(
                    "corotational; a side under {} of an element holding tip functions turns with its largest side",
                    crate::model::SMALL_SIDE
                ),
                (true, true, true) => format!(
                    "corotational; a side under {} of an element holding tip functions turns with its largest side, and a side under {} of a cut element turns with the other where both lie in one part (a cut that ends inside the body)",
                    crate::model::SMALL_SIDE,
                    crate::model::SMALL_CUT_SIDE
                ),
            },
        );
        match (corot, dynamic.map(|o| o.linear_solver)) {
            (false, _) => add(
                "numeric factorisation every iteration",
                false,
                "constant matrix: factorised once",
            ),
            (true, Some(LinearSolver::Pcg { max_cg, .. })) => add(
                &format!("numeric factorisation when PCG needs more than {max_cg} iterations"),
                true,
                "linear_solver = \"pcg\": CG preconditioned by the last factorisation",
            ),
            (true, Some(LinearSolver::WarpedPcg { max_cg, .. })) => add(
                &format!("numeric factorisation when PCG needs more than {max_cg} iterations"),
                true,
                "CG preconditioned by the last factorisation warped by the node rotations",
            ),
            (
                true,
                Some(LinearSolver::Lagged {
                    every,
                    refactor_after,
                    max_rate,
                    anderson,
                }),
            ) => {
                let mut when = Vec::new();
                if every != usize::MAX {
                    when.push(format!("every {every} steps"));
                }
                if max_rate < 1.0 {
                    when.push(format!(
                        "when an iteration on it leaves more than {max_rate} of the residual"
                    ));
                }
                when.push(format!(
                    "after {refactor_after} Newton iterations on one factor"
                ));
                if let Some(o) = dynamic {
                    when.push(format!(
                        "in each of the last 3 of the {} iterations a step may take",
                        o.max_iterations
                    ));
                }
                let how = if anderson > 0 {
                    format!(
                        "modified Newton on a lagged factorisation of the exact tangent, Anderson-accelerated (history {}) after an iteration that reduced the residual by less than 10x",
                        anderson.min(crate::dynamics::ANDERSON_MAX)
                    )
                } else {
                    "modified Newton on a lagged factorisation of the exact tangent".to_string()
                };
                add(
                    &format!("numeric factorisation {}", when.join(", or ")),
                    true,
                    &how,
                )
            }
            (true, Some(LinearSolver::Direct)) => add(
                "numeric factorisation every iteration",
                true,
                if dynamic.is_some_and(|o| o.exact_tangent) {
                    "exact corotational tangent changes"
                } else {
                    "tangent R K R^T changes"
                },
            ),
            (true, None) => add(
                "numeric factorisation every iteration",
                true,
                "exact corotational tangent (rotation derivative included) changes",
            ),
        }
        if let (true, Some(o)) = (progressive, dynamic) {
            // Blades giving `event_travel` take an event only once their
            // edge has moved that far (every blade must, for fewer events).
            let lagging: Option<Vec<f64>> = blades.iter().map(|c| c.event_travel).collect();
            add(
                "cut events",
                true,
                &match lagging {
                    Some(reach) => format!(
                        "once a blade's edge has moved its event_travel ({} m) since the last event, or passed its end: the modelled cut lags the blade by up to that",
                        reach.iter().map(|r| format!("{r}")).collect::<Vec<_>>().join(", ")
                    ),
                    _ => "at every step the cut grows".to_string(),
                },
            );
            add(
                "cut events: the state carried over",
                true,
                if tip_blade {
                    "new shifted DOFs start at zero (the field, its rates and both energies unchanged); where a tip front moved, d, v and a projected together by least squares in the energy norm (|e|^2 + (h^2/4) e:C:e/mu over the elements whose field changed); the energy change at each event is reported"
                } else {
                    "new shifted DOFs start at zero: the field, its rates and both energies unchanged; an extended front projects only where an event drops or recuts enriched DOFs that hold the field (a path that turns), d, v and a by least squares in the energy norm, and reports the energy change"
                },
            );
            match (corot, o.event_solve) {
                (false, EventSolve::Bordered { max_border }) => add(
                    "cut events: bordered solve on the last factor",
                    true,
                    &format!("linear: after an event that only appends equations the steps solve on the previous factor (border k <= min({max_border}, 2 nnz(L)/n), refactorised once its steps have cost a factorisation); refactorise beyond, or where DOFs were dropped"),
                ),
                (false, EventSolve::Refactorise) => add(
                    "cut events: refactorisation",
                    true,
                    "linear: K_eff refactorised at the first step after each event",
                ),
                (true, _) => {
                    add(
                        "cut events: bordered solve on the last factor",
                        false,
                        "corotational: the step after an event factorises the new model's tangent, or iterates on the lagged one",
                    );
                    let lagged = matches!(o.linear_solver, LinearSolver::Lagged { .. });
                    add(
                        "cut events: the lagged factor carried over",
                        lagged,
                        if lagged {
                            "where an event keeps every equation (a front moving inside the elements it holds, the pattern unchanged) the steps after it iterate on the factor of the steps before, refactorised when their rate asks; elsewhere the step after it factorises the new model's tangent"
                        } else {
                            "the step after an event factorises the new model's tangent (lagged factor only)"
                        },
                    );
                }
            }
        }
        if dynamic.is_some() {
            add(
                "element loop for the internal forces every step",
                corot,
                if corot {
                    "corotational: the forces rotate with the elements"
                } else {
                    "linear: f = K d from the stiffness assembled once (one sparse product a step)"
                },
            );
        }
        add(
            "Newton load steps",
            corot && dynamic.is_none(),
            if corot && dynamic.is_none() {
                "corotational static; a load step Newton does not finish is halved, down to 1/256 of it"
            } else {
                "not needed"
            },
        );
        add(
            "Newmark time stepping",
            dynamic.is_some(),
            if dynamic.is_some() {
                "dynamic scene"
            } else {
                "static scene"
            },
        );
        Plan {
            stages: s,
            elements,
            nodes: model.mesh.n_nodes(),
            dofs: model.n_dofs(),
            heaviside: model.cut.as_ref().map_or(0, |c| c.n_heaviside()),
            tip: model.cut.as_ref().map_or(0, |c| c.n_tip()),
            free: model.n_free,
            level_sets: model.cut.as_ref().map_or((0, 0), |c| c.measured),
            times,
            at_start: false,
        }
    }

    /// The stage named `name`, if the plan has it.
    pub fn stage(&self, name: &str) -> Option<&Stage> {
        self.stages.iter().find(|s| s.name == name)
    }
}

impl fmt::Display for Plan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "plan:")?;
        for st in &self.stages {
            writeln!(
                f,
                "  [{}] {} ({})",
                if st.run { "run " } else { "skip" },
                st.name,
                st.why
            )?;
        }
        write!(
            f,
            "size{}: {} elements, {} nodes, {} DOFs ({} Heaviside-, {} tip-enriched nodes), {} free DOFs",
            if self.at_start {
                " at the start (the blade's cut events add DOFs: see the sweep)"
            } else {
                ""
            },
            self.elements,
            self.nodes,
            self.dofs,
            self.heaviside,
            self.tip,
            self.free
        )?;
        let (measured, of) = self.level_sets;
        if measured < of {
            write!(
                f,
                "; level sets measured at {measured} of {of} nodes (the others beyond the surface's reach)"
            )?;
        }
        Ok(())
    }
}

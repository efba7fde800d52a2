//! Scene → [`Model`]: the box selections of fixes and tractions on the mesh,
//! the cut set-up, the model's precompute, and the [`Plan`] of the run.

use crate::blade::Blade;
use crate::cut::{CutInput, CutSetup, CutSurface};
use crate::mesh::TetMesh;
use crate::model::{Integration, Model, ModelInput, Traction};
use crate::plan::Plan;
use crate::scene::{CutGeometry, FrontMode, Scene, SceneError};
use crate::solve::Pattern;
use crate::surface::TriangleSurface;
use nalgebra::{Point3, Vector3};
use std::time::Instant;

/// Per node: which components are prescribed, and their values.
pub type Fixed = Vec<(usize, [Option<f64>; 3])>;

impl Scene {
    /// Builds the model of `mesh` and the plan saying what runs. Refuses a
    /// mesh whose model would not fit in memory, a fix or traction that
    /// selects nothing, and a static scene with a part that floats free.
    pub fn build(&self, mesh: TetMesh) -> Result<(Model, Plan), SceneError> {
        self.build_beside(mesh, 1, |_, _| ())
            .map(|(model, plan, ())| (model, plan))
    }

    /// As [`Scene::build`], calling `beside` with the pattern and each
    /// equation's shape function while the model's scatter maps are built
    /// ([`Model::build_beside`]: on another thread when `threads` > 1); the
    /// plan's model time is the build's wall time with `beside` in it.
    pub fn build_beside<T: Send>(
        &self,
        mesh: TetMesh,
        threads: usize,
        beside: impl FnOnce(&Pattern, &[usize]) -> T + Send,
    ) -> Result<(Model, Plan, T), SceneError> {
        self.check_mesh_memory(&mesh)?;
        let t0 = Instant::now();
        let file = self.file();
        let (fixed, tractions) = self.selections(&mesh)?;
        let t_setup = t0.elapsed().as_secs_f64();

        let t1 = Instant::now();
        let cut = self.setup_cuts(&mesh)?;
        let t_cut = t1.elapsed().as_secs_f64();

        let t2 = Instant::now();
        let n_elements = mesh.n_elements();
        let (model, beside) = Model::build_beside(
            self.input(mesh, cut, fixed, &tractions),
            Integration::Grouped,
            threads,
            beside,
        )
        .map_err(|source| SceneError::Model {
            file: file.clone(),
            source,
        })?;
        let t_model = t2.elapsed().as_secs_f64();
        if let Some(part) = model.free_parts().into_iter().next() {
            if !self.is_dynamic() {
                return Err(SceneError::FloatingPart { file, part });
            }
        }
        let plan = Plan::new(self, &model, n_elements, [t_setup, t_cut, t_model]);
        Ok((model, plan, beside))
    }

    /// The model of `mesh` with the cut set-up `cut` and the selections of
    /// [`Scene::selections`] (a progressive cut rebuilds it at each event).
    pub fn model_input(
        &self,
        mesh: TetMesh,
        cut: Option<CutSetup>,
        fixed: Fixed,
        tractions: &[Traction],
    ) -> Result<Model, crate::model::ModelError> {
        Model::build(self.input(mesh, cut, fixed, tractions))
    }

    fn input<'a>(
        &self,
        mesh: TetMesh,
        cut: Option<CutSetup>,
        fixed: Fixed,
        tractions: &'a [Traction],
    ) -> ModelInput<'a> {
        ModelInput {
            mesh,
            material: self.material,
            formulation: self.formulation,
            cut,
            fixed,
            gravity: self.gravity,
            body_force: None,
            tractions,
            need_mass: self.is_dynamic(),
        }
    }

    /// The nodes the `[[fix]]` boxes select (with their prescribed
    /// components) and the boundary faces of the `[[traction]]` boxes; a box
    /// that selects nothing is an error naming it.
    pub fn selections(&self, mesh: &TetMesh) -> Result<(Fixed, Vec<Traction>), SceneError> {
        let file = self.file();
        let (lo, hi) = mesh.bounding_box();
        let tol = 1e-9 * (hi - lo).norm();
        let inside = |p: &Point3<f64>, min: &[f64; 3], max: &[f64; 3]| {
            (0..3).all(|k| p[k] >= min[k] - tol && p[k] <= max[k] + tol)
        };

        // Dirichlet nodes.
        let mut fixed_nodes: Vec<[Option<f64>; 3]> = vec![[None; 3]; mesh.n_nodes()];
        // Which fix prescribed each component (two that disagree are refused).
        let mut by: Vec<[usize; 3]> = vec![[usize::MAX; 3]; mesh.n_nodes()];
        for (i, fx) in self.fixes.iter().enumerate() {
            let mut count = 0;
            for (n, p) in mesh.nodes.iter().enumerate() {
                if inside(p, &fx.min, &fx.max) {
                    count += 1;
                    for c in 0..3 {
                        if !fx.components[c] {
                            continue;
                        }
                        let value = fx.displacement[c];
                        if let Some(other) = fixed_nodes[n][c].filter(|&v| v != value) {
                            return Err(SceneError::Key {
                                file,
                                key: format!("fix[{i}].displacement"),
                                message: format!(
                                    "prescribes {value} in {} at node ({}, {}, {}), where fix[{}] prescribes {other}",
                                    ["x", "y", "z"][c],
                                    p.x,
                                    p.y,
                                    p.z,
                                    by[n][c]
                                ),
                            });
                        }
                        fixed_nodes[n][c] = Some(value);
                        by[n][c] = i;
                    }
                }
            }
            if count == 0 {
                return Err(SceneError::Key {
                    file,
                    key: format!("fix[{i}]"),
                    message: format!("selects no node (box min {:?}, max {:?})", fx.min, fx.max),
                });
            }
        }
        let fixed: Fixed = fixed_nodes
            .into_iter()
            .enumerate()
            .filter(|(_, c)| c.iter().any(Option::is_some))
            .collect();

        // Tractions.
        let boundary = if self.tractions.is_empty() {
            Vec::new()
        } else {
            mesh.boundary_faces()
        };
        let mut tractions = Vec::new();
        for (i, t) in self.tractions.iter().enumerate() {
            let faces: Vec<_> = boundary
                .iter()
                .filter(|(tri, _)| tri.iter().all(|&v| inside(&mesh.nodes[v], &t.min, &t.max)))
                .copied()
                .collect();
            if faces.is_empty() {
                return Err(SceneError::Key {
                    file,
                    key: format!("traction[{i}]"),
                    message: "selects no boundary face".into(),
                });
            }
            tractions.push(Traction {
                faces,
                value: Vector3::from(t.traction),
            });
        }
        Ok((fixed, tractions))
    }

    /// The cut set-up of every `[[cut]]` on `mesh` (`None` without cuts).
    ///
    /// The one place that maps the scene's cuts to the cut module: planar
    /// patches and triangulated surfaces with their own `snap`, `front` and
    /// `tip_radius`; a blade in a static scene takes its completed sweep.
    /// Dynamic scenes with blades run through [`crate::blade`] instead.
    fn setup_cuts(&self, mesh: &TetMesh) -> Result<Option<CutSetup>, SceneError> {
        if self.cuts.is_empty() {
            return Ok(None);
        }
        let file = self.file();
        let mut surfaces: Vec<Box<dyn CutSurface>> = Vec::with_capacity(self.cuts.len());
        for (i, c) in self.cuts.iter().enumerate() {
            surfaces.push(match &c.geometry {
                CutGeometry::Patch(p) => Box::new(p.clone()),
                CutGeometry::Surface(path) => Box::new(TriangleSurface::read(path).map_err(
                    |source| SceneError::Surface {
                        file: file.clone(),
                        key: format!("cut[{i}].surface"),
                        source,
                    },
                )?),
                CutGeometry::Blade { .. } if self.is_dynamic() => {
                    return Err(SceneError::Unsupported {
                        file,
                        key: format!("cut[{i}].blade"),
                        what: "a blade in a dynamic scene through the CLI (the library's blade::run_dynamic runs it)".into(),
                    })
                }
                CutGeometry::Blade { keyframes, travel } => {
                    let blade = Blade::from_keyframes(i, keyframes.clone(), *travel).map_err(
                        |source| SceneError::Blade {
                            file: file.clone(),
                            source,
                        },
                    )?;
                    match blade.swept(f64::INFINITY) {
                        Some(swept) => swept.into_surface(),
                        None => {
                            return Err(SceneError::Blade {
                                file: file.clone(),
                                source: crate::blade::BladeError::Misses {
                                    index: i,
                                    key: blade.key(),
                                },
                            })
                        }
                    }
                }
            });
        }
        let inputs: Vec<CutInput<'_>> = self
            .cuts
            .iter()
            .zip(&surfaces)
            .map(|(c, s)| c.input(s.as_ref(), mesh.kind))
            .collect();
        crate::cut::setup_cut(mesh, &inputs)
            .map(Some)
            .map_err(|source| SceneError::Cut { file, source })
    }
}

impl crate::scene::CutSpec {
    /// The cut module's input for this cut on `surface`, in a mesh of `kind`.
    pub fn input<'a>(
        &self,
        surface: &'a dyn CutSurface,
        kind: crate::mesh::ElementKind,
    ) -> CutInput<'a> {
        let o = self.options();
        CutInput {
            surface,
            snap: o.snap,
            front: o.front,
            tip_radius: o.tip_radius,
            blending: o.blending(kind),
        }
    }

    /// Its snap, front treatment (the default where the table gives none)
    /// and tip radius: a progressive run sets each cut up with these too.
    pub fn options(&self) -> crate::blade::CutOptions {
        crate::blade::CutOptions {
            snap: self.snap,
            front: match self.front.unwrap_or(DEFAULT_FRONT) {
                FrontMode::Tip => crate::cut::FrontMode::Tip,
                FrontMode::Extend => crate::cut::FrontMode::Extend,
            },
            tip_radius: self.tip_radius,
            blending: self.blending,
        }
    }
}

/// `front` when a cut does not say (DESIGN.md): branch functions at the
/// front, which ends the cut where the surface ends.
pub const DEFAULT_FRONT: FrontMode = FrontMode::Tip;

//! The precomputed model: everything that is built once from a scene and then
//! borrowed by every solve and time step.
//!
//! An element is a list of *shape functions* (its nodes, then its enriched
//! nodes) and a list of *integration groups*. A group is a set of points with
//! one rotation: the whole element (Tet4), one side of a cut element (Tet4,
//! seed eq. 64–71), or one quadrature point (Tet10). Within a group the shape
//! gradients ∇φ_a = ψ_a ∇N_a (ψ = 1 for standard DOFs, the shifted Heaviside
//! value of eq. 58–59 for enriched ones) are stored once, so FEM and X-FEM share
//! one kernel, and the linear formulation is the corotational one with R = I.
//!
//! Global DOFs: shape function `a` owns DOFs 3a..3a+3; shape functions are
//! numbered nodes first, then enriched nodes (the vector [u₁…u_N a₁…a_Nenr] of
//! eq. 74). Dirichlet DOFs are eliminated: only free DOFs enter the matrix.

use crate::cut::{find_root, psi, regions_joined, CutSetup, ElementCut};
use crate::element::{barycentric_gradients, shape_gradients, shape_values};
use crate::front::{self, N_BRANCH};
use crate::material::{Lame, Material};
use crate::mesh::{tet_volume, BarycentricMap, ElementKind, TetMesh, TET10_EDGES};
use crate::quadrature::{self, QuadPoint};
use crate::solve::{Parallelism, Pattern};
use nalgebra::{Matrix3, Point3, Vector3};
use std::ops::Range;

pub use crate::kernel::{group_rotation, GroupKernel};
use crate::mass::lump_element_mass;

/// Marker for a DOF that is not in the system (prescribed), or an entry not stored.
pub const NONE: u32 = u32::MAX;

#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("element {element} is degenerate (volume {volume:e})")]
    DegenerateElement { element: usize, volume: f64 },
    #[error(
        "mid-node {node} lies {offset:e} off the midpoint of its edge (length {length:e}): \
         Tet10 elements here are straight-sided (TetMesh::straighten_edges)"
    )]
    CurvedEdge {
        node: usize,
        offset: f64,
        length: f64,
    },
    #[error("the model has {0} DOFs, more than this solver indexes")]
    TooLarge(usize),
    #[error(
        "a model with a body force beyond gravity cannot be updated at a cut event: build it again"
    )]
    BodyForceUpdate,
}

/// A prescribed value for one global DOF.
#[derive(Debug, Clone, Copy)]
pub struct Prescribed {
    pub dof: usize,
    pub value: f64,
}

/// A body force per unit volume as a function of the reference position.
pub type BodyForce = dyn Fn(&Point3<f64>) -> Vector3<f64> + Sync;

/// How a Tet4 element's integration points are grouped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Integration {
    /// One group per side: the strain is constant there, so the side's volume
    /// is its weight (the volume ratios of seed eq. 60–63). The default.
    Grouped,
    /// One group per quadrature point of every sub-tet (seed eq. 51), as Tet10
    /// always does; for Tet4 it gives the same matrices, only slower. In
    /// elements holding tip-enriched nodes, a rotation per point instead of
    /// per side (the same linear matrices; corotational forces that differ
    /// by the rotations' spread over a side).
    SubTetQuadrature,
}

/// Which integration points share a rotation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Formulation {
    Linear,
    Corotational,
}

/// One integration group: weight (volume it stands for) and where its
/// gradients start in [`Model::grads`] (one per shape function of the element).
///
/// A *point* group (`stiffness` = [`NONE`]) is one quadrature point, or a
/// Tet4 side whose gradients are constant. A *dense* group (the sides of
/// elements holding tip-enriched nodes, integrated with hundreds of points
/// each) stores its local stiffness K = Σ_q w_q B_qᵀ C B_q, (3m)² values
/// row-major from `stiffness` in [`Model::stiffness`], and, at `grads`, the
/// weight-averaged gradients ḡ_a of its points: its rotation is the polar
/// rotation of F̄ = I + Σ_a d_a ⊗ ḡ_a, shared by all its points (as a cut
/// Tet4 side shares one), and its forces are the gradient of its energy
/// ½ uᵀKu, u = Rᵀx − X ([`crate::kernel::DenseKernel`]).
#[derive(Debug, Clone, Copy)]
pub struct Group {
    pub weight: f64,
    pub grads: u32,
    pub stiffness: u32,
}

impl Group {
    /// A group of one quadrature point (or of constant gradients).
    pub fn point(weight: f64, grads: u32) -> Group {
        Group {
            weight,
            grads,
            stiffness: NONE,
        }
    }

    pub fn is_dense(&self) -> bool {
        self.stiffness != NONE
    }
}

/// Per-element ranges into the model's flat arrays.
#[derive(Debug, Clone)]
pub struct ElementData {
    /// Global shape-function ids of this element (nodes, then enriched nodes).
    pub shapes: Range<usize>,
    /// Its integration groups.
    pub groups: Range<usize>,
    /// Start of its scatter map ((3m)² CSC positions) in [`Model::scatter`].
    pub scatter: usize,
}

/// A boundary traction: force per area on the faces inside a box.
#[derive(Debug, Clone)]
pub struct Traction {
    pub faces: Vec<([usize; 3], usize)>,
    pub value: Vector3<f64>,
}

/// What the model is built from (already validated by the scene).
pub struct ModelInput<'a> {
    pub mesh: TetMesh,
    pub material: Material,
    pub formulation: Formulation,
    pub cut: Option<CutSetup>,
    /// Per node: which components are prescribed and their values.
    pub fixed: Vec<(usize, [Option<f64>; 3])>,
    pub gravity: Option<Vector3<f64>>,
    /// A body force per unit volume that varies in space (manufactured solutions), added to gravity.
    pub body_force: Option<&'a BodyForce>,
    pub tractions: &'a [Traction],
    /// Whether to build the lumped mass (dynamic scenes only).
    pub need_mass: bool,
}

/// Everything built once.
pub struct Model {
    pub mesh: TetMesh,
    pub material: Material,
    pub lame: Lame,
    pub formulation: Formulation,
    /// How it was integrated, its gravity, and whether it has a body force
    /// beyond gravity (what [`Model::update_cut`] integrates changed elements with).
    pub integration: Integration,
    pub gravity: Option<Vector3<f64>>,
    pub body_force: bool,
    pub cut: Option<CutSetup>,
    /// Number of shape functions (nodes + enriched nodes).
    pub n_shape: usize,
    /// Reference position X_a of each shape function (zero for enriched ones).
    pub shape_ref: Vec<Vector3<f64>>,
    pub elements: Vec<ElementData>,
    pub shape_ids: Vec<u32>,
    pub groups: Vec<Group>,
    pub grads: Vec<Vector3<f64>>,
    /// The dense groups' local stiffness matrices ([`Group`]).
    pub stiffness: Vec<f64>,
    /// Group index → element index.
    pub group_element: Vec<u32>,
    /// Global DOF → equation number, or [`NONE`] if prescribed.
    pub equation: Vec<u32>,
    pub n_free: usize,
    pub prescribed: Vec<Prescribed>,
    /// Lower-triangular pattern of the free-DOF system.
    pub pattern: Pattern,
    /// Per element, (3m)² positions into the CSC values (NONE where not stored).
    pub scatter: Vec<u32>,
    /// External force at full load (body force + tractions), all DOFs.
    pub load: Vec<f64>,
    /// Lumped mass per shape function (seed eq. 81–82 for enriched ones), if built.
    pub lumped_mass: Option<Vec<f64>>,
    /// Lumped coupling M^ua_ii per enriched node (index = enriched id), the
    /// side-wise row sum that keeps separated parts' inertia exact (see [`lump_element_mass`]).
    pub lumped_coupling: Option<Vec<f64>>,
    /// Consistent mass, lower triangle on the pattern, if built.
    pub consistent_mass: Option<Vec<f64>>,
    /// Per element (Tet10 with the lumped mass built, else empty), per side
    /// (slot 0: side 0 or +1, slot 1: side −1) and node: its cells' lumped
    /// mass less ρ ∫ N_k, what the gravity load of a part that floats free
    /// changes by to be its lumped mass times g ([`Model::lumped_load`]).
    lump_residual: Vec<[[f64; 10]; 2]>,
    /// Per node (Tet10 with tip enrichment only, else empty): the vertices of
    /// the edge a mid-node sits on when one of them is tip-enriched.
    pub mid_edge: Vec<Option<[u32; 2]>>,
    /// The boundary tractions (kept so that a cut event can integrate the
    /// enriched shape functions of the faces it changes again).
    pub tractions: Vec<Traction>,
    /// Per element the cut event that made this model integrated: what its
    /// block added to the loads and masses (shape ids of this model), so
    /// that the next event takes it out without integrating the old block
    /// again (a tip front changes every element holding its branch
    /// functions at every event).
    contributions: std::collections::HashMap<usize, ElementBlock>,
}

impl Model {
    pub fn n_dofs(&self) -> usize {
        3 * self.n_shape
    }

    pub fn n_enriched(&self) -> usize {
        self.cut.as_ref().map_or(0, |c| c.n_enriched)
    }

    /// Shape functions of element `e` (global ids).
    pub fn element_shapes(&self, e: usize) -> &[u32] {
        &self.shape_ids[self.elements[e].shapes.clone()]
    }

    /// Gradients of group `g` (one per shape function of its element).
    pub fn group_grads(&self, g: usize) -> &[Vector3<f64>] {
        let e = self.group_element[g] as usize;
        let m = self.elements[e].shapes.len();
        let start = self.groups[g].grads as usize;
        &self.grads[start..start + m]
    }

    /// The local stiffness of dense group `g` (the (3m)² symmetric K by its
    /// lower triangle, rows packed: [`crate::kernel::packed_len`]), if it is one.
    pub fn group_stiffness(&self, g: usize) -> Option<&[f64]> {
        let group = self.groups[g];
        group.is_dense().then(|| {
            let m = self.elements[self.group_element[g] as usize].shapes.len();
            let start = group.stiffness as usize;
            &self.stiffness[start..start + crate::kernel::packed_len(3 * m)]
        })
    }

    /// Builds the model: element data, enrichment, DOF numbering, pattern, loads, mass.
    pub fn build(input: ModelInput<'_>) -> Result<Model, ModelError> {
        Model::build_with(input, Integration::Grouped)
    }

    /// As [`Model::build`], choosing how Tet4 elements are integrated.
    pub fn build_with(
        input: ModelInput<'_>,
        integration: Integration,
    ) -> Result<Model, ModelError> {
        Model::build_beside(input, integration, 1, |_, _| ()).map(|(model, ())| model)
    }

    /// As [`Model::build_with`], calling `beside` with the pattern and the
    /// shape function of each equation (as [`crate::assembly::equation_shapes`])
    /// as soon as they are known: on another thread, while the elements'
    /// scatter maps are built, when `threads` > 1 (e.g. the fill-reducing
    /// ordering and symbolic factorisation of a static solve).
    ///
    /// In named steps: per element, [`element_cells`] (its shape functions
    /// and integration cells, each cell's volume computed once) and
    /// [`Integrator::block`] (one walk over those cells: integration groups,
    /// loads, mass); then [`number_dofs`] (prescribed DOFs eliminated),
    /// [`element_pattern`], [`scatters`] (beside `beside`), the boundary
    /// tractions and the consistent mass on the pattern.
    pub fn build_beside<T: Send>(
        input: ModelInput<'_>,
        integration: Integration,
        threads: usize,
        beside: impl FnOnce(&Pattern, &[usize]) -> T + Send,
    ) -> Result<(Model, T), ModelError> {
        let ModelInput {
            mesh,
            material,
            formulation,
            cut,
            fixed,
            gravity,
            body_force,
            tractions,
            need_mass,
        } = input;
        // The corotational local displacements Rᵀ(x + d) − x read every
        // node's position; a straight-sided element's map holds its
        // mid-nodes only at the midpoints.
        if let Some((node, offset, length)) = mesh.curved_mid_node() {
            return Err(ModelError::CurvedEdge {
                node,
                offset,
                length,
            });
        }
        let n_shape = shape_count(&mesh, cut.as_ref())?;
        let mut shape_ref: Vec<Vector3<f64>> = mesh.nodes.iter().map(|p| p.coords).collect();
        shape_ref.resize(n_shape, Vector3::zeros());
        let joined = small_side_rotation(&mesh, cut.as_ref(), formulation, integration);
        let integrator = Integrator {
            mesh: &mesh,
            lame: Lame::from(material),
            rho: material.density,
            integration,
            joined: joined.as_deref(),
            gravity,
            body_force,
            need_mass,
            stiffness: true,
            old: None,
        };
        let mut flat = FlatElements::with_capacity(mesh.n_elements(), mesh.cells.len());
        let mut globals = Globals::new(n_shape, cut.as_ref(), need_mass);
        let mut masses = Vec::with_capacity(if need_mass { mesh.n_elements() } else { 0 });
        let keep_residual = need_mass && mesh.kind == ElementKind::Tet10;
        let mut lump_residual = Vec::new();
        for e in 0..mesh.n_elements() {
            let cells = element_cells(&mesh, cut.as_ref(), e)?;
            let block = integrator.block(&cells, Some(&mut globals));
            flat.push_block(e, &block);
            if need_mass {
                masses.push(block.mass);
            }
            if keep_residual {
                lump_residual.push(block.lump_residual);
            }
        }
        let mut fixed = fixed;
        if let Some(c) = cut.as_ref() {
            let enriched = enriched_fixes(&mesh, c, &fixed);
            fixed.extend(enriched);
            // Components prescribed per tip node (the node's own, or its
            // tip DOFs given directly, as the exact-solution study does).
            let n_nodes = mesh.n_nodes();
            let first = n_nodes + c.n_enriched;
            let mut tip_node = vec![0; c.n_tip];
            for (i, t) in c.tip.iter().enumerate() {
                if let Some(t) = t {
                    tip_node[*t] = i;
                }
            }
            let mut prescribed = vec![[false; 3]; n_nodes];
            for &(shape, comps) in &fixed {
                let node = if shape < n_nodes {
                    Some(shape)
                } else if shape >= first {
                    tip_node.get((shape - first) / N_BRANCH).copied()
                } else {
                    None
                };
                if let Some(i) = node {
                    for (p, v) in prescribed[i].iter_mut().zip(comps) {
                        *p |= v.is_some();
                    }
                }
            }
            let ramp = ramp_fixes(&mesh, c, |i, k| prescribed[i][k]);
            fixed.extend(
                ramp.into_iter()
                    .map(|(s, held)| (s, held.map(|h| h.then_some(0.0)))),
            );
        }
        let (equation, prescribed, n_free) = number_dofs(n_shape, &fixed);
        let pattern = element_pattern(&flat, &equation, n_free);
        let beside = || {
            let mut shapes = vec![0; n_free];
            for (dof, &eq) in equation.iter().enumerate() {
                if eq != NONE {
                    shapes[eq as usize] = dof / 3;
                }
            }
            beside(&pattern, &shapes)
        };
        let (scatter, beside) = if threads > 1 {
            rayon::join(|| scatters(&flat, &equation, &pattern), beside)
        } else {
            (scatters(&flat, &equation, &pattern), beside())
        };
        // Boundary tractions: ∫ t φ_a over the selected faces, standard shapes
        // here, the enriched ones once the model is built.
        for t in tractions {
            add_traction(&mesh, t, &mut globals.load);
        }
        let consistent_mass = need_mass.then(|| {
            let mut values = vec![0.0; pattern.nnz()];
            for (el, me) in flat.elements.iter().zip(&masses) {
                add_element_mass(el, me, &scatter, &mut values, 1.0);
            }
            values
        });
        let mid_edge = mid_edges(&mesh, cut.as_ref());
        let mut model = Model {
            lame: Lame::from(material),
            mesh,
            material,
            formulation,
            integration,
            gravity,
            body_force: body_force.is_some(),
            cut,
            n_shape,
            shape_ref,
            elements: flat.elements,
            shape_ids: flat.shape_ids,
            groups: flat.groups,
            grads: flat.grads,
            stiffness: flat.stiffness,
            group_element: flat.group_element,
            equation,
            n_free,
            prescribed,
            pattern,
            scatter,
            load: globals.load,
            lumped_mass: globals.lumped,
            lumped_coupling: globals.coupling,
            consistent_mass,
            lump_residual,
            mid_edge,
            tractions: tractions.to_vec(),
            contributions: Default::default(),
        };
        let mut load = std::mem::take(&mut model.load);
        for t in tractions {
            for face in &t.faces {
                model.add_enriched_traction(face, &t.value, 1.0, None, &mut load);
            }
        }
        model.load = load;
        Ok((model, beside))
    }

    /// Adds `sign` ∫ t ψ_s dA over boundary face `face` (its corner nodes
    /// and its element) for each enriched shape function ψ_s of the element
    /// (the standard ones: [`add_traction`]) to `load`, at shape id
    /// `map[s]` with a map (dropped where [`NONE`]).
    ///
    /// The face is split where the element's φ changes sign (a Heaviside or
    /// branch function jumps there) and each side's piece, cut into 16
    /// triangles, takes a 7-point degree-5 rule: the branch functions are
    /// smooth on each side, √r at the front.
    fn add_enriched_traction(
        &self,
        face: &([usize; 3], usize),
        value: &Vector3<f64>,
        sign: f64,
        map: Option<&[u32]>,
        load: &mut [f64],
    ) {
        let (tri, e) = *face;
        let nn = self.mesh.kind.nodes();
        let ev = self.element_evaluator(e);
        if ev.len() <= nn {
            return;
        }
        let ids = self.element_shapes(e);
        let (mut vals, mut grads) = (vec![0.0; ev.len()], vec![Vector3::zeros(); ev.len()]);
        let corners = tri.map(|i| self.mesh.nodes[i]);
        for side in [1i8, -1] {
            for piece in clip_triangle(&corners, |x| f64::from(side) * ev.phi_at(x), side == 1) {
                for (x, w) in triangle_points(&piece) {
                    ev.eval(&x, side, &mut vals, &mut grads);
                    for (a, &id) in ids.iter().enumerate().skip(nn) {
                        let id = match map {
                            Some(m) if m[id as usize] == NONE => continue,
                            Some(m) => m[id as usize] as usize,
                            None => id as usize,
                        };
                        for c in 0..3 {
                            load[3 * id + c] += sign * w * value[c] * vals[a];
                        }
                    }
                }
            }
        }
    }

    /// Displacement of node `i` seen from side `side` of the cut (0: no cut):
    /// u_i + ψ a_i with ψ the shifted enrichment of that side.
    pub fn node_displacement(&self, d: &[f64], node: usize, side: i8) -> Vector3<f64> {
        let mut u = Vector3::new(d[3 * node], d[3 * node + 1], d[3 * node + 2]);
        if let Some(c) = &self.cut {
            if let (Some(j), true) = (c.enriched[node], side != 0) {
                // With the ramp the Heaviside enrichment is ramped by 1 − R.
                let ramp = match self.mid_edge.get(node) {
                    _ if c.ramp.is_empty() => 0.0,
                    Some(&Some([a, b])) => 0.5 * (c.ramp_at(a as usize) + c.ramp_at(b as usize)),
                    _ => c.ramp_at(node),
                };
                let p = psi(side, c.node_side[node]) * (1.0 - ramp);
                let s = self.mesh.n_nodes() + j;
                u += Vector3::new(d[3 * s], d[3 * s + 1], d[3 * s + 2]) * p;
            }
            if let (Some(t), true) = (c.tip[node], side != 0) {
                // Shifted branch functions vanish at their node, except F₁ seen
                // from the other side of a node on the cut face.
                let (f, g) = (c.phi[node], c.front_level[node]);
                let own = if f >= 0.0 { 1 } else { -1 };
                let r = f.hypot(g);
                let here = front::branch_values(r, front::polar_angle(f, g, side));
                let shift = front::branch_values(r, front::polar_angle(f, g, own));
                let first = self.mesh.n_nodes() + c.n_enriched + N_BRANCH * t;
                let ramp = c.ramp_at(node) * c.tip_scale[t];
                for b in 0..N_BRANCH {
                    let s = first + b;
                    u += Vector3::new(d[3 * s], d[3 * s + 1], d[3 * s + 2])
                        * (ramp * (here[b] - shift[b]));
                }
            }
            // A Tet10 mid-node: the tip functions of its edge's tip-enriched
            // vertices (λ = ½ each, times the ramp there) do not vanish there.
            if let Some(&Some([a, b])) = self.mid_edge.get(node) {
                let (f, g) = (c.phi[node], c.front_level[node]);
                let side = if side != 0 { side } else { c.node_side[node] };
                let here = front::branch_values(f.hypot(g), front::polar_angle(f, g, side));
                let (a, b) = (a as usize, b as usize);
                for v in [a, b] {
                    let Some(t) = c.tip[v] else { continue };
                    let w = c.edge_tip_weight(a, b, v);
                    let (fv, gv) = (c.phi[v], c.front_level[v]);
                    let own = if fv >= 0.0 { 1 } else { -1 };
                    let shift = front::branch_values(fv.hypot(gv), front::polar_angle(fv, gv, own));
                    let first = self.mesh.n_nodes() + c.n_enriched + N_BRANCH * t;
                    let w = 0.5 * w * c.tip_scale[t];
                    for k in 0..N_BRANCH {
                        let s = first + k;
                        u += Vector3::new(d[3 * s], d[3 * s + 1], d[3 * s + 2])
                            * (w * (here[k] - shift[k]));
                    }
                }
            }
        }
        u
    }

    /// Local nodes of element `e` whose Heaviside shape functions the element holds.
    fn heaviside_local(&self, e: usize) -> Vec<usize> {
        let Some(c) = &self.cut else {
            return Vec::new();
        };
        let conn = self.mesh.element(e);
        (0..conn.len())
            .filter(|&k| {
                let i = conn[k];
                c.enriched[i].is_some()
                    && match &c.elements[e] {
                        ElementCut::Cut { .. } => true,
                        ElementCut::Touched { side } => psi(*side, c.node_side[i]) != 0.0,
                        ElementCut::Uncut => false,
                    }
            })
            .collect()
    }

    /// The shape functions of element `e` built once, to be evaluated at
    /// many points without allocation ([`ElementEvaluator::eval`]).
    pub fn element_evaluator(&self, e: usize) -> ElementEvaluator {
        let verts = self.mesh.vertex_points(e);
        let dl = barycentric_gradients(&verts).unwrap_or([Vector3::zeros(); 4]);
        let shapes = self
            .cut
            .as_ref()
            .map(|c| ElementShapes::any(&self.mesh, c, e, &dl, self.heaviside_local(e)));
        let fixed_side = match self.cut.as_ref().map(|c| &c.elements[e]) {
            Some(ElementCut::Cut { .. }) => None,
            Some(ElementCut::Touched { side }) => Some(*side),
            _ => Some(0),
        };
        ElementEvaluator {
            kind: self.mesh.kind,
            map: BarycentricMap::new(&verts),
            canonical: self.mesh.canonical_points(e),
            dl,
            len: self.elements[e].shapes.len(),
            fixed_side,
            shapes,
            front: self.cut.as_ref().is_some_and(|c| !c.front_level.is_empty()),
        }
    }

    /// Values of element `e`'s shape functions ([`Model::element_shapes`]
    /// order) at reference point `x`, on side `side` of the cut.
    pub fn shape_values_at(&self, e: usize, x: &Point3<f64>, side: i8) -> Vec<f64> {
        let ev = self.element_evaluator(e);
        let (mut vals, mut grads) = (vec![0.0; ev.len()], vec![Vector3::zeros(); ev.len()]);
        ev.eval(x, side, &mut vals, &mut grads);
        vals
    }

    /// Displacement u_h and its gradient ∇u_h at reference point `x` of
    /// element `e`, on side `side` of the cut (every shape function, tip ones included).
    pub fn field_at(
        &self,
        d: &[f64],
        e: usize,
        x: &Point3<f64>,
        side: i8,
    ) -> (Vector3<f64>, Matrix3<f64>) {
        let ev = self.element_evaluator(e);
        let (mut vals, mut grads) = (vec![0.0; ev.len()], vec![Vector3::zeros(); ev.len()]);
        ev.eval(x, side, &mut vals, &mut grads);
        let (mut u, mut gu) = (Vector3::zeros(), Matrix3::zeros());
        for (a, &s) in self.element_shapes(e).iter().enumerate() {
            let s = s as usize;
            let da = Vector3::new(d[3 * s], d[3 * s + 1], d[3 * s + 2]);
            u += da * vals[a];
            gu += da * grads[a].transpose();
        }
        (u, gu)
    }

    /// Quadrature points (position, weight, side) covering element `e` for
    /// integrating fields with a front singularity: the element's cells, with
    /// rules collapsed onto the front where they touch it, degree 5 elsewhere.
    pub fn field_points(&self, e: usize) -> Vec<(Point3<f64>, f64, i8)> {
        let mut out = Vec::new();
        self.field_points_into(e, &self.element_evaluator(e), &mut out);
        out
    }

    /// [`Model::field_points`] of element `e` into `out` (cleared first),
    /// with the element's evaluator `ev` (its front rules).
    pub fn field_points_into(
        &self,
        e: usize,
        ev: &ElementEvaluator,
        out: &mut Vec<(Point3<f64>, f64, i8)>,
    ) {
        out.clear();
        let mut push_cell = |cell: &[Point3<f64>; 4], side: i8| match (&ev.shapes, ev.front) {
            (Some(shapes), true) => out.extend(
                shapes
                    .cell_rule(cell)
                    .into_iter()
                    .map(|q| (q.x, q.weight, side)),
            ),
            _ => out.extend(front::degree5_rule(cell).map(|q| (q.x, q.weight, side))),
        };
        match self.cut.as_ref().map(|c| &c.elements[e]) {
            Some(ElementCut::Cut { sub_tets, .. }) => {
                for s in sub_tets {
                    push_cell(&s.vertices, s.side);
                }
            }
            Some(ElementCut::Touched { side }) => push_cell(&ev.canonical, *side),
            _ => push_cell(&ev.canonical, 0),
        }
    }

    /// Displacement at reference point `x` inside element `e` on side `side`.
    ///
    /// `x` outside `e` extrapolates its shape functions (callers locate the
    /// point first). Barycentric coordinates exist for every element of a
    /// model, since [`Model::build`] refuses degenerate ones; the centroid in
    /// their place is only a guard that no built model reaches.
    pub fn displacement_at(&self, d: &[f64], e: usize, x: &Point3<f64>, side: i8) -> Vector3<f64> {
        if let Some(c) = &self.cut {
            if c.holds_tip(self.mesh.element(e)) {
                return self.field_at(d, e, x, side).0;
            }
        }
        let verts = self.mesh.vertex_points(e);
        let bary = crate::mesh::barycentric(&verts, x);
        debug_assert!(bary.is_some(), "element {e} of a built model is degenerate");
        let bary = bary.unwrap_or([0.25; 4]);
        let mut n = [0.0; 10];
        shape_values(self.mesh.kind, &bary, &mut n);
        let conn = self.mesh.element(e);
        let mut u = Vector3::zeros();
        for (k, &i) in conn.iter().enumerate() {
            let el_side = match self.cut.as_ref().map(|c| &c.elements[e]) {
                Some(ElementCut::Cut { .. }) => side,
                Some(ElementCut::Touched { side }) => *side,
                _ => 0,
            };
            u += self.node_displacement(d, i, el_side) * n[k];
        }
        u
    }
}

/// Distance to the front, relative to the element size, within which a point
/// is on the front (the round-off of the interpolated level sets is ~1e-15 h).
pub const FRONT_SNAP: f64 = 1e-12;

/// The shape functions of one element of a model (standard, Heaviside and
/// tip ones, in [`Model::element_shapes`] order), built once by
/// [`Model::element_evaluator`] and evaluated at many points without allocation.
pub struct ElementEvaluator {
    kind: ElementKind,
    /// Points to the element's barycentric coordinates (`None`: degenerate,
    /// which no built model holds; the centroid stands in).
    map: Option<BarycentricMap>,
    /// The element's vertices in its canonical order, its cell where it is
    /// not cut ([`TetMesh::canonical_points`]).
    canonical: [Point3<f64>; 4],
    dl: [Vector3<f64>; 4],
    len: usize,
    /// The side the element's field is seen from (`None`: a cut element, the point's own).
    fixed_side: Option<i8>,
    /// With a cut: its shape functions (Heaviside and tip ones included).
    shapes: Option<ElementShapes>,
    /// Whether the cut has a tip front (the field rules collapse onto it).
    front: bool,
}

impl ElementEvaluator {
    /// Number of shape functions.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The level set φ at reference point `x` (interpolated from the
    /// element's vertices; 0 without a cut).
    pub fn phi_at(&self, x: &Point3<f64>) -> f64 {
        let bary = self.map.map_or([0.25; 4], |m| m.at(x));
        self.shapes
            .as_ref()
            .map_or(0.0, |s| (0..4).map(|k| s.phi[k] * bary[k]).sum())
    }

    /// The side of the cut that `x` lies on in this element: its fixed
    /// side, or in a cut element the sign of its interpolated φ at `x`
    /// (`hint`, else +1, where φ is within round-off of 0: on its cut).
    /// Another model's cells (a cut event's) may cut the element elsewhere
    /// or not at all: a point of an uncut cell (side 0) in an element cut
    /// here, or of a cell on the other side of a cut moved by a lift, is on
    /// this side, and the field there holds its enrichment.
    pub fn side_at(&self, x: &Point3<f64>, hint: i8) -> i8 {
        if let Some(side) = self.fixed_side {
            return side;
        }
        let phi = self.phi_at(x);
        let size = self
            .shapes
            .as_ref()
            .map_or(0.0, |s| s.phi.iter().fold(0.0f64, |m, p| m.max(p.abs())));
        let tol = 1e-12 * size;
        if phi > tol {
            1
        } else if phi < -tol {
            -1
        } else if hint != 0 {
            hint
        } else {
            1
        }
    }

    /// Values and gradients of the shape functions at reference point `x`,
    /// on side `side` of the cut; `vals` and `grads` hold [`Self::len`] each.
    pub fn eval(&self, x: &Point3<f64>, side: i8, vals: &mut [f64], grads: &mut [Vector3<f64>]) {
        let bary = self.map.map_or([0.25; 4], |m| m.at(x));
        match &self.shapes {
            Some(shapes) => shapes.eval(&bary, self.fixed_side.unwrap_or(side), vals, grads),
            None => {
                shape_values(self.kind, &bary, vals);
                shape_gradients(self.kind, &bary, &self.dl, grads);
            }
        }
    }
}

/// The shape functions of an element holding tip-enriched nodes, evaluated
/// point by point: its nodes' N_k, the shifted Heaviside ψ N_k of its
/// Heaviside-enriched nodes (eq. 58–59), then per tip-enriched node four
/// N_k (F_b − F_b(x_k)) with gradients ∇N_k (F_b − F_b(x_k)) + N_k ∇F_b.
/// φ and ψ are interpolated linearly from the element's vertices.
pub struct ElementShapes {
    kind: ElementKind,
    /// Points to barycentric coordinates (`None`: a degenerate element).
    map: Option<BarycentricMap>,
    dl: [Vector3<f64>; 4],
    /// Local nodes carrying the Heaviside enrichment (in shape order).
    pub heaviside: Vec<usize>,
    /// Local nodes carrying the tip enrichment, with their tip block ids.
    pub tip: Vec<(usize, usize)>,
    /// Per entry of `tip`, the branch functions the element holds: all four,
    /// or on the ramp's ring [`ring_free_branches`] (the others are held at
    /// zero, [`ramp_fixes`], and no element holds them).
    tip_branches: Vec<&'static [usize]>,
    node_side: [i8; 10],
    phi: [f64; 4],
    psi: [f64; 4],
    grad_phi: Vector3<f64>,
    grad_psi: Vector3<f64>,
    /// F_b(x_k) of each tip node (on its own side).
    shift: Vec<[f64; N_BRANCH]>,
    /// Per entry of `tip`, its functions' factor 1/√h ([`CutSetup::tip_scale`]).
    tip_scale: Vec<f64>,
    /// With [`crate::cut::Blending::Ramp`]: the vertices in I, whose λ sum to R.
    ramp: Option<[bool; 4]>,
    /// Local element size (tolerance for vertices on the front).
    size: f64,
    /// The element's volume (what a cell's is measured against: [`SLIVER`]).
    volume: f64,
}

impl ElementShapes {
    /// The shapes of element `e`, or `None` when it holds no tip-enriched node.
    pub fn new(
        mesh: &TetMesh,
        cut: &CutSetup,
        e: usize,
        dl: &[Vector3<f64>; 4],
        heaviside: Vec<usize>,
    ) -> Option<ElementShapes> {
        let s = ElementShapes::any(mesh, cut, e, dl, heaviside);
        (!s.tip.is_empty()).then_some(s)
    }

    /// The shapes of element `e`, with or without tip-enriched nodes.
    pub fn any(
        mesh: &TetMesh,
        cut: &CutSetup,
        e: usize,
        dl: &[Vector3<f64>; 4],
        heaviside: Vec<usize>,
    ) -> ElementShapes {
        let conn = mesh.element(e);
        let v = mesh.vertices(e);
        let ramp = (!cut.ramp.is_empty()).then(|| v.map(|i| cut.ramp[i]));
        let tip: Vec<(usize, usize)> = if cut.holds_tip(conn) {
            conn.iter()
                .enumerate()
                .filter_map(|(k, &i)| cut.tip[i].map(|t| (k, t)))
                .collect()
        } else {
            Vec::new()
        };
        let tip_branches = tip
            .iter()
            .map(|&(k, _)| tip_branches(mesh.kind, cut, conn[k]))
            .collect();
        let tip_scale = tip.iter().map(|&(_, t)| cut.tip_scale[t]).collect();
        let (phi, psi) = cut.vertex_levels(mesh, e);
        let grad_phi = (0..4).fold(Vector3::zeros(), |s, k| s + dl[k] * phi[k]);
        let grad_psi = (0..4).fold(Vector3::zeros(), |s, k| s + dl[k] * psi[k]);
        let mut node_side = [0i8; 10];
        for (k, &i) in conn.iter().enumerate() {
            node_side[k] = cut.node_side[i];
        }
        let size = mesh.element_size(e);
        let shift = tip
            .iter()
            .map(|&(k, _)| {
                let l = node_bary(k);
                let (f, g) = (dot4(&l, &phi), dot4(&l, &psi));
                let side = if f >= 0.0 { 1 } else { -1 };
                // As in `eval`: a node within round-off of the front is on it.
                let r = f.hypot(g);
                let r = if r <= FRONT_SNAP * size { 0.0 } else { r };
                front::branch_values(r, front::polar_angle(f, g, side))
            })
            .collect();
        let verts = mesh.vertex_points(e);
        let volume = tet_volume(&verts).abs();
        ElementShapes {
            kind: mesh.kind,
            map: BarycentricMap::new(&verts),
            dl: *dl,
            heaviside,
            tip,
            tip_branches,
            node_side,
            phi,
            psi,
            grad_phi,
            grad_psi,
            shift,
            tip_scale,
            ramp,
            size,
            volume,
        }
    }

    /// Number of shape functions.
    pub fn len(&self) -> usize {
        self.kind.nodes()
            + self.heaviside.len()
            + self.tip_branches.iter().map(|b| b.len()).sum::<usize>()
    }

    /// The varying factor of every Heaviside function at barycentric `l`:
    /// 1 − R(x) on Tet4 with the ramp, else 1 ([`ElementShapes::eval`]).
    fn heaviside_ramp(&self, l: &[f64; 4]) -> f64 {
        match &self.ramp {
            Some(in_i) if self.kind == ElementKind::Tet4 => {
                1.0 - (0..4).filter(|&i| in_i[i]).map(|i| l[i]).sum::<f64>()
            }
            _ => 1.0,
        }
    }

    /// The constant factor of local node `k`'s Heaviside function: 1 − R_k
    /// (R at the node) on Tet10 with the ramp, else 1 (Tet4's ramp, 1 − R(x),
    /// varies: [`ElementShapes::eval`]).
    fn heaviside_scale(&self, k: usize) -> f64 {
        match &self.ramp {
            Some(in_i) if self.kind == ElementKind::Tet10 => {
                let l = node_bary(k);
                1.0 - (0..4).filter(|&i| in_i[i]).map(|i| l[i]).sum::<f64>()
            }
            _ => 1.0,
        }
    }

    /// Barycentric coordinates of `x` in the element (its centroid for a
    /// degenerate element, which no built model holds).
    pub fn bary(&self, x: &Point3<f64>) -> [f64; 4] {
        self.map.map_or([0.25; 4], |m| m.at(x))
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// Global ids of the tip shape functions (`first` = id of tip block 0's first function).
    pub fn tip_shape_ids(&self, first: usize) -> impl Iterator<Item = u32> + '_ {
        self.tip
            .iter()
            .zip(&self.tip_branches)
            .flat_map(move |(&(_, t), &branches)| {
                branches
                    .iter()
                    .map(move |&b| (first + N_BRANCH * t + b) as u32)
            })
    }

    /// Values and gradients of all shape functions at barycentric `l`, seen
    /// from side `side` (±1 for a cell on one side of the cut, 0 elsewhere).
    pub fn eval(&self, l: &[f64; 4], side: i8, vals: &mut [f64], grads: &mut [Vector3<f64>]) {
        let nn = self.kind.nodes();
        let mut n = [0.0; 10];
        let mut gn = [Vector3::zeros(); 10];
        shape_values(self.kind, l, &mut n);
        shape_gradients(self.kind, l, &self.dl, &mut gn);
        vals[..nn].copy_from_slice(&n[..nn]);
        grads[..nn].copy_from_slice(&gn[..nn]);
        let (r, gr) = match &self.ramp {
            Some(in_i) => (0..4)
                .filter(|&i| in_i[i])
                .fold((0.0, Vector3::zeros()), |(r, g), i| {
                    (r + l[i], g + self.dl[i])
                }),
            None => (1.0, Vector3::zeros()),
        };
        // With the ramp, the Heaviside enrichment is ramped down by 1 − R
        // where the tip functions take over the jump: by 1 − R(x) on Tet4, by
        // its node's constant 1 − R_k on Tet10 ([`ElementShapes::heaviside_scale`]:
        // the functions' shifts then stay quadratic, as the tip functions' on
        // the linear λ do; ramped by 1 − R(x) they are cubic and leave what the
        // tip functions' shifts do not cancel, the exact study's interpolant
        // H1 error 0.4 at n = 2…6).
        let (h, gh) = if self.ramp.is_some() && self.kind == ElementKind::Tet4 {
            (1.0 - r, -gr)
        } else {
            (1.0, Vector3::zeros())
        };
        let mut a = nn;
        for &k in &self.heaviside {
            let p = if side == 0 {
                0.0
            } else {
                psi(side, self.node_side[k]) * self.heaviside_scale(k)
            };
            vals[a] = n[k] * h * p;
            grads[a] = (gn[k] * h + gh * n[k]) * p;
            a += 1;
        }
        let (mut f, mut g) = (dot4(l, &self.phi), dot4(l, &self.psi));
        // A point within round-off of the front is on it (r = 0: the tip
        // functions vanish, so the cut's opening is exactly 0 there rather
        // than √r of the interpolation's round-off, ~1e-8).
        // (|(φ, ψ)|² against the snap², no hypot: this runs at every point.)
        let snap = FRONT_SNAP * self.size;
        if f * f + g * g <= snap * snap {
            (f, g) = (0.0, 0.0);
        }
        let (fv, fg) = front::branch_with_gradients(f, g, &self.grad_phi, &self.grad_psi, side);
        // Tip functions on the vertices' linear partition of unity λ_k, times
        // the ramp R = Σ_{i∈I} λ_i where it is on (else R ≡ 1), over √h.
        for (j, &(k, _)) in self.tip.iter().enumerate() {
            let c = self.tip_scale[j];
            let (w, gw) = (l[k] * r * c, (self.dl[k] * r + gr * l[k]) * c);
            for &b in self.tip_branches[j] {
                let df = fv[b] - self.shift[j][b];
                vals[a] = w * df;
                grads[a] = gw * df + fg[b] * w;
                a += 1;
            }
        }
    }

    /// Quadrature points of an integration cell: collapsed onto the front
    /// where the cell touches it (φ = ψ = 0 at a vertex or an edge), the
    /// degree-5 rule elsewhere (Tet4; a 5³ Duffy tensor rule for Tet10).
    /// A cell the front meets along none of its edges and at none of its
    /// vertices (across a face: a front on a face of its element, as the
    /// seed's on its structured meshes' node plane x = 0.015), or passes
    /// within [`NEAR_TOUCH`] of its size, is first split by the level sets'
    /// planes through its point nearest the front (φ = 0 and ψ = 0 where it
    /// meets the front), so that the front runs along edges of the pieces;
    /// so is a cell the front passes through one vertex of and on into
    /// (a front through a node: the vertex's rule took the singular line
    /// only at that vertex; [`front_enters_at_vertex`])
    /// (test below: ∫ 1/r over such an element 2.9e-2 off with the red
    /// refinement alone; the seed's gravity probes, Tet4 and Tet10 at L0
    /// and L1, moved 5.6e-4 … 2.1e-3 of the largest by refining the
    /// quadrature further, now 3.5e-6 … 3.2e-5).
    pub fn cell_rule(&self, cell: &[Point3<f64>; 4]) -> Vec<front::PhysicalPoint> {
        self.cell_rule_at(cell, None)
    }

    /// [`ElementShapes::cell_rule`]; `target`: `None` for a cell, which is
    /// split first where the front passes through it off its edges or
    /// within [`NEAR_TOUCH`] of its size; `Some(p)` for such a piece,
    /// collapsed onto its vertices whose level sets are `p` (the cell's
    /// nearest to the front) and not split again.
    fn cell_rule_at(
        &self,
        cell: &[Point3<f64>; 4],
        target: Option<[f64; 2]>,
    ) -> Vec<front::PhysicalPoint> {
        let tol = 1e-9 * self.size;
        let p = target.unwrap_or([0.0, 0.0]);
        // Level sets at the cell's vertices, from the element's vertex values.
        let parent = self.vertices_from_cell(cell);
        let on_front = parent.map(|l| match l {
            Some(l) => {
                (dot4(&l, &self.phi) - p[0]).abs() <= tol
                    && (dot4(&l, &self.psi) - p[1]).abs() <= tol
            }
            None => false,
        });
        // A sliver (a cell of a split whose plane passes within a lift or
        // snap of the element's nodes, under SLIVER of its volume) holds
        // about that fraction of the element's integrals: a collapsed rule
        // of order 3 there (27 points for 64 or 125), and no refinement
        // near the front, err no more than the full rules elsewhere (the
        // patch test's residual stays 4.9e-5 with order 3; order 2 made
        // it 2.8e-4). A blade on a node layer leaves most cells of its
        // front elements such slivers (312 of 396 at 1k Tet4).
        let sliver = tet_volume(cell).abs() < SLIVER * self.volume;
        let ls = parent.map(|l| {
            l.map_or([f64::INFINITY; 2], |l| {
                [dot4(&l, &self.phi), dot4(&l, &self.psi)]
            })
        });
        // A front through one vertex and on into the cell (a front through
        // a node, not along an edge from it) is split below like a front
        // across the cell: the vertex rule takes the singular line only at
        // that vertex.
        let through_vertex = target.is_none() && !sliver && front_enters_at_vertex(&ls, &on_front);
        if on_front.iter().any(|&b| b) && !through_vertex {
            let n = match (self.kind, sliver) {
                (_, true) => 3,
                (ElementKind::Tet4, false) => 4,
                (ElementKind::Tet10, false) => 5,
            };
            return front::cell_rule(cell, on_front, n);
        }
        // The front through the cell off its edges and vertices, or within
        // NEAR_TOUCH of it: split by the level sets' planes through the
        // cell's point nearest the front, which the pieces collapse onto.
        let diam = front::level_diameter(&ls);
        let (gap, star) = front::front_nearest(&ls);
        if target.is_none()
            && diam.is_finite()
            && (gap <= tol || !sliver && gap <= NEAR_TOUCH * diam)
        {
            let shifted = |k: usize| {
                ls.map(|l| {
                    let v = l[k] - star[k];
                    if v.abs() <= tol {
                        0.0
                    } else {
                        v
                    }
                })
            };
            let (f, g) = (shifted(0), shifted(1));
            let crossed = |v: &[f64; 4]| v.iter().any(|&x| x > 0.0) && v.iter().any(|&x| x < 0.0);
            let pieces: Vec<[Point3<f64>; 4]> = if crossed(&f) {
                crate::cut::split_front(cell, &f, &g, tol)
                    .into_iter()
                    .map(|s| s.vertices)
                    .collect()
            } else if crossed(&g) {
                crate::cut::split_tet(cell, &g)
                    .into_iter()
                    .map(|s| s.vertices)
                    .collect()
            } else {
                vec![*cell]
            };
            return pieces
                .iter()
                .flat_map(|piece| self.cell_rule_at(piece, Some(star)))
                .collect();
        }
        // Cells the front passes within NEAR_POLAR of their size: polar
        // coordinates about the front, graded towards it.
        if !sliver && target.is_none() && diam.is_finite() && gap <= NEAR_POLAR * diam {
            let (n, n_z) = match self.kind {
                ElementKind::Tet4 => (4, 2),
                ElementKind::Tet10 => (4, 3),
            };
            if let Some(points) = front::polar_rule(cell, &ls, n, n_z) {
                return points;
            }
        }
        // Cells the front passes close to: refined once (see the patch test
        // in tests/front.rs for what this buys: the quadrature residual of a
        // linear field 6.3e-4 → 4.9e-5, for 1.9× the points of tip elements).
        let mut out = Vec::new();
        let degree5 = |c: &[Point3<f64>; 4], out: &mut Vec<front::PhysicalPoint>| {
            out.extend(front::degree5_rule(c))
        };
        front::near_front_rule(
            cell,
            &ls,
            if sliver { 0 } else { NEAR_FRONT_DEPTH },
            NEAR_FRONT_GAP,
            &degree5,
            &mut out,
        );
        if self.kind == ElementKind::Tet10 && out.len() == quadrature::DEGREE5.len() && !sliver {
            // 14 points × 6 strains < 3 × 50 DOFs of a fully tip-enriched Tet10:
            // a Duffy-mapped 5³ tensor rule keeps its element matrix definite.
            return front::cell_rule(cell, [false; 4], 5);
        }
        out
    }

    /// Barycentric coordinates (in the element) of the cell's vertices.
    fn vertices_from_cell(&self, cell: &[Point3<f64>; 4]) -> [Option<[f64; 4]>; 4] {
        cell.map(|x| self.map.map(|m| m.at(&x)))
    }
}

/// Whether the front, through exactly one vertex of a cell (`on_front`),
/// goes on into the cell: the vertex's image in the (φ, ψ) plane lies in
/// the closed triangle of the other three's (then the front's line meets
/// the cell beyond that vertex, inside or along a face).
fn front_enters_at_vertex(ls: &[[f64; 2]; 4], on_front: &[bool; 4]) -> bool {
    let mut at = on_front
        .iter()
        .enumerate()
        .filter(|(_, &b)| b)
        .map(|(k, _)| k);
    let (Some(k), None) = (at.next(), at.next()) else {
        return false;
    };
    let o = ls[k];
    let [a, b, c] = [0, 1, 2].map(|j| {
        let q = ls[if j < k { j } else { j + 1 }];
        [q[0] - o[0], q[1] - o[1]]
    });
    let cross = |p: [f64; 2], q: [f64; 2], r: [f64; 2]| {
        (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
    };
    let area = cross(a, b, c);
    let scale = [a, b, c]
        .iter()
        .map(|p| p[0].abs().max(p[1].abs()))
        .fold(0.0, f64::max);
    if !area.is_finite() || area.abs() <= 1e-12 * scale * scale {
        return false;
    }
    // Barycentric coordinates of the origin in the triangle a, b, c.
    let z = [0.0, 0.0];
    let l = [cross(z, b, c), cross(a, z, c), cross(a, b, z)].map(|v| v / area);
    l.iter().all(|&v| v >= -1e-9)
}

/// A cell (not a sliver) whose level-set image comes within this fraction
/// of its diameter of the front is split and collapsed onto its nearest
/// points ([`ElementShapes::cell_rule`]): a front just off a face (a cut
/// on a node layer, whose nodes the snap lifts by up to 1e-4 of their
/// element) runs along that face, and the red refinement's rule erred
/// there as where the front crosses the face: the seed's `gravity` with
/// its cut on the node layer z = 0.1 (3 × 6 × 10 and 6 × 12 × 20 boxes)
/// moved 3.4e-4 … 1.0e-3 of the largest probe displacement under a refined
/// quadrature, now 3.4e-6 … 2.5e-4. Slivers (the lifted layer's, under
/// [`SLIVER`] of their element) are left to their rule: splitting them too
/// took the 1k-Tet4 tip event of `examples/tip_event.rs` from 26460 to
/// 41760 points for the same accuracy; without them, 29820.
const NEAR_TOUCH: f64 = 1e-3;

/// A cell (not a sliver) whose level-set image comes within this fraction
/// of its diameter of the front, but not within [`NEAR_TOUCH`], takes
/// [`front::polar_rule`]: one red refinement and the degree-5 rule erred
/// there by 7e-3 … 2.6e-2 in ∫ 1/r (under 8.3e-4 farther out).
const NEAR_POLAR: f64 = 0.1;

/// Red refinements of a tip element's cell that does not touch the front
/// but whose level-set gap to it is under [`NEAR_FRONT_GAP`] times its size.
const NEAR_FRONT_DEPTH: usize = 1;
const NEAR_FRONT_GAP: f64 = 0.5;

/// Sides of a tip element under this fraction of its volume share the
/// largest side's group (and rotation): see [`merge_small_sides`].
pub const SMALL_SIDE: f64 = 1e-3;

/// Sides of a corotational Tet10 cut element under this fraction of its
/// volume turn with the other side where both lie in one part
/// ([`Integrator::small_side`]). The smallest fraction that let every
/// fuzz scene run: with 1e-5 one still stalled (seed 3012, whose inverted
/// corner held 2.7e-6 of its element); the modelling change (a corner's
/// stiffness against the two sides' relative rotation) grows with it: a
/// soft static scene's probes moved by 1.6e-5 with 1e-4, by 5.0e-4 with
/// [`SMALL_SIDE`]'s 1e-3.
pub const SMALL_CUT_SIDE: f64 = 1e-4;

/// Moves the points of each side of a tip element smaller than
/// [`SMALL_SIDE`] of the element's volume into its largest side (columns
/// and weights), so they share its dense group and
/// rotation. A side that small (a corner or sliver a lifted face or the
/// snap leaves, down to 1e-12 of the element) holds DOFs that little else
/// constrains; with a rotation of its own it inverted and made the exact
/// tangent indefinite, and Newton stalled (a blade 1e-7 off a node layer,
/// Tet10 corotational). With the largest side's rotation its energy is
/// quadratic in them; the cost is a stiffness of that fraction of the
/// element against the two sides' relative rotation (none in linear runs,
/// whose groups do not rotate).
fn merge_small_sides(sides: &mut [(Vec<f64>, Vec<f64>); 3], volume: f64) {
    let totals = sides.each_ref().map(|(_, w)| w.iter().sum::<f64>().abs());
    let Some(largest) = (0..3).max_by(|&a, &b| totals[a].total_cmp(&totals[b])) else {
        return;
    };
    #[allow(clippy::needless_range_loop)]
    for s in 0..3 {
        if s == largest || sides[s].1.is_empty() || totals[s] >= SMALL_SIDE * volume {
            continue;
        }
        let (columns, weights) = std::mem::take(&mut sides[s]);
        sides[largest].0.extend(columns);
        sides[largest].1.extend(weights);
    }
}

/// Cells under this fraction of their element's volume take rules of lower
/// order ([`ElementShapes::cell_rule`]).
const SLIVER: f64 = 1e-3;

fn dot4(l: &[f64; 4], v: &[f64; 4]) -> f64 {
    l[0] * v[0] + l[1] * v[1] + l[2] * v[2] + l[3] * v[3]
}

/// Barycentric coordinates of local node `k` (a vertex or a Tet10 mid-edge node).
fn node_bary(k: usize) -> [f64; 4] {
    let mut l = [0.0; 4];
    if k < 4 {
        l[k] = 1.0;
    } else {
        let (a, b) = TET10_EDGES[k - 4];
        l[a] = 0.5;
        l[b] = 0.5;
    }
    l
}

/// Maps reference quadrature point `q` of the cell `cell` (a sub-tet of the
/// parent `parent`) to barycentric coordinates of the parent and a weight.
fn map_point(
    parent: &[Point3<f64>; 4],
    cell: &[Point3<f64>; 4],
    q: &QuadPoint,
    cell_volume: f64,
) -> ([f64; 4], f64) {
    let x = cell
        .iter()
        .zip(q.bary)
        .fold(Vector3::zeros(), |s, (p, l)| s + p.coords * l);
    let bary = if std::ptr::eq(parent, cell) || parent == cell {
        q.bary
    } else {
        crate::mesh::barycentric(parent, &Point3::from(x)).unwrap_or(q.bary)
    };
    (bary, q.weight * cell_volume)
}

/// Values of the element's shape functions (nodes, then enriched ones × ψ).
fn eval_shapes(
    kind: ElementKind,
    bary: &[f64; 4],
    enr_local: &[usize],
    psi_of: impl Fn(usize) -> f64,
    nvals: &mut [f64; 10],
    out: &mut [f64],
) {
    shape_values(kind, bary, nvals);
    let nn = kind.nodes();
    out[..nn].copy_from_slice(&nvals[..nn]);
    for (j, &k) in enr_local.iter().enumerate() {
        out[nn + j] = nvals[k] * psi_of(k);
    }
}

/// The lower entries (column, row), row ≥ column, that elements with
/// equations `elements` (NONE for a fixed DOF) put in a matrix of order
/// `n`, sorted and each once: bucketed by column, duplicates dropped with a
/// marker per row, each column's few rows sorted (a sort of all entries,
/// 136k at a 1k-Tet4 tip event for 24k distinct, took 2.6 ms of it).
fn changed_entries(elements: impl Iterator<Item = Vec<u32>>, n: usize) -> Vec<(u32, u32)> {
    let mut lists: Vec<Vec<u32>> = Vec::new();
    let mut count = vec![0usize; n + 1];
    for mut dofs in elements {
        dofs.retain(|&d| d != NONE);
        dofs.sort_unstable();
        for (i, &c) in dofs.iter().enumerate() {
            count[c as usize + 1] += dofs.len() - i;
        }
        lists.push(dofs);
    }
    for c in 0..n {
        count[c + 1] += count[c];
    }
    let mut rows = vec![0u32; count[n]];
    let mut next = count.clone();
    for dofs in &lists {
        for (i, &c) in dofs.iter().enumerate() {
            let at = next[c as usize];
            rows[at..at + dofs.len() - i].copy_from_slice(&dofs[i..]);
            next[c as usize] += dofs.len() - i;
        }
    }
    let mut seen = vec![NONE; n];
    let mut out = Vec::new();
    let mut column = Vec::new();
    for c in 0..n {
        column.clear();
        for &r in &rows[count[c]..count[c + 1]] {
            if seen[r as usize] != c as u32 {
                seen[r as usize] = c as u32;
                column.push(r);
            }
        }
        column.sort_unstable();
        out.extend(column.iter().map(|&r| (c as u32, r)));
    }
    out
}

/// Equation numbers of an element's local DOFs (3 per shape function).
pub fn element_equations(shapes: &[u32], equation: &[u32]) -> Vec<u32> {
    shapes
        .iter()
        .flat_map(|&s| (0..3).map(move |c| equation[3 * s as usize + c]))
        .collect()
}

/// Adds ∫_faces t φ_a dA to `load` (degree-2 triangle rule, exact for Tet10 faces).
fn add_traction(mesh: &TetMesh, t: &Traction, load: &mut [f64]) {
    // Three-point triangle rule (degree 2), weights 1/3 of the area.
    const TRI: [[f64; 3]; 3] = [
        [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
        [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
        [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
    ];
    let mut n = [0.0; 10];
    for &(tri, e) in &t.faces {
        let verts = mesh.vertices(e);
        let local: Vec<usize> = tri
            .iter()
            .map(|v| verts.iter().position(|w| w == v).unwrap_or(0))
            .collect();
        let p: Vec<Point3<f64>> = tri.iter().map(|&i| mesh.nodes[i]).collect();
        let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        for r in TRI {
            let mut bary = [0.0; 4];
            for (k, &l) in local.iter().enumerate() {
                bary[l] = r[k];
            }
            shape_values(mesh.kind, &bary, &mut n);
            for (k, &node) in mesh.element(e).iter().enumerate() {
                for c in 0..3 {
                    load[3 * node + c] += area / 3.0 * t.value[c] * n[k];
                }
            }
        }
    }
}

/// The part of triangle `p` where `f ≥ 0` (`f` linear on it), as 0–2
/// triangles; where `f` vanishes on the whole triangle, all of it with
/// `keep_zero`, else nothing (so that the two sides do not both take it).
fn clip_triangle(
    p: &[Point3<f64>; 3],
    f: impl Fn(&Point3<f64>) -> f64,
    keep_zero: bool,
) -> Vec<[Point3<f64>; 3]> {
    let v = p.map(|x| f(&x));
    if v.iter().all(|&x| x == 0.0) {
        return if keep_zero { vec![*p] } else { Vec::new() };
    }
    let mut poly: Vec<Point3<f64>> = Vec::with_capacity(4);
    for k in 0..3 {
        let (a, b) = (k, (k + 1) % 3);
        if v[a] >= 0.0 {
            poly.push(p[a]);
        }
        if (v[a] > 0.0 && v[b] < 0.0) || (v[a] < 0.0 && v[b] > 0.0) {
            let t = v[a] / (v[a] - v[b]);
            poly.push(p[a] + (p[b] - p[a]) * t);
        }
    }
    (1..poly.len().saturating_sub(1))
        .map(|k| [poly[0], poly[k], poly[k + 1]])
        .filter(|t| (t[1] - t[0]).cross(&(t[2] - t[0])).norm() > 0.0)
        .collect()
}

/// Quadrature points (position, weight) of triangle `p`: 16 similar
/// triangles, each with the 7-point degree-5 rule (Dunavant).
fn triangle_points(p: &[Point3<f64>; 3]) -> Vec<(Point3<f64>, f64)> {
    const RULE: [(f64, f64, f64); 3] = [
        (1.0 / 3.0, 1.0 / 3.0, 0.225),
        (
            0.059_715_871_789_770,
            0.470_142_064_105_115,
            0.132_394_152_788_506,
        ),
        (
            0.797_426_985_353_087,
            0.101_286_507_323_456,
            0.125_939_180_544_827,
        ),
    ];
    const N: usize = 4;
    let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm() / (N * N) as f64;
    let at = |s: f64, t: f64| p[0] + (p[1] - p[0]) * s + (p[2] - p[0]) * t;
    let mut out = Vec::with_capacity(7 * N * N);
    let h = 1.0 / N as f64;
    for i in 0..N {
        for j in 0..N - i {
            // The upright sub-triangle (i, j) and, where it fits, the inverted one.
            let up = [(i, j), (i + 1, j), (i, j + 1)];
            let down = [(i + 1, j), (i + 1, j + 1), (i, j + 1)];
            let cells: &[[(usize, usize); 3]] = if i + j + 1 < N { &[up, down] } else { &[up] };
            for cell in cells {
                let q = cell.map(|(a, b)| (a as f64 * h, b as f64 * h));
                for &(a, b, w) in &RULE {
                    let c = 1.0 - a - b;
                    for (l0, l1, l2) in [(a, b, c), (b, c, a), (c, a, b)] {
                        let s = l0 * q[0].0 + l1 * q[1].0 + l2 * q[2].0;
                        let t = l0 * q[0].1 + l1 * q[1].1 + l2 * q[2].1;
                        out.push((at(s, t), w * area));
                        if a == b {
                            break; // the centroid: once
                        }
                    }
                }
            }
        }
    }
    out
}

// ---------------------------------------------------------------------------
// The named steps of [`Model::build_with`] (and of [`Model::update_cut`]).

/// Number of shape functions of a mesh with a cut: nodes, Heaviside-enriched
/// nodes, four branch functions per tip-enriched node.
fn shape_count(mesh: &TetMesh, cut: Option<&CutSetup>) -> Result<usize, ModelError> {
    let n_enriched = cut.map_or(0, |c| c.n_enriched);
    let n_tip = cut.map_or(0, |c| c.n_tip);
    let n_shape = mesh.n_nodes() + n_enriched + N_BRANCH * n_tip;
    if 3 * n_shape >= NONE as usize {
        return Err(ModelError::TooLarge(3 * n_shape));
    }
    Ok(n_shape)
}

/// An integration cell of an element: a (sub-)tetrahedron on one side of the cut.
struct Cell {
    vertices: [Point3<f64>; 4],
    /// +1 / −1 above / below the cut, 0 for an element without enrichment.
    side: i8,
    /// Its volume (> 0: cells without volume are left out).
    volume: f64,
}

/// Step 1 of the build for one element: its geometry, its shape functions
/// (nodes, then Heaviside-enriched nodes, then tip functions) and its
/// integration cells with their volumes.
struct ElementCells {
    /// The element's index in the mesh.
    element: usize,
    verts: [Point3<f64>; 4],
    dl: [Vector3<f64>; 4],
    /// Global shape-function ids.
    shape_ids: Vec<u32>,
    /// Local nodes whose Heaviside shape functions the element holds.
    heaviside: Vec<usize>,
    node_side: [i8; 10],
    cells: Vec<Cell>,
    /// The point-by-point shapes of an element holding tip-enriched nodes.
    tip: Option<ElementShapes>,
}

impl ElementCells {
    /// ψ of local node `k` in `cell` (0 in an element without enrichment).
    fn psi(&self, cell: &Cell, k: usize) -> f64 {
        if cell.side == 0 {
            0.0
        } else {
            psi(cell.side, self.node_side[k])
        }
    }
}

/// Step 1: the cells of element `e` (degenerate elements are refused).
fn element_cells(
    mesh: &TetMesh,
    cut: Option<&CutSetup>,
    e: usize,
) -> Result<ElementCells, ModelError> {
    let conn = mesh.element(e);
    let verts = mesh.vertex_points(e);
    let volume = tet_volume(&verts);
    let dl = barycentric_gradients(&verts)
        .filter(|_| volume > 0.0)
        .ok_or(ModelError::DegenerateElement { element: e, volume })?;
    let n_nodes = mesh.n_nodes();
    let mut shape_ids: Vec<u32> = conn.iter().map(|&i| i as u32).collect();
    let mut heaviside = Vec::new();
    let mut node_side = [0i8; 10];
    let mut cells = Vec::new();
    // Cells of either orientation ([`crate::cut::SubTet`]); an element's
    // own cell in its canonical order.
    let canonical = mesh.canonical_points(e);
    let mut cell = |vertices: [Point3<f64>; 4], side: i8| {
        let volume = tet_volume(&vertices).abs();
        if volume > 0.0 {
            cells.push(Cell {
                vertices,
                side,
                volume,
            });
        }
    };
    match (cut, cut.map(|c| &c.elements[e])) {
        (Some(c), Some(ElementCut::Cut { sub_tets, .. })) => {
            for (k, &i) in conn.iter().enumerate() {
                node_side[k] = c.node_side[i];
                if let Some(j) = c.enriched[i] {
                    heaviside.push(k);
                    shape_ids.push((n_nodes + j) as u32);
                }
            }
            for s in sub_tets {
                cell(s.vertices, s.side);
            }
        }
        (Some(c), Some(ElementCut::Touched { side })) => {
            for (k, &i) in conn.iter().enumerate() {
                node_side[k] = c.node_side[i];
                if let Some(j) = c.enriched[i] {
                    if psi(*side, c.node_side[i]) != 0.0 {
                        heaviside.push(k);
                        shape_ids.push((n_nodes + j) as u32);
                    }
                }
            }
            cell(canonical, *side);
        }
        _ => cell(canonical, 0),
    }
    let tip = cut.and_then(|c| ElementShapes::new(mesh, c, e, &dl, heaviside.clone()));
    if let (Some(shapes), Some(c)) = (&tip, cut) {
        shape_ids.extend(shapes.tip_shape_ids(n_nodes + c.n_enriched));
    }
    Ok(ElementCells {
        element: e,
        verts,
        dl,
        shape_ids,
        heaviside,
        node_side,
        cells,
        tip,
    })
}

/// Step 2's result for one element: everything its cells contribute, in
/// local shape order.
#[derive(Clone)]
struct ElementBlock {
    shape_ids: Vec<u32>,
    /// Local index of the first Heaviside shape function (nodes per element).
    heaviside_start: usize,
    /// Integration groups, `grads` relative to this block's gradients.
    groups: Vec<Group>,
    grads: Vec<Vector3<f64>>,
    /// Dense groups' stiffness, `stiffness` relative to this block's.
    stiffness: Vec<f64>,
    /// ∫ f φ_a (3 per shape function; empty without body force).
    load: Vec<f64>,
    /// Lumped mass per shape function, lumped u–a coupling per Heaviside
    /// shape function, consistent mass (m × m); empty without mass.
    lumped: Vec<f64>,
    coupling: Vec<f64>,
    mass: Vec<f64>,
    /// Tet10 with mass: per side slot and node, the cells' lumped mass less
    /// ρ ∫ N_k ([`Model::lump_residual`]).
    lump_residual: [[f64; 10]; 2],
    /// With an old field to fit ([`Integrator::old`]), a tip element's
    /// integrals for the event's projection.
    fit: Option<Box<TipFit>>,
}

/// A cut event's projection integrals of one element holding tip functions
/// in the new model ([`Model::update_cut_fitted_with`]), taken on the points
/// that integrate its block (the points [`Model::field_points`] gives),
/// with the new shape functions φ_a in [`Model::element_shapes`] order and
/// the old model's field (u, v, a) at each point:
/// what [`crate::blade::project_tip_change`] would otherwise evaluate the
/// new functions again for.
#[derive(Debug, Clone)]
pub struct TipFit {
    /// m × m: ∫ φ_a φ_b.
    pub l2: nalgebra::DMatrix<f64>,
    /// 3m × 3m: ∫ ∂_i φ_a ∂_j φ_b at (3a + i, 3b + j).
    pub gradients: nalgebra::DMatrix<f64>,
    /// m × 9: ∫ φ_a u, ∫ φ_a v, ∫ φ_a a (three columns each).
    pub values: nalgebra::DMatrix<f64>,
    /// 3m × 3: ∫ ε(φ_a e_c) : C : ε(w) / μ = ∫ (∇w + ∇wᵀ)_c · ∇φ_a + (λ/μ)
    /// div w ∂_c φ_a at row 3a + c, column 0, 1, 2 for w = u, v, a.
    pub strain: nalgebra::DMatrix<f64>,
}

/// Per element (index), its [`TipFit`].
pub type TipFits = std::collections::HashMap<usize, TipFit>;

/// A field of a model to fit at a cut event: its displacement, velocity
/// and acceleration (all DOFs of `model`).
#[derive(Clone, Copy)]
pub struct OldField<'a> {
    pub model: &'a Model,
    pub d: &'a [f64],
    pub v: &'a [f64],
    pub a: &'a [f64],
}

/// What a tip element's block collects for its [`TipFit`], point by point:
/// the old field on the element, w (u, v, a) per point (9 each, in the
/// order of the points' shape values), and per side the points' symmetric
/// S_q = w (∇f + ∇fᵀ + (λ/μ) div f I) for f = u, v, a, 27 a point in the
/// order of the side's gradient columns (entry (c, d) of S_f at
/// 9d + 3f + c), for the sums Σ_q S_q ∇φ_a(x_q) ([`FitPoints::strain`]).
struct FitPoints {
    field: ElementField,
    fields: Vec<f64>,
    stresses: [Vec<f64>; 3],
}

impl FitPoints {
    /// 3m × 3: Σ_q S_q ∇φ_a(x_q) at row 3a + c, column f, over every side's
    /// points (`sides` the tip block's gradient columns, 3m a point). Three
    /// products a side, one per gradient component d: the m × n matrix of
    /// ∂_d φ_a (strides 3 and 3m in the columns) times the n × 9 of
    /// S_f(c, d) (stride 27). It was a sum of 9 products a function, field
    /// and point (3 × m × 9 scalar updates a point).
    fn strain(&self, m: usize, sides: &[(Vec<f64>, Vec<f64>); 3]) -> nalgebra::DMatrix<f64> {
        let mut r = nalgebra::DMatrix::<f64>::zeros(m, 9);
        for ((columns, weights), stresses) in sides.iter().zip(&self.stresses) {
            let n = weights.len();
            if n == 0 {
                continue;
            }
            for d in 0..3 {
                let g =
                    nalgebra::DMatrixView::from_slice_with_strides(&columns[d..], m, n, 3, 3 * m);
                let t =
                    nalgebra::DMatrixView::from_slice_with_strides(&stresses[9 * d..], n, 9, 27, 1);
                r.gemm(1.0, &g, &t, 1.0);
            }
        }
        nalgebra::DMatrix::from_fn(3 * m, 3, |row, f| r[(row / 3, 3 * f + row % 3)])
    }
}

/// An [`OldField`] on one element: its evaluator and its DOF values.
struct ElementField {
    ev: ElementEvaluator,
    d: Vec<Vector3<f64>>,
    v: Vec<Vector3<f64>>,
    a: Vec<Vector3<f64>>,
    vals: Vec<f64>,
    grads: Vec<Vector3<f64>>,
}

impl ElementField {
    fn new(field: &OldField<'_>, e: usize) -> ElementField {
        let ev = field.model.element_evaluator(e);
        let ids = field.model.element_shapes(e);
        let at = |x: &[f64]| -> Vec<Vector3<f64>> {
            ids.iter()
                .map(|&s| {
                    let s = s as usize;
                    Vector3::new(x[3 * s], x[3 * s + 1], x[3 * s + 2])
                })
                .collect()
        };
        ElementField {
            d: at(field.d),
            v: at(field.v),
            a: at(field.a),
            vals: vec![0.0; ids.len()],
            grads: vec![Vector3::zeros(); ids.len()],
            ev,
        }
    }

    /// u, v and a at `x` on side `side`, and their gradients (row c = ∇u_c).
    fn at(&mut self, x: &Point3<f64>, side: i8) -> ([Vector3<f64>; 3], [Matrix3<f64>; 3]) {
        // The old field on the side x lies on in the old element.
        let side = self.ev.side_at(x, side);
        self.ev.eval(x, side, &mut self.vals, &mut self.grads);
        let mut w = [Vector3::zeros(); 3];
        let mut gw = [Matrix3::zeros(); 3];
        for (k, (&n, g)) in self.vals.iter().zip(&self.grads).enumerate() {
            for (f, x) in [self.d[k], self.v[k], self.a[k]].into_iter().enumerate() {
                w[f] += x * n;
                gw[f] += x * g.transpose();
            }
        }
        (w, gw)
    }
}

/// What step 2 integrates with: the rules, loads and density of a build.
struct Integrator<'a> {
    mesh: &'a TetMesh,
    lame: Lame,
    rho: f64,
    integration: Integration,
    /// Per element, where a cut element's small side may take its other
    /// side's rotation ([`small_side_rotation`]): `None` where none may.
    joined: Option<&'a [bool]>,
    gravity: Option<Vector3<f64>>,
    body_force: Option<&'a BodyForce>,
    need_mass: bool,
    /// Whether to integrate the stiffness (groups, gradients); without it
    /// only the loads and masses of a tip element's block.
    stiffness: bool,
    /// The old field a cut event projects: with it, a tip element's block
    /// (with dense groups and mass) carries its [`TipFit`].
    old: Option<OldField<'a>>,
}

impl Integrator<'_> {
    fn has_load(&self) -> bool {
        self.gravity.is_some() || self.body_force.is_some()
    }

    /// The body force per unit volume at `x`.
    fn force(&self, x: &Point3<f64>) -> Vector3<f64> {
        let mut f = self.gravity.map_or(Vector3::zeros(), |g| g * self.rho);
        if let Some(bf) = self.body_force {
            f += bf(x);
        }
        f
    }

    /// Step 2: one walk over the element's cells. With `direct` its load
    /// and lumped mass go straight into those global vectors, point by point
    /// as they are integrated (the build), else into the block's own (an update).
    fn block(&self, cells: &ElementCells, direct: Option<&mut Globals>) -> ElementBlock {
        let m = cells.shape_ids.len();
        let mut block = ElementBlock {
            shape_ids: cells.shape_ids.clone(),
            heaviside_start: self.mesh.kind.nodes(),
            groups: Vec::new(),
            grads: Vec::new(),
            stiffness: Vec::new(),
            load: if self.has_load() && direct.is_none() {
                vec![0.0; 3 * m]
            } else {
                Vec::new()
            },
            lumped: Vec::new(),
            coupling: Vec::new(),
            mass: Vec::new(),
            lump_residual: [[0.0; 10]; 2],
            fit: None,
        };
        if self.need_mass {
            if direct.is_none() {
                block.lumped = vec![0.0; m];
                block.coupling = vec![0.0; cells.heaviside.len()];
            }
            block.mass = vec![0.0; m * m];
        }
        let mut sink = Sink {
            direct,
            n_nodes: self.mesh.n_nodes(),
        };
        match &cells.tip {
            Some(shapes) => self.tip_block(cells, shapes, &mut block, &mut sink),
            None => self.standard_block(cells, &mut block, &mut sink),
        }
        block
    }

    /// Elements holding tip-enriched nodes: one dense group per side
    /// ([`Group`]: the stiffness of all its points summed, their averaged
    /// gradients; with [`Integration::SubTetQuadrature`] one point group per
    /// point, a rotation each), the rules of [`ElementShapes::cell_rule`];
    /// loads and mass point by point.
    fn tip_block(
        &self,
        cells: &ElementCells,
        shapes: &ElementShapes,
        block: &mut ElementBlock,
        sink: &mut Sink<'_>,
    ) {
        let kind = self.mesh.kind;
        let nn = kind.nodes();
        let m = block.shape_ids.len();
        let mut vals = vec![0.0; m];
        let mut gr = vec![Vector3::zeros(); m];
        let per_point = self.integration == Integration::SubTetQuadrature;
        // Per side (−1, 0, +1): its points' gradients, 3m a column, and weights.
        let mut sides: [(Vec<f64>, Vec<f64>); 3] = Default::default();
        // The points' shape values (m a column) and ρ w: the consistent mass
        // is one product V W Vᵀ at the end, not m² updates a point.
        let (mut mass_values, mut mass_weights) = (Vec::new(), Vec::new());
        // Per cell: ∫N_k and ∫N_k² for the lumped mass; with Tet4's ramp
        // h = 1 − R(x) also ∫h N_k and ∫h² N_k (the Heaviside functions').
        let (mut lump_n, mut lump_n2) = (Vec::new(), Vec::new());
        let varying = shapes.ramp.is_some() && kind == ElementKind::Tet4;
        let (mut lump_hn, mut lump_h2n) = (Vec::new(), Vec::new());
        // A cut event's fit: the old field on this element, and the
        // integrals of the new functions against it (the Grams come from
        // the mass and the dense groups below).
        let mut fit = self
            .old
            .filter(|_| self.stiffness && !per_point && self.need_mass && self.rho > 0.0)
            .map(|old| FitPoints {
                field: ElementField::new(&old, cells.element),
                fields: Vec::new(),
                stresses: Default::default(),
            });
        let ratio = self.lame.lambda / self.lame.mu;
        // The cells' rules first, so that the point-wise buffers are sized
        // once (grown point by point, their copies were 5 % of a tip event).
        let rules: Vec<_> = cells
            .cells
            .iter()
            .map(|cell| shapes.cell_rule(&cell.vertices))
            .collect();
        let mut per_side = [0; 3];
        for (cell, rule) in cells.cells.iter().zip(&rules) {
            per_side[(cell.side + 1) as usize] += rule.len();
        }
        let total: usize = per_side.iter().sum();
        for ((columns, weights), &n) in sides.iter_mut().zip(&per_side) {
            if self.stiffness && !per_point {
                columns.reserve_exact(3 * m * n);
                weights.reserve_exact(n);
            }
        }
        if self.need_mass {
            mass_values.reserve_exact(m * total);
            mass_weights.reserve_exact(total);
        }
        if let Some(fit) = fit.as_mut() {
            fit.fields.reserve_exact(9 * total);
            for (stresses, &n) in fit.stresses.iter_mut().zip(&per_side) {
                stresses.reserve_exact(27 * n);
            }
        }
        for (cell, rule) in cells.cells.iter().zip(rules) {
            let (mut int_n, mut int_n2) = ([0.0; 10], [0.0; 10]);
            let (mut int_hn, mut int_h2n) = ([0.0; 4], [0.0; 4]);
            let (columns, weights) = &mut sides[(cell.side + 1) as usize];
            for q in rule {
                let bary = shapes.bary(&q.x);
                let w = q.weight;
                shapes.eval(&bary, cell.side, &mut vals, &mut gr);
                if let Some(fit) = fit.as_mut() {
                    // The old field's w u, w v, w a (against the values) and
                    // w ((∇u + ∇uᵀ) + (λ/μ) div u I), the same of v and a
                    // (against the gradients).
                    let (field, gradients) = fit.field.at(&q.x, cell.side);
                    for f in field {
                        fit.fields.extend((f * w).iter());
                    }
                    let stresses = &mut fit.stresses[(cell.side + 1) as usize];
                    let at = stresses.len();
                    stresses.resize(at + 27, 0.0);
                    for (f, g) in gradients.iter().enumerate() {
                        let s = (g + g.transpose() + Matrix3::identity() * (g.trace() * ratio)) * w;
                        for d in 0..3 {
                            for c in 0..3 {
                                stresses[at + 9 * d + 3 * f + c] = s[(c, d)];
                            }
                        }
                    }
                }
                if !self.stiffness {
                } else if per_point {
                    block.groups.push(Group::point(w, block.grads.len() as u32));
                    block.grads.extend_from_slice(&gr);
                } else {
                    weights.push(w);
                    columns.extend(gr.iter().flat_map(|g| [g.x, g.y, g.z]));
                }
                if self.has_load() {
                    let f = self.force(&q.x);
                    for (a, &v) in vals.iter().enumerate() {
                        for c in 0..3 {
                            sink.load(block, a, c, w * f[c] * v);
                        }
                    }
                }
                if self.need_mass {
                    mass_values.extend_from_slice(&vals);
                    mass_weights.push(self.rho * w);
                    for k in 0..nn {
                        int_n[k] += w * vals[k];
                        int_n2[k] += w * vals[k] * vals[k];
                    }
                    if varying {
                        let h = shapes.heaviside_ramp(&bary);
                        for k in 0..4 {
                            int_hn[k] += w * h * vals[k];
                            int_h2n[k] += w * h * h * vals[k];
                        }
                    }
                }
            }
            if self.need_mass {
                lump_n.push(int_n);
                lump_n2.push(int_n2);
                if varying {
                    lump_hn.push(int_hn);
                    lump_h2n.push(int_h2n);
                }
            }
        }
        if self.need_mass {
            // A Heaviside function h ψ N_k lumps as ψ N_k does times the
            // factors of its coupling and mass: c and c² for Tet10's
            // constant c = 1 − R_k; Tet4's varying h: ∫h N_k / ∫N_k and
            // ∫h² N_k / ∫N_k over the cell (its share is ρ ∫N_k, the
            // cell's row sum: these make it ρ ∫h N_k and ρ ∫h² N_k).
            let scale = |c: usize, k: usize| {
                if varying {
                    let n = lump_n[c][k];
                    if n > 0.0 {
                        (lump_hn[c][k] / n, lump_h2n[c][k] / n)
                    } else {
                        (1.0, 1.0)
                    }
                } else {
                    let f = shapes.heaviside_scale(k);
                    (f, f * f)
                }
            };
            self.lump(cells, &lump_n, &lump_n2, scale, block, sink);
        }
        // (Before the merge moves the sides' columns: their sum is the same.)
        let strain = fit.as_ref().map(|fit| fit.strain(m, &sides));
        if !per_point {
            merge_small_sides(&mut sides, shapes.volume);
        }
        let mut gradients = fit
            .as_ref()
            .map(|_| nalgebra::DMatrix::<f64>::zeros(3 * m, 3 * m));
        for (columns, weights) in &sides {
            if self.stiffness && !weights.is_empty() {
                let a = self.dense_group(m, columns, weights, block);
                if let Some(g) = gradients.as_mut() {
                    *g += a;
                }
            }
        }
        if self.need_mass && !mass_weights.is_empty() {
            let v = nalgebra::DMatrixView::from_slice(&mass_values, m, mass_weights.len());
            let mut vw = nalgebra::DMatrix::from_column_slice(m, mass_weights.len(), &mass_values);
            for (mut col, &w) in vw.column_iter_mut().zip(&mass_weights) {
                col *= w;
            }
            // Row-major m × m, symmetric: the column-major product is the same.
            let mut mass = nalgebra::DMatrixViewMut::from_slice(&mut block.mass, m, m);
            mass.gemm(1.0, &vw, &v.transpose(), 1.0);
        }
        if let (Some(fit), Some(gradients), Some(strain)) = (fit, gradients, strain) {
            let l2 = nalgebra::DMatrix::from_row_slice(m, m, &block.mass) / self.rho;
            // Σ_q φ_a(x_q) w_q F_q (the points in `mass_values`' order).
            let n = fit.fields.len() / 9;
            let v = nalgebra::DMatrixView::from_slice(&mass_values, m, n);
            let f = nalgebra::DMatrixView::from_slice(&fit.fields, 9, n);
            let values = v * f.transpose();
            block.fit = Some(Box::new(TipFit {
                l2,
                gradients,
                values,
                strain,
            }));
        }
        if self.need_mass {
            // Tip DOFs: the diagonal of the consistent mass (no coupling).
            for a in nn + cells.heaviside.len()..m {
                let diagonal = block.mass[a * m + a];
                sink.lumped(block, a, diagonal);
            }
        }
    }

    /// Appends the dense group of points with gradients `columns` (3m per
    /// point) and weights `weights`: weight Σw, gradients ḡ_a = Σ w g_a / Σw
    /// and K_ab = λ A_ab + μ A_abᵀ + μ tr(A_ab) I with A = Σ_q w_q G_q G_qᵀ
    /// (G_q the point's 3m gradient components: one matrix product); returns A.
    fn dense_group(
        &self,
        m: usize,
        columns: &[f64],
        weights: &[f64],
        block: &mut ElementBlock,
    ) -> nalgebra::DMatrix<f64> {
        let n = 3 * m;
        let nq = weights.len();
        // (clone_owned of a view goes element by element: 9 % of a tip event.)
        let mut gw = nalgebra::DMatrix::from_column_slice(n, nq, columns);
        for (mut col, &w) in gw.column_iter_mut().zip(weights) {
            col *= w;
        }
        // A = (G W) Gᵀ is symmetric: its lower triangle from one product
        // (faer's triangular matmul: 1.2–1.3× faster than the full product at
        // a Tet4 tip element's 60 × 148), mirrored.
        let mut a = nalgebra::DMatrix::<f64>::zeros(n, n);
        {
            use faer::linalg::matmul::triangular::{matmul, BlockStructure};
            let gw = faer::MatRef::from_column_major_slice(gw.as_slice(), n, nq);
            let g = faer::MatRef::from_column_major_slice(columns, n, nq);
            let out = faer::MatMut::from_column_major_slice_mut(a.as_mut_slice(), n, n);
            matmul(
                out,
                BlockStructure::TriangularLower,
                faer::Accum::Replace,
                gw,
                BlockStructure::Rectangular,
                g.transpose(),
                BlockStructure::Rectangular,
                1.0,
                faer::Par::Seq,
            );
        }
        for c in 1..n {
            for r in 0..c {
                a[(r, c)] = a[(c, r)];
            }
        }
        let total: f64 = weights.iter().sum();
        let grads = block.grads.len() as u32;
        for f in 0..m {
            let s = gw.fixed_rows::<3>(3 * f).column_sum();
            block.grads.push(if total != 0.0 { s / total } else { s });
        }
        // K's lower triangle, rows packed (`DenseKernel::stiffness`).
        let stiffness = block.stiffness.len() as u32;
        block
            .stiffness
            .resize(block.stiffness.len() + crate::kernel::packed_len(n), 0.0);
        let k = &mut block.stiffness[stiffness as usize..];
        let (lambda, mu) = (self.lame.lambda, self.lame.mu);
        for p in 0..m {
            for q in 0..=p {
                let ab = a.fixed_view::<3, 3>(3 * p, 3 * q);
                let trace = ab.trace();
                for i in 0..3 {
                    // Columns up to the diagonal in the diagonal block.
                    for j in 0..if q == p { i + 1 } else { 3 } {
                        let (r, c) = (3 * p + i, 3 * q + j);
                        let mut v = lambda * ab[(i, j)] + mu * ab[(j, i)];
                        if i == j {
                            v += mu * trace;
                        }
                        k[crate::kernel::packed_index(r, c)] = v;
                    }
                }
            }
        }
        block.groups.push(Group {
            weight: total,
            grads,
            stiffness,
        });
        a
    }

    /// The side of a cut element (with a rotation per point) under
    /// [`SMALL_CUT_SIDE`] of its volume, where [`Integrator::joined`] lets it
    /// rotate with the other side, and the other side's centroid
    /// (barycentric in the element). A corner the cut leaves a few 1e-8 of
    /// a Tet10 (just beyond the snap) holds DOFs that little else
    /// constrains: with a rotation per point, from the element's quadratic
    /// extrapolated into the corner, its points inverted under a shock and
    /// Newton stalled (a blade sweeping a partial cut, the top face moved at
    /// once). With the other side's rotation its energy is quadratic in
    /// them; the cost is a stiffness of that fraction of the element
    /// against the two sides' relative rotation (as [`merge_small_sides`]
    /// in tip elements). Only within one part: across a through cut it
    /// would be a force between two parts.
    fn small_side(&self, cells: &ElementCells) -> Option<(i8, [f64; 4])> {
        if !self.joined.is_some_and(|j| j[cells.element]) || cells.heaviside.is_empty() {
            return None;
        }
        let mut volume = [0.0; 2];
        let mut centre = [Vector3::zeros(); 2];
        for cell in cells.cells.iter().filter(|c| c.side != 0) {
            let s = usize::from(cell.side > 0);
            let v = cell.volume.abs();
            volume[s] += v;
            centre[s] += cell.vertices.iter().map(|p| p.coords).sum::<Vector3<f64>>() * (0.25 * v);
        }
        let total = volume[0] + volume[1];
        let s = if volume[0] < volume[1] { 0 } else { 1 };
        if volume[s] <= 0.0 || volume[s] >= SMALL_CUT_SIDE * total {
            return None;
        }
        let other = 1 - s;
        let x = Point3::from(centre[other] / volume[other]);
        let bary = crate::mesh::barycentric(&cells.verts, &x)?;
        Some((if s == 1 { 1 } else { -1 }, bary))
    }

    /// Elements without tip functions: per cell, the stiffness points
    /// (grouped per side for Tet4: the strain is constant there), the load
    /// points and the mass points.
    fn standard_block(&self, cells: &ElementCells, block: &mut ElementBlock, sink: &mut Sink<'_>) {
        let kind = self.mesh.kind;
        let nn = kind.nodes();
        let m = block.shape_ids.len();
        let grouped = kind == ElementKind::Tet4 && self.integration == Integration::Grouped;
        let stiffness_rule = quadrature::rule(if grouped { 1 } else { 2 });
        // Gravity is constant (degree = shape degree); a varying body force gets degree 5.
        let load_rule = if self.body_force.is_some() {
            quadrature::rule(5)
        } else {
            stiffness_rule
        };
        let mass_rule = quadrature::rule(match kind {
            ElementKind::Tet4 => 2,
            ElementKind::Tet10 => 4,
        });
        let mut nvals = [0.0; 10];
        let mut ngrads = [Vector3::zeros(); 10];
        let mut shape_val = vec![0.0; m];
        let mut side_group: [Option<usize>; 3] = [None; 3];
        // A small side rotating with the other ([`Integrator::small_side`]):
        // its points' gradients (3m a column) and weights.
        let small = self.small_side(cells);
        let (mut small_columns, mut small_weights) = (Vec::new(), Vec::new());
        // Per cell: ∫N_k and ∫N_k² for the lumped mass.
        let (mut lump_n, mut lump_n2) = (Vec::new(), Vec::new());
        for cell in &cells.cells {
            for q in stiffness_rule {
                let (bary, w) = map_point(&cells.verts, &cell.vertices, q, cell.volume);
                shape_gradients(kind, &bary, &cells.dl, &mut ngrads);
                if small.is_some_and(|(side, _)| side == cell.side) {
                    small_columns.extend(ngrads[..nn].iter().flat_map(|g| [g.x, g.y, g.z]));
                    small_columns.extend(cells.heaviside.iter().flat_map(|&k| {
                        let g = ngrads[k] * cells.psi(cell, k);
                        [g.x, g.y, g.z]
                    }));
                    small_weights.push(w);
                    continue;
                }
                let g = match (grouped, side_group[(cell.side + 1) as usize]) {
                    (true, Some(g)) => g,
                    _ => {
                        let g = block.groups.len();
                        block
                            .groups
                            .push(Group::point(0.0, block.grads.len() as u32));
                        block.grads.extend(std::iter::repeat_n(Vector3::zeros(), m));
                        if grouped {
                            side_group[(cell.side + 1) as usize] = Some(g);
                        }
                        g
                    }
                };
                // For Tet4 all points of a side have the same gradients: store them once.
                let gstart = block.groups[g].grads as usize;
                if !grouped || block.groups[g].weight == 0.0 {
                    block.grads[gstart..gstart + nn].copy_from_slice(&ngrads[..nn]);
                    for (j, &k) in cells.heaviside.iter().enumerate() {
                        block.grads[gstart + nn + j] = ngrads[k] * cells.psi(cell, k);
                    }
                }
                block.groups[g].weight += w;
            }
            if self.has_load() {
                for q in load_rule {
                    let (bary, w) = map_point(&cells.verts, &cell.vertices, q, cell.volume);
                    eval_shapes(
                        kind,
                        &bary,
                        &cells.heaviside,
                        |k| cells.psi(cell, k),
                        &mut nvals,
                        &mut shape_val,
                    );
                    let x = cells
                        .verts
                        .iter()
                        .zip(bary)
                        .fold(Vector3::zeros(), |s, (p, l)| s + p.coords * l);
                    let f = self.force(&Point3::from(x));
                    for (a, &phi) in shape_val.iter().enumerate() {
                        for c in 0..3 {
                            sink.load(block, a, c, w * f[c] * phi);
                        }
                    }
                }
            }
            if self.need_mass {
                // Consistent element mass M_ab = ρ ∫ φ_a φ_b (eq. 77–80), and
                // ∫ N_k, ∫ N_k² over the cell for the lumped mass.
                let (mut int_n, mut int_n2) = ([0.0; 10], [0.0; 10]);
                for q in mass_rule {
                    let (bary, w) = map_point(&cells.verts, &cell.vertices, q, cell.volume);
                    eval_shapes(
                        kind,
                        &bary,
                        &cells.heaviside,
                        |k| cells.psi(cell, k),
                        &mut nvals,
                        &mut shape_val,
                    );
                    for a in 0..m {
                        for b in 0..m {
                            block.mass[a * m + b] += self.rho * w * shape_val[a] * shape_val[b];
                        }
                    }
                    for k in 0..nn {
                        int_n[k] += w * nvals[k];
                        int_n2[k] += w * nvals[k] * nvals[k];
                    }
                }
                lump_n.push(int_n);
                lump_n2.push(int_n2);
            }
        }
        if let Some((side, centroid)) = small {
            // Its stiffness summed, its rotation the other side's: the
            // averaged gradients are the other side's field's (linear in
            // x for Tet10, so their mean is their value at its centroid).
            let m = block.shape_ids.len();
            self.dense_group(m, &small_columns, &small_weights, block);
            shape_gradients(kind, &centroid, &cells.dl, &mut ngrads);
            let start = block.grads.len() - m;
            let averaged = &mut block.grads[start..];
            averaged[..nn].copy_from_slice(&ngrads[..nn]);
            for (j, &k) in cells.heaviside.iter().enumerate() {
                averaged[nn + j] = ngrads[k] * psi(-side, cells.node_side[k]);
            }
        }
        if self.need_mass {
            self.lump(cells, &lump_n, &lump_n2, |_, _| (1.0, 1.0), block, sink);
        }
    }

    /// Adds the cells' lumped masses (seed eq. 81–82, [`lump_element_mass`]:
    /// `int_n[c]`, `int_n2[c]` are cell c's ∫N_k, ∫N_k²) to the block;
    /// `heaviside_scale(c, k)`: the factors of the coupling and the mass of
    /// local node k's Heaviside function in cell c against ψ N_k's (1 but
    /// with the ramp).
    fn lump(
        &self,
        cells: &ElementCells,
        int_n: &[[f64; 10]],
        int_n2: &[[f64; 10]],
        heaviside_scale: impl Fn(usize, usize) -> (f64, f64),
        block: &mut ElementBlock,
        sink: &mut Sink<'_>,
    ) {
        let nn = self.mesh.kind.nodes();
        // Tet10: the cells of a side as one (their volumes and integrals
        // summed; the first one standing for them), so that the masses are
        // the side's, not those of the sub-tets the split happened to make.
        let groups = lumping_groups(self.mesh.kind, cells, int_n, int_n2);
        let volumes: Vec<f64> = groups.iter().map(|g| g.volume).collect();
        let (int_n, int_n2): (Vec<_>, Vec<_>) = groups.iter().map(|g| (g.int_n, g.int_n2)).unzip();
        let shares = lump_element_mass(self.mesh.kind, self.rho, &volumes, &int_n, &int_n2);
        for ((group, share), n) in groups.iter().zip(&shares).zip(&int_n) {
            let (c, cell) = (group.cell, &cells.cells[group.cell]);
            for k in 0..nn {
                sink.lumped(block, k, share[k]);
            }
            if self.mesh.kind == ElementKind::Tet10 {
                let slot = &mut block.lump_residual[usize::from(cell.side < 0)];
                for k in 0..nn {
                    slot[k] += share[k] - self.rho * n[k];
                }
            }
            for (j, &k) in cells.heaviside.iter().enumerate() {
                // (A Heaviside function h ψ N_k: mass ψ² and coupling ψ
                // times N_k's, times the factors of h, `heaviside_scale`.)
                let p = cells.psi(cell, k);
                let (coupling, mass) = heaviside_scale(c, k);
                sink.lumped(block, nn + j, p * p * mass * share[k]);
                sink.coupling(block, j, p * coupling * share[k]);
            }
        }
    }
}

/// The cells an element's mass is lumped over ([`Integrator::lump`]): the
/// first cell standing for them (its side, its index for the Heaviside
/// factors), their volume and ∫N_k, ∫N_k².
struct LumpingGroup {
    cell: usize,
    volume: f64,
    int_n: [f64; 10],
    int_n2: [f64; 10],
}

/// Tet10: one group a side (the cells of a side summed), since its HRZ
/// shares and their balancing ([`lump_element_mass`]) are not additive
/// over cells: lumped per sub-tet, the masses were those of the split the
/// element's node numbering made (a mesh numbered otherwise moved a damped
/// Tet10 scene's probes by up to 6.2e-7 of the largest; summed per side,
/// only what the side is counts). Tet4: one group a cell (its row sums
/// add up, and the ramp's factors `heaviside_scale` are per cell).
fn lumping_groups(
    kind: ElementKind,
    cells: &ElementCells,
    int_n: &[[f64; 10]],
    int_n2: &[[f64; 10]],
) -> Vec<LumpingGroup> {
    let mut groups: Vec<LumpingGroup> = Vec::new();
    for (c, cell) in cells.cells.iter().enumerate() {
        let same_side = groups
            .iter()
            .position(|g| kind == ElementKind::Tet10 && cells.cells[g.cell].side == cell.side);
        match same_side {
            Some(g) => {
                let g = &mut groups[g];
                g.volume += cell.volume;
                for k in 0..10 {
                    g.int_n[k] += int_n[c][k];
                    g.int_n2[k] += int_n2[c][k];
                }
            }
            None => groups.push(LumpingGroup {
                cell: c,
                volume: cell.volume,
                int_n: int_n[c],
                int_n2: int_n2[c],
            }),
        }
    }
    groups
}

/// Where an element's load and lumped mass go as they are integrated: the
/// global vectors (a build, so each DOF sums its terms in the same order as
/// one global loop), or the block's own (an update adds or removes whole blocks).
struct Sink<'g> {
    direct: Option<&'g mut Globals>,
    n_nodes: usize,
}

impl Sink<'_> {
    fn load(&mut self, block: &mut ElementBlock, a: usize, c: usize, value: f64) {
        match self.direct.as_deref_mut() {
            Some(g) => g.load[3 * block.shape_ids[a] as usize + c] += value,
            None => block.load[3 * a + c] += value,
        }
    }

    fn lumped(&mut self, block: &mut ElementBlock, a: usize, value: f64) {
        match self.direct.as_deref_mut() {
            Some(g) => {
                if let Some(l) = g.lumped.as_mut() {
                    l[block.shape_ids[a] as usize] += value;
                }
            }
            None => block.lumped[a] += value,
        }
    }

    /// Coupling of the block's `j`-th Heaviside shape function.
    fn coupling(&mut self, block: &mut ElementBlock, j: usize, value: f64) {
        let n_nodes = self.n_nodes;
        match self.direct.as_deref_mut() {
            Some(g) => {
                if let Some(cp) = g.coupling.as_mut() {
                    cp[block.shape_ids[block.heaviside_start + j] as usize - n_nodes] += value;
                }
            }
            None => block.coupling[j] += value,
        }
    }
}

/// The per-element flat arrays of a model, appended element by element.
struct FlatElements {
    elements: Vec<ElementData>,
    shape_ids: Vec<u32>,
    groups: Vec<Group>,
    grads: Vec<Vector3<f64>>,
    stiffness: Vec<f64>,
    group_element: Vec<u32>,
    scatter_len: usize,
}

impl FlatElements {
    fn with_capacity(n_elements: usize, n_shapes: usize) -> FlatElements {
        FlatElements {
            elements: Vec::with_capacity(n_elements),
            shape_ids: Vec::with_capacity(n_shapes),
            groups: Vec::with_capacity(n_elements),
            grads: Vec::with_capacity(n_shapes),
            stiffness: Vec::new(),
            group_element: Vec::with_capacity(n_elements),
            scatter_len: 0,
        }
    }

    /// Appends element `e`'s shape functions, groups, gradients and dense
    /// stiffness (`groups`' offsets relative to the first of `grads` and of
    /// `stiffness`).
    fn push(
        &mut self,
        e: usize,
        shape_ids: &[u32],
        groups: &[Group],
        grads: &[Vector3<f64>],
        stiffness: &[f64],
    ) {
        let m = shape_ids.len();
        let first = self.shape_ids.len();
        self.shape_ids.extend_from_slice(shape_ids);
        let group_start = self.groups.len();
        let offset = self.grads.len() as u32 - groups.first().map_or(0, |g| g.grads);
        let dense_first = groups
            .iter()
            .find(|g| g.is_dense())
            .map_or(0, |g| g.stiffness);
        let dense_offset = self.stiffness.len() as u32 - dense_first;
        self.groups.extend(groups.iter().map(|g| Group {
            weight: g.weight,
            grads: g.grads + offset,
            stiffness: if g.is_dense() {
                g.stiffness + dense_offset
            } else {
                NONE
            },
        }));
        self.grads.extend_from_slice(grads);
        self.stiffness.extend_from_slice(stiffness);
        self.group_element
            .extend(std::iter::repeat_n(e as u32, groups.len()));
        self.elements.push(ElementData {
            shapes: first..first + m,
            groups: group_start..self.groups.len(),
            scatter: self.scatter_len,
        });
        self.scatter_len += 9 * m * m;
    }

    fn push_block(&mut self, e: usize, block: &ElementBlock) {
        self.push(
            e,
            &block.shape_ids,
            &block.groups,
            &block.grads,
            &block.stiffness,
        );
    }
}

/// The global vectors the element blocks add into: load, lumped mass and coupling.
struct Globals {
    load: Vec<f64>,
    lumped: Option<Vec<f64>>,
    coupling: Option<Vec<f64>>,
}

impl Globals {
    fn new(n_shape: usize, cut: Option<&CutSetup>, need_mass: bool) -> Globals {
        let n_enriched = cut.map_or(0, |c| c.n_enriched);
        Globals {
            load: vec![0.0; 3 * n_shape],
            lumped: need_mass.then(|| vec![0.0; n_shape]),
            coupling: need_mass.then(|| vec![0.0; n_enriched]),
        }
    }

    /// Adds `sign` × the block's load and lumped mass; shape ids [`NONE`] are skipped.
    fn add_signed(&mut self, block: &ElementBlock, sign: f64, n_nodes: usize) {
        let ids = &block.shape_ids;
        for (a, f) in block.load.chunks_exact(3).enumerate() {
            if ids[a] == NONE {
                continue;
            }
            let s = ids[a] as usize;
            for c in 0..3 {
                self.load[3 * s + c] += sign * f[c];
            }
        }
        if let (Some(lumped), Some(coupling)) = (self.lumped.as_mut(), self.coupling.as_mut()) {
            for (a, &mass) in block.lumped.iter().enumerate() {
                if ids[a] != NONE {
                    lumped[ids[a] as usize] += sign * mass;
                }
            }
            for (j, &c) in block.coupling.iter().enumerate() {
                let s = ids[block.heaviside_start + j];
                if s != NONE {
                    coupling[s as usize - n_nodes] += sign * c;
                }
            }
        }
    }

    fn add(&mut self, block: &ElementBlock, n_nodes: usize) {
        self.add_signed(block, 1.0, n_nodes);
    }

    fn sub_mapped(&mut self, block: &ElementBlock, n_nodes: usize) {
        self.add_signed(block, -1.0, n_nodes);
    }
}

/// Step 3: global DOF → equation number, prescribed DOFs eliminated ([`NONE`]).
/// The enriched shape functions of a node, by kind: its Heaviside one and
/// its [`N_BRANCH`] branch functions (shape ids as [`Model::build`] numbers them).
fn enriched_shapes_of(n_nodes: usize, cut: &CutSetup, node: usize) -> impl Iterator<Item = usize> {
    let heaviside = cut.enriched[node].map(|j| n_nodes + j);
    let tip = cut.tip.get(node).copied().flatten();
    let first = tip.map(|t| n_nodes + cut.n_enriched + N_BRANCH * t);
    heaviside
        .into_iter()
        .chain(first.into_iter().flat_map(|f| f..f + N_BRANCH))
}

/// Enriched DOFs prescribed to zero at fixed nodes, where the Dirichlet
/// boundary needs it. The enrichment must vanish where the cut crosses a
/// Dirichlet boundary, or the body moves between its fixed nodes (a cut
/// reaching a clamped face would open there, and test functions that do not
/// vanish on the boundary make the discrete problem another one: the linear
/// field no longer solves the patch test with a cut crossing a symmetry
/// plane). With shifted enrichment a node's displacement is its standard
/// DOFs' on its own side (the prescribed value), and its Heaviside function
/// is non-zero only on the other side: on the boundary only where the cut
/// crosses it ([`heaviside_held`]). Where it does not, that function is the
/// material beyond the cut within the node's elements, which the boundary
/// does not hold: prescribing it there clamped that material too (a part
/// freed inside the body within one element of a clamped face did not fall
/// but vibrated about its place, found by a fuzz of closed surfaces through
/// the CLI). Tip functions vary along the boundary beside the node: all of
/// them are prescribed at a fixed node. Entries for enriched shapes of
/// `fixed` pass through [`number_dofs`] unchanged (the first entry of a DOF
/// wins).
fn enriched_fixes(
    mesh: &TetMesh,
    cut: &CutSetup,
    fixed: &[(usize, [Option<f64>; 3])],
) -> Vec<(usize, [Option<f64>; 3])> {
    let n_nodes = mesh.n_nodes();
    let mut is_fixed = vec![[false; 3]; n_nodes];
    for &(node, comps) in fixed.iter().filter(|(n, _)| *n < n_nodes) {
        for (f, v) in is_fixed[node].iter_mut().zip(comps) {
            *f |= v.is_some();
        }
    }
    let held = heaviside_held(mesh, cut, |i, c| is_fixed[i][c]);
    let mut out = Vec::new();
    for &(node, comps) in fixed.iter().filter(|(n, _)| *n < n_nodes) {
        if let Some(j) = cut.enriched[node] {
            let h = held[node];
            out.push((n_nodes + j, std::array::from_fn(|c| h[c].then_some(0.0))));
        }
        if let Some(t) = cut.tip.get(node).copied().flatten() {
            let zero = comps.map(|v| v.map(|_| 0.0));
            let first = n_nodes + cut.n_enriched + N_BRANCH * t;
            out.extend((first..first + N_BRANCH).map(|s| (s, zero)));
        }
    }
    out
}

/// Per node, the components of its Heaviside function that a Dirichlet
/// boundary holds at zero: in each cut element whose fixed vertices (those
/// with component c prescribed, `fixed(i, c)`) span an edge the cut
/// crosses (its vertices on either side, φ_i φ_k < 0, the crossing behind
/// the front where a tip front passes through the element), component c of
/// every enriched node of the element with c prescribed. The prescribed
/// nodes of an element span the Dirichlet boundary there (an edge, a face),
/// and the other side of each node's Heaviside function reaches it only
/// through that crossing.
fn heaviside_held(
    mesh: &TetMesh,
    cut: &CutSetup,
    fixed: impl Fn(usize, usize) -> bool,
) -> Vec<[bool; 3]> {
    let n_nodes = mesh.n_nodes();
    let mut held = vec![[false; 3]; n_nodes];
    for (e, element) in cut.elements.iter().enumerate() {
        let ElementCut::Cut { partial, .. } = element else {
            continue;
        };
        let conn = mesh.element(e);
        if !conn.iter().any(|&i| cut.enriched[i].is_some()) {
            continue;
        }
        let v = mesh.vertices(e);
        // A tip front inside the element: only crossings behind it count.
        let tip_front = *partial && !cut.front_level.is_empty();
        let crossed = |i: usize, k: usize| {
            let (fi, fk) = (cut.phi[i], cut.phi[k]);
            if fi * fk >= 0.0 {
                return false;
            }
            if !tip_front {
                return true;
            }
            let t = fi / (fi - fk);
            let (gi, gk) = (cut.front_level[i], cut.front_level[k]);
            gi + t * (gk - gi) < 0.0
        };
        for c in 0..3 {
            let spans_crossing = (0..4).any(|a| {
                (a + 1..4).any(|b| fixed(v[a], c) && fixed(v[b], c) && crossed(v[a], v[b]))
            });
            if spans_crossing {
                for &i in conn {
                    if cut.enriched[i].is_some() && fixed(i, c) {
                        held[i][c] = true;
                    }
                }
            }
        }
    }
    held
}

/// Every branch function of a tip node.
const ALL_BRANCHES: [usize; N_BRANCH] = [0, 1, 2, 3];

/// The branch functions the elements of tip node `i` hold: on the ramp's
/// ring [`ring_free_branches`], elsewhere all four.
pub fn tip_branches(kind: ElementKind, cut: &CutSetup, i: usize) -> &'static [usize] {
    match cut.ramp.get(i) {
        Some(false) => ring_free_branches(kind),
        _ => &ALL_BRANCHES,
    }
}

/// The branch functions a ring node (a tip node outside I: a blending
/// element's other vertex, R = 0 there) carries with the ramp; the others
/// are prescribed to zero ([`ramp_fixes`]) and no element holds them.
///
/// Tet4: F₀ and F₁. On the exact near-front field (geometric R = 0.2,
/// `tests/front.rs blending_measure`) its L2 error is that of all four
/// (9.23e-4 against 9.17e-4 at n = 24), energy 0.042 against 0.039, at
/// fewer DOFs (63969 against 70000), and
/// the stress suite's Jacobi-scaled condition estimate of the `front-near`
/// rows with R = 0.3 3e3–2e4 (no ramp: 2e3–2e4; all four, one node's F₀,
/// F₁ prescribed: 1e8–1e9).
///
/// Tet10: all four (the ramp is an option there, not a case's default:
/// [`crate::cut::Blending::for_cut`]). Without F₃ its energy error was
/// 1.03–1.47× above no ramp at n = 3 … 8 (L2 6.5e-3 against 4.6e-3 at
/// n = 3), without F₂ and F₃ worse; with all four it is 1.1–1.3× below,
/// but only the point gauge pins their dependence.
pub fn ring_free_branches(kind: ElementKind) -> &'static [usize] {
    match kind {
        ElementKind::Tet4 => &[0, 1],
        ElementKind::Tet10 => &ALL_BRANCHES,
    }
}

/// The tip DOFs the ramp ([`crate::cut::Blending::Ramp`]) holds at zero,
/// per shape function and component (empty without the ramp).
///
/// With the ramp the tip functions are linearly dependent. Of (φ, ψ) the
/// four branch functions satisfy φ (F₀ − F₃) + ψ F₂ = 0 and
/// φ (F₁ − F₂) − ψ F₃ = 0 (φ F₀ = r F₂, ψ F₀ = r (F₃ − F₀), φ F₁ = r F₃,
/// ψ F₁ = r (F₁ − F₂)), and φ, ψ are interpolated from the vertices. Every
/// vertex of an element holding a node of I carries λ_k R (F − F(x_k)) with
/// the ramp, so the tip DOFs a_k = α c₁(k) + β c₂(k), c₁ = (φ_k, 0, ψ_k,
/// −φ_k) and c₂ = (0, φ_k, −φ_k, −ψ_k), of a connected region of tip nodes
/// make the zero field, in each component: a body whose region's tip DOFs
/// are not pinned is singular (the seed's beam at L0: eigenvalue 1e-13 of a
/// matrix whose largest diagonal is 2e4). Without the ramp the blending
/// elements, whose other vertices carry no tip functions, break the
/// identity.
///
/// The ring nodes (tip nodes outside I) carry only
/// [`ring_free_branches`]: their other branch functions are held at zero
/// in every component, which pins α and β along the region's outer
/// surface as the blending elements do without the ramp (F₂, F₃ of one
/// ring node with (φ, ψ) ≠ 0 pin both: their rows (ψ, −φ), (−φ, −ψ) are
/// independent; F₃ alone needs two nodes with independent (φ, ψ)).
/// Prescribing instead F₀ and F₁ of one node per region (a point) left the
/// combinations that vanish there but nearly nowhere else: the stress
/// suite's condition estimates rose from 2e3–2e4 to 1e8–1e9 (Jacobi-scaled).
/// A region whose ring pins do not pin both (no ring, or its nodes' (φ, ψ)
/// parallel) takes that point gauge too, per component in which no tip
/// node with (φ, ψ) ≠ 0 is prescribed (`prescribed(i, c)`): F₀ and F₁ of
/// its node with the largest |φ|; both combinations have φ_m there.
fn ramp_fixes(
    mesh: &TetMesh,
    cut: &CutSetup,
    prescribed: impl Fn(usize, usize) -> bool,
) -> Vec<(usize, [bool; 3])> {
    if cut.ramp.is_empty() || cut.n_tip == 0 {
        return Vec::new();
    }
    let n_nodes = mesh.n_nodes();
    let first = n_nodes + cut.n_enriched;
    let kept = ring_free_branches(mesh.kind);
    let held: Vec<usize> = (0..N_BRANCH).filter(|b| !kept.contains(b)).collect();
    let level = |i: usize| (cut.phi[i], cut.front_level.get(i).copied().unwrap_or(0.0));
    // Regions: tip nodes joined through the elements holding tip functions.
    let mut parent: Vec<usize> = (0..n_nodes).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    for e in 0..mesh.n_elements() {
        let v = mesh.vertices(e);
        if !cut.holds_tip(mesh.element(e)) {
            continue;
        }
        let tips: Vec<usize> = v.into_iter().filter(|&i| cut.tip[i].is_some()).collect();
        for w in tips.windows(2) {
            let (a, b) = (root(&mut parent, w[0]), root(&mut parent, w[1]));
            parent[a] = b;
        }
    }
    struct Region {
        /// Components prescribed at a tip node off the front.
        pinned: [bool; 3],
        /// The node of largest |φ|.
        largest: Option<usize>,
        /// Σ ρ ρᵀ over the ring pins' rows ρ = (c₁(k)_b, c₂(k)_b): what
        /// they pin of (α, β).
        gram: [f64; 3],
    }
    let mut regions: std::collections::BTreeMap<usize, Region> = std::collections::BTreeMap::new();
    let mut out = Vec::new();
    for i in (0..n_nodes).filter(|&i| cut.tip[i].is_some()) {
        let r = root(&mut parent, i);
        let region = regions.entry(r).or_insert(Region {
            pinned: [false; 3],
            largest: None,
            gram: [0.0; 3],
        });
        let (phi, psi) = level(i);
        let off_front = phi != 0.0 || psi != 0.0;
        for (c, p) in region.pinned.iter_mut().enumerate() {
            *p |= off_front && prescribed(i, c);
        }
        if phi != 0.0 && region.largest.is_none_or(|m| phi.abs() > cut.phi[m].abs()) {
            region.largest = Some(i);
        }
        if !cut.ramp[i] {
            let t = cut.tip[i].expect("a tip node");
            for &b in &held {
                let row = [[phi, 0.0], [0.0, phi], [psi, -phi], [-phi, -psi]][b];
                region.gram[0] += row[0] * row[0];
                region.gram[1] += row[0] * row[1];
                region.gram[2] += row[1] * row[1];
                out.push((first + N_BRANCH * t + b, [true; 3]));
            }
        }
    }
    for region in regions.values() {
        // Both of (α, β) pinned: the Gram's smaller eigenvalue is not round-off of its larger.
        let [a, b, d] = region.gram;
        let (mean, spread) = (0.5 * (a + d), (0.25 * (a - d) * (a - d) + b * b).sqrt());
        if mean - spread > 1e-8 * (mean + spread) {
            continue;
        }
        let (Some(m), false) = (region.largest, region.pinned.iter().all(|&p| p)) else {
            continue;
        };
        let comps = region.pinned.map(|p| !p);
        let base = first + N_BRANCH * cut.tip[m].expect("a tip node");
        out.push((base, comps));
        out.push((base + 1, comps));
    }
    out
}

fn number_dofs(
    n_shape: usize,
    fixed: &[(usize, [Option<f64>; 3])],
) -> (Vec<u32>, Vec<Prescribed>, usize) {
    let mut equation = vec![0u32; 3 * n_shape];
    let mut prescribed = Vec::new();
    for &(node, comps) in fixed {
        for (c, v) in comps.iter().enumerate() {
            if let Some(v) = v {
                let dof = 3 * node + c;
                if equation[dof] != NONE {
                    equation[dof] = NONE;
                    prescribed.push(Prescribed { dof, value: *v });
                }
            }
        }
    }
    let mut n_free = 0usize;
    for eq in equation.iter_mut() {
        if *eq != NONE {
            *eq = n_free as u32;
            n_free += 1;
        }
    }
    (equation, prescribed, n_free)
}

/// Writes the CSC positions of element `el`'s (3m)² entries into `scatter`
/// (`dofs`: scratch for its equations).
fn element_scatter(
    el: &ElementData,
    shapes: &[u32],
    equation: &[u32],
    pattern: &Pattern,
    scatter: &mut [u32],
    dofs: &mut Vec<u32>,
) {
    dofs.clear();
    dofs.extend(
        shapes
            .iter()
            .flat_map(|&s| (0..3).map(move |c| equation[3 * s as usize + c])),
    );
    let n = dofs.len();
    for (q, &c) in dofs.iter().enumerate() {
        let column =
            (c != NONE).then(|| pattern.col_ptr[c as usize]..pattern.col_ptr[c as usize + 1]);
        // The next component of the same shape function (equation c − 1 before
        // it): its column holds the same rows less the diagonal c − 1, so a
        // row's position there is its position in column c − 1 shifted.
        let shift = (q % 3 != 0 && c != NONE && c > 0 && dofs[q - 1] == c - 1).then(|| {
            pattern.col_ptr[c as usize] as isize - pattern.col_ptr[c as usize - 1] as isize - 1
        });
        // A shape function's components have consecutive equations, so the
        // next row is most often the next entry of the column.
        let mut last: Option<(u32, usize)> = None;
        for (p, &r) in dofs.iter().enumerate() {
            let at = el.scatter + p * n + q;
            let Some(col) = column.clone().filter(|_| r != NONE && r >= c) else {
                scatter[at] = NONE;
                continue;
            };
            let shifted = shift.and_then(|sh| {
                let before = scatter[at - 1];
                let pos = (before as isize + sh) as usize;
                (before != NONE && col.contains(&pos) && pattern.row_idx[pos] == r as usize)
                    .then_some(pos)
            });
            let pos = match (shifted, last) {
                (Some(pos), _) => pos,
                (None, Some((lr, lp)))
                    if r == lr + 1 && lp + 1 < col.end && pattern.row_idx[lp + 1] == r as usize =>
                {
                    lp + 1
                }
                _ => {
                    col.start
                        + pattern.row_idx[col.clone()]
                            .binary_search(&(r as usize))
                            .expect("pattern holds every element entry")
                }
            };
            scatter[at] = pos as u32;
            last = Some((r, pos));
        }
    }
}

/// Step 4: the lower-triangular pattern of the free system and each
/// element's scatter map. The pattern is built per shape function: its
/// neighbours (the shape functions it shares an element with, found through
/// the shape → element incidence with a marker) give the rows of its
/// components' columns, so no element entry is pushed and sorted twice.
fn element_pattern(flat: &FlatElements, equation: &[u32], n_free: usize) -> Pattern {
    let n_shape = equation.len() / 3;
    // Shape function → elements (CSR).
    let mut start = vec![0usize; n_shape + 1];
    for el in &flat.elements {
        for &s in &flat.shape_ids[el.shapes.clone()] {
            start[s as usize + 1] += 1;
        }
    }
    for s in 0..n_shape {
        start[s + 1] += start[s];
    }
    let mut fill = start.clone();
    let mut incidence = vec![0u32; start[n_shape]];
    for (e, el) in flat.elements.iter().enumerate() {
        for &s in &flat.shape_ids[el.shapes.clone()] {
            incidence[fill[s as usize]] = e as u32;
            fill[s as usize] += 1;
        }
    }
    // The DOF of each equation (columns come in equation order).
    let mut dof_of = vec![0u32; n_free];
    for (dof, &eq) in equation.iter().enumerate() {
        if eq != NONE {
            dof_of[eq as usize] = dof as u32;
        }
    }
    let mut mark = vec![u32::MAX; n_shape];
    let mut neighbours: Vec<u32> = Vec::new();
    let mut neighbours_of = u32::MAX;
    let mut col_ptr = Vec::with_capacity(n_free + 1);
    let mut row_idx = Vec::new();
    col_ptr.push(0);
    for c in 0..n_free {
        let s = dof_of[c] / 3;
        if s != neighbours_of {
            neighbours.clear();
            for &e in &incidence[start[s as usize]..start[s as usize + 1]] {
                let el = &flat.elements[e as usize];
                for &t in &flat.shape_ids[el.shapes.clone()] {
                    if mark[t as usize] != s {
                        mark[t as usize] = s;
                        neighbours.push(t);
                    }
                }
            }
            neighbours_of = s;
        }
        let first = row_idx.len();
        for &t in &neighbours {
            for k in 0..3 {
                let r = equation[3 * t as usize + k];
                if r != NONE && r as usize >= c {
                    row_idx.push(r as usize);
                }
            }
        }
        row_idx[first..].sort_unstable();
        col_ptr.push(row_idx.len());
    }
    Pattern {
        n: n_free,
        col_ptr,
        row_idx,
    }
}

/// Each element's scatter map into `pattern` ([`element_scatter`]).
fn scatters(flat: &FlatElements, equation: &[u32], pattern: &Pattern) -> Vec<u32> {
    let mut scatter = vec![NONE; flat.scatter_len];
    let mut dofs = Vec::new();
    for el in &flat.elements {
        element_scatter(
            el,
            &flat.shape_ids[el.shapes.clone()],
            equation,
            pattern,
            &mut scatter,
            &mut dofs,
        );
    }
    scatter
}

/// Adds `sign` × an element's consistent mass `me` (m × m, per shape
/// function; the same for the three components) to the values on the pattern.
fn add_element_mass(el: &ElementData, me: &[f64], scatter: &[u32], values: &mut [f64], sign: f64) {
    let m = el.shapes.len();
    for a in 0..m {
        for b in 0..m {
            for c in 0..3 {
                let pos = scatter[el.scatter + (3 * a + c) * 3 * m + 3 * b + c];
                if pos != NONE {
                    values[pos as usize] += sign * me[a * m + b];
                }
            }
        }
    }
}

/// Tet10 mid-nodes next to tip-enriched vertices: their edge (for
/// [`Model::node_displacement`]); empty otherwise.
fn mid_edges(mesh: &TetMesh, cut: Option<&CutSetup>) -> Vec<Option<[u32; 2]>> {
    let mut mid_edge = Vec::new();
    if let (ElementKind::Tet10, Some(c)) = (mesh.kind, cut) {
        if c.n_tip > 0 {
            mid_edge = vec![None; mesh.n_nodes()];
            for e in 0..mesh.n_elements() {
                let conn = mesh.element(e);
                for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                    let (a, b) = (conn[a], conn[b]);
                    if c.edge_tip_weight(a, b, a) > 0.0 || c.edge_tip_weight(a, b, b) > 0.0 {
                        mid_edge[conn[4 + k]] = Some([a as u32, b as u32]);
                    }
                }
            }
        }
    }
    mid_edge
}

impl Model {
    /// Parts of the body that a static solve cannot hold, described for an
    /// error message: held by no Dirichlet condition, or by prescribed
    /// components that leave a rigid motion free (a face fixed in x and y
    /// only lets its part slide in z; a single fixed node or a line of them
    /// lets it turn). Such a stiffness is singular, and its factorisation
    /// may still pass on round-off pivots.
    ///
    /// Regions are (element, side) pairs; two regions that share a node and see
    /// the same DOFs there (the same ψ of its enrichment) belong to one part, so
    /// a cut that separates the body makes two parts. A part's prescribed
    /// DOFs are the prescribed components of the nodes where one of its
    /// regions sees the standard DOFs alone (ψ = 0), and those where it sees
    /// a node's standard and Heaviside DOFs both prescribed (u + ψ a = 0 at
    /// the node: where the cut crosses a fixed boundary, [`enriched_fixes`]).
    pub fn free_parts(&self) -> Vec<String> {
        let mesh = &self.mesh;
        let (regions, parts) = self.parts();
        let mut free: Vec<String> = parts
            .into_iter()
            .filter_map(|part| {
                let n = part.regions.len();
                let c = part.regions.iter().fold(Vector3::zeros(), |s, &r| {
                    s + mesh
                        .vertex_points(regions[r].0)
                        .iter()
                        .fold(Vector3::zeros(), |s, p| s + p.coords)
                        / 4.0
                }) / n as f64;
                let at = format!(
                    "{n} element regions around ({:.4}, {:.4}, {:.4})",
                    c.x, c.y, c.z
                );
                let mut nodes = part.held;
                if nodes.is_empty() {
                    return Some(format!("{at} touch no [[fix]]"));
                }
                nodes.sort_unstable();
                nodes.dedup();
                self.free_rigid_motion(&nodes).map(|motion| {
                    format!("{at} are held by [[fix]] components that leave them free to {motion}")
                })
            })
            .collect();
        free.sort();
        free
    }

    /// The gravity load for the lumped mass: [`Model::load`] with each part
    /// that touches no Dirichlet boundary loaded by its lumped mass times g
    /// instead of ρ g ∫ φ_a, so that it falls with g exactly. The two
    /// differ on Tet10 only (HRZ masses, [`crate::mass::lump_cell_mass`];
    /// Tet4's lumped mass is the row sum, ρ ∫ N_k): there, under the
    /// consistent load, a part that floats free strained as it fell (its
    /// nodes up to 8e-2 off ½ g t² for a part of a few coarse elements,
    /// 24 % on a soft bar), a self-equilibrated load of its own weight. Parts held by
    /// a boundary keep the consistent load, so that a damped dynamic scene
    /// settles on the static solution. Tip functions in a floating part
    /// (another cut's front inside a fragment) take no gravity load: their
    /// lumped mass is diagonal, with no coupling to the standard DOFs, so the
    /// lumped mass times the part's translation g is zero on them, and their
    /// consistent load ρ g ∫ N_i (F_k − F_k(x_i)) pushed the fragment's nodes
    /// off ½ g t² (1e-5 of it, Tet4). `None` where nothing changes (Tet4
    /// without tip functions, no part floats free, no gravity, a body force
    /// beyond gravity, or no lumped mass built).
    pub fn lumped_load(&self) -> Option<Vec<f64>> {
        let tips = self.cut.as_ref().is_some_and(|c| c.n_tip > 0);
        if (self.lump_residual.is_empty() && !tips) || self.body_force || self.lumped_mass.is_none()
        {
            return None;
        }
        let g = self.gravity?;
        let (regions, parts) = self.parts();
        let floating: Vec<(usize, i8)> = parts
            .into_iter()
            .filter(|p| p.held.is_empty())
            .flat_map(|p| p.regions.into_iter().map(|r| regions[r]))
            .collect();
        if floating.is_empty() {
            return None;
        }
        let n_nodes = self.mesh.n_nodes();
        let mut load = self.load.clone();
        for (e, side) in floating {
            if let Some(c) = self.cut.as_ref().filter(|_| tips) {
                let first = n_nodes + c.n_enriched;
                for &node in self.mesh.element(e) {
                    if let Some(t) = c.tip[node] {
                        let dofs = 3 * (first + N_BRANCH * t)..3 * (first + N_BRANCH * (t + 1));
                        load[dofs].fill(0.0);
                    }
                }
            }
            let Some(residual) = self.lump_residual.get(e).map(|r| &r[usize::from(side < 0)])
            else {
                continue;
            };
            for (k, &node) in self.mesh.element(e).iter().enumerate() {
                let r = residual[k];
                for c in 0..3 {
                    load[3 * node + c] += r * g[c];
                }
                let enriched = self.cut.as_ref().and_then(|c| {
                    let p = psi(side, c.node_side[node]);
                    c.enriched[node]
                        .filter(|_| side != 0 && p != 0.0)
                        .map(|j| (j, p))
                });
                if let Some((j, p)) = enriched {
                    for c in 0..3 {
                        load[3 * (n_nodes + j) + c] += p * r * g[c];
                    }
                }
            }
        }
        Some(load)
    }

    /// How many parts touch no Dirichlet boundary ([`Model::lumped_load`]).
    pub fn floating_parts(&self) -> usize {
        self.parts().1.iter().filter(|p| p.held.is_empty()).count()
    }

    /// The body's regions ((element, side) pairs) and its parts: the
    /// regions joined through the nodes where they see the same DOFs, with
    /// the nodes (and components) where each part is held ([`Model::free_parts`]).
    fn parts(&self) -> (Vec<(usize, i8)>, Vec<Part>) {
        let mesh = &self.mesh;
        let (regions, mut parent) = regions_joined(mesh, self.cut.as_ref());
        // Per region: the nodes where it is held, with the components.
        let mut held: Vec<Vec<(usize, [bool; 3])>> = vec![Vec::new(); regions.len()];
        let n_nodes = mesh.n_nodes();
        let fixed = |dof: usize| self.equation[dof] == NONE;
        for (r, &(e, side)) in regions.iter().enumerate() {
            for &node in mesh.element(e) {
                let enriched = self.cut.as_ref().and_then(|c| c.enriched[node]);
                let p = match (&self.cut, enriched) {
                    (Some(c), Some(_)) if side != 0 => psi(side, c.node_side[node]) as i8,
                    _ => 0,
                };
                let mask: [bool; 3] = std::array::from_fn(|c| {
                    fixed(3 * node + c)
                        && (p == 0 || enriched.is_some_and(|j| fixed(3 * (n_nodes + j) + c)))
                });
                if mask.iter().any(|&m| m) {
                    held[r].push((node, mask));
                }
            }
        }
        // Parts in the order of their first region.
        let mut part_of_root = vec![usize::MAX; regions.len()];
        let mut parts: Vec<Part> = Vec::new();
        for (r, nodes) in held.into_iter().enumerate() {
            let root = find_root(&mut parent, r);
            if part_of_root[root] == usize::MAX {
                part_of_root[root] = parts.len();
                parts.push(Part {
                    regions: Vec::new(),
                    held: Vec::new(),
                });
            }
            let part = &mut parts[part_of_root[root]];
            part.regions.push(r);
            part.held.extend(nodes);
        }
        (regions, parts)
    }

    /// The rigid motion that the prescribed components of `nodes` leave
    /// free, described ("translate along (0, 0, 1)"), or `None` when they
    /// hold all six. Each prescribed component c of node i constrains the
    /// rigid motions u(X) = t + ω × (X − X̄) by u_c(X_i) = 0: a row of a
    /// 6-column matrix A (positions centred on and scaled by the nodes'
    /// spread, so A is O(1)); a motion is free where AᵀA has an eigenvalue
    /// under 1e-10 of its largest.
    fn free_rigid_motion(&self, nodes: &[(usize, [bool; 3])]) -> Option<String> {
        let points = || nodes.iter().map(|&(i, _)| self.mesh.nodes[i].coords);
        let centre = points().sum::<Vector3<f64>>() / nodes.len() as f64;
        let spread = points().map(|x| (x - centre).norm()).fold(0.0, f64::max);
        let mut gram = nalgebra::Matrix6::<f64>::zeros();
        for &(i, held) in nodes {
            let y = if spread > 0.0 {
                (self.mesh.nodes[i].coords - centre) / spread
            } else {
                Vector3::zeros()
            };
            for c in (0..3).filter(|&c| held[c]) {
                let mut a = nalgebra::Vector6::<f64>::zeros();
                a[c] = 1.0;
                for k in 0..3 {
                    a[3 + k] = Vector3::ith(k, 1.0).cross(&y)[c];
                }
                gram += a * a.transpose();
            }
        }
        let eig = nalgebra::SymmetricEigen::new(gram);
        let largest = eig.eigenvalues.max();
        let (k, smallest) = eig.eigenvalues.argmin();
        if smallest > 1e-10 * largest {
            return None;
        }
        let v = eig.eigenvectors.column(k);
        let (t, w) = (
            Vector3::new(v[0], v[1], v[2]),
            Vector3::new(v[3], v[4], v[5]),
        );
        let unit = |x: Vector3<f64>| {
            // Largest component positive; rounded, + 0 (no "-0.000").
            let x = x / x.norm();
            let x = if x.x + x.y + x.z < 0.0 { -x } else { x };
            let x = x.map(|v| (v * 1e3).round() / 1e3 + 0.0);
            format!("({:.3}, {:.3}, {:.3})", x.x, x.y, x.z)
        };
        Some(if w.norm() <= 1e-6 {
            format!("translate along {}", unit(t))
        } else {
            format!("turn about an axis along {}", unit(w))
        })
    }
}

// ---------------------------------------------------------------------------
// A cut event: the model of a grown cut from the model of the old one.

/// Per element, whether a side of it under [`SMALL_CUT_SIDE`] of its volume
/// takes the rotation of its other side ([`Integrator::standard_block`]):
/// for corotational Tet10 with a rotation per point, where the element's
/// two sides lie in one part ([`sides_in_one_part`]); `None` elsewhere
/// (linear groups do not rotate; a cut Tet4 side is one group already).
fn small_side_rotation(
    mesh: &TetMesh,
    cut: Option<&CutSetup>,
    formulation: Formulation,
    integration: Integration,
) -> Option<Vec<bool>> {
    let rotates = formulation == Formulation::Corotational
        && mesh.kind == ElementKind::Tet10
        && integration == Integration::Grouped;
    cut.filter(|_| rotates).map(|c| sides_in_one_part(mesh, c))
}

/// Per element: whether it is cut and its two sides lie in one part of the
/// body (the cut ends somewhere and the material goes round it), so that
/// one side may take the other's rotation without joining two parts.
fn sides_in_one_part(mesh: &TetMesh, cut: &CutSetup) -> Vec<bool> {
    let (regions, mut parent) = regions_joined(mesh, Some(cut));
    let mut joined = vec![false; mesh.n_elements()];
    for r in 1..regions.len() {
        let ((e, side), (e_prev, side_prev)) = (regions[r], regions[r - 1]);
        if e == e_prev && side == -1 && side_prev == 1 {
            joined[e] = find_root(&mut parent, r) == find_root(&mut parent, r - 1);
        }
    }
    joined
}

/// A part of the body ([`Model::parts`]): its regions (indices into the
/// region list) and the nodes, with components, where it is held.
struct Part {
    regions: Vec<usize>,
    held: Vec<(usize, [bool; 3])>,
}

/// How [`Model::update_cut_mapped`] maps the old model onto the new one.
#[derive(Debug, Clone)]
pub struct CutUpdate {
    /// The elements integrated again (ascending); the others' blocks are the old ones.
    pub changed: Vec<usize>,
    /// Old pattern position → new one ([`NONE`]: the entry is gone).
    pub position: Vec<u32>,
    /// Old free equation → new one ([`NONE`]: dropped).
    pub equation: Vec<u32>,
}

impl CutUpdate {
    /// Whether every old free equation keeps its number and none is new
    /// (`n_free` the new model's): a front moving inside the elements that
    /// hold its branch functions.
    pub fn keeps_every_equation(&self, n_free: usize) -> bool {
        self.equation.len() == n_free
            && self
                .equation
                .iter()
                .enumerate()
                .all(|(i, &e)| e as usize == i)
    }
}

/// What [`Model::update_cut`] kept and recomputed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UpdateStats {
    /// Elements integrated again (their cut, enrichment or front changed).
    pub changed_elements: usize,
    /// Free equations appended, and old ones dropped (tip → Heaviside).
    pub new_equations: usize,
    pub dropped_equations: usize,
}

/// Whether element `e` has the same shape functions and integration cells
/// under the cut set-ups `a` and `b` (its block of the model is then the same):
/// the same classification and sub-tets, the same Heaviside-enriched nodes
/// on the same sides, the same tip-enriched nodes and, where it holds one,
/// the same level sets at its nodes.
pub fn same_element_model(
    mesh: &TetMesh,
    a: Option<&CutSetup>,
    b: Option<&CutSetup>,
    e: usize,
) -> bool {
    let conn = mesh.element(e);
    let uncut = ElementCut::Uncut;
    let (ea, eb) = (
        a.map_or(&uncut, |c| &c.elements[e]),
        b.map_or(&uncut, |c| &c.elements[e]),
    );
    if !same_element_cut(ea, eb) {
        return false;
    }
    let tip = |c: Option<&CutSetup>, i: usize| {
        c.is_some_and(|c| c.tip.get(i).copied().flatten().is_some())
    };
    let has_tip = |c: Option<&CutSetup>| c.is_some_and(|c| c.holds_tip(conn));
    let ramp = |c: Option<&CutSetup>, i: usize| c.map_or(1.0, |c| c.ramp_at(i));
    let (ta, tb) = (has_tip(a), has_tip(b));
    if ta != tb {
        return false;
    }
    if matches!(ea, ElementCut::Uncut) && !ta {
        // Its shape functions are its nodes' whatever the enrichment around it.
        return true;
    }
    let enriched = |c: Option<&CutSetup>, i: usize| c.is_some_and(|c| c.enriched[i].is_some());
    let side = |c: Option<&CutSetup>, i: usize| c.map_or(0, |c| c.node_side[i]);
    for &i in conn {
        if enriched(a, i) != enriched(b, i)
            || (enriched(a, i) && side(a, i) != side(b, i))
            || tip(a, i) != tip(b, i)
            || ramp(a, i) != ramp(b, i)
        {
            return false;
        }
    }
    if ta {
        let (Some(a), Some(b)) = (a, b) else {
            return false;
        };
        let level = |c: &CutSetup, i: usize| {
            (
                c.phi[i].to_bits(),
                c.front_level.get(i).map(|x| x.to_bits()),
            )
        };
        if conn
            .iter()
            .any(|&i| level(a, i) != level(b, i) || a.node_side[i] != b.node_side[i])
            || a.tip_levels.get(&e) != b.tip_levels.get(&e)
        {
            return false;
        }
    }
    true
}

/// Whether two element classifications are the same, sub-tets bit for bit.
pub fn same_element_cut(a: &ElementCut, b: &ElementCut) -> bool {
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

/// Shape id in `new` of each shape function of `old` (the same node, the
/// same kind of enrichment, the same branch), [`NONE`] where it is gone.
fn shape_map(
    n_nodes: usize,
    old: Option<&CutSetup>,
    new: Option<&CutSetup>,
    n_old: usize,
) -> Vec<u32> {
    let mut map = vec![NONE; n_old];
    for (i, m) in map.iter_mut().enumerate().take(n_nodes) {
        *m = i as u32;
    }
    let (Some(o), Some(n)) = (old, new) else {
        return map;
    };
    for i in 0..n_nodes {
        if let (Some(jo), Some(jn)) = (o.enriched[i], n.enriched[i]) {
            map[n_nodes + jo] = (n_nodes + jn) as u32;
        }
        if let (Some(to), Some(tn)) = (
            o.tip.get(i).copied().flatten(),
            n.tip.get(i).copied().flatten(),
        ) {
            for b in 0..N_BRANCH {
                map[n_nodes + o.n_enriched + N_BRANCH * to + b] =
                    (n_nodes + n.n_enriched + N_BRANCH * tn + b) as u32;
            }
        }
    }
    map
}

impl Model {
    /// The model of the same mesh, fixes and loads with the cut set-up
    /// `cut` in place of its own: a cut event of a progressive cut.
    ///
    /// Only the elements whose shape functions or cells changed
    /// ([`same_element_model`]: newly cut or touched, crossed by the moved
    /// front, holding a node whose enrichment changed) are integrated again;
    /// the others keep their groups and gradients (the standard block K_uu of
    /// an element does not change when it is cut: METHODS.md, "Blades").
    /// Loads, lumped and consistent mass are the old ones with the changed
    /// elements' old contributions taken out and their new ones added. The
    /// shape functions are numbered as [`Model::build`] numbers them, so
    /// [`crate::blade::map_state`] applies; the *equations* of DOFs that
    /// exist before and after keep their numbers (compacted in order where
    /// DOFs disappear), new ones are appended, and the pattern is the old
    /// one (entries of gone DOFs left out) with the changed elements'
    /// entries added. It equals a full build up to round-off (the test
    /// `incremental_update_equals_a_full_build_at_every_event`), except that
    /// the pattern may keep entries a changed element no longer couples
    /// (zero values).
    ///
    /// A model built with a body force beyond gravity cannot be updated (it
    /// does not keep the function): [`ModelError::BodyForceUpdate`].
    pub fn update_cut(&self, cut: Option<CutSetup>) -> Result<(Model, UpdateStats), ModelError> {
        self.update_cut_mapped(cut)
            .map(|(model, stats, _)| (model, stats))
    }

    /// [`Model::update_cut`] with the map from the old model to the new
    /// one: what a cut event's caller needs to carry matrices over the
    /// event instead of assembling them again.
    pub fn update_cut_mapped(
        &self,
        cut: Option<CutSetup>,
    ) -> Result<(Model, UpdateStats, CutUpdate), ModelError> {
        self.update_cut_mapped_with(cut, Parallelism::SEQUENTIAL)
    }

    /// [`Model::update_cut_mapped`] with the changed elements integrated on
    /// `parallelism`'s threads (the same model whatever their number: each
    /// element's blocks are computed alone and added in element order).
    pub fn update_cut_mapped_with(
        &self,
        cut: Option<CutSetup>,
        parallelism: Parallelism,
    ) -> Result<(Model, UpdateStats, CutUpdate), ModelError> {
        self.update_cut_inner(cut, parallelism, None)
            .map(|(model, stats, update, _)| (model, stats, update))
    }

    /// [`Model::update_cut_mapped_with`] that also integrates, for a cut
    /// event's projection of `state` (this model's field), the [`TipFit`]
    /// of each element integrated again that holds tip functions in the
    /// new model, on the points of its new block: the projection
    /// ([`crate::blade::map_state_fitted_with`]) then evaluates only the
    /// elements without one. A model integrated point by point
    /// ([`Integration::SubTetQuadrature`]) or without mass gives none.
    pub fn update_cut_fitted_with(
        &self,
        cut: Option<CutSetup>,
        state: &crate::dynamics::State,
        parallelism: Parallelism,
    ) -> Result<(Model, UpdateStats, CutUpdate, TipFits), ModelError> {
        let old = OldField {
            model: self,
            d: &state.d,
            v: &state.v,
            a: &state.a,
        };
        self.update_cut_inner(cut, parallelism, Some(old))
    }

    fn update_cut_inner(
        &self,
        cut: Option<CutSetup>,
        parallelism: Parallelism,
        old: Option<OldField<'_>>,
    ) -> Result<(Model, UpdateStats, CutUpdate, TipFits), ModelError> {
        if self.body_force {
            return Err(ModelError::BodyForceUpdate);
        }
        let mesh = &self.mesh;
        let n_nodes = mesh.n_nodes();
        let n_shape = shape_count(mesh, cut.as_ref())?;
        let need_mass = self.lumped_mass.is_some();
        let map = shape_map(n_nodes, self.cut.as_ref(), cut.as_ref(), self.n_shape);
        let joined = small_side_rotation(mesh, cut.as_ref(), self.formulation, self.integration);
        let integrator = Integrator {
            mesh,
            lame: self.lame,
            rho: self.material.density,
            integration: self.integration,
            joined: joined.as_deref(),
            gravity: self.gravity,
            body_force: None,
            need_mass,
            stiffness: true,
            old,
        };
        // A changed element's old block is integrated again only for what
        // it added to the loads and masses (its stiffness is dropped whole).
        let old_integrator = Integrator {
            stiffness: false,
            old: None,
            ..integrator
        };
        let mut stats = UpdateStats::default();

        // Globals: the old ones on the new shape ids.
        let mut globals = Globals::new(n_shape, cut.as_ref(), need_mass);
        for (so, &sn) in map.iter().enumerate() {
            if sn == NONE {
                continue;
            }
            let sn = sn as usize;
            globals.load[3 * sn..3 * sn + 3].copy_from_slice(&self.load[3 * so..3 * so + 3]);
            if let (Some(l), Some(lo)) = (globals.lumped.as_mut(), &self.lumped_mass) {
                l[sn] = lo[so];
            }
            if let (Some(c), Some(co), true) = (
                globals.coupling.as_mut(),
                &self.lumped_coupling,
                so >= n_nodes && so < n_nodes + self.n_enriched(),
            ) {
                c[sn - n_nodes] = co[so - n_nodes];
            }
        }

        // Elements: kept, or integrated again (old block out, new block in).
        let mut flat = FlatElements::with_capacity(mesh.n_elements(), self.shape_ids.len());
        let mut changed: Vec<(usize, ElementBlock)> = Vec::new();
        let mut fits = TipFits::new();
        let mut old_masses: Vec<(usize, Vec<f64>)> = Vec::new();
        // Per DOF of the new Heaviside functions: whether a Dirichlet
        // boundary the cut crosses holds it at zero ([`enriched_fixes`]);
        // with the ramp, of the tip functions too: whether their node's
        // component is fixed or [`ramp_fixes`] holds it (a node that leaves
        // or joins the ramp's ring). `None` for the other DOFs (standard
        // ones stay as they are, tip ones are held where their node's
        // component is fixed).
        let node_fixed = |i: usize, c: usize| self.equation[3 * i + c] == NONE;
        let mut heaviside_dof_held: Vec<Option<bool>> = vec![None; 3 * n_shape];
        if let Some(c) = cut.as_ref() {
            let held = heaviside_held(mesh, c, node_fixed);
            for i in 0..n_nodes {
                if let Some(j) = c.enriched[i] {
                    for (k, &h) in held[i].iter().enumerate() {
                        heaviside_dof_held[3 * (n_nodes + j) + k] = Some(h);
                    }
                }
            }
            if !c.ramp.is_empty() {
                let first = n_nodes + c.n_enriched;
                for (i, t) in c.tip.iter().enumerate() {
                    let Some(t) = t else {
                        continue;
                    };
                    for s in first + N_BRANCH * t..first + N_BRANCH * (t + 1) {
                        for k in 0..3 {
                            heaviside_dof_held[3 * s + k] = Some(node_fixed(i, k));
                        }
                    }
                }
                for (s, held) in ramp_fixes(mesh, c, node_fixed) {
                    for (k, h) in held.into_iter().enumerate() {
                        if h {
                            heaviside_dof_held[3 * s + k] = Some(true);
                        }
                    }
                }
            }
        }
        // Nodes whose Heaviside (or, with the ramp, tip) functions stay but
        // whose held components change (the cut reached, or left, a
        // Dirichlet boundary beside them): their elements are integrated again, so that the DOFs
        // that become free get their entries.
        let mut flipped = vec![false; n_nodes];
        if let Some(oc) = self.cut.as_ref() {
            for (i, f) in flipped.iter_mut().enumerate() {
                let Some(jo) = oc.enriched[i] else {
                    continue;
                };
                let so = n_nodes + jo;
                if map[so] == NONE {
                    continue;
                }
                let sn = map[so] as usize;
                *f = (0..3).any(|k| {
                    heaviside_dof_held[3 * sn + k] != Some(self.equation[3 * so + k] == NONE)
                });
            }
            // With the ramp, tip functions held or freed (a node that joins
            // or leaves the ring).
            let first = n_nodes + oc.n_enriched;
            for (i, t) in oc.tip.iter().enumerate() {
                let Some(t) = t else {
                    continue;
                };
                for so in first + N_BRANCH * t..first + N_BRANCH * (t + 1) {
                    if map[so] == NONE {
                        continue;
                    }
                    let sn = map[so] as usize;
                    flipped[i] |= (0..3).any(|k| {
                        heaviside_dof_held[3 * sn + k]
                            .is_some_and(|h| h != (self.equation[3 * so + k] == NONE))
                    });
                }
            }
        }
        // The changed elements' old contributions (loads, masses) and new
        // blocks, integrated side by side; added below in element order.
        // Elements whose sides join or part (a blade freed a fragment, or
        // the front went round): a small side's rotation changes with it.
        let joined_old =
            small_side_rotation(mesh, self.cut.as_ref(), self.formulation, self.integration);
        let rejoined = |e: usize| {
            let at = |j: &Option<Vec<bool>>| j.as_ref().is_some_and(|j| j[e]);
            at(&joined_old) != at(&joined)
        };
        let kept: Vec<bool> = (0..mesh.n_elements())
            .map(|e| {
                same_element_model(mesh, self.cut.as_ref(), cut.as_ref(), e)
                    && !mesh.element(e).iter().any(|&i| flipped[i])
                    && !rejoined(e)
            })
            .collect();
        let to_integrate: Vec<usize> = (0..mesh.n_elements()).filter(|&e| !kept[e]).collect();
        let integrate_old = need_mass || integrator.has_load();
        let blocks = parallelism.map(to_integrate.len(), |k| {
            let e = to_integrate[k];
            let old_block = if integrate_old {
                Some(match self.contributions.get(&e) {
                    Some(block) => block.clone(),
                    None => {
                        let old_cells = element_cells(mesh, self.cut.as_ref(), e)?;
                        old_integrator.block(&old_cells, None)
                    }
                })
            } else {
                None
            };
            let cells = element_cells(mesh, cut.as_ref(), e)?;
            Ok::<_, ModelError>((old_block, integrator.block(&cells, None)))
        });
        let mut blocks = blocks.into_iter();
        let keep_residual = !self.lump_residual.is_empty();
        let mut lump_residual =
            Vec::with_capacity(if keep_residual { mesh.n_elements() } else { 0 });
        // A kept element's shape ids on the new numbering (one buffer).
        let mut ids: Vec<u32> = Vec::new();
        for e in 0..mesh.n_elements() {
            let el = &self.elements[e];
            if kept[e] {
                if keep_residual {
                    lump_residual.push(self.lump_residual[e]);
                }
                ids.clear();
                ids.extend(
                    self.shape_ids[el.shapes.clone()]
                        .iter()
                        .map(|&s| map[s as usize]),
                );
                let groups = &self.groups[el.groups.clone()];
                let m = el.shapes.len();
                let (g0, g1) = match (groups.first(), groups.last()) {
                    (Some(f), Some(l)) => (f.grads as usize, l.grads as usize + m),
                    _ => (0, 0),
                };
                let dense = || groups.iter().filter(|g| g.is_dense());
                let (k0, k1) = match (dense().next(), dense().next_back()) {
                    (Some(f), Some(l)) => (
                        f.stiffness as usize,
                        l.stiffness as usize + crate::kernel::packed_len(3 * m),
                    ),
                    _ => (0, 0),
                };
                flat.push(
                    e,
                    &ids,
                    groups,
                    &self.grads[g0..g1],
                    &self.stiffness[k0..k1],
                );
                continue;
            }
            let (old_block, block) = blocks.next().expect("one block per changed element")?;
            if keep_residual {
                lump_residual.push(block.lump_residual);
            }
            if let Some(mut old_block) = old_block {
                for s in old_block.shape_ids.iter_mut() {
                    *s = map[*s as usize];
                }
                globals.sub_mapped(&old_block, n_nodes);
                if need_mass {
                    old_masses.push((e, std::mem::take(&mut old_block.mass)));
                }
            }
            globals.add(&block, n_nodes);
            flat.push_block(e, &block);
            let mut block = block;
            if let Some(fit) = block.fit.take() {
                fits.insert(e, *fit);
            }
            changed.push((e, block));
        }
        stats.changed_elements = changed.len();

        // Equations: the old numbers of DOFs that stay (compacted in order), new ones appended.
        let mut old_of_new = vec![NONE; n_shape];
        for (so, &sn) in map.iter().enumerate() {
            if sn != NONE {
                old_of_new[sn as usize] = so as u32;
            }
        }
        let mut eq_map = vec![NONE; self.n_free];
        // (A DOF a Dirichlet boundary now holds drops its equation.)
        let held_now = |so: usize, c: usize| {
            map[so] != NONE && heaviside_dof_held[3 * map[so] as usize + c] == Some(true)
        };
        for (dof, &eq) in self.equation.iter().enumerate() {
            if eq != NONE && map[dof / 3] != NONE && !held_now(dof / 3, dof % 3) {
                eq_map[eq as usize] = 0;
            }
        }
        let mut n_free = 0u32;
        for m in eq_map.iter_mut() {
            if *m == 0 {
                *m = n_free;
                n_free += 1;
            }
        }
        stats.dropped_equations = self.n_free - n_free as usize;
        // The node of each new shape function, for the fixes of new enriched ones.
        let mut node_of = vec![NONE; n_shape];
        if let Some(c) = cut.as_ref() {
            for i in 0..n_nodes {
                for s in enriched_shapes_of(n_nodes, c, i) {
                    node_of[s] = i as u32;
                }
            }
        }
        // Old prescribed DOFs on their new shape ids (an enriched one may be gone).
        let mut prescribed: Vec<Prescribed> = self
            .prescribed
            .iter()
            .filter_map(|p| {
                let sn = map[p.dof / 3];
                let dof = 3 * sn as usize + p.dof % 3;
                (sn != NONE && heaviside_dof_held[dof] != Some(false)).then_some(Prescribed {
                    dof,
                    value: p.value,
                })
            })
            .collect();
        let mut equation = vec![NONE; 3 * n_shape];
        for (sn, &so) in old_of_new.iter().enumerate() {
            if so != NONE {
                for c in 0..3 {
                    let eq = self.equation[3 * so as usize + c];
                    let held = heaviside_dof_held[3 * sn + c];
                    if eq != NONE && held == Some(true) {
                        // Held from now on: its equation is gone.
                        prescribed.push(Prescribed {
                            dof: 3 * sn + c,
                            value: 0.0,
                        });
                    } else if eq != NONE {
                        equation[3 * sn + c] = eq_map[eq as usize];
                    } else if held == Some(false) {
                        // Held before, free now: a new equation.
                        equation[3 * sn + c] = n_free;
                        n_free += 1;
                    }
                }
            } else {
                // A new shape function (enriched): prescribed to zero where
                // [`enriched_fixes`] prescribes it, else a new equation.
                let node = node_of[sn];
                for c in 0..3 {
                    let held = heaviside_dof_held[3 * sn + c].unwrap_or_else(|| {
                        node != NONE && self.equation[3 * node as usize + c] == NONE
                    });
                    if held {
                        prescribed.push(Prescribed {
                            dof: 3 * sn + c,
                            value: 0.0,
                        });
                    } else {
                        equation[3 * sn + c] = n_free;
                        n_free += 1;
                    }
                }
            }
        }
        let n_free = n_free as usize;
        stats.new_equations = n_free + stats.dropped_equations - self.n_free;

        // Pattern: the old entries that stay merged, column by column, with
        // the changed elements' entries; eq_map keeps the old order, so the
        // old rows stay sorted and each old entry's new position is known.
        let old = &self.pattern;
        let extra = changed_entries(
            changed.iter().map(|(e, _)| {
                let el = &flat.elements[*e];
                element_equations(&flat.shape_ids[el.shapes.clone()], &equation)
            }),
            n_free,
        );
        let mut old_column = vec![NONE; n_free];
        for (c, &cn) in eq_map.iter().enumerate() {
            if cn != NONE {
                old_column[cn as usize] = c as u32;
            }
        }
        let mut position = vec![NONE; old.nnz()];
        let mut col_ptr = Vec::with_capacity(n_free + 1);
        let mut row_idx = Vec::with_capacity(old.nnz() + extra.len());
        col_ptr.push(0);
        let mut next = 0;
        for cn in 0..n_free {
            let start = next;
            while next < extra.len() && extra[next].0 as usize == cn {
                next += 1;
            }
            let mut added = extra[start..next]
                .iter()
                .map(|&(_, r)| r as usize)
                .peekable();
            if old_column[cn] != NONE {
                let c = old_column[cn] as usize;
                for p in old.col_ptr[c]..old.col_ptr[c + 1] {
                    let rn = eq_map[old.row_idx[p]];
                    if rn == NONE {
                        continue;
                    }
                    let rn = rn as usize;
                    while let Some(r) = added.next_if(|&r| r < rn) {
                        row_idx.push(r);
                    }
                    added.next_if_eq(&rn);
                    position[p] = row_idx.len() as u32;
                    row_idx.push(rn);
                }
            }
            row_idx.extend(added);
            col_ptr.push(row_idx.len());
        }
        let pattern = Pattern {
            n: n_free,
            col_ptr,
            row_idx,
        };
        // Scatter maps in element order: a kept element's mapped through
        // `position` (written once, not filled first), a changed one's found.
        let mut scatter: Vec<u32> = Vec::with_capacity(flat.scatter_len);
        let mut dofs = Vec::new();
        let mut next_changed = changed.iter().map(|(e, _)| *e).peekable();
        for (e, el) in flat.elements.iter().enumerate() {
            debug_assert_eq!(scatter.len(), el.scatter);
            let n = 9 * el.shapes.len() * el.shapes.len();
            if next_changed.next_if_eq(&e).is_some() {
                scatter.resize(el.scatter + n, NONE);
                element_scatter(
                    el,
                    &flat.shape_ids[el.shapes.clone()],
                    &equation,
                    &pattern,
                    &mut scatter,
                    &mut dofs,
                );
            } else {
                let old_el = &self.elements[e];
                scatter.extend(
                    self.scatter[old_el.scatter..old_el.scatter + n]
                        .iter()
                        .map(|&p| position.get(p as usize).copied().unwrap_or(NONE)),
                );
            }
        }

        // Consistent mass: the old values moved, changed elements' old mass out, new in.
        let consistent_mass = self.consistent_mass.as_ref().map(|old_values| {
            let mut values = vec![0.0; pattern.nnz()];
            for (p, &v) in old_values.iter().enumerate() {
                if position[p] != NONE {
                    values[position[p] as usize] += v;
                }
            }
            for (e, me) in &old_masses {
                let el = &self.elements[*e];
                let m = el.shapes.len();
                for a in 0..m {
                    for b in 0..m {
                        for c in 0..3 {
                            let p = self.scatter[el.scatter + (3 * a + c) * 3 * m + 3 * b + c];
                            if p != NONE && position[p as usize] != NONE {
                                values[position[p as usize] as usize] -= me[a * m + b];
                            }
                        }
                    }
                }
            }
            for (e, block) in &changed {
                add_element_mass(&flat.elements[*e], &block.mass, &scatter, &mut values, 1.0);
            }
            values
        });
        let mut shape_ref = self.shape_ref.clone();
        shape_ref.resize(n_nodes, Vector3::zeros());
        shape_ref.resize(n_shape, Vector3::zeros());
        let mid_edge = mid_edges(mesh, cut.as_ref());
        let model = Model {
            mesh: mesh.clone(),
            material: self.material,
            lame: self.lame,
            formulation: self.formulation,
            integration: self.integration,
            gravity: self.gravity,
            body_force: false,
            cut,
            n_shape,
            shape_ref,
            elements: flat.elements,
            shape_ids: flat.shape_ids,
            groups: flat.groups,
            grads: flat.grads,
            stiffness: flat.stiffness,
            group_element: flat.group_element,
            equation,
            n_free,
            prescribed,
            pattern,
            scatter,
            load: globals.load,
            lumped_mass: globals.lumped,
            lumped_coupling: globals.coupling,
            consistent_mass,
            lump_residual,
            mid_edge,
            tractions: self.tractions.clone(),
            contributions: Default::default(),
        };
        let mut model = model;
        if !self.tractions.is_empty() {
            // The enriched traction loads of the changed elements' faces: the
            // old ones out (on the new shape ids), the new ones in.
            let mut is_changed = vec![false; mesh.n_elements()];
            for (e, _) in &changed {
                is_changed[*e] = true;
            }
            let mut load = std::mem::take(&mut model.load);
            for t in &self.tractions {
                for face in t.faces.iter().filter(|f| is_changed[f.1]) {
                    self.add_enriched_traction(face, &t.value, -1.0, Some(&map), &mut load);
                    model.add_enriched_traction(face, &t.value, 1.0, None, &mut load);
                }
            }
            model.load = load;
        }
        let update = CutUpdate {
            changed: changed.iter().map(|(e, _)| *e).collect(),
            position,
            equation: eq_map,
        };
        if need_mass || integrator.has_load() {
            // The changed elements' new blocks (loads and masses only): a tip
            // front changes most of them again at the next event. Only
            // these, so the map holds what one event changed, not a sweep.
            for (e, block) in changed {
                model.contributions.insert(
                    e,
                    ElementBlock {
                        groups: Vec::new(),
                        grads: Vec::new(),
                        stiffness: Vec::new(),
                        ..block
                    },
                );
            }
        }
        Ok((model, stats, update, fits))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// [`changed_entries`] against sorting all pairs: elements of 4–30
    /// equations (some fixed, some shared) in a matrix of order 200.
    #[test]
    fn changed_entries_are_the_sorted_distinct_lower_pairs() {
        let mut seed = 12345u64;
        let mut next = move |k: u64| {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (seed >> 33) % k
        };
        let elements: Vec<Vec<u32>> = (0..60)
            .map(|_| {
                let len = 4 + next(27) as usize;
                (0..len)
                    .map(|_| if next(8) == 0 { NONE } else { next(200) as u32 })
                    .collect()
            })
            .collect();
        let mut expected = Vec::new();
        for dofs in &elements {
            for &r in dofs {
                for &c in dofs {
                    if r != NONE && c != NONE && r >= c {
                        expected.push((c, r));
                    }
                }
            }
        }
        expected.sort_unstable();
        expected.dedup();
        assert!(expected.len() > 1000);
        assert_eq!(changed_entries(elements.into_iter(), 200), expected);
    }

    /// ∫ 1/r (r the distance to the front, the singularity of a tip
    /// stiffness) over the elements that `select` picks by their vertices'
    /// (φ, ψ), in a 2 × 2 × 2 box of [0, 1]³ (Tet4 and Tet10) cut by
    /// `patch`: [`ElementShapes::cell_rule`]'s against `reference(vertices,
    /// (φ, ψ), 1/r)`, within `bound` relative; at least one element a mesh.
    fn inverse_distance_within(
        patch: &crate::cut::PlanarPatch,
        select: impl Fn(&[[f64; 2]; 4]) -> bool,
        reference: impl Fn(&[Point3<f64>; 4], &[[f64; 2]; 4], &dyn Fn(&Point3<f64>) -> f64) -> f64,
        bound: f64,
    ) {
        use crate::cut::{setup_cut, CutInput, DEFAULT_SNAP};
        use crate::element::barycentric_gradients;
        let tet4 = crate::mesh::box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 1.0), [2, 2, 2]);
        for mesh in [tet4.clone(), tet4.to_tet10()] {
            let cut = setup_cut(&mesh, &[CutInput::tip(patch, DEFAULT_SNAP, None)]).unwrap();
            let mut checked = 0;
            for e in 0..mesh.n_elements() {
                let verts = mesh.vertex_points(e);
                let (f, g) = cut.vertex_levels(&mesh, e);
                let ls: [[f64; 2]; 4] = std::array::from_fn(|k| [f[k], g[k]]);
                if !select(&ls) {
                    continue;
                }
                let dl = barycentric_gradients(&verts).unwrap();
                let Some(shapes) = ElementShapes::new(&mesh, &cut, e, &dl, Vec::new()) else {
                    continue;
                };
                let inv_r = |x: &Point3<f64>| {
                    let l = crate::mesh::barycentric(&verts, x).unwrap();
                    1.0 / dot4(&l, &f).hypot(dot4(&l, &g))
                };
                let rule = shapes.cell_rule(&verts);
                let got: f64 = rule.iter().map(|q| q.weight * inv_r(&q.x)).sum();
                let exact = reference(&verts, &ls, &inv_r);
                let err = (got - exact).abs() / exact;
                println!(
                    "{:?} element {e}: gap {:.1e}, {} points, relative error {err:.1e}",
                    mesh.kind,
                    front::front_gap(&ls),
                    rule.len()
                );
                assert!(err < bound, "element {e}: {got} against {exact} ({err:e})");
                checked += 1;
            }
            assert!(checked > 0, "{:?}: no element selected", mesh.kind);
        }
    }

    /// ∫ f over a cell red-refined `depth` times towards the front (where
    /// its level-set gap is under half its size), Duffy rules of order 6
    /// on the pieces: the reference of the quadrature tests below.
    fn refined_towards_front(
        verts: &[Point3<f64>; 4],
        ls: &[[f64; 2]; 4],
        f: &dyn Fn(&Point3<f64>) -> f64,
        depth: usize,
    ) -> f64 {
        let leaf = |c: &[Point3<f64>; 4], out: &mut Vec<front::PhysicalPoint>| {
            out.extend(front::cell_rule(c, [false; 4], 6))
        };
        let mut fine = Vec::new();
        front::near_front_rule(verts, ls, depth, 0.5, &leaf, &mut fine);
        fine.iter().map(|q| q.weight * f(&q.x)).sum()
    }

    /// A front through a node and on into the cells beside it (the crack
    /// plane x + y + z = 1.5 through the centre node of a 2 × 2 × 2 box,
    /// the front along (1, −1, 0) there, along no edge): ∫ 1/r over each
    /// cell with the front through one vertex and into it, against the
    /// cell split at the front ([`split_at_front`]). The vertex's collapsed
    /// rule took the singular line only at that vertex: 0.11 … 0.37
    /// relative error (64 points on Tet4, 125 on Tet10); split, ≤ 1.4e-4
    /// (Tet4, 256 or 384 points) and ≤ 2.5e-5 (Tet10, 500 or 750). (The exact
    /// near-front field on that plane, Tet10 n = 4, topological tip: the
    /// solve's energy error 0.114 against its interpolant's 0.109, now 0.084,
    /// and 0.081 with the plane moved off the nodes.)
    #[test]
    fn a_front_through_a_node_into_its_cells_is_integrated_as_a_front_edge() {
        let n = Vector3::new(1.0, 1.0, 1.0).normalize();
        let t = Vector3::new(1.0, -1.0, 0.0).normalize();
        let m = n.cross(&t);
        let c = Point3::new(0.5, 0.5, 0.5);
        let patch = crate::cut::PlanarPatch {
            origin: c - t * 3.0 - m * 3.0,
            u: t * 6.0,
            v: m * 3.0,
        };
        let through_vertex = |ls: &[[f64; 2]; 4]| {
            let on_front = ls.map(|l| l[0].abs() <= 1e-12 && l[1].abs() <= 1e-12);
            front_enters_at_vertex(ls, &on_front)
        };
        inverse_distance_within(&patch, through_vertex, split_at_front, 2e-4);
    }

    /// ∫ f over a cell split by φ = 0 and ψ = 0 (so that the front runs
    /// along edges of the pieces), collapsed rules of order 12 on the
    /// pieces that touch it, the others red-refined three times towards it
    /// with Duffy rules of order 8: the reference of the tests of cells the
    /// front passes through.
    fn split_at_front(
        verts: &[Point3<f64>; 4],
        ls: &[[f64; 2]; 4],
        f: &dyn Fn(&Point3<f64>) -> f64,
    ) -> f64 {
        let tol = 1e-9;
        let level = |x: &Point3<f64>| {
            let l = crate::mesh::barycentric(verts, x).unwrap();
            [0, 1].map(|k| (0..4).map(|v| l[v] * ls[v][k]).sum::<f64>())
        };
        let (phi, psi) = (ls.map(|l| l[0]), ls.map(|l| l[1]));
        crate::cut::split_front(verts, &phi, &psi, tol)
            .iter()
            .map(|piece| {
                let on_front = piece.vertices.map(|x| {
                    let [a, b] = level(&x);
                    a.abs() <= tol && b.abs() <= tol
                });
                let mut points = Vec::new();
                if on_front.iter().any(|&b| b) {
                    points = front::cell_rule(&piece.vertices, on_front, 12);
                } else {
                    // Off the front: refined three times towards it.
                    let leaf = |c: &[Point3<f64>; 4], out: &mut Vec<front::PhysicalPoint>| {
                        out.extend(front::cell_rule(c, [false; 4], 8))
                    };
                    let ls = piece.vertices.map(|x| level(&x));
                    front::near_front_rule(&piece.vertices, &ls, 3, 0.5, &leaf, &mut points);
                }
                points.iter().map(|q| q.weight * f(&q.x)).sum::<f64>()
            })
            .sum()
    }

    /// A front on an element's face (the seed's: x = 0.015 is a node plane
    /// of its structured meshes) passes through the element's cell along
    /// none of its edges. ∫ 1/r over such elements against the cell split
    /// by φ = 0 and ψ = 0 with collapsed rules of order 12 (red-refined
    /// three times towards the front off it). Before the split, the cell
    /// took one red refinement and the degree-5 rule: 2.9e-2 relative error
    /// on Tet4 (112 points); now 9.6e-5 (432 points), Tet10 4.9e-6.
    #[test]
    fn a_front_across_a_cell_face_is_integrated_as_a_front_edge() {
        // x = 0.5 a node plane, z = 0.3 not one.
        let patch = crate::cut::PlanarPatch {
            origin: Point3::new(-0.5, -0.5, 0.3),
            u: Vector3::new(0.0, 2.0, 0.0),
            v: Vector3::new(1.0, 0.0, 0.0),
        };
        let on_a_face = |ls: &[[f64; 2]; 4]| {
            ls.iter().all(|l| l[1] >= -1e-12)
                && ls.iter().filter(|l| l[1].abs() <= 1e-12).count() == 3
                && ls.iter().any(|l| l[0] > 0.0)
                && ls.iter().any(|l| l[0] < 0.0)
        };
        inverse_distance_within(&patch, on_a_face, split_at_front, 1e-3);
    }

    /// A cut on a node layer: the snap lifts the layer's nodes off it, so
    /// the front runs just beside the faces of the elements on the layer
    /// (a gap of about 1e-4 of their size). ∫ 1/r over those elements
    /// against the element red-refined towards the front nine times, Duffy
    /// rules of order 6 on the pieces (within 1e-5 of eleven times). Before
    /// the split, one red refinement: 3.9e-3 relative error (Tet4); now
    /// ≤ 1.0e-4 (Tet4), ≤ 1.4e-5 (Tet10).
    #[test]
    fn a_front_just_beside_a_face_is_integrated_as_a_front_edge() {
        // z = 0.5 a node layer, x = 0.25 not a node plane.
        let patch = crate::cut::PlanarPatch {
            origin: Point3::new(-0.5, -0.5, 0.5),
            u: Vector3::new(0.0, 2.0, 0.0),
            v: Vector3::new(0.75, 0.0, 0.0),
        };
        let beside = |ls: &[[f64; 2]; 4]| {
            let gap = front::front_gap(ls);
            gap > 1e-9 && gap <= NEAR_TOUCH * front::level_diameter(ls)
        };
        inverse_distance_within(
            &patch,
            beside,
            |v, l, f| refined_towards_front(v, l, f, 9),
            1e-3,
        );
    }

    /// An oblique front inside the elements passes some of them at a gap
    /// of 1e-3 … 0.1 of their size (64 of the 522 within half their size,
    /// over six random fronts through a 3 × 3 × 3 box): ∫ 1/r over those
    /// elements against the element red-refined towards the front seven
    /// times (over 64 such cells of six random fronts, four times is within
    /// 2.2e-5 of it, three times 1.6e-4). Before [`front::polar_rule`], one
    /// red refinement and the degree-5 rule: up to 2.6e-2 relative error
    /// over those 64 cells, 1.7e-3 here; now ≤ 4.3e-5 there, 1.0e-4 here.
    #[test]
    fn a_front_near_a_cell_is_integrated_in_polar_coordinates() {
        let patch = crate::cut::PlanarPatch {
            origin: Point3::new(-0.5, -0.5, 0.43),
            u: Vector3::new(0.0, 2.0, 0.11),
            v: Vector3::new(0.87, 0.0, 0.05),
        };
        let near = |ls: &[[f64; 2]; 4]| {
            let (gap, diam) = (front::front_gap(ls), front::level_diameter(ls));
            gap > NEAR_TOUCH * diam && gap <= NEAR_POLAR * diam
        };
        inverse_distance_within(
            &patch,
            near,
            |v, l, f| refined_towards_front(v, l, f, 7),
            2e-4,
        );
    }

    /// [`ramp_fixes`]: the ring nodes' branch functions outside
    /// [`ring_free_branches`] held in every component, and the point gauge
    /// only where those pins leave the dependence (Tet10, whose ring keeps
    /// all four; Tet4 with the ring's level sets zeroed, as if it lay on
    /// the front), on the components that no tip node off the front has
    /// prescribed.
    #[test]
    fn the_ramp_holds_its_ring_and_gauges_only_a_region_the_ring_does_not_pin() {
        use crate::cut::{setup_cut, Blending, CutInput, PlanarPatch, DEFAULT_SNAP};
        let patch = PlanarPatch {
            origin: Point3::new(-0.5, -0.5, 1.1),
            u: Vector3::new(0.0, 2.0, 0.0),
            v: Vector3::new(1.03, 0.0, 0.0),
        };
        let tet4 = crate::mesh::box_mesh(Point3::origin(), Point3::new(1.0, 1.0, 2.0), [4, 4, 8]);
        for mesh in [tet4.clone(), tet4.to_tet10()] {
            let input = CutInput {
                blending: Blending::Ramp,
                ..CutInput::tip(&patch, DEFAULT_SNAP, Some(0.3))
            };
            let mut cut = setup_cut(&mesh, &[input]).unwrap();
            let n_nodes = mesh.n_nodes();
            let first = n_nodes + cut.n_enriched;
            let ring: Vec<usize> = (0..n_nodes)
                .filter(|&i| cut.tip[i].is_some() && !cut.ramp[i])
                .collect();
            assert!(!ring.is_empty());
            let kept = ring_free_branches(mesh.kind);
            let mut expected: Vec<(usize, [bool; 3])> = ring
                .iter()
                .flat_map(|&i| {
                    let base = first + N_BRANCH * cut.tip[i].unwrap();
                    (0..N_BRANCH)
                        .filter(|b| !kept.contains(b))
                        .map(move |b| (base + b, [true; 3]))
                })
                .collect();
            let mut fixes = ramp_fixes(&mesh, &cut, |_, _| false);
            fixes.sort_unstable();
            expected.sort_unstable();
            if expected.is_empty() {
                // Tet10: the ring keeps all four; one node's F₀, F₁ gauge.
                assert_eq!(fixes.len(), 2, "{:?}: {fixes:?}", mesh.kind);
                assert_eq!(fixes[1].0, fixes[0].0 + 1);
            } else {
                assert_eq!(
                    fixes, expected,
                    "{:?}: the ring's pins, no gauge",
                    mesh.kind
                );
            }
            // The ring on the front: its pins hold nothing of the
            // dependence; F₀, F₁ of the node of largest |φ| take it out,
            // on the components no tip node has prescribed (here y).
            for &i in &ring {
                cut.phi[i] = 0.0;
                cut.front_level[i] = 0.0;
            }
            // (The first of the largest, as `ramp_fixes` takes it.)
            let m = (0..n_nodes)
                .filter(|&i| cut.tip[i].is_some())
                .fold(None, |m: Option<usize>, i| match m {
                    Some(m) if cut.phi[i].abs() <= cut.phi[m].abs() => Some(m),
                    _ => Some(i),
                })
                .unwrap();
            let base = first + N_BRANCH * cut.tip[m].unwrap();
            let gauge = |prescribed: &dyn Fn(usize, usize) -> bool| {
                let fixes = ramp_fixes(&mesh, &cut, prescribed);
                assert_eq!(fixes.len(), expected.len() + 2, "{:?}", mesh.kind);
                fixes
                    .into_iter()
                    .filter(|f| f.0 == base || f.0 == base + 1)
                    .collect::<Vec<_>>()
            };
            // x and z prescribed at m.
            assert_eq!(
                gauge(&|i, c| c != 1 && i == m),
                [
                    (base, [false, true, false]),
                    (base + 1, [false, true, false])
                ],
                "{:?}",
                mesh.kind
            );
            // Prescribed only on the ring, on the front now: pins nothing.
            let ring_node = |i: usize| cut.tip[i].is_some() && !cut.ramp[i];
            assert_eq!(
                gauge(&|i, _| ring_node(i)),
                [(base, [true; 3]), (base + 1, [true; 3])],
                "{:?}",
                mesh.kind
            );
        }
    }
}

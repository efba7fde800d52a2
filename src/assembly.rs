//! Assembly: internal forces, strain energy and the tangent stiffness from the
//! per-group kernel, scattered into the free-DOF CSC values.
//!
//! This runs every Newton iteration / time step; it borrows the [`Model`] and
//! writes into buffers owned by the caller ([`Workspace`]), allocating nothing.

use crate::kernel::DenseKernel;
use crate::model::{group_rotation, Formulation, GroupKernel, Model, NONE};
use crate::solve::Parallelism;
use nalgebra::{Matrix3, Vector3};
use std::ops::Range;

/// Per-step state that persists across iterations: one rotation per group
/// (the warm start of the next polar decomposition).
#[derive(Debug, Clone)]
pub struct Rotations(pub Vec<Matrix3<f64>>);

impl Rotations {
    pub fn identity(model: &Model) -> Rotations {
        Rotations(vec![Matrix3::identity(); model.groups.len()])
    }
}

/// Scratch buffers sized for the largest element, and, for a parallel
/// assembly, one chunk of elements per thread with its own buffers.
pub struct Workspace {
    disp: Vec<Vector3<f64>>,
    scratch: Scratch,
    chunks: Vec<Chunk>,
}

/// The kernels' scratch (rotated gradients, the exact tangent's v_jb; a
/// dense group's local displacements and forces, its tangent's P_a, T_a).
struct Scratch {
    rotated: Vec<Vector3<f64>>,
    cross: Vec<[Vector3<f64>; 3]>,
    local: Vec<f64>,
    local_y: Vec<f64>,
    local_forces: Vec<f64>,
    p: Vec<Matrix3<f64>>,
    t: Vec<Matrix3<f64>>,
    /// A dense group's exact tangent: X and N = K X, 3m rows each.
    rows: Vec<[f64; 3]>,
}

impl Scratch {
    fn new(m: usize) -> Scratch {
        Scratch {
            rotated: vec![Vector3::zeros(); m],
            cross: vec![[Vector3::zeros(); 3]; m],
            local: vec![0.0; 3 * m],
            local_y: vec![0.0; 3 * m],
            local_forces: vec![0.0; 3 * m],
            p: vec![Matrix3::zeros(); m],
            t: vec![Matrix3::zeros(); m],
            rows: vec![[0.0; 3]; 6 * m],
        }
    }
}

/// A contiguous range of elements (and so of groups) assembled by one thread
/// into its own force and tangent buffers, summed afterwards.
struct Chunk {
    elements: Range<usize>,
    groups: Range<usize>,
    disp: Vec<Vector3<f64>>,
    scratch: Scratch,
    forces: Vec<f64>,
    tangent: Vec<f64>,
    energy: f64,
}

impl Workspace {
    /// One thread.
    pub fn new(model: &Model) -> Workspace {
        Workspace::with_parallelism(model, Parallelism::SEQUENTIAL)
    }

    /// The element loops of [`evaluate`] on `parallelism`'s threads (rayon):
    /// the elements in as many contiguous chunks, each with its own force and
    /// tangent buffers (n_dofs + nnz values a thread), summed after the pass.
    pub fn with_parallelism(model: &Model, parallelism: Parallelism) -> Workspace {
        let m = model
            .elements
            .iter()
            .map(|e| e.shapes.len())
            .max()
            .unwrap_or(0);
        let n_el = model.elements.len();
        let threads = parallelism.n_threads().min(n_el).max(1);
        let chunks = if threads > 1 {
            (0..threads)
                .map(|t| {
                    let elements = t * n_el / threads..(t + 1) * n_el / threads;
                    let first = model.elements.get(elements.start);
                    let groups = first.map_or(0, |e| e.groups.start)
                        ..model.elements[elements.end - 1].groups.end;
                    Chunk {
                        elements,
                        groups,
                        disp: vec![Vector3::zeros(); m],
                        scratch: Scratch::new(m),
                        forces: vec![0.0; model.n_dofs()],
                        tangent: vec![0.0; model.pattern.nnz()],
                        energy: 0.0,
                    }
                })
                .collect()
        } else {
            Vec::new()
        };
        Workspace {
            disp: vec![Vector3::zeros(); m],
            scratch: Scratch::new(m),
            chunks,
        }
    }
}

/// What to compute in one pass over the elements.
pub struct Request<'a> {
    /// Internal forces, all DOFs (overwritten).
    pub forces: Option<&'a mut [f64]>,
    /// Tangent R K Rᵀ on the free DOFs, lower CSC values (overwritten).
    pub tangent: Option<&'a mut [f64]>,
    /// Update the rotations from `d` (corotational); otherwise use those stored.
    pub update_rotations: bool,
    /// Corotational: the exact tangent of the forces (rotation derivative
    /// included) instead of R K Rᵀ (the seed's).
    pub exact_tangent: bool,
}

/// What [`for_each_group`] hands its visitor as the gradient of the nodal
/// vector x.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Gradient {
    /// F = I + Σ_a x_a ⊗ ∇φ_a: x is a displacement.
    Deformation,
    /// ∇x = Σ_a x_a ⊗ ∇φ_a alone: x is a velocity or a direction, whose
    /// gradient F − I would round against the identity (its last bits then
    /// depended on its size: the stiffness damping β_R K v of a scene in
    /// another unit of time differed in the last bits).
    Vector,
}

/// The one gather/group loop of the crate: for each group g of each element,
/// calls `visit(g, shapes, values, grads, G, scratch)` with `values` the
/// element's x_a and G the [`Gradient`] `gradient` of the nodal vector `x`
/// (all DOFs; a dense group's averaged gradients give F̄).
fn for_each_group(
    model: &Model,
    elements: Range<usize>,
    x: &[f64],
    gradient: Gradient,
    disp: &mut [Vector3<f64>],
    scratch: &mut Scratch,
    mut visit: impl FnMut(usize, &[u32], &[Vector3<f64>], &[Vector3<f64>], &Matrix3<f64>, &mut Scratch),
) {
    for el in &model.elements[elements] {
        let shapes = &model.shape_ids[el.shapes.clone()];
        let m = shapes.len();
        for (a, &s) in shapes.iter().enumerate() {
            let s = s as usize;
            disp[a] = Vector3::new(x[3 * s], x[3 * s + 1], x[3 * s + 2]);
        }
        for g in el.groups.clone() {
            let start = model.groups[g].grads as usize;
            let grads = &model.grads[start..start + m];
            let f = match gradient {
                Gradient::Deformation => GroupKernel::deformation_gradient(grads, |a| disp[a]),
                Gradient::Vector => grads
                    .iter()
                    .enumerate()
                    .fold(Matrix3::zeros(), |h, (a, g)| h + disp[a] * g.transpose()),
            };
            visit(g, shapes, &disp[..m], grads, &f, scratch);
        }
    }
}

/// The integration groups whose deformation gradient at `d` (all DOFs)
/// has det F ≤ 0, each as `visit(group)`.
fn for_each_inverted(model: &Model, d: &[f64], mut visit: impl FnMut(usize)) {
    let mut ws = Workspace::new(model);
    for_each_group(
        model,
        0..model.elements.len(),
        d,
        Gradient::Deformation,
        &mut ws.disp,
        &mut ws.scratch,
        |g, _, _, _, f, _| {
            if f.determinant() <= 0.0 {
                visit(g);
            }
        },
    );
}

/// Integration groups whose deformation gradient at `d` (all DOFs) has
/// det F ≤ 0: inverted elements (or sides of cut elements).
pub fn inverted_groups(model: &Model, d: &[f64]) -> usize {
    let mut inverted = 0;
    for_each_inverted(model, d, |_| inverted += 1);
    inverted
}

/// The reference volume of the integration groups whose deformation
/// gradient at `d` (all DOFs) has det F ≤ 0, as a fraction of the body's
/// (the sum of all groups' weights): where [`inverted_groups`] counts, this
/// weighs, so that a sliver side of a cut element turned inside out counts
/// for its volume, not as a collapsing element.
pub fn inverted_fraction(model: &Model, d: &[f64]) -> f64 {
    let mut inverted = 0.0;
    for_each_inverted(model, d, |g| inverted += model.groups[g].weight);
    let volume: f64 = model.groups.iter().map(|g| g.weight).sum();
    inverted / volume
}

/// Adds the element vector `fa` of shape function `a` into the all-DOF vector `out`.
fn add_nodal(out: &mut [f64], shapes: &[u32], a: usize, fa: &Vector3<f64>) {
    let s = shapes[a] as usize;
    for c in 0..3 {
        out[3 * s + c] += fa[c];
    }
}

/// One pass over all groups at displacement `d`: returns the strain energy.
pub fn evaluate(
    model: &Model,
    d: &[f64],
    rot: &mut Rotations,
    ws: &mut Workspace,
    req: Request<'_>,
) -> f64 {
    evaluate_damped(model, d, rot, ws, req, 0.0)
}

/// [`evaluate`] with `damping` × R K Rᵀ added to the requested tangent, R the
/// rotations the pass uses: the Newton matrix of a linear step with
/// stiffness-proportional Rayleigh damping D = β_R K, whose velocity
/// derivative brings γβ_R/(βΔt) K beside K (seed section 3.5). (Corotational
/// steps hold the damping's rotations over the step and add its stiffness
/// themselves: `dynamics`.)
pub fn evaluate_damped(
    model: &Model,
    d: &[f64],
    rot: &mut Rotations,
    ws: &mut Workspace,
    mut req: Request<'_>,
    damping: f64,
) -> f64 {
    let pass = Pass {
        model,
        d,
        update: req.update_rotations,
        exact: req.exact_tangent,
        damping,
    };
    if ws.chunks.is_empty() {
        return pass.run(
            0..model.elements.len(),
            &mut rot.0,
            0,
            &mut ws.disp,
            &mut ws.scratch,
            req.forces,
            req.tangent,
        );
    }
    let (want_forces, want_tangent) = (req.forces.is_some(), req.tangent.is_some());
    run_chunks(
        &pass,
        &mut rot.0,
        0,
        &mut ws.chunks,
        want_forces,
        want_tangent,
    );
    if let Some(f) = req.forces.as_deref_mut() {
        sum_into(f, ws.chunks.iter().map(|c| &c.forces[..]));
    }
    if let Some(k) = req.tangent.as_deref_mut() {
        sum_into(k, ws.chunks.iter().map(|c| &c.tangent[..]));
    }
    ws.chunks.iter().map(|c| c.energy).sum()
}

/// Adds the forces (all DOFs) and the stiffness (lower CSC values on the
/// model's pattern) of `elements` alone at `d` to `forces` and `tangent`,
/// unrotated (a linear model's); returns their strain energy. What a cut
/// event changes of a linear model's K ([`crate::dynamics::LinearForces::updated`]).
pub fn add_linear_elements(
    model: &Model,
    d: &[f64],
    elements: &[usize],
    ws: &mut Workspace,
    forces: &mut [f64],
    tangent: &mut [f64],
) -> f64 {
    let pass = Pass {
        model,
        d,
        update: false,
        exact: false,
        damping: 0.0,
    };
    let mut rot = Vec::new();
    let mut energy = 0.0;
    for &e in elements {
        let groups = model.elements[e].groups.clone();
        rot.clear();
        rot.resize(groups.len(), Matrix3::identity());
        energy += pass.accumulate(
            e..e + 1,
            &mut rot,
            groups.start,
            &mut ws.disp,
            &mut ws.scratch,
            Some(&mut *forces),
            Some(&mut *tangent),
        );
    }
    energy
}

/// out = Σ parts.
fn sum_into<'a>(out: &mut [f64], mut parts: impl Iterator<Item = &'a [f64]>) {
    if let Some(first) = parts.next() {
        out.copy_from_slice(first);
    }
    for part in parts {
        for (o, p) in out.iter_mut().zip(part) {
            *o += p;
        }
    }
}

/// Assembles `chunks` (contiguous, groups from `g0` on in `rot`) in
/// parallel by halving (rayon::join: no allocation).
fn run_chunks(
    pass: &Pass<'_>,
    rot: &mut [Matrix3<f64>],
    g0: usize,
    chunks: &mut [Chunk],
    forces: bool,
    tangent: bool,
) {
    if let [c] = chunks {
        c.energy = pass.run(
            c.elements.clone(),
            rot,
            g0,
            &mut c.disp,
            &mut c.scratch,
            forces.then_some(&mut c.forces[..]),
            tangent.then_some(&mut c.tangent[..]),
        );
        return;
    }
    let mid = chunks.len() / 2;
    let split = chunks[mid].groups.start;
    let (left, right) = chunks.split_at_mut(mid);
    let (rot_left, rot_right) = rot.split_at_mut(split - g0);
    rayon::join(
        || run_chunks(pass, rot_left, g0, left, forces, tangent),
        || run_chunks(pass, rot_right, split, right, forces, tangent),
    );
}

/// What one pass of [`evaluate_damped`] computes.
struct Pass<'a> {
    model: &'a Model,
    d: &'a [f64],
    update: bool,
    exact: bool,
    damping: f64,
}

impl Pass<'_> {
    /// The pass over `elements`, whose groups' rotations are `rot[g − g0]`;
    /// overwrites `forces` and `tangent`; returns the strain energy.
    #[allow(clippy::too_many_arguments)]
    fn run(
        &self,
        elements: Range<usize>,
        rot: &mut [Matrix3<f64>],
        g0: usize,
        disp: &mut [Vector3<f64>],
        scratch: &mut Scratch,
        mut forces: Option<&mut [f64]>,
        mut tangent: Option<&mut [f64]>,
    ) -> f64 {
        if let Some(f) = forces.as_deref_mut() {
            f.fill(0.0);
        }
        if let Some(k) = tangent.as_deref_mut() {
            k.fill(0.0);
        }
        self.accumulate(elements, rot, g0, disp, scratch, forces, tangent)
    }

    /// [`Pass::run`] adding to `forces` and `tangent` instead of overwriting them.
    #[allow(clippy::too_many_arguments)]
    fn accumulate(
        &self,
        elements: Range<usize>,
        rot: &mut [Matrix3<f64>],
        g0: usize,
        disp: &mut [Vector3<f64>],
        scratch: &mut Scratch,
        mut forces: Option<&mut [f64]>,
        mut tangent: Option<&mut [f64]>,
    ) -> f64 {
        let (model, damping) = (self.model, self.damping);
        let lame = model.lame;
        let corotational = model.formulation == Formulation::Corotational;
        let update = self.update && corotational;
        let exact = self.exact && corotational;
        let mut energy = 0.0;
        for_each_group(
            model,
            elements,
            self.d,
            Gradient::Deformation,
            disp,
            scratch,
            |g, shapes, values, grads, f, scratch| {
                let r = &mut rot[g - g0];
                if update {
                    *r = group_rotation(model.formulation, f, r);
                }
                let group = model.groups[g];
                let m = shapes.len();
                let el = &model.elements[model.group_element[g] as usize];
                let map = &model.scatter[el.scatter..el.scatter + 9 * m * m];
                let scattered =
                    |k: &mut [f64], scale: f64, a: usize, b: usize, block: &Matrix3<f64>| {
                        scatter_block(k, map, 3 * m, a, b, block, scale)
                    };
                if let Some(stiffness) = model.group_stiffness(g) {
                    let kernel = DenseKernel {
                        stiffness,
                        rotation: *r,
                    };
                    let (u, y, h) = (
                        &mut scratch.local[..3 * m],
                        &mut scratch.local_y[..3 * m],
                        &mut scratch.local_forces[..3 * m],
                    );
                    // Positions from the element's first node, not the
                    // origin: Rᵀ(x + d) − x of a body far from the origin
                    // would carry (Rᵀ − I) x, a rigid translation the
                    // stiffness annihilates only up to round-off (a body
                    // 0.3 m off the origin stalled Newton at 1e-9).
                    let n_nodes = model.mesh.n_nodes();
                    let first = shapes[0] as usize;
                    let origin = if first < n_nodes {
                        model.shape_ref[first]
                    } else {
                        Vector3::zeros()
                    };
                    kernel.local_displacements(
                        values,
                        |a| {
                            let s = shapes[a] as usize;
                            if s < n_nodes {
                                model.shape_ref[s] - origin
                            } else {
                                model.shape_ref[s]
                            }
                        },
                        u,
                        y,
                    );
                    energy += kernel.local_forces(u, h);
                    // Corotational: the rotation's derivative (conservative forces, a Hessian).
                    let rd = corotational
                        .then(|| kernel.rotation_derivative(f))
                        .flatten();
                    if let Some(out) = forces.as_deref_mut() {
                        let correction =
                            rd.as_ref().map(|rd| (rd, grads, DenseKernel::moment(u, h)));
                        kernel.add_forces(h, correction, |a, fa| add_nodal(out, shapes, a, &fa));
                    }
                    if let Some(k) = tangent.as_deref_mut() {
                        let exact_rd = rd.as_ref().filter(|_| exact);
                        if let Some(rd) = exact_rd {
                            kernel.exact_tangent_blocks(
                                rd,
                                grads,
                                u,
                                y,
                                h,
                                &mut scratch.p[..m],
                                &mut scratch.t[..m],
                                &mut scratch.rows[..6 * m],
                                |a, b, block| scattered(k, 1.0, a, b, block),
                            );
                        }
                        let scale = if exact_rd.is_some() {
                            damping
                        } else {
                            1.0 + damping
                        };
                        if scale != 0.0 {
                            kernel
                                .tangent_blocks(m, |a, b, block| scattered(k, scale, a, b, block));
                        }
                    }
                    return;
                }
                let kernel = GroupKernel {
                    lame,
                    weight: group.weight,
                    grads,
                    rotation: *r,
                };
                let eps = kernel.strain(f);
                energy += kernel.energy(&eps);
                if let Some(out) = forces.as_deref_mut() {
                    let sigma = kernel.stress(&eps);
                    kernel.add_forces(&sigma, |a, fa| add_nodal(out, shapes, a, &fa));
                }
                if let Some(k) = tangent.as_deref_mut() {
                    let scale = 1.0 + damping;
                    let exact_done = exact
                        && kernel.exact_tangent_blocks(
                            f,
                            &mut scratch.rotated[..m],
                            &mut scratch.cross[..m],
                            |a, b, block| scattered(k, 1.0, a, b, block),
                        );
                    if exact_done {
                        if damping != 0.0 {
                            kernel.tangent_blocks(&mut scratch.rotated[..m], |a, b, block| {
                                scattered(k, damping, a, b, block)
                            });
                        }
                    } else {
                        kernel.tangent_blocks(&mut scratch.rotated[..m], |a, b, block| {
                            scattered(k, scale, a, b, block)
                        });
                    }
                }
            },
        );
        energy
    }
}

/// Adds `scale` × the element block (a, b), b ≤ a, and its transpose (b, a)
/// through the element's scatter map (n = 3m columns); each global lower entry
/// is reached from exactly one of (a,b,i,j), (b,a,j,i).
fn scatter_block(
    k: &mut [f64],
    map: &[u32],
    n: usize,
    a: usize,
    b: usize,
    block: &Matrix3<f64>,
    scale: f64,
) {
    for i in 0..3 {
        for j in 0..3 {
            let v = scale * block[(i, j)];
            let p1 = map[(3 * a + i) * n + 3 * b + j];
            if p1 != NONE {
                k[p1 as usize] += v;
            }
            if a != b {
                let p2 = map[(3 * b + j) * n + 3 * a + i];
                if p2 != NONE {
                    k[p2 as usize] += v;
                }
            }
        }
    }
}

/// y += R K Rᵀ z for all DOFs (z over all DOFs), with the stored rotations.
pub fn tangent_product(
    model: &Model,
    z: &[f64],
    rot: &Rotations,
    ws: &mut Workspace,
    y: &mut [f64],
) {
    let lame = model.lame;
    let (disp, scratch) = (&mut ws.disp, &mut ws.scratch);
    for_each_group(
        model,
        0..model.elements.len(),
        z,
        Gradient::Vector,
        disp,
        scratch,
        |g, shapes, values, grads, gz, scratch| {
            let rotation = rot.0[g];
            if let Some(stiffness) = model.group_stiffness(g) {
                // y_a += R (K Rᵀz)_a.
                let kernel = DenseKernel {
                    stiffness,
                    rotation,
                };
                let m = shapes.len();
                let (u, ry, h) = (
                    &mut scratch.local[..3 * m],
                    &mut scratch.local_y[..3 * m],
                    &mut scratch.local_forces[..3 * m],
                );
                kernel.local_displacements(values, |_| Vector3::zeros(), u, ry);
                kernel.local_forces(u, h);
                kernel.add_forces(h, None, |a, fa| add_nodal(y, shapes, a, &fa));
                return;
            }
            let kernel = GroupKernel {
                lame,
                weight: model.groups[g].weight,
                grads,
                rotation,
            };
            // The local strain of Rᵀz: sym(Rᵀ ∇z).
            let rgz = kernel.rotation.transpose() * gz;
            let eps = (rgz + rgz.transpose()) * 0.5;
            let sigma = kernel.stress(&eps);
            kernel.add_forces(&sigma, |a, fa| add_nodal(y, shapes, a, &fa));
        },
    );
}
/// The shape function (node, or enriched node) of each free equation: the
/// blocks of a node-wise fill-reducing ordering (three equations a node).
pub fn equation_shapes(model: &Model) -> Vec<usize> {
    let mut shape = vec![0; model.n_free];
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != NONE {
            shape[eq as usize] = dof / 3;
        }
    }
    shape
}

/// Copies the free part of a full-DOF vector into `out` (by equation number).
pub fn gather_free(model: &Model, full: &[f64], out: &mut [f64]) {
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != NONE {
            out[eq as usize] = full[dof];
        }
    }
}

/// Adds `free` (by equation number) into the full-DOF vector.
pub fn scatter_free_add(model: &Model, free: &[f64], full: &mut [f64]) {
    for (dof, &eq) in model.equation.iter().enumerate() {
        if eq != NONE {
            full[dof] += free[eq as usize];
        }
    }
}

/// Where a field load acts: in the body (per unit volume) or on a cut face
/// (per unit area, with the outward unit normal of the side's region).
pub enum FieldLoadAt<'a> {
    Volume,
    CutFace { normal: &'a Vector3<f64> },
}

/// The load vector (all DOFs, shape-function order) of a body force and a
/// cut-face traction given as functions of the reference position and the
/// side of the cut (±1; 0 in an element the cut does not enrich):
/// ∫_Ω f·φ_a dV + Σ_± ∫_Γ± t·φ_a dA with every shape function of each
/// element, shifted Heaviside (seed eq. 58–59) and tip ones included.
///
/// The volume part uses [`Model::field_points`] (degree 5 on each cell,
/// collapsed rules at a front); the cut faces are the faces of the sub-tets
/// on the zero set of the element's interpolated φ (seed eq. 72–73), each
/// integrated from its own sub-tet's side with a 4×4 Duffy–Gauss rule, and,
/// where the cut runs along element faces (φ = 0 at their three vertices,
/// which carry the Heaviside enrichment), those faces from each element
/// beside them. Add the result to [`Model::load`] for a manufactured solution.
pub fn field_load(
    model: &Model,
    load: impl Fn(&nalgebra::Point3<f64>, i8, FieldLoadAt<'_>) -> Vector3<f64>,
) -> Vec<f64> {
    use crate::cut::ElementCut;
    use crate::element::{barycentric_gradients, shape_gradients, shape_values};
    use crate::mesh::{barycentric, TET_FACES};
    let mesh = &model.mesh;
    let nn = mesh.kind.nodes();
    let n_nodes = mesh.n_nodes();
    let mut out = vec![0.0; 3 * model.n_shape];
    let gauss = crate::front::gauss_legendre(4);
    for e in 0..mesh.n_elements() {
        let verts = mesh.vertex_points(e);
        let Some(dl) = barycentric_gradients(&verts) else {
            continue;
        };
        let ids = model.element_shapes(e);
        let m = ids.len();
        let (mut vals, mut grads) = (vec![0.0; m], vec![Vector3::zeros(); m]);
        let conn = mesh.element(e);
        let shapes = model.cut.as_ref().map(|c| {
            let heaviside: Vec<usize> = (0..nn)
                .filter(|&k| {
                    c.enriched[conn[k]].is_some_and(|j| ids[nn..].contains(&((n_nodes + j) as u32)))
                })
                .collect();
            crate::model::ElementShapes::any(mesh, c, e, &dl, heaviside)
        });
        let element_cut = model.cut.as_ref().map(|c| &c.elements[e]);
        // The side an element's shape functions are seen from at a point of side `side`.
        let seen = |side: i8| match element_cut {
            Some(ElementCut::Cut { .. }) => side,
            Some(ElementCut::Touched { side }) => *side,
            _ => 0,
        };
        let mut add = |x: &nalgebra::Point3<f64>,
                       side: i8,
                       w: f64,
                       f: Vector3<f64>,
                       vals: &mut [f64],
                       grads: &mut [Vector3<f64>]| {
            let l = barycentric(&verts, x).unwrap_or([0.25; 4]);
            match &shapes {
                Some(s) => s.eval(&l, seen(side), vals, grads),
                None => {
                    shape_values(mesh.kind, &l, vals);
                    shape_gradients(mesh.kind, &l, &dl, grads);
                }
            }
            for (a, &v) in vals.iter().enumerate() {
                let s = ids[a] as usize;
                for c in 0..3 {
                    out[3 * s + c] += w * f[c] * v;
                }
            }
        };
        for (x, w, side) in model.field_points(e) {
            let f = load(&x, side, FieldLoadAt::Volume);
            add(&x, side, w, f, &mut vals, &mut grads);
        }
        // The traction on a triangle of the cut, outward away from `inner`,
        // seen from `side`, with a 4×4 Duffy–Gauss rule.
        let mut face_load =
            |p: [nalgebra::Point3<f64>; 3], inner: &nalgebra::Point3<f64>, side: i8| {
                let cross = (p[1] - p[0]).cross(&(p[2] - p[0]));
                let area2 = cross.norm();
                if area2 <= 0.0 {
                    return;
                }
                let mut normal = cross / area2;
                if normal.dot(&(inner - p[0])) > 0.0 {
                    normal = -normal;
                }
                for &(u, wu) in &gauss {
                    for &(v, wv) in &gauss {
                        let (a, b) = (u, v * (1.0 - u));
                        let x = p[0] + (p[1] - p[0]) * a + (p[2] - p[0]) * b;
                        let w = wu * wv * (1.0 - u) * area2;
                        let t = load(&x, side, FieldLoadAt::CutFace { normal: &normal });
                        add(&x, side, w, t, &mut vals, &mut grads);
                    }
                }
            };
        let Some(c) = model.cut.as_ref() else {
            continue;
        };
        let v = mesh.vertices(e);
        let Some(ElementCut::Cut { sub_tets, .. }) = element_cut else {
            // A cut along the element's faces (on a node layer, φ = 0 at
            // their vertices after the snap): each face whose three
            // vertices carry the Heaviside enrichment (the cut opens
            // there), from the side of the element's fourth vertex.
            for (opposite, face) in TET_FACES.iter().enumerate() {
                let tri = face.map(|k| v[k]);
                if tri
                    .iter()
                    .all(|&i| c.phi[i] == 0.0 && c.enriched[i].is_some())
                {
                    let side = if c.phi[v[opposite]] < 0.0 { -1 } else { 1 };
                    face_load(face.map(|k| verts[k]), &verts[opposite], side);
                }
            }
            continue;
        };
        let phi = mesh.vertices(e).map(|i| c.phi[i]);
        let phi_at = |x: &nalgebra::Point3<f64>| {
            let l = barycentric(&verts, x).unwrap_or([0.25; 4]);
            (0..4).map(|k| l[k] * phi[k]).sum::<f64>()
        };
        let tol = 1e-9 * mesh.element_size(e);
        for s in sub_tets {
            for (opposite, face) in TET_FACES.iter().enumerate() {
                let p = face.map(|k| s.vertices[k]);
                if p.iter().any(|x| phi_at(x).abs() > tol) {
                    continue;
                }
                // Outward: away from the sub-tet's fourth vertex.
                face_load(p, &s.vertices[opposite], s.side);
            }
        }
    }
    out
}

/// One pass over what the corotational assembly reads and writes, without its
/// arithmetic: each element's shape ids and nodal values of `d`, each group's
/// weight and gradients, and the element's scatter map with one add per
/// stored entry into `k` (tangent values) and per DOF into `f` — the
/// memory-traffic floor of [`evaluate`] (benches/step.rs, examples/step_profile.rs
/// time it against the assembly). Returns a sum so the reads are kept.
pub fn element_data_pass(model: &Model, d: &[f64], f: &mut [f64], k: &mut [f64]) -> f64 {
    let mut acc = 0.0;
    for el in &model.elements {
        let shapes = &model.shape_ids[el.shapes.clone()];
        let n = shapes.len();
        let mut u = 0.0;
        for &s in shapes {
            let s = 3 * s as usize;
            u += d[s] + d[s + 1] + d[s + 2];
        }
        for g in el.groups.clone() {
            let group = model.groups[g];
            let start = group.grads as usize;
            let grads = &model.grads[start..start + n];
            acc += group.weight * u * grads.iter().map(|v| v.x + v.y + v.z).sum::<f64>();
            if let Some(k) = model.group_stiffness(g) {
                acc += u * k.iter().sum::<f64>();
            }
        }
        for &s in shapes {
            let s = 3 * s as usize;
            for c in 0..3 {
                f[s + c] += acc;
            }
        }
        for &p in &model.scatter[el.scatter..el.scatter + 9 * n * n] {
            if p != NONE {
                k[p as usize] += acc;
            }
        }
    }
    acc
}

/// The bytes one [`element_data_pass`] reads from the model's element
/// arrays (shape ids, groups, gradients, scatter maps), not counting `d`,
/// `f`, `k`.
pub fn element_data_bytes(model: &Model) -> usize {
    use std::mem::size_of;
    let scatter: usize = model
        .elements
        .iter()
        .map(|e| 9 * e.shapes.len().pow(2))
        .sum();
    let grads: usize = model
        .elements
        .iter()
        .map(|e| e.groups.len() * e.shapes.len())
        .sum();
    model.shape_ids.len() * size_of::<u32>()
        + model.groups.len() * size_of::<crate::model::Group>()
        + grads * size_of::<Vector3<f64>>()
        + scatter * size_of::<u32>()
        + model.stiffness.len() * size_of::<f64>()
        + model.elements.len() * size_of::<crate::model::ElementData>()
}

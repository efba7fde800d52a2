//! The answer must not depend on how a mesh lists each tetrahedron's nodes,
//! nor on the handedness of the coordinates: the same bar with every
//! element's vertices listed in another (even) order, and the bar mirrored
//! (x → 1 − x, each element re-oriented by swapping two vertices, as the
//! `.msh` reader does), with the cut, the load and the displacements
//! mirrored, give the same nodal displacements to round-off. Splits of cut
//! elements, refinements towards a front and collapsed rules all depend on
//! the order of a cell's vertices, and cells used to take the element's
//! listing (and a sub-tet swapped two vertices where it came out negatively
//! oriented): the branch functions' quadrature carried that order into the
//! answer, and so did the per-point rotations of cut Tet10 elements
//! (corotational). On this 2 × 2 × 4 bar, relisted / mirrored: Tet4 tip
//! 5.8e-4 / 8.6e-5 (within 0.6: 1.2e-3 / 3.0e-4), Tet10 tip 3.0e-3 /
//! 1.9e-3 (corotational 6.2e-3 / 8.5e-4), Tet10 extended and corotational
//! 4.1e-4 / 3.2e-4 of the largest displacement; now ≤ 6e-12. Cells are now
//! built in each element's canonical order (ascending node indices) and
//! keep the orientation the split gives them.

mod common;
use common::{bar, model, solve};
use nalgebra::{Matrix3, Point3, Vector3};
use xfem_cut::cut::{setup_cut, CutInput, PlanarPatch, DEFAULT_SNAP};
use xfem_cut::mesh::{ElementKind, TetMesh, TET10_EDGES};
use xfem_cut::model::{Formulation, Model};

/// `mesh` with each element's vertices taken in the order `order` (local
/// vertex k of the new listing is the old vertex `order[k]`), mid-edge
/// nodes following their edges.
fn relisted(mesh: &TetMesh, order: impl Fn(usize) -> [usize; 4]) -> TetMesh {
    let n = mesh.kind.nodes();
    let mut cells = Vec::with_capacity(mesh.cells.len());
    for e in 0..mesh.n_elements() {
        let old = mesh.element(e);
        let o = order(e);
        cells.extend(o.iter().map(|&k| old[k]));
        if mesh.kind == ElementKind::Tet10 {
            for &(a, b) in &TET10_EDGES {
                let (oa, ob) = (o[a], o[b]);
                let k = TET10_EDGES
                    .iter()
                    .position(|&(x, y)| (x, y) == (oa, ob) || (x, y) == (ob, oa))
                    .unwrap();
                cells.push(old[4 + k]);
            }
        }
    }
    assert_eq!(cells.len(), mesh.n_elements() * n);
    TetMesh {
        kind: mesh.kind,
        nodes: mesh.nodes.clone(),
        cells,
    }
}

/// An oblique patch whose front runs inside elements.
fn patch(mirror: &Matrix3<f64>, shift: &Vector3<f64>) -> PlanarPatch {
    let at = |p: Point3<f64>| Point3::from(mirror * p.coords + shift);
    PlanarPatch {
        origin: at(Point3::new(-0.1, -0.1, 0.93)),
        u: mirror * Vector3::new(0.63, 0.07, 0.21),
        v: mirror * Vector3::new(-0.05, 1.3, 0.11),
    }
}

/// The bar's displacements with the patch cut into it, front `front`
/// (None: extended; Some(r): tip-enriched, within r when r > 0).
fn solved(
    mesh: &TetMesh,
    mirror: &Matrix3<f64>,
    shift: &Vector3<f64>,
    front: Option<f64>,
    formulation: Formulation,
) -> (Model, Vec<f64>) {
    let p = patch(mirror, shift);
    let input = match front {
        None => CutInput::extend(&p, DEFAULT_SNAP),
        Some(r) => CutInput::tip(&p, DEFAULT_SNAP, (r > 0.0).then_some(r)),
    };
    let cut = setup_cut(mesh, &[input]).unwrap();
    assert!(cut.n_cut() > 0);
    assert_eq!(front.is_some(), cut.n_tip() > 0);
    let g = mirror * Vector3::new(3.0, 1.0, -2.0);
    let m = model(mesh, Some(cut), formulation, g, None, false).unwrap();
    let d = solve(&m);
    (m, d)
}

/// Largest difference of the nodal displacements (both sides of each
/// node; `flip`: side s of `a` is side −s of `b`, and `b` is mirrored by
/// `mirror`), relative to the largest.
fn difference(
    a: &Model,
    da: &[f64],
    b: &Model,
    db: &[f64],
    mirror: &Matrix3<f64>,
    flip: bool,
) -> f64 {
    let (mut diff, mut scale): (f64, f64) = (0.0, 0.0);
    for i in 0..a.mesh.n_nodes() {
        for side in [-1i8, 1] {
            let x = a.node_displacement(da, i, side);
            let y = mirror * b.node_displacement(db, i, if flip { -side } else { side });
            diff = diff.max((x - y).norm());
            scale = scale.max(x.norm());
        }
    }
    diff / scale
}

#[test]
fn relisted_and_mirrored_meshes_give_the_same_displacements() {
    let identity = Matrix3::identity();
    let mirror = Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0));
    // x → 1 − x maps the bar [0, 1] × [0, 1] × [0, 2] onto itself.
    let shift = Vector3::new(1.0, 0.0, 0.0);
    for kind in [ElementKind::Tet4, ElementKind::Tet10] {
        let base = bar([2, 2, 4]);
        let base = if kind == ElementKind::Tet10 {
            base.to_tet10()
        } else {
            base
        };
        // Even permutations keep each element positively oriented.
        let evens = [[1, 2, 0, 3], [2, 0, 1, 3], [0, 2, 3, 1], [3, 1, 0, 2]];
        let relist = relisted(&base, |e| evens[e % evens.len()]);
        let mut mirrored = relisted(&base, |_| [0, 2, 1, 3]);
        for p in &mut mirrored.nodes {
            p.x = 1.0 - p.x;
        }
        for (front, formulation) in [
            (Some(0.0), Formulation::Linear),
            (Some(0.6), Formulation::Linear),
            (Some(0.0), Formulation::Corotational),
            (None, Formulation::Corotational),
        ] {
            let what = format!("{kind:?} front {front:?} {formulation:?}");
            let zero = Vector3::zeros();
            let (ma, da) = solved(&base, &identity, &zero, front, formulation);
            let (mb, db) = solved(&relist, &identity, &zero, front, formulation);
            let (mc, dc) = solved(&mirrored, &mirror, &shift, front, formulation);
            let relisted = difference(&ma, &da, &mb, &db, &identity, false);
            let mirrored = difference(&ma, &da, &mc, &dc, &mirror, true);
            println!("{what}: relisted {relisted:.1e}, mirrored {mirrored:.1e}");
            assert!(relisted <= 1e-10, "{what}: relisted {relisted:e}");
            assert!(mirrored <= 1e-10, "{what}: mirrored {mirrored:e}");
        }
    }
}

//! Tet4 and Tet10 shape functions in barycentric coordinates, and their
//! gradients on a straight-sided (affine) tetrahedron.

use crate::mesh::{ElementKind, TET10_EDGES};
use nalgebra::{Matrix3, Point3, Vector3};

/// Gradients of the barycentric coordinates λ0..λ3 of the tetrahedron `p`
/// (constant on an affine element), or `None` for a degenerate one.
pub fn barycentric_gradients(p: &[Point3<f64>; 4]) -> Option<[Vector3<f64>; 4]> {
    let j = Matrix3::from_columns(&[p[1] - p[0], p[2] - p[0], p[3] - p[0]]);
    let jinv_t = j.try_inverse()?.transpose();
    let g1 = jinv_t.column(0).into_owned();
    let g2 = jinv_t.column(1).into_owned();
    let g3 = jinv_t.column(2).into_owned();
    Some([-(g1 + g2 + g3), g1, g2, g3])
}

/// Shape function values at barycentric point `l`, written into `n` (length `kind.nodes()`).
pub fn shape_values(kind: ElementKind, l: &[f64; 4], n: &mut [f64]) {
    match kind {
        ElementKind::Tet4 => n[..4].copy_from_slice(l),
        ElementKind::Tet10 => {
            for i in 0..4 {
                n[i] = l[i] * (2.0 * l[i] - 1.0);
            }
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                n[4 + k] = 4.0 * l[a] * l[b];
            }
        }
    }
}

/// Physical gradients of the shape functions at barycentric point `l`, given
/// the barycentric gradients `dl` of the element, written into `g`.
pub fn shape_gradients(
    kind: ElementKind,
    l: &[f64; 4],
    dl: &[Vector3<f64>; 4],
    g: &mut [Vector3<f64>],
) {
    match kind {
        ElementKind::Tet4 => g[..4].copy_from_slice(dl),
        ElementKind::Tet10 => {
            for i in 0..4 {
                g[i] = dl[i] * (4.0 * l[i] - 1.0);
            }
            for (k, &(a, b)) in TET10_EDGES.iter().enumerate() {
                g[4 + k] = (dl[a] * l[b] + dl[b] * l[a]) * 4.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::DEGREE5;

    fn tet() -> [Point3<f64>; 4] {
        [
            Point3::new(0.1, -0.2, 0.05),
            Point3::new(1.3, 0.1, -0.1),
            Point3::new(0.2, 0.9, 0.3),
            Point3::new(-0.1, 0.2, 1.1),
        ]
    }

    fn node_bary(kind: ElementKind, i: usize) -> [f64; 4] {
        let mut l = [0.0; 4];
        if i < 4 {
            l[i] = 1.0;
        } else {
            let (a, b) = TET10_EDGES[i - 4];
            l[a] = 0.5;
            l[b] = 0.5;
        }
        let _ = kind;
        l
    }

    #[test]
    fn shape_functions_are_nodal_and_partition_unity() {
        for kind in [ElementKind::Tet4, ElementKind::Tet10] {
            let n_nodes = kind.nodes();
            let mut n = [0.0; 10];
            for i in 0..n_nodes {
                shape_values(kind, &node_bary(kind, i), &mut n);
                for j in 0..n_nodes {
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((n[j] - want).abs() < 1e-15);
                }
            }
            for q in &DEGREE5 {
                shape_values(kind, &q.bary, &mut n);
                assert!((n[..n_nodes].iter().sum::<f64>() - 1.0).abs() < 1e-14);
            }
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let p = tet();
        let dl = barycentric_gradients(&p).unwrap();
        let kind = ElementKind::Tet10;
        let mut g = [Vector3::zeros(); 10];
        let l = DEGREE5[9].bary;
        shape_gradients(kind, &l, &dl, &mut g);
        let x = Point3::from(
            p.iter()
                .zip(l)
                .fold(Vector3::zeros(), |s, (pi, li)| s + pi.coords * li),
        );
        let h = 1e-6;
        for d in 0..3 {
            let mut e = Vector3::zeros();
            e[d] = h;
            let bary = |x: Point3<f64>| crate::mesh::barycentric(&p, &x).unwrap();
            let (mut np, mut nm) = ([0.0; 10], [0.0; 10]);
            shape_values(kind, &bary(x + e), &mut np);
            shape_values(kind, &bary(x - e), &mut nm);
            for i in 0..10 {
                let fd = (np[i] - nm[i]) / (2.0 * h);
                assert!((fd - g[i][d]).abs() < 1e-7, "node {i} dir {d}");
            }
        }
    }
}

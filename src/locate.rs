//! Point location in a tet mesh: an R*-tree of element boxes, then an exact
//! barycentric test.

use crate::mesh::{barycentric, TetMesh};
use nalgebra::Point3;
use rstar::{RTree, RTreeObject, AABB};

struct ElementBox {
    element: usize,
    bbox: AABB<[f64; 3]>,
}

impl RTreeObject for ElementBox {
    type Envelope = AABB<[f64; 3]>;
    fn envelope(&self) -> Self::Envelope {
        self.bbox
    }
}

/// Finds the element containing a point.
pub struct Locator {
    tree: RTree<ElementBox>,
}

impl Locator {
    pub fn new(mesh: &TetMesh) -> Locator {
        let (lo, hi) = mesh.bounding_box();
        // Boxes grow by 1e-9 of the mesh diagonal so points on faces are found.
        let slack = 1e-9 * (hi - lo).norm();
        let boxes = (0..mesh.n_elements())
            .map(|e| {
                let p = mesh.vertex_points(e);
                let mut a = [f64::INFINITY; 3];
                let mut b = [f64::NEG_INFINITY; 3];
                for q in &p {
                    for k in 0..3 {
                        a[k] = a[k].min(q[k] - slack);
                        b[k] = b[k].max(q[k] + slack);
                    }
                }
                ElementBox {
                    element: e,
                    bbox: AABB::from_corners(a, b),
                }
            })
            .collect();
        Locator {
            tree: RTree::bulk_load(boxes),
        }
    }

    /// The element containing `x` and its barycentric coordinates: among the
    /// candidates, the one whose smallest barycentric coordinate is largest
    /// (so points on faces or slightly outside by round-off are found).
    /// `filter` can restrict the candidates (e.g. to one side of a cut).
    pub fn locate_with(
        &self,
        mesh: &TetMesh,
        x: &Point3<f64>,
        filter: impl Fn(usize) -> bool,
    ) -> Option<(usize, [f64; 4])> {
        let q = [x.x, x.y, x.z];
        let mut best: Option<(usize, [f64; 4], f64)> = None;
        for cand in self
            .tree
            .locate_in_envelope_intersecting(&AABB::from_point(q))
        {
            if !filter(cand.element) {
                continue;
            }
            let Some(l) = barycentric(&mesh.vertex_points(cand.element), x) else {
                continue;
            };
            let worst = l.iter().copied().fold(f64::INFINITY, f64::min);
            if best.as_ref().is_none_or(|b| worst > b.2) {
                best = Some((cand.element, l, worst));
            }
        }
        best.filter(|b| b.2 > -1e-6).map(|b| (b.0, b.1))
    }

    pub fn locate(&self, mesh: &TetMesh, x: &Point3<f64>) -> Option<(usize, [f64; 4])> {
        self.locate_with(mesh, x, |_| true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::box_mesh;

    #[test]
    fn finds_points_inside_on_faces_and_at_corners() {
        let m = box_mesh(Point3::origin(), Point3::new(1.0, 2.0, 3.0), [3, 4, 5]);
        let loc = Locator::new(&m);
        for p in [
            Point3::new(0.3, 0.7, 1.1),
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 2.0, 3.0),
            Point3::new(1.0 / 3.0, 0.5, 0.6 + 1e-13),
        ] {
            let (e, l) = loc.locate(&m, &p).expect("found");
            let back = m
                .vertex_points(e)
                .iter()
                .zip(l)
                .fold(nalgebra::Vector3::zeros(), |s, (q, w)| s + q.coords * w);
            assert!((back - p.coords).norm() < 1e-12);
            assert!(l.iter().all(|&w| w > -1e-9));
        }
        assert!(loc.locate(&m, &Point3::new(1.5, 0.5, 0.5)).is_none());
    }
}

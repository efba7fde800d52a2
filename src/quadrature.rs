//! Quadrature rules on the reference tetrahedron, in barycentric coordinates
//! with weights that sum to one (multiply by the tet volume).

/// A quadrature point: barycentric coordinates (λ0..λ3) and weight (fraction of the volume).
#[derive(Debug, Clone, Copy)]
pub struct QuadPoint {
    pub bary: [f64; 4],
    pub weight: f64,
}

const fn qp(bary: [f64; 4], weight: f64) -> QuadPoint {
    QuadPoint { bary, weight }
}

/// Degree 1: the centroid.
pub const DEGREE1: [QuadPoint; 1] = [qp([0.25; 4], 1.0)];

const A2: f64 = 0.585_410_196_624_968_5;
const B2: f64 = 0.138_196_601_125_010_5;
/// Degree 2: four points (Keast), all weights 1/4.
pub const DEGREE2: [QuadPoint; 4] = [
    qp([A2, B2, B2, B2], 0.25),
    qp([B2, A2, B2, B2], 0.25),
    qp([B2, B2, A2, B2], 0.25),
    qp([B2, B2, B2, A2], 0.25),
];

const W5A: f64 = 0.073_493_043_116_361_9;
const A5: f64 = 0.092_735_250_310_891_2;
const A5C: f64 = 1.0 - 3.0 * A5;
const W5B: f64 = 0.112_687_925_718_015_8;
const B5: f64 = 0.310_885_919_263_300_6;
const B5C: f64 = 1.0 - 3.0 * B5;
const W5C: f64 = 0.042_546_020_777_081_2;
const C5: f64 = 0.045_503_704_125_649_6;
const C5C: f64 = 0.5 - C5;
/// Degree 5: fourteen points with positive weights (Walkington).
pub const DEGREE5: [QuadPoint; 14] = [
    qp([A5C, A5, A5, A5], W5A),
    qp([A5, A5C, A5, A5], W5A),
    qp([A5, A5, A5C, A5], W5A),
    qp([A5, A5, A5, A5C], W5A),
    qp([B5C, B5, B5, B5], W5B),
    qp([B5, B5C, B5, B5], W5B),
    qp([B5, B5, B5C, B5], W5B),
    qp([B5, B5, B5, B5C], W5B),
    qp([C5, C5, C5C, C5C], W5C),
    qp([C5, C5C, C5, C5C], W5C),
    qp([C5, C5C, C5C, C5], W5C),
    qp([C5C, C5, C5, C5C], W5C),
    qp([C5C, C5, C5C, C5], W5C),
    qp([C5C, C5C, C5, C5], W5C),
];

/// The cheapest rule here that integrates polynomials of `degree` exactly.
pub fn rule(degree: usize) -> &'static [QuadPoint] {
    match degree {
        0 | 1 => &DEGREE1,
        2 => &DEGREE2,
        _ => &DEGREE5,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn factorial(n: u32) -> f64 {
        (1..=n).map(f64::from).product()
    }

    /// ∫ λ0^a λ1^b λ2^c λ3^d dV / V = a! b! c! d! 3! / (a+b+c+d+3)!.
    fn exact(p: [u32; 4]) -> f64 {
        let s: u32 = p.iter().sum();
        p.iter().map(|&k| factorial(k)).product::<f64>() * 6.0 / factorial(s + 3)
    }

    #[test]
    fn rules_integrate_monomials_of_their_degree_exactly() {
        for (degree, rule) in [(1, &DEGREE1[..]), (2, &DEGREE2[..]), (5, &DEGREE5[..])] {
            for a in 0..=degree {
                for b in 0..=degree - a {
                    for c in 0..=degree - a - b {
                        for d in 0..=degree - a - b - c {
                            let p = [a, b, c, d];
                            let q: f64 = rule
                                .iter()
                                .map(|q| {
                                    q.weight
                                        * (0..4)
                                            .map(|i| q.bary[i].powi(p[i] as i32))
                                            .product::<f64>()
                                })
                                .sum();
                            assert!(
                                (q - exact(p)).abs() < 1e-14,
                                "degree {degree} rule on {p:?}: {q} vs {}",
                                exact(p)
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn weights_are_positive_and_points_inside() {
        for q in DEGREE1.iter().chain(&DEGREE2).chain(&DEGREE5) {
            assert!(q.weight > 0.0);
            assert!(q.bary.iter().all(|&l| l > 0.0));
            assert!((q.bary.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        }
    }
}

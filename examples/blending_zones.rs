//! Where the energy error of geometric tip enrichment lies: the exact
//! near-front Williams field (`study::exact::WilliamsFront`, the report's
//! `near_front`) on the structured unit box, `tip_radius` R, with the
//! blending a case takes (or `ramp` / `none`), and the share of the energy
//! error² in the elements all of whose vertices lie within R ("enriched"),
//! those where some do ("blending": with the ramp, where it falls from 1 to
//! 0) and the rest, by the distance of their centroid from the front in
//! elements.
//!
//! Why it is here: Tet10's last orders on that field stay near 2.7 / 1.7
//! (L2 / energy; 2.72 / 1.66 from n = 8 to 12, 2.79 / 1.74 to 16, 2.68 /
//! 1.69 to 20) where geometric enrichment should restore 3 / 2. Standard
//! X-FEM's blending (the branch functions on an incomplete partition of
//! unity) is the usual suspect for p > 1, but it is not what this shows
//! (Tet10, R = 0.2, no ramp): the blending elements' part of the relative
//! energy error goes 2.07e-2 / 9.67e-3 / 5.44e-3 at n = 8 / 12 / 16 (order
//! 1.9–2.0, 66 / 56 / 48 % of the error²), while the fully enriched
//! elements' part, where the field lies in the space, goes 9.85e-3 /
//! 6.40e-3 / 4.45e-3 (order 1.1–1.3; that zone widens in elements as R / h
//! grows, so the zones do not compare level to level exactly), and the
//! standard elements' 1.10e-2 / 5.82e-3 / 3.55e-3. The one-element ramp
//! moves the error into its blending layer (n = 12: 64 %) and leaves the
//! order (`tests/front.rs blending_measure_tet10`). The quadrature in part:
//! with the Tet10 front cells' collapsed rules 5 → 8 points a direction, the
//! polar rule's (4, 3) → (7, 5) and the cells near the front red-refined 3
//! deep out to twice their size (1 deep out to half), the energy errors at
//! n = 8 and 12 moved by under 0.4 %, at n = 16 and 20 by 1.4 and 3.5 %
//! (7.87e-3 → 7.76e-3, 5.40e-3 → 5.21e-3; the last order 1.69 → 1.79). With
//! every node enriched (R = 10), where the field lies in the space, the solve
//! errs 1.5e-3 … 2.2e-3 in energy at n = 4 and 6 (Tet4 and Tet10) against 1e-12 for
//! the field's own DOFs: the rules' consistency error, 2.7e-4 … 4.2e-4 with
//! the rules above.
//!
//! What limits Tet10 is the blending layer itself, which the field's nodal
//! interpolant (`WilliamsFront::interpolant`, printed per zone) shows: it
//! is the field in the fully enriched elements (error 1e-12) and errs
//! 3.27e-2 / 1.84e-2 / 1.23e-2 in the blending elements at n = 8 / 12 / 16
//! (order 1.43, 1.40): there the partial partition of unity Σ_{k∈I} λ_k,
//! gradient 1/h, multiplies the branch functions, and what the quadratic
//! functions must make up of them errs O(h^1.5) in energy. With the ramp
//! the interpolant is the same function (`ramp`: the same figures). The
//! Galerkin solution beats the interpolant in the blending layer (order
//! 1.9–2.0 above) by moving error into the enriched elements (1.0–1.3); its
//! orders stay under 2 with that trade. A blending function smooth over a
//! width that does not shrink with h is the known remedy (cutoff-function
//! enrichment); it is not built.
//!
//! `cargo run --release --example blending_zones -- N R [tet4|tet10] [ramp|none]`
//! (e.g. `12 0.2 tet10`: 2 s).
use xfem_cut::cut::{setup_cut, Blending, CutInput, FrontMode, DEFAULT_SNAP};
use xfem_cut::material::Lame;
use xfem_cut::mesh::ElementKind;
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};
use xfem_cut::study::exact::{energy_density, linear_model, unit_box, WilliamsFront, MATERIAL};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: blending_zones N R [tet4|tet10] [ramp|none]";
    let n: usize = args.first().and_then(|s| s.parse().ok()).expect(usage);
    let radius: f64 = args.get(1).and_then(|s| s.parse().ok()).expect(usage);
    let kind = match args.get(2).map(String::as_str) {
        Some("tet4") => ElementKind::Tet4,
        None | Some("tet10") => ElementKind::Tet10,
        Some(other) => panic!("{usage}: element {other}"),
    };
    let blending = match args.get(3).map(String::as_str) {
        None => Blending::for_cut(FrontMode::Tip, Some(radius), kind),
        Some("ramp") => Blending::Ramp,
        Some("none") => Blending::None,
        Some(other) => panic!("{usage}: blending {other}"),
    };
    let front = WilliamsFront::new();
    let mesh = unit_box(n, kind, 0.0);
    let patch = front.patch();
    let input = CutInput {
        surface: &patch,
        snap: DEFAULT_SNAP,
        front: FrontMode::Tip,
        tip_radius: Some(radius),
        blending,
    };
    let cut = setup_cut(&mesh, &[input]).expect("the front's cut");
    let fixed = front.boundary_values(&mesh, &cut);
    let model = linear_model(mesh, Some(cut), fixed).expect("the model");
    let mut chol = Cholesky::new(&model.pattern).expect("the factor");
    let sol = solve_static(&model, &mut chol, &StaticOptions::default()).expect("the solve");
    let lame = Lame::from(MATERIAL);
    let cut = model.cut.as_ref().expect("a cut");
    // The field's nodal interpolant: exact where every vertex is in I.
    let interpolant = front.interpolant(&model.mesh, cut, model.n_shape);
    let h = 1.0 / n as f64;
    let mut zones = std::collections::BTreeMap::<(&str, usize), (f64, usize)>::new();
    // Per zone: the interpolant's error².
    let mut interpolated = std::collections::BTreeMap::<&str, f64>::new();
    let (mut total, mut norm) = (0.0, 0.0);
    for e in 0..model.mesh.n_elements() {
        let p = model.mesh.vertex_points(e);
        let centroid = (p[0].coords + p[1].coords + p[2].coords + p[3].coords) / 4.0;
        let d = centroid - front.c.coords;
        let rho = (d - front.t * d.dot(&front.t)).norm();
        // The vertices in I (with the ramp, its ring carries branch
        // functions too, ramped down: its elements blend).
        let in_i = |i: usize| {
            if cut.ramp.is_empty() {
                cut.tip[i].is_some()
            } else {
                cut.ramp[i]
            }
        };
        let enriched = model.mesh.vertices(e).iter().filter(|&&i| in_i(i)).count();
        let zone = match enriched {
            4 => "enriched",
            0 => "standard",
            _ => "blending",
        };
        let (mut err, mut err_i) = (0.0, 0.0);
        for (x, w, side) in model.field_points(e) {
            let (_, gh) = model.field_at(&sol.d, e, &x, side);
            let (_, gi) = model.field_at(&interpolant, e, &x, side);
            let (_, g) = front.exact(&x, side);
            err += w * energy_density(&(gh - g), &lame);
            err_i += w * energy_density(&(gi - g), &lame);
            norm += w * energy_density(&g, &lame);
        }
        *interpolated.entry(zone).or_insert(0.0) += err_i;
        total += err;
        let band = ((rho / h).floor() as usize).min(9);
        let z = zones.entry((zone, band)).or_insert((0.0, 0));
        z.0 += err;
        z.1 += 1;
    }
    println!(
        "{kind:?} n = {n}, R = {radius} ({:.1} h), {blending:?}: {} free DOFs, {} tip nodes, energy error {:.4e}",
        radius / h,
        model.n_free,
        cut.n_tip(),
        (total / norm).sqrt()
    );
    let mut by_zone = std::collections::BTreeMap::<&str, (f64, usize)>::new();
    for ((zone, band), (err, count)) in &zones {
        let z = by_zone.entry(zone).or_insert((0.0, 0));
        z.0 += err;
        z.1 += count;
        if *err >= 0.01 * total {
            let within = if *band == 9 {
                "9+".to_string()
            } else {
                format!("{band}–{}", band + 1)
            };
            println!(
                "  {zone:8} centroid {within} h from the front: {:5.1} % of the error² in {count} elements",
                100.0 * err / total
            );
        }
    }
    for (zone, (err, count)) in by_zone {
        println!(
            "  {zone:8} in all: {:5.1} % in {count} elements (its part of the relative energy error: {:.4e}; the interpolant's: {:.4e})",
            100.0 * err / total,
            (err / norm).sqrt(),
            (interpolated[zone] / norm).sqrt()
        );
    }
}

//! Code verification with exact solutions (issue 14): the manufactured
//! solution with a jump across a through-cut and the near-front Williams
//! field, through `xfem_cut::study::exact`, the same code the report runs.

use nalgebra::{Matrix3, Point3, Vector3};
use xfem_cut::assembly::{field_load, FieldLoadAt};
use xfem_cut::cut::{setup_cut, CutInput, DEFAULT_SNAP};
use xfem_cut::material::Lame;
use xfem_cut::mesh::{ElementKind, TetMesh};
use xfem_cut::model::Model;
use xfem_cut::solve::Cholesky;
use xfem_cut::statics::{solve_static, StaticOptions};
use xfem_cut::study::exact::{
    check_radius_sweep, last_orders, linear_model, radius_sweep, relative_errors, run_study,
    stress, study_variants, unit_box, Case, Row, ThroughCut, MATERIAL,
};

#[test]
fn the_manufactured_body_force_is_minus_div_sigma_by_nested_differences() {
    let tc = ThroughCut::new();
    let lame = Lame::from(MATERIAL);
    let h = 1e-3;
    for field in [&tc.plus, &tc.minus] {
        for x in [
            Point3::new(0.2, 0.3, 0.4),
            Point3::new(0.7, 0.6, 0.1),
            Point3::new(0.5, 0.9, 0.8),
        ] {
            // Gradient by central differences of the values.
            let grad_fd = |y: &Point3<f64>| {
                let mut g = Matrix3::zeros();
                for j in 0..3 {
                    let mut e = Vector3::zeros();
                    e[j] = h;
                    g.set_column(
                        j,
                        &((field.value(&(y + e)) - field.value(&(y - e))) / (2.0 * h)),
                    );
                }
                g
            };
            let g = field.gradient(&x);
            let gerr = (grad_fd(&x) - g).norm() / g.norm();
            // div σ by central differences of the stress of the differenced gradient.
            let mut div = Vector3::zeros();
            for j in 0..3 {
                let mut e = Vector3::zeros();
                e[j] = h;
                let sp = stress(&grad_fd(&(x + e)), &lame);
                let sm = stress(&grad_fd(&(x - e)), &lame);
                div += (sp.column(j) - sm.column(j)) / (2.0 * h);
            }
            let f = field.body_force(&x, &lame);
            let ferr = (f + div).norm() / f.norm();
            println!(
                "at {:?}: gradient {gerr:.1e}, body force {ferr:.1e} (|f| = {:.3})",
                x.coords,
                f.norm()
            );
            assert!(gerr < 1e-5 && ferr < 1e-4, "{gerr:e} {ferr:e}");
        }
    }
}

#[test]
fn field_load_integrates_volumes_and_both_cut_faces() {
    // Partition of unity: the standard DOFs' loads sum to ∫ f dV and ∫ t dA.
    // A constant body force over the unit box gives its volume; a constant
    // traction on the + face of the plane gives its section's area, which for
    // a plane y = y(x, z) over the whole (x, z) square is 1 / |n_y|.
    let tc = ThroughCut::new();
    let patch = tc.patch();
    let area = 1.0 / tc.n.y.abs();
    for (kind, div) in [
        (ElementKind::Tet4, 3),
        (ElementKind::Tet4, 5),
        (ElementKind::Tet10, 3),
    ] {
        let mesh = unit_box(div, kind, 0.2);
        let cut = setup_cut(&mesh, &[CutInput::extend(&patch, DEFAULT_SNAP)]).unwrap();
        let model = linear_model(mesh, Some(cut), vec![]).unwrap();
        let n = model.mesh.n_nodes();
        let total = |load: &[f64]| {
            (0..n).fold(Vector3::zeros(), |s, i| {
                s + Vector3::new(load[3 * i], load[3 * i + 1], load[3 * i + 2])
            })
        };
        let volume = total(&field_load(&model, |_, _, at| match at {
            FieldLoadAt::Volume => Vector3::new(1.0, 2.0, 3.0),
            FieldLoadAt::CutFace { .. } => Vector3::zeros(),
        }));
        let face = total(&field_load(&model, |_, side, at| match at {
            FieldLoadAt::CutFace { normal } if side > 0 => {
                // The + side's outward normal is −n.
                assert!((normal + tc.n).norm() < 1e-9, "{normal:?}");
                Vector3::new(1.0, 0.0, 0.0)
            }
            FieldLoadAt::CutFace { normal } => {
                assert!((normal - tc.n).norm() < 1e-9 && side < 0);
                Vector3::zeros()
            }
            FieldLoadAt::Volume => Vector3::zeros(),
        }));
        println!(
            "{kind:?} n {div}: ∫f {:?}, ∫t {:.15} (plane section {area:.15})",
            volume.as_slice(),
            face.x
        );
        assert!((volume - Vector3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        assert!((face.x - area).abs() < 1e-12 && face.yz().norm() == 0.0);
    }
}

/// A cut along element faces (a node layer, and the diagonal plane x = z
/// through nodes and faces of the structured box): `field_load` takes the
/// traction on those faces from each side. (It took it only on the faces
/// of sub-tets, which such a cut has none of, and the through cut's
/// manufactured solution on the layer did not converge: L2 5.9e-2 →
/// 6.7e-2 from n = 8 to 16.) Asserted: the + face's constant traction sums
/// to the plane's section, the − face's to nothing, each with its outward
/// normal; and the manufactured solution on both planes converges at the
/// smooth rates with errors within 1.2× of the plane moved 0.013 off them
/// (Tet4 n = 8, 16: L2 1.18e-2, 3.11e-3 on the layer; Tet10 n = 4, 6: 1.41e-3, 4.01e-4).
#[test]
fn a_cut_along_element_faces_takes_its_traction_and_converges() {
    let lame = Lame::from(MATERIAL);
    let s2 = 0.5f64.sqrt();
    for (name, normal, area) in [
        ("layer z = 0.5", Vector3::z(), 1.0),
        ("plane x = z", Vector3::new(s2, 0.0, -s2), 2f64.sqrt()),
    ] {
        let at = |dz: f64| ThroughCut {
            c: Point3::new(0.5, 0.5, 0.5 + dz),
            n: normal,
            ..ThroughCut::new()
        };
        let on = at(0.0);
        for (kind, div) in [(ElementKind::Tet4, 4), (ElementKind::Tet10, 2)] {
            let model = through_model(&on, unit_box(div, kind, 0.0));
            let n = model.mesh.n_nodes();
            let face = field_load(&model, |_, side, at| match at {
                FieldLoadAt::CutFace { normal: out } => {
                    assert!((out + normal * f64::from(side)).norm() < 1e-12, "{out:?}");
                    Vector3::new(f64::from(u8::from(side > 0)), 0.0, 0.0)
                }
                FieldLoadAt::Volume => Vector3::zeros(),
            });
            let sum: f64 = (0..n).map(|i| face[3 * i]).sum();
            println!("{name}, {kind:?} n {div}: ∫t {sum:.15} (section {area:.15})");
            assert!((sum - area).abs() < 1e-12, "{name}: {sum}");
        }
        for (kind, divs, order) in [
            (ElementKind::Tet4, [8, 16], 1.8),
            (ElementKind::Tet10, [4, 6], 2.7),
        ] {
            let errors = |tc: &ThroughCut| {
                divs.map(|div| {
                    let mut model = through_model(tc, unit_box(div, kind, 0.0));
                    let load = field_load(&model, |x, side, at| tc.load(x, side, at, &lame));
                    for (l, f) in model.load.iter_mut().zip(load) {
                        *l += f;
                    }
                    let mut chol = Cholesky::new(&model.pattern).unwrap();
                    let sol = solve_static(&model, &mut chol, &StaticOptions::default()).unwrap();
                    relative_errors(&model, &sol.d, |x, s| tc.exact(x, s)).0
                })
            };
            let (e, off) = (errors(&on), errors(&at(0.013)));
            let rate = (e[0] / e[1]).ln() / (divs[1] as f64 / divs[0] as f64).ln();
            println!(
                "{name}, {kind:?}: L2 {:.3e} → {:.3e} (order {rate:.2}), off it {:.3e} → {:.3e}",
                e[0], e[1], off[0], off[1]
            );
            assert!(rate >= order, "{name} {kind:?}: order {rate}");
            assert!(
                e[1] <= 1.2 * off[1],
                "{name} {kind:?}: {} vs {}",
                e[1],
                off[1]
            );
        }
    }
}

/// The through cut `tc` on `mesh`: X-FEM Heaviside, every boundary node
/// prescribed from its side's field.
fn through_model(tc: &ThroughCut, mesh: TetMesh) -> Model {
    let cut = setup_cut(&mesh, &[CutInput::extend(&tc.patch(), DEFAULT_SNAP)]).unwrap();
    let fixed = tc.boundary_values(&mesh, &cut);
    linear_model(mesh, Some(cut), fixed).unwrap()
}

fn print(rows: &[Row]) {
    for r in rows {
        println!(
            "{} {} {} n {:2}: {:6} DOFs, {:4} Heaviside, {:4} tip: L2 {:.3e} energy {:.3e} ({:.1} s)",
            r.case, r.variant, r.element, r.divisions, r.dofs, r.heaviside, r.tip, r.l2, r.energy, r.seconds
        );
    }
}

#[test]
fn through_cut_jump_converges_at_the_smooth_rates() {
    for v in study_variants()
        .iter()
        .filter(|v| v.case == Case::ThroughCut)
    {
        let rows = run_study(std::slice::from_ref(v), |_| {}).unwrap();
        print(&rows);
        let refs: Vec<&Row> = rows.iter().collect();
        let (l2, en) = last_orders(&refs).unwrap();
        let (tl2, ten) = (v.theory.0.unwrap(), v.theory.1.unwrap());
        println!(
            "{} {}: orders L2 {l2:.2} (theory {tl2}), energy {en:.2} (theory {ten})",
            v.name,
            v.kind.name()
        );
        assert!(
            (l2 - tl2).abs() <= 0.2 && (en - ten).abs() <= 0.2,
            "{l2} {en}"
        );
    }
}

#[test]
fn near_front_geometric_tip_tet4_converges_at_the_rates_of_issue_11() {
    // Issue 11: geometric tip enrichment, Tet4, L2 order ≥ 1.8 and energy ≥ 0.85
    // (theory 2 / 1); the variant the report's code-verification section runs,
    // a case's default, over n = 16 → 24. There R = 0.2 spans 2.5 and 3.8
    // median edges, so the default ramps the blending elements
    // (`cut::RAMP_SPAN`). Standard X-FEM (no ramp) gave 1.80 / 0.87 here and
    // 1.84 / 0.84 over 24 → 32 (the blending elements' error): the energy
    // order ≥ 0.9 asserted below fails without the ramp. The report runs it
    // to n = 32 (a minute a level, too slow here).
    let mut v = study_variants()
        .into_iter()
        .find(|v| {
            v.case == Case::NearFront
                && v.kind == ElementKind::Tet4
                && v.tip_radius.is_some()
                && v.name == "geometric tip R=0.2"
        })
        .unwrap();
    v.divisions = vec![16, 24];
    let rows = run_study(&[v], |_| {}).unwrap();
    print(&rows);
    let refs: Vec<&Row> = rows.iter().collect();
    let (l2, en) = last_orders(&refs).unwrap();
    println!("near front geometric tip tet4: orders L2 {l2:.2}, energy {en:.2}");
    assert!(l2 >= 1.8 && en >= 0.9, "{l2} {en}");
}

#[test]
fn near_front_geometric_tip_tet10_converges_faster_and_beats_tet4_at_fewer_dofs() {
    // Issue 11: Tet10 more accurate than Tet4 at equal DOFs. The report's
    // Tet10 variants, structured and jittered, at n = 8 and 12 (about 12 s):
    // measured L2 / energy orders 2.72 / 1.66 and 2.92 / 1.79 (theory 3 / 2;
    // structured 2.03 / 0.93 from n = 4 to 6, which is before the asymptotic
    // range: R = 0.2 is about one element there). The structured n = 8
    // (12006 DOFs) against the Tet4 variant at n = 16 (19260 DOFs, its
    // blending elements ramped as a case's default ramps them there): L2
    // 6.6e-4 against 1.9e-3, energy 2.5e-2 against 6.2e-2 (standard X-FEM
    // Tet4: 4.0e-3 and 1.4e-1 at 16650 DOFs).
    let geometric = |kind| {
        study_variants()
            .into_iter()
            .filter(move |v| v.case == Case::NearFront && v.kind == kind && v.tip_radius.is_some())
    };
    let mut variants: Vec<_> = geometric(ElementKind::Tet10)
        .map(|mut v| {
            v.divisions = vec![8, 12];
            v
        })
        .collect();
    assert_eq!(variants.len(), 2);
    let mut tet4 = geometric(ElementKind::Tet4)
        .find(|v| v.jitter == 0.0)
        .unwrap();
    tet4.divisions = vec![16];
    variants.push(tet4);
    let rows = run_study(&variants, |_| {}).unwrap();
    print(&rows);
    for name in ["geometric tip R=0.2", "geometric tip R=0.2 jittered"] {
        let t10: Vec<&Row> = rows
            .iter()
            .filter(|r| r.element == "tet10" && r.variant == name)
            .collect();
        let (l2, en) = last_orders(&t10).unwrap();
        println!("near front {name} tet10: orders L2 {l2:.2}, energy {en:.2}");
        assert!(l2 >= 2.5 && en >= 1.5, "{name}: {l2} {en}");
    }
    let coarse = rows
        .iter()
        .find(|r| r.element == "tet10" && r.divisions == 8 && !r.variant.contains("jittered"))
        .unwrap();
    let t4 = rows.iter().find(|r| r.element == "tet4").unwrap();
    assert!(coarse.dofs < t4.dofs, "{} {}", coarse.dofs, t4.dofs);
    assert!(
        coarse.l2 < t4.l2 / 2.0 && coarse.energy < t4.energy / 2.0,
        "Tet10 {:.3e} {:.3e}, Tet4 {:.3e} {:.3e}",
        coarse.l2,
        coarse.energy,
        t4.l2,
        t4.energy
    );
}

#[test]
fn boundary_values_give_each_sides_field_at_boundary_nodes_from_both_sides() {
    // The prescribed standard and Heaviside DOFs of a boundary node make
    // u_i + ψ(s) a_i the exact field of side s at the node, for s = ±1, at
    // every enriched boundary node (Tet10 mid-nodes included).
    let tc = ThroughCut::new();
    for kind in [ElementKind::Tet4, ElementKind::Tet10] {
        let model = through_model(&tc, unit_box(4, kind, 0.2));
        let mut d = vec![0.0; model.n_dofs()];
        for p in &model.prescribed {
            d[p.dof] = p.value;
        }
        let c = model.cut.as_ref().unwrap();
        let (mut checked, mut worst) = (0, 0.0f64);
        for (i, x) in model.mesh.nodes.iter().enumerate() {
            let boundary = (0..3).any(|k| x[k].abs() < 1e-12 || (x[k] - 1.0).abs() < 1e-12);
            if !boundary || c.enriched[i].is_none() {
                continue;
            }
            for side in [1, -1] {
                let u = model.node_displacement(&d, i, side);
                worst = worst.max((u - tc.exact(x, side).0).norm());
            }
            checked += 1;
        }
        println!("{kind:?}: {checked} enriched boundary nodes, worst |u_h − u_side| {worst:.1e}");
        assert!(checked > 10 && worst < 1e-14, "{checked} {worst:e}");
    }
}

#[test]
fn the_precut_mesh_is_conforming_and_split_by_the_plane() {
    // Its boundary is the box's six faces and both faces of the plane section
    // (no face left unmatched between neighbours), every element on one side.
    use xfem_cut::study::exact::precut_mesh;
    let tc = ThroughCut::new();
    let section = 1.0 / tc.n.y.abs();
    for (div, jitter) in [(4, 0.0), (5, 0.2)] {
        let mesh = unit_box(div, ElementKind::Tet4, jitter);
        let (m, side) = precut_mesh(&mesh, |x| tc.level_set(x), ElementKind::Tet4);
        let (mut outer, mut plane, mut stray) = (0.0, 0.0, 0);
        for (f, _) in m.boundary_faces() {
            let p = f.map(|i| m.nodes[i]);
            let area = 0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
            let on_box = (0..3).any(|c| {
                p.iter().all(|x| x[c].abs() < 1e-12) || p.iter().all(|x| (x[c] - 1.0).abs() < 1e-12)
            });
            if on_box {
                outer += area;
            } else if p.iter().all(|x| tc.level_set(x).abs() < 1e-12) {
                plane += area;
            } else {
                stray += 1;
            }
        }
        let volume: f64 = (0..m.n_elements()).map(|e| m.volume(e)).sum();
        let wrong_side = (0..m.n_elements())
            .filter(|&e| {
                let c = m
                    .vertex_points(e)
                    .iter()
                    .fold(Vector3::zeros(), |s, p| s + p.coords)
                    / 4.0;
                let s = if tc.level_set(&c.into()) >= 0.0 {
                    1
                } else {
                    -1
                };
                m.element(e).iter().any(|&i| side[i] != s)
            })
            .count();
        println!("n {div} jitter {jitter}: {} tets, outer faces {outer:.15}, plane faces {plane:.15} (2 × {section:.15}), {stray} stray, volume {volume:.15}, {wrong_side} on the wrong side", m.n_elements());
        assert_eq!(stray, 0);
        assert_eq!(wrong_side, 0);
        assert!((outer - 6.0).abs() < 1e-12 && (plane - 2.0 * section).abs() < 1e-12);
        assert!((volume - 1.0).abs() < 1e-12);
    }
}

#[test]
fn a_larger_tip_radius_buys_accuracy_for_its_dofs() {
    // The report's `tip_radius` sweep, run here (about 15 s): the errors fall
    // as R enriches more nodes, Tet4 and Tet10.
    let rows = run_study(&radius_sweep(), |_| {}).unwrap();
    print(&rows);
    let refs: Vec<&Row> = rows.iter().collect();
    if let Err(e) = check_radius_sweep(&refs) {
        panic!("{e}");
    }
}

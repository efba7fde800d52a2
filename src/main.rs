//! The `xfem-cut` command line: a thin layer over the library.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use xfem_cut::run::{probe_values, solve_scene_observed, Progress};
use xfem_cut::scene::Scene;
use xfem_cut::solve::Parallelism;

/// mimalloc keeps freed memory for reuse: a cut event builds the model's
/// arrays anew, and the system allocator hands them back to the kernel and
/// faults them in zeroed again at the next event (a 10k-tet linear event
/// spent a third of its time in page faults).
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "xfem-cut",
    version,
    about = "Surgical cutting of soft tissue: corotational FEM + X-FEM cuts, static and Newmark dynamics"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Solve a scene at one refinement level; writes DIR/result.vtu (+ result.pvd series for
    /// dynamic runs) and DIR/probes.csv (x,y,z,ux,uy,uz) when the case lists probes.
    #[command(
        after_help = "Environment: XFEM_THREADS=N runs the element loops (and a blade sweep's cut events) on N threads and, from 4k equations in scenes without a blade, factorises in two halves side by side (default 1)."
    )]
    Run {
        /// The case file (TOML).
        case: PathBuf,
        /// Refinement level (index into [body] levels or mesh list).
        #[arg(long, default_value_t = 0)]
        level: usize,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Solve on this gmsh mesh instead of the case's own (e.g. a pre-cut reference mesh).
        #[arg(long)]
        mesh: Option<PathBuf>,
    },
    /// Convergence study: every variant (FEM on pre-cut meshes, X-FEM on structured and
    /// unstructured meshes; Tet4, Tet10) at every level, L2 error against the fine FEniCSx
    /// reference (`make refs`). Rows of these cases replace theirs in the CSV.
    Converge {
        /// Case files (each needs refs/out/<name>/*_fine/p2.vtu).
        cases: Vec<PathBuf>,
        /// Output CSV [default: reports/data/convergence.csv, or
        /// reports/data/convergence_corot.csv with --corotational].
        #[arg(long)]
        csv: Option<PathBuf>,
        /// Skip runs with more DOFs than this.
        #[arg(long, default_value_t = 250_000)]
        max_dofs: usize,
        /// Solve every variant corotational (static Newton) and compare with our
        /// corotational Tet10 FEM solution on the finest pre-cut level within
        /// --max-dofs (levels below it run).
        #[arg(long)]
        corotational: bool,
        /// Code verification instead: the exact-solution cases (a manufactured jump across
        /// a through-cut, the near-front Williams field) at every level, L2 and energy
        /// errors [CSV default: reports/data/exact.csv; skipped when its inputs' hash,
        /// kept in <CSV>.hash, is unchanged].
        #[arg(long, conflicts_with_all = ["cases", "corotational"])]
        exact: bool,
    },
    /// The stability stress suite: cuts near nodes, crack fronts near nodes, edges and faces, ν → 0.5, dt sweep, 10⁴ undamped steps,
    /// a freed fragment falling and tumbling, 90°/180° twists, inverted elements.
    /// Each row has a pass/fail criterion; exits non-zero if one fails.
    Stress {
        #[arg(long, default_value = "reports/data/stress.csv")]
        csv: PathBuf,
        /// Run only the families whose name contains this (near-node, front-near, poisson, dt, long,
        /// fragment, rotation, inverted); the CSV is then not written.
        #[arg(long, default_value = "")]
        only: String,
    },
    /// (Re)write reports/README.md and its plots from the CSVs, the FEniCSx manifests and criterion's estimates.
    Report {
        #[arg(long, default_value = "reports")]
        dir: PathBuf,
        #[arg(long, default_value = "target/criterion")]
        criterion: PathBuf,
    },
}

fn main() {
    if let Err(e) = run() {
        // Our errors carry their causes in their own message: print the top one.
        eprintln!("error: {}", e.to_string().replace('\n', " "));
        std::process::exit(1);
    }
}

/// Threads of a run: `XFEM_THREADS` (default 1, the per-core figures the
/// report quotes).
fn threads() -> Result<usize> {
    match std::env::var("XFEM_THREADS") {
        Err(_) => Ok(1),
        Ok(v) => match v.trim().parse::<usize>() {
            Ok(n) if n >= 1 => Ok(n),
            _ => anyhow::bail!(
                "environment variable XFEM_THREADS: expected a whole number ≥ 1, got {v:?}"
            ),
        },
    }
}

fn run() -> Result<()> {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) => {
            use clap::error::ErrorKind;
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                e.exit();
            }
            // Bad arguments: clap's message up to its usage hint, on one line
            // (as for cases), naming the argument and the value.
            let text = e.to_string();
            let message: Vec<&str> = text
                .lines()
                .take_while(|l| !l.trim().is_empty() && !l.starts_with("Usage:"))
                .map(str::trim)
                .collect();
            eprintln!("{}", message.join(" "));
            std::process::exit(2);
        }
    };
    match cli.command {
        Command::Run {
            case,
            level,
            out,
            mesh,
        } => {
            let scene = Scene::load(&case)?;
            let threads = threads()?;
            // Refused before the solve rather than after it.
            if out.exists() && !out.is_dir() {
                anyhow::bail!("--out {}: exists and is not a directory", out.display());
            }
            // Where the solve is, on a terminal only (hidden in logs): a
            // soft corotational scene's Newton can take minutes.
            // The plan is printed as soon as it is known (before the solve;
            // a blade's with the sizes of its start), so a long run shows
            // what it does.
            let bar = indicatif::ProgressBar::new_spinner();
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
            let mut planned = false;
            let result = solve_scene_observed(
                &scene,
                level,
                mesh.as_deref(),
                true,
                Parallelism::threads(threads),
                &mut |p| match p {
                    Progress::Planned(plan) => {
                        bar.suspend(|| {
                            println!("{}: {}", scene.name, scene.description);
                            println!("{plan}");
                        });
                        planned = true;
                    }
                    Progress::Newton(n) => bar.set_message(format!(
                        "static: load {:.4}, Newton iteration {}, relative residual {:.2e}",
                        n.lambda, n.iteration, n.residual
                    )),
                    Progress::Step { step, steps, time } => {
                        bar.set_message(format!("dynamic: step {step} of {steps}, t = {time:.4} s"))
                    }
                },
            );
            bar.finish_and_clear();
            let result = result?;
            if !planned {
                println!("{}: {}", scene.name, scene.description);
                println!("{}", result.plan);
            }
            let t = result.timings;
            if result.sweep.is_some() {
                // A blade's cut is set up and its model built at each cut event.
                println!(
                    "precompute: mesh {:.1} ms, selections {:.1} ms (the cut set-up, element data and factorisations are made at the start and at each cut event: see the sweep below)",
                    t.mesh * 1e3,
                    t.model * 1e3,
                );
            } else if t.symbolic_beside {
                // `refs/bench_static.py` reads this line.
                println!(
                    "precompute: mesh {:.1} ms, cut set-up {:.1} ms, element data + pattern with the symbolic factorisation beside it {:.1} ms (symbolic factorisation {:.1} ms)",
                    t.mesh * 1e3,
                    t.cut * 1e3,
                    t.model * 1e3,
                    t.symbolic * 1e3
                );
            } else {
                println!(
                    "precompute: mesh {:.1} ms, cut set-up {:.1} ms, element data + pattern {:.1} ms, symbolic factorisation {:.1} ms",
                    t.mesh * 1e3,
                    t.cut * 1e3,
                    t.model * 1e3,
                    t.symbolic * 1e3
                );
            }
            if threads > 1 {
                println!("threads: {threads} (XFEM_THREADS; factorisations and element loops)");
            }
            if let Some(factor) = &result.factor {
                if result.sweep.is_some() {
                    println!("factor (the sweep's last): {factor}");
                } else {
                    println!("factor: {factor}");
                }
            }
            if t.steps > 0 {
                println!(
                    "dynamic: {} steps in {:.1} ms ({:.3} ms/step), {} factorisations, Newton iterations per step max {}",
                    t.steps,
                    t.solve * 1e3,
                    t.solve * 1e3 / t.steps as f64,
                    result.factorisations,
                    result.iterations.iter().max().unwrap_or(&0)
                );
                if let Some(steps) = &result.steps {
                    println!("per step: {steps}");
                }
                if let (Some(sweep), Some([cutting, other])) =
                    (&result.sweep, &result.steps_while_cutting)
                {
                    println!(
                        "per step while the blades cut (t in ({}, {}] s): {cutting}",
                        sweep.start,
                        sweep.cut_until()
                    );
                    // Steps before the first blade starts, after the last ends.
                    let before = sweep.series.first().is_some_and(|s| s.0 <= sweep.start);
                    let after = sweep.end < sweep.run_end;
                    let when = match (before, after) {
                        (true, true) => "before and after",
                        (true, false) => "before",
                        (false, true) => "after",
                        (false, false) => "",
                    };
                    if other.steps > 0 {
                        println!("per step {when}: {other}");
                    }
                }
                if let Some(sweep) = &result.sweep {
                    let mut times: Vec<f64> = sweep.series.iter().map(|s| s.1).collect();
                    times.sort_by(f64::total_cmp);
                    if let Some(&max) = times.last() {
                        println!(
                            "per step (Newton solve, events apart): median {:.3} ms, max {:.3} ms",
                            times[times.len() / 2] * 1e3,
                            max * 1e3
                        );
                    }
                    println!("{sweep}");
                }
            } else {
                println!(
                    "static: solve {:.1} ms, Newton iterations per load step {:?}, relative residual {:.2e}, {} factorisations{}",
                    t.solve * 1e3,
                    result.iterations,
                    result.residual,
                    result.factorisations,
                    match result.cutbacks {
                        0 => String::new(),
                        n => format!(", {n} load steps halved (Newton did not finish them)"),
                    }
                );
            }
            // A state turned inside out is written (it is the model's
            // answer) but not passed off as physical.
            if let Some(inverted) = xfem_cut::run::inversion(&result) {
                eprintln!("warning: {}: {inverted}", scene.file.display());
            }
            // The probes' values first: an error writes nothing.
            let values = probe_values(&scene, &result)?;
            std::fs::create_dir_all(&out)
                .map_err(|e| anyhow::anyhow!("--out {}: cannot create it: {e}", out.display()))?;
            let mut stale = xfem_cut::output::write_result(&scene, &result, &out)?;
            let path = out.join("probes.csv");
            if !scene.probes.is_empty() {
                xfem_cut::output::write_probes(&path, &scene.probes, &values)?;
                println!("wrote {}", path.display());
            } else if path.is_file() {
                // An earlier run's probes would pass for this one's.
                std::fs::remove_file(&path).map_err(|e| {
                    anyhow::anyhow!(
                        "{}: cannot remove an earlier run's file: {e}",
                        path.display()
                    )
                })?;
                stale.push(path);
            }
            if !stale.is_empty() {
                println!(
                    "removed {} file(s) an earlier run left in {} that this run did not write ({})",
                    stale.len(),
                    out.display(),
                    stale_names(&out, &stale)
                );
            }
            Ok(())
        }
        Command::Converge {
            csv, exact: true, ..
        } => {
            use xfem_cut::study::exact;
            let csv = csv.unwrap_or_else(|| PathBuf::from("reports").join(exact::CSV));
            let mut variants = exact::study_variants();
            variants.extend(exact::radius_sweep());
            let hash = exact::inputs_hash(&variants)?;
            let hash_path = PathBuf::from(format!("{}.hash", csv.display()));
            if csv.exists() && std::fs::read_to_string(&hash_path).is_ok_and(|h| h.trim() == hash) {
                println!("{} is up to date (inputs hash {hash})", csv.display());
                return Ok(());
            }
            if let Some(dir) = csv.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
            }
            let rows = exact::run_study(&variants, |r| {
                eprintln!(
                    "{} {} {} n = {}: {} DOFs, L2 {:.3e}, energy {:.3e} ({:.1} s)",
                    r.case, r.variant, r.element, r.divisions, r.dofs, r.l2, r.energy, r.seconds
                )
            })?;
            exact::write_csv(&csv, &rows)?;
            std::fs::write(&hash_path, format!("{hash}\n"))
                .map_err(|e| anyhow::anyhow!("writing {}: {e}", hash_path.display()))?;
            println!("wrote {}", csv.display());
            Ok(())
        }
        Command::Converge {
            cases,
            csv,
            max_dofs,
            corotational,
            exact: false,
        } => {
            let csv = csv.unwrap_or_else(|| {
                PathBuf::from(if corotational {
                    "reports/data/convergence_corot.csv"
                } else {
                    "reports/data/convergence.csv"
                })
            });
            let mut rows = if csv.exists() {
                xfem_cut::study::converge::read_csv(&csv)?
            } else {
                Vec::new()
            };
            let bar = indicatif::ProgressBar::new_spinner();
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
            for case in &cases {
                let name = Scene::load(case)?.name;
                bar.set_message(format!("{name}: running"));
                let new =
                    xfem_cut::study::converge::converge_case(case, max_dofs, corotational, |msg| {
                        // indicatif drops println when not on a terminal (make's logs).
                        if bar.is_hidden() {
                            eprintln!("{msg}");
                        } else {
                            bar.println(msg);
                        }
                    })
                    .map_err(anyhow::Error::msg)?;
                rows.retain(|r| r.case != name);
                rows.extend(new);
                xfem_cut::study::converge::write_csv(&csv, &rows)?;
            }
            bar.finish_and_clear();
            println!("wrote {}", csv.display());
            Ok(())
        }
        Command::Stress { csv, only } => {
            if let Some(dir) = csv.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .map_err(|e| anyhow::anyhow!("creating {}: {e}", dir.display()))?;
            }
            let rows = xfem_cut::study::stress::run_suite(&only, |r| {
                println!(
                    "{} {} | {} | {} ({:.1} s)",
                    if r.pass { "pass" } else { "FAIL" },
                    r.test,
                    r.setting,
                    r.measured,
                    r.seconds
                )
            });
            if only.is_empty() {
                xfem_cut::study::stress::write_csv(&csv, &rows)?;
                println!("wrote {}", csv.display());
            }
            let failed = rows.iter().filter(|r| !r.pass).count();
            anyhow::ensure!(
                failed == 0,
                "{failed} of {} stress tests failed",
                rows.len()
            );
            Ok(())
        }
        Command::Report { dir, criterion } => {
            let machine = format!(
                "{} cores, {}; commit {}",
                std::thread::available_parallelism().map_or(0, |n| n.get()),
                std::env::consts::ARCH,
                std::process::Command::new("git")
                    .args(["rev-parse", "--short", "HEAD"])
                    .output()
                    .ok()
                    .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
                    .unwrap_or_default()
            );
            xfem_cut::study::report::write_report(&dir, &criterion, &machine)?;
            println!("wrote {}", dir.join("README.md").display());
            Ok(())
        }
    }
}

/// `files` (under `out`) named in short: `result.pvd, frames/result_00002.vtu
/// … frames/result_00043.vtu (42 frames)`.
fn stale_names(out: &std::path::Path, files: &[PathBuf]) -> String {
    let rel = |p: &PathBuf| p.strip_prefix(out).unwrap_or(p).display().to_string();
    let (frames, other): (Vec<&PathBuf>, Vec<&PathBuf>) = files
        .iter()
        .partition(|p| p.parent().is_some_and(|d| d.ends_with("frames")));
    let mut parts: Vec<String> = other.iter().map(|p| rel(p)).collect();
    match frames.as_slice() {
        [] => {}
        [one] => parts.push(rel(one)),
        [first, .., last] => parts.push(format!(
            "{} … {} ({} frames)",
            rel(first),
            rel(last),
            frames.len()
        )),
    }
    parts.join(", ")
}

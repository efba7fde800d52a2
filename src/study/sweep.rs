//! The cost of a progressive cut as a time series (issue 12): per time step
//! the simulated time, the wall time of the step and whether a cut event
//! followed it (with the event's own seconds: set-up, model update, state
//! map, symbolic factorisation; the numeric refactorisation is in the next
//! step's time). [`rows`] takes them from a [`Sweep`], [`write_csv`] /
//! [`read_csv`] store them, [`plot`] draws them (step time against simulated
//! time, events marked) for the report.

use crate::blade::Sweep;
use crate::io::IoError;
use plotters::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One time step of a sweep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SweepRow {
    /// Simulated time at the end of the step (s).
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub time: f64,
    /// Wall time of the step (s).
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub step_seconds: f64,
    /// Whether a cut event followed the step.
    pub event: bool,
    /// Wall time of that event (s; 0 without one).
    #[serde(serialize_with = "crate::io::csv::sci")]
    pub event_seconds: f64,
}

/// Why a sweep series could not be drawn.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("{}: drawing the sweep series: {message}", file.display())]
    Draw { file: PathBuf, message: String },
    #[error("no steps to draw")]
    Empty,
}

/// The per-step series of a finished sweep, events attached to the step they followed.
pub fn rows(sweep: &Sweep) -> Vec<SweepRow> {
    let mut events = sweep.events.iter().peekable();
    sweep
        .series
        .iter()
        .enumerate()
        .map(|(k, &(time, step_seconds, event))| {
            let mut event_seconds = 0.0;
            while let Some(e) = events.next_if(|e| e.step <= k + 1) {
                if e.step == k + 1 {
                    event_seconds += e.seconds;
                }
            }
            SweepRow {
                time,
                step_seconds,
                event,
                event_seconds,
            }
        })
        .collect()
}

/// Writes the series as CSV (`time,step_seconds,event,event_seconds`).
pub fn write_csv(path: &Path, rows: &[SweepRow]) -> Result<(), IoError> {
    crate::io::csv::write_rows(path, rows)
}

/// Reads a series [`write_csv`] wrote.
pub fn read_csv(path: &Path) -> Result<Vec<SweepRow>, IoError> {
    crate::io::csv::read_rows(path, false)
}

/// What a sweep during [`Phases::start`, `Phases::end`] cost against the
/// same run's steps before it (the uncut beam on the same mesh).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Phases {
    pub start: f64,
    pub end: f64,
    /// Median step (s) before the blade enters, the first step (the
    /// integrator's factorisation) left out.
    pub uncut_step: f64,
    /// Mean wall time (s) a step of the sweep costs, its event included
    /// (steps ending in (start, end]).
    pub sweep_step: f64,
    /// Median event (s, its own time) and median event with the step after it.
    pub event: f64,
    pub event_and_step: f64,
    /// Median step (s) after the sweep.
    pub after_step: f64,
    /// Steps of the sweep and the events among them.
    pub sweep_steps: usize,
    pub events: usize,
}

/// [`Phases`] of `rows` for a blade that cuts during [`start`, `end`] (a
/// small tolerance on the step times); NaN where a phase has no steps.
pub fn phases(rows: &[SweepRow], start: f64, end: f64) -> Phases {
    let tol = 1e-9 * end.abs().max(1.0);
    let median = |mut v: Vec<f64>| -> f64 {
        if v.is_empty() {
            return f64::NAN;
        }
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let during: Vec<&SweepRow> = rows
        .iter()
        .filter(|r| r.time > start + tol && r.time <= end + tol)
        .collect();
    let sweep_step = if during.is_empty() {
        f64::NAN
    } else {
        during
            .iter()
            .map(|r| r.step_seconds + r.event_seconds)
            .sum::<f64>()
            / during.len() as f64
    };
    Phases {
        start,
        end,
        uncut_step: median(
            rows.iter()
                .skip(1)
                .filter(|r| r.time <= start + tol && !r.event)
                .map(|r| r.step_seconds)
                .collect(),
        ),
        sweep_step,
        event: median(
            rows.iter()
                .filter(|r| r.event)
                .map(|r| r.event_seconds)
                .collect(),
        ),
        event_and_step: median(
            rows.windows(2)
                .filter(|w| w[0].event)
                .map(|w| w[0].event_seconds + w[1].step_seconds)
                .collect(),
        ),
        after_step: median(
            rows.iter()
                .filter(|r| r.time > end + tol)
                .map(|r| r.step_seconds)
                .collect(),
        ),
        sweep_steps: during.len(),
        events: rows.iter().filter(|r| r.event).count(),
    }
}

/// Draws the step time (ms, log scale) against simulated time, the steps
/// followed by a cut event and the events' own time marked, as an SVG.
pub fn plot(path: &Path, title: &str, rows: &[SweepRow]) -> Result<(), PlotError> {
    let draw = |e: &dyn std::fmt::Display| PlotError::Draw {
        file: path.to_path_buf(),
        message: e.to_string(),
    };
    if rows.is_empty() {
        return Err(PlotError::Empty);
    }
    let ms = |s: f64| (s * 1e3).max(1e-4);
    let t_max = rows.iter().map(|r| r.time).fold(0.0, f64::max);
    let values = rows
        .iter()
        .flat_map(|r| [ms(r.step_seconds), ms(r.event_seconds)])
        .filter(|&v| v > 1e-4);
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
    let (lo, hi) = if lo.is_finite() {
        (lo, hi)
    } else {
        (1e-3, 1.0)
    };
    let root = SVGBackend::new(path, (760, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw(&e))?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 17))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..t_max * 1.02, (lo * 0.7..hi * 1.5).log_scale())
        .map_err(|e| draw(&e))?;
    chart
        .configure_mesh()
        .x_desc("simulated time (s)")
        .y_desc("wall time (ms)")
        .draw()
        .map_err(|e| draw(&e))?;
    let step: Vec<(f64, f64)> = rows.iter().map(|r| (r.time, ms(r.step_seconds))).collect();
    chart
        .draw_series(LineSeries::new(step, BLUE.stroke_width(1)))
        .map_err(|e| draw(&e))?
        .label("step")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLUE));
    let events: Vec<&SweepRow> = rows.iter().filter(|r| r.event).collect();
    chart
        .draw_series(
            events
                .iter()
                .map(|r| Circle::new((r.time, ms(r.event_seconds)), 4, RED.filled())),
        )
        .map_err(|e| draw(&e))?
        .label("cut event (set-up, model update, symbolic)")
        .legend(|(x, y)| Circle::new((x + 9, y), 4, RED.filled()));
    chart
        .draw_series(
            events
                .iter()
                .map(|r| Cross::new((r.time, ms(r.step_seconds)), 4, RED.stroke_width(1))),
        )
        .map_err(|e| draw(&e))?
        .label("step followed by an event")
        .legend(|(x, y)| Cross::new((x + 9, y), 4, RED));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| draw(&e))?;
    root.present().map_err(|e| draw(&e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::blade::Event;
    use crate::dynamics::Energies;

    fn event(step: usize, seconds: f64) -> Event {
        Event {
            step,
            time: 0.01 * step as f64,
            dofs_before: 0,
            dofs_after: 0,
            enriched_before: 0,
            enriched_after: 0,
            before: Energies::default(),
            after: Energies::default(),
            pattern_changed: true,
            border: None,
            lagged: false,
            changed_elements: 0,
            model_seconds: 0.0,
            symbolic_seconds: 0.0,
            seconds,
        }
    }

    #[test]
    fn a_series_keeps_its_events_and_reads_back_and_draws() {
        let sweep = Sweep {
            series: (1..=5)
                .map(|k| (0.01 * k as f64, 1e-3 * k as f64, k == 2 || k == 4))
                .collect(),
            events: vec![event(2, 0.25), event(4, 0.5)],
            ..Sweep::default()
        };
        let r = rows(&sweep);
        let flags: Vec<bool> = r.iter().map(|r| r.event).collect();
        assert_eq!(flags, [false, true, false, true, false]);
        let secs: Vec<f64> = r.iter().map(|r| r.event_seconds).collect();
        assert_eq!(secs, [0.0, 0.25, 0.0, 0.5, 0.0]);
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("sweep.csv");
        write_csv(&csv, &r).unwrap();
        assert_eq!(read_csv(&csv).unwrap(), r);
        let svg = dir.path().join("sweep.svg");
        plot(&svg, "test sweep", &r).unwrap();
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.starts_with("<svg") && text.contains("cut event"));
        assert!(matches!(plot(&svg, "empty", &[]), Err(PlotError::Empty)));
    }

    #[test]
    fn phases_split_a_series_at_the_sweep() {
        let row = |time: f64, step: f64, event: f64| SweepRow {
            time,
            step_seconds: step,
            event: event > 0.0,
            event_seconds: event,
        };
        // A first step with the factorisation, two uncut steps, a sweep
        // of three steps (events after the first two), two steps after.
        let rows = [
            row(0.01, 9.0, 0.0),
            row(0.02, 1.0, 0.0),
            row(0.03, 1.0, 0.0),
            row(0.04, 2.0, 10.0),
            row(0.05, 4.0, 20.0),
            row(0.06, 3.0, 0.0),
            row(0.07, 1.5, 0.0),
            row(0.08, 1.5, 0.0),
        ];
        let p = phases(&rows, 0.03, 0.06);
        assert_eq!(p.uncut_step, 1.0);
        assert_eq!(p.sweep_steps, 3);
        assert_eq!(p.events, 2);
        assert!((p.sweep_step - (12.0 + 24.0 + 3.0) / 3.0).abs() < 1e-12);
        assert_eq!(p.event, 20.0);
        // Event + the step after it: 10 + 4 and 20 + 3.
        assert_eq!(p.event_and_step, 23.0);
        assert_eq!(p.after_step, 1.5);
        assert!(phases(&rows, 0.1, 0.2).sweep_step.is_nan());
    }
}

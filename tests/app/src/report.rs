//! `sinew report FILE`: a training report of a recorded session. The recording is replayed through the server
//! tick (bit for bit, so the report is what the session was) with the training layer watching every tick, and
//! the report is written into a directory:
//! - `report.json`: per participant the metrics, time per skill state, transitions and event counts;
//! - `force.png`: the force on each tool over time, with the harm threshold;
//! - `path_top.png`: each instrument tip's path seen from above (world x, y);
//! - `states.png`: time per skill state, per participant;
//! - `summary.txt`: the same in a few lines of text.
//!
//! Owns: [`SessionReport`], [`ParticipantReport`], [`write_report`].
//! Must not: change the recording, or call anything but the server crate's public replay and training APIs.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use plotters::prelude::*;
use serde::Serialize;
use sinew_server::recording::replay_observed;
use sinew_server::training::{
    EventKind, ExerciseRun, ExerciseScore, MetricsConfig, MetricsSummary, SessionObserver,
    SkillState,
};

/// Samples kept for the plots: one every this many ticks.
const PLOT_EVERY_TICKS: u64 = 10;

/// One participant (tool and the device that drove it).
#[derive(Debug, Clone, Serialize)]
pub struct ParticipantReport {
    /// Tool index in the world.
    pub tool: usize,
    /// Tool name.
    pub tool_name: String,
    /// Device id bound to it.
    pub device: String,
    /// The metrics.
    pub metrics: MetricsSummary,
    /// Seconds in each skill state, by state name.
    pub time_in_state_s: BTreeMap<String, f64>,
    /// Skill-state transitions.
    pub transitions: u64,
    /// Events, by kind name (kinds that happened).
    pub events: BTreeMap<String, u64>,
}

/// The report of one recording.
#[derive(Debug, Clone, Serialize)]
pub struct SessionReport {
    /// The recording.
    pub recording: PathBuf,
    /// Its scene.
    pub scene: String,
    /// Ticks replayed.
    pub ticks: u64,
    /// Simulated seconds.
    pub duration_s: f64,
    /// The replay reproduced every recorded force and the final tissue bit for bit (if false, the report
    /// describes the replay, not what the surgeons felt).
    pub bit_exact: bool,
    /// Why the recording ends early, if it does.
    pub damage: Option<String>,
    /// Per participant, in world order.
    pub participants: Vec<ParticipantReport>,
    /// The exercise's score, if the world is an exercise.
    pub exercise: Option<ExerciseScore>,
}

struct Series {
    t_s: Vec<f64>,
    force_n: Vec<f64>,
    tip_xy_mm: Vec<(f64, f64)>,
}

/// Replay `recording` and write its report into `out_dir` (created if needed). Returns the report.
pub fn write_report(recording: &Path, out_dir: &Path) -> anyhow::Result<SessionReport> {
    let (rec, world) = crate::play_device::read_with_world(recording)?;
    let dt_s = 1.0 / world.tick_hz;
    let tools = world.tools.len();
    let mut observer = SessionObserver::new(tools, MetricsConfig::new(dt_s));
    if let Some(spec) = &world.exercise {
        observer = observer.with_exercise(ExerciseRun::new(spec.clone(), tools, dt_s));
    }
    let mut series: Vec<Series> = (0..tools)
        .map(|_| Series {
            t_s: Vec::new(),
            force_n: Vec::new(),
            tip_xy_mm: Vec::new(),
        })
        .collect();
    let mut events = vec![BTreeMap::<String, u64>::new(); tools];
    let outcome = replay_observed(&rec, &world, |view| {
        observer.observe(
            view,
            |e| {
                if let Some(counts) = events.get_mut(usize::from(e.tool)) {
                    *counts.entry(e.kind.name().to_owned()).or_default() += 1;
                }
            },
            |_, _| {},
        );
        if view.tick % PLOT_EVERY_TICKS == 0 {
            for (t, s) in series.iter_mut().enumerate() {
                let Some(a) = observer.activity(t) else {
                    continue;
                };
                s.t_s.push(view.tick as f64 * dt_s);
                s.force_n.push(f64::from(a.force_n));
                if a.active {
                    s.tip_xy_mm
                        .push((f64::from(a.tip_world_mm[0]), f64::from(a.tip_world_mm[1])));
                }
            }
        }
    })
    .with_context(|| format!("building the recorded world of {}", recording.display()))?;

    let participants: Vec<ParticipantReport> = world
        .tools
        .iter()
        .enumerate()
        .filter_map(|(t, spec)| {
            let machine = observer.machine(t)?;
            let time_in_state_s = SkillState::ALL
                .iter()
                .map(|s| {
                    (
                        s.name().to_owned(),
                        machine.ticks_in()[s.index()] as f64 * dt_s,
                    )
                })
                .collect();
            Some(ParticipantReport {
                tool: t,
                tool_name: spec.name.clone(),
                device: spec.device_id.clone(),
                metrics: observer.metrics(t)?.summary(),
                time_in_state_s,
                transitions: machine.transitions(),
                events: events.get(t).cloned().unwrap_or_default(),
            })
        })
        .collect();
    let report = SessionReport {
        recording: recording.to_owned(),
        scene: world.scene.clone(),
        ticks: outcome.ticks,
        duration_s: outcome.sim_s,
        bit_exact: outcome.exact(),
        damage: rec.damage.clone(),
        participants,
        exercise: observer.exercise().map(ExerciseRun::score),
    };

    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let json = serde_json::to_string_pretty(&report)?;
    write(&out_dir.join("report.json"), json.as_bytes())?;
    write(&out_dir.join("summary.txt"), summary(&report).as_bytes())?;
    crate::figure_font::register_sans_serif()?;
    let harm_n = MetricsConfig::DEFAULT_HARM_THRESHOLD_N as f64;
    draw_force(&out_dir.join("force.png"), &report, &series, harm_n)?;
    draw_paths(&out_dir.join("path_top.png"), &report, &series)?;
    draw_states(&out_dir.join("states.png"), &report)?;
    Ok(report)
}

fn write(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    std::fs::write(path, bytes).with_context(|| format!("writing {}", path.display()))
}

/// A few lines a trainee reads.
pub fn summary(report: &SessionReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{}: scene `{}`, {:.1} s, {} ticks{}",
        report.recording.display(),
        report.scene,
        report.duration_s,
        report.ticks,
        if report.bit_exact {
            ", replayed bit for bit"
        } else {
            ", NOT replayed bit for bit"
        }
    );
    if let Some(damage) = &report.damage {
        let _ = writeln!(s, "  the recording ends early: {damage}");
    }
    if let Some(e) = &report.exercise {
        let _ = writeln!(
            s,
            "exercise `{}` ({}): {} - score {:.0}/100, {} of {} {} in {:.1} s{}; errors: {} wrong tool, {} off \
             target, {} too deep; mean distance from the marks {:.1} mm, deepest press {:.1} mm",
            e.name,
            e.kind.as_str(),
            if e.passed {
                "passed"
            } else if e.completed && e.errors.total() > 0 {
                "completed with errors"
            } else if e.completed {
                "completed, the wound left open"
            } else {
                "not completed"
            },
            e.score,
            e.targets_hit,
            e.targets_total,
            if e.ranking.is_some() {
                "pairs ranked right"
            } else {
                "targets"
            },
            e.time_s,
            if e.timed_out { " (time ran out)" } else { "" },
            e.errors.wrong_tool,
            e.errors.off_target,
            e.errors.too_deep,
            e.mean_distance_mm,
            e.max_depth_mm
        );
        if let Some(gap) = e.wound_gap_mm {
            let _ = writeln!(
                s,
                "  the wound's gap at the end {gap:.2} mm (to pass: {} mm or less)",
                sinew_server::scene::SUTURE_GAP_LIMIT_MM
            );
        }
        if let Some(knot) = &e.knot {
            let _ = writeln!(
                s,
                "  the knot at the end: {} ({}), {} knot(s) came undone{}",
                knot.name.as_deref().unwrap_or("none"),
                if knot.secure { "secure" } else { "not secure" },
                knot.undone,
                if knot.undone > 0 && e.errors.knot_undone > 0 {
                    " (errors)"
                } else {
                    ""
                }
            );
        }
        if let Some(cut) = &e.pattern {
            let _ = writeln!(
                s,
                "  the pattern {}: {:.1} mm^2 cut outside the band, {:.1} mm^2 left inside it, a {:.2}% penalty; \
                 MISTELS points {:.1} (cutoff - seconds - penalty)",
                if cut.freed {
                    "came free"
                } else {
                    "did not come free"
                },
                cut.outside_band_mm2,
                cut.inside_band_mm2,
                cut.deviation_pct,
                cut.mistels_points
            );
        }
        if let Some(r) = &e.ranking {
            let pairs: Vec<String> = r
                .pairs
                .iter()
                .map(|p| {
                    format!(
                        "{} < {} ({:.2}x): {}",
                        p.softer,
                        p.firmer,
                        p.stiffness_ratio,
                        if p.correct { "right" } else { "wrong" }
                    )
                })
                .collect();
            let _ = writeln!(
                s,
                "  ranked {} (softest first; truth {}); pairs: {}",
                if r.answer.is_empty() {
                    "nothing".to_owned()
                } else {
                    r.answer.join(" < ")
                },
                r.truth.join(" < "),
                pairs.join(", ")
            );
        }
    }
    for p in &report.participants {
        let m = &p.metrics;
        let _ = writeln!(
            s,
            "{} ({}): task {:.1} s, path {:.0} mm (economy {}), {} contacts for {:.1} s, force mean {:.2} N \
             peak {:.2} N, harm {:.3} N s above {:.1} N",
            p.device,
            p.tool_name,
            m.task_time_s,
            m.path_length_mm,
            m.economy.map_or("n/a".to_owned(), |e| format!("{e:.2}")),
            m.contacts,
            m.contact_time_s,
            m.mean_contact_force_n,
            m.peak_force_n,
            m.harm_n_s,
            m.harm_threshold_n
        );
        let states: Vec<String> = SkillState::ALL
            .iter()
            .filter_map(|st| {
                let secs = p.time_in_state_s.get(st.name()).copied().unwrap_or(0.0);
                (secs > 0.0).then(|| format!("{} {secs:.1} s", st.name()))
            })
            .collect();
        let _ = writeln!(
            s,
            "  states: {} ({} transitions); faults {}",
            states.join(", "),
            p.transitions,
            p.events
                .get(EventKind::TissueFault.name())
                .copied()
                .unwrap_or(0)
        );
    }
    s
}

const COLOURS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

fn plot_error<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing the report: {e:?}")
}

/// A chart's legend, in the report's style.
fn legend<'a, DB: DrawingBackend + 'a, CT: plotters::coord::CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_series_labels()
        .position(position)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(plot_error)
}

/// A chart's grid and axis names, in the report's style.
fn axes<'a, DB: DrawingBackend + 'a>(
    chart: &mut ChartContext<
        'a,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    x_desc: &str,
    y_desc: &str,
) -> anyhow::Result<()>
where
    DB::ErrorType: 'static,
{
    chart
        .configure_mesh()
        .x_desc(x_desc)
        .y_desc(y_desc)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(plot_error)
}

fn draw_force(
    path: &Path,
    report: &SessionReport,
    series: &[Series],
    harm_n: f64,
) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1000, 450)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    let t_max = report.duration_s.max(0.1);
    let f_max = series
        .iter()
        .flat_map(|s| s.force_n.iter().copied())
        .fold(harm_n, f64::max)
        * 1.35;
    let mut chart = ChartBuilder::on(&root)
        .caption("Force on each tool", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(0.0..t_max, 0.0..f_max)
        .map_err(plot_error)?;
    axes(&mut chart, "time (s)", "force (N)")?;
    for (p, s) in report.participants.iter().zip(series) {
        let colour = COLOURS[p.tool % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                s.t_s.iter().copied().zip(s.force_n.iter().copied()),
                colour.stroke_width(2),
            ))
            .map_err(plot_error)?
            .label(p.device.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
    }
    chart
        .draw_series(LineSeries::new(
            [(0.0, harm_n), (t_max, harm_n)],
            BLACK.mix(0.5).stroke_width(1),
        ))
        .map_err(plot_error)?
        .label("harm threshold")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK.mix(0.5)));
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present().map_err(plot_error)
}

fn draw_paths(path: &Path, report: &SessionReport, series: &[Series]) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (700, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    let points = series.iter().flat_map(|s| s.tip_xy_mm.iter().copied());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (-50.0, 50.0, -50.0, 50.0);
    }
    // Same scale on both axes, with a margin.
    let half = ((x1 - x0).max(y1 - y0) / 2.0 + 5.0).max(10.0);
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let mut chart = ChartBuilder::on(&root)
        .caption("Instrument tips seen from above", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)
        .map_err(plot_error)?;
    axes(&mut chart, "x (mm)", "y (mm)")?;
    for (p, s) in report.participants.iter().zip(series) {
        let colour = COLOURS[p.tool % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                s.tip_xy_mm.iter().copied(),
                colour.stroke_width(2),
            ))
            .map_err(plot_error)?
            .label(format!("{} (o start, x end)", p.device))
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
        // A tip that never moved sideways is a point: the markers show it.
        if let (Some(first), Some(last)) = (s.tip_xy_mm.first(), s.tip_xy_mm.last()) {
            chart
                .draw_series([Circle::new(*first, 6, colour.stroke_width(2))])
                .map_err(plot_error)?;
            chart
                .draw_series([Cross::new(*last, 6, colour.stroke_width(2))])
                .map_err(plot_error)?;
        }
    }
    legend(&mut chart, SeriesLabelPosition::UpperLeft)?;
    root.present().map_err(plot_error)
}

fn draw_states(path: &Path, report: &SessionReport) -> anyhow::Result<()> {
    let root = BitMapBackend::new(path, (1000, 450)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    let n = SkillState::ALL.len();
    let per = report.participants.len().max(1) as f64;
    let most = report
        .participants
        .iter()
        .flat_map(|p| p.time_in_state_s.values().copied())
        .fold(0.1, f64::max)
        * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption("Time per skill state", ("sans-serif", 22))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(55)
        .build_cartesian_2d(-0.5..n as f64 - 0.5, 0.0..most)
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n)
        .x_label_formatter(&|x| {
            let i = x.round();
            if (x - i).abs() < 1e-6 && (0.0..n as f64).contains(&i) {
                SkillState::ALL[i as usize].name().to_owned()
            } else {
                String::new()
            }
        })
        .y_desc("time (s)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(plot_error)?;
    for (k, p) in report.participants.iter().enumerate() {
        let colour = COLOURS[p.tool % COLOURS.len()];
        let width = 0.8 / per;
        chart
            .draw_series(SkillState::ALL.iter().map(|s| {
                let secs = p.time_in_state_s.get(s.name()).copied().unwrap_or(0.0);
                let left = s.index() as f64 - 0.4 + k as f64 * width;
                Rectangle::new([(left, 0.0), (left + width, secs)], colour.filled())
            }))
            .map_err(plot_error)?
            .label(p.device.clone())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], colour.filled()));
    }
    legend(&mut chart, SeriesLabelPosition::MiddleRight)?;
    root.present().map_err(plot_error)
}

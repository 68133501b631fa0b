//! The latency-moderated mode's results (issue "Remote surgeons"): a table of mode x round trip x hand, and the
//! figure of force against time for direct and moderated mode at 100 ms with the light hand.
//!
//! Every run is a drill on virtual time (`sinew_testkit::scenarios`): the real server tick and device loops joined by
//! seeded emulated links, so the figures are deterministic and do not depend on the machine's speed.
//!
//! ```text
//! cargo bench -p sinew-testkit --bench latency_table                      # table, all round trips
//! cargo bench -p sinew-testkit --bench latency_table -- --rtts 100,200    # fewer round trips
//! cargo bench -p sinew-testkit --bench latency_table -- --figure figures/force_direct_vs_moderated_100ms_light.png  (relative to tests/)
//! ```
//!
//! Columns: the hold on the soft pad and on the 10x stiffer pad at +-20 ms jitter and 5% loss (stable = force
//! peak-to-peak < 0.05 N, stylus speed RMS < 1 mm/s, net energy out <= 1 mJ over the last 2 s); the felt
//! stiffness of a slow 1-5 mm press over the zero-delay one of the same mode and hand; the RMS force error of a
//! 0.5 Hz stroke against zero delay (fraction of peak); force messages a second while holding. The figure
//! needs a TrueType font: DejaVu Sans (Debian `fonts-dejavu-core`) or the file in `SINEW_FONT`.

#![allow(clippy::print_stdout)] // a bench binary reports on stdout

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use anyhow::Context as _;
use hapticserver::{HandPreset, ModePolicy, TraceSample};
use plotters::prelude::*;
use sinew::figure_font::plot_error;
use sinew_testkit::drill::Link;
use sinew_testkit::scenarios::{felt_stiffness_n_per_mm, hold, lossy_link, stroke_error};

const HANDS: [HandPreset; 3] = [HandPreset::Light, HandPreset::Nominal, HandPreset::Firm];
const MODES: [ModePolicy; 2] = [ModePolicy::Direct, ModePolicy::Moderated];

struct Options {
    rtts_ms: Vec<f64>,
    figure: Option<PathBuf>,
    table: bool,
}

fn parse_options() -> anyhow::Result<Options> {
    let mut options = Options {
        rtts_ms: vec![10.0, 50.0, 100.0, 200.0],
        figure: None,
        table: true,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--rtts" => {
                let list = args.next().context("--rtts needs a list, e.g. 10,100")?;
                options.rtts_ms = list
                    .split(',')
                    .map(|v| {
                        v.trim()
                            .parse::<f64>()
                            .ok()
                            .filter(|ms| ms.is_finite() && (0.0..=1000.0).contains(ms))
                            .with_context(|| {
                                format!("--rtts: `{v}` is not a round trip in 0-1000 ms")
                            })
                    })
                    .collect::<anyhow::Result<_>>()?;
            }
            "--figure" => {
                options.figure = Some(args.next().context("--figure needs a PNG path")?.into());
            }
            "--no-table" => options.table = false,
            // cargo bench passes --bench; ignore the harness flags it may add.
            "--bench" => {}
            other => anyhow::bail!(
                "unknown argument `{other}` (known: --rtts LIST, --figure PATH, --no-table)"
            ),
        }
    }
    Ok(options)
}

/// One row of the table.
struct Row {
    mode: ModePolicy,
    rtt_ms: f64,
    hand: HandPreset,
    pad_p2p_n: f32,
    pad_energy_out_mj: f64,
    pad_mean_force_n: f32,
    pad_stable: bool,
    stiff_stable: bool,
    stiffness_ratio: Option<f32>,
    stroke_error: f32,
    messages_per_s: f64,
}

fn measure(
    mode: ModePolicy,
    rtt_ms: f64,
    hand: HandPreset,
    reference_n_per_mm: Option<f32>,
) -> anyhow::Result<Row> {
    let pad = hold("pad.toml", hand, lossy_link(rtt_ms), mode)?;
    let stiff = hold("pad_stiff.toml", hand, lossy_link(rtt_ms), mode)?;
    let felt = felt_stiffness_n_per_mm(hand, Link::rtt(rtt_ms), mode)?;
    let (stroke_error, _, _) = stroke_error(hand, 2.0, Link::rtt(rtt_ms), mode)?;
    Ok(Row {
        mode,
        rtt_ms,
        hand,
        pad_p2p_n: pad.hold.force_p2p_n,
        pad_energy_out_mj: pad.energy_out_mj,
        pad_mean_force_n: pad.hold.mean_force_n,
        pad_stable: pad.stable(),
        stiff_stable: stiff.stable(),
        stiffness_ratio: felt.zip(reference_n_per_mm).map(|(f, r)| f / r),
        stroke_error,
        messages_per_s: pad.messages_per_s,
    })
}

/// Run `jobs` on every core the machine offers; results in job order.
fn run_parallel<J: Sync, R: Send>(jobs: &[J], work: impl Fn(&J) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let next = Mutex::new(0usize);
    let results: Mutex<Vec<Option<R>>> = Mutex::new((0..jobs.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| {
                loop {
                    let index = {
                        let mut next = next
                            .lock()
                            .unwrap_or_else(std::sync::PoisonError::into_inner);
                        let index = *next;
                        *next += 1;
                        index
                    };
                    let Some(job) = jobs.get(index) else { break };
                    let result = work(job);
                    results
                        .lock()
                        .unwrap_or_else(std::sync::PoisonError::into_inner)[index] = Some(result);
                }
            });
        }
    });
    results
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .into_iter()
        .flatten()
        .collect()
}

fn yes_no(stable: bool) -> &'static str {
    if stable { "yes" } else { "**no**" }
}

fn print_table(rtts_ms: &[f64]) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    // The zero-delay felt stiffness of each mode and hand: the denominators.
    let references: Vec<(ModePolicy, HandPreset)> = MODES
        .iter()
        .flat_map(|&m| HANDS.iter().map(move |&h| (m, h)))
        .collect();
    let reference_values = run_parallel(&references, |&(mode, hand)| {
        felt_stiffness_n_per_mm(hand, Link::rtt(0.0), mode)
    });
    let mut reference_of = Vec::new();
    for (case, value) in references.iter().zip(reference_values) {
        reference_of.push((*case, value?));
    }
    let jobs: Vec<(ModePolicy, f64, HandPreset)> = MODES
        .iter()
        .flat_map(|&m| {
            rtts_ms
                .iter()
                .flat_map(move |&r| HANDS.iter().map(move |&h| (m, r, h)))
        })
        .collect();
    let rows = run_parallel(&jobs, |&(mode, rtt_ms, hand)| {
        let reference = reference_of
            .iter()
            .find(|((m, h), _)| *m == mode && *h == hand)
            .and_then(|(_, r)| *r);
        measure(mode, rtt_ms, hand, reference)
    });
    println!(
        "| mode | RTT | hand | stable, pad | stable, 10x pad | hold on pad: F, p2p, energy out | felt stiffness / zero delay | 0.5 Hz stroke RMS error | force msg/s holding |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for row in rows {
        let row = row?;
        println!(
            "| {} | {:.0} ms | {} | {} | {} | {:.2} N, {:.4} N, {:+.1} mJ | {} | {:.3} | {:.0} |",
            row.mode.name(),
            row.rtt_ms,
            row.hand.name(),
            yes_no(row.pad_stable),
            yes_no(row.stiff_stable),
            row.pad_mean_force_n,
            row.pad_p2p_n,
            row.pad_energy_out_mj,
            row.stiffness_ratio
                .map_or("-".to_owned(), |r| format!("{r:.3}")),
            row.stroke_error,
            row.messages_per_s
        );
    }
    println!(
        "zero-delay felt stiffness, N/mm: {}",
        reference_of
            .iter()
            .map(|((m, h), r)| format!(
                "{} {} {}",
                m.name(),
                h.name(),
                r.map_or("-".to_owned(), |r| format!("{r:.3}"))
            ))
            .collect::<Vec<_>>()
            .join(", ")
    );
    println!(
        "({} drill runs in {:.0} s)",
        6 + jobs.len() * 5,
        started.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Force along the pad normal against time: zero delay, direct and moderated at 100 ms (+-20 ms, 5% loss),
/// light hand, pressing and holding on the soft pad.
fn draw_figure(path: &Path) -> anyhow::Result<()> {
    sinew::figure_font::register_sans_serif()?;
    let hand = HandPreset::Light;
    let cases = [
        (
            "zero delay",
            Link::rtt(0.0),
            ModePolicy::Moderated,
            RGBColor(120, 120, 120),
        ),
        (
            "direct, 100 ms",
            lossy_link(100.0),
            ModePolicy::Direct,
            RGBColor(200, 40, 40),
        ),
        (
            "moderated, 100 ms",
            lossy_link(100.0),
            ModePolicy::Moderated,
            RGBColor(30, 90, 200),
        ),
    ];
    let traces = run_parallel(&cases, |(_, link, mode, _)| {
        hold("pad.toml", hand, *link, *mode)
    });
    let mut series: Vec<(&str, RGBColor, Vec<TraceSample>)> = Vec::new();
    for ((label, link, mode, color), outcome) in cases.iter().zip(traces) {
        let outcome = outcome?;
        let end_mm = outcome
            .trace
            .last()
            .map_or([f32::NAN; 3], |s| s.position_mm);
        println!(
            "figure: {}; probe centre ends at z {:.1} mm (pad surface 0)",
            outcome.row("pad.toml", hand, link, *mode),
            end_mm[2]
        );
        series.push((label, *color, outcome.trace));
    }
    let peak = series
        .iter()
        .flat_map(|(_, _, t)| t.iter().map(|s| s.force_n[2]))
        .fold(0.0f32, f32::max);
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let root = BitMapBackend::new(path, (1200, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Light hand presses and holds the pad, 100 ms round trip (+-20 ms jitter, 5% loss)",
            ("sans-serif", 24),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0f64..5.0f64, -0.1f32..(peak * 1.1).max(0.5))
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("force along the pad normal, N")
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(plot_error)?;
    for (index, (label, color, trace)) in series.iter().enumerate() {
        // The zero-delay reference is drawn wide so that the moderated line on top of it shows both.
        let width = if index == 0 { 7 } else { 2 };
        chart
            .draw_series(LineSeries::new(
                trace.iter().map(|s| (s.t_s, s.force_n[2])),
                color.stroke_width(width),
            ))
            .map_err(plot_error)?
            .label(*label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
            });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .label_font(("sans-serif", 18))
        .draw()
        .map_err(plot_error)?;
    root.present().map_err(plot_error)?;
    println!("figure written to {}", path.display());
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let options = parse_options()?;
    if let Some(path) = &options.figure {
        draw_figure(path)?;
    }
    if options.table {
        print_table(&options.rtts_ms)?;
    }
    Ok(())
}

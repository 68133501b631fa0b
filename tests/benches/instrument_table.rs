//! Every interaction at a distance (issue "Every interaction at a distance"): a table of instrument world x
//! hand x round trip -> peak and RMS force against zero delay, passivity energy withheld, clamp; the tug of
//! war's rows; and the figure of the tug of war's two forces over time at zero delay and at 200 ms.
//!
//! Every run is a drill on virtual time (`sinew_testkit::fidelity`): the real server tick and device loops
//! joined by seeded emulated links, in `--mode auto`, so the figures are deterministic and do not depend on the
//! machine's speed.
//!
//! ```text
//! cargo bench -p sinew-testkit --bench instrument_table                          # the whole table
//! cargo bench -p sinew-testkit --bench instrument_table -- --worlds grasp_pull --hands nominal --rtts 200
//! cargo bench -p sinew-testkit --bench instrument_table -- --no-table --figure figures/tug_of_war_0_vs_200ms.png  (relative to tests/)
//! ```
//!
//! The figure needs a TrueType font: DejaVu Sans (Debian `fonts-dejavu-core`) or the file in `SINEW_FONT`.

#![allow(clippy::print_stdout)] // a bench binary reports on stdout

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use hapticserver::{HandPreset, TraceSample};
use plotters::prelude::*;
use sinew::figure_font::plot_error;
use sinew_testkit::drill::Link;
use sinew_testkit::fidelity::{TUG_RUN_S, fidelity, mean_force_n, sheet_difference_mm, tug_of_war};
use sinew_testkit::harness::load_shipped_world;

struct Options {
    worlds: Vec<String>,
    hands: Vec<HandPreset>,
    rtts_ms: Vec<f64>,
    figure: Option<PathBuf>,
    table: bool,
}

fn list(args: &mut impl Iterator<Item = String>, flag: &str) -> anyhow::Result<Vec<String>> {
    let value = args
        .next()
        .with_context(|| format!("{flag} needs a comma-separated list"))?;
    Ok(value.split(',').map(|v| v.trim().to_owned()).collect())
}

fn parse_options() -> anyhow::Result<Options> {
    let mut options = Options {
        worlds: ["grasp_pull", "cut", "cut_under_tension", "cautery"]
            .map(str::to_owned)
            .to_vec(),
        hands: vec![HandPreset::Light, HandPreset::Nominal, HandPreset::Firm],
        rtts_ms: vec![50.0, 100.0, 200.0],
        figure: None,
        table: true,
    };
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--worlds" => options.worlds = list(&mut args, "--worlds")?,
            "--hands" => {
                options.hands = list(&mut args, "--hands")?
                    .iter()
                    .map(|h| h.parse().map_err(anyhow::Error::msg))
                    .collect::<anyhow::Result<_>>()?;
            }
            "--rtts" => {
                options.rtts_ms = list(&mut args, "--rtts")?
                    .iter()
                    .map(|v| {
                        v.parse::<f64>()
                            .ok()
                            .filter(|ms| ms.is_finite() && (0.0..=1000.0).contains(ms))
                            .with_context(|| {
                                format!("--rtts: `{v}` is not a round trip in 0-1000 ms")
                            })
                    })
                    .collect::<anyhow::Result<_>>()?;
            }
            "--figure" => {
                options.figure = Some(PathBuf::from(args.next().context("--figure needs a path")?));
            }
            "--no-table" => options.table = false,
            // cargo bench passes --bench to every bench binary.
            "--bench" => {}
            other => anyhow::bail!(
                "unknown argument `{other}`: expected --worlds, --hands, --rtts, --figure PATH or --no-table"
            ),
        }
    }
    Ok(options)
}

fn print_table(options: &Options) -> anyhow::Result<()> {
    println!(
        "| world | device | hand | round trip | peak, delayed / zero delay | RMS, delayed / zero delay | passivity withheld | clamp | largest force step |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for name in &options.worlds {
        let file = format!("{name}.toml");
        let world = load_shipped_world(&file)?;
        for &hand in &options.hands {
            for &rtt_ms in &options.rtts_ms {
                let f = fidelity(&world, hand, Link::rtt(rtt_ms), Link::rtt(rtt_ms))?;
                for row in f.rows(name, hand, rtt_ms) {
                    println!("{row}");
                }
                if name.starts_with("cut") {
                    // The scalpel's drag while it cuts: the mean force over the steady cut.
                    let (from_s, to_s) = (1.4, 2.9);
                    println!(
                        "| {name} | left, drag while cutting (1.4-2.9 s) | {} | {rtt_ms:.0} ms | mean {:.4} / {:.4} N | | | | |",
                        hand.name(),
                        mean_force_n(&f.delayed.traces[0], from_s, to_s),
                        mean_force_n(&f.reference.traces[0], from_s, to_s),
                    );
                }
            }
        }
    }
    let world = load_shipped_world("tug_of_war.toml")?;
    let hand = HandPreset::Nominal;
    let reference = tug_of_war(&world, hand, Link::rtt(0.0), Link::rtt(0.0))?;
    println!();
    println!(
        "| tug of war (nominal hands) | right feels left's pull | left feels | hold p2p, left / right | speed RMS, left / right | energy out, left / right | withheld, left / right | clamp | sheet vs zero delay |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for (left_ms, right_ms) in [(0.0, 0.0), (10.0, 200.0), (200.0, 10.0), (200.0, 200.0)] {
        let tug = tug_of_war(&world, hand, Link::rtt(left_ms), Link::rtt(right_ms))?;
        println!(
            "| {left_ms:.0} / {right_ms:.0} ms | {:.3} N ({:+.1}%) | {:.3} N ({:+.1}%) | {:.4} / {:.4} N | {:.3} / {:.3} mm/s | {:+.2} / {:+.2} mJ | {:.2} / {:.2} mJ | {} | {:.3} mm |",
            tug.right_feels_n,
            100.0 * (tug.right_feels_n / reference.right_feels_n - 1.0),
            tug.left_feels_n,
            100.0 * (tug.left_feels_n / reference.left_feels_n - 1.0),
            tug.hold[0].force_p2p_n,
            tug.hold[1].force_p2p_n,
            tug.hold[0].velocity_rms_mm_s,
            tug.hold[1].velocity_rms_mm_s,
            tug.energy_out_mj[0],
            tug.energy_out_mj[1],
            tug.withheld_mj[0],
            tug.withheld_mj[1],
            if tug.clamped.iter().any(|&c| c) {
                "reached"
            } else {
                "-"
            },
            sheet_difference_mm(&tug.sheet_mm, &reference.sheet_mm),
        );
    }
    Ok(())
}

fn magnitude(f: [f32; 3]) -> f32 {
    (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]).sqrt()
}

/// The tug of war's two forces against time, at zero delay (wide, pale) and with both surgeons at 200 ms.
fn draw_figure(path: &Path) -> anyhow::Result<()> {
    sinew::figure_font::register_sans_serif()?;
    let world = load_shipped_world("tug_of_war.toml")?;
    let hand = HandPreset::Nominal;
    let reference = tug_of_war(&world, hand, Link::rtt(0.0), Link::rtt(0.0))?;
    let delayed = tug_of_war(&world, hand, Link::rtt(200.0), Link::rtt(200.0))?;
    let series: [(&str, RGBColor, u32, &[TraceSample]); 4] = [
        (
            "left (pulls), zero delay",
            RGBColor(240, 170, 170),
            7,
            &reference.traces[0],
        ),
        (
            "right (holds), zero delay",
            RGBColor(170, 190, 240),
            7,
            &reference.traces[1],
        ),
        (
            "left, both at 200 ms",
            RGBColor(200, 30, 30),
            2,
            &delayed.traces[0],
        ),
        (
            "right, both at 200 ms",
            RGBColor(30, 70, 200),
            2,
            &delayed.traces[1],
        ),
    ];
    let peak = series
        .iter()
        .flat_map(|(_, _, _, t)| t.iter().map(|s| magnitude(s.force_n)))
        .fold(0.0f32, f32::max);
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let root = BitMapBackend::new(path, (1200, 600)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Tug of war on tug_of_war.toml: left pulls, right holds (nominal hands)",
            ("sans-serif", 24),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0f64..TUG_RUN_S, 0.0f32..(peak * 1.15).max(0.5))
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc("time, s")
        .y_desc("force felt, N")
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(plot_error)?;
    for (label, color, width, trace) in series {
        chart
            .draw_series(LineSeries::new(
                trace.iter().map(|s| (s.t_s, magnitude(s.force_n))),
                color.stroke_width(width),
            ))
            .map_err(plot_error)?
            .label(label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
            });
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
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
        print_table(&options)?;
    }
    Ok(())
}

//! Force against depth of an 8 mm sphere pressed into the Hertz block (issue "Tissue from material data"):
//! Hertz's answer, the corotational FEM, the calibrated springs and the old hand-tuned per-edge springs, as a
//! table and a figure. The machinery is `sinew_testkit::hertz` (shared with `tests/tests/hertz.rs`); the answers are
//! static equilibria, so they do not depend on the machine.
//!
//! ```text
//! cargo bench -p sinew-testkit --bench hertz_figure                                         # the table
//! cargo bench -p sinew-testkit --bench hertz_figure -- --figure ../docs/hertz_force_depth.png  (relative to tests/)
//! cargo bench -p sinew-testkit --bench hertz_figure -- --simulated   # also the FEM as the simulation renders it
//! ```
//!
//! `--simulated` adds, at 1.5 mm, the force the simulation itself renders to the indenter (tool commands in,
//! the tick's output read after 1.5 s held): the block as a multi-rate object at 25 Hz (pinned contacts), and
//! stepped every 1 ms tick (about a minute: 20,789 tetrahedra a tick).
//!
//! The figure needs a TrueType font: DejaVu Sans (Debian `fonts-dejavu-core`) or the file in `SINEW_FONT`.

#![allow(clippy::print_stdout)] // a bench binary reports on stdout

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use plotters::prelude::*;
use sinew::figure_font::plot_error;
use sinew_testkit::hertz::{Material, block_parts, hertz_n, press};

/// Depths, mm: 0.25 to 3 in quarter millimetres.
fn depths_mm() -> Vec<f32> {
    (1..=12).map(|k| k as f32 * 0.25).collect()
}

fn parse_figure_path() -> anyhow::Result<Option<PathBuf>> {
    let mut figure = None;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--figure" => figure = Some(args.next().context("--figure needs a path")?.into()),
            "--bench" | "--simulated" => {} // cargo bench passes the first; main reads the second
            other => {
                anyhow::bail!("unknown argument `{other}` (known: --figure PATH, --simulated)")
            }
        }
    }
    Ok(figure)
}

fn main() -> anyhow::Result<()> {
    let figure = parse_figure_path()?;
    let depths = depths_mm();
    let mut curves = Vec::new();
    for material in Material::ALL {
        let forces = press(&block_parts(material)?, &depths);
        curves.push((material, forces));
    }
    print!("| depth, mm | Hertz, N |");
    for (material, _) in &curves {
        print!(" {}, N (error) |", material.label());
    }
    println!("\n|---|---|{}", "---|".repeat(curves.len()));
    for (k, &d) in depths.iter().enumerate() {
        let h = hertz_n(d);
        print!("| {d:.2} | {h:.4} |");
        for (_, forces) in &curves {
            print!(
                " {:.4} ({:+.1}%) |",
                forces[k],
                (forces[k] / h - 1.0) * 100.0
            );
        }
        println!();
    }
    if std::env::args().any(|a| a == "--simulated") {
        let h = hertz_n(1.5);
        for (label, step_hz) in [("multi-rate at 25 Hz", 25), ("stepped every tick", 1000)] {
            let f = sinew_testkit::hertz::sim_press(Material::Fem, step_hz, &[1.5])?[0];
            println!(
                "FEM in the simulation, {label}: 1.5 mm: {f:.4} N, Hertz {h:.4} N ({:+.1}%)",
                (f / h - 1.0) * 100.0
            );
        }
    }
    if let Some(path) = figure {
        draw(&path, &depths, &curves)?;
    }
    Ok(())
}

fn draw(path: &Path, depths: &[f32], curves: &[(Material, Vec<f32>)]) -> anyhow::Result<()> {
    sinew::figure_font::register_sans_serif()?;
    let peak = curves
        .iter()
        .flat_map(|(_, f)| f.iter().copied())
        .fold(hertz_n(3.0), f32::max);
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let root = BitMapBackend::new(path, (1000, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(plot_error)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "8 mm sphere into a 10 kPa, nu 0.45 block: force against depth",
            ("sans-serif", 24),
        )
        .margin(16)
        .x_label_area_size(44)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0f32..3.1f32, 0.0f32..peak * 1.05)
        .map_err(plot_error)?;
    chart
        .configure_mesh()
        .x_desc("depth, mm")
        .y_desc("force, N")
        .label_style(("sans-serif", 16))
        .draw()
        .map_err(plot_error)?;
    let hertz: Vec<(f32, f32)> = (0..=62)
        .map(|k| k as f32 * 0.05)
        .map(|d| (d, hertz_n(d)))
        .collect();
    chart
        .draw_series(LineSeries::new(
            hertz,
            RGBColor(120, 120, 120).stroke_width(6),
        ))
        .map_err(plot_error)?
        .label("Hertz, 4/3 E* sqrt(R) d^1.5")
        .legend(|(x, y)| {
            PathElement::new(
                vec![(x, y), (x + 24, y)],
                RGBColor(120, 120, 120).stroke_width(4),
            )
        });
    let colors = [
        RGBColor(30, 90, 200),
        RGBColor(30, 150, 60),
        RGBColor(200, 40, 40),
    ];
    for ((material, forces), color) in curves.iter().zip(colors) {
        let points: Vec<(f32, f32)> = depths.iter().copied().zip(forces.iter().copied()).collect();
        chart
            .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
            .map_err(plot_error)?
            .label(material.label())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3))
            });
        chart
            .draw_series(
                points
                    .into_iter()
                    .map(|p| Circle::new(p, 4, color.filled())),
            )
            .map_err(plot_error)?;
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

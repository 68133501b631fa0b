//! The TrueType font figures label with (plotters draws text with it): DejaVu Sans from the system, or the
//! file named by `SINEW_FONT`. Registered once per process as plotters' "sans-serif".

use std::path::PathBuf;
use std::sync::OnceLock;

/// Register the font as "sans-serif" (once; later calls return the first outcome).
pub fn register_sans_serif() -> anyhow::Result<()> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let bytes = font_bytes().map_err(|e| e.to_string())?;
            plotters::style::register_font("sans-serif", plotters::style::FontStyle::Normal, bytes)
                .map_err(|_| "the figure font is not a usable TrueType font".to_owned())
        })
        .clone()
        .map_err(anyhow::Error::msg)
}

/// A plotters drawing error as an error the figure benches report.
pub fn plot_error<E: std::fmt::Debug>(e: E) -> anyhow::Error {
    anyhow::anyhow!("drawing the figure: {e:?}")
}

fn font_bytes() -> anyhow::Result<&'static [u8]> {
    let candidates: Vec<PathBuf> = std::env::var_os("SINEW_FONT")
        .map(PathBuf::from)
        .into_iter()
        .chain([
            "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf".into(),
            "/usr/share/fonts/TTF/DejaVuSans.ttf".into(),
        ])
        .collect();
    for path in &candidates {
        if let Ok(bytes) = std::fs::read(path) {
            return Ok(Box::leak(bytes.into_boxed_slice()));
        }
    }
    anyhow::bail!(
        "no TrueType font for the figure labels (tried {candidates:?}): install fonts-dejavu-core or set SINEW_FONT"
    )
}

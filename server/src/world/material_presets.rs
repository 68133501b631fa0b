//! Tissue presets: Young's modulus, Poisson's ratio and density with their literature sources, read from
//! `worlds/material_presets.toml` (built into the binary, so a world names a preset without shipping the file).

use std::collections::BTreeMap;

use serde::Deserialize;

/// The presets file, as shipped.
pub const PRESETS_TOML: &str = include_str!(concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../worlds/material_presets.toml"
));

/// One preset.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialPreset {
    /// Young's modulus, kPa.
    pub youngs_modulus_kpa: f32,
    /// Poisson's ratio.
    pub poisson_ratio: f32,
    /// Density, kg/m^3.
    pub density_kg_per_m3: f32,
    /// Where the values come from.
    pub source: String,
}

/// Every preset by name (liver, skin, fat, muscle), or why the built-in file does not parse.
pub fn material_presets() -> Result<BTreeMap<String, MaterialPreset>, String> {
    toml::from_str(PRESETS_TOML).map_err(|e| format!("material_presets.toml: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_presets_parse_with_sources_and_values_in_range() {
        let presets = material_presets().unwrap();
        let names: Vec<&str> = presets.keys().map(String::as_str).collect();
        assert_eq!(names, ["fat", "liver", "muscle", "skin"]);
        for (name, p) in &presets {
            assert!(
                p.youngs_modulus_kpa > 0.5 && p.youngs_modulus_kpa < 1000.0,
                "{name}"
            );
            assert!(
                p.poisson_ratio >= 0.25 && p.poisson_ratio <= 0.499,
                "{name}"
            );
            assert!(
                p.density_kg_per_m3 > 800.0 && p.density_kg_per_m3 < 1300.0,
                "{name}"
            );
            assert!(p.source.len() > 40, "{name} has no source");
        }
    }
}

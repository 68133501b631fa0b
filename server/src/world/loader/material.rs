//! An object's material: presets, springs or finite elements, laws, calibration from elastic constants.

use toml::Spanned;

use crate::tissue::SpringLaw;
use crate::world::file_format::{
    CutSection, ElasticModel, LawSection, MaterialSection, MaterialValue,
};
use crate::world::material_presets::material_presets;

use super::*;

impl Context<'_> {
    /// `is_volume`: the object has tetrahedra (a `.msh` mesh or `extrude`), so density needs no thickness.
    /// The object's material keys, with a preset's modulus, ratio and density filled in where they are not given
    /// (errors in those then name the preset's line).
    pub(super) fn resolved_material(
        &self,
        i: usize,
        at: &Spanned<MaterialValue>,
        is_volume: bool,
    ) -> Result<MaterialSection, WorldError> {
        let (mut keys, preset) = match at.get_ref() {
            MaterialValue::Table(m) => ((**m).clone(), m.preset.clone()),
            MaterialValue::Preset(name) => (
                MaterialSection::default(),
                Some(Spanned::new(at.span(), name.clone())),
            ),
        };
        let Some(preset) = preset else {
            return Ok(keys);
        };
        let key = format!("objects[{i}].material.preset");
        let presets = material_presets().map_err(|e| self.invalid(&preset, &key, e))?;
        let Some(values) = presets.get(preset.get_ref()) else {
            let known: Vec<&str> = presets.keys().map(String::as_str).collect();
            return Err(self.invalid(
                &preset,
                &key,
                format!(
                    "unknown material preset `{}`: the presets are {}",
                    preset.get_ref(),
                    known.join(", ")
                ),
            ));
        };
        if !is_volume {
            return Err(self.invalid(
                &preset,
                &key,
                "material presets describe bulk tissue: use them on a volume (a .msh mesh, or `extrude`), or give a sheet's stiffness_n_per_mm",
            ));
        }
        let here = |v: f32| Spanned::new(preset.span(), v);
        keys.youngs_modulus_kpa
            .get_or_insert_with(|| here(values.youngs_modulus_kpa));
        keys.poisson_ratio
            .get_or_insert_with(|| here(values.poisson_ratio));
        if keys.mass_kg.is_none() {
            keys.density_kg_per_m3
                .get_or_insert_with(|| here(values.density_kg_per_m3));
        }
        Ok(keys)
    }

    /// `model` says what carries the elasticity; `object` is blamed for a key that is missing.
    pub(super) fn material(
        &self,
        i: usize,
        m: &MaterialSection,
        is_volume: bool,
        model: ElasticModel,
        object: &Spanned<String>,
    ) -> Result<MaterialSpec, WorldError> {
        let key = |k: &str| format!("objects[{i}].material.{k}");
        let mass = match (&m.mass_kg, &m.density_kg_per_m3, &m.thickness_mm) {
            (_, _, Some(thickness)) if is_volume => {
                return Err(self.invalid(
                    thickness,
                    &key("thickness_mm"),
                    "a volume mesh (.msh or extrude) takes its mass from its tetrahedra: give density_kg_per_m3 alone",
                ));
            }
            (None, Some(density), None) if is_volume => MassSpec::Density {
                kg_per_m3: self.positive(density, &key("density_kg_per_m3"))?,
                thickness_mm: 0.0,
            },
            (Some(total), None, None) => MassSpec::TotalKg(self.positive(total, &key("mass_kg"))?),
            // A calibrated sheet's thickness sets its stiffness, not its mass.
            (Some(total), None, Some(_))
                if model == ElasticModel::MassSpring && m.youngs_modulus_kpa.is_some() =>
            {
                MassSpec::TotalKg(self.positive(total, &key("mass_kg"))?)
            }
            (None, Some(density), Some(thickness)) => MassSpec::Density {
                kg_per_m3: self.positive(density, &key("density_kg_per_m3"))?,
                thickness_mm: self.positive(thickness, &key("thickness_mm"))?,
            },
            _ => {
                return Err(self.invalid(
                    object,
                    &key("mass_kg"),
                    if is_volume {
                        "give either mass_kg or density_kg_per_m3"
                    } else {
                        "give either mass_kg, or density_kg_per_m3 with thickness_mm"
                    },
                ));
            }
        };
        let elastic = self.elastic(i, m)?;
        let mut calibrated = None;
        let (stiffness, fem) = match (model, &m.stiffness_n_per_mm, elastic) {
            (ElasticModel::FemCorotational, Some(at), _) => {
                return Err(self.invalid(
                    at,
                    &key("stiffness_n_per_mm"),
                    "fem-corotational takes its stiffness from youngs_modulus_kpa and poisson_ratio: remove stiffness_n_per_mm",
                ));
            }
            (ElasticModel::FemCorotational, None, Some((youngs, poisson))) => (
                0.0,
                Some(crate::tissue::fem::FemMaterial {
                    youngs_modulus_n_per_mm2: youngs * N_PER_MM2_PER_KPA,
                    poisson_ratio: poisson,
                    corotated: true,
                }),
            ),
            (ElasticModel::FemCorotational, None, None) => {
                return Err(self.invalid(
                    object,
                    &key("youngs_modulus_kpa"),
                    "fem-corotational needs youngs_modulus_kpa and poisson_ratio in [objects.material]",
                ));
            }
            (ElasticModel::MassSpring, Some(at), None) => {
                (self.positive(at, &key("stiffness_n_per_mm"))?, None)
            }
            (ElasticModel::MassSpring, Some(at), Some(_)) => {
                return Err(self.invalid(
                    at,
                    &key("stiffness_n_per_mm"),
                    "give stiffness_n_per_mm, or youngs_modulus_kpa with poisson_ratio, not both",
                ));
            }
            (ElasticModel::MassSpring, None, Some((youngs, poisson))) => {
                calibrated = Some(self.spring_calibration(i, m, is_volume, youngs, poisson)?);
                (0.0, None)
            }
            (ElasticModel::MassSpring, None, None) => {
                return Err(self.invalid(
                    object,
                    &key("stiffness_n_per_mm"),
                    "give stiffness_n_per_mm (N/mm per edge), or youngs_modulus_kpa with poisson_ratio",
                ));
            }
        };
        let damping = match &m.damping_n_s_per_mm {
            None => 0.0,
            Some(at) => {
                let damping = *at.get_ref();
                self.check(
                    at,
                    &key("damping_n_s_per_mm"),
                    damping.is_finite() && damping >= 0.0,
                    &format!("must be >= 0 (got {damping})"),
                )?;
                damping
            }
        };
        let law = match &m.law {
            None => SpringLaw::Linear,
            Some(at) => match at.get_ref() {
                LawSection::Linear => SpringLaw::Linear,
                LawSection::PiecewiseLinear {
                    knee_strain,
                    stiffness_ratio,
                } => {
                    self.check(
                        at,
                        &key("law"),
                        knee_strain.is_finite()
                            && *knee_strain > 0.0
                            && stiffness_ratio.is_finite()
                            && *stiffness_ratio > 0.0
                            && *stiffness_ratio <= 1000.0,
                        "piecewise-linear needs knee_strain > 0 and stiffness_ratio in (0, 1000]",
                    )?;
                    SpringLaw::PiecewiseLinear {
                        knee_strain: *knee_strain,
                        stiffness_ratio: *stiffness_ratio,
                    }
                }
                LawSection::Exponential { stiffening } => {
                    self.check(
                        at,
                        &key("law"),
                        stiffening.is_finite() && *stiffening > 0.0 && *stiffening <= 100.0,
                        "exponential needs stiffening in (0, 100]",
                    )?;
                    SpringLaw::Exponential {
                        stiffening: *stiffening,
                    }
                }
            },
        };
        Ok(MaterialSpec {
            fem,
            calibrated,
            law,
            global_bulk_modulus_n_per_mm2: self
                .non_negative(&m.bulk_modulus_kpa, &key("bulk_modulus_kpa"))?
                * N_PER_MM2_PER_KPA,
            tet_bulk_modulus_n_per_mm2: self
                .non_negative(&m.tet_bulk_modulus_kpa, &key("tet_bulk_modulus_kpa"))?
                * N_PER_MM2_PER_KPA,
            mass,
            stiffness_n_per_mm: stiffness,
            damping_n_s_per_mm: damping,
            anchor_stiffness_n_per_mm: self.non_negative(
                &m.anchor_stiffness_n_per_mm,
                &key("anchor_stiffness_n_per_mm"),
            )?,
            drag_per_s: self.non_negative(&m.drag_per_s, &key("drag_per_s"))?,
            tear_strain: match &m.tear_strain {
                None => None,
                Some(at) => {
                    let strain = *at.get_ref();
                    self.check(
                        at,
                        &key("tear_strain"),
                        strain.is_finite() && strain > 0.0 && strain <= 100.0,
                        "must be a strain above 0 and at most 100 (0.5 tears a spring stretched to 1.5 times its rest length)",
                    )?;
                    Some(strain)
                }
            },
            cut_follows_blade: m
                .cut
                .as_ref()
                .is_some_and(|c| *c.get_ref() == CutSection::FollowBlade),
            cut_resistance_n: self.optional_in(
                &m.cut_resistance_n,
                &key("cut_resistance_n"),
                0.0..=5.0,
                MaterialSpec::DEFAULT_CUT_RESISTANCE_N,
                "must be 0 to 5 N",
            )?,
            burn_shrink: self.optional_in(
                &m.burn_shrink,
                &key("burn_shrink"),
                0.0..=0.5,
                0.0,
                "must be 0 to 0.5 (the share of rest length a fully burnt spring loses)",
            )?,
            friction_coefficient: self.optional_in(
                &m.friction_coefficient,
                &key("friction_coefficient"),
                0.0..=2.0,
                0.0,
                "must be 0 to 2 (Coulomb's coefficient; 0 is frictionless)",
            )?,
            puncture: crate::tissue::PunctureSpec {
                force_n: self.optional_in(
                    &m.puncture_force_n,
                    &key("puncture_force_n"),
                    0.05..=50.0,
                    crate::tissue::PunctureSpec::DEFAULT.force_n,
                    "must be 0.05 to 50 N (skin-like tissue takes 1-4 N)",
                )?,
                max_angle_rad: self
                    .optional_in(
                        &m.puncture_max_angle_deg,
                        &key("puncture_max_angle_deg"),
                        1.0..=89.0,
                        crate::tissue::PunctureSpec::DEFAULT.max_angle_rad.to_degrees(),
                        "must be 1 to 89 degrees from the surface's normal",
                    )?
                    .to_radians(),
                needle_friction: self.optional_in(
                    &m.needle_friction,
                    &key("needle_friction"),
                    0.0..=2.0,
                    crate::tissue::PunctureSpec::DEFAULT.needle_friction,
                    "must be 0 to 2 (Coulomb's coefficient; published needle-tissue values are 0.12-0.34)",
                )?,
                suture_tear_n: match &m.suture_tear_n {
                    None => None,
                    Some(at) => {
                        let force_n = *at.get_ref();
                        self.check(
                            at,
                            &key("suture_tear_n"),
                            force_n.is_finite() && (0.1..=50.0).contains(&force_n),
                            "must be 0.1 to 50 N (skin-like tissue lets a 3-0 to 5-0 suture cut out at 3.3-4.1 N)",
                        )?;
                        Some(force_n)
                    }
                },
            },
        })
    }

    /// What a mass-spring object's springs are calibrated to: a volume's Poisson's ratio must be at least the
    /// network's 1/4 (a volume term adds the rest), a sheet's must be its network's 1/3 and it needs a thickness.
    pub(super) fn spring_calibration(
        &self,
        i: usize,
        m: &MaterialSection,
        is_volume: bool,
        youngs_kpa: f32,
        poisson: f32,
    ) -> Result<SpringCalibration, WorldError> {
        use crate::tissue::calibration::{SHEET_NETWORK_POISSON, TET_NETWORK_POISSON};
        let key = |k: &str| format!("objects[{i}].material.{k}");
        // Both are given (the caller has checked them in pairs).
        let (Some(at_youngs), Some(at_poisson)) = (&m.youngs_modulus_kpa, &m.poisson_ratio) else {
            return Ok(SpringCalibration {
                youngs_modulus_n_per_mm2: youngs_kpa * N_PER_MM2_PER_KPA,
                poisson_ratio: poisson,
                thickness_mm: 0.0,
            });
        };
        let thickness_mm = if is_volume {
            if poisson < TET_NETWORK_POISSON {
                return Err(self.invalid(
                    at_poisson,
                    &key("poisson_ratio"),
                    format!("calibrated springs on a volume need poisson_ratio >= {TET_NETWORK_POISSON} (a spring network's own ratio; a volume term adds the rest): use model = \"fem-corotational\" for {poisson}"),
                ));
            }
            0.0
        } else {
            if (poisson - SHEET_NETWORK_POISSON).abs() > 0.005 {
                return Err(self.invalid(
                    at_poisson,
                    &key("poisson_ratio"),
                    format!("a sheet of springs has Poisson's ratio 1/3 whatever its constants (got {poisson}): give poisson_ratio = 0.333, or make the tissue a volume (extrude or .msh)"),
                ));
            }
            match &m.thickness_mm {
                Some(at) => self.positive(at, &key("thickness_mm"))?,
                None => {
                    return Err(self.invalid(
                        at_youngs,
                        &key("thickness_mm"),
                        "calibrated springs on a sheet need thickness_mm, the sheet's thickness (its stiffness is E times thickness)",
                    ));
                }
            }
        };
        Ok(SpringCalibration {
            youngs_modulus_n_per_mm2: youngs_kpa * N_PER_MM2_PER_KPA,
            poisson_ratio: poisson,
            thickness_mm,
        })
    }

    /// Young's modulus (kPa) and Poisson's ratio, if given: both or neither, each in range.
    pub(super) fn elastic(
        &self,
        i: usize,
        m: &MaterialSection,
    ) -> Result<Option<(f32, f32)>, WorldError> {
        let key = |k: &str| format!("objects[{i}].material.{k}");
        match (&m.youngs_modulus_kpa, &m.poisson_ratio) {
            (None, None) => Ok(None),
            (Some(at), None) => Err(self.invalid(
                at,
                &key("poisson_ratio"),
                "youngs_modulus_kpa needs poisson_ratio beside it",
            )),
            (None, Some(at)) => Err(self.invalid(
                at,
                &key("youngs_modulus_kpa"),
                "poisson_ratio needs youngs_modulus_kpa beside it",
            )),
            (Some(e), Some(nu)) => {
                let youngs = *e.get_ref();
                self.check(
                    e,
                    &key("youngs_modulus_kpa"),
                    youngs.is_finite() && youngs > 0.0 && youngs <= MAX_YOUNGS_MODULUS_KPA,
                    &format!("must be above 0 and at most {MAX_YOUNGS_MODULUS_KPA} kPa (got {youngs}); soft tissue is 0.1 to 1000 kPa"),
                )?;
                let poisson = *nu.get_ref();
                self.check(
                    nu,
                    &key("poisson_ratio"),
                    poisson.is_finite() && (0.0..=MAX_POISSON_RATIO).contains(&poisson),
                    &format!("must be 0 to {MAX_POISSON_RATIO} (got {poisson}); 0.5 is incompressible, which no finite stiffness holds"),
                )?;
                Ok(Some((youngs, poisson)))
            }
        }
    }
}

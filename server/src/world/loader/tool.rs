//! A tool's section: shape, shaft, coupling, limits, and its instrument (grasper, cautery, scalpel, scissors;
//! a needle driver's keys are read in `needle_driver.rs`).

use std::path::Path;

use toml::Spanned;

use crate::world::file_format::{
    ActivationName, InstrumentKindName, InstrumentSection, ShapeSection, ToolSection,
};
use crate::world::mesh_file::{load_obj_mesh, validate_closed};

use super::*;

impl Context<'_> {
    pub(super) fn tool(
        &self,
        i: usize,
        tool: &ToolSection,
        base: &Path,
    ) -> Result<ToolSpec, WorldError> {
        let key = |k: &str| format!("tools[{i}].{k}");
        let device_id = tool.device.get_ref().clone();
        if let Err(e) = sinew_protocol::keys::validate_segment("device", &device_id) {
            return Err(self.invalid(&tool.device, &key("device"), e.to_string()));
        }
        if tool.name.get_ref().is_empty() {
            return Err(self.invalid(&tool.name, &key("name"), "empty"));
        }
        let dims_ok = |dims: &[f32]| dims.iter().all(|d| d.is_finite() && *d > 0.0);
        let shape = match tool.shape.get_ref() {
            ShapeSection::Sphere { radius_mm } => {
                self.check(
                    &tool.shape,
                    &key("shape"),
                    dims_ok(&[*radius_mm]),
                    "radius_mm must be positive",
                )?;
                ToolShapeSpec::Sphere {
                    radius_mm: *radius_mm,
                }
            }
            ShapeSection::Capsule {
                half_length_mm,
                radius_mm,
            } => {
                self.check(
                    &tool.shape,
                    &key("shape"),
                    dims_ok(&[*half_length_mm, *radius_mm]),
                    "half_length_mm and radius_mm must be positive",
                )?;
                ToolShapeSpec::Capsule {
                    half_length_mm: *half_length_mm,
                    radius_mm: *radius_mm,
                }
            }
            ShapeSection::Mesh { mesh, units } => {
                let mesh_error = |reason| WorldError::Mesh {
                    file: self.path.to_owned(),
                    line: self.line(tool.shape.span()),
                    key: key("shape.mesh"),
                    mesh: mesh.clone(),
                    reason,
                };
                let surface = load_obj_mesh(&base.join(mesh), units.to_mm()).map_err(mesh_error)?;
                validate_closed(&surface).map_err(mesh_error)?;
                ToolShapeSpec::Mesh(surface)
            }
        };
        self.check(
            &tool.device,
            &key("device_origin_in_world_mm"),
            tool.device_origin_in_world_mm.iter().all(|c| c.is_finite()),
            "must be finite",
        )?;
        let max_force_n = self.positive(&tool.max_force_n, &key("max_force_n"))?;
        let mut coupling = crate::haptics::CouplingParams::default();
        if let Some(at) = &tool.coupling {
            let section = at.get_ref();
            let fields = [
                (
                    section.stiffness_n_per_mm,
                    "stiffness_n_per_mm",
                    &mut coupling.stiffness_n_per_mm,
                ),
                (
                    section.damping_n_s_per_mm,
                    "damping_n_s_per_mm",
                    &mut coupling.damping_n_s_per_mm,
                ),
                (
                    section.max_speed_mm_s,
                    "max_speed_mm_s",
                    &mut coupling.max_speed_mm_s,
                ),
            ];
            for (value, name, slot) in fields {
                if let Some(value) = value {
                    self.check(
                        at,
                        &key(&format!("coupling.{name}")),
                        value.is_finite() && value > 0.0,
                        "must be a positive number",
                    )?;
                    *slot = value;
                }
            }
        }
        let instrument = match &tool.instrument {
            None => crate::world::InstrumentSpec::Probe,
            Some(at) => self.instrument(i, at)?,
        };
        let shaft = match &tool.shaft {
            None => None,
            Some(at) => {
                let section = at.get_ref();
                self.check(
                    at,
                    &key("shaft.radius_mm"),
                    section.radius_mm.is_finite() && (0.1..=50.0).contains(&section.radius_mm),
                    "must be 0.1 to 50 mm",
                )?;
                self.check(
                    at,
                    &key("shaft.length_mm"),
                    section.length_mm.is_finite() && (1.0..=1000.0).contains(&section.length_mm),
                    "must be 1 to 1000 mm",
                )?;
                Some(ShaftSpec {
                    radius_mm: section.radius_mm,
                    length_mm: section.length_mm,
                })
            }
        };
        Ok(ToolSpec {
            name: tool.name.get_ref().clone(),
            device_id,
            shape,
            device_origin_in_world_mm: tool.device_origin_in_world_mm,
            max_force_n,
            coupling,
            instrument,
            shaft,
        })
    }

    /// An optional number: `default` when absent, else the value if it is finite and within `range`; else the
    /// error names `key` and its line.
    pub(super) fn optional_in(
        &self,
        value: &Option<Spanned<f32>>,
        key: &str,
        range: std::ops::RangeInclusive<f32>,
        default: f32,
        says: &str,
    ) -> Result<f32, WorldError> {
        match value {
            None => Ok(default),
            Some(at) => {
                let v = *at.get_ref();
                self.check(at, key, v.is_finite() && range.contains(&v), says)?;
                Ok(v)
            }
        }
    }

    /// `value`, when given, into `slot` if it is finite and `ok`; else the error names `key`.
    pub(super) fn take_checked<T>(
        &self,
        at: &Spanned<T>,
        key: &str,
        value: Option<f32>,
        ok: impl Fn(f32) -> bool,
        says: &str,
        slot: &mut f32,
    ) -> Result<(), WorldError> {
        if let Some(value) = value {
            self.check(at, key, value.is_finite() && ok(value), says)?;
            *slot = value;
        }
        Ok(())
    }

    /// An instrument's button mask (default button 1): at least one bit.
    pub(super) fn button_mask<T>(
        &self,
        at: &Spanned<T>,
        key: &str,
        mask: Option<u32>,
    ) -> Result<u32, WorldError> {
        let mask = mask.unwrap_or(1);
        self.check(at, key, mask != 0, "must name at least one button bit")?;
        Ok(mask)
    }

    /// The `activation` keys of an instrument with jaws (a grasper, scissors): a button (default 1) or a
    /// gripper's angle with its hysteresis band, each key checked.
    pub(super) fn jaw_activation(
        &self,
        i: usize,
        at: &Spanned<InstrumentSection>,
    ) -> Result<crate::world::JawActivation, WorldError> {
        use crate::world::{GraspSpec, JawActivation};
        let section = at.get_ref();
        let key = |k: &str| format!("tools[{i}].instrument.{k}");
        let rad = |deg: f32| deg.to_radians();
        let angle_keys = section.close_below_deg.is_some() || section.open_above_deg.is_some();
        let activation = match section.activation.unwrap_or(ActivationName::Button) {
            ActivationName::Button => {
                if angle_keys {
                    return Err(self.invalid(
                        at,
                        &key("close_below_deg"),
                        "the jaw angle thresholds need activation = \"angle\"",
                    ));
                }
                JawActivation::Button {
                    mask: self.button_mask(at, &key("button_mask"), section.button_mask)?,
                }
            }
            ActivationName::Angle => {
                if section.button_mask.is_some() {
                    return Err(self.invalid(
                        at,
                        &key("button_mask"),
                        "a button mask needs activation = \"button\"",
                    ));
                }
                let JawActivation::Angle {
                    mut close_below_rad,
                    mut open_above_rad,
                } = GraspSpec::ANGLE_DEFAULT
                else {
                    unreachable!("the angle default is an angle activation")
                };
                if let Some(deg) = section.close_below_deg {
                    close_below_rad = rad(deg);
                }
                if let Some(deg) = section.open_above_deg {
                    open_above_rad = rad(deg);
                }
                self.check(
                    at,
                    &key("close_below_deg"),
                    close_below_rad.is_finite() && close_below_rad >= 0.0,
                    "must be a number >= 0",
                )?;
                self.check(
                    at,
                    &key("open_above_deg"),
                    open_above_rad.is_finite() && open_above_rad > close_below_rad,
                    "must be above close_below_deg (the hysteresis band)",
                )?;
                JawActivation::Angle {
                    close_below_rad,
                    open_above_rad,
                }
            }
        };
        Ok(activation)
    }

    /// `tools[i].instrument`: every key checked for its kind and its range.
    pub(super) fn instrument(
        &self,
        i: usize,
        at: &Spanned<InstrumentSection>,
    ) -> Result<crate::world::InstrumentSpec, WorldError> {
        use crate::world::{GraspSpec, InstrumentSpec};
        let section = at.get_ref();
        let key = |k: &str| format!("tools[{i}].instrument.{k}");
        // Which keys each kind takes; any other given key is refused by name.
        let given = [
            ("activation", section.activation.is_some()),
            ("button_mask", section.button_mask.is_some()),
            ("close_below_deg", section.close_below_deg.is_some()),
            ("open_above_deg", section.open_above_deg.is_some()),
            ("open_angle_deg", section.open_angle_deg.is_some()),
            ("jaw_length_mm", section.jaw_length_mm.is_some()),
            ("bite_mm", section.bite_mm.is_some()),
            ("slip_force_n", section.slip_force_n.is_some()),
            ("max_attachments", section.max_attachments.is_some()),
            ("burn_per_s", section.burn_per_s.is_some()),
            ("reach_mm", section.reach_mm.is_some()),
            ("edge_from_mm", section.edge_from_mm.is_some()),
            ("edge_to_mm", section.edge_to_mm.is_some()),
            ("cut_resistance_n", section.cut_resistance_n.is_some()),
            ("blade_length_mm", section.blade_length_mm.is_some()),
            ("hinge_mm", section.hinge_mm.is_some()),
            ("needle_radius_mm", section.needle_radius_mm.is_some()),
            ("needle_sweep_deg", section.needle_sweep_deg.is_some()),
            ("needle_diameter_mm", section.needle_diameter_mm.is_some()),
            ("grasp_at_deg", section.grasp_at_deg.is_some()),
            ("thread_length_mm", section.thread_length_mm.is_some()),
            ("thread_segments", section.thread_segments.is_some()),
        ];
        let (takes, kind_says): (&[&str], &str) = match section.kind {
            InstrumentKindName::Probe => (
                &[],
                "a probe has no jaws or tip: only a grasper or a cautery tool takes it",
            ),
            InstrumentKindName::Grasper => (
                &[
                    "activation",
                    "button_mask",
                    "close_below_deg",
                    "open_above_deg",
                    "open_angle_deg",
                    "jaw_length_mm",
                    "bite_mm",
                    "slip_force_n",
                    "max_attachments",
                ],
                "a grasper does not take it",
            ),
            InstrumentKindName::Cautery => (
                &["button_mask", "burn_per_s", "reach_mm"],
                "a cautery tool takes button_mask, burn_per_s and reach_mm",
            ),
            InstrumentKindName::Scalpel => (
                &["edge_from_mm", "edge_to_mm"],
                "a scalpel takes edge_from_mm and edge_to_mm (the drag of cutting is the tissue's: \
                 [objects.material] cut_resistance_n)",
            ),
            InstrumentKindName::Scissors => (
                &[
                    "activation",
                    "button_mask",
                    "close_below_deg",
                    "open_above_deg",
                    "open_angle_deg",
                    "blade_length_mm",
                    "hinge_mm",
                ],
                "scissors take activation, button_mask, close_below_deg, open_above_deg, open_angle_deg, \
                 blade_length_mm and hinge_mm",
            ),
            InstrumentKindName::NeedleDriver => (
                &[
                    "jaw_length_mm",
                    "needle_radius_mm",
                    "needle_sweep_deg",
                    "needle_diameter_mm",
                    "grasp_at_deg",
                    "thread_length_mm",
                    "thread_segments",
                ],
                "a needle driver takes jaw_length_mm, needle_radius_mm, needle_sweep_deg, \
                 needle_diameter_mm, grasp_at_deg, thread_length_mm and thread_segments",
            ),
        };
        if let Some((name, _)) = given
            .iter()
            .find(|(name, given)| *given && !takes.contains(name))
        {
            return Err(self.invalid(at, &key(name), kind_says));
        }
        match section.kind {
            InstrumentKindName::Probe => Ok(InstrumentSpec::Probe),
            InstrumentKindName::NeedleDriver => self.needle_driver(i, at),
            InstrumentKindName::Scalpel => {
                let mut scalpel = crate::world::ScalpelSpec::DEFAULT;
                for (k, (name, value)) in [
                    ("edge_from_mm", section.edge_from_mm),
                    ("edge_to_mm", section.edge_to_mm),
                ]
                .into_iter()
                .enumerate()
                {
                    if let Some(p) = value {
                        self.check(
                            at,
                            &key(name),
                            p.iter().all(|c| c.is_finite() && c.abs() <= 500.0),
                            "must be three finite numbers within 500 mm of the tool origin",
                        )?;
                        scalpel.edge_mm[k] = p;
                    }
                }
                let [a, b] = scalpel.edge_mm;
                let length =
                    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
                self.check(
                    at,
                    &key("edge_to_mm"),
                    length >= 0.1,
                    "the edge must be at least 0.1 mm long (edge_from_mm and edge_to_mm too close)",
                )?;
                Ok(InstrumentSpec::Scalpel(scalpel))
            }
            InstrumentKindName::Scissors => {
                let mut scissors = crate::world::ScissorsSpec::DEFAULT;
                scissors.activation = self.jaw_activation(i, at)?;
                self.take_checked(
                    at,
                    &key("open_angle_deg"),
                    section.open_angle_deg.map(f32::to_radians),
                    |v| v > 2.0 * crate::world::ScissorsSpec::CROSSING_RAD && v <= 1.6,
                    "must be more than 6 and at most about 90 degrees",
                    &mut scissors.open_angle_rad,
                )?;
                self.take_checked(
                    at,
                    &key("blade_length_mm"),
                    section.blade_length_mm,
                    |v| (1.0..=200.0).contains(&v),
                    "must be 1 to 200 mm",
                    &mut scissors.blade_length_mm,
                )?;
                if let Some(p) = section.hinge_mm {
                    self.check(
                        at,
                        &key("hinge_mm"),
                        p.iter().all(|c| c.is_finite() && c.abs() <= 500.0),
                        "must be three finite numbers within 500 mm of the tool origin",
                    )?;
                    scissors.hinge_mm = p;
                }
                Ok(InstrumentSpec::Scissors(scissors))
            }
            InstrumentKindName::Cautery => {
                let mut cautery = crate::world::CauterySpec::DEFAULT;
                cautery.button_mask =
                    self.button_mask(at, &key("button_mask"), section.button_mask)?;
                self.take_checked(
                    at,
                    &key("burn_per_s"),
                    section.burn_per_s,
                    |rate| rate > 0.0 && rate <= 100_000.0,
                    "must be a positive number of burn levels per second, at most 100000",
                    &mut cautery.burn_per_s,
                )?;
                self.take_checked(
                    at,
                    &key("reach_mm"),
                    section.reach_mm,
                    |reach| (0.0..=10.0).contains(&reach),
                    "must be 0 to 10 mm",
                    &mut cautery.reach_mm,
                )?;
                Ok(InstrumentSpec::Cautery(cautery))
            }
            InstrumentKindName::Grasper => {
                let mut grasp = GraspSpec::DEFAULT;
                let rad = |deg: f32| deg.to_radians();
                grasp.activation = self.jaw_activation(i, at)?;
                let positive = [
                    (
                        "open_angle_deg",
                        section.open_angle_deg.map(rad),
                        &mut grasp.open_angle_rad,
                        180.0f32.to_radians(),
                    ),
                    (
                        "jaw_length_mm",
                        section.jaw_length_mm,
                        &mut grasp.jaw_length_mm,
                        200.0,
                    ),
                    (
                        "slip_force_n",
                        section.slip_force_n,
                        &mut grasp.slip_force_n,
                        100.0,
                    ),
                ];
                for (name, value, slot, most) in positive {
                    self.take_checked(
                        at,
                        &key(name),
                        value,
                        |v| v > 0.0 && v <= most,
                        &format!("must be a positive number, at most {most}"),
                        slot,
                    )?;
                }
                self.take_checked(
                    at,
                    &key("bite_mm"),
                    section.bite_mm,
                    |bite| (0.0..=10.0).contains(&bite),
                    "must be 0 to 10 mm",
                    &mut grasp.bite_mm,
                )?;
                if let Some(most) = section.max_attachments {
                    self.check(
                        at,
                        &key("max_attachments"),
                        (1..=crate::interaction::MAX_ATTACHMENTS).contains(&most),
                        &format!("must be 1 to {}", crate::interaction::MAX_ATTACHMENTS),
                    )?;
                    grasp.max_attachments = most;
                }
                Ok(InstrumentSpec::Grasper(grasp))
            }
        }
    }
}

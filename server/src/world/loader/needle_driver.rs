//! A needle driver's keys: `instrument = { kind = "needle_driver", jaw_length_mm, needle_radius_mm,
//! needle_sweep_deg, needle_diameter_mm, grasp_at_deg, thread_length_mm, thread_segments }`, each checked for
//! its range.

use toml::Spanned;

use crate::interaction::suture::{NeedleArc, NeedleDriverSpec, ThreadSpec};
use crate::world::file_format::InstrumentSection;

use super::*;

impl Context<'_> {
    /// `tools[i].instrument` of kind `needle_driver` (its keys already checked to be a needle driver's).
    pub(super) fn needle_driver(
        &self,
        i: usize,
        at: &Spanned<InstrumentSection>,
    ) -> Result<crate::world::InstrumentSpec, WorldError> {
        let section = at.get_ref();
        let key = |k: &str| format!("tools[{i}].instrument.{k}");
        let mut spec = NeedleDriverSpec::DEFAULT;
        self.take_checked(
            at,
            &key("jaw_length_mm"),
            section.jaw_length_mm,
            |v| (1.0..=200.0).contains(&v),
            "must be 1 to 200 mm",
            &mut spec.jaw_length_mm,
        )?;
        let mut radius_mm = spec.arc.radius_mm();
        self.take_checked(
            at,
            &key("needle_radius_mm"),
            section.needle_radius_mm,
            |v| (2.0..=50.0).contains(&v),
            "must be 2 to 50 mm (skin needles are 5-20 mm)",
            &mut radius_mm,
        )?;
        let mut sweep_deg = spec.arc.sweep_rad().to_degrees();
        self.take_checked(
            at,
            &key("needle_sweep_deg"),
            section.needle_sweep_deg,
            |v| (30.0..=270.0).contains(&v),
            "must be 30 to 270 degrees (a 3/8 circle is 135, a half circle 180)",
            &mut sweep_deg,
        )?;
        let arc = NeedleArc::new(radius_mm, sweep_deg)
            .map_err(|e| self.invalid(at, &key("needle_radius_mm"), e.to_string()))?;
        spec.arc = arc;
        self.take_checked(
            at,
            &key("needle_diameter_mm"),
            section.needle_diameter_mm,
            |v| v > 0.0 && v <= 0.25 * radius_mm && v <= 3.0,
            "must be above 0 and at most 3 mm and a quarter of the needle's radius",
            &mut spec.diameter_mm,
        )?;
        let mut grasp_at_deg = spec.grasp_at_rad.to_degrees().min(sweep_deg);
        if section.grasp_at_deg.is_none() {
            // The default grip, a third of the way from the tail, on whatever needle was given.
            grasp_at_deg = sweep_deg / 3.0;
        }
        self.take_checked(
            at,
            &key("grasp_at_deg"),
            section.grasp_at_deg,
            |v| v >= 0.0 && v <= 0.75 * sweep_deg,
            "must be 0 (the tail) to three quarters of needle_sweep_deg: the jaws hold the needle behind its point",
            &mut grasp_at_deg,
        )?;
        spec.grasp_at_rad = grasp_at_deg.to_radians();
        self.take_checked(
            at,
            &key("thread_length_mm"),
            section.thread_length_mm,
            |v| v == 0.0 || (10.0..=1000.0).contains(&v),
            "must be 0 (no thread) or 10 to 1000 mm",
            &mut spec.thread.length_mm,
        )?;
        if let Some(segments) = section.thread_segments {
            self.check(
                at,
                &key("thread_segments"),
                (4..=512).contains(&segments),
                "must be 4 to 512",
            )?;
            spec.thread.segments = segments;
        }
        if spec.thread.is_some() && spec.thread.segment_mm() > ThreadSpec::MAX_SEGMENT_MM {
            let named = if section.thread_segments.is_some() {
                "thread_segments"
            } else {
                "thread_length_mm"
            };
            return Err(self.invalid(
                at,
                &key(named),
                format!(
                    "a thread of {} mm in {} segments has segments of {:.2} mm: at most {} mm each \
                     (give more thread_segments)",
                    spec.thread.length_mm,
                    spec.thread.segments,
                    spec.thread.segment_mm(),
                    ThreadSpec::MAX_SEGMENT_MM
                ),
            ));
        }
        Ok(crate::world::InstrumentSpec::NeedleDriver(spec))
    }
}

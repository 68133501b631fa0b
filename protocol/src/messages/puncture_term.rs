//! The pop of a needle's puncture, rendered at the device: what a local model carries while a needle's tip
//! tents a surface, so a distant hand feels the tissue give the tick its own push passes the material's
//! threshold, not a round trip later.
//!
//! Owns: [`PunctureTerm`] and its domain checks. Must not: evaluate it (the hapticserver's renderer does: it
//! watches its own rendered force along the tip and, past [`PunctureTerm::pop_at_n`], renders the model as
//! [`PunctureTerm::after`] makes it) or build it (the server's needle model).
//!
//! A needle is driven by rolling its driver: the tip advances mostly by the turn, which a model linear in the
//! device's position cannot see (held at its tail, the tip of a half-circle needle moves against the jaws'
//! own translation). So the term also carries the tip's lever from the tool's origin and the tool's
//! orientation the model was built at (wire v17): the device adds the push the turn since then gives the tip
//! ([`PunctureTerm::rolled_push_n`]), and pops on its own turn too.
//!
//! Frames and units: the device frame, mm, N, N/mm, as the enclosing [`crate::LocalModel`].

use serde::{Deserialize, Serialize};

use crate::codec::{FieldError, check};
use crate::messages::local_model::{LocalModel, Sym3, sym3_is_psd, sym3_mul};

/// A needle's tip pressing a surface, about to puncture it (zero: no needle presses; see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct PunctureTerm {
    /// Which press this is: the server counts every surface a needle's tip starts to press, and a device pops
    /// each press once (0: no term).
    pub press: u32,
    /// The tip punctures when the model's linear force pushes back against the tip's direction by this much,
    /// N (> 0): the material's puncture force, plus what the rest of the model (the needle's holes, the thread)
    /// pushes back along the tip at `x0`.
    pub pop_at_n: f32,
    /// The direction the tip drives along, unit, device frame.
    pub tip_axis: [f32; 3],
    /// After the pop, the model's force at `x0`, N: the tip's load gone, the rest of the model's force left.
    pub f0_after_n: [f32; 3],
    /// After the pop, the model's stiffness, N/mm, symmetric positive semi-definite: free along the tip (the
    /// needle slides on through its new hole), the tissue's stiffness across it.
    pub stiffness_after_n_per_mm: Sym3,
    /// After the pop, the needle's drag through its holes against the device's motion, N (>= 0; rendered as
    /// [`LocalModel::cut_drag_n`] is).
    pub drag_after_n: f32,
    /// The tip less the tool's origin when the model was built, mm, device frame (v17).
    pub tip_lever_mm: [f32; 3],
    /// The tool's orientation when the model was built, a unit quaternion `[x, y, z, w]`, device frame (as the
    /// device's pose reports it) (v17).
    pub orientation_xyzw: [f32; 4],
}

/// The longest tip lever a term may carry, mm.
const MAX_LEVER_MM: f32 = 1000.0;

/// `a b` for quaternions `[x, y, z, w]`.
fn quat_mul(a: [f32; 4], b: [f32; 4]) -> [f32; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

fn quat_conjugate(q: [f32; 4]) -> [f32; 4] {
    [-q[0], -q[1], -q[2], q[3]]
}

/// `v` turned by the unit quaternion `q`.
fn quat_rotate(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    let r = quat_mul(quat_mul(q, [v[0], v[1], v[2], 0.0]), quat_conjugate(q));
    [r[0], r[1], r[2]]
}

impl PunctureTerm {
    /// Whether a needle presses (the term applies).
    pub fn is_active(&self) -> bool {
        self.press != 0
    }

    /// Domain checks: an inactive term is all zero; an active one has a positive, finite `pop_at_n`, a unit
    /// tip axis, finite forces, a positive semi-definite stiffness and a non-negative drag.
    pub fn validate(&self) -> Result<(), FieldError> {
        if !self.is_active() {
            return if *self == Self::default() {
                Ok(())
            } else {
                Err(("local_model.puncture", "press 0 with a term"))
            };
        }
        check::finite("local_model.puncture.pop_at_n", &[self.pop_at_n])?;
        if self.pop_at_n <= 0.0 {
            return Err(("local_model.puncture.pop_at_n", "must be > 0"));
        }
        check::finite("local_model.puncture.tip_axis", &self.tip_axis)?;
        let norm = self.tip_axis.iter().map(|c| c * c).sum::<f32>().sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(("local_model.puncture.tip_axis", "not unit length"));
        }
        check::finite("local_model.puncture.f0_after_n", &self.f0_after_n)?;
        check::finite(
            "local_model.puncture.stiffness_after_n_per_mm",
            &self.stiffness_after_n_per_mm,
        )?;
        if !sym3_is_psd(&self.stiffness_after_n_per_mm) {
            return Err((
                "local_model.puncture.stiffness_after_n_per_mm",
                "not positive semi-definite",
            ));
        }
        check::finite("local_model.puncture.drag_after_n", &[self.drag_after_n])?;
        if self.drag_after_n < 0.0 {
            return Err(("local_model.puncture.drag_after_n", "negative"));
        }
        check::finite("local_model.puncture.tip_lever_mm", &self.tip_lever_mm)?;
        if self.tip_lever_mm.iter().any(|c| c.abs() > MAX_LEVER_MM) {
            return Err(("local_model.puncture.tip_lever_mm", "longer than 1 m"));
        }
        check::finite(
            "local_model.puncture.orientation_xyzw",
            &self.orientation_xyzw,
        )?;
        let norm = self
            .orientation_xyzw
            .iter()
            .map(|c| c * c)
            .sum::<f32>()
            .sqrt();
        if (norm - 1.0).abs() > 1e-3 {
            return Err(("local_model.puncture.orientation_xyzw", "not unit length"));
        }
        Ok(())
    }

    /// How much harder the tip pushes back for the turn the device has made since the model was built, N, with
    /// `stiffness` the model's `K` and `orientation_xyzw` the device's orientation now (unit, `[x, y, z, w]`):
    /// the turn moves the tip by `d = (q_now q_model^-1 - I) lever`, and the tissue answers `K d` along the
    /// tip, as it answers a translation. Zero for an inactive term or a non-finite orientation.
    pub fn rolled_push_n(&self, stiffness: &Sym3, orientation_xyzw: [f32; 4]) -> f32 {
        if !self.is_active() || !orientation_xyzw.iter().all(|c| c.is_finite()) {
            return 0.0;
        }
        let turn = quat_mul(orientation_xyzw, quat_conjugate(self.orientation_xyzw));
        let turned = quat_rotate(turn, self.tip_lever_mm);
        let moved: [f32; 3] = std::array::from_fn(|k| turned[k] - self.tip_lever_mm[k]);
        let force = sym3_mul(stiffness, &moved);
        let push =
            force[0] * self.tip_axis[0] + force[1] * self.tip_axis[1] + force[2] * self.tip_axis[2];
        if push.is_finite() { push } else { 0.0 }
    }

    /// How hard `force_n` (the model's linear force, N) pushes back against the tip's direction, N.
    pub fn push_back_n(&self, force_n: [f32; 3]) -> f32 {
        -(force_n[0] * self.tip_axis[0]
            + force_n[1] * self.tip_axis[1]
            + force_n[2] * self.tip_axis[2])
    }

    /// `model` (which carries this term) as it is once the tip has punctured: the tip's load gone, free along
    /// the tip, the holes' drag against the motion, and no term (the press is over). Still attached (the
    /// needle's holes hold it).
    pub fn after(&self, model: &LocalModel) -> LocalModel {
        LocalModel {
            f0_n: self.f0_after_n,
            stiffness_n_per_mm: self.stiffness_after_n_per_mm,
            cut_drag_n: self.drag_after_n,
            cut_facet_mm: 0.0,
            friction_coefficient: 0.0,
            stick_stiffness_n_per_mm: 0.0,
            attached: true,
            puncture: PunctureTerm::default(),
            ..*model
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn term() -> PunctureTerm {
        PunctureTerm {
            press: 3,
            pop_at_n: 2.5,
            tip_axis: [0.0, 0.0, -1.0],
            f0_after_n: [0.1, 0.0, 0.2],
            stiffness_after_n_per_mm: [0.3, 0.3, 0.0, 0.0, 0.0, 0.0],
            drag_after_n: 0.2,
            tip_lever_mm: [0.0, 0.0, -10.0],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        }
    }

    /// A turn of the device moves the tip on its lever: turned 0.1 rad about y, a tip 10 mm down the tool's -z
    /// moves 1 mm along -x (to first order); along a tip axis of -x into tissue of 0.8 N/mm along x it pushes
    /// back 0.8 N more, and turned back the other way 0.8 N less. No turn, no push; a bad orientation, none.
    #[test]
    fn a_turn_pushes_the_tip_on_its_lever() {
        let t = PunctureTerm {
            tip_axis: [-1.0, 0.0, 0.0],
            ..term()
        };
        let k = [0.8, 0.2, 0.2, 0.0, 0.0, 0.0];
        let about_y = |angle: f32| [0.0, (angle / 2.0).sin(), 0.0, (angle / 2.0).cos()];
        let on = t.rolled_push_n(&k, about_y(0.1));
        let back = t.rolled_push_n(&k, about_y(-0.1));
        // The exact move: 10 sin(0.1) = 0.998 mm.
        assert!((on - 0.8 * 10.0 * 0.1f32.sin()).abs() < 1e-4, "{on}");
        assert!((back + 0.8 * 10.0 * 0.1f32.sin()).abs() < 1e-4, "{back}");
        assert_eq!(t.rolled_push_n(&k, [0.0, 0.0, 0.0, 1.0]), 0.0);
        assert_eq!(t.rolled_push_n(&k, [f32::NAN, 0.0, 0.0, 1.0]), 0.0);
        assert_eq!(PunctureTerm::default().rolled_push_n(&k, about_y(0.1)), 0.0);
    }

    #[test]
    fn the_domain_refuses_what_a_device_could_not_render() {
        assert_eq!(PunctureTerm::default().validate(), Ok(()));
        assert_eq!(term().validate(), Ok(()));
        let bad = [
            (PunctureTerm { press: 0, ..term() }, "local_model.puncture"),
            (
                PunctureTerm {
                    pop_at_n: 0.0,
                    ..term()
                },
                "local_model.puncture.pop_at_n",
            ),
            (
                PunctureTerm {
                    pop_at_n: f32::NAN,
                    ..term()
                },
                "local_model.puncture.pop_at_n",
            ),
            (
                PunctureTerm {
                    tip_axis: [0.0, 0.5, 0.0],
                    ..term()
                },
                "local_model.puncture.tip_axis",
            ),
            (
                PunctureTerm {
                    f0_after_n: [f32::INFINITY, 0.0, 0.0],
                    ..term()
                },
                "local_model.puncture.f0_after_n",
            ),
            (
                PunctureTerm {
                    stiffness_after_n_per_mm: [1.0, -1.0, 0.0, 0.0, 0.0, 0.0],
                    ..term()
                },
                "local_model.puncture.stiffness_after_n_per_mm",
            ),
            (
                PunctureTerm {
                    drag_after_n: -0.1,
                    ..term()
                },
                "local_model.puncture.drag_after_n",
            ),
            (
                PunctureTerm {
                    tip_lever_mm: [f32::NAN, 0.0, 0.0],
                    ..term()
                },
                "local_model.puncture.tip_lever_mm",
            ),
            (
                PunctureTerm {
                    tip_lever_mm: [2000.0, 0.0, 0.0],
                    ..term()
                },
                "local_model.puncture.tip_lever_mm",
            ),
            (
                PunctureTerm {
                    orientation_xyzw: [0.0, 0.0, 0.0, 0.5],
                    ..term()
                },
                "local_model.puncture.orientation_xyzw",
            ),
        ];
        for (t, field) in bad {
            assert_eq!(t.validate().map_err(|e| e.0), Err(field), "{t:?}");
        }
    }

    #[test]
    fn after_the_pop_the_model_has_the_after_terms_and_no_press() {
        let model = LocalModel {
            f0_n: [0.0, 0.0, 2.6],
            stiffness_n_per_mm: [0.5; 6],
            puncture: term(),
            radius_mm: 3.0,
            fade_mm: 1.0,
            ..LocalModel::default()
        };
        assert_eq!(term().push_back_n(model.f0_n), 2.6);
        let after = term().after(&model);
        assert_eq!(after.f0_n, term().f0_after_n);
        assert_eq!(after.stiffness_n_per_mm, term().stiffness_after_n_per_mm);
        assert_eq!(after.cut_drag_n, 0.2);
        assert!(after.attached && !after.puncture.is_active());
        assert_eq!((after.radius_mm, after.x0_mm), (3.0, model.x0_mm));
    }
}

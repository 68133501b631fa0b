//! Coulomb friction rendered at the device: a stick point the device keeps, a stick spring, and its cone.
//!
//! Owns: [`StickPoint`], the friction term of a local model. While the tool pushes on the tissue (the model's
//! linear part renders a normal force `N > 0` along the contact normal `n`, the direction of `f0`), the device
//! keeps a stick point `a`. The friction force is the stick spring along the surface, `f_t = -k_t P (x - a)`
//! with `P = I - n n^T`, held inside the cone `|f_t| <= mu N`; past the cone the stick point slides behind the
//! hand so that the force sits on the cone's edge (kinetic friction, the same coefficient). Out of contact, or
//! without a friction term, there is no stick point, and the next touch sticks where it lands. A grasp
//! (`attached`) has no friction term: its held tissue is in the bilateral linear part. This is the
//! friction-cone god-object of Salisbury et al. (1995) and Ruspini et al. (1997), after Hayward and
//! Armstrong's stick-slip spring (2000): passive, since the spring stores what it is given and sliding only
//! dissipates.
//!
//! Why at the device: the server's friction arrives one round trip late. Carried in `f0`, a stroke's reversal
//! was felt as friction pulling the hand along for a round trip, and the friction tilted the contact normal
//! (and with it `K`), so a sideways error pushed the hand into the surface: the normal force swung by 0.5 N
//! at 100 ms. Rendered here, the stick and the slip happen where the hand is, every millisecond; the server's
//! tissue sticks and slips with its own tool, at the same coefficient.
//!
//! Continuity: for a fixed model and stick point the force moves by at most `k_t |dx| + mu |dN|` per tick
//! (a projection onto a ball is 1-Lipschitz in the vector and in the radius), and it vanishes with `N`, so
//! touch-down and release are continuous.
//!
//! Must not: keep anything but the stick point, read the clock, allocate, or panic.

use sinew_protocol::LocalModel;

use super::local_model::MIN_CONTACT_FORCE_N;
use super::{all_finite, dot3};

/// The device's stick point: where along the surface the friction spring is at rest, mm, device frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StickPoint {
    anchor_mm: Option<[f32; 3]>,
}

impl StickPoint {
    /// No stick point: the next contact sticks where it lands.
    pub fn reset(&mut self) {
        self.anchor_mm = None;
    }

    /// The stick point, mm, while the tool pushes on frictional tissue.
    pub fn anchor_mm(&self) -> Option<[f32; 3]> {
        self.anchor_mm
    }

    /// The friction force of `model` with the device at `position_mm`, given the force its linear part
    /// renders there (`linear_n`, N): `-k_t P (x - a)` inside the cone `mu N`, `N = n . linear_n`. Moves the
    /// stick point when the hand slips past the cone; drops it when there is no friction term (none, or the
    /// model is `attached`) or no push.
    ///
    /// Real-time contract: no allocation, never panics; finite (zero, and no stick point, when any input is
    /// not).
    pub fn step(
        &mut self,
        model: &LocalModel,
        linear_n: [f32; 3],
        position_mm: [f32; 3],
    ) -> [f32; 3] {
        const ZERO: [f32; 3] = [0.0; 3];
        let mu = model.friction_coefficient;
        let k_t = model.stick_stiffness_n_per_mm;
        let f0_norm_n = dot3(model.f0_n, model.f0_n).sqrt();
        if !(model.in_contact
            && !model.attached
            && mu.is_finite()
            && mu > 0.0
            && k_t.is_finite()
            && k_t > 0.0
            && f0_norm_n.is_finite()
            && f0_norm_n > MIN_CONTACT_FORCE_N
            && all_finite(position_mm))
        {
            self.anchor_mm = None;
            return ZERO;
        }
        let normal = model.f0_n.map(|c| c / f0_norm_n);
        let normal_force_n = dot3(normal, linear_n);
        if !(normal_force_n.is_finite() && normal_force_n > 0.0) {
            self.anchor_mm = None;
            return ZERO;
        }
        let anchor = self.anchor_mm.unwrap_or(position_mm);
        let offset: [f32; 3] = std::array::from_fn(|i| position_mm[i] - anchor[i]);
        let along_normal = dot3(offset, normal);
        let mut slide: [f32; 3] = std::array::from_fn(|i| offset[i] - along_normal * normal[i]);
        let limit_n = mu * normal_force_n;
        let spring_n = k_t * dot3(slide, slide).sqrt();
        if spring_n > limit_n {
            // Slipping: the stick point follows the hand, the force on the cone's edge.
            let scale = limit_n / spring_n;
            slide = slide.map(|c| c * scale);
        }
        let force_n = slide.map(|c| -k_t * c);
        let anchor_mm: [f32; 3] = std::array::from_fn(|i| position_mm[i] - slide[i]);
        if all_finite(force_n) && all_finite(anchor_mm) {
            self.anchor_mm = Some(anchor_mm);
            force_n
        } else {
            self.anchor_mm = None;
            ZERO
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Pushing 1 N along +z, friction 0.5, stick spring 2 N/mm.
    fn frictional() -> LocalModel {
        LocalModel {
            in_contact: true,
            f0_n: [0.0, 0.0, 1.0],
            radius_mm: 10.0,
            fade_mm: 2.0,
            friction_coefficient: 0.5,
            stick_stiffness_n_per_mm: 2.0,
            ..LocalModel::default()
        }
    }

    fn norm(v: [f32; 3]) -> f32 {
        dot3(v, v).sqrt()
    }

    #[test]
    fn sticks_where_it_lands_then_slips_at_the_cone() {
        let model = frictional();
        let mut stick = StickPoint::default();
        let push = [0.0, 0.0, 1.0];
        assert_eq!(stick.step(&model, push, [1.0, 2.0, 0.0]), [0.0; 3]);
        assert_eq!(stick.anchor_mm(), Some([1.0, 2.0, 0.0]));
        // 0.1 mm along x: the spring, 0.2 N back; the normal offset does not count.
        let f = stick.step(&model, push, [1.1, 2.0, -0.3]);
        assert!(
            (f[0] + 0.2).abs() < 1e-5 && f[1] == 0.0 && f[2] == 0.0,
            "{f:?}"
        );
        // 1 mm along x: past the cone (2 N > 0.5 N): 0.5 N back, the stick point 0.25 mm behind the hand.
        let f = stick.step(&model, push, [2.0, 2.0, 0.0]);
        assert!((f[0] + 0.5).abs() < 1e-5, "{f:?}");
        let anchor = stick.anchor_mm().unwrap();
        assert!((anchor[0] - 1.75).abs() < 1e-5, "{anchor:?}");
        // Going back 0.25 mm: at rest on the stick point, no force; further back, the spring the other way.
        let f = stick.step(&model, push, [1.75, 2.0, 0.0]);
        assert!(norm(f) < 1e-5, "{f:?}");
        let f = stick.step(&model, push, [1.65, 2.0, 0.0]);
        assert!((f[0] - 0.2).abs() < 1e-5, "{f:?}");
    }

    #[test]
    fn the_cone_follows_the_normal_force_and_release_is_continuous() {
        let model = frictional();
        let mut stick = StickPoint::default();
        stick.step(&model, [0.0, 0.0, 1.0], [0.0; 3]);
        // Sliding at 10 mm/s while the push falls from 1 N to 0 over 1000 ticks: the force is mu N, then 0.
        let mut previous = [0.0f32; 3];
        let mut max_step_n = 0.0f32;
        for tick in 1..=1100u32 {
            let push_n = (1.0 - tick as f32 / 1000.0).max(0.0);
            let x = [0.01 * tick as f32, 0.0, 0.0];
            let f = stick.step(&model, [0.0, 0.0, push_n], x);
            assert!(
                norm(f) <= 0.5 * push_n + 1e-6,
                "tick {tick}: {f:?} at N {push_n}"
            );
            // Stuck for the first 25 ticks (0.02 N a tick up to the cone), then sliding on it.
            if tick > 30 && push_n > 0.0 {
                assert!((f[0] + 0.5 * push_n).abs() < 1e-4, "tick {tick}: {f:?}");
            }
            if tick > 1 {
                max_step_n = max_step_n.max(norm([
                    f[0] - previous[0],
                    f[1] - previous[1],
                    f[2] - previous[2],
                ]));
            }
            previous = f;
        }
        assert_eq!(previous, [0.0; 3]);
        assert_eq!(stick.anchor_mm(), None);
        // Bounded by k_t |dx| + mu |dN| = 2 * 0.01 + 0.5 * 0.001.
        assert!(max_step_n <= 0.0205, "max step {max_step_n} N");
    }

    #[test]
    fn a_closed_cycle_takes_energy_out_of_the_hand() {
        // Passivity: round and round a 2 mm circle on the surface, the work the device does on the hand
        // (sum of f . dx) is never positive, over any prefix of whole cycles.
        let model = frictional();
        let mut stick = StickPoint::default();
        let push = [0.0, 0.0, 1.0];
        let at = |tick: u32| {
            let phase = tick as f32 * 0.01;
            [2.0 * phase.cos(), 2.0 * phase.sin(), 0.0]
        };
        let mut x = at(0);
        let mut f = stick.step(&model, push, x);
        let mut work_on_hand_mj = 0.0f32;
        for tick in 1..=6284u32 {
            let next = at(tick);
            work_on_hand_mj += dot3(f, [next[0] - x[0], next[1] - x[1], 0.0]);
            x = next;
            f = stick.step(&model, push, x);
            if tick % 629 == 0 {
                assert!(work_on_hand_mj <= 1e-4, "tick {tick}: {work_on_hand_mj} mJ");
            }
        }
        // Sliding all the way round (12.6 mm per cycle at 0.5 N): about 6.3 mJ per cycle dissipated.
        assert!(work_on_hand_mj < -50.0, "{work_on_hand_mj} mJ");
    }

    #[test]
    fn no_friction_term_no_push_or_bad_input_render_zero_and_drop_the_stick_point() {
        let mut stick = StickPoint::default();
        let push = [0.0, 0.0, 1.0];
        let frictionless = LocalModel {
            friction_coefficient: 0.0,
            ..frictional()
        };
        let no_spring = LocalModel {
            stick_stiffness_n_per_mm: 0.0,
            ..frictional()
        };
        let out_of_contact = LocalModel {
            in_contact: false,
            ..frictional()
        };
        for model in [frictionless, no_spring, out_of_contact] {
            stick.step(&frictional(), push, [0.0; 3]);
            assert_eq!(stick.step(&model, push, [1.0, 0.0, 0.0]), [0.0; 3]);
            assert_eq!(stick.anchor_mm(), None);
        }
        stick.step(&frictional(), push, [0.0; 3]);
        assert_eq!(
            stick.step(&frictional(), [0.0, 0.0, -0.1], [1.0, 0.0, 0.0]),
            [0.0; 3]
        );
        assert_eq!(stick.anchor_mm(), None);
        for bad in [f32::NAN, f32::INFINITY] {
            stick.step(&frictional(), push, [0.0; 3]);
            assert_eq!(stick.step(&frictional(), push, [bad, 0.0, 0.0]), [0.0; 3]);
            assert_eq!(stick.anchor_mm(), None);
            stick.step(&frictional(), push, [0.0; 3]);
            assert_eq!(
                stick.step(&frictional(), [0.0, 0.0, bad], [0.1, 0.0, 0.0]),
                [0.0; 3]
            );
            assert_eq!(stick.anchor_mm(), None);
        }
    }
}

//! The simulated hand: a stylus mass held by a spring-damper hand that follows a target.
//!
//! Owns: the stylus state (position, velocity) and its integration. The hand pulls the stylus toward a target
//! (spring on the position error, damper on the velocity error); the force the device renders pushes the stylus
//! too, so a force field really resists the hand and the stylus lags a target pressed into tissue.
//!
//! Units: positions mm, velocities mm/s, forces N, mass kg, stiffness N/mm, damping N/(mm/s). Newton's law in
//! these units: `a_mm_per_s2 = 1000 * F_n / m_kg`. Integration: semi-implicit (symplectic) Euler with substeps
//! no longer than [`HandParams::max_substep_s`].
//!
//! Must not: know where the target comes from (that is [`crate::hand_script`]) or clamp forces (that is
//! [`crate::safety`]).

use nalgebra::Vector3;

/// Physical parameters of the simulated hand and stylus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandParams {
    /// Moving mass: stylus, the device's moving parts and the part of the arm that moves with them, kg.
    pub stylus_mass_kg: f32,
    /// Grip stiffness of the hand holding the stylus, N/mm.
    pub stiffness_n_per_mm: f32,
    /// Damping of the hand on the stylus's velocity relative to the target's, N s/mm.
    pub damping_n_s_per_mm: f32,
    /// Longest integration substep, s.
    pub max_substep_s: f32,
}

impl Default for HandParams {
    /// A light grip on a Touch-like stylus: 45 g, 0.4 N/mm, critically damped (8.5 N s/m), 0.25 ms substeps.
    fn default() -> Self {
        Self::with_damping_ratio(0.045, 0.4, 1.0)
    }
}

/// The operator presets of the latency drills (DESIGN.md; measured arms: about 0.55 kg, 6.5 N s/m, 135 N/m,
/// van Beek et al. 2015). `Light` is the hardest case for stability: little mass and damping to soak up
/// energy a delayed loop puts into the hand.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HandPreset {
    /// The default grip ([`HandParams::default`]): 45 g, 0.4 N/mm, critically damped.
    Grip,
    /// 0.1 kg, 1.5 N s/m, 30 N/m.
    Light,
    /// 0.3 kg, 5 N s/m, 150 N/m.
    Nominal,
    /// 0.6 kg, 15 N s/m, 1000 N/m.
    Firm,
}

impl HandPreset {
    /// Every preset, lightest first.
    pub const ALL: [HandPreset; 4] = [
        HandPreset::Grip,
        HandPreset::Light,
        HandPreset::Nominal,
        HandPreset::Firm,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            HandPreset::Grip => "grip",
            HandPreset::Light => "light",
            HandPreset::Nominal => "nominal",
            HandPreset::Firm => "firm",
        }
    }

    /// The parameters (SI values converted to mm: N/m / 1000 = N/mm, N s/m / 1000 = N s/mm).
    pub fn params(self) -> HandParams {
        let si = |mass_kg: f32, damping_n_s_per_m: f32, stiffness_n_per_m: f32| HandParams {
            stylus_mass_kg: mass_kg,
            stiffness_n_per_mm: stiffness_n_per_m / 1000.0,
            damping_n_s_per_mm: damping_n_s_per_m / 1000.0,
            max_substep_s: 0.000_25,
        };
        match self {
            HandPreset::Grip => HandParams::default(),
            HandPreset::Light => si(0.1, 1.5, 30.0),
            HandPreset::Nominal => si(0.3, 5.0, 150.0),
            HandPreset::Firm => si(0.6, 15.0, 1000.0),
        }
    }
}

impl std::str::FromStr for HandPreset {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        HandPreset::ALL
            .into_iter()
            .find(|p| p.name() == s.trim())
            .ok_or_else(|| format!("unknown hand `{s}`: expected grip, light, nominal or firm"))
    }
}

impl HandParams {
    /// Parameters with damping given as a fraction of critical (`ratio * 2 sqrt(k m)`).
    pub fn with_damping_ratio(mass_kg: f32, stiffness_n_per_mm: f32, ratio: f32) -> Self {
        let stiffness_n_per_m = stiffness_n_per_mm * 1000.0;
        Self {
            stylus_mass_kg: mass_kg,
            stiffness_n_per_mm,
            damping_n_s_per_mm: ratio * 2.0 * (stiffness_n_per_m * mass_kg).sqrt() / 1000.0,
            max_substep_s: 0.000_25,
        }
    }

    /// Damping coefficient, N/(mm/s).
    pub fn damping_n_per_mm_s(&self) -> f32 {
        self.damping_n_s_per_mm
    }

    /// Undamped natural frequency of the stylus on the hand spring, rad/s.
    pub fn natural_frequency_rad_s(&self) -> f32 {
        (self.stiffness_n_per_mm * 1000.0 / self.stylus_mass_kg).sqrt()
    }
}

/// Where the hand wants the stylus, and how fast that point moves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HandTarget {
    /// Target position, device frame, mm.
    pub position_mm: [f32; 3],
    /// Target velocity, device frame, mm/s.
    pub velocity_mm_s: [f32; 3],
}

impl HandTarget {
    /// A target standing still at `position_mm`.
    pub fn at_rest(position_mm: [f32; 3]) -> Self {
        Self {
            position_mm,
            velocity_mm_s: [0.0; 3],
        }
    }
}

/// The stylus on the hand spring.
#[derive(Debug, Clone, PartialEq)]
pub struct HandModel {
    params: HandParams,
    damping_n_per_mm_s: f32,
    position_mm: Vector3<f32>,
    velocity_mm_s: Vector3<f32>,
}

impl HandModel {
    /// A stylus at rest at `position_mm`.
    pub fn new(params: HandParams, position_mm: [f32; 3]) -> Self {
        Self {
            damping_n_per_mm_s: params.damping_n_per_mm_s(),
            params,
            position_mm: Vector3::from(position_mm),
            velocity_mm_s: Vector3::zeros(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &HandParams {
        &self.params
    }

    /// Stylus tip position, mm.
    pub fn position_mm(&self) -> [f32; 3] {
        self.position_mm.into()
    }

    /// Stylus tip velocity, mm/s.
    pub fn velocity_mm_s(&self) -> [f32; 3] {
        self.velocity_mm_s.into()
    }

    /// Advance by `dt_s` under the hand's pull toward `target` and the device's `device_force_n`.
    ///
    /// Real-time contract: no allocation, never panics. A non-finite or non-positive `dt_s` leaves the state
    /// unchanged; a non-finite force or target is treated as zero force (the hand lets go of that input), so
    /// the state stays finite.
    pub fn step(&mut self, dt_s: f32, target: &HandTarget, device_force_n: [f32; 3]) {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return;
        }
        let finite = |v: &[f32; 3]| v.iter().all(|c| c.is_finite());
        let device_force_n = if finite(&device_force_n) {
            Vector3::from(device_force_n)
        } else {
            Vector3::zeros()
        };
        let target_ok = finite(&target.position_mm) && finite(&target.velocity_mm_s);
        let max_substep_s = if self.params.max_substep_s > 0.0 {
            self.params.max_substep_s
        } else {
            0.000_25
        };
        // Bounded so a huge dt cannot stall the loop; beyond that the step is coarser but still stable for
        // the default parameters up to dt = 1000 * 2 / omega.
        let substeps = (dt_s / max_substep_s).ceil().clamp(1.0, 1000.0) as u32;
        let h_s = dt_s / substeps as f32;
        let accel_per_n = 1000.0 / self.params.stylus_mass_kg;
        let target_position_mm = Vector3::from(target.position_mm);
        let target_velocity_mm_s = Vector3::from(target.velocity_mm_s);
        for i in 0..substeps {
            let hand_force_n = if target_ok {
                // The target moves on during the step: extrapolate it to this substep.
                let target_now_mm = target_position_mm + target_velocity_mm_s * (h_s * i as f32);
                (target_now_mm - self.position_mm) * self.params.stiffness_n_per_mm
                    + (target_velocity_mm_s - self.velocity_mm_s) * self.damping_n_per_mm_s
            } else {
                -self.velocity_mm_s * self.damping_n_per_mm_s
            };
            let accel_mm_per_s2 = (hand_force_n + device_force_n) * accel_per_n;
            self.velocity_mm_s += accel_mm_per_s2 * h_s;
            self.position_mm += self.velocity_mm_s * h_s;
        }
    }

    /// Keep the stylus inside the box `[min_mm, max_mm]` (the device's mechanical stops): a coordinate
    /// outside is put back on the wall and its velocity component zeroed.
    pub fn confine(&mut self, min_mm: [f32; 3], max_mm: [f32; 3]) {
        for axis in 0..3 {
            let (lo, hi) = (min_mm[axis], max_mm[axis]);
            if self.position_mm[axis] < lo {
                self.position_mm[axis] = lo;
                self.velocity_mm_s[axis] = 0.0;
            } else if self.position_mm[axis] > hi {
                self.position_mm[axis] = hi;
                self.velocity_mm_s[axis] = 0.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(hand: &mut HandModel, seconds: f32, target: &HandTarget, force_n: [f32; 3]) {
        let dt_s = 0.001;
        for _ in 0..(seconds / dt_s).round() as usize {
            hand.step(dt_s, target, force_n);
        }
    }

    #[test]
    fn constant_push_settles_force_over_stiffness_off_target() {
        let mut hand = HandModel::new(HandParams::default(), [0.0; 3]);
        let target = HandTarget::at_rest([0.0; 3]);
        run(&mut hand, 1.0, &target, [0.0, 0.0, 1.0]);
        let p = hand.position_mm();
        // 1 N / 0.4 N/mm = 2.5 mm, along the push.
        assert!((p[2] - 2.5).abs() < 0.01, "settled at {p:?}");
        assert!(p[0].abs() < 1e-6 && p[1].abs() < 1e-6);
        assert!(hand.velocity_mm_s()[2].abs() < 0.01);
    }

    #[test]
    fn without_force_it_tracks_a_moving_target() {
        let mut hand = HandModel::new(HandParams::default(), [0.0; 3]);
        let dt_s = 0.001;
        let mut worst_mm: f32 = 0.0;
        for tick in 0..3000 {
            let t_s = tick as f32 * dt_s;
            let w = std::f32::consts::TAU; // 1 Hz
            let target = HandTarget {
                position_mm: [10.0 * (w * t_s).sin(), 0.0, 0.0],
                velocity_mm_s: [10.0 * w * (w * t_s).cos(), 0.0, 0.0],
            };
            hand.step(dt_s, &target, [0.0; 3]);
            if tick > 200 {
                let next_x = 10.0 * (w * (t_s + dt_s)).sin();
                worst_mm = worst_mm.max((hand.position_mm()[0] - next_x).abs());
            }
        }
        assert!(worst_mm < 0.1, "tracking error {worst_mm} mm");
    }

    #[test]
    fn step_response_is_critically_damped() {
        let mut hand = HandModel::new(HandParams::default(), [0.0; 3]);
        let target = HandTarget::at_rest([0.0, 0.0, -10.0]);
        let mut lowest = 0.0f32;
        for _ in 0..500 {
            hand.step(0.001, &target, [0.0; 3]);
            lowest = lowest.min(hand.position_mm()[2]);
        }
        assert!(lowest > -10.01, "overshoot to {lowest}");
        assert!((hand.position_mm()[2] + 10.0).abs() < 0.01);
    }

    #[test]
    fn coarse_steps_stay_stable_and_bad_input_stays_finite() {
        let mut hand = HandModel::new(HandParams::default(), [0.0; 3]);
        let target = HandTarget::at_rest([5.0, 5.0, 5.0]);
        for _ in 0..20 {
            hand.step(0.05, &target, [0.0; 3]);
        }
        let p = hand.position_mm();
        assert!(p.iter().all(|c| (c - 5.0).abs() < 0.01), "{p:?}");
        hand.step(0.001, &target, [f32::NAN, f32::INFINITY, 0.0]);
        hand.step(f32::NAN, &target, [0.0; 3]);
        hand.step(-1.0, &target, [0.0; 3]);
        hand.step(0.001, &HandTarget::at_rest([f32::NAN; 3]), [0.0; 3]);
        assert!(hand.position_mm().iter().all(|c| c.is_finite()));
        assert!(hand.velocity_mm_s().iter().all(|c| c.is_finite()));
    }

    #[test]
    fn confine_stops_at_the_walls() {
        let mut hand = HandModel::new(HandParams::default(), [0.0; 3]);
        run(
            &mut hand,
            0.5,
            &HandTarget::at_rest([0.0, 0.0, 100.0]),
            [0.0; 3],
        );
        hand.confine([-50.0; 3], [50.0; 3]);
        assert_eq!(hand.position_mm()[2], 50.0);
        assert_eq!(hand.velocity_mm_s()[2], 0.0);
    }
}

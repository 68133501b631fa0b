//! Per-participant skill metrics, accumulated tick by tick from the tool's activity: task time, path length of
//! the tool and economy of motion, time in contact, mean and peak force, and force above a harm threshold.
//!
//! Owns: [`MetricsConfig`], [`ParticipantMetrics`] (the accumulator) and [`MetricsSummary`] (what a report
//! shows). Definitions, so that a scripted session's answer can be worked out by hand:
//! - **task time**: from the first tick a device drove the tool to the last, inclusive, times dt;
//! - **path length**: the sum of the instrument tip's displacements (where the device puts the tool) between consecutive driven ticks (a gap in
//!   driving starts a new segment: the jump across it is not motion of the hand);
//! - **straight line**: the distance from the first driven position to the last; **economy**: path over
//!   straight line (1 is the shortest path; undefined below 1 mm of straight line);
//! - **contact time**: driven ticks in contact times dt; **contacts**: how many times contact began (the
//!   debounced [`EventKind::ContactBegin`] events: a touch broken for a few ticks is one touch);
//! - **mean force**: the force's magnitude averaged over contact ticks; **peak force**: its largest magnitude;
//! - **harm**: the integral over driven ticks of the force's excess over the harm threshold, N s.
//!
//! Tissue damage (cut or burned area outside a target, tears) and errors (wrong tool, missed targets) come
//! with the instruments and the exercises that define them.
//!
//! Must not: allocate (it can run on the sim thread) or read a clock.

use serde::{Deserialize, Serialize};

use super::events::{EventKind, SessionEvent, ToolActivity};

/// What the metrics need to know of the session.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MetricsConfig {
    /// Tick length, s.
    pub dt_s: f64,
    /// Force above which the tissue is being harmed, N.
    pub harm_threshold_n: f32,
}

impl MetricsConfig {
    /// Default harm threshold, N: two thirds of a Touch's 3.3 N continuous force, well above what probing the
    /// pad needs (about 1 N at 5 mm). An exercise sets its own.
    pub const DEFAULT_HARM_THRESHOLD_N: f32 = 2.2;

    /// Ticks of `dt_s` and the default harm threshold.
    pub fn new(dt_s: f64) -> Self {
        Self {
            dt_s,
            harm_threshold_n: Self::DEFAULT_HARM_THRESHOLD_N,
        }
    }
}

/// The accumulator for one participant.
#[derive(Debug, Clone)]
pub struct ParticipantMetrics {
    config: MetricsConfig,
    first_active_tick: Option<u64>,
    last_active_tick: u64,
    active_ticks: u64,
    was_active: bool,
    start_mm: [f64; 3],
    last_mm: [f64; 3],
    path_length_mm: f64,
    contact_ticks: u64,
    contacts: u64,
    contact_force_sum_n: f64,
    peak_force_n: f32,
    harm_n_s: f64,
}

/// The metrics of one participant, as a report shows them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsSummary {
    /// First to last driven tick, s (0 if never driven).
    pub task_time_s: f64,
    /// Driven ticks times dt, s.
    pub driven_time_s: f64,
    /// Path length of the instrument tip, mm.
    pub path_length_mm: f64,
    /// First to last driven position, mm.
    pub straight_line_mm: f64,
    /// Path length over straight line (None below 1 mm of straight line).
    pub economy: Option<f64>,
    /// Time in contact, s.
    pub contact_time_s: f64,
    /// Times contact began.
    pub contacts: u64,
    /// Mean force magnitude while in contact, N (0 without contact).
    pub mean_contact_force_n: f64,
    /// Largest force magnitude, N.
    pub peak_force_n: f64,
    /// The harm threshold used, N.
    pub harm_threshold_n: f64,
    /// Integral of the force's excess over the harm threshold, N s.
    pub harm_n_s: f64,
}

impl ParticipantMetrics {
    /// An empty accumulator.
    pub fn new(config: MetricsConfig) -> Self {
        Self {
            config,
            first_active_tick: None,
            last_active_tick: 0,
            active_ticks: 0,
            was_active: false,
            start_mm: [0.0; 3],
            last_mm: [0.0; 3],
            path_length_mm: 0.0,
            contact_ticks: 0,
            contacts: 0,
            contact_force_sum_n: 0.0,
            peak_force_n: 0.0,
            harm_n_s: 0.0,
        }
    }

    /// Tick `tick`'s activity. Non-finite positions and forces are ignored (they never reach a device either).
    pub fn push(&mut self, tick: u64, activity: &ToolActivity) {
        let active = activity.active;
        if !active {
            self.was_active = false;
            return;
        }
        let p = activity.tip_world_mm.map(f64::from);
        let position_ok = p.iter().all(|c| c.is_finite());
        if self.first_active_tick.is_none() && position_ok {
            self.first_active_tick = Some(tick);
            self.start_mm = p;
            self.last_mm = p;
        }
        self.last_active_tick = tick;
        self.active_ticks += 1;
        if position_ok {
            if self.was_active {
                self.path_length_mm += distance(&self.last_mm, &p);
            }
            self.last_mm = p;
        }
        self.was_active = position_ok;

        let force_n = if activity.force_n.is_finite() {
            activity.force_n.max(0.0)
        } else {
            0.0
        };
        self.peak_force_n = self.peak_force_n.max(force_n);
        let excess_n = force_n - self.config.harm_threshold_n;
        if excess_n > 0.0 {
            self.harm_n_s += f64::from(excess_n) * self.config.dt_s;
        }
        if activity.in_contact {
            self.contact_ticks += 1;
            self.contact_force_sum_n += f64::from(force_n);
        }
    }

    /// An event on this participant's tool (counts contacts).
    pub fn on_event(&mut self, event: &SessionEvent) {
        if event.kind == EventKind::ContactBegin {
            self.contacts += 1;
        }
    }

    /// The metrics so far.
    pub fn summary(&self) -> MetricsSummary {
        let dt = self.config.dt_s;
        let task_time_s = self
            .first_active_tick
            .map_or(0.0, |first| (self.last_active_tick - first + 1) as f64 * dt);
        let straight_line_mm = if self.first_active_tick.is_some() {
            distance(&self.start_mm, &self.last_mm)
        } else {
            0.0
        };
        MetricsSummary {
            task_time_s,
            driven_time_s: self.active_ticks as f64 * dt,
            path_length_mm: self.path_length_mm,
            straight_line_mm,
            economy: (straight_line_mm >= 1.0).then(|| self.path_length_mm / straight_line_mm),
            contact_time_s: self.contact_ticks as f64 * dt,
            contacts: self.contacts,
            mean_contact_force_n: if self.contact_ticks > 0 {
                self.contact_force_sum_n / self.contact_ticks as f64
            } else {
                0.0
            },
            peak_force_n: f64::from(self.peak_force_n),
            harm_threshold_n: f64::from(self.config.harm_threshold_n),
            harm_n_s: self.harm_n_s,
        }
    }
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    fn at(x: f32, y: f32, force_n: f32, in_contact: bool) -> ToolActivity {
        ToolActivity {
            active: true,
            near: in_contact,
            in_contact,
            force_n,
            tip_world_mm: [x, y, 0.0],
            ..ToolActivity::default()
        }
    }

    #[test]
    fn an_l_shaped_path_with_a_gap_has_its_known_length_economy_and_times() {
        let mut m = ParticipantMetrics::new(MetricsConfig::new(0.001));
        // 30 mm along x in 300 ticks, then 40 mm along y in 400: path 70, straight line 50.
        let mut tick = 0;
        for i in 0..=300 {
            m.push(tick, &at(i as f32 * 0.1, 0.0, 0.0, false));
            tick += 1;
        }
        for i in 1..=400 {
            m.push(tick, &at(30.0, i as f32 * 0.1, 0.0, false));
            tick += 1;
        }
        // Not driven for 100 ticks, then back 1 m away: the jump is not path.
        for _ in 0..100 {
            m.push(tick, &ToolActivity::default());
            tick += 1;
        }
        m.push(tick, &at(1000.0, 0.0, 0.0, false));
        let s = m.summary();
        assert!((s.path_length_mm - 70.0).abs() < 1e-3, "{s:?}");
        assert!((s.straight_line_mm - 1000.0).abs() < 1e-3, "{s:?}");
        assert!((s.task_time_s - 0.802).abs() < 1e-12, "{s:?}");
        assert!((s.driven_time_s - 0.702).abs() < 1e-12, "{s:?}");
    }

    #[test]
    fn contact_time_mean_peak_and_harm_of_a_triangle_force() {
        let mut m = ParticipantMetrics::new(MetricsConfig {
            dt_s: 0.001,
            harm_threshold_n: 2.0,
        });
        // Free for 100 ticks, then 1000 ticks of contact with a force rising 0 -> 3 N and back (a triangle,
        // peak at tick 500), then free again; a second 10-tick touch at 1 N.
        for t in 0..100 {
            m.push(t, &at(0.0, 0.0, 0.0, false));
        }
        for i in 0..=1000u64 {
            let f = 3.0 * (1.0 - (i as f32 - 500.0).abs() / 500.0);
            m.push(100 + i, &at(0.0, 0.0, f, true));
        }
        m.push(1101, &at(0.0, 0.0, 0.0, false));
        for tick in [100, 1102] {
            m.on_event(&SessionEvent {
                tick,
                tool: 0,
                kind: EventKind::ContactBegin,
            });
        }
        for i in 0..10 {
            m.push(1102 + i, &at(0.0, 0.0, 1.0, true));
        }
        let s = m.summary();
        assert_eq!(s.contacts, 2);
        assert!((s.contact_time_s - 1.011).abs() < 1e-12, "{s:?}");
        assert!((s.peak_force_n - 3.0).abs() < 1e-6);
        // Mean over the triangle is 1.5 N (1001 samples sum to 1500 N), plus ten at 1 N.
        let mean = (1500.0 + 10.0) / 1011.0;
        assert!((s.mean_contact_force_n - mean).abs() < 1e-4, "{s:?}");
        // Above 2 N: a triangle of height 1 N and base 1/3 of 1 s: 1/6 N s.
        assert!((s.harm_n_s - 1.0 / 6.0).abs() < 2e-3, "{s:?}");
        assert!(s.economy.is_none(), "no straight line to speak of");
    }

    #[test]
    fn never_driven_is_all_zero_and_garbage_is_ignored() {
        let mut m = ParticipantMetrics::new(MetricsConfig::new(0.001));
        m.push(0, &ToolActivity::default());
        let s = m.summary();
        assert_eq!(
            (s.task_time_s, s.path_length_mm, s.peak_force_n),
            (0.0, 0.0, 0.0)
        );
        m.push(1, &at(f32::NAN, 0.0, f32::INFINITY, true));
        m.push(2, &at(0.0, 0.0, 1.0, true));
        m.push(3, &at(5.0, 0.0, f32::NAN, true));
        let s = m.summary();
        assert!(
            s.path_length_mm.is_finite() && s.peak_force_n == 1.0,
            "{s:?}"
        );
        assert!((s.path_length_mm - 5.0).abs() < 1e-9);
    }
}

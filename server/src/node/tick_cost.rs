//! Whether a world can keep its tick rate: a load-time estimate of the tick's cost, and a low-rate account of
//! ticks that ran late.
//!
//! Owns: [`estimate`], which builds a throwaway copy of the scene with region tracking off (every node
//! steps, as when a tool touches everywhere), times a few whole steps, and says what the live tick will
//! cost; [`verdict`], which turns that into the start-up log line; and [`LateTicks`], fed once a second by the
//! publish thread, which logs sustained overruns at most every 10 s with the numbers.
//!
//! Must not: touch the live simulation (the copy is stepped, never the real one, so a replay starts from the
//! same state).

use std::time::{Duration, Instant};

use crate::sim::{Sim, SimBuildError, ToolCommand, ToolOutput};
use crate::world::World;

/// How long the estimate may step the copy (at least [`MIN_STEPS`] steps are timed whatever it costs).
pub const ESTIMATE_BUDGET: Duration = Duration::from_millis(300);
/// Fewest steps timed.
pub const MIN_STEPS: usize = 3;
/// Most steps timed.
pub const MAX_STEPS: usize = 50;

/// What the estimate found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TickCost {
    /// Median whole-scene step, s.
    pub step_s: f64,
    /// The tick period, s.
    pub period_s: f64,
    /// Steps timed.
    pub steps: usize,
    /// Tissue nodes in the scene.
    pub nodes: usize,
}

impl TickCost {
    /// The share of the tick one step takes.
    pub fn load(&self) -> f64 {
        self.step_s / self.period_s
    }

    /// The rate the server can tick at if a step costs this much, Hz.
    pub fn achievable_hz(&self) -> f64 {
        (1.0 / self.step_s).min(1.0 / self.period_s)
    }
}

/// Time whole steps of a copy of `world` with region tracking off.
pub fn estimate(world: &World) -> Result<TickCost, SimBuildError> {
    let mut whole = world.clone();
    for object in &mut whole.objects {
        object.region = None;
    }
    let mut sim = Sim::new(&whole)?;
    let nodes = sim.objects.iter().map(|o| o.model.node_count()).sum();
    let dt_s = (1.0 / world.tick_hz) as f32;
    let commands = vec![ToolCommand::default(); sim.tools.len()];
    let mut outputs = vec![ToolOutput::default(); sim.tools.len()];
    let mut times = Vec::with_capacity(MAX_STEPS);
    let started = Instant::now();
    while times.len() < MIN_STEPS
        || (times.len() < MAX_STEPS && started.elapsed() < ESTIMATE_BUDGET)
    {
        let t0 = Instant::now();
        sim.step(dt_s, &commands, &mut outputs);
        times.push(t0.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    Ok(TickCost {
        step_s: times[times.len() / 2],
        period_s: 1.0 / world.tick_hz,
        steps: times.len(),
        nodes,
    })
}

/// How the estimate reads.
#[derive(Debug, Clone, PartialEq)]
pub enum Verdict {
    /// Comfortably inside the tick.
    Fits(String),
    /// Over half the tick: it fits on a quiet machine.
    Tight(String),
    /// Over 90% of the tick: the server cannot keep the rate.
    TooBig(String),
}

/// The start-up line for `cost` of world `scene`.
pub fn verdict(scene: &str, cost: &TickCost) -> Verdict {
    let figures = format!(
        "world `{scene}`: {} tissue nodes; a whole-scene step costs about {:.0} us at load ({} steps timed), \
         {:.0}% of the {:.0} us tick",
        cost.nodes,
        cost.step_s * 1e6,
        cost.steps,
        cost.load() * 100.0,
        cost.period_s * 1e6
    );
    if cost.load() > 0.9 {
        Verdict::TooBig(format!(
            "{figures}. The server cannot keep {:.0} Hz: forces will reach the devices at about {:.0} Hz and \
             ticks will run late. Use fewer nodes (a coarser mesh), a lower tick_hz, or region tracking \
             (it helps only while touches stay small)",
            1.0 / cost.period_s,
            cost.achievable_hz()
        ))
    } else if cost.load() > 0.5 {
        Verdict::Tight(format!(
            "{figures}: little room left for the rest of the tick on a busy machine"
        ))
    } else {
        Verdict::Fits(figures)
    }
}

/// Ticks that ran late, watched once a second; logged at most every [`LateTicks::LOG_PERIOD`].
#[derive(Debug)]
pub struct LateTicks {
    last_overruns: u64,
    since_log: u64,
    late_seconds: u64,
    last_log: Option<Instant>,
}

impl LateTicks {
    /// How often sustained overruns are logged.
    pub const LOG_PERIOD: Duration = Duration::from_secs(10);

    /// Nothing seen yet.
    pub fn new() -> Self {
        Self {
            last_overruns: 0,
            since_log: 0,
            late_seconds: 0,
            last_log: None,
        }
    }

    /// The overrun counter now; returns a log line when one is due: overruns happened in this second, and
    /// the last line is [`LateTicks::LOG_PERIOD`] old (or there was none).
    pub fn observe(
        &mut self,
        now: Instant,
        overruns: u64,
        tick_p99_us: f32,
        period_us: f64,
    ) -> Option<String> {
        let new = overruns.saturating_sub(self.last_overruns);
        self.last_overruns = overruns;
        if new == 0 {
            return None;
        }
        self.since_log += new;
        self.late_seconds += 1;
        if self
            .last_log
            .is_some_and(|last| now.duration_since(last) < Self::LOG_PERIOD)
        {
            return None;
        }
        let line = format!(
            "ticks ran late: {} periods skipped over {} s with late ticks since the last report (tick p99 {:.0} us, \
             period {:.0} us): forces reach the devices less often than the tick rate",
            self.since_log, self.late_seconds, tick_p99_us, period_us
        );
        self.since_log = 0;
        self.late_seconds = 0;
        self.last_log = Some(now);
        Some(line)
    }
}

impl Default for LateTicks {
    fn default() -> Self {
        Self::new()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_verdict_follows_the_share_of_the_tick() {
        let cost = |step_us: f64| TickCost {
            step_s: step_us * 1e-6,
            period_s: 1e-3,
            steps: 10,
            nodes: 1000,
        };
        assert!(matches!(verdict("pad", &cost(100.0)), Verdict::Fits(_)));
        assert!(matches!(verdict("pad", &cost(700.0)), Verdict::Tight(_)));
        match verdict("big", &cost(13_000.0)) {
            Verdict::TooBig(line) => {
                assert!(line.contains("13000 us"), "{line}");
                assert!(line.contains("about 77 Hz"), "{line}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn sustained_overruns_are_logged_at_most_every_ten_seconds_with_their_count() {
        let mut late = LateTicks::new();
        let t0 = Instant::now();
        let s = Duration::from_secs(1);
        assert!(late.observe(t0, 0, 500.0, 1000.0).is_none());
        let first = late.observe(t0 + s, 40, 1800.0, 1000.0).unwrap();
        assert!(first.contains("40 periods skipped over 1 s"), "{first}");
        for k in 2..11 {
            assert!(
                late.observe(t0 + k * s, 40 * u64::from(k), 1800.0, 1000.0)
                    .is_none()
            );
        }
        let again = late.observe(t0 + 11 * s, 440, 1800.0, 1000.0).unwrap();
        assert!(again.contains("400 periods skipped over 10 s"), "{again}");
        assert!(late.observe(t0 + 12 * s, 440, 500.0, 1000.0).is_none());
    }
}

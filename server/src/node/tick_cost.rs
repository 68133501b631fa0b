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

use crate::scene::World;
use crate::sim::{Sim, SimBuildError, ToolCommand, ToolOutput};

/// How long the estimate may step the copy (at least [`MIN_STEPS`] steps are timed whatever it costs).
pub const ESTIMATE_BUDGET: Duration = Duration::from_millis(300);
/// Fewest steps timed.
pub const MIN_STEPS: usize = 3;
/// Most steps timed.
pub const MAX_STEPS: usize = 50;

/// What a multi-rate object's own step costs, against its period.
#[derive(Debug, Clone, PartialEq)]
pub struct LaneCost {
    /// The object's name.
    pub object: String,
    /// One step (timed inline: the hand-off ticks' median less the other ticks'), s.
    pub step_s: f64,
    /// Its step period, s.
    pub period_s: f64,
}

impl LaneCost {
    /// The share of its own thread's time the object takes.
    pub fn load(&self) -> f64 {
        self.step_s / self.period_s
    }
}

/// What the estimate found.
#[derive(Debug, Clone, PartialEq)]
pub struct TickCost {
    /// Median whole-scene step, s.
    pub step_s: f64,
    /// The tick period, s.
    pub period_s: f64,
    /// Steps timed.
    pub steps: usize,
    /// Tissue nodes in the scene.
    pub nodes: usize,
    /// The multi-rate objects (they step on threads of their own: not in `step_s`).
    pub lanes: Vec<LaneCost>,
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
    // Multi-rate objects step inline here: a hand-off tick (every `N`th) carries one whole step of the object.
    let longest_step = world
        .objects
        .iter()
        .map(|o| o.ticks_per_step)
        .max()
        .unwrap_or(1) as usize;
    let min_steps = if longest_step > 1 {
        2 * longest_step + 2
    } else {
        MIN_STEPS
    };
    let mut times = Vec::with_capacity(MAX_STEPS.max(min_steps));
    let started = Instant::now();
    while times.len() < min_steps
        || (times.len() < MAX_STEPS.max(min_steps) && started.elapsed() < ESTIMATE_BUDGET)
    {
        let t0 = Instant::now();
        sim.step(dt_s, &commands, &mut outputs);
        times.push(t0.elapsed().as_secs_f64());
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    // Ticks on which no multi-rate object handed off: the tick's own cost.
    let plain = |k: usize| {
        world
            .objects
            .iter()
            .all(|o| o.ticks_per_step == 1 || !k.is_multiple_of(o.ticks_per_step as usize))
    };
    let tick_s = median(
        (0..times.len())
            .filter(|&k| plain(k))
            .map(|k| times[k])
            .collect(),
    );
    let lanes = world
        .objects
        .iter()
        .filter(|o| o.ticks_per_step > 1)
        .map(|o| {
            let n = o.ticks_per_step as usize;
            let hand_offs = (0..times.len()).step_by(n).map(|k| times[k]).collect();
            LaneCost {
                object: o.name.clone(),
                step_s: (median(hand_offs) - tick_s).max(0.0),
                period_s: n as f64 / world.tick_hz,
            }
        })
        .collect();
    Ok(TickCost {
        step_s: tick_s,
        period_s: 1.0 / world.tick_hz,
        steps: times.len(),
        nodes,
        lanes,
    })
}

/// The tick bench's workload on a throwaway copy of `world`, on the calling thread (one core, no network):
/// its first two tools press 5 mm and stroke +-8 mm along x (2 s period, after a 0.5 s descent), `ticks`
/// whole steps timed. `sinew demo` runs it before the live system, so its live tick is compared with this in
/// the same run (`cargo bench -p sinew-server --bench tick` times the same workload). Multi-rate objects step
/// inline here, so a world with them measures its hand-off ticks too.
pub fn press_and_stroke(
    world: &World,
    ticks: usize,
) -> Result<sinew_protocol::rt::LatencyHistogram, SimBuildError> {
    let mut sim = Sim::new(world)?;
    let dt_s = (1.0 / world.tick_hz) as f32;
    let mut commands = vec![ToolCommand::default(); sim.tools.len()];
    let mut outputs = vec![ToolOutput::default(); sim.tools.len()];
    let mut histogram = sinew_protocol::rt::LatencyHistogram::new();
    for k in 0..ticks {
        press_and_stroke_commands(k as f32 * dt_s, &mut commands);
        let start = Instant::now();
        sim.step(dt_s, &commands, &mut outputs);
        histogram.record(start.elapsed());
    }
    Ok(histogram)
}

/// The bench workload's commands at time `t_s`: the first two of `commands` press 5 mm (over 0.5 s) and then
/// stroke +-8 mm along x with a 2 s period, in opposite directions, the second 5 mm along y from the first.
pub fn press_and_stroke_commands(t_s: f32, commands: &mut [ToolCommand]) {
    let depth = (t_s / 0.5).min(1.0) * 5.0;
    let stroke = if t_s > 0.5 {
        8.0 * (std::f32::consts::TAU * (t_s - 0.5) / 2.0).sin()
    } else {
        0.0
    };
    for (i, command) in commands.iter_mut().take(2).enumerate() {
        let (x, y) = if i == 0 {
            (stroke, 0.0)
        } else {
            (-stroke, 5.0)
        };
        *command = ToolCommand {
            active: true,
            position_device_mm: [x, y, 4.0 - depth],
            orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            ..ToolCommand::default()
        };
    }
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
    let lanes: String = cost
        .lanes
        .iter()
        .map(|lane| {
            format!(
                "; object `{}` steps at {:.0} Hz on its own thread, a step costing about {:.1} ms, {:.0}% of its \
                 {:.0} ms period",
                lane.object,
                1.0 / lane.period_s,
                lane.step_s * 1e3,
                lane.load() * 100.0,
                lane.period_s * 1e3
            )
        })
        .collect();
    let figures = format!("{figures}{lanes}");
    if let Some(lane) = cost.lanes.iter().find(|lane| lane.load() > 0.9) {
        return Verdict::TooBig(format!(
            "{figures}. Object `{}` cannot keep {:.0} Hz on its own thread: every hand-off will wait for its step \
             and the tick will run late. Lower its step_hz or use a coarser mesh",
            lane.object,
            1.0 / lane.period_s
        ));
    }
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

/// Ticks that ran late, watched once a second over windows of [`LateTicks::WINDOW`]: a window in which more
/// than [`LateTicks::SUSTAINED`] of the periods were skipped is logged at its end, with the numbers. A few
/// overruns from a VM stall, or the first second's warm-up, are not worth a line.
#[derive(Debug)]
pub struct LateTicks {
    window_start: Option<(Instant, u64, u64)>,
}

impl LateTicks {
    /// The window, and so the longest a sustained overrun goes unsaid.
    pub const WINDOW: Duration = Duration::from_secs(10);
    /// The share of skipped periods in a window that makes it sustained.
    pub const SUSTAINED: f64 = 0.01;

    /// Nothing seen yet.
    pub fn new() -> Self {
        Self { window_start: None }
    }

    /// The counters now (ticks run, periods skipped); returns a log line at the end of a window in which
    /// ticks ran late for more than [`LateTicks::SUSTAINED`] of the periods.
    pub fn observe(
        &mut self,
        now: Instant,
        ticks: u64,
        overruns: u64,
        tick_p99_us: f32,
        period_us: f64,
    ) -> Option<String> {
        let Some((start, ticks0, overruns0)) = self.window_start else {
            self.window_start = Some((now, ticks, overruns));
            return None;
        };
        let elapsed = now.duration_since(start);
        if elapsed < Self::WINDOW {
            return None;
        }
        self.window_start = Some((now, ticks, overruns));
        let skipped = overruns.saturating_sub(overruns0);
        let periods = ticks.saturating_sub(ticks0) + skipped;
        if (skipped as f64) <= Self::SUSTAINED * periods.max(1) as f64 {
            return None;
        }
        Some(format!(
            "ticks ran late: {skipped} of {periods} periods skipped in the last {:.0} s (tick p99 {tick_p99_us:.0} us, \
             period {period_us:.0} us): forces reach the devices about {:.0} times a second",
            elapsed.as_secs_f64(),
            ticks.saturating_sub(ticks0) as f64 / elapsed.as_secs_f64()
        ))
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
            lanes: Vec::new(),
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
    fn a_multi_rate_object_is_judged_against_its_own_period() {
        let cost = |lane_step_ms: f64| TickCost {
            step_s: 100e-6,
            period_s: 1e-3,
            steps: 50,
            nodes: 3100,
            lanes: vec![LaneCost {
                object: "liver".into(),
                step_s: lane_step_ms * 1e-3,
                period_s: 20e-3,
            }],
        };
        match verdict("liver", &cost(13.0)) {
            Verdict::Fits(line) => assert!(
                line.contains("object `liver` steps at 50 Hz on its own thread, a step costing about 13.0 ms, 65%"),
                "{line}"
            ),
            other => panic!("{other:?}"),
        }
        match verdict("liver", &cost(25.0)) {
            Verdict::TooBig(line) => {
                assert!(line.contains("Object `liver` cannot keep 50 Hz"), "{line}")
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn sustained_overruns_are_logged_once_a_window_and_a_stall_is_not() {
        let mut late = LateTicks::new();
        let t0 = Instant::now();
        let s = Duration::from_secs(1);
        assert!(late.observe(t0, 0, 0, 500.0, 1000.0).is_none());
        // A VM stall: 5 periods in 10 s.
        assert!(late.observe(t0 + 5 * s, 5_000, 5, 900.0, 1000.0).is_none());
        assert!(late.observe(t0 + 10 * s, 9_995, 5, 900.0, 1000.0).is_none());
        // An oversized world: 77 ticks a second, 923 periods skipped.
        assert!(
            late.observe(t0 + 15 * s, 10_380, 4_620, 13_000.0, 1000.0)
                .is_none()
        );
        let line = late
            .observe(t0 + 20 * s, 10_765, 9_235, 13_000.0, 1000.0)
            .unwrap();
        assert!(
            line.contains("9230 of 10000 periods skipped in the last 10 s"),
            "{line}"
        );
        assert!(line.contains("about 77 times a second"), "{line}");
    }
}

//! A per-tick record of what the device did: position, velocity, rendered force, mode.
//!
//! Owns: [`TraceSample`] and [`Trace`], a buffer allocated once at its full capacity; the loop appends one
//! sample a tick until it is full (then stops recording and counts the drop), so recording never allocates
//! in a tick. Drills and benches read it to measure stability, stiffness and force tracking; the binary
//! writes it as CSV (`--trace-csv`).
//!
//! Must not: allocate after construction, or be written from anywhere but the device loop.

use std::io::Write;

/// One device tick.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct TraceSample {
    /// Loop clock, s.
    pub t_s: f64,
    /// Stylus position, device frame, mm.
    pub position_mm: [f32; 3],
    /// Stylus velocity, device frame, mm/s.
    pub velocity_mm_s: [f32; 3],
    /// Force rendered, N.
    pub force_n: [f32; 3],
    /// Weight of the local model in the rendered force (0 direct, 1 moderated).
    pub model_weight: f32,
    /// The command stream was stale (the silence rule was ramping the force down).
    pub stale: bool,
    /// The force before the passivity controller and the safety filter, N (diagnostics).
    pub target_n: [f32; 3],
    /// The renderer's blend offset at this tick, N (zero in direct mode; diagnostics).
    pub blend_offset_n: [f32; 3],
    /// The passivity observer's energy after this tick, mJ (diagnostics).
    pub passivity_energy_mj: f64,
}

/// A fixed-capacity trace.
#[derive(Debug, Clone, Default)]
pub struct Trace {
    samples: Vec<TraceSample>,
    dropped: u64,
}

impl Trace {
    /// A trace holding up to `capacity` samples (allocated now).
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            samples: Vec::with_capacity(capacity),
            dropped: 0,
        }
    }

    /// Append a sample; when full, count it as dropped. Never allocates.
    pub fn push(&mut self, sample: TraceSample) {
        if self.samples.len() < self.samples.capacity() {
            self.samples.push(sample);
        } else {
            self.dropped += 1;
        }
    }

    /// The samples so far.
    pub fn samples(&self) -> &[TraceSample] {
        &self.samples
    }

    /// Samples that did not fit.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }

    /// Write as CSV with a header: `t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s,fx_n,fy_n,fz_n,model_weight,stale,
    /// target_fz_n,blend_fz_n,passivity_energy_mj` (the last three: force before passivity and safety, the
    /// renderer's blend offset, the passivity account).
    pub fn write_csv(&self, out: &mut impl Write) -> std::io::Result<()> {
        writeln!(
            out,
            "t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s,fx_n,fy_n,fz_n,model_weight,stale,\
             target_fz_n,blend_fz_n,passivity_energy_mj"
        )?;
        for s in &self.samples {
            let [x, y, z] = s.position_mm;
            let [vx, vy, vz] = s.velocity_mm_s;
            let [fx, fy, fz] = s.force_n;
            writeln!(
                out,
                "{:.6},{x},{y},{z},{vx},{vy},{vz},{fx},{fy},{fz},{},{},{},{},{}",
                s.t_s,
                s.model_weight,
                u8::from(s.stale),
                s.target_n[2],
                s.blend_offset_n[2],
                s.passivity_energy_mj
            )?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_trace_drops_and_counts_without_growing() {
        let mut trace = Trace::with_capacity(3);
        for i in 0..5 {
            trace.push(TraceSample {
                t_s: f64::from(i),
                ..TraceSample::default()
            });
        }
        assert_eq!(trace.samples().len(), 3);
        assert_eq!(trace.dropped(), 2);
        let mut csv = Vec::new();
        trace.write_csv(&mut csv).unwrap();
        let text = String::from_utf8(csv).unwrap();
        assert_eq!(text.lines().count(), 4);
        assert!(text.starts_with("t_s,x_mm"));
    }
}

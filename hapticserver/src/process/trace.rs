//! A per-tick record of what the device did: position, velocity, rendered force, mode.
//!
//! Owns: [`TraceSample`] and [`Trace`], a buffer allocated once at its full capacity; the loop appends one
//! sample a tick until it is full (then stops recording and counts the drop), so recording never allocates
//! in a tick. Drills and benches read it to measure stability, stiffness and force tracking; the binary
//! writes it as CSV (`--trace-csv`).
//!
//! Reads its own CSV back ([`Trace::parse_csv`]) for the tools that look at another process's run.
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

    /// The header line [`Trace::write_csv`] writes.
    pub const CSV_HEADER: &'static str = "t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s,fx_n,fy_n,fz_n,model_weight,stale,\
         target_fz_n,blend_fz_n,passivity_energy_mj";

    /// Read what [`Trace::write_csv`] wrote (the diagnostics' x and y, not written, read as zero). An error
    /// names the line and the column.
    pub fn parse_csv(text: &str) -> Result<Vec<TraceSample>, String> {
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, header)) if header.trim() == Self::CSV_HEADER => {}
            _ => {
                return Err(format!(
                    "line 1: expected the trace header `{}`",
                    Self::CSV_HEADER
                ));
            }
        }
        let mut samples = Vec::new();
        for (index, line) in lines.filter(|(_, l)| !l.trim().is_empty()) {
            let mut values = [0.0f64; 15];
            let mut fields = line.split(',');
            for (column, value) in values.iter_mut().enumerate() {
                let field = fields
                    .next()
                    .ok_or_else(|| format!("line {}: {column} columns, need 15", index + 1))?;
                *value = field.trim().parse().map_err(|_| {
                    format!(
                        "line {}: column {}: `{field}` is not a number",
                        index + 1,
                        column + 1
                    )
                })?;
            }
            if fields.next().is_some() {
                return Err(format!("line {}: more than 15 columns", index + 1));
            }
            let v = |i: usize| values[i] as f32;
            samples.push(TraceSample {
                t_s: values[0],
                position_mm: [v(1), v(2), v(3)],
                velocity_mm_s: [v(4), v(5), v(6)],
                force_n: [v(7), v(8), v(9)],
                model_weight: v(10),
                stale: values[11] != 0.0,
                target_n: [0.0, 0.0, v(12)],
                blend_offset_n: [0.0, 0.0, v(13)],
                passivity_energy_mj: values[14],
            });
        }
        Ok(samples)
    }

    /// Write as CSV with a header: `t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s,fx_n,fy_n,fz_n,model_weight,stale,
    /// target_fz_n,blend_fz_n,passivity_energy_mj` (the last three: force before passivity and safety, the
    /// renderer's blend offset, the passivity account).
    pub fn write_csv(&self, out: &mut impl Write) -> std::io::Result<()> {
        writeln!(out, "{}", Self::CSV_HEADER)?;
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

    #[test]
    fn the_csv_reads_back_as_written_and_bad_lines_are_named() {
        let mut trace = Trace::with_capacity(2);
        let sample = TraceSample {
            t_s: 1.25,
            position_mm: [1.0, -2.5, 3.0],
            velocity_mm_s: [0.5, 0.0, -7.0],
            force_n: [0.1, 0.2, -0.3],
            model_weight: 1.0,
            stale: true,
            target_n: [0.0, 0.0, 0.75],
            blend_offset_n: [0.0, 0.0, -0.05],
            passivity_energy_mj: -3.5,
        };
        trace.push(sample);
        trace.push(TraceSample::default());
        let mut csv = Vec::new();
        trace.write_csv(&mut csv).unwrap();
        let text = String::from_utf8(csv).unwrap();
        assert_eq!(
            Trace::parse_csv(&text).unwrap(),
            vec![sample, TraceSample::default()]
        );
        let bad = text.replacen("1.250000,1", "1.250000,x", 1);
        let err = Trace::parse_csv(&bad).unwrap_err();
        assert!(err.contains("line 2") && err.contains("column 2"), "{err}");
        let short = format!("{}\n1,2,3\n", Trace::CSV_HEADER);
        assert!(Trace::parse_csv(&short).unwrap_err().contains("line 2"));
        assert!(Trace::parse_csv("t,x\n").unwrap_err().contains("line 1"));
    }
}

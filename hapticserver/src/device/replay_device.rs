//! A device that plays a recorded pose stream: a surgeon's hand from a session recording (`sinew play-device`)
//! or a hapticserver trace (`hapticserver --device replay --replay-trace FILE`), driven into a live scene.
//!
//! Owns: the timed samples, the play cursor and the force it was last told to render (it has no motor: the
//! force goes nowhere, as with a stylus held still in a clamp). [`Device::read`] advances play time by `dt_s`
//! and returns the newest sample at or before it; after the last one it holds that position at rest and raises
//! [`ReplayDevice::finished`]. Samples are in the wire frame already, so a replay device takes no mount.
//!
//! Must not: allocate in `read`/`write_force`, or accept non-finite or time-reversed samples.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use thiserror::Error;

use crate::device::{Device, DeviceError, DeviceModel, DeviceReading};
use crate::sim_device::sim_device_model;

/// Model name announced for a replay device.
pub const REPLAY_MODEL_NAME: &str = "replay";

/// One recorded reading and when it was taken, s from any origin (play starts at the first sample).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReplaySample {
    /// When, s.
    pub t_s: f64,
    /// What the device read then (wire frame).
    pub reading: DeviceReading,
}

/// A pose stream that cannot be played.
#[derive(Debug, Error)]
pub enum ReplayError {
    /// Nothing to play.
    #[error("{source_name}: no poses to play{hint}")]
    Empty {
        /// File or recording.
        source_name: String,
        /// What to check.
        hint: String,
    },
    /// A sample is not usable.
    #[error("{source_name}: line {line}: {message}")]
    BadSample {
        /// File or recording.
        source_name: String,
        /// 1-based line (or sample index + 1 for in-memory streams).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The file cannot be read.
    #[error("{source_name}: {message}")]
    Read {
        /// File.
        source_name: String,
        /// Why.
        message: String,
    },
}

/// The replay device.
#[derive(Debug)]
pub struct ReplayDevice {
    samples: Vec<ReplaySample>,
    next: usize,
    play_time_s: f64,
    current: DeviceReading,
    finished: Arc<AtomicBool>,
    force_n: [f32; 3],
}

impl ReplayDevice {
    /// A device playing `samples` (times non-decreasing, every value finite); `source_name` names them in
    /// errors.
    pub fn new(source_name: &str, samples: Vec<ReplaySample>) -> Result<Self, ReplayError> {
        let Some(first) = samples.first() else {
            return Err(ReplayError::Empty {
                source_name: source_name.to_owned(),
                hint: String::new(),
            });
        };
        let t0 = first.t_s;
        let mut previous = t0;
        for (i, sample) in samples.iter().enumerate() {
            let bad = |message: &str| ReplayError::BadSample {
                source_name: source_name.to_owned(),
                line: i + 1,
                message: message.to_owned(),
            };
            if !sample.t_s.is_finite() || !sample.reading.is_finite() {
                return Err(bad("a value is not finite"));
            }
            if sample.t_s < previous {
                return Err(bad("time goes backwards"));
            }
            previous = sample.t_s;
        }
        let mut samples = samples;
        for sample in &mut samples {
            sample.t_s -= t0;
        }
        let current = samples[0].reading;
        Ok(Self {
            samples,
            next: 1,
            play_time_s: 0.0,
            current,
            finished: Arc::new(AtomicBool::new(false)),
            force_n: [0.0; 3],
        })
    }

    /// Read a hapticserver trace (`--trace-csv`): `t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s,...` with a
    /// header line.
    pub fn from_trace_csv(path: &Path) -> Result<Self, ReplayError> {
        let source_name = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| ReplayError::Read {
            source_name: source_name.clone(),
            message: e.to_string(),
        })?;
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, header))
                if header.starts_with("t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s") => {}
            _ => {
                return Err(ReplayError::BadSample {
                    source_name,
                    line: 1,
                    message: "expected the trace header `t_s,x_mm,y_mm,z_mm,vx_mm_s,vy_mm_s,vz_mm_s,...` \
                              (hapticserver --trace-csv)"
                        .to_owned(),
                });
            }
        }
        let mut samples = Vec::new();
        for (index, line) in lines {
            if line.trim().is_empty() {
                continue;
            }
            let bad = |message: String| ReplayError::BadSample {
                source_name: source_name.clone(),
                line: index + 1,
                message,
            };
            let mut values = [0.0f64; 7];
            let mut fields = line.split(',');
            for (column, value) in values.iter_mut().enumerate() {
                let field = fields
                    .next()
                    .ok_or_else(|| bad(format!("{} columns, need at least 7", column)))?;
                *value = field.trim().parse().map_err(|_| {
                    bad(format!("column {}: `{field}` is not a number", column + 1))
                })?;
            }
            let [t_s, x, y, z, vx, vy, vz] = values;
            samples.push(ReplaySample {
                t_s,
                reading: DeviceReading {
                    position_mm: [x as f32, y as f32, z as f32],
                    linear_velocity_mm_s: [vx as f32, vy as f32, vz as f32],
                    ..DeviceReading::default()
                },
            });
        }
        if samples.is_empty() {
            return Err(ReplayError::Empty {
                source_name,
                hint: " (the trace has a header and no rows)".to_owned(),
            });
        }
        Self::new(&source_name, samples)
    }

    /// Raised once the last sample has been played (shared, so a caller can watch it after the loop owns the
    /// device).
    pub fn finished(&self) -> Arc<AtomicBool> {
        self.finished.clone()
    }

    /// Length of the stream, s.
    pub fn duration_s(&self) -> f64 {
        self.samples.last().map_or(0.0, |s| s.t_s)
    }

    /// The force it was last told to render, N.
    pub fn force_n(&self) -> [f32; 3] {
        self.force_n
    }
}

impl Device for ReplayDevice {
    /// The simulated device's limits (a Touch-like 3.3 N): forces a replayed hand is sent stay in a real
    /// device's range.
    fn model(&self) -> DeviceModel {
        DeviceModel {
            name: REPLAY_MODEL_NAME.to_owned(),
            ..sim_device_model()
        }
    }

    fn read(&mut self, dt_s: f32) -> Result<DeviceReading, DeviceError> {
        if dt_s.is_finite() && dt_s > 0.0 {
            self.play_time_s += f64::from(dt_s);
        }
        while let Some(sample) = self.samples.get(self.next)
            && sample.t_s <= self.play_time_s
        {
            self.current = sample.reading;
            self.next += 1;
        }
        if self.next >= self.samples.len() && !self.finished.load(Ordering::Relaxed) {
            // Hold the last position at rest.
            self.current.linear_velocity_mm_s = [0.0; 3];
            self.finished.store(true, Ordering::Release);
        }
        Ok(self.current)
    }

    fn write_force(&mut self, force_n: [f32; 3]) -> Result<(), DeviceError> {
        let (force_n, result) = crate::device::finite_or_zero(force_n);
        self.force_n = force_n;
        result
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(t_s: f64, z: f32) -> ReplaySample {
        ReplaySample {
            t_s,
            reading: DeviceReading {
                position_mm: [0.0, 0.0, z],
                linear_velocity_mm_s: [0.0, 0.0, -1.0],
                ..DeviceReading::default()
            },
        }
    }

    #[test]
    fn plays_on_time_then_holds_at_rest() {
        let mut device =
            ReplayDevice::new("test", vec![at(5.0, 10.0), at(5.002, 9.0), at(5.004, 8.0)]).unwrap();
        let finished = device.finished();
        assert_eq!(device.read(0.0).unwrap().position_mm[2], 10.0);
        assert_eq!(device.read(0.001).unwrap().position_mm[2], 10.0);
        assert_eq!(device.read(0.001).unwrap().position_mm[2], 9.0);
        assert!(!finished.load(Ordering::Acquire));
        // A long step (a stalled loop) jumps to the newest sample, not the next one.
        let last = device.read(0.01).unwrap();
        assert_eq!(last.position_mm[2], 8.0);
        assert_eq!(last.linear_velocity_mm_s, [0.0; 3]);
        assert!(finished.load(Ordering::Acquire));
        assert_eq!(device.read(1.0).unwrap().position_mm[2], 8.0);
        assert!((device.duration_s() - 0.004).abs() < 1e-9);
    }

    #[test]
    fn bad_streams_are_refused_by_sample() {
        let err = ReplayDevice::new("rec", vec![]).unwrap_err().to_string();
        assert!(err.contains("rec: no poses"), "{err}");
        let err = ReplayDevice::new("rec", vec![at(1.0, 0.0), at(0.5, 0.0)])
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 2: time goes backwards"), "{err}");
        let err = ReplayDevice::new("rec", vec![at(0.0, f32::NAN)])
            .unwrap_err()
            .to_string();
        assert!(err.contains("line 1: a value is not finite"), "{err}");
    }

    #[test]
    fn trace_csv_round_trips_and_names_bad_lines() {
        let dir = std::env::temp_dir().join(format!("sinew-replay-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("trace.csv");
        let mut trace = crate::trace::Trace::with_capacity(4);
        for i in 0..3 {
            trace.push(crate::trace::TraceSample {
                t_s: f64::from(i) * 0.001,
                position_mm: [1.0, 2.0, 3.0 - i as f32],
                ..crate::trace::TraceSample::default()
            });
        }
        let mut bytes = Vec::new();
        trace.write_csv(&mut bytes).unwrap();
        std::fs::write(&path, &bytes).unwrap();
        let mut device = ReplayDevice::from_trace_csv(&path).unwrap();
        assert_eq!(device.read(0.0).unwrap().position_mm, [1.0, 2.0, 3.0]);
        assert_eq!(device.read(0.002).unwrap().position_mm, [1.0, 2.0, 1.0]);

        std::fs::write(&path, "x,y\n").unwrap();
        let err = ReplayDevice::from_trace_csv(&path).unwrap_err().to_string();
        assert!(err.contains("line 1: expected the trace header"), "{err}");
        let mut text = String::from_utf8(bytes).unwrap();
        text.push_str("0.5,1,2,oops,0,0,0\n");
        std::fs::write(&path, text).unwrap();
        let err = ReplayDevice::from_trace_csv(&path).unwrap_err().to_string();
        assert!(
            err.contains("line 5: column 4: `oops` is not a number"),
            "{err}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

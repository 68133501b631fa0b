//! Fixed-bucket latency histogram.

/// Sub-buckets per power of two: resolution is 1/32 (about 3%) of the value.
const SUB_BITS: u32 = 5;
const SUB: usize = 1 << SUB_BITS;
/// Values up to 2^40 ns (18 minutes) are bucketed; larger ones land in the last bucket.
const TOP_BITS: usize = 40;
const BUCKETS: usize = (TOP_BITS - SUB_BITS as usize + 1) * SUB;

/// Records durations in nanoseconds into log-linear buckets (about 3% resolution) and answers percentiles.
/// Fixed size, no allocation after construction, `record` is O(1) and never panics.
#[derive(Clone)]
pub struct LatencyHistogram {
    counts: Box<[u64; BUCKETS]>,
    total: u64,
    max_ns: u64,
    sum_ns: u128,
}

impl std::fmt::Debug for LatencyHistogram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LatencyHistogram")
            .field("count", &self.total)
            .field("p50_ns", &self.percentile_ns(50.0))
            .field("p99_ns", &self.percentile_ns(99.0))
            .field("max_ns", &self.max_ns)
            .finish()
    }
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self::new()
    }
}

fn bucket_of(value_ns: u64) -> usize {
    if value_ns < SUB as u64 {
        return value_ns as usize;
    }
    let msb = 63 - value_ns.leading_zeros();
    if msb as usize >= TOP_BITS {
        return BUCKETS - 1;
    }
    let shift = msb - SUB_BITS;
    let sub = ((value_ns >> shift) as usize) & (SUB - 1);
    ((shift as usize + 1) * SUB + sub).min(BUCKETS - 1)
}

fn bucket_upper_ns(bucket: usize) -> u64 {
    if bucket < SUB {
        return bucket as u64;
    }
    let shift = (bucket / SUB - 1) as u32;
    let sub = (bucket % SUB) as u64;
    ((SUB as u64 + sub + 1) << shift) - 1
}

impl LatencyHistogram {
    /// An empty histogram (allocates its buckets once).
    pub fn new() -> Self {
        Self {
            counts: Box::new([0; BUCKETS]),
            total: 0,
            max_ns: 0,
            sum_ns: 0,
        }
    }

    /// Record one duration. Real-time safe.
    pub fn record_ns(&mut self, value_ns: u64) {
        self.counts[bucket_of(value_ns)] += 1;
        self.total += 1;
        self.max_ns = self.max_ns.max(value_ns);
        self.sum_ns += u128::from(value_ns);
    }

    /// Record a `Duration`.
    pub fn record(&mut self, value: std::time::Duration) {
        self.record_ns(u64::try_from(value.as_nanos()).unwrap_or(u64::MAX));
    }

    /// Number of samples.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// Largest sample, ns.
    pub fn max_ns(&self) -> u64 {
        self.max_ns
    }

    /// Mean, ns (0 when empty).
    pub fn mean_ns(&self) -> f64 {
        if self.total == 0 {
            0.0
        } else {
            self.sum_ns as f64 / self.total as f64
        }
    }

    /// The value below which `percent` of samples lie (bucket upper edge, capped at the max), ns; 0 when empty.
    pub fn percentile_ns(&self, percent: f64) -> u64 {
        if self.total == 0 {
            return 0;
        }
        let rank = ((percent / 100.0) * self.total as f64).ceil().max(1.0) as u64;
        let mut seen = 0;
        for (bucket, &count) in self.counts.iter().enumerate() {
            seen += count;
            if seen >= rank {
                // The last bucket is open-ended: its only honest upper edge is the max.
                if bucket == BUCKETS - 1 {
                    return self.max_ns;
                }
                return bucket_upper_ns(bucket).min(self.max_ns);
            }
        }
        self.max_ns
    }

    /// Percentile in microseconds, as f32 for stats messages.
    pub fn percentile_us(&self, percent: f64) -> f32 {
        self.percentile_ns(percent) as f32 / 1000.0
    }

    /// Overwrite with `other`'s samples, without allocating (for publishing a loop's histogram).
    pub fn copy_from(&mut self, other: &LatencyHistogram) {
        self.counts.copy_from_slice(&other.counts[..]);
        self.total = other.total;
        self.max_ns = other.max_ns;
        self.sum_ns = other.sum_ns;
    }

    /// The samples recorded after `earlier` was copied from this same histogram: a window of a cumulative
    /// record (for a soak run's per-minute figures). Its max is the upper edge of its highest bucket, capped at
    /// this histogram's max. Allocates (not for hot loops).
    pub fn since(&self, earlier: &LatencyHistogram) -> LatencyHistogram {
        let mut window = LatencyHistogram::new();
        let mut highest = None;
        for (bucket, (now, then)) in self.counts.iter().zip(earlier.counts.iter()).enumerate() {
            let count = now.saturating_sub(*then);
            window.counts[bucket] = count;
            window.total += count;
            if count > 0 {
                highest = Some(bucket);
            }
        }
        window.sum_ns = self.sum_ns.saturating_sub(earlier.sum_ns);
        window.max_ns = highest.map_or(0, |b| {
            if b == BUCKETS - 1 {
                self.max_ns
            } else {
                bucket_upper_ns(b).min(self.max_ns)
            }
        });
        window
    }

    /// Forget every sample.
    pub fn reset(&mut self) {
        self.counts.fill(0);
        self.total = 0;
        self.max_ns = 0;
        self.sum_ns = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_window_holds_only_the_later_samples() {
        let mut h = LatencyHistogram::new();
        for _ in 0..100 {
            h.record_ns(1_000);
        }
        let earlier = h.clone();
        for _ in 0..10 {
            h.record_ns(500_000);
        }
        let window = h.since(&earlier);
        assert_eq!(window.count(), 10);
        let p50 = window.percentile_ns(50.0);
        assert!((480_000..=520_000).contains(&p50), "{p50}");
        assert_eq!(window.mean_ns(), 500_000.0);
    }

    #[test]
    fn percentiles_are_within_bucket_resolution() {
        let mut h = LatencyHistogram::new();
        for v in 1..=100_000u64 {
            h.record_ns(v * 10);
        }
        let p50 = h.percentile_ns(50.0) as f64;
        let p99 = h.percentile_ns(99.0) as f64;
        assert!((p50 / 500_000.0 - 1.0).abs() < 0.04, "p50 {p50}");
        assert!((p99 / 990_000.0 - 1.0).abs() < 0.04, "p99 {p99}");
        assert_eq!(h.max_ns(), 1_000_000);
        assert_eq!(h.percentile_ns(100.0), 1_000_000);
    }

    #[test]
    fn buckets_are_monotonic_and_cover_extremes() {
        let mut last = 0;
        for v in (0..1_000_000u64)
            .step_by(37)
            .chain([u64::MAX / 2, u64::MAX])
        {
            let b = bucket_of(v);
            assert!(b >= last && b < BUCKETS);
            last = b;
        }
        let mut h = LatencyHistogram::new();
        assert_eq!(h.percentile_ns(99.0), 0);
        h.record_ns(u64::MAX);
        assert_eq!(h.percentile_ns(50.0), u64::MAX);
    }
}

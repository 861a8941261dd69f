//! A fixed-layout histogram of time intervals (the gaps between consecutive offboard
//! setpoints a vehicle receives), cheap to record into and to merge across vehicles.
//!
//! Layout: 0.1 ms buckets from 0 to 100 ms (1000 buckets), 1 ms buckets from 100 ms to
//! 1 s (900 buckets), and one overflow bucket for 1 s and more; the largest interval is
//! also kept exactly. Storage is allocated on the first sample (about 7.6 KB), so a
//! vehicle that never receives setpoints costs nothing.
//!
//! Quantiles and "above a threshold" counts are resolved to a bucket and err on the
//! pessimistic side: a quantile is reported as the upper edge of its bucket (capped at
//! the exact maximum), and [`IntervalHistogram::count_above`] counts the whole bucket
//! that contains the threshold.

use serde::Serialize;
use std::time::Duration;

/// Width of the fine buckets, µs.
const FINE_US: u64 = 100;
/// Upper edge of the fine range, µs.
const FINE_END_US: u64 = 100_000;
/// Width of the coarse buckets, µs.
const COARSE_US: u64 = 1_000;
/// Upper edge of the coarse range, µs (everything above goes to the overflow bucket).
const COARSE_END_US: u64 = 1_000_000;
const FINE_BUCKETS: usize = (FINE_END_US / FINE_US) as usize;
const COARSE_BUCKETS: usize = ((COARSE_END_US - FINE_END_US) / COARSE_US) as usize;
/// Buckets in all, the overflow bucket included.
const BUCKETS: usize = FINE_BUCKETS + COARSE_BUCKETS + 1;

/// A histogram of intervals (see module docs).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct IntervalHistogram {
    /// Counts per bucket; empty until the first sample.
    counts: Vec<u64>,
    total: u64,
    max_us: u64,
    sum_us: u128,
}

/// One non-empty bucket: `[lo_ms, hi_ms)` and how many intervals fell in it. The
/// overflow bucket has `hi_ms` = the exact maximum.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IntervalBucket {
    /// Lower edge, ms (inclusive).
    pub lo_ms: f64,
    /// Upper edge, ms (exclusive, except for the overflow bucket).
    pub hi_ms: f64,
    /// Intervals in the bucket.
    pub count: u64,
}

/// Summary of an [`IntervalHistogram`], as the stats report it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct IntervalSummary {
    /// Intervals recorded.
    pub count: u64,
    /// Mean interval, ms (0 when empty).
    pub mean_ms: f64,
    /// Median, ms (upper edge of its bucket).
    pub p50_ms: f64,
    /// 99th percentile, ms (upper edge of its bucket).
    pub p99_ms: f64,
    /// 99.9th percentile, ms (upper edge of its bucket).
    pub p999_ms: f64,
    /// Largest interval, ms (exact).
    pub max_ms: f64,
}

fn bucket_of(us: u64) -> usize {
    if us < FINE_END_US {
        (us / FINE_US) as usize
    } else if us < COARSE_END_US {
        FINE_BUCKETS + ((us - FINE_END_US) / COARSE_US) as usize
    } else {
        BUCKETS - 1
    }
}

/// `[lo, hi)` of bucket `i`, µs (the overflow bucket ends at `u64::MAX`).
fn edges_us(i: usize) -> (u64, u64) {
    if i < FINE_BUCKETS {
        let lo = i as u64 * FINE_US;
        (lo, lo + FINE_US)
    } else if i < FINE_BUCKETS + COARSE_BUCKETS {
        let lo = FINE_END_US + (i - FINE_BUCKETS) as u64 * COARSE_US;
        (lo, lo + COARSE_US)
    } else {
        (COARSE_END_US, u64::MAX)
    }
}

impl IntervalHistogram {
    /// An empty histogram.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records one interval.
    pub fn record(&mut self, interval: Duration) {
        let us = u64::try_from(interval.as_micros()).unwrap_or(u64::MAX);
        if self.counts.is_empty() {
            self.counts = vec![0; BUCKETS];
        }
        self.counts[bucket_of(us)] += 1;
        self.total += 1;
        self.max_us = self.max_us.max(us);
        self.sum_us += u128::from(us);
    }

    /// Adds every sample of `other` (aggregation over vehicles).
    pub fn merge(&mut self, other: &IntervalHistogram) {
        if other.total == 0 {
            return;
        }
        if self.counts.is_empty() {
            self.counts = vec![0; BUCKETS];
        }
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += *b;
        }
        self.total += other.total;
        self.max_us = self.max_us.max(other.max_us);
        self.sum_us += other.sum_us;
    }

    /// Forgets every sample.
    pub fn clear(&mut self) {
        *self = Self::default();
    }

    /// Intervals recorded.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// Largest interval recorded, ms (0 when empty).
    pub fn max_ms(&self) -> f64 {
        self.max_us as f64 / 1e3
    }

    /// Mean interval, ms (0 when empty).
    pub fn mean_ms(&self) -> f64 {
        if self.total == 0 {
            0.0
        } else {
            self.sum_us as f64 / self.total as f64 / 1e3
        }
    }

    /// The `q` quantile (0..=1), ms: the upper edge of the bucket holding it, capped at the
    /// exact maximum (0 when empty).
    pub fn quantile_ms(&self, q: f64) -> f64 {
        if self.total == 0 {
            return 0.0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.total as f64).ceil() as u64).max(1);
        let mut seen = 0;
        for (i, &c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                let (_, hi) = edges_us(i);
                return hi.min(self.max_us) as f64 / 1e3;
            }
        }
        self.max_ms()
    }

    /// Intervals longer than `threshold_ms`, counting the whole bucket that contains the
    /// threshold (so at most one bucket width, 0.1 ms below 100 ms, too pessimistic).
    pub fn count_above(&self, threshold_ms: f64) -> u64 {
        if self.total == 0 || threshold_ms.is_nan() || threshold_ms >= self.max_ms() {
            return 0;
        }
        let t_us = (threshold_ms.max(0.0) * 1e3) as u64;
        let first = bucket_of(t_us);
        self.counts[first..].iter().sum()
    }

    /// The non-empty buckets, shortest intervals first.
    pub fn buckets(&self) -> Vec<IntervalBucket> {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, c)| **c > 0)
            .map(|(i, &count)| {
                let (lo, hi) = edges_us(i);
                IntervalBucket {
                    lo_ms: lo as f64 / 1e3,
                    hi_ms: hi.min(self.max_us.max(lo)) as f64 / 1e3,
                    count,
                }
            })
            .collect()
    }

    /// Count, mean, p50, p99, p99.9 and max.
    pub fn summary(&self) -> IntervalSummary {
        IntervalSummary {
            count: self.total,
            mean_ms: self.mean_ms(),
            p50_ms: self.quantile_ms(0.5),
            p99_ms: self.quantile_ms(0.99),
            p999_ms: self.quantile_ms(0.999),
            max_ms: self.max_ms(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(x: f64) -> Duration {
        Duration::from_secs_f64(x / 1e3)
    }

    #[test]
    fn buckets_cover_the_range_without_gaps() {
        let mut prev_hi = 0;
        for i in 0..BUCKETS - 1 {
            let (lo, hi) = edges_us(i);
            assert_eq!(lo, prev_hi, "bucket {i}");
            assert_eq!(bucket_of(lo), i);
            assert_eq!(bucket_of(hi - 1), i);
            prev_hi = hi;
        }
        assert_eq!(prev_hi, COARSE_END_US);
        assert_eq!(bucket_of(COARSE_END_US), BUCKETS - 1);
        assert_eq!(bucket_of(u64::MAX), BUCKETS - 1);
    }

    #[test]
    fn quantiles_and_threshold_counts() {
        let mut h = IntervalHistogram::new();
        assert_eq!(h.summary(), IntervalSummary::default());
        for _ in 0..98 {
            h.record(ms(20.03));
        }
        h.record(ms(26.0));
        h.record(ms(250.4));
        let s = h.summary();
        assert_eq!(s.count, 100);
        assert!((s.p50_ms - 20.1).abs() < 1e-9, "{s:?}");
        assert!((s.p99_ms - 26.1).abs() < 1e-9, "{s:?}");
        assert!((s.max_ms - 250.4).abs() < 1e-9, "{s:?}");
        assert_eq!(h.count_above(25.0), 2);
        assert_eq!(h.count_above(26.05), 2, "the threshold's bucket counts");
        assert_eq!(h.count_above(26.1), 1);
        assert_eq!(h.count_above(300.0), 0);
        assert_eq!(h.buckets().len(), 3);
        assert_eq!(h.buckets()[2].hi_ms, 250.4, "capped at the exact max");
    }

    #[test]
    fn merge_adds_and_overflow_keeps_the_exact_max() {
        let mut a = IntervalHistogram::new();
        let mut b = IntervalHistogram::new();
        a.record(ms(10.0));
        b.record(Duration::from_secs(3));
        a.merge(&b);
        a.merge(&IntervalHistogram::new());
        assert_eq!(a.count(), 2);
        assert_eq!(a.max_ms(), 3000.0);
        assert_eq!(a.quantile_ms(1.0), 3000.0);
        assert_eq!(a.buckets()[1].hi_ms, 3000.0);
        a.clear();
        assert_eq!(a.count(), 0);
    }
}

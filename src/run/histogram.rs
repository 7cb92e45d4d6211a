//! Latency percentiles over a run of any length: [`Histogram`] keeps the samples in constant
//! memory, [`Percentiles`] are its figures in the summary.

use serde::Serialize;

/// Latency percentiles (microseconds).
#[derive(Debug, Serialize, Default, Clone, Copy)]
pub struct Percentiles {
    /// Median.
    pub p50: f64,
    /// 99th percentile.
    pub p99: f64,
    /// Largest.
    pub max: f64,
    /// Samples.
    pub samples: usize,
}

/// Latency samples (us) in a fixed histogram of buckets 1 % wide from 1 us to about 100 s, so
/// that a long `--live` run keeps constant memory. Percentiles are bucket upper bounds (within
/// 1 % above the true value, never above the largest sample); the largest sample is exact. The
/// rank of a percentile is [`crate::percentile::nearest_rank`].
#[derive(Debug, Clone)]
pub(crate) struct Histogram {
    counts: Vec<u64>,
    samples: u64,
    max: f64,
}

impl Histogram {
    const GROWTH: f64 = 1.01;
    const BUCKETS: usize = 1852; // 1.01^1851 > 1e8

    pub(crate) fn new() -> Self {
        Self {
            counts: vec![0; Self::BUCKETS],
            samples: 0,
            max: 0.0,
        }
    }

    pub(crate) fn add(&mut self, us: f64) {
        let bucket = if us <= 1.0 {
            0
        } else {
            ((us.ln() / Self::GROWTH.ln()).ceil() as usize).min(Self::BUCKETS - 1)
        };
        self.counts[bucket] += 1;
        self.samples += 1;
        self.max = self.max.max(us);
    }

    fn at(&self, q: f64) -> f64 {
        let rank = crate::percentile::nearest_rank(q, self.samples);
        let mut seen = 0;
        for (bucket, count) in self.counts.iter().enumerate() {
            seen += count;
            if seen >= rank {
                return Self::GROWTH.powi(bucket as i32).min(self.max);
            }
        }
        self.max
    }

    pub(crate) fn percentiles(&self) -> Percentiles {
        if self.samples == 0 {
            return Percentiles::default();
        }
        Percentiles {
            p50: self.at(0.5),
            p99: self.at(0.99),
            max: self.max,
            samples: self.samples as usize,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_percentiles_are_within_one_percent_above_the_exact_ones() {
        // Latency-like samples from 0.3 us to ~60 ms (a deterministic spread).
        let mut exact: Vec<f64> = (0..20_000u64)
            .map(|i| 0.3 * (1.0 + (i * 7919 % 20_000) as f64).powf(1.3))
            .collect();
        let mut h = Histogram::new();
        for &x in &exact {
            h.add(x);
        }
        exact.sort_by(f64::total_cmp);
        let p = h.percentiles();
        assert_eq!(p.samples, exact.len());
        assert_eq!(p.max, exact[exact.len() - 1]);
        for (q, got) in [(0.5, p.p50), (0.99, p.p99)] {
            let want = exact[(q * exact.len() as f64).ceil() as usize - 1];
            assert!(
                got >= want && got <= want.max(1.0) * 1.01,
                "q {q}: {got} vs exact {want}"
            );
        }
        assert_eq!(Histogram::new().percentiles().samples, 0);
    }
}

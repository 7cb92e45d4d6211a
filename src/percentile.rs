//! The one percentile rule of the figures `icrflow` reports (the run's summary, through
//! [`crate::run::histogram`], and `monitor`'s latency): the nearest rank. The `q` quantile of
//! `n` samples is the sample of rank `ceil(q n)` in ascending order (1-based, at least the
//! first): the smallest sample with at least a share `q` of the samples at or below it. It is
//! always one of the samples, never an interpolation between two.

/// The 1-based rank of the `q` quantile among `n` samples by the nearest-rank rule:
/// `ceil(q n)`, at least 1 and at most `n` (`q` in 0..=1; 0 for no samples).
pub fn nearest_rank(q: f64, n: u64) -> u64 {
    ((q * n as f64).ceil() as u64).max(1).min(n)
}

/// The `q` quantile of `sorted` (ascending) by [`nearest_rank`]; `None` when it is empty.
pub fn of_sorted(sorted: &[f64], q: f64) -> Option<f64> {
    let rank = nearest_rank(q, sorted.len() as u64);
    sorted.get((rank as usize).checked_sub(1)?).copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quantile_is_the_sample_of_rank_ceil_q_n() {
        // 1..=10: the median is the 5th (ceil 5.0), not the 6th nor 5.5; p99 the 10th.
        let ten: Vec<f64> = (1..=10).map(f64::from).collect();
        assert_eq!(of_sorted(&ten, 0.5), Some(5.0));
        assert_eq!(of_sorted(&ten, 0.99), Some(10.0));
        assert_eq!(of_sorted(&ten, 0.0), Some(1.0));
        assert_eq!(of_sorted(&ten, 1.0), Some(10.0));
        // 1..=1000: p50 the 500th, p99 the 990th; an odd count's median is its middle.
        let thousand: Vec<f64> = (1..=1000).map(f64::from).collect();
        assert_eq!(of_sorted(&thousand, 0.5), Some(500.0));
        assert_eq!(of_sorted(&thousand, 0.99), Some(990.0));
        assert_eq!(of_sorted(&[1.0, 2.0, 3.0], 0.5), Some(2.0));
        assert_eq!(of_sorted(&[7.0], 0.99), Some(7.0));
        assert_eq!(of_sorted(&[], 0.5), None);
        assert_eq!(nearest_rank(0.5, 0), 0);
        assert_eq!(nearest_rank(0.99, 101), 100);
    }
}

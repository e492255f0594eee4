//! Statistics of timing samples: the median with a percentile-bootstrap 95 % confidence
//! interval, and the ratio of two configurations' medians with its interval, which marks a
//! difference beyond noise when it excludes 1. Resampling is seeded, so a results file
//! always reports the same interval.

use crate::rng::SplitMix64;

/// Bootstrap resamples per interval.
pub const RESAMPLES: usize = 2000;

/// The seed of every bootstrap (reproducible intervals).
const SEED: u64 = 0x5eed_71e5;

/// The median of `samples` (the mean of the middle two for an even count; 0 when empty).
pub fn median(samples: &[f64]) -> f64 {
    if samples.is_empty() {
        return 0.0;
    }
    let mut s = samples.to_vec();
    s.sort_by(f64::total_cmp);
    let m = s.len() / 2;
    if s.len() % 2 == 1 {
        s[m]
    } else {
        0.5 * (s[m - 1] + s[m])
    }
}

/// The `q` quantile (0..=1) of sorted values, nearest rank.
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let i = (q * (sorted.len() - 1) as f64).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

/// The median of a resample (with replacement) of `samples`, into `scratch`.
fn resampled_median(samples: &[f64], rng: &mut SplitMix64, scratch: &mut Vec<f64>) -> f64 {
    scratch.clear();
    let n = samples.len() as u64;
    scratch.extend((0..n).map(|_| samples[(rng.next_u64() % n) as usize]));
    median(scratch)
}

/// A statistic with its 95 % confidence interval.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Estimate {
    pub value: f64,
    pub low: f64,
    pub high: f64,
}

impl Estimate {
    /// Whether the interval excludes `x`.
    pub fn excludes(&self, x: f64) -> bool {
        x < self.low || x > self.high
    }
}

/// The median of `samples` and its percentile-bootstrap 95 % interval (the median itself,
/// twice, for fewer than two samples).
pub fn median_ci(samples: &[f64]) -> Estimate {
    let value = median(samples);
    if samples.len() < 2 {
        return Estimate {
            value,
            low: value,
            high: value,
        };
    }
    let mut rng = SplitMix64::new(SEED);
    let mut scratch = Vec::with_capacity(samples.len());
    let mut medians: Vec<f64> = (0..RESAMPLES)
        .map(|_| resampled_median(samples, &mut rng, &mut scratch))
        .collect();
    medians.sort_by(f64::total_cmp);
    Estimate {
        value,
        low: quantile(&medians, 0.025),
        high: quantile(&medians, 0.975),
    }
}

/// The ratio `median(b) / median(a)` and its 95 % interval, each configuration resampled on
/// its own; `None` when either has no samples or `a`'s median is 0.
pub fn ratio_ci(a: &[f64], b: &[f64]) -> Option<Estimate> {
    let (ma, mb) = (median(a), median(b));
    if a.is_empty() || b.is_empty() || ma <= 0.0 {
        return None;
    }
    let mut rng = SplitMix64::new(SEED);
    let mut scratch = Vec::with_capacity(a.len().max(b.len()));
    let mut ratios: Vec<f64> = (0..RESAMPLES)
        .filter_map(|_| {
            let ra = resampled_median(a, &mut rng, &mut scratch);
            let rb = resampled_median(b, &mut rng, &mut scratch);
            (ra > 0.0).then(|| rb / ra)
        })
        .collect();
    if ratios.is_empty() {
        return None;
    }
    ratios.sort_by(f64::total_cmp);
    Some(Estimate {
        value: mb / ma,
        low: quantile(&ratios, 0.025),
        high: quantile(&ratios, 0.975),
    })
}

/// For samples taken in pairs (frame `i` of `a` and of `b` show the same view, as along a
/// camera path, where the view moves the time more than noise does): the median of the
/// per-frame ratios `b[i] / a[i]` and its bootstrap 95 % interval, resampling frames. `None`
/// when the lengths differ or no frame of `a` took time.
pub fn paired_ratio_ci(a: &[f64], b: &[f64]) -> Option<Estimate> {
    if a.len() != b.len() {
        return None;
    }
    let ratios: Vec<f64> = a
        .iter()
        .zip(b)
        .filter(|(x, _)| **x > 0.0)
        .map(|(x, y)| y / x)
        .collect();
    (!ratios.is_empty()).then(|| median_ci(&ratios))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` samples around `centre` with a spread of `spread`, deterministic.
    fn noisy(n: usize, centre: f64, spread: f64, seed: u64) -> Vec<f64> {
        let mut rng = SplitMix64::new(seed);
        (0..n)
            .map(|_| centre + spread * (rng.next_f64() - 0.5))
            .collect()
    }

    #[test]
    fn medians_of_known_samples() {
        assert_eq!(median(&[]), 0.0);
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
    }

    #[test]
    fn the_interval_holds_the_median_narrows_with_more_samples_and_repeats() {
        let few = median_ci(&noisy(10, 100.0, 20.0, 1));
        let many = median_ci(&noisy(1000, 100.0, 20.0, 1));
        for e in [few, many] {
            assert!(e.low <= e.value && e.value <= e.high, "{e:?}");
            assert!(e.low > 90.0 && e.high < 110.0, "{e:?}");
        }
        assert!(
            many.high - many.low < (few.high - few.low) / 3.0,
            "{few:?} {many:?}"
        );
        assert_eq!(
            median_ci(&noisy(50, 5.0, 1.0, 2)),
            median_ci(&noisy(50, 5.0, 1.0, 2))
        );
        let one = median_ci(&[7.0]);
        assert_eq!((one.low, one.value, one.high), (7.0, 7.0, 7.0));
    }

    #[test]
    fn ratios_find_a_real_difference_and_none_between_equal_samples() {
        let a = noisy(30, 100.0, 10.0, 3);
        let same = ratio_ci(&a, &a).expect("ratio");
        assert_eq!(same.value, 1.0);
        assert!(!same.excludes(1.0), "{same:?}");
        let slower = ratio_ci(&a, &noisy(30, 130.0, 10.0, 4)).expect("ratio");
        assert!(slower.excludes(1.0) && slower.low > 1.1, "{slower:?}");
        let noise = ratio_ci(&a, &noisy(30, 100.0, 10.0, 5)).expect("ratio");
        assert!(!noise.excludes(1.0), "{noise:?}");
        assert_eq!(ratio_ci(&[], &a), None);
        assert_eq!(ratio_ci(&[0.0], &a), None);
    }

    #[test]
    fn pairing_frames_finds_a_small_difference_the_spread_of_views_hides() {
        // Times that follow the view along a path (5 to 50 ms), B 5 % slower at every frame.
        let a: Vec<f64> = noisy(40, 0.0, 1.0, 6)
            .iter()
            .enumerate()
            .map(|(i, n)| 5.0 + 45.0 * (i as f64 / 39.0) + 0.1 * n)
            .collect();
        let b: Vec<f64> = a.iter().map(|x| x * 1.05).collect();
        let unpaired = ratio_ci(&a, &b).expect("ratio");
        assert!(!unpaired.excludes(1.0), "{unpaired:?}");
        let paired = paired_ratio_ci(&a, &b).expect("paired");
        assert!((paired.value - 1.05).abs() < 1e-9, "{paired:?}");
        assert!(paired.excludes(1.0), "{paired:?}");
        assert!(!paired_ratio_ci(&a, &a).expect("same").excludes(1.0));
        assert_eq!(paired_ratio_ci(&a, &b[1..]), None);
    }
}

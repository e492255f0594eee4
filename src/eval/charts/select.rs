//! The records a chart compares: the baseline, the models and their slices, and per-label
//! means of time and accuracy.

use std::collections::BTreeMap;

use super::axes::mean;
use crate::eval::results::{Record, Results};

/// Baseline (unstressed) records.
pub(super) fn baseline(results: &Results) -> impl Iterator<Item = &Record> {
    results.records.iter().filter(|r| r.stress.is_none())
}

/// Distinct model names in first-appearance order.
pub fn models(results: &Results) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for r in &results.records {
        if !out.contains(&r.model) {
            out.push(r.model.clone());
        }
    }
    out
}

/// The baseline records of `model` grouped by (resolution, point count), each a slice the
/// speed-vs-accuracy and per-pass charts (and the report's Pareto sets) compare: the headline
/// slice (largest resolution and, within it, largest point count) first, then the others by
/// decreasing pixels and points.
pub fn model_slices<'a>(results: &'a Results, model: &str) -> Vec<Vec<&'a Record>> {
    // Keyed by (pixels, points, resolution), so the largest slice comes last.
    type Key = (u64, u64, (u32, u32));
    let mut slices: BTreeMap<Key, Vec<&Record>> = BTreeMap::new();
    for r in baseline(results).filter(|r| r.model == model) {
        slices
            .entry((r.pixels(), r.points, (r.width, r.height)))
            .or_default()
            .push(r);
    }
    slices.into_values().rev().collect()
}

/// Per label (in first-appearance order): the records with that label.
pub(super) fn by_label<'a>(records: &[&'a Record]) -> Vec<(String, Vec<&'a Record>)> {
    let mut out: Vec<(String, Vec<&Record>)> = Vec::new();
    for r in records {
        let label = r.label();
        match out.iter_mut().find(|(l, _)| *l == label) {
            Some((_, group)) => group.push(r),
            None => out.push((label, vec![r])),
        }
    }
    out
}

/// `(label, mean frame ms, mean metric)` per label, skipping labels without a finite metric
/// and the reference ([`Record::is_reference`]), whose accuracy is its own.
pub fn speed_accuracy(
    records: &[&Record],
    metric: impl Fn(&Record) -> Option<f64>,
) -> Vec<(String, f64, f64)> {
    let measured: Vec<&Record> = records
        .iter()
        .copied()
        .filter(|r| !r.is_reference())
        .collect();
    by_label(&measured)
        .into_iter()
        .filter_map(|(label, group)| {
            let ms: Vec<f64> = group.iter().map(|r| r.frame_ms_median).collect();
            let acc: Vec<f64> = group.iter().filter_map(|r| metric(r)).collect();
            Some((label, mean(&ms)?, mean(&acc)?))
        })
        .collect()
}

/// `(label, mean frame ms)` per configuration of the reference among `records`.
pub fn reference_times(records: &[&Record]) -> Vec<(String, f64)> {
    let references: Vec<&Record> = records
        .iter()
        .copied()
        .filter(|r| r.is_reference())
        .collect();
    by_label(&references)
        .into_iter()
        .filter_map(|(label, group)| {
            let ms: Vec<f64> = group.iter().map(|r| r.frame_ms_median).collect();
            Some((label, mean(&ms)?))
        })
        .collect()
}

/// The value of `key` among `records` with the most distinct values of `other`.
pub(super) fn slice_with_most<K: Ord + Copy, O: Ord>(
    records: &[&Record],
    key: impl Fn(&Record) -> K,
    other: impl Fn(&Record) -> O,
) -> Option<K> {
    let mut distinct: BTreeMap<K, std::collections::BTreeSet<O>> = BTreeMap::new();
    for r in records {
        distinct.entry(key(r)).or_default().insert(other(r));
    }
    distinct
        .into_iter()
        .max_by_key(|(_, set)| set.len())
        .map(|(k, _)| k)
}

/// The frame-time interval drawn for `group`, records averaged into one chart point: the mean
/// of their bootstrap 95 % interval bounds (for one record, its interval), over the records
/// with raw samples; `None` when none has them. For several records the span is wider than
/// the interval of their mean, so a bar never understates the noise.
pub(super) fn frame_interval(group: &[&Record]) -> Option<(f64, f64)> {
    let cis: Vec<_> = group.iter().filter_map(|r| r.frame_ci()).collect();
    let lows: Vec<f64> = cis.iter().map(|c| c.low).collect();
    let highs: Vec<f64> = cis.iter().map(|c| c.high).collect();
    Some((mean(&lows)?, mean(&highs)?))
}

/// [`frame_interval`] per label of [`speed_accuracy`]'s points, in their order.
pub(super) fn speed_intervals(
    records: &[&Record],
    points: &[(String, f64, f64)],
) -> Vec<Option<(f64, f64)>> {
    let groups = by_label(records);
    points
        .iter()
        .map(|(label, ..)| {
            groups
                .iter()
                .find(|(l, _)| l == label)
                .and_then(|(_, group)| frame_interval(group))
        })
        .collect()
}

/// The records among `records` timed along a camera path ([`Record::path_times`]), grouped
/// by (pose, resolution, points, lights): for each pose its largest slice (most pixels, then
/// points, then lights) first.
pub(super) fn path_slices<'a>(records: &[&'a Record]) -> Vec<Vec<&'a Record>> {
    type Key<'k> = (&'k str, std::cmp::Reverse<(u64, u64, u32)>, (u32, u32));
    let mut slices: BTreeMap<Key, Vec<&Record>> = BTreeMap::new();
    for r in records
        .iter()
        .filter(|r| !r.path_times.is_empty() && r.path_times.len() == r.frame_samples_ms.len())
    {
        let size = std::cmp::Reverse((r.pixels(), r.points, r.lights));
        slices
            .entry((r.pose.as_str(), size, (r.width, r.height)))
            .or_default()
            .push(r);
    }
    slices.into_values().collect()
}

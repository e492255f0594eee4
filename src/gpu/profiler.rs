//! GPU timestamp profiler: named scopes (render-graph passes) that follow each other without
//! gaps, read back after the frame's fence (one query pool per frame in flight), reported as
//! the median over the last `WINDOW` frames.
//!
//! One timestamp marks each boundary: scope `i` runs from boundary `i` to boundary `i + 1`,
//! and the last boundary ends the frame. Every GPU millisecond of a frame therefore belongs
//! to a named scope and the scopes add up to the frame time. (With a begin/end pair per
//! scope, lavapipe left the tail of a multisampled raster, which its rasterizer threads finish
//! while the next pass's barriers wait, to no scope: 40 % of a `mesh` frame.)

use std::sync::Arc;

use anyhow::Result;
use ash::vk;

use super::Context;

/// Median and spread of one scope's GPU times over the recorded frames.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ScopeStats {
    pub name: String,
    pub median_ms: f64,
    /// Interquartile range (p75 - p25) in milliseconds.
    pub iqr_ms: f64,
    pub samples: usize,
}

/// The raw samples of the recorded frames, oldest first (`Profiler::series`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Series {
    /// Per scope (render-graph pass, in execution order): its name and milliseconds per frame.
    pub scopes: Vec<(String, Vec<f64>)>,
    /// Milliseconds of each whole frame.
    pub frame: Vec<f64>,
    /// Each frame's start on the device's timestamp clock, milliseconds.
    pub starts: Vec<f64>,
    /// With pipeline statistics on, per scope and frame its shader invocations: vertex,
    /// fragment and compute (`STATISTICS`); empty otherwise.
    pub invocations: Vec<[Vec<f64>; 3]>,
}

/// The pipeline statistics counted per scope: vertex, fragment and compute shader
/// invocations.
pub const STATISTICS: [vk::QueryPipelineStatisticFlags; 3] = [
    vk::QueryPipelineStatisticFlags::VERTEX_SHADER_INVOCATIONS,
    vk::QueryPipelineStatisticFlags::FRAGMENT_SHADER_INVOCATIONS,
    vk::QueryPipelineStatisticFlags::COMPUTE_SHADER_INVOCATIONS,
];

/// Pipeline-statistics queries, one per scope and frame slot, and their samples.
struct Statistics {
    pools: Vec<vk::QueryPool>,
    /// Per slot: whether its pool holds a frame recorded with the queries.
    written: Vec<bool>,
    /// Per scope, per counter of `STATISTICS`: the last `WINDOW` frames.
    samples: Vec<[SampleWindow; 3]>,
    /// Reused buffer for query results: one value per counter of each scope.
    raw: Vec<[u64; 3]>,
}

/// Statistics of a sample set: median and interquartile range.
pub fn median_and_iqr(samples: &[f64]) -> (f64, f64) {
    if samples.is_empty() {
        return (0.0, 0.0);
    }
    let mut s = samples.to_vec();
    s.sort_by(f64::total_cmp);
    let q = |p: f64| {
        let x = p * (s.len() - 1) as f64;
        let (lo, hi) = (x.floor() as usize, x.ceil() as usize);
        s[lo] + (s[hi] - s[lo]) * (x - lo as f64)
    };
    (q(0.5), q(0.75) - q(0.25))
}

/// How many of the most recent frames the statistics cover, per scope. A long viewer run keeps
/// collecting timestamps; the window keeps the profiler's memory constant (about 8 KiB per
/// scope) while medians follow the recent frames.
pub const WINDOW: usize = 1024;

/// The last `WINDOW` samples of one scope: a ring whose storage is allocated once, up front,
/// so recording a sample never allocates.
#[derive(Debug)]
pub struct SampleWindow {
    values: Vec<f64>,
    /// Where the next sample goes once the ring is full.
    next: usize,
    last: Option<f64>,
}

impl Default for SampleWindow {
    fn default() -> Self {
        Self {
            values: Vec::with_capacity(WINDOW),
            next: 0,
            last: None,
        }
    }
}

impl SampleWindow {
    /// Records a sample, replacing the oldest one when the window is full.
    pub fn push(&mut self, value: f64) {
        if self.values.len() < WINDOW {
            self.values.push(value);
        } else {
            self.values[self.next] = value;
            self.next = (self.next + 1) % WINDOW;
        }
        self.last = Some(value);
    }

    /// The samples in the window (in no particular order).
    pub fn samples(&self) -> &[f64] {
        &self.values
    }

    /// The samples in the window, oldest first.
    pub fn ordered(&self) -> Vec<f64> {
        let (newer, older) = self.values.split_at(self.next);
        older.iter().chain(newer).copied().collect()
    }

    /// The most recent sample.
    pub fn last(&self) -> Option<f64> {
        self.last
    }

    /// Median and interquartile range over the window.
    pub fn median_and_iqr(&self) -> (f64, f64) {
        median_and_iqr(&self.values)
    }

    /// Forgets every sample (keeps the storage).
    pub fn clear(&mut self) {
        self.values.clear();
        self.next = 0;
        self.last = None;
    }
}

/// Timestamp queries for a fixed list of scopes, one query pool per frame slot: the frame
/// recorded into slot `k` writes slot `k`'s pool, and its results are collected once slot
/// `k`'s fence has been waited on, before the slot is recorded again.
pub struct Profiler {
    ctx: Arc<Context>,
    pools: Vec<vk::QueryPool>,
    /// Per slot: whether its pool holds a submitted frame not yet collected.
    written: Vec<bool>,
    names: Vec<String>,
    /// Per scope, then a final "frame" entry: milliseconds of the last `WINDOW` frames.
    samples: Vec<SampleWindow>,
    /// Each of those frames' first boundary on the device's clock, in milliseconds.
    starts: SampleWindow,
    /// Reused buffer for query results.
    raw: Vec<u64>,
    statistics: Option<Statistics>,
}

impl Profiler {
    /// A profiler for `names` scopes (one boundary query each, plus the frame's end) and
    /// `slots` frames in flight.
    pub fn new(ctx: &Arc<Context>, names: Vec<String>, slots: usize) -> Result<Self> {
        let count = names.len() as u32 + 1;
        let slots = slots.max(1);
        let mut profiler = Self {
            ctx: ctx.clone(),
            pools: Vec::with_capacity(slots),
            written: vec![false; slots],
            // Not `vec![..; n]`: cloning a Vec drops its reserved capacity.
            samples: (0..=names.len()).map(|_| SampleWindow::default()).collect(),
            starts: SampleWindow::default(),
            raw: vec![0; count as usize],
            names,
            statistics: None,
        };
        for _ in 0..slots {
            // SAFETY: valid create info; destroyed in Drop (also on an early return).
            let pool = unsafe {
                ctx.device.create_query_pool(
                    &vk::QueryPoolCreateInfo::default()
                        .query_type(vk::QueryType::TIMESTAMP)
                        .query_count(count),
                    None,
                )?
            };
            profiler.pools.push(pool);
        }
        Ok(profiler)
    }

    /// Counts each scope's shader invocations (`STATISTICS`) beside its time, from the next
    /// frame on. Queries around every pass may perturb the timings they sit beside: an
    /// opt-in. Fails where the device lacks `pipelineStatisticsQuery`.
    pub fn enable_statistics(&mut self) -> Result<()> {
        if !self.ctx.caps.pipeline_statistics {
            anyhow::bail!(
                "{} lacks pipeline statistics queries (pipelineStatisticsQuery)",
                self.ctx.caps.device_name
            );
        }
        if self.statistics.is_some() {
            return Ok(());
        }
        let flags = STATISTICS
            .iter()
            .fold(vk::QueryPipelineStatisticFlags::empty(), |a, &f| a | f);
        let scopes = self.names.len().max(1) as u32;
        let mut statistics = Statistics {
            pools: Vec::with_capacity(self.pools.len()),
            written: vec![false; self.pools.len()],
            samples: (0..self.names.len())
                .map(|_| std::array::from_fn(|_| SampleWindow::default()))
                .collect(),
            raw: vec![[0; 3]; scopes as usize],
        };
        for _ in 0..self.pools.len() {
            // SAFETY: valid create info; destroyed in Drop.
            let pool = unsafe {
                self.ctx.device.create_query_pool(
                    &vk::QueryPoolCreateInfo::default()
                        .query_type(vk::QueryType::PIPELINE_STATISTICS)
                        .pipeline_statistics(flags)
                        .query_count(scopes),
                    None,
                )
            };
            match pool {
                Ok(pool) => statistics.pools.push(pool),
                Err(e) => {
                    for pool in statistics.pools {
                        // SAFETY: created above, never used.
                        unsafe { self.ctx.device.destroy_query_pool(pool, None) };
                    }
                    return Err(e.into());
                }
            }
        }
        self.statistics = Some(statistics);
        Ok(())
    }

    /// Whether pipeline statistics are counted.
    pub fn counts_statistics(&self) -> bool {
        self.statistics.is_some()
    }

    /// Starts counting scope `scope`'s invocations (outside any rendering scope).
    pub fn begin_statistics(&self, cmd: vk::CommandBuffer, slot: usize, scope: usize) {
        if let Some(st) = &self.statistics {
            // SAFETY: the pool was reset in this command buffer; the query is ended by
            // `end_statistics` before the next one begins.
            unsafe {
                self.ctx.device.cmd_begin_query(
                    cmd,
                    st.pools[slot],
                    scope as u32,
                    vk::QueryControlFlags::empty(),
                )
            };
        }
    }

    /// Ends scope `scope`'s count.
    pub fn end_statistics(&self, cmd: vk::CommandBuffer, slot: usize, scope: usize) {
        if let Some(st) = &self.statistics {
            // SAFETY: matches `begin_statistics` in the same command buffer.
            unsafe {
                self.ctx
                    .device
                    .cmd_end_query(cmd, st.pools[slot], scope as u32)
            };
        }
    }

    /// Number of scopes.
    pub fn scopes_len(&self) -> usize {
        self.names.len()
    }

    /// Number of frame slots (query pools).
    pub fn slots(&self) -> usize {
        self.pools.len()
    }

    fn query_count(&self) -> u32 {
        self.raw.len() as u32
    }

    /// Resets slot `slot`'s queries at the start of a frame's command buffer. The slot's
    /// previous frame must have been collected (or be abandoned).
    pub fn reset(&mut self, cmd: vk::CommandBuffer, slot: usize) {
        // SAFETY: cmd is recording, outside a render pass instance; the slot's previous
        // frame has completed (its fence was waited on before re-recording).
        unsafe {
            self.ctx
                .device
                .cmd_reset_query_pool(cmd, self.pools[slot], 0, self.query_count())
        };
        if let Some(st) = &mut self.statistics {
            let scopes = self.names.len().max(1) as u32;
            st.written[slot] = true;
            // SAFETY: as above.
            unsafe {
                self.ctx
                    .device
                    .cmd_reset_query_pool(cmd, st.pools[slot], 0, scopes)
            };
        }
        self.written[slot] = true;
    }

    /// Writes boundary `index` into `slot`'s pool: the start of scope `index`, which ends the
    /// previous scope; `index == scopes` ends the frame. Each boundary is written at most once
    /// per frame.
    pub fn stamp(&self, cmd: vk::CommandBuffer, slot: usize, index: usize) {
        let query = index as u32;
        // SAFETY: query < query_count; the pool was reset earlier in this command buffer.
        unsafe {
            self.ctx.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pools[slot],
                query,
            )
        };
    }

    /// Reads the timestamps of the frame recorded into `slot` (call after that frame's fence)
    /// and records them. Does nothing when the slot holds no uncollected frame. Allocates
    /// nothing.
    pub fn collect(&mut self, slot: usize) -> Result<()> {
        if !std::mem::take(&mut self.written[slot]) || self.names.is_empty() {
            return Ok(());
        }
        // SAFETY: every query was written in the completed command buffer.
        unsafe {
            self.ctx.device.get_query_pool_results(
                self.pools[slot],
                0,
                &mut self.raw,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )?
        };
        let period = f64::from(self.ctx.caps.timestamp_period);
        let ms = |ticks: u64| ticks as f64 * period / 1.0e6;
        let n = self.names.len();
        for i in 0..n {
            let (b, e) = (self.raw[i], self.raw[i + 1]);
            self.samples[i].push(ms(e.saturating_sub(b)));
        }
        let frame = ms(self.raw[n].saturating_sub(self.raw[0]));
        self.samples[n].push(frame);
        self.starts.push(ms(self.raw[0]));
        let recorded = self
            .statistics
            .as_mut()
            .is_some_and(|st| std::mem::take(&mut st.written[slot]));
        if let Some(st) = self.statistics.as_mut().filter(|_| recorded) {
            // SAFETY: every scope's query was begun and ended in the completed command buffer.
            unsafe {
                self.ctx.device.get_query_pool_results(
                    st.pools[slot],
                    0,
                    &mut st.raw,
                    vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
                )?
            };
            for (scope, counts) in st.samples.iter_mut().enumerate() {
                for (k, window) in counts.iter_mut().enumerate() {
                    window.push(st.raw[scope][k] as f64);
                }
            }
        }
        Ok(())
    }

    /// Forgets recorded samples (e.g. after warm-up frames).
    pub fn clear(&mut self) {
        self.samples.iter_mut().for_each(SampleWindow::clear);
        self.starts.clear();
        if let Some(st) = &mut self.statistics {
            st.samples
                .iter_mut()
                .flatten()
                .for_each(SampleWindow::clear);
        }
    }

    /// Every recorded frame (the last `WINDOW`), oldest first: per scope its milliseconds,
    /// the whole frame's, and where each frame started on the device's clock.
    pub fn series(&self) -> Series {
        let n = self.names.len();
        Series {
            scopes: self
                .names
                .iter()
                .zip(&self.samples)
                .map(|(name, s)| (name.clone(), s.ordered()))
                .collect(),
            frame: self.samples[n].ordered(),
            starts: self.starts.ordered(),
            invocations: self.statistics.as_ref().map_or_else(Vec::new, |st| {
                st.samples
                    .iter()
                    .map(|counts| std::array::from_fn(|k| counts[k].ordered()))
                    .collect()
            }),
        }
    }

    /// Per-scope statistics over the last `WINDOW` frames, in scope order.
    pub fn scopes(&self) -> Vec<ScopeStats> {
        self.names
            .iter()
            .zip(&self.samples)
            .map(|(name, s)| stats(name, s))
            .collect()
    }

    /// Whole-frame GPU time (first boundary to the frame's end) over the last `WINDOW`
    /// frames.
    pub fn frame(&self) -> ScopeStats {
        stats("frame", &self.samples[self.names.len()])
    }

    /// The most recently collected frame's per-scope milliseconds.
    pub fn last(&self) -> Vec<(String, f64)> {
        self.names
            .iter()
            .zip(&self.samples)
            .filter_map(|(n, s)| s.last().map(|v| (n.clone(), v)))
            .collect()
    }
}

fn stats(name: &str, s: &SampleWindow) -> ScopeStats {
    let (median_ms, iqr_ms) = s.median_and_iqr();
    ScopeStats {
        name: name.into(),
        median_ms,
        iqr_ms,
        samples: s.samples().len(),
    }
}

impl Drop for Profiler {
    fn drop(&mut self) {
        let statistics = self.statistics.iter().flat_map(|st| &st.pools);
        for &pool in self.pools.iter().chain(statistics) {
            // SAFETY: no pending frame uses the pool (owners wait before dropping).
            unsafe { self.ctx.device.destroy_query_pool(pool, None) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{median_and_iqr, SampleWindow, WINDOW};

    #[test]
    fn median_and_iqr_of_known_samples() {
        assert_eq!(median_and_iqr(&[]), (0.0, 0.0));
        assert_eq!(median_and_iqr(&[3.0]), (3.0, 0.0));
        let (m, iqr) = median_and_iqr(&[5.0, 1.0, 3.0, 2.0, 4.0]);
        assert_eq!(m, 3.0);
        assert_eq!(iqr, 2.0);
    }

    #[test]
    fn sample_window_stays_bounded_and_follows_the_recent_frames() {
        let mut w = SampleWindow::default();
        let capacity = w.values.capacity();
        assert!(capacity >= WINDOW, "storage allocated up front");
        for i in 0..5000 {
            w.push(f64::from(i));
            assert!(w.samples().len() <= WINDOW);
        }
        assert_eq!(w.samples().len(), WINDOW);
        assert_eq!(w.values.capacity(), capacity, "the ring never grows");
        assert_eq!(w.last(), Some(4999.0));
        let ordered: Vec<f64> = (5000 - WINDOW as i32..5000).map(f64::from).collect();
        assert_eq!(w.ordered(), ordered, "oldest first across the wrap");
        // The window holds exactly the last 1024 samples: 3976..=4999.
        let mut kept = w.samples().to_vec();
        kept.sort_by(f64::total_cmp);
        let expected: Vec<f64> = (5000 - WINDOW as i32..5000).map(f64::from).collect();
        assert_eq!(kept, expected);
        let (median, iqr) = w.median_and_iqr();
        assert_eq!(median, (3976.0 + 4999.0) / 2.0);
        assert_eq!(iqr, 0.5 * (WINDOW - 1) as f64);
        w.clear();
        assert!(w.samples().is_empty() && w.last().is_none());
        assert_eq!(w.values.capacity(), capacity, "clearing keeps the storage");
    }
}

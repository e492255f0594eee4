//! GPU timestamp profiler: one begin/end query pair per named scope (render-graph pass), read
//! back after the frame's fence, reported as the median over frames.

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
    pub spread_ms: f64,
    pub samples: usize,
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

/// Timestamp queries for a fixed list of scopes.
pub struct Profiler {
    ctx: Arc<Context>,
    pool: vk::QueryPool,
    names: Vec<String>,
    /// Per scope, then a final "frame" entry: milliseconds per recorded frame.
    samples: Vec<Vec<f64>>,
    written: bool,
}

impl Profiler {
    /// A profiler for `names` scopes (2 queries each).
    pub fn new(ctx: &Arc<Context>, names: Vec<String>) -> Result<Self> {
        let count = (names.len() as u32 * 2).max(2);
        // SAFETY: valid create info; destroyed in Drop.
        let pool = unsafe {
            ctx.device.create_query_pool(
                &vk::QueryPoolCreateInfo::default()
                    .query_type(vk::QueryType::TIMESTAMP)
                    .query_count(count),
                None,
            )?
        };
        let samples = vec![Vec::new(); names.len() + 1];
        Ok(Self {
            ctx: ctx.clone(),
            pool,
            names,
            samples,
            written: false,
        })
    }

    fn query_count(&self) -> u32 {
        (self.names.len() as u32 * 2).max(2)
    }

    /// Resets the queries at the start of a frame's command buffer.
    pub fn reset(&mut self, cmd: vk::CommandBuffer) {
        // SAFETY: cmd is recording, outside a render pass instance.
        unsafe {
            self.ctx
                .device
                .cmd_reset_query_pool(cmd, self.pool, 0, self.query_count())
        };
        self.written = true;
    }

    /// Writes the begin (`end == false`) or end timestamp of scope `index`.
    pub fn stamp(&self, cmd: vk::CommandBuffer, index: usize, end: bool) {
        let query = index as u32 * 2 + u32::from(end);
        // SAFETY: query < query_count; the pool was reset earlier in this command buffer.
        unsafe {
            self.ctx.device.cmd_write_timestamp2(
                cmd,
                vk::PipelineStageFlags2::ALL_COMMANDS,
                self.pool,
                query,
            )
        };
    }

    /// Reads the frame's timestamps (call after the frame's fence) and records them.
    pub fn collect(&mut self) -> Result<()> {
        if !self.written || self.names.is_empty() {
            return Ok(());
        }
        let mut raw = vec![0u64; self.query_count() as usize];
        // SAFETY: every query was written in the completed command buffer.
        unsafe {
            self.ctx.device.get_query_pool_results(
                self.pool,
                0,
                &mut raw,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )?
        };
        let ms = |ticks: u64| ticks as f64 * self.ctx.caps.timestamp_period as f64 / 1.0e6;
        for i in 0..self.names.len() {
            let (b, e) = (raw[2 * i], raw[2 * i + 1]);
            self.samples[i].push(ms(e.saturating_sub(b)));
        }
        let first = raw[0];
        let last = raw[2 * self.names.len() - 1];
        let frame = self.names.len();
        self.samples[frame].push(ms(last.saturating_sub(first)));
        Ok(())
    }

    /// Forgets recorded samples (e.g. after warm-up frames).
    pub fn clear(&mut self) {
        self.samples.iter_mut().for_each(Vec::clear);
    }

    /// Per-scope statistics, in scope order.
    pub fn scopes(&self) -> Vec<ScopeStats> {
        self.names
            .iter()
            .zip(&self.samples)
            .map(|(name, s)| {
                let (median_ms, spread_ms) = median_and_iqr(s);
                ScopeStats {
                    name: name.clone(),
                    median_ms,
                    spread_ms,
                    samples: s.len(),
                }
            })
            .collect()
    }

    /// Whole-frame GPU time (first scope begin to last scope end).
    pub fn frame(&self) -> ScopeStats {
        let s = &self.samples[self.names.len()];
        let (median_ms, spread_ms) = median_and_iqr(s);
        ScopeStats {
            name: "frame".into(),
            median_ms,
            spread_ms,
            samples: s.len(),
        }
    }

    /// The most recent frame's per-scope milliseconds.
    pub fn last(&self) -> Vec<(String, f64)> {
        self.names
            .iter()
            .zip(&self.samples)
            .filter_map(|(n, s)| s.last().map(|v| (n.clone(), *v)))
            .collect()
    }
}

impl Drop for Profiler {
    fn drop(&mut self) {
        // SAFETY: no pending frame uses the pool (owners wait before dropping).
        unsafe { self.ctx.device.destroy_query_pool(self.pool, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::median_and_iqr;

    #[test]
    fn median_and_iqr_of_known_samples() {
        assert_eq!(median_and_iqr(&[]), (0.0, 0.0));
        assert_eq!(median_and_iqr(&[3.0]), (3.0, 0.0));
        let (m, iqr) = median_and_iqr(&[5.0, 1.0, 3.0, 2.0, 4.0]);
        assert_eq!(m, 3.0);
        assert_eq!(iqr, 2.0);
    }
}

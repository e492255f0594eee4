//! Timing studies of one configuration: warm-up and measured frames (`FramePlan`), every raw
//! sample kept (`Study`: per pass and frame, with the median's bootstrap 95 % interval), run
//! metadata (`RunMeta`), a tidy CSV (one row per frame × pass) and a trace in the Chrome
//! trace-event format that Perfetto and chrome://tracing open (GPU passes on one track, the
//! host's recording and submission on another).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use serde::{Deserialize, Serialize};

use super::stats::{median_ci, Estimate};
use crate::gpu::profiler::WINDOW;
use crate::gpu::Context;
use crate::render::{Renderer, TimingSeries};

/// How many frames a measurement renders.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FramePlan {
    /// Frames rendered and discarded first (pipelines, caches and thread pools settle).
    pub warmup: u32,
    /// Frames measured at least.
    pub frames: u32,
    /// Seconds measured at least: frames continue past `frames` until this much wall time
    /// passed (at most `profiler::WINDOW` frames in all).
    pub min_time_s: f64,
}

impl FramePlan {
    /// Fails on a plan the profiler cannot hold.
    pub fn check(&self) -> Result<()> {
        if self.frames == 0 || self.frames as usize > WINDOW {
            bail!(
                "--frames must be 1 to {WINDOW} (the profiler keeps that many), not {}",
                self.frames
            );
        }
        if !(self.min_time_s >= 0.0 && self.min_time_s.is_finite()) {
            bail!(
                "--min-time must be a number of seconds >= 0, not {}",
                self.min_time_s
            );
        }
        Ok(())
    }
}

/// Renders `plan.warmup` frames by `frame(renderer, None)`, forgets their timings, then
/// measures frames by `frame(renderer, Some(i))`, i counting from 0, until both
/// `plan.frames` and `plan.min_time_s` are reached; returns every measured frame's timings.
pub fn measure(
    renderer: &mut Renderer,
    plan: FramePlan,
    mut frame: impl FnMut(&mut Renderer, Option<usize>) -> Result<()>,
) -> Result<TimingSeries> {
    plan.check()?;
    for _ in 0..plan.warmup {
        frame(renderer, None)?;
    }
    renderer.clear_timings();
    let start = Instant::now();
    let mut measured = 0;
    while measured < plan.frames as usize
        || (measured < WINDOW && start.elapsed().as_secs_f64() < plan.min_time_s)
    {
        frame(renderer, Some(measured))?;
        measured += 1;
    }
    Ok(renderer.timing_series())
}

/// What a timing was measured on and with.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RunMeta {
    /// surfel's version and the commit it was built from (`unknown` outside a git checkout).
    pub version: String,
    pub commit: String,
    pub device: String,
    pub driver: String,
    pub vulkan: String,
    /// The CPU model (`/proc/cpuinfo`) and its logical cores.
    pub cpu: String,
    pub cores: usize,
    /// The operating system and kernel.
    pub os: String,
    /// How frames reach the screen: `headless` for `render` and `bench`.
    pub present_mode: String,
    pub method: String,
    pub width: u32,
    pub height: u32,
    pub points: u64,
}

impl RunMeta {
    /// The metadata of a headless run of `method` on `ctx`.
    pub fn headless(ctx: &Context, method: &str, (width, height): (u32, u32), points: u64) -> Self {
        Self {
            version: env!("CARGO_PKG_VERSION").into(),
            commit: env!("SURFEL_COMMIT").into(),
            device: ctx.caps.device_name.clone(),
            driver: ctx.caps.driver.clone(),
            vulkan: ctx.caps.api_version.clone(),
            cpu: cpu_model(),
            cores: std::thread::available_parallelism().map_or(1, usize::from),
            os: os_name(),
            present_mode: "headless".into(),
            method: method.into(),
            width,
            height,
            points,
        }
    }
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| std::env::consts::ARCH.into())
}

fn os_name() -> String {
    let name = std::fs::read_to_string("/etc/os-release")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("PRETTY_NAME="))
                .map(|v| v.trim_matches('"').to_string())
        });
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .ok()
        .map(|k| k.trim().to_string());
    match (name, kernel) {
        (Some(n), Some(k)) => format!("{n}, Linux {k}"),
        (Some(n), None) => n,
        (None, Some(k)) => format!("Linux {k}"),
        (None, None) => std::env::consts::OS.into(),
    }
}

/// One pass's (or the whole frame's) measured milliseconds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PassSummary {
    pub name: String,
    /// The median and its bootstrap 95 % interval.
    pub median_ms: f64,
    pub ci_low_ms: f64,
    pub ci_high_ms: f64,
    /// Interquartile range.
    pub iqr_ms: f64,
    /// Measured frames.
    pub frames: usize,
    /// Every measured frame's milliseconds, in order.
    pub samples_ms: Vec<f64>,
}

impl PassSummary {
    pub fn of(name: &str, samples: &[f64]) -> Self {
        let Estimate { value, low, high } = median_ci(samples);
        Self {
            name: name.into(),
            median_ms: value,
            ci_low_ms: low,
            ci_high_ms: high,
            iqr_ms: crate::gpu::profiler::median_and_iqr(samples).1,
            frames: samples.len(),
            samples_ms: samples.to_vec(),
        }
    }
}

/// A measured configuration: its metadata, plan, passes and frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Study {
    pub meta: RunMeta,
    pub plan: FramePlan,
    /// GPU time per pass, in execution order.
    pub passes: Vec<PassSummary>,
    /// GPU time of the whole frame.
    pub frame: PassSummary,
    /// Host milliseconds recording and submitting each frame.
    pub cpu_record: PassSummary,
    pub cpu_submit: PassSummary,
    /// With `--pipeline-stats`: each pass's median shader invocations per frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub invocations: Vec<Invocations>,
}

/// One pass's median shader invocations per frame (pipeline statistics).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Invocations {
    pub name: String,
    pub vertex: f64,
    pub fragment: f64,
    pub compute: f64,
}

impl Invocations {
    /// Each pass's median invocations over the measured frames (empty without pipeline
    /// statistics).
    pub fn of(series: &TimingSeries) -> Vec<Self> {
        series
            .gpu
            .scopes
            .iter()
            .zip(&series.gpu.invocations)
            .map(|((name, _), [vertex, fragment, compute])| Invocations {
                name: name.clone(),
                vertex: super::stats::median(vertex),
                fragment: super::stats::median(fragment),
                compute: super::stats::median(compute),
            })
            .collect()
    }
}

impl Study {
    pub fn new(meta: RunMeta, plan: FramePlan, series: &TimingSeries) -> Self {
        Self {
            meta,
            plan,
            passes: series
                .gpu
                .scopes
                .iter()
                .map(|(name, s)| PassSummary::of(name, s))
                .collect(),
            frame: PassSummary::of("frame", &series.gpu.frame),
            cpu_record: PassSummary::of("record", &series.cpu_record),
            cpu_submit: PassSummary::of("submit", &series.cpu_submit),
            invocations: Invocations::of(series),
        }
    }

    /// The tidy table: `frame,pass,ms`, one row per measured frame and pass.
    pub fn csv(&self) -> String {
        let mut out = String::from("frame,pass,ms\n");
        for p in &self.passes {
            for (i, ms) in p.samples_ms.iter().enumerate() {
                out.push_str(&format!("{i},{},{ms}\n", p.name));
            }
        }
        out
    }
}

/// Where a timed run writes what it measured (`--timings`, `--timings-csv`, `--trace`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Outputs {
    /// The JSON: the study and what the run adds to it.
    pub json: Option<PathBuf>,
    /// The tidy CSV ([`Study::csv`]).
    pub csv: Option<PathBuf>,
    /// The trace ([`trace`]).
    pub trace: Option<PathBuf>,
}

impl Outputs {
    /// Whether any output was asked for.
    pub fn any(&self) -> bool {
        self.json.is_some() || self.csv.is_some() || self.trace.is_some()
    }

    /// Writes `json`, the study's CSV and the trace of `series` where asked, and prints each
    /// pass's median with its interval.
    pub fn write(
        &self,
        json: &serde_json::Value,
        study: &Study,
        series: &TimingSeries,
    ) -> Result<()> {
        if let Some(path) = &self.json {
            write(path, &serde_json::to_string_pretty(json)?)?;
        }
        if let Some(path) = &self.csv {
            write(path, &study.csv())?;
        }
        if let Some(path) = &self.trace {
            write(
                path,
                &serde_json::to_string(&trace(&study.meta.method, series))?,
            )?;
        }
        for p in study.passes.iter().chain([&study.frame]) {
            eprintln!(
                "{:<24} {:>9.3} ms (95 % CI {:.3}-{:.3}, IQR {:.3}, {} frames)",
                p.name, p.median_ms, p.ci_low_ms, p.ci_high_ms, p.iqr_ms, p.frames
            );
        }
        for i in &study.invocations {
            eprintln!(
                "{:<24} invocations: {} vertex, {} fragment, {} compute",
                i.name, i.vertex, i.fragment, i.compute
            );
        }
        Ok(())
    }
}

/// Writes `text` to `path`, naming the file in the error.
pub fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("{}: cannot write", path.display()))
}

/// The Chrome trace-event JSON of `series` for `label`: per frame one GPU slice per pass (a
/// pass starts where the previous one ended: the profiler's scopes follow each other), placed
/// at the frame's start on the device clock, and the host's `record` and `submit` slices.
/// Where the device calibrates its clock against the host's (`gpu_to_host_ms`), both tracks
/// share one time line, starting at the first event, and `otherData.clocks` says
/// `calibrated`; elsewhere each track starts at 0 and it says `separate`.
pub fn trace(label: &str, series: &TimingSeries) -> serde_json::Value {
    let us = |ms: f64| ms * 1e3;
    let first = |v: &[f64]| v.first().copied().unwrap_or(0.0);
    let (gpu0, cpu0) = match series.gpu_to_host_ms {
        Some(offset) => {
            let t0 = first(&series.cpu_starts).min(first(&series.gpu.starts) + offset);
            (t0 - offset, t0)
        }
        None => (first(&series.gpu.starts), first(&series.cpu_starts)),
    };
    let mut events = vec![
        serde_json::json!({"name": "process_name", "ph": "M", "pid": 1,
            "args": {"name": format!("surfel {label}")}}),
        serde_json::json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": 1,
            "args": {"name": "GPU"}}),
        serde_json::json!({"name": "thread_name", "ph": "M", "pid": 1, "tid": 2,
            "args": {"name": "CPU record/submit"}}),
    ];
    for (f, start) in series.gpu.starts.iter().enumerate() {
        let mut at = start - gpu0;
        for (name, samples) in &series.gpu.scopes {
            let Some(&ms) = samples.get(f) else { continue };
            events.push(
                serde_json::json!({"name": name, "cat": "gpu", "ph": "X", "pid": 1,
                "tid": 1, "ts": us(at), "dur": us(ms), "args": {"frame": f}}),
            );
            at += ms;
        }
    }
    for (f, start) in series.cpu_starts.iter().enumerate() {
        let at = start - cpu0;
        let record = series.cpu_record.get(f).copied().unwrap_or(0.0);
        events.push(
            serde_json::json!({"name": "record", "cat": "cpu", "ph": "X", "pid": 1,
            "tid": 2, "ts": us(at), "dur": us(record), "args": {"frame": f}}),
        );
        if let Some(&submit) = series.cpu_submit.get(f) {
            events.push(
                serde_json::json!({"name": "submit", "cat": "cpu", "ph": "X",
                "pid": 1, "tid": 2, "ts": us(at + record), "dur": us(submit),
                "args": {"frame": f}}),
            );
        }
    }
    let clocks = if series.gpu_to_host_ms.is_some() {
        "calibrated"
    } else {
        "separate"
    };
    serde_json::json!({"traceEvents": events, "displayTimeUnit": "ms",
        "otherData": {"clocks": clocks}})
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::Series;

    fn series() -> TimingSeries {
        TimingSeries {
            gpu: Series {
                scopes: vec![
                    ("a".into(), vec![1.0, 2.0, 3.0]),
                    ("b".into(), vec![0.5, 0.5, 0.5]),
                ],
                frame: vec![1.5, 2.5, 3.5],
                starts: vec![100.0, 110.0, 120.0],
                invocations: Vec::new(),
            },
            cpu_starts: vec![5.0, 15.0, 25.0],
            cpu_record: vec![0.1, 0.1, 0.1],
            cpu_submit: vec![0.2, 0.2, 0.2],
            gpu_to_host_ms: None,
        }
    }

    #[test]
    fn the_csv_holds_one_row_per_frame_and_pass() {
        let meta = RunMeta {
            version: "0".into(),
            commit: "c".into(),
            device: "d".into(),
            driver: "r".into(),
            vulkan: "1.4".into(),
            cpu: "x".into(),
            cores: 1,
            os: "o".into(),
            present_mode: "headless".into(),
            method: "points".into(),
            width: 1,
            height: 1,
            points: 1,
        };
        let plan = FramePlan {
            warmup: 0,
            frames: 3,
            min_time_s: 0.0,
        };
        let study = Study::new(meta, plan, &series());
        let csv = study.csv();
        let rows: Vec<&str> = csv.lines().collect();
        assert_eq!(rows.len(), 1 + 3 * 2);
        assert_eq!(rows[0], "frame,pass,ms");
        assert_eq!(rows[3], "2,a,3");
        assert_eq!(study.passes[0].median_ms, 2.0);
        assert_eq!(study.frame.frames, 3);
    }

    #[test]
    fn trace_slices_follow_each_other_within_a_frame() {
        let t = trace("points", &series());
        let slices: Vec<&serde_json::Value> = t["traceEvents"]
            .as_array()
            .expect("events")
            .iter()
            .filter(|e| e["cat"] == "gpu")
            .collect();
        assert_eq!(slices.len(), 6);
        // Frame 1 starts 10 ms after frame 0; its pass b starts after its pass a (2 ms).
        assert_eq!(slices[2]["ts"], 10_000.0);
        assert_eq!(slices[3]["ts"], 12_000.0);
        assert_eq!(slices[3]["dur"], 500.0);
        assert_eq!(t["otherData"]["clocks"], "separate");
        // Calibrated: the GPU's 100 ms is the host's 6 ms, 1 ms after the first record.
        let calibrated = trace(
            "points",
            &TimingSeries {
                gpu_to_host_ms: Some(-94.0),
                ..series()
            },
        );
        let events = calibrated["traceEvents"].as_array().expect("events");
        let first = |cat: &str| events.iter().find(|e| e["cat"] == cat).expect(cat)["ts"].clone();
        assert_eq!((first("cpu"), first("gpu")), (0.0.into(), 1_000.0.into()));
        assert_eq!(calibrated["otherData"]["clocks"], "calibrated");
        let plan = FramePlan {
            warmup: 0,
            frames: 0,
            min_time_s: 0.0,
        };
        assert!(plan.check().is_err());
    }
}

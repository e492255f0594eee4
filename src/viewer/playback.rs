//! A camera path played in the viewer (`surfel view FILE --path PATH`): warm-up frames at the
//! path's first pose, then one timed frame per path frame, presented as any viewer frame
//! is. The timings are the study `render --path` writes (with the swapchain's present mode
//! in its metadata); where outputs were asked for, the viewer quits after the flight, else
//! the HUD reports it and `A` plays it again. A rebuilt renderer (a resize, a method switch)
//! restarts the flight, since its timings start anew.

use anyhow::{Context as _, Result};

use super::orbit::Orbit;
use super::Viewer;
use crate::eval::stats::median_ci;
use crate::eval::timing::{FramePlan, Outputs, RunMeta, Study};
use crate::scene::Camera;

/// The present mode of the viewer's swapchain (`gpu::swapchain`), recorded with its timings.
const PRESENT_MODE: &str = "fifo";

/// A camera path to play: the camera and path time of every frame, the warm-up and where the
/// timings go.
#[derive(Clone, Debug)]
pub struct PathPlay {
    pub cameras: Vec<Camera>,
    pub times: Vec<f64>,
    pub warmup: u32,
    pub outputs: Outputs,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Warm-up frames rendered so far.
    Warmup(u32),
    /// The path frame rendered next.
    Timed(usize),
    Done,
}

/// A path being played.
pub(super) struct Playback {
    play: PathPlay,
    phase: Phase,
}

/// What the viewer does once a frame of the path was submitted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Step {
    Continue,
    /// The last path frame was submitted: collect and write the timings.
    Finished,
}

impl Playback {
    pub(super) fn new(play: PathPlay) -> Self {
        Self {
            play,
            phase: Phase::Warmup(0),
        }
    }

    /// Plays the path again from its warm-up.
    pub(super) fn restart(&mut self) {
        self.phase = Phase::Warmup(0);
    }

    /// Restarts a flight whose timed frames began (the renderer's timings start anew).
    pub(super) fn restart_if_timing(&mut self) {
        if matches!(self.phase, Phase::Timed(_)) {
            self.restart();
        }
    }

    /// Before a frame: whether timing starts with it (the caller waits for the warm-up
    /// frames and forgets their timings).
    fn starts_timing(&mut self) -> bool {
        match self.phase {
            Phase::Warmup(n) if n >= self.play.warmup => {
                self.phase = Phase::Timed(0);
                true
            }
            _ => false,
        }
    }

    /// The camera of the next frame; `None` once the path was played.
    fn camera(&self) -> Option<Camera> {
        match self.phase {
            Phase::Warmup(_) => self.play.cameras.first().copied(),
            Phase::Timed(i) => self.play.cameras.get(i).copied(),
            Phase::Done => None,
        }
    }

    /// After a frame was submitted.
    fn advance(&mut self) -> Step {
        match self.phase {
            Phase::Warmup(n) => self.phase = Phase::Warmup(n + 1),
            Phase::Timed(i) if i + 1 >= self.play.cameras.len() => {
                self.phase = Phase::Done;
                return Step::Finished;
            }
            Phase::Timed(i) => self.phase = Phase::Timed(i + 1),
            Phase::Done => {}
        }
        Step::Continue
    }
}

impl Viewer {
    /// The camera of the next frame: the path's while one plays, else the orbit's. Called
    /// before the frame begins; when timing starts with it, waits for the warm-up frames and
    /// forgets their timings.
    pub(super) fn next_camera(&mut self) -> Result<Camera> {
        let Some(playback) = self.playback.as_mut() else {
            return Ok(self.orbit.camera());
        };
        if playback.starts_timing() {
            if let Some(gpu) = self.gpu.as_mut() {
                gpu.renderer.finish()?;
                gpu.renderer.clear_timings();
            }
        }
        Ok(playback.camera().unwrap_or_else(|| self.orbit.camera()))
    }

    /// After a frame was submitted: steps the path, and after its last frame writes the
    /// timings and leaves the camera at the path's end.
    pub(super) fn path_frame_done(&mut self) -> Result<()> {
        let Some(playback) = self.playback.as_mut() else {
            return Ok(());
        };
        if playback.advance() != Step::Finished {
            return Ok(());
        }
        let play = playback.play.clone();
        if let Some(last) = play.cameras.last() {
            self.orbit = Orbit::from_camera(last, self.opts.up);
        }
        let (width, height) = self.size();
        let label = self.config().label();
        let points = self.scene.drawn().map_or(0, |(_, info)| info.points);
        let ctx = self.ctx.clone().context("context")?;
        let gpu = self.gpu.as_mut().context("no window")?;
        gpu.renderer.finish()?;
        let series = gpu.renderer.timing_series();
        let plan = FramePlan {
            warmup: play.warmup,
            frames: play.cameras.len() as u32,
            min_time_s: 0.0,
        };
        let meta = RunMeta {
            present_mode: PRESENT_MODE.into(),
            ..RunMeta::headless(&ctx, &label, (width, height), points.into())
        };
        let study = Study::new(meta, plan, &series);
        let mut json = serde_json::to_value(&study)?;
        json["path_times"] = serde_json::to_value(&play.times)?;
        play.outputs.write(&json, &study, &series)?;
        let ci = median_ci(&study.frame.samples_ms);
        self.outcome(Ok(format!(
            "path: {} frames, GPU {:.3} ms per frame [95 % CI {:.3}, {:.3}]",
            study.frame.frames, ci.value, ci.low, ci.high
        )))?;
        if play.outputs.any() {
            self.quit = true;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn play(frames: usize, warmup: u32) -> Playback {
        let camera = |i: usize| Camera {
            eye: glam::Vec3::new(i as f32, 0.0, 5.0),
            ..Camera::framing(glam::Vec3::ZERO, 1.0)
        };
        Playback::new(PathPlay {
            cameras: (0..frames).map(camera).collect(),
            times: (0..frames).map(|i| i as f64).collect(),
            warmup,
            outputs: Outputs::default(),
        })
    }

    /// Plays `p` to its end: per frame, whether timing started and the camera's eye x.
    fn flight(p: &mut Playback) -> Vec<(bool, f32)> {
        let mut frames = Vec::new();
        loop {
            let started = p.starts_timing();
            let Some(camera) = p.camera() else {
                return frames;
            };
            frames.push((started, camera.eye.x));
            if p.advance() == Step::Finished {
                assert_eq!(p.camera(), None);
                return frames;
            }
        }
    }

    #[test]
    fn warm_up_at_the_first_pose_then_one_timed_frame_per_path_frame() {
        let mut p = play(3, 2);
        let expected = [
            (false, 0.0),
            (false, 0.0),
            (true, 0.0),
            (false, 1.0),
            (false, 2.0),
        ];
        assert_eq!(flight(&mut p), expected);
        p.restart();
        assert_eq!(flight(&mut p), expected);
        assert_eq!(flight(&mut play(2, 0)), [(true, 0.0), (false, 1.0)]);
    }

    #[test]
    fn a_rebuild_while_timing_restarts_the_flight() {
        let mut p = play(3, 1);
        p.restart_if_timing();
        assert_eq!(p.phase, Phase::Warmup(0));
        p.advance();
        assert!(p.starts_timing());
        p.advance();
        p.restart_if_timing();
        assert_eq!(p.phase, Phase::Warmup(0));
    }
}

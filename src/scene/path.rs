//! Camera paths: keyframes of camera poses over time (orbits, whose `distance` zooms, or
//! eye/target fly-throughs), sampled at `frames` evenly spaced times from the first key to the
//! last. `surfel render --path` renders and times every frame along it, as viewers are
//! compared on a scripted flight.
//!
//! ```toml
//! frames = 60
//! [[keys]]
//! time = 0.0
//! camera = { orbit = [0.0, 15.0] }
//! [[keys]]
//! time = 2.0
//! camera = { orbit = [90.0, 30.0], distance = 0.5 }
//! ```
//!
//! Between two orbit keys the azimuth, elevation and distance are interpolated linearly (the
//! camera circles and zooms); between any other two keys the eye and target of their cameras
//! are (a straight flight). The first frame is the first key's pose and the last frame the
//! last key's.

use std::path::Path;

use anyhow::{bail, Context as _, Result};
use serde::{Deserialize, Serialize};

use super::camera::{Camera, Pose};

/// One keyframe.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Key {
    /// Seconds (or any unit) along the path; keys ascend.
    pub time: f64,
    pub camera: Pose,
}

/// A camera path: its keys and how many frames sample it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPath {
    /// Frames rendered along the path (at least 2).
    #[serde(default = "default_frames")]
    pub frames: u32,
    pub keys: Vec<Key>,
}

fn default_frames() -> u32 {
    60
}

/// The most frames a path renders (what the profiler keeps per run).
pub const MAX_FRAMES: u32 = 1024;

impl CameraPath {
    /// Reads a path file (TOML).
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("{}: cannot read camera path", path.display()))?;
        Self::parse(&text).with_context(|| format!("{}: invalid camera path", path.display()))
    }

    /// Parses and checks a path: at least two keys at finite, strictly increasing times, every
    /// pose one a camera can take, 2 to `MAX_FRAMES` frames.
    pub fn parse(text: &str) -> Result<Self> {
        let path: Self = toml::from_str(text)?;
        if path.keys.len() < 2 {
            bail!("a path needs at least two keys, found {}", path.keys.len());
        }
        if !(2..=MAX_FRAMES).contains(&path.frames) {
            bail!("frames must be 2 to {MAX_FRAMES}, not {}", path.frames);
        }
        for (i, k) in path.keys.iter().enumerate() {
            if !k.time.is_finite() {
                bail!("key {}: time {} is not finite", i + 1, k.time);
            }
            k.camera
                .check()
                .map_err(|e| anyhow::anyhow!("key {}: {e}", i + 1))?;
        }
        if let Some(w) = path.keys.windows(2).position(|w| w[1].time <= w[0].time) {
            bail!(
                "key {}: time {} does not follow {} (keys ascend in time)",
                w + 2,
                path.keys[w + 1].time,
                path.keys[w].time
            );
        }
        Ok(path)
    }

    /// The time of every frame, first key to last.
    pub fn times(&self) -> Vec<f64> {
        let (t0, t1) = (self.keys[0].time, self.keys[self.keys.len() - 1].time);
        let last = f64::from(self.frames - 1);
        (0..self.frames)
            .map(|i| t0 + (t1 - t0) * f64::from(i) / last)
            .collect()
    }

    /// The camera at `time`, each pose made a camera by `camera` (the scene's framing).
    pub fn camera_at(&self, time: f64, camera: &dyn Fn(&Pose) -> Camera) -> Camera {
        let next = self
            .keys
            .iter()
            .position(|k| k.time >= time)
            .unwrap_or(self.keys.len() - 1)
            .max(1);
        let (a, b) = (&self.keys[next - 1], &self.keys[next]);
        let s = ((time - a.time) / (b.time - a.time)).clamp(0.0, 1.0) as f32;
        match (a.camera, b.camera) {
            (
                Pose::Orbit {
                    orbit: oa,
                    distance: da,
                },
                Pose::Orbit {
                    orbit: ob,
                    distance: db,
                },
            ) => camera(&Pose::Orbit {
                orbit: [oa[0] + (ob[0] - oa[0]) * s, oa[1] + (ob[1] - oa[1]) * s],
                distance: da + (db - da) * s,
            }),
            _ => {
                let (ca, cb) = (camera(&a.camera), camera(&b.camera));
                Camera {
                    eye: ca.eye.lerp(cb.eye, s),
                    target: ca.target.lerp(cb.target, s),
                    near: ca.near + (cb.near - ca.near) * s,
                    ..ca
                }
            }
        }
    }

    /// The camera of every frame.
    pub fn cameras(&self, camera: &dyn Fn(&Pose) -> Camera) -> Vec<Camera> {
        self.times()
            .into_iter()
            .map(|t| self.camera_at(t, camera))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::camera::Up;
    use glam::Vec3;

    fn frame(pose: &Pose) -> Camera {
        pose.camera(Vec3::ZERO, 1.0, Up::Y, glam::DVec3::ZERO)
    }

    #[test]
    fn frames_start_and_end_at_the_keys_and_orbits_interpolate_their_angles() {
        let path = CameraPath::parse(
            "frames = 5\n[[keys]]\ntime = 0\ncamera = { orbit = [0.0, 10.0] }\n\
             [[keys]]\ntime = 2\ncamera = { orbit = [80.0, 30.0], distance = 0.5 }\n",
        )
        .expect("path");
        assert_eq!(path.times(), [0.0, 0.5, 1.0, 1.5, 2.0]);
        let cameras = path.cameras(&frame);
        let orbit = |az, el, distance| {
            frame(&Pose::Orbit {
                orbit: [az, el],
                distance,
            })
        };
        assert_eq!(cameras[0], orbit(0.0, 10.0, 1.0));
        assert_eq!(cameras[2], orbit(40.0, 20.0, 0.75));
        assert_eq!(cameras[4], orbit(80.0, 30.0, 0.5));
    }

    #[test]
    fn fly_throughs_move_the_eye_in_a_straight_line() {
        let path = CameraPath::parse(
            "frames = 3\n[[keys]]\ntime = 0\ncamera = { eye = [0, 0, 4], target = [0, 0, 0] }\n\
             [[keys]]\ntime = 1\ncamera = { eye = [2, 0, 4], target = [2, 0, 0] }\n",
        )
        .expect("path");
        let mid = path.cameras(&frame)[1];
        assert!((mid.eye - Vec3::new(1.0, 0.0, 4.0)).length() < 1e-6);
        assert!((mid.target - Vec3::new(1.0, 0.0, 0.0)).length() < 1e-6);
    }

    #[test]
    fn bad_paths_say_what_is_wrong() {
        let err = |text: &str| format!("{:#}", CameraPath::parse(text).unwrap_err());
        let key = |t: f64| format!("[[keys]]\ntime = {t}\ncamera = {{ orbit = [0.0, 0.0] }}\n");
        assert!(err(&key(0.0)).contains("at least two keys"));
        assert!(err(&format!("{}{}", key(1.0), key(1.0))).contains("key 2: time 1"));
        assert!(err(&format!("frames = 1\n{}{}", key(0.0), key(1.0))).contains("frames must be"));
        assert!(err(
            "[[keys]]\ntime = 0\ncamera = { orbit = [0.0, 0.0], distance = -1 }\n\
                     [[keys]]\ntime = 1\ncamera = { orbit = [0.0, 0.0] }\n"
        )
        .contains("key 1"));
        assert!(err("frames = 3\nspeed = 2\n").contains("unknown field"));
    }
}

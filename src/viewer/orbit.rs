//! The viewer's orbit camera: a target, a distance and two angles about the up axis, turned by
//! a left drag, panned by a right drag, zoomed by the wheel, and the home pose `R` returns to.

use glam::{Vec2, Vec3};

use crate::scene::camera::{orbit_angles, orbit_direction};
use crate::scene::{Camera, Up};

/// The elevation a drag or a script's `orbit` step stops at (radians, just short of the pole).
const MAX_ELEVATION: f32 = 1.55;

/// Orbit state around a target: azimuth around `up`, elevation towards it (radians).
pub struct Orbit {
    pub target: Vec3,
    pub distance: f32,
    pub azimuth: f32,
    pub elevation: f32,
    pub up: Up,
    /// The pose the orbit started from (`R` returns to it).
    pub home: Camera,
}

impl Orbit {
    pub fn from_camera(c: &Camera, up: Up) -> Self {
        let d = c.eye - c.target;
        let (azimuth, elevation) = orbit_angles(up, d);
        Self {
            target: c.target,
            distance: d.length().max(1e-6),
            azimuth,
            elevation,
            up,
            home: *c,
        }
    }

    /// The camera at the current angles: the up axis points up, except while looking straight
    /// along it (a home pose at ±90°, before any vertical drag), which keeps the home up vector.
    pub fn camera(&self) -> Camera {
        let dir = orbit_direction(self.up, self.azimuth, self.elevation);
        let along_axis = (self.elevation.abs() - std::f32::consts::FRAC_PI_2).abs() < 1e-4;
        Camera {
            eye: self.target + dir * self.distance,
            target: self.target,
            up: if along_axis {
                self.home.up
            } else {
                self.up.vector()
            },
            ..self.home
        }
    }

    /// Orbits from `camera`, keeping the up axis and the home pose.
    pub fn look(&mut self, camera: &Camera) {
        let home = self.home;
        *self = Self::from_camera(camera, self.up);
        self.home = home;
    }

    /// Back to the home pose (`R`).
    pub fn reset(&mut self) {
        *self = Self::from_camera(&self.home, self.up);
    }

    /// A left drag of `delta` pixels: turns about the up axis and tilts towards it.
    pub fn turn(&mut self, delta: Vec2) {
        self.azimuth -= delta.x * 0.01;
        self.elevation = (self.elevation + delta.y * 0.01).clamp(-MAX_ELEVATION, MAX_ELEVATION);
    }

    /// Sets the angles (degrees), the elevation short of the poles (a script's `orbit` step).
    pub fn set_angles(&mut self, azimuth: f32, elevation: f32) {
        self.azimuth = azimuth.to_radians();
        self.elevation = elevation.to_radians().clamp(-MAX_ELEVATION, MAX_ELEVATION);
    }

    /// A right drag of `delta` pixels in a window `height` pixels high: moves the target with
    /// the image.
    pub fn pan(&mut self, delta: Vec2, height: f32) {
        let c = self.camera();
        let forward = (c.target - c.eye).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(c.up).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let scale = 2.0 * self.distance * (c.fov_y * 0.5).tan() / height.max(1.0);
        self.target += (-right * delta.x + up * delta.y) * scale;
    }

    /// The wheel: each line up brings the eye 10 % closer.
    pub fn zoom(&mut self, lines: f32) {
        self.distance *= 0.9f32.powf(lines);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drag_orbit_turns_about_the_up_axis_and_resets_home() {
        for up in [Up::Y, Up::Z] {
            let home = Camera::orbit_about(up, Vec3::ONE, 2.0, 30.0, 35.0, 1.0);
            let mut orbit = Orbit::from_camera(&home, up);
            let start = orbit.camera();
            assert!((start.eye - home.eye).length() < 1e-4, "{up}");
            assert_eq!(start.up, home.up);
            orbit.azimuth += 1.0;
            let turned = orbit.camera();
            let axis = up.vector();
            let expected =
                Vec3::ONE + glam::Quat::from_axis_angle(axis, 1.0) * (home.eye - Vec3::ONE);
            assert!(
                (turned.eye - expected).length() < 1e-4,
                "{up}: {}",
                turned.eye
            );
            assert_eq!(turned.up, axis);
            orbit.reset();
            assert_eq!(orbit.camera().eye, start.eye);
        }
        // Down from straight above a z-up scene, then to the horizon: +z stays up in the image.
        let top = Camera::orbit_about(Up::Z, Vec3::ZERO, 1.0, 0.0, 90.0, 1.0);
        let mut orbit = Orbit::from_camera(&top, Up::Z);
        assert_eq!(orbit.camera().up, top.up);
        orbit.azimuth = 1.5;
        orbit.elevation = 0.0;
        assert_eq!(orbit.camera().up, Vec3::Z);
    }
}

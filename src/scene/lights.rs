//! Lights (002 §4): attached to the camera, static in the world, or orbiting the model.

use glam::{Mat4, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use super::Up;
use crate::layout::{GpuLight, LIGHT_CAMERA, LIGHT_ORBIT, LIGHT_STATIC, MAX_LIGHTS};

/// Where a light lives.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LightKind {
    /// Offset from the eye in view space (a headlight at `[0, 0, 0]`).
    Camera,
    /// Fixed world position.
    Static,
    /// Circles the model centre in the plane perpendicular to the data's up axis at
    /// `position[0]` scene radii and height `position[1]` radii along the up axis,
    /// `position[2]` degrees per second.
    Orbit,
}

/// One light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Light {
    pub kind: LightKind,
    #[serde(default)]
    pub position: [f32; 3],
    #[serde(default = "white")]
    pub color: [f32; 3],
}

fn white() -> [f32; 3] {
    [1.0; 3]
}

impl Light {
    /// The default headlight.
    pub fn headlight() -> Self {
        Self {
            kind: LightKind::Camera,
            position: [0.0; 3],
            color: white(),
        }
    }
}

/// `count` lights spread on a ring around the camera (for the light-count sweeps of 002 ch. 6);
/// intensities divided so the total stays that of one light.
pub fn ring(count: u32, radius: f32) -> Vec<Light> {
    (0..count)
        .map(|i| {
            let a = i as f32 / count.max(1) as f32 * std::f32::consts::TAU;
            Light {
                kind: LightKind::Camera,
                position: [a.cos() * radius, a.sin() * radius, 0.0],
                color: [1.0 / count.max(1) as f32; 3],
            }
        })
        .collect()
}

/// The lights of the light-count sweeps (002 ch. 6) and of the viewer's digit keys: none, the
/// headlight, or a ring of `count` camera lights (`ring`).
pub fn sweep(count: u32, radius: f32) -> Vec<Light> {
    match count {
        0 => Vec::new(),
        1 => vec![Light::headlight()],
        n => ring(n, radius),
    }
}

/// Resolves lights to view space for a frame at `time` seconds; orbiting lights circle `up`.
/// At most `MAX_LIGHTS`.
pub fn resolve(
    lights: &[Light],
    view: Mat4,
    (centre, radius): (Vec3, f32),
    up: Up,
    time: f32,
) -> impl Iterator<Item = GpuLight> + '_ {
    let (u, front) = (up.vector(), up.front());
    let right = u.cross(front);
    lights.iter().take(MAX_LIGHTS as usize).map(move |l| {
        let p = Vec3::from(l.position);
        let (view_pos, kind) = match l.kind {
            LightKind::Camera => (p, LIGHT_CAMERA),
            LightKind::Static => (view.transform_point3(p), LIGHT_STATIC),
            LightKind::Orbit => {
                let angle = (p.z * time).to_radians();
                let world = centre
                    + (right * angle.cos() + front * angle.sin()) * (p.x * radius)
                    + u * (p.y * radius);
                (view.transform_point3(world), LIGHT_ORBIT)
            }
        };
        GpuLight {
            position: view_pos.extend(1.0),
            color_kind: Vec4::new(l.color[0], l.color[1], l.color[2], kind as f32),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_lights_stay_in_view_space_and_static_ones_move_with_the_view() {
        let view = Mat4::from_translation(Vec3::new(0.0, 0.0, -5.0));
        let lights = [
            Light::headlight(),
            Light {
                kind: LightKind::Static,
                position: [1.0, 0.0, 0.0],
                color: [1.0; 3],
            },
        ];
        let g: Vec<_> = resolve(&lights, view, (Vec3::ZERO, 1.0), Up::Y, 0.0).collect();
        assert_eq!(g[0].position.truncate(), Vec3::ZERO);
        assert_eq!(g[1].position.truncate(), Vec3::new(1.0, 0.0, -5.0));
        assert_eq!(g[1].color_kind.w, LIGHT_STATIC as f32);
    }

    #[test]
    fn the_sweep_has_exactly_the_asked_number_of_lights() {
        assert!(sweep(0, 1.0).is_empty());
        assert_eq!(sweep(1, 1.0), vec![Light::headlight()]);
        for n in [3, 5, 7, 9, 16] {
            let l = sweep(n, 2.0);
            assert_eq!(l.len(), n as usize);
            assert!(l.iter().all(|l| l.kind == LightKind::Camera));
        }
    }

    #[test]
    fn ring_keeps_total_intensity_and_resolve_caps_the_count() {
        let r = ring(9, 1.0);
        let total: f32 = r.iter().map(|l| l.color[0]).sum();
        assert!((total - 1.0).abs() < 1e-5);
        assert_eq!(
            resolve(
                &ring(40, 1.0),
                Mat4::IDENTITY,
                (Vec3::ZERO, 1.0),
                Up::Y,
                0.0
            )
            .count(),
            MAX_LIGHTS as usize
        );
    }

    #[test]
    fn orbit_light_circles_the_centre() {
        let l = [Light {
            kind: LightKind::Orbit,
            position: [2.0, 0.0, 90.0],
            color: [1.0; 3],
        }];
        let at = |up, time| {
            resolve(&l, Mat4::IDENTITY, (Vec3::ZERO, 1.0), up, time)
                .next()
                .expect("light")
                .position
                .truncate()
        };
        assert!(at(Up::Y, 0.0).abs_diff_eq(Vec3::new(2.0, 0.0, 0.0), 1e-5));
        assert!(at(Up::Y, 1.0).abs_diff_eq(Vec3::new(0.0, 0.0, 2.0), 1e-5));
        // Z-up data (LAS): the light stays in the xy plane, never leaving the ground's level.
        for t in [0.0, 0.5, 1.0, 2.5] {
            let p = at(Up::Z, t);
            assert!(p.z.abs() < 1e-5 && (p.length() - 2.0).abs() < 1e-5, "{p}");
        }
    }

    #[test]
    fn orbit_light_height_is_along_the_up_axis() {
        let l = [Light {
            kind: LightKind::Orbit,
            position: [1.0, 3.0, 0.0],
            color: [1.0; 3],
        }];
        for up in Up::ALL {
            let p = resolve(&l, Mat4::IDENTITY, (Vec3::ZERO, 2.0), up, 0.0)
                .next()
                .expect("light")
                .position
                .truncate();
            assert!((p.dot(up.vector()) - 6.0).abs() < 1e-5, "{up:?}: {p}");
        }
    }
}

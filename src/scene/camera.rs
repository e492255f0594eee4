//! Camera: deterministic default framing, orbit poses, eye/target poses, reversed-Z projection.

use glam::{Mat4, Vec3};

/// Default vertical field of view in degrees.
pub const DEFAULT_FOV_Y_DEG: f32 = 45.0;

/// A perspective camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in radians.
    pub fov_y: f32,
    /// Near plane distance (the far plane is at infinity, reversed-Z).
    pub near: f32,
}

impl Camera {
    /// Frames the bounding sphere (`centre`, `radius`) looking down -z: the sphere just fits
    /// the vertical field of view.
    pub fn framing(centre: Vec3, radius: f32) -> Self {
        Self::orbit(centre, radius, 0.0, 0.0)
    }

    /// Orbits the bounding-sphere centre: azimuth around +y from +z, elevation towards +y,
    /// both in degrees, at the framing distance.
    pub fn orbit(centre: Vec3, radius: f32, azimuth_deg: f32, elevation_deg: f32) -> Self {
        Self::orbit_at(centre, radius, azimuth_deg, elevation_deg, 1.0)
    }

    /// Like `orbit` with the distance scaled by `distance_scale` (1 = framing distance).
    pub fn orbit_at(
        centre: Vec3,
        radius: f32,
        azimuth_deg: f32,
        elevation_deg: f32,
        distance_scale: f32,
    ) -> Self {
        let fov_y = DEFAULT_FOV_Y_DEG.to_radians();
        let radius = radius.max(1e-6);
        let distance = radius / (fov_y * 0.5).sin() * distance_scale;
        let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
        let dir = Vec3::new(az.sin() * el.cos(), el.sin(), az.cos() * el.cos());
        Self {
            eye: centre + dir * distance,
            target: centre,
            up: up_for(dir),
            fov_y,
            near: radius * 1e-3,
        }
    }

    /// A camera at `eye` looking at `target`; `scale` (the scene radius) sets the near plane.
    pub fn look_at(eye: Vec3, target: Vec3, scale: f32) -> Self {
        let dir = (eye - target).normalize_or(Vec3::Z);
        Self {
            eye,
            target,
            up: up_for(dir),
            fov_y: DEFAULT_FOV_Y_DEG.to_radians(),
            near: scale.max(1e-6) * 1e-3,
        }
    }

    /// World to view (right-handed, looking down -z).
    pub fn view(&self) -> Mat4 {
        Mat4::look_at_rh(self.eye, self.target, self.up)
    }

    /// View to Vulkan clip space: infinite reversed-Z (depth 1 at the near plane, 0 at
    /// infinity), y pointing down.
    pub fn projection(&self, aspect: f32) -> Mat4 {
        let mut p = Mat4::perspective_infinite_reverse_rh(self.fov_y, aspect.max(1e-6), self.near);
        p.y_axis.y = -p.y_axis.y;
        p
    }

    /// Distance from the eye to the target.
    pub fn distance(&self) -> f32 {
        (self.eye - self.target).length()
    }
}

/// +y unless the view direction is (nearly) vertical, then +z.
fn up_for(dir: Vec3) -> Vec3 {
    if dir.normalize_or(Vec3::Z).dot(Vec3::Y).abs() > 0.999 {
        Vec3::Z
    } else {
        Vec3::Y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_camera_looks_down_minus_z_and_fits_the_sphere() {
        let c = Camera::framing(Vec3::new(1.0, 2.0, 3.0), 2.0);
        assert!((c.eye.x - 1.0).abs() < 1e-6 && (c.eye.y - 2.0).abs() < 1e-6);
        assert!(c.eye.z > 3.0);
        // The sphere's top touches the top of the view frustum.
        let d = c.distance();
        assert!(((2.0 / d).asin() * 2.0 - c.fov_y).abs() < 1e-5);
        // The centre projects to the image centre at depth in (0, 1].
        let clip = c.projection(1.0) * c.view() * Vec3::new(1.0, 2.0, 3.0).extend(1.0);
        let ndc = clip.truncate() / clip.w;
        assert!(ndc.x.abs() < 1e-5 && ndc.y.abs() < 1e-5 && ndc.z > 0.0 && ndc.z <= 1.0);
    }

    #[test]
    fn projection_flips_y_for_vulkan() {
        let c = Camera::framing(Vec3::ZERO, 1.0);
        let clip = c.projection(1.0) * c.view() * Vec3::new(0.0, 0.5, 0.0).extend(1.0);
        assert!(
            clip.y / clip.w < 0.0,
            "world up must map to the top (negative NDC y)"
        );
    }

    #[test]
    fn orbit_moves_around_the_centre_at_constant_distance() {
        let a = Camera::orbit(Vec3::ZERO, 1.0, 90.0, 0.0);
        assert!(a.eye.x > 0.0 && a.eye.z.abs() < 1e-5);
        let b = Camera::orbit(Vec3::ZERO, 1.0, 0.0, 90.0);
        assert!(b.eye.y > 0.0);
        assert_eq!(b.up, Vec3::Z);
        assert!((a.distance() - b.distance()).abs() < 1e-5);
    }
}

/// A named camera pose relative to the scene's bounding sphere.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged)]
pub enum Pose {
    /// `eye`/`target` in scene coordinates.
    LookAt { eye: [f32; 3], target: [f32; 3] },
    /// Degrees around the bounding-sphere centre; `distance` scales the framing distance.
    Orbit {
        orbit: [f32; 2],
        #[serde(default = "one")]
        distance: f32,
    },
}

fn one() -> f32 {
    1.0
}

impl Default for Pose {
    fn default() -> Self {
        Pose::Orbit {
            orbit: [0.0, 0.0],
            distance: 1.0,
        }
    }
}

impl Pose {
    /// The camera for a scene with this bounding sphere.
    pub fn camera(&self, centre: Vec3, radius: f32) -> Camera {
        match *self {
            Pose::LookAt { eye, target } => Camera::look_at(eye.into(), target.into(), radius),
            Pose::Orbit { orbit, distance } => {
                Camera::orbit_at(centre, radius, orbit[0], orbit[1], distance)
            }
        }
    }

    /// Parses `default`, `AZ,EL` or `AZ,EL,DIST` (an orbit).
    pub fn parse_orbit(s: &str) -> Result<Self, String> {
        if s == "default" {
            return Ok(Self::default());
        }
        let v = parse_floats(s)?;
        match v.as_slice() {
            [az, el] => Ok(Pose::Orbit {
                orbit: [*az, *el],
                distance: 1.0,
            }),
            [az, el, d] if *d > 0.0 => Ok(Pose::Orbit {
                orbit: [*az, *el],
                distance: *d,
            }),
            _ => Err(format!(
                "expected AZ,EL or AZ,EL,DISTANCE (degrees), got {s:?}"
            )),
        }
    }
}

/// Parses comma-separated finite floats.
pub fn parse_floats(s: &str) -> Result<Vec<f32>, String> {
    s.split(',')
        .map(|t| {
            t.trim()
                .parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("expected a number, got {:?} in {s:?}", t.trim()))
        })
        .collect()
}

/// Parses `X,Y,Z`.
pub fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    match parse_floats(s)?.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(format!("expected X,Y,Z, got {s:?}")),
    }
}

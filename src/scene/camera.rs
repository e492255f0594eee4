//! Camera: deterministic default framing, orbit poses about the scene's up axis, eye/target
//! poses, reversed-Z projection.

use std::fmt;
use std::str::FromStr;

use glam::{DVec3, Mat4, Vec3};

/// Default vertical field of view in degrees.
pub const DEFAULT_FOV_Y_DEG: f32 = 45.0;

/// The default orbit (azimuth, elevation in degrees) for data whose up axis is not +y: an
/// oblique view from above.
pub const OBLIQUE_ORBIT_DEG: [f32; 2] = [30.0, 35.0];

/// The world axis that points up in a scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Up {
    #[serde(rename = "x")]
    X,
    #[default]
    #[serde(rename = "y")]
    Y,
    #[serde(rename = "z")]
    Z,
    #[serde(rename = "-x")]
    NegX,
    #[serde(rename = "-y")]
    NegY,
    #[serde(rename = "-z")]
    NegZ,
}

impl Up {
    /// Every axis, in the order of its names.
    pub const ALL: [Up; 6] = [Up::X, Up::Y, Up::Z, Up::NegX, Up::NegY, Up::NegZ];

    /// The name used on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Up::X => "x",
            Up::Y => "y",
            Up::Z => "z",
            Up::NegX => "-x",
            Up::NegY => "-y",
            Up::NegZ => "-z",
        }
    }

    /// The unit vector of the axis.
    pub fn vector(self) -> Vec3 {
        match self {
            Up::X => Vec3::X,
            Up::Y => Vec3::Y,
            Up::Z => Vec3::Z,
            Up::NegX => Vec3::NEG_X,
            Up::NegY => Vec3::NEG_Y,
            Up::NegZ => Vec3::NEG_Z,
        }
    }

    /// Where the eye sits at azimuth 0 and elevation 0: +z for +y up (today's default view),
    /// -y for +z up (looking north along +y); the image of +z under the rotation taking +y to
    /// this axis.
    pub fn front(self) -> Vec3 {
        match self {
            Up::X | Up::Y | Up::NegX => Vec3::Z,
            Up::Z => Vec3::NEG_Y,
            Up::NegY => Vec3::NEG_Z,
            Up::NegZ => Vec3::Y,
        }
    }

    /// The camera's up vector when looking straight along the axis: +z for a y axis (as
    /// before), +y for a z axis (north at the top of a view from above), +z for an x axis.
    fn perpendicular(self) -> Vec3 {
        match self {
            Up::Z | Up::NegZ => Vec3::Y,
            Up::X | Up::Y | Up::NegX | Up::NegY => Vec3::Z,
        }
    }

    /// The default pose for data with this up axis: today's front view for +y, an oblique
    /// view from above otherwise.
    pub fn default_pose(self) -> Pose {
        match self {
            Up::Y => Pose::default(),
            _ => Pose::Orbit {
                orbit: OBLIQUE_ORBIT_DEG,
                distance: 1.0,
            },
        }
    }
}

impl fmt::Display for Up {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Up {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim().to_ascii_lowercase();
        Up::ALL
            .into_iter()
            .find(|u| u.name() == t)
            .ok_or_else(|| format!("unknown up axis {s:?}: expected x, y, z, -x, -y or -z"))
    }
}

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

    /// Orbits the bounding-sphere centre of +y-up data: azimuth around +y from +z, elevation
    /// towards +y, both in degrees, at the framing distance.
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
        Self::orbit_about(
            Up::Y,
            centre,
            radius,
            azimuth_deg,
            elevation_deg,
            distance_scale,
        )
    }

    /// Like `orbit_at` about the axis `up`: azimuth around `up` from `up.front()`, elevation
    /// towards `up`.
    pub fn orbit_about(
        up: Up,
        centre: Vec3,
        radius: f32,
        azimuth_deg: f32,
        elevation_deg: f32,
        distance_scale: f32,
    ) -> Self {
        let fov_y = DEFAULT_FOV_Y_DEG.to_radians();
        let radius = radius.max(1e-6);
        let distance = radius / (fov_y * 0.5).sin() * distance_scale;
        let dir = orbit_direction(up, azimuth_deg.to_radians(), elevation_deg.to_radians());
        Self {
            eye: centre + dir * distance,
            target: centre,
            up: up_for(dir, up),
            fov_y,
            near: radius * 1e-3,
        }
    }

    /// A camera at `eye` looking at `target` with +y up; `scale` (the scene radius) sets the
    /// near plane.
    pub fn look_at(eye: Vec3, target: Vec3, scale: f32) -> Self {
        Self::look_at_up(Up::Y, eye, target, scale)
    }

    /// Like `look_at` with `up` pointing up in the image.
    pub fn look_at_up(up: Up, eye: Vec3, target: Vec3, scale: f32) -> Self {
        let dir = (eye - target).normalize_or(Vec3::Z);
        Self {
            eye,
            target,
            up: up_for(dir, up),
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

/// The unit direction from the orbit centre to the eye: azimuth (radians) around `up` from
/// `up.front()`, elevation (radians) towards `up`.
pub fn orbit_direction(up: Up, azimuth: f32, elevation: f32) -> Vec3 {
    let (u, front) = (up.vector(), up.front());
    let right = u.cross(front);
    (right * azimuth.sin() + front * azimuth.cos()) * elevation.cos() + u * elevation.sin()
}

/// The azimuth and elevation (radians) of the direction `d` about `up`; inverse of
/// `orbit_direction`.
pub fn orbit_angles(up: Up, d: Vec3) -> (f32, f32) {
    let (u, front) = (up.vector(), up.front());
    let right = u.cross(front);
    let d = d.normalize_or(front);
    (
        d.dot(right).atan2(d.dot(front)),
        d.dot(u).clamp(-1.0, 1.0).asin(),
    )
}

/// The up axis unless the view direction is (nearly) along it, then a perpendicular axis.
fn up_for(dir: Vec3, up: Up) -> Vec3 {
    if dir.normalize_or(Vec3::Z).dot(up.vector()).abs() > 0.999 {
        up.perpendicular()
    } else {
        up.vector()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn file_coordinates_parse_in_f64() {
        assert_eq!(
            parse_dvec3("512345.678, 4123456.789,250.25"),
            Ok([512_345.678, 4_123_456.789, 250.25])
        );
        assert!(parse_dvec3("1,2").unwrap_err().contains("expected X,Y,Z"));
        assert!(parse_dvec3("1,inf,2").unwrap_err().contains("\"inf\""));
        assert_eq!(parse_floats("1.5,-2"), Ok(vec![1.5, -2.0]));
    }

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

    /// The orbit formula before up axes existed, for +y-up data.
    fn old_y_up_eye(centre: Vec3, radius: f32, az: f32, el: f32, scale: f32) -> Vec3 {
        let distance = radius / (DEFAULT_FOV_Y_DEG.to_radians() * 0.5).sin() * scale;
        let (az, el) = (az.to_radians(), el.to_radians());
        centre + Vec3::new(az.sin() * el.cos(), el.sin(), az.cos() * el.cos()) * distance
    }

    #[test]
    fn y_up_orbits_match_the_old_formula() {
        let centre = Vec3::new(1.0, -2.0, 0.5);
        for (az, el, scale) in [
            (0.0, 0.0, 1.0),
            (30.0, 15.0, 1.0),
            (-120.0, 60.0, 0.4),
            (200.0, -45.0, 2.0),
            (10.0, 90.0, 1.0),
        ] {
            let c = Camera::orbit_about(Up::Y, centre, 3.0, az, el, scale);
            let old = old_y_up_eye(centre, 3.0, az, el, scale);
            assert!(
                (c.eye - old).length() < 1e-4,
                "{az},{el}: {} vs {old}",
                c.eye
            );
            let up = if el == 90.0 { Vec3::Z } else { Vec3::Y };
            assert_eq!(c.up, up);
        }
        assert_eq!(Up::Y.default_pose(), Pose::default());
        assert_eq!(
            Pose::default().camera(centre, 3.0, Up::Y, DVec3::ZERO),
            Camera::framing(centre, 3.0)
        );
    }

    #[test]
    fn z_up_elevation_90_looks_straight_down() {
        let c = Camera::orbit_about(Up::Z, Vec3::new(5.0, 6.0, 7.0), 2.0, 37.0, 90.0, 1.0);
        let forward = (c.target - c.eye).normalize();
        assert!((forward - Vec3::NEG_Z).length() < 1e-5, "{forward}");
        // The up vector is perpendicular to the view: north (+y) at the top of the image.
        assert_eq!(c.up, Vec3::Y);
        let clip = c.projection(1.0) * c.view() * Vec3::new(5.0, 6.5, 7.0).extend(1.0);
        assert!(clip.y / clip.w < 0.0, "+y must map to the top of the image");
    }

    #[test]
    fn azimuth_rotates_about_the_up_axis() {
        for up in Up::ALL {
            let u = up.vector();
            let base = Camera::orbit_about(up, Vec3::ZERO, 1.0, 0.0, 20.0, 1.0);
            for az in [45.0f32, 90.0, 180.0, -30.0] {
                let c = Camera::orbit_about(up, Vec3::ZERO, 1.0, az, 20.0, 1.0);
                // Same height along the axis, same distance, rotated by `az` about it.
                assert!((c.eye.dot(u) - base.eye.dot(u)).abs() < 1e-4, "{up} {az}");
                let expected = glam::Quat::from_axis_angle(u, az.to_radians()) * base.eye;
                assert!((c.eye - expected).length() < 1e-4, "{up} {az}: {}", c.eye);
                assert_eq!(c.up, u);
            }
            let (az, el) = orbit_angles(up, orbit_direction(up, 0.7, -0.3));
            assert!((az - 0.7).abs() < 1e-5 && (el + 0.3).abs() < 1e-5, "{up}");
        }
        // Elevation rises towards the axis.
        let c = Camera::orbit_about(Up::Z, Vec3::ZERO, 1.0, 0.0, 35.0, 1.0);
        assert!(c.eye.z > 0.0 && c.eye.y < 0.0 && c.eye.x.abs() < 1e-5);
    }

    #[test]
    fn up_axes_parse_by_name_and_reject_others() {
        for up in Up::ALL {
            assert_eq!(up.name().parse::<Up>(), Ok(up));
        }
        assert_eq!(" Z ".parse::<Up>(), Ok(Up::Z));
        let e = "w".parse::<Up>().unwrap_err();
        assert!(e.contains("\"w\"") && e.contains("-z"), "{e}");
        assert_eq!(
            Up::Z.default_pose(),
            Pose::Orbit {
                orbit: OBLIQUE_ORBIT_DEG,
                distance: 1.0
            }
        );
    }
}

/// A named camera pose relative to the scene's bounding sphere. A scene file writes it as
/// [`POSE_FORMS`] says; which form a table has is decided from its keys (`PoseFields`), so a
/// table of neither form is refused with what it lacks or mixes.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(untagged, try_from = "PoseFields")]
pub enum Pose {
    /// `eye`/`target` in the file's coordinates (a LiDAR file's real-world coordinates, f64);
    /// the cloud's local origin is subtracted when the camera is made.
    LookAt { eye: [f64; 3], target: [f64; 3] },
    /// Degrees around the bounding-sphere centre; `distance` scales the framing distance.
    Orbit { orbit: [f32; 2], distance: f32 },
}

/// The forms a scene file's camera takes, for messages.
pub const POSE_FORMS: &str = "expected `orbit = [AZ, EL]` (degrees; `distance = D` scales the \
     framing distance, default 1) or `eye = [X, Y, Z]` with `target = [X, Y, Z]`";

/// A camera table's keys, before [`Pose`]'s form is chosen from those present.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct PoseFields {
    orbit: Option<[f32; 2]>,
    distance: Option<f32>,
    eye: Option<[f64; 3]>,
    target: Option<[f64; 3]>,
}

impl TryFrom<PoseFields> for Pose {
    type Error = String;

    fn try_from(f: PoseFields) -> Result<Self, String> {
        let found = match (f.orbit, f.eye, f.target) {
            (Some(orbit), None, None) => {
                return Ok(Pose::Orbit {
                    orbit,
                    distance: f.distance.unwrap_or(1.0),
                })
            }
            (None, Some(eye), Some(target)) if f.distance.is_none() => {
                return Ok(Pose::LookAt { eye, target })
            }
            (None, Some(_), Some(_)) => "`distance` with `eye` and `target`",
            (Some(_), _, _) => "`orbit` with `eye` or `target`",
            (None, Some(_), None) => "`eye` without `target`",
            (None, None, Some(_)) => "`target` without `eye`",
            (None, None, None) if f.distance.is_some() => "`distance` without `orbit`",
            (None, None, None) => "an empty table",
        };
        Err(format!("camera: {POSE_FORMS}; found {found}"))
    }
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
    /// Refuses a pose no camera can take: a non-finite value, an eye on its target, a
    /// distance that is not positive.
    pub fn check(&self) -> Result<(), String> {
        match *self {
            Pose::LookAt { eye, target } => {
                if !eye.iter().chain(&target).all(|v| v.is_finite()) {
                    return Err(format!(
                        "camera eye {eye:?} and target {target:?} must be finite"
                    ));
                }
                if eye == target {
                    return Err(format!(
                        "camera eye and target are the same point {eye:?}; expected distinct points"
                    ));
                }
            }
            Pose::Orbit { orbit, distance } => {
                if !(orbit.iter().all(|v| v.is_finite()) && distance > 0.0 && distance.is_finite())
                {
                    return Err(format!(
                        "camera orbit {orbit:?} must be finite and its distance {distance} positive"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The camera for a scene with this bounding sphere, up axis and local origin (in the
    /// file's coordinates).
    pub fn camera(&self, centre: Vec3, radius: f32, up: Up, origin: DVec3) -> Camera {
        match *self {
            Pose::LookAt { eye, target } => {
                let local = |p: [f64; 3]| (DVec3::from(p) - origin).as_vec3();
                Camera::look_at_up(up, local(eye), local(target), radius)
            }
            Pose::Orbit { orbit, distance } => {
                Camera::orbit_about(up, centre, radius, orbit[0], orbit[1], distance)
            }
        }
    }

    /// Parses `default` (`None`: the up axis's default pose), `AZ,EL` or `AZ,EL,DIST` (an
    /// orbit).
    pub fn parse_orbit(s: &str) -> Result<Option<Self>, String> {
        if s == "default" {
            return Ok(None);
        }
        let v = parse_floats(s)?;
        match v.as_slice() {
            [az, el] => Ok(Some(Pose::Orbit {
                orbit: [*az, *el],
                distance: 1.0,
            })),
            [az, el, d] if *d > 0.0 => Ok(Some(Pose::Orbit {
                orbit: [*az, *el],
                distance: *d,
            })),
            _ => Err(format!(
                "expected AZ,EL or AZ,EL,DISTANCE (degrees), got {s:?}"
            )),
        }
    }
}

/// Parses comma-separated numbers that `finite` accepts.
fn parse_list<T: std::str::FromStr>(s: &str, finite: fn(&T) -> bool) -> Result<Vec<T>, String> {
    s.split(',')
        .map(|t| {
            t.trim()
                .parse::<T>()
                .ok()
                .filter(finite)
                .ok_or_else(|| format!("expected a number, got {:?} in {s:?}", t.trim()))
        })
        .collect()
}

/// Parses comma-separated finite floats.
pub fn parse_floats(s: &str) -> Result<Vec<f32>, String> {
    parse_list(s, |v: &f32| v.is_finite())
}

/// Parses `X,Y,Z` as f64 (file coordinates).
pub fn parse_dvec3(s: &str) -> Result<[f64; 3], String> {
    match parse_list(s, |v: &f64| v.is_finite())?.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(format!("expected X,Y,Z, got {s:?}")),
    }
}

/// Parses `X,Y,Z`.
pub fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    match parse_floats(s)?.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(format!("expected X,Y,Z, got {s:?}")),
    }
}

//! What the viewer hides: a clipping box (axis-aligned or oriented, in the file's real-world
//! coordinates) and a set of hidden classification classes. The projection passes apply both
//! per point (`point_kept` in `glsl/common/streams.glsl`, from `FrameUniforms.clip` and
//! `class_hidden`); [`Filter::keeps`] is the same test on the CPU, with the same f32 matrix,
//! so the viewer reports how many points a filter keeps and tests predict the projected count.

use glam::{DMat3, DMat4, DVec3, Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::Cloud;

/// Which side of the box is drawn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Keep {
    /// The points inside the box (Potree's "clip outside").
    #[default]
    Inside,
    /// The points outside the box (cuts a hole, e.g. through a roof).
    Outside,
}

/// A box in the file's coordinates: a centre, half extents along its own axes and its
/// rotation (degrees about the file's z, then y, then x axis: yaw, pitch, roll). With no
/// rotation it is axis-aligned.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClipBox {
    pub centre: [f64; 3],
    pub half: [f64; 3],
    #[serde(default)]
    pub rotation: [f64; 3],
    #[serde(default)]
    pub keep: Keep,
}

impl ClipBox {
    /// The axis-aligned box with corners `a` and `b` (any two opposite corners).
    pub fn aligned(a: DVec3, b: DVec3) -> Self {
        Self {
            centre: ((a + b) * 0.5).to_array(),
            half: ((a - b).abs() * 0.5).to_array(),
            rotation: [0.0; 3],
            keep: Keep::Inside,
        }
    }

    /// The box with this centre, half extents and rotation (orthonormal axes as columns, a
    /// proper rotation), its angles recovered as yaw, pitch, roll.
    pub fn oriented(centre: DVec3, half: DVec3, axes: DMat3) -> Self {
        let (r00, r10, r20) = (axes.x_axis.x, axes.x_axis.y, axes.x_axis.z);
        let (r21, r22) = (axes.y_axis.z, axes.z_axis.z);
        Self {
            centre: centre.to_array(),
            half: half.to_array(),
            rotation: [
                r10.atan2(r00).to_degrees(),
                (-r20).clamp(-1.0, 1.0).asin().to_degrees(),
                r21.atan2(r22).to_degrees(),
            ],
            keep: Keep::Inside,
        }
    }

    /// The box's rotation (its axes as columns) in the file's frame.
    fn axes(&self) -> DMat3 {
        let [yaw, pitch, roll] = self.rotation.map(f64::to_radians);
        DMat3::from_rotation_z(yaw) * DMat3::from_rotation_y(pitch) * DMat3::from_rotation_x(roll)
    }

    /// Refuses a box that keeps nothing defined: a non-finite value or a negative extent.
    pub fn check(&self) -> Result<(), String> {
        let values = self.centre.iter().chain(&self.half).chain(&self.rotation);
        if !values.clone().all(|v| v.is_finite()) || self.half.iter().any(|h| *h < 0.0) {
            return Err(format!(
                "clip box: centre {:?}, half {:?} and rotation {:?} must be finite, half extents not negative",
                self.centre, self.half, self.rotation
            ));
        }
        Ok(())
    }

    /// The matrix taking a point of a cloud whose local frame starts at `origin` to the box's
    /// unit coordinates (inside where every coordinate is within ±1). Computed in f64 (the
    /// centre may be a UTM coordinate), rounded to f32 once. A flat axis (zero half extent)
    /// keeps the points within a relative 1e-9 of the box's diagonal of its plane.
    pub fn local_to_unit(&self, origin: DVec3) -> Mat4 {
        let half = DVec3::from(self.half);
        let floor = half.length().max(1e-300) * 1e-9;
        let scale = DMat4::from_scale(half.max(DVec3::splat(floor)).recip());
        let rotate = DMat4::from_mat3(self.axes().transpose());
        let shift = DMat4::from_translation(origin - DVec3::from(self.centre));
        (scale * rotate * shift).as_mat4()
    }

    /// The eight corners in the file's coordinates (for drawing the box).
    pub fn corners(&self) -> [DVec3; 8] {
        let axes = self.axes();
        let (c, h) = (DVec3::from(self.centre), DVec3::from(self.half));
        std::array::from_fn(|k| {
            let s = DVec3::new(
                if k & 1 == 0 { -1.0 } else { 1.0 },
                if k & 2 == 0 { -1.0 } else { 1.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            );
            c + axes * (s * h)
        })
    }
}

/// Whether `p` (box unit coordinates from [`ClipBox::local_to_unit`]) is inside.
pub fn unit_inside(p: Vec3) -> bool {
    p.abs().max_element() <= 1.0
}

/// A set of classification classes (0..=255), one bit each.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Classes(pub [u32; 8]);

impl Classes {
    pub fn contains(&self, class: u8) -> bool {
        self.0[usize::from(class >> 5)] & (1 << (class & 31)) != 0
    }

    pub fn set(&mut self, class: u8, on: bool) {
        let word = &mut self.0[usize::from(class >> 5)];
        if on {
            *word |= 1 << (class & 31);
        } else {
            *word &= !(1 << (class & 31));
        }
    }

    pub fn is_empty(&self) -> bool {
        self.0.iter().all(|w| *w == 0)
    }

    pub fn list(&self) -> Vec<u8> {
        (0..=255u8).filter(|&c| self.contains(c)).collect()
    }

    pub fn from_list(classes: &[u8]) -> Self {
        let mut set = Self::default();
        for &c in classes {
            set.set(c, true);
        }
        set
    }
}

/// The classification class stored as the f32 scalar `value` (the loaders store whole numbers;
/// anything else is class 255).
pub fn class_of(value: f32) -> u8 {
    if (0.0..=255.0).contains(&value) && value.fract() == 0.0 {
        value as u8
    } else {
        255
    }
}

/// The index of the cloud's classification field, if it has one.
pub fn classification_field(cloud: &Cloud) -> Option<usize> {
    cloud
        .scalars
        .iter()
        .position(|s| s.name == "classification")
}

/// The viewer's clipping box and hidden classes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Filter {
    pub clip: Option<ClipBox>,
    pub hidden: Classes,
}

/// A [`Filter`] resolved for one cloud: the box matrix in its local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Resolved {
    pub clip: Option<(Mat4, Keep)>,
    pub hidden: Classes,
}

impl Filter {
    pub fn is_active(&self) -> bool {
        self.clip.is_some() || !self.hidden.is_empty()
    }

    /// The filter resolved for a cloud whose local frame starts at `origin`, `None` when it
    /// keeps every point (what `Renderer::set_filter` takes).
    pub fn active(&self, origin: DVec3) -> Option<Resolved> {
        self.is_active().then(|| self.resolve(origin))
    }

    pub fn resolve(&self, origin: DVec3) -> Resolved {
        Resolved {
            clip: self.clip.map(|b| (b.local_to_unit(origin), b.keep)),
            hidden: self.hidden,
        }
    }

    /// How many points of `cloud` the filter keeps (what the projection passes draw).
    pub fn count(&self, cloud: &Cloud) -> usize {
        let resolved = self.resolve(cloud.origin);
        let classes = classification_field(cloud).map(|k| &cloud.scalars[k].values);
        (0..cloud.positions.len())
            .filter(|&i| {
                let class = classes.map(|c| class_of(c[i]));
                resolved.keeps(cloud.positions[i], class)
            })
            .count()
    }
}

impl Resolved {
    /// Whether a point at local position `p` of class `class` (none: the cloud has no
    /// classification, which no class filter hides) is drawn.
    pub fn keeps(&self, p: Vec3, class: Option<u8>) -> bool {
        if let Some((m, keep)) = self.clip {
            if unit_inside(m.transform_point3(p)) != (keep == Keep::Inside) {
                return false;
            }
        }
        class.is_none_or(|c| !self.hidden.contains(c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_oriented_box_at_utm_coordinates_keeps_what_it_contains() {
        let origin = DVec3::new(500_000.0, 4_000_000.0, 100.0);
        let b = ClipBox {
            centre: [500_010.0, 4_000_000.0, 100.0],
            half: [5.0, 1.0, 2.0],
            rotation: [90.0, 0.0, 0.0],
            keep: Keep::Inside,
        };
        let m = b.local_to_unit(origin);
        // Rotated 90° about z, the 5 m half extent lies along y.
        assert!(unit_inside(m.transform_point3(Vec3::new(10.0, 4.9, 1.9))));
        assert!(!unit_inside(m.transform_point3(Vec3::new(10.0, 5.1, 0.0))));
        assert!(!unit_inside(m.transform_point3(Vec3::new(11.1, 0.0, 0.0))));
        for c in b.corners() {
            let u = m.transform_point3((c - origin).as_vec3());
            assert!((u.abs() - Vec3::ONE).abs().max_element() < 1e-5, "{u}");
        }
        let a = ClipBox::aligned(DVec3::new(1.0, 5.0, -1.0), DVec3::new(-1.0, 2.0, 1.0));
        assert_eq!(a.centre, [0.0, 3.5, 0.0]);
        assert_eq!(a.half, [1.0, 1.5, 1.0]);
        assert!(ClipBox {
            half: [-1.0, 1.0, 1.0],
            ..a
        }
        .check()
        .is_err());
        // Angles recovered from axes give the same axes back.
        let r = DMat3::from_rotation_z(0.3)
            * DMat3::from_rotation_y(-0.2)
            * DMat3::from_rotation_x(0.1);
        let o = ClipBox::oriented(DVec3::ZERO, DVec3::ONE, r);
        assert!(
            (o.axes() - r)
                .to_cols_array()
                .iter()
                .all(|d| d.abs() < 1e-12),
            "{o:?}"
        );
        assert!(ClipBox {
            centre: [f64::NAN, 0.0, 0.0],
            ..a
        }
        .check()
        .is_err());
    }

    #[test]
    fn classes_are_bits_and_odd_values_are_class_255() {
        let mut c = Classes::from_list(&[2, 7, 255]);
        assert!(c.contains(2) && c.contains(255) && !c.contains(3));
        c.set(2, false);
        assert_eq!(c.list(), vec![7, 255]);
        assert_eq!(class_of(2.0), 2);
        assert_eq!(class_of(-1.0), 255);
        assert_eq!(class_of(f32::NAN), 255);
        assert_eq!(class_of(300.0), 255);
        assert_eq!(class_of(2.5), 255);
    }
}

//! The viewer's picking and measuring: a pick snaps to the nearest point drawn near the cursor
//! that is visible from the camera, and measurements combine picks in the file's real-world
//! coordinates (f64).
//!
//! Visibility is decided twice. The depth buffer of the frame on screen rejects a point whose
//! view depth lies behind what the frame shows at its pixel. A sparse cloud lets hidden points
//! through the gaps between its nearer points, so the candidates then go through hidden point
//! removal (`hpr::exact`, 003 §2.1) of the points in a cone around the pick ray: a point on a
//! wall behind a sparse wall is hidden even where the depth buffer shows it. The flipping
//! radius is the density radius of `Radius::Density`, R = κ D² / s, taken for the occluders:
//! D is the nearest layer's depth (the points within `LAYER` of the nearest depth in the cone)
//! and s the sparser of two spacings, the whole cloud's and that layer's (its points spread
//! over the cone's square at that depth). The cloud's spacing and centre alone would be the
//! dense back wall's and keep the back wall visible through the sparse front one; a smaller
//! radius only hides more, and a pick then snaps to a nearer visible point.
//!
//! A pick is an event: it projects every point once on the CPU (in parallel), never per frame.

use glam::{DVec3, IVec2, Mat4, Vec2, Vec3};
use rayon::prelude::*;
use serde_json::{json, Value};

use crate::hpr::{self, Radius};
use crate::scene::clip::{class_of, classification_field, Resolved};
use crate::scene::{Camera, Cloud, Up};

/// Half the side of the square around the cursor in which a pick snaps to a point, in pixels.
pub const PICK_RADIUS: i32 = 8;
/// Half the side of the square around the cursor whose points form the hidden point removal's
/// cone (wide enough for the occluders around the candidates), in pixels.
pub const CONE_RADIUS: i32 = 4 * PICK_RADIUS;
/// At most this many points go through the cone's hidden point removal; a denser cone (a
/// cloud seen from far away, dense on screen) relies on the depth buffer alone.
pub const CONE_MAX_POINTS: usize = 400_000;
/// The nearest layer of the cone: points within this fraction of the nearest depth.
pub const LAYER: f32 = 0.05;
/// A point is in front of the depth buffer when its view depth is at most this much
/// (relative) behind the buffer's: splats and reconstructions interpolate depth across a
/// surface, so a point on the surface can lie slightly behind the depth drawn at its pixel.
pub const DEPTH_TOLERANCE: f32 = 0.01;

/// The frame a pick looks at: its camera, size and linear view depth (`Frame::depth`).
pub struct Screen<'a> {
    pub camera: &'a Camera,
    pub width: u32,
    pub height: u32,
    pub depth: &'a [f32],
}

impl Screen<'_> {
    fn view_proj(&self) -> Mat4 {
        let aspect = self.width as f32 / self.height.max(1) as f32;
        self.camera.projection(aspect) * self.camera.view()
    }

    fn depth_at(&self, px: IVec2) -> f32 {
        self.depth[px.y as usize * self.width as usize + px.x as usize]
    }
}

/// The pixel a 1-pixel point at `p` covers and its view depth, as the compute rasterizer and
/// the point pipeline put it (`glsl/compute/raster.comp`); `None` outside the view.
pub fn pixel_of(view_proj: Mat4, p: Vec3, width: u32, height: u32) -> Option<(IVec2, f32)> {
    let c = view_proj * p.extend(1.0);
    if c.w <= 0.0 || c.z > c.w || c.x.abs() > c.w || c.y.abs() > c.w {
        return None;
    }
    let half = Vec2::new(width as f32, height as f32) * 0.5;
    let win = Vec2::new(c.x, c.y) / c.w * half + half;
    let corner = ((win - 0.5) * 256.0).round() / 256.0;
    let px = (corner - 0.5).ceil().as_ivec2();
    (px.x >= 0 && px.y >= 0 && px.x < width as i32 && px.y < height as i32).then_some((px, c.w))
}

/// A picked point.
#[derive(Clone, Debug, PartialEq)]
pub struct Picked {
    /// The point's index in the cloud picked from.
    pub index: usize,
    /// For a streamed file, the node holding the point ("HREF node KEY") and its index there
    /// (printed as the point's index).
    pub node: Option<(String, usize)>,
    /// The pixel the point is drawn at.
    pub pixel: IVec2,
    /// In the file's coordinates: the cloud's f64 origin plus the local f32 position.
    pub world: DVec3,
    pub view_depth: f32,
}

/// What a pick found and why.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    pub pixel: IVec2,
    /// The depth buffer at the pixel (`None`: nothing drawn there).
    pub buffer_depth: Option<f32>,
    /// Points drawn within `PICK_RADIUS`.
    pub candidates: usize,
    /// Of those, behind the depth buffer.
    pub behind_depth: usize,
    /// Of the rest, hidden by hidden point removal in the cone.
    pub hidden: usize,
    /// Points in the cone's hidden point removal (`None`: skipped, the cone was too dense or
    /// no candidate was left to check).
    pub cone_points: Option<usize>,
    pub picked: Option<Picked>,
}

/// The viewer's state a pick reads: the cloud, its filter and the flipping-radius spacing.
pub struct Target<'a> {
    pub cloud: &'a Cloud,
    pub filter: Option<&'a Resolved>,
    /// `hpr::spacing` of the cloud (computed once).
    pub spacing: f64,
}

impl Target<'_> {
    fn kept(&self, i: usize, classes: Option<&[f32]>) -> bool {
        self.filter
            .is_none_or(|f| f.keeps(self.cloud.positions[i], classes.map(|c| class_of(c[i]))))
    }
}

/// Picks the point at `pixel` of `screen`: among the points the filter keeps, drawn within
/// `PICK_RADIUS` pixels, in front of the depth buffer and visible to hidden point removal,
/// the one drawn nearest to the pixel (then the nearest to the camera).
pub fn pick(target: &Target<'_>, screen: &Screen<'_>, pixel: IVec2) -> Pick {
    let cloud = target.cloud;
    let view_proj = screen.view_proj();
    let classes = classification_field(cloud).map(|k| cloud.scalars[k].values.as_slice());
    let inside = |px: IVec2, r: i32| (px - pixel).abs().max_element() <= r;
    // Every kept point drawn within the cone's square: (index, pixel, view depth).
    let cone: Vec<(usize, IVec2, f32)> = (0..cloud.positions.len())
        .into_par_iter()
        .filter_map(|i| {
            let (px, d) = pixel_of(view_proj, cloud.positions[i], screen.width, screen.height)?;
            (inside(px, CONE_RADIUS) && target.kept(i, classes)).then_some((i, px, d))
        })
        .collect();
    let mut candidates: Vec<(usize, IVec2, f32)> = cone
        .iter()
        .copied()
        .filter(|(_, px, _)| inside(*px, PICK_RADIUS))
        .collect();
    candidates.sort_by(|a, b| {
        let da = (a.1 - pixel).length_squared();
        let db = (b.1 - pixel).length_squared();
        da.cmp(&db).then(a.2.total_cmp(&b.2)).then(a.0.cmp(&b.0))
    });
    let total = candidates.len();
    candidates.retain(|(_, px, d)| *d <= screen.depth_at(*px) * (1.0 + DEPTH_TOLERANCE));
    let behind_depth = total - candidates.len();
    let mut cone_points = None;
    let mut hidden = 0;
    if !candidates.is_empty() && cone.len() <= CONE_MAX_POINTS {
        let points: Vec<Vec3> = cone.iter().map(|(i, _, _)| cloud.positions[*i]).collect();
        let nearest = cone.iter().map(|c| c.2).fold(f32::INFINITY, f32::min);
        let layer = cone
            .iter()
            .filter(|c| c.2 <= nearest * (1.0 + LAYER))
            .count();
        let pixel_size = 2.0 * nearest * (screen.camera.fov_y * 0.5).tan() / screen.height as f32;
        let side = (2 * CONE_RADIUS + 1) as f32 * pixel_size;
        let local = f64::from(side) / (layer.max(1) as f64).sqrt();
        let eye = screen.camera.eye;
        let farthest = points
            .iter()
            .map(|p| f64::from(p.distance(eye)))
            .fold(0.0, f64::max);
        let near = f64::from(nearest);
        let radius = Radius::Absolute(
            (hpr::DENSITY_KAPPA * near * near / target.spacing.max(local)).max(1.01 * farthest),
        );
        if let Ok(v) = hpr::exact(&points, screen.camera.eye, radius) {
            let visible: std::collections::HashSet<usize> =
                v.visible.iter().map(|&k| cone[k as usize].0).collect();
            let before = candidates.len();
            candidates.retain(|(i, _, _)| visible.contains(i));
            hidden = before - candidates.len();
            cone_points = Some(points.len());
        }
    }
    let depth = screen.depth_at(pixel);
    Pick {
        pixel,
        buffer_depth: depth.is_finite().then_some(depth),
        candidates: total,
        behind_depth,
        hidden,
        cone_points,
        picked: candidates
            .first()
            .map(|&(index, pixel, view_depth)| Picked {
                index,
                node: None,
                pixel,
                world: cloud.origin + cloud.positions[index].as_dvec3(),
                view_depth,
            }),
    }
}

/// The point's attributes as the file has them: colour, normal, radius and every scalar field.
pub fn attributes(cloud: &Cloud, i: usize) -> Value {
    let mut out = serde_json::Map::new();
    if let Some(c) = cloud.colors.as_ref().map(|c| c[i]) {
        out.insert("rgb".into(), json!([c[0], c[1], c[2]]));
    }
    if let Some(n) = cloud.normals.as_ref().map(|n| n[i]) {
        out.insert("normal".into(), json!([n.x, n.y, n.z]));
    }
    if let Some(r) = cloud.radii.as_ref().map(|r| r[i]) {
        out.insert("radius".into(), json!(r));
    }
    for s in &cloud.scalars {
        out.insert(s.name.clone(), json!(s.values[i]));
    }
    Value::Object(out)
}

impl Pick {
    /// The pick as JSON (`pick` of a script prints it).
    pub fn json(&self, cloud: &Cloud) -> Value {
        json!({
            "pixel": [self.pixel.x, self.pixel.y],
            "buffer_depth": self.buffer_depth,
            "candidates": self.candidates,
            "behind_depth_buffer": self.behind_depth,
            "hidden_by_hpr": self.hidden,
            "hpr_cone_points": self.cone_points,
            "point": self.picked.as_ref().map(|p| json!({
                "index": p.node.as_ref().map_or(p.index, |n| n.1),
                "node": p.node.as_ref().map(|n| &n.0),
                "position": [p.world.x, p.world.y, p.world.z],
                "drawn_at": [p.pixel.x, p.pixel.y],
                "view_depth": p.view_depth,
                "attributes": attributes(cloud, p.index),
            })),
        })
    }
}

/// What a measurement computes from its picked points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Measure {
    /// Two points: the distance and its horizontal and vertical parts.
    Distance,
    /// Two points, the first on the ground: the height of the second above it.
    Height,
    /// Any number: the length along them.
    Polyline,
    /// Three or more: the closed polygon's area (and its horizontal projection's).
    Area,
}

impl Measure {
    pub const ALL: [Measure; 4] = [
        Measure::Distance,
        Measure::Height,
        Measure::Polyline,
        Measure::Area,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Measure::Distance => "distance",
            Measure::Height => "height",
            Measure::Polyline => "polyline",
            Measure::Area => "area",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }

    /// Points the measurement takes (`None`: any number).
    pub fn points(self) -> Option<usize> {
        match self {
            Measure::Distance | Measure::Height => Some(2),
            Measure::Polyline | Measure::Area => None,
        }
    }
}

/// The figures of measurement `m` over `points` (file coordinates, f64) with `up` the
/// vertical: named values in file units (squared for areas). Too few points give none.
pub fn measure(m: Measure, points: &[DVec3], up: Up) -> Vec<(&'static str, f64)> {
    let axis = up.vector().as_dvec3();
    let vertical = |d: DVec3| d.dot(axis);
    let horizontal = |d: DVec3| (d - axis * d.dot(axis)).length();
    match (m, points) {
        (Measure::Distance, [a, b, ..]) => {
            let d = *b - *a;
            vec![
                ("distance", d.length()),
                ("horizontal", horizontal(d)),
                ("vertical", vertical(d).abs()),
            ]
        }
        (Measure::Height, [ground, top, ..]) => {
            let d = *top - *ground;
            vec![("height", vertical(d)), ("horizontal", horizontal(d))]
        }
        (Measure::Polyline, [_, _, ..]) => {
            let length = points.windows(2).map(|w| w[0].distance(w[1])).sum();
            let plan = points.windows(2).map(|w| horizontal(w[1] - w[0])).sum();
            vec![("length", length), ("horizontal_length", plan)]
        }
        (Measure::Area, [first, _, _, ..]) => {
            // The vector area of the closed polygon about its first point (differences stay
            // small at UTM coordinates): half the sum of the edges' cross products. Its
            // length is the area of a planar polygon; its vertical part the plan area.
            let v: DVec3 = points
                .windows(2)
                .map(|w| (w[0] - *first).cross(w[1] - *first))
                .sum::<DVec3>()
                * 0.5;
            let perimeter = points
                .iter()
                .zip(points.iter().cycle().skip(1))
                .map(|(a, b)| a.distance(*b))
                .sum();
            vec![
                ("area", v.length()),
                ("plan_area", v.dot(axis).abs()),
                ("perimeter", perimeter),
            ]
        }
        _ => Vec::new(),
    }
}

/// The HUD line of measured value `name` (its words spaced; areas in square units).
pub fn measure_line(name: &str, value: f64) -> String {
    let unit = if name.contains("area") {
        " sq. units"
    } else {
        ""
    };
    format!("  {} {value:.3}{unit}", name.replace('_', " "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measurements_in_utm_coordinates_keep_their_precision() {
        let o = DVec3::new(512_345.678, 4_123_456.789, 250.0);
        let a = o + DVec3::new(3.0, 4.0, 0.0);
        let b = o + DVec3::new(6.0, 8.0, 12.0);
        let d = measure(Measure::Distance, &[a, b], Up::Z);
        assert_eq!(d[0].0, "distance");
        assert!((d[0].1 - 13.0).abs() < 1e-9, "{d:?}");
        assert!((d[1].1 - 5.0).abs() < 1e-9 && (d[2].1 - 12.0).abs() < 1e-9);
        let h = measure(Measure::Height, &[b, a], Up::Z);
        assert!((h[0].1 + 12.0).abs() < 1e-9, "signed: {h:?}");
        let square = [
            o,
            o + DVec3::X * 2.0,
            o + DVec3::new(2.0, 3.0, 0.0),
            o + DVec3::Y * 3.0,
        ];
        let area = measure(Measure::Area, &square, Up::Z);
        let names: Vec<&str> = area.iter().map(|(n, _)| *n).collect();
        assert_eq!(names, ["area", "plan_area", "perimeter"]);
        assert_eq!(
            measure_line("plan_area", 6.0),
            "  plan area 6.000 sq. units"
        );
        assert_eq!(measure_line("horizontal", 5.0), "  horizontal 5.000");
        assert!((area[0].1 - 6.0).abs() < 1e-9 && (area[1].1 - 6.0).abs() < 1e-9);
        assert!((area[2].1 - 10.0).abs() < 1e-9);
        // A vertical wall has an area but no plan area.
        let wall = [
            o,
            o + DVec3::X,
            o + DVec3::new(1.0, 0.0, 2.0),
            o + DVec3::Z * 2.0,
        ];
        let area = measure(Measure::Area, &wall, Up::Z);
        assert!((area[0].1 - 2.0).abs() < 1e-9 && area[1].1.abs() < 1e-9);
        let line = measure(Measure::Polyline, &square, Up::Z);
        assert!((line[0].1 - 7.0).abs() < 1e-9);
        assert!(measure(Measure::Area, &square[..2], Up::Z).is_empty());
        assert_eq!(Measure::parse("height"), Some(Measure::Height));
    }

    #[test]
    fn a_pixel_is_where_the_rasterizer_puts_a_point() {
        let camera = Camera::look_at_up(Up::Y, Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 1.0);
        let vp = camera.projection(1.0) * camera.view();
        let (px, d) = pixel_of(vp, Vec3::ZERO, 64, 64).expect("in view");
        // The point square [31.5, 32.5] covers pixel 31's centre (top-left rule).
        assert_eq!(px, IVec2::new(31, 31));
        assert!((d - 5.0).abs() < 1e-5);
        assert!(
            pixel_of(vp, Vec3::new(0.0, 0.0, 6.0), 64, 64).is_none(),
            "behind"
        );
    }
}

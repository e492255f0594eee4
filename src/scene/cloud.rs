//! The in-memory point cloud every loader produces and every method consumes.

use glam::{DVec3, Vec2, Vec3};
use rayon::prelude::*;

use super::camera::Up;

/// A named per-point scalar attribute (LAS intensity, classification, PLY confidence, ...).
#[derive(Clone, Debug, PartialEq)]
pub struct Scalar {
    pub name: String,
    pub values: Vec<f32>,
}

/// What a loader had to do to the file's records, reported by `surfel info`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LoadStats {
    /// Records in the file (header count for PLY/PCD/LAS).
    pub records: usize,
    /// Records dropped because a coordinate was NaN or infinite.
    pub dropped_non_finite: usize,
    /// Records the file itself marks invalid (E57 `cartesianInvalidState` /
    /// `sphericalInvalidState`), or text rows without the values their column names call for,
    /// skipped.
    pub dropped_invalid: usize,
    /// For an octree file (COPC): the points of each level and how many levels were read.
    pub levels: Option<Levels>,
    /// For a text file without column names: the columns as their count made them.
    pub guessed_columns: Option<String>,
    /// Why the loader chose [`Cloud::up`] from the data, when it did; `None` leaves the
    /// format's convention ([`super::format_up`]).
    pub up_rule: Option<String>,
    /// Problems that did not stop the load, each naming the file (`scene::load_with` prints
    /// them on stderr).
    pub warnings: Vec<String>,
    /// For a LAS, LAZ or COPC file: its header's description.
    pub las: Option<LasSummary>,
    /// The exact bounds of the points read, in f64 file coordinates, where the loader keeps
    /// them (LAS, LAZ, COPC).
    pub file_bounds: Option<[DVec3; 2]>,
    /// The GPS time the `gps_time` scalar counts from, when the file has GPS times: the
    /// earliest record's (COPC: the earliest its info VLR records), so the field holds seconds
    /// after it (f32 cannot hold absolute GPS times to the microsecond).
    pub gps_time_origin: Option<f64>,
}

/// What `surfel info` prints of a LAS, LAZ or COPC file's header.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LasSummary {
    /// The LAS version, such as `1.4`.
    pub version: String,
    /// The point data record format (0 to 10).
    pub point_format: u8,
    /// The coordinates' scale and offset (file coordinate = scale × stored integer + offset).
    pub scale: DVec3,
    pub offset: DVec3,
    /// The coordinate reference system: the WKT's name and authority code, or the GeoTIFF
    /// keys' EPSG codes; `None` when the file records none.
    pub crs: Option<String>,
    /// How the file was read when not as its name says (a pre-1.0 COPC draft read as LAZ).
    pub note: Option<String>,
}

/// The octree levels of a COPC file and the levels a point budget let a load read.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Levels {
    /// Points in each level, from the root (level 0) down, as the hierarchy declares them.
    pub points: Vec<u64>,
    /// Levels read: `0..read` (all of them without a budget).
    pub read: usize,
}

impl Levels {
    /// Points in the levels that were read.
    pub fn points_read(&self) -> u64 {
        self.points[..self.read].iter().sum()
    }

    /// Points in the deeper levels the budget left out.
    pub fn points_skipped(&self) -> u64 {
        self.points[self.read..].iter().sum()
    }
}

/// Exact duplicate positions in a cloud, reported by `surfel info`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Duplicates {
    /// Points whose position equals an earlier point's.
    pub points: usize,
    /// Distinct positions that occur more than once.
    pub positions: usize,
}

/// Axis-aligned bounds of the finite points seen so far, in f64 file coordinates.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bounds {
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Bounds {
    pub(crate) const EMPTY: Bounds = Bounds {
        lo: DVec3::INFINITY,
        hi: DVec3::NEG_INFINITY,
    };

    /// Adds `p` when all its coordinates are finite.
    #[inline]
    pub(crate) fn add(&mut self, p: DVec3) {
        if p.is_finite() {
            self.lo = self.lo.min(p);
            self.hi = self.hi.max(p);
        }
    }

    pub(crate) fn union(self, other: Bounds) -> Bounds {
        Bounds {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
        }
    }

    /// The f64 centre of the box, `None` when no finite point was added.
    pub(crate) fn centre(&self) -> Option<DVec3> {
        (self.lo.x <= self.hi.x).then(|| (self.lo + self.hi) * 0.5)
    }
}

/// Line primitives over a cloud's points (000 §5.1): segments as pairs of point indices.
/// A ribbon's points carry its normal and half width as normal and radius; a tube's carry
/// its tangent and radius.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Lines {
    pub ribbons: Vec<[u32; 2]>,
    pub tubes: Vec<[u32; 2]>,
}

/// A point cloud in a local frame: `positions` are relative to `origin` (f64, in file units),
/// so large LiDAR coordinates keep their precision after the conversion to f32.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Cloud {
    pub positions: Vec<Vec3>,
    /// Unit normals, one per point, when the file has them or preprocessing computed them.
    pub normals: Option<Vec<Vec3>>,
    /// sRGB colors with alpha, one per point.
    pub colors: Option<Vec<[u8; 4]>>,
    /// World-space splat radii, one per point.
    pub radii: Option<Vec<f32>>,
    pub scalars: Vec<Scalar>,
    /// Triangles indexing `positions` (mesh inputs); the evaluation's ground truth.
    pub faces: Option<Vec<[u32; 3]>>,
    /// Ribbons and tubes indexing `positions` (line models, `surfel convert-lines`).
    pub lines: Option<Lines>,
    /// Offset that was subtracted from the file's coordinates.
    pub origin: DVec3,
    pub stats: LoadStats,
    /// Where the scanner (or camera) of each scan stood, in the same local frame as
    /// `positions`, when the file records it (an E57 scan's pose, a PCD `VIEWPOINT`): scans in
    /// point order, each from its first point to the next scan's. Estimated normals face it
    /// ([`super::orient`]).
    pub sensors: Vec<Sensor>,
    /// The axis pointing up in the data: the format's convention (+z for LAS, LAZ, COPC, E57
    /// and PCD; +y otherwise), or what the loader read from the data (`stats.up_rule`: an
    /// organized PCD's camera frame, survey-sized text coordinates); cameras orbit about it.
    pub up: Up,
    /// Survey data (LAS, LAZ, COPC, text in projected coordinates): seen from above, so
    /// estimated normals face `up` where no scanner position is known.
    pub survey: bool,
}

/// A scan's scanner position and the first point of the scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sensor {
    pub first: usize,
    pub position: Vec3,
}

/// The scans of `sensors` over the points `keep` (ascending indices of the old points).
pub(crate) fn remap_sensors(sensors: &[Sensor], keep: &[usize]) -> Vec<Sensor> {
    let mut out: Vec<Sensor> = Vec::with_capacity(sensors.len());
    for s in sensors {
        let first = keep.partition_point(|&k| k < s.first);
        // A scan left without points gives way to the next one starting at the same point.
        if let Some(last) = out.last_mut().filter(|l| l.first == first) {
            *last = Sensor { first, ..*s };
        } else {
            out.push(Sensor { first, ..*s });
        }
    }
    out
}

impl Cloud {
    /// The points at `keep` (ascending indices) with every attribute, radii multiplied by
    /// `radius_scale(i)`; faces and lines dropped. Every field is listed so that a new per-point field of
    /// `Cloud` is a compile error here rather than silently misaligned.
    pub fn select(&self, keep: &[usize], radius_scale: impl Fn(usize) -> f32) -> Cloud {
        let mut out = Cloud {
            positions: keep.iter().map(|&i| self.positions[i]).collect(),
            normals: self
                .normals
                .as_ref()
                .map(|v| keep.iter().map(|&i| v[i]).collect()),
            colors: self
                .colors
                .as_ref()
                .map(|v| keep.iter().map(|&i| v[i]).collect()),
            radii: self
                .radii
                .as_ref()
                .map(|v| keep.iter().map(|&i| v[i] * radius_scale(i)).collect()),
            scalars: self.scalars.clone(),
            faces: None,
            lines: None,
            sensors: remap_sensors(&self.sensors, keep),
            up: self.up,
            survey: self.survey,
            origin: self.origin,
            stats: self.stats.clone(),
        };
        for s in &mut out.scalars {
            s.values = keep.iter().map(|&i| s.values[i]).collect();
        }
        out
    }

    /// The points of `parts` one after another, in the first part's frame (every part must
    /// share its origin): a per-point field is kept when every part has it, a scalar field
    /// when every part has one of its name; faces, lines and sensors are dropped.
    pub fn concat(parts: Vec<Cloud>) -> Cloud {
        let Some(first) = parts.first() else {
            return Cloud::default();
        };
        let all = |has: &dyn Fn(&Cloud) -> bool| parts.iter().all(has);
        let keep_normals = all(&|c| c.normals.is_some());
        let keep_colors = all(&|c| c.colors.is_some());
        let keep_radii = all(&|c| c.radii.is_some());
        let names: Vec<String> = first
            .scalars
            .iter()
            .map(|s| s.name.clone())
            .filter(|n| all(&|c| c.scalars.iter().any(|s| &s.name == n)))
            .collect();
        let mut out = Cloud {
            normals: keep_normals.then(Vec::new),
            colors: keep_colors.then(Vec::new),
            radii: keep_radii.then(Vec::new),
            scalars: names
                .iter()
                .map(|name| Scalar {
                    name: name.clone(),
                    values: Vec::new(),
                })
                .collect(),
            origin: first.origin,
            up: first.up,
            survey: first.survey,
            ..Cloud::default()
        };
        for part in parts {
            out.positions.extend(part.positions);
            if let (Some(o), Some(p)) = (out.normals.as_mut(), part.normals) {
                o.extend(p);
            }
            if let (Some(o), Some(p)) = (out.colors.as_mut(), part.colors) {
                o.extend(p);
            }
            if let (Some(o), Some(p)) = (out.radii.as_mut(), part.radii) {
                o.extend(p);
            }
            for s in &mut out.scalars {
                let values = part
                    .scalars
                    .iter()
                    .find(|p| p.name == s.name)
                    .map(|p| p.values.as_slice())
                    .unwrap_or_default();
                s.values.extend_from_slice(values);
            }
        }
        out
    }

    /// Moves scalar fields that hold geometry into place: three normal components (named
    /// `NormalX`/`nx`/`normal_x` and so on, in any case), or the two 16-bit octahedral
    /// coordinates `surfel convert` writes, become `normals`, a field named `radius` becomes
    /// `radii`. LAS and COPC files carry them as extra bytes.
    pub fn adopt_geometry_fields(&mut self) {
        let find = |scalars: &[Scalar], names: &[&str]| {
            scalars.iter().position(|s| {
                let lower = s.name.to_ascii_lowercase();
                names.contains(&lower.as_str())
            })
        };
        let axes = [
            ["normalx", "normal_x", "nx"],
            ["normaly", "normal_y", "ny"],
            ["normalz", "normal_z", "nz"],
        ];
        let oct = super::octahedral::NORMAL_OCT;
        if self.normals.is_none() && oct.iter().all(|n| find(&self.scalars, &[n]).is_some()) {
            let mut take = |name: &str| {
                let at = find(&self.scalars, &[name]).expect("checked above");
                self.scalars.remove(at).values
            };
            let (u, v) = (take(oct[0]), take(oct[1]));
            self.normals = Some(
                u.iter()
                    .zip(&v)
                    .map(|(&u, &v)| {
                        let e = Vec2::new(
                            super::octahedral::from_unorm16(u),
                            super::octahedral::from_unorm16(v),
                        );
                        super::octahedral::from_octahedral(e)
                    })
                    .collect(),
            );
        }
        if self.normals.is_none() && axes.iter().all(|a| find(&self.scalars, a).is_some()) {
            let mut take = |names: &[&str]| {
                let at = find(&self.scalars, names).expect("checked above");
                self.scalars.remove(at).values
            };
            let [x, y, z] = axes.map(|a| take(&a));
            self.normals = Some(
                x.iter()
                    .zip(&y)
                    .zip(&z)
                    .map(|((&x, &y), &z)| Vec3::new(x, y, z).normalize_or_zero())
                    .collect(),
            );
        }
        if self.radii.is_none() {
            if let Some(at) = find(&self.scalars, &["radius"]) {
                self.radii = Some(self.scalars.remove(at).values);
            }
        }
    }

    pub fn len(&self) -> usize {
        self.positions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Axis-aligned bounds of the positions, `None` for an empty cloud.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .par_iter()
                .fold(|| (first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)))
                .reduce(|| (first, first), |a, b| (a.0.min(b.0), a.1.max(b.1))),
        )
    }

    /// Centre and radius of the sphere around the bounding box (the default camera frames it).
    pub fn bounding_sphere(&self) -> Option<(Vec3, f32)> {
        let (lo, hi) = self.bounds()?;
        let centre = (lo + hi) * 0.5;
        Some((centre, ((hi - lo).length() * 0.5).max(f32::MIN_POSITIVE)))
    }

    /// Counts exact duplicate positions (bitwise equal coordinates, with -0 equal to +0): the
    /// positions are sorted in parallel, so it takes O(n log n) time and 12 bytes per point.
    pub fn duplicates(&self) -> Duplicates {
        let mut keys: Vec<[u32; 3]> = self
            .positions
            .par_iter()
            .map(|p| (*p + Vec3::ZERO).to_array().map(f32::to_bits))
            .collect();
        keys.par_sort_unstable();
        let (points, positions) = keys
            .par_windows(2)
            .enumerate()
            .filter(|(_, w)| w[0] == w[1])
            .map(|(i, w)| (1, usize::from(i == 0 || keys[i - 1] != w[0])))
            .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        Duplicates { points, positions }
    }

    /// Removes every point with a NaN or infinite coordinate, together with its normal, color,
    /// radius and scalar values. Faces that used a removed point are removed; the others are
    /// re-indexed. Adds the number of removed points to `stats.dropped_non_finite` and returns it.
    pub fn retain_finite(&mut self) -> usize {
        if self.positions.par_iter().all(|p| p.is_finite()) {
            return 0;
        }
        let keep: Vec<bool> = self.positions.iter().map(|p| p.is_finite()).collect();
        let dropped = keep.iter().filter(|k| !**k).count();
        fn filter<T: Copy>(values: &mut Vec<T>, keep: &[bool]) {
            if values.len() == keep.len() {
                let mut i = 0;
                values.retain(|_| {
                    i += 1;
                    keep[i - 1]
                });
            }
        }
        filter(&mut self.positions, &keep);
        if let Some(normals) = &mut self.normals {
            filter(normals, &keep);
        }
        if let Some(colors) = &mut self.colors {
            filter(colors, &keep);
        }
        if let Some(radii) = &mut self.radii {
            filter(radii, &keep);
        }
        for scalar in &mut self.scalars {
            filter(&mut scalar.values, &keep);
        }
        if let Some(faces) = &mut self.faces {
            let mut remap = Vec::with_capacity(keep.len());
            let mut next = 0u32;
            for &k in &keep {
                remap.push(if k { Some(next) } else { None });
                next += u32::from(k);
            }
            faces.retain_mut(|face| {
                let mapped = face.map(|i| remap.get(i as usize).copied().flatten());
                match mapped {
                    [Some(a), Some(b), Some(c)] => {
                        *face = [a, b, c];
                        true
                    }
                    _ => false,
                }
            });
        }
        if !self.sensors.is_empty() {
            let kept: Vec<usize> = (0..keep.len()).filter(|&i| keep[i]).collect();
            self.sensors = remap_sensors(&self.sensors, &kept);
        }
        self.stats.dropped_non_finite += dropped;
        dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn concat_keeps_the_fields_every_part_has() {
        let scalar = |name: &str, v: &[f32]| Scalar {
            name: name.into(),
            values: v.to_vec(),
        };
        let a = Cloud {
            positions: vec![Vec3::X, Vec3::Y],
            colors: Some(vec![[1; 4], [2; 4]]),
            radii: Some(vec![0.5, 0.25]),
            scalars: vec![
                scalar("intensity", &[1.0, 2.0]),
                scalar("only_a", &[7.0, 8.0]),
            ],
            origin: DVec3::new(10.0, 0.0, 0.0),
            ..Cloud::default()
        };
        let b = Cloud {
            positions: vec![Vec3::Z],
            colors: Some(vec![[3; 4]]),
            scalars: vec![scalar("intensity", &[3.0])],
            ..Cloud::default()
        };
        let c = Cloud::concat(vec![a, b]);
        assert_eq!(c.positions, vec![Vec3::X, Vec3::Y, Vec3::Z]);
        assert_eq!(c.colors, Some(vec![[1; 4], [2; 4], [3; 4]]));
        assert_eq!(c.radii, None);
        assert_eq!(c.normals, None);
        assert_eq!(c.scalars, vec![scalar("intensity", &[1.0, 2.0, 3.0])]);
        assert_eq!(c.origin, DVec3::new(10.0, 0.0, 0.0));
        assert!(Cloud::concat(Vec::new()).is_empty());
    }

    #[test]
    fn duplicates_count_repeats_and_the_positions_repeated() {
        let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let cloud = Cloud {
            positions: vec![
                p(1.0, 2.0, 3.0),
                p(0.0, 0.0, 0.0),
                p(1.0, 2.0, 3.0),
                p(-0.0, 0.0, -0.0),
                p(1.0, 2.0, 3.0),
                p(1.0, 2.0, 3.000_001),
                p(5.0, 5.0, 5.0),
                p(5.0, 5.0, 5.0),
            ],
            ..Cloud::default()
        };
        // (1,2,3) three times, the origin twice (signed zeros are equal), (5,5,5) twice.
        assert_eq!(
            cloud.duplicates(),
            Duplicates {
                points: 4,
                positions: 3
            }
        );
        assert_eq!(Cloud::default().duplicates(), Duplicates::default());
    }

    #[test]
    fn levels_split_read_and_skipped_points() {
        let levels = Levels {
            points: vec![10, 80, 640],
            read: 2,
        };
        assert_eq!((levels.points_read(), levels.points_skipped()), (90, 640));
    }
}

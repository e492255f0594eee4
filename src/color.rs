//! Color by attribute: which field of a cloud the albedo comes from, and how its values map to
//! colors. The mapping itself runs in the shaders (`stream_albedo` in `glsl/common/streams.glsl`,
//! used by every method); this module resolves a field name against a cloud into the frame
//! uniforms' color mode, value range and axis, and says which one scalar stream the GPU needs.
//!
//! Fields: `rgb` (the file's colors, the default when it has them), `none` (the base color),
//! `elevation` (ramp along the up axis between the cloud's lowest and highest point, the
//! default without colors), `normal` (the unit normal `n * 0.5 + 0.5` as an sRGB color) and
//! every scalar of the cloud by name (also as `scalar:NAME`): `intensity` in grey,
//! `classification` in the ASPRS palette, `return_number` (alias `return`) in the return
//! palette, any other scalar on the ramp. Scalar ranges are robust: the 2nd to 98th percentile.
//! `rgb`, `none` and `elevation` are surface colors, lit wherever the frame has normals; the
//! other attribute colors are unlit, as CloudCompare and Potree show them: the palette color in
//! the image is the color in the legend.

use glam::Vec3;
use rayon::prelude::*;

use crate::layout::*;
use crate::scene::{Cloud, Up};

/// Samples used for a percentile estimate: larger fields are sampled with a fixed stride.
pub const PERCENTILE_SAMPLES: usize = 1 << 20;

/// The color settings of a frame for one field of one cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Coloring {
    /// `COLOR_*`.
    pub mode: u32,
    /// The scalar field (index into `Cloud::scalars`) the mode reads, uploaded as a stream.
    pub scalar: Option<usize>,
    /// Values mapped to the start and the end of the ramp.
    pub range: [f32; 2],
    /// The up axis (elevation).
    pub axis: Vec3,
    /// Shown without lighting (attribute colors).
    pub unlit: bool,
}

impl Coloring {
    /// The file's colors when it has them, else the (lit) base color: what the benchmark and
    /// the evaluation score with, so that lit methods compare shading against `mesh`.
    pub fn default_for(has_colors: bool) -> Self {
        Self {
            mode: if has_colors { COLOR_RGB } else { COLOR_NONE },
            scalar: None,
            range: [0.0, 1.0],
            axis: Vec3::Z,
            unlit: false,
        }
    }

    /// `color_range` of the frame uniforms: start and reciprocal extent.
    pub fn range_uniform(&self) -> [f32; 2] {
        let extent = self.range[1] - self.range[0];
        [self.range[0], if extent > 0.0 { 1.0 / extent } else { 0.0 }]
    }
}

/// The fields `cloud` can be colored by, in the order the viewer cycles them.
pub fn fields(cloud: &Cloud) -> Vec<String> {
    let mut names = Vec::new();
    if cloud.colors.is_some() {
        names.push("rgb".to_owned());
    }
    names.extend(["none", "elevation"].map(str::to_owned));
    if cloud.normals.is_some() {
        names.push("normal".to_owned());
    }
    names.extend(cloud.scalars.iter().map(|s| s.name.clone()));
    names
}

/// The field after `current` in `fields` (cyclically; the first when `current` is not there).
pub fn next_field<'a>(fields: &'a [String], current: &str) -> Option<&'a str> {
    let next = fields
        .iter()
        .position(|f| f == current)
        .map_or(0, |i| (i + 1) % fields.len());
    fields.get(next).map(String::as_str)
}

/// The field `cloud` is colored by when none is named: its colours, else (as Potree does)
/// elevation. The choice reads nothing a method adds (estimated normals), so every method
/// shows a file in the same colors.
pub fn default_field(cloud: &Cloud) -> &'static str {
    if cloud.colors.is_some() {
        "rgb"
    } else {
        "elevation"
    }
}

/// Resolves `name` (a field of [`fields`], `scalar:NAME` or `return`) for `cloud`, whose up axis
/// is `up`. An unknown name is an error listing the fields of this cloud.
pub fn select(cloud: &Cloud, name: &str, up: Up) -> Result<Coloring, String> {
    // A mode on its own, lit; palette and scalar modes override `unlit` (and the range).
    let lit = |mode| Coloring {
        mode,
        scalar: None,
        range: [0.0, 1.0],
        axis: up.vector(),
        unlit: false,
    };
    let unknown = || {
        format!(
            "--color-by '{name}': no such field; this file has: {}",
            fields(cloud).join(", ")
        )
    };
    let field = name.strip_prefix("scalar:");
    match (field, name) {
        (None, "rgb") if cloud.colors.is_some() => return Ok(lit(COLOR_RGB)),
        (None, "none") => return Ok(lit(COLOR_NONE)),
        (None, "elevation") => {
            let axis = up.vector();
            let (lo, hi) = cloud
                .positions
                .par_iter()
                .map(|p| p.dot(axis))
                .fold(
                    || (f32::INFINITY, f32::NEG_INFINITY),
                    |(lo, hi), v| (lo.min(v), hi.max(v)),
                )
                .reduce(
                    || (f32::INFINITY, f32::NEG_INFINITY),
                    |a, b| (a.0.min(b.0), a.1.max(b.1)),
                );
            let range = if lo <= hi { [lo, hi] } else { [0.0, 1.0] };
            return Ok(Coloring {
                range,
                ..lit(COLOR_ELEVATION)
            });
        }
        (None, "normal") if cloud.normals.is_some() => {
            return Ok(Coloring {
                unlit: true,
                ..lit(COLOR_NORMAL)
            })
        }
        _ => {}
    }
    let wanted = match field.unwrap_or(name) {
        "return" if field.is_none() => "return_number",
        other => other,
    };
    let index = cloud
        .scalars
        .iter()
        .position(|s| s.name == wanted)
        .ok_or_else(unknown)?;
    let values = &cloud.scalars[index].values;
    let mode = match wanted {
        "intensity" => COLOR_INTENSITY,
        "classification" => COLOR_CLASSIFICATION,
        "return_number" => COLOR_RETURN,
        _ => COLOR_SCALAR,
    };
    let range = match mode {
        COLOR_INTENSITY | COLOR_SCALAR => robust_range(values),
        _ => [0.0, 1.0],
    };
    Ok(Coloring {
        mode,
        scalar: Some(index),
        range,
        axis: up.vector(),
        unlit: true,
    })
}

/// The 2nd and 98th percentiles of the finite `values` (of an evenly strided sample of
/// [`PERCENTILE_SAMPLES`] for larger fields); the full minimum and maximum when those two
/// coincide; `[0, 1]` when no value is finite.
pub fn robust_range(values: &[f32]) -> [f32; 2] {
    let stride = values.len().div_ceil(PERCENTILE_SAMPLES).max(1);
    let mut sample: Vec<f32> = values
        .iter()
        .step_by(stride)
        .copied()
        .filter(|v| v.is_finite())
        .collect();
    if sample.is_empty() {
        return [0.0, 1.0];
    }
    let last = sample.len() - 1;
    let at = |q: f64| ((q * last as f64).round() as usize).min(last);
    let (lo_at, hi_at) = (at(0.02), at(0.98));
    let hi = *sample.select_nth_unstable_by(hi_at, f32::total_cmp).1;
    let lo = *sample[..=hi_at]
        .select_nth_unstable_by(lo_at, f32::total_cmp)
        .1;
    if lo < hi {
        return [lo, hi];
    }
    let (min, max) = min_max(values);
    [min, max]
}

/// Minimum and maximum of the finite values (`(0, 0)` when there is none).
pub fn min_max(values: &[f32]) -> (f32, f32) {
    let (lo, hi) = values
        .par_iter()
        .filter(|v| v.is_finite())
        .fold(
            || (f32::INFINITY, f32::NEG_INFINITY),
            |(lo, hi), &v| (lo.min(v), hi.max(v)),
        )
        .reduce(
            || (f32::INFINITY, f32::NEG_INFINITY),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        );
    if lo <= hi {
        (lo, hi)
    } else {
        (0.0, 0.0)
    }
}

/// The ASPRS standard class names (LAS 1.4 R15, table 17) and palette, classes 0-18.
const CLASSES: [(&str, u32); 19] = [
    ("created, never classified", CLASS_COLOR_0),
    ("unclassified", CLASS_COLOR_1),
    ("ground", CLASS_COLOR_2),
    ("low vegetation", CLASS_COLOR_3),
    ("medium vegetation", CLASS_COLOR_4),
    ("high vegetation", CLASS_COLOR_5),
    ("building", CLASS_COLOR_6),
    ("low point (noise)", CLASS_COLOR_7),
    ("reserved (model key-point)", CLASS_COLOR_8),
    ("water", CLASS_COLOR_9),
    ("rail", CLASS_COLOR_10),
    ("road surface", CLASS_COLOR_11),
    ("reserved (overlap)", CLASS_COLOR_12),
    ("wire guard (shield)", CLASS_COLOR_13),
    ("wire conductor (phase)", CLASS_COLOR_14),
    ("transmission tower", CLASS_COLOR_15),
    ("wire-structure connector", CLASS_COLOR_16),
    ("bridge deck", CLASS_COLOR_17),
    ("high noise", CLASS_COLOR_18),
];

/// The sRGB color of the scalar ramp at `t` in 0..=1 (clamped), interpolated in sRGB as the
/// shader's `ramp` does; `COLOR_INTENSITY` is grey instead (`ramp_color`).
pub fn ramp(t: f32) -> [u8; 3] {
    const STOPS: [u32; 5] = [RAMP_0, RAMP_1, RAMP_2, RAMP_3, RAMP_4];
    let x = if t.is_nan() {
        0.0
    } else {
        t.clamp(0.0, 1.0) * 4.0
    };
    let k = (x as usize).min(3);
    let (a, b) = (rgb8(STOPS[k]), rgb8(STOPS[k + 1]));
    let f = x - k as f32;
    std::array::from_fn(|i| {
        (f32::from(a[i]) + (f32::from(b[i]) - f32::from(a[i])) * f).round() as u8
    })
}

/// The color mode's ramp at `t` (a grey ramp for intensity), `None` for modes without one.
pub fn ramp_color(mode: u32, t: f32) -> Option<[u8; 3]> {
    match mode {
        COLOR_SCALAR | COLOR_ELEVATION => Some(ramp(t)),
        COLOR_INTENSITY => {
            let v = (t.clamp(0.0, 1.0) * 255.0).round() as u8;
            Some([v; 3])
        }
        _ => None,
    }
}

/// An sRGB 0xRRGGBB constant as bytes.
pub fn rgb8(c: u32) -> [u8; 3] {
    [(c >> 16) as u8, (c >> 8) as u8, c as u8]
}

/// The palette color of classification `class` (as the shader picks it).
pub fn class_color(class: u32) -> [u8; 3] {
    rgb8(
        CLASSES
            .get(class as usize)
            .map_or(CLASS_COLOR_OTHER, |c| c.1),
    )
}

/// The palette color of return number `number` (as the shader picks it).
pub fn return_color(number: u32) -> [u8; 3] {
    rgb8(match number {
        0 => RETURN_COLOR_0,
        1 => RETURN_COLOR_1,
        2 => RETURN_COLOR_2,
        3 => RETURN_COLOR_3,
        4 => RETURN_COLOR_4,
        _ => RETURN_COLOR_5,
    })
}

/// One line of the classification legend.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LegendEntry {
    pub class: u32,
    pub name: String,
    pub color: [u8; 3],
    /// Points of this class.
    pub count: usize,
}

/// The classes present in `cloud`'s `classification` field, ascending, with their names,
/// palette colors and point counts (for the HUD's legend). Values that are not whole numbers
/// in 0..=255 are counted under one "other" entry (class 256). Empty without the field.
pub fn legend(cloud: &Cloud) -> Vec<LegendEntry> {
    let Some(field) = cloud.scalars.iter().find(|s| s.name == "classification") else {
        return Vec::new();
    };
    let counts = field
        .values
        .par_iter()
        .fold(
            || vec![0usize; 257],
            |mut counts, &v| {
                let valid = (0.0..=255.0).contains(&v) && v.fract() == 0.0;
                counts[if valid { v as usize } else { 256 }] += 1;
                counts
            },
        )
        .reduce(
            || vec![0usize; 257],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        );
    counts
        .iter()
        .enumerate()
        .filter(|(_, &n)| n > 0)
        .map(|(class, &count)| legend_entry(class as u32, count))
        .collect()
}

/// The legend line of `count` points of `class` (256: values that are not classes).
pub fn legend_entry(class: u32, count: usize) -> LegendEntry {
    LegendEntry {
        class,
        name: CLASSES
            .get(class as usize)
            .map_or_else(|| "other".to_owned(), |c| c.0.to_owned()),
        color: class_color(class),
        count,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scalar;

    fn cloud(scalars: Vec<(&str, Vec<f32>)>, colors: bool) -> Cloud {
        let n = scalars.first().map_or(3, |s| s.1.len());
        Cloud {
            positions: (0..n).map(|i| Vec3::new(0.0, 0.0, i as f32)).collect(),
            colors: colors.then(|| vec![[1, 2, 3, 255]; n]),
            scalars: scalars
                .into_iter()
                .map(|(name, values)| Scalar {
                    name: name.to_owned(),
                    values,
                })
                .collect(),
            ..Default::default()
        }
    }

    #[test]
    fn robust_range_takes_the_2nd_and_98th_percentiles() {
        // 0..=100 with two wild outliers: the percentiles ignore them.
        let mut values: Vec<f32> = (0..=100).map(|v| v as f32).collect();
        values.extend([-1e6, 1e6, f32::NAN]);
        // 103 finite values: ranks round(0.02 * 102) = 2 and round(0.98 * 102) = 100 of the
        // sorted [-1e6, 0, 1, ..., 100, 1e6].
        assert_eq!(robust_range(&values), [1.0, 99.0]);
        // A field that is constant but for a few points falls back to its min and max.
        let mut flat = vec![5.0; 1000];
        flat[3] = 7.0;
        assert_eq!(robust_range(&flat), [5.0, 7.0]);
        assert_eq!(robust_range(&[f32::NAN]), [0.0, 1.0]);
        // Large fields are sampled with a stride: a uniform ramp keeps its percentiles.
        let big: Vec<f32> = (0..3 * PERCENTILE_SAMPLES).map(|v| v as f32).collect();
        let [lo, hi] = robust_range(&big);
        let n = big.len() as f32;
        assert!((lo / n - 0.02).abs() < 1e-3 && (hi / n - 0.98).abs() < 1e-3);
    }

    #[test]
    fn names_resolve_to_modes_and_unknown_names_list_the_fields() {
        let c = cloud(
            vec![
                ("intensity", vec![0.0, 50.0, 100.0]),
                ("classification", vec![2.0, 6.0, 2.0]),
                ("return_number", vec![1.0, 2.0, 1.0]),
                ("Deviation", vec![-1.0, 0.0, 1.0]),
            ],
            true,
        );
        let s = |name| select(&c, name, Up::Z).unwrap();
        assert_eq!(s("rgb").mode, COLOR_RGB);
        assert!(!s("rgb").unlit && s("rgb").scalar.is_none());
        assert_eq!(s("intensity").mode, COLOR_INTENSITY);
        assert_eq!(s("intensity").scalar, Some(0));
        assert_eq!(s("intensity").range, [0.0, 100.0]);
        assert_eq!(s("classification").mode, COLOR_CLASSIFICATION);
        assert_eq!(s("return").scalar, Some(2));
        assert_eq!(s("return").mode, COLOR_RETURN);
        assert_eq!(s("scalar:Deviation").mode, COLOR_SCALAR);
        assert_eq!(s("Deviation").scalar, Some(3));
        assert_eq!(s("elevation").range, [0.0, 2.0]);
        assert_eq!(s("elevation").axis, Vec3::Z);
        assert!(!s("elevation").unlit);
        let e = select(&c, "bogus", Up::Z).unwrap_err();
        assert_eq!(
            e,
            "--color-by 'bogus': no such field; this file has: rgb, none, elevation, \
             intensity, classification, return_number, Deviation"
        );
        let all = fields(&c);
        assert_eq!(next_field(&all, "rgb"), Some("none"));
        assert_eq!(next_field(&all, "Deviation"), Some("rgb"));
        assert_eq!(next_field(&all, "gone"), Some("rgb"));
        assert_eq!(next_field(&[], "rgb"), None);
        // No colors, no `rgb`.
        let plain = cloud(vec![], false);
        assert!(select(&plain, "rgb", Up::Y).is_err());
        // Without colors, elevation (as Potree), with normals or without.
        assert_eq!(default_field(&plain), "elevation");
        let lit = Cloud {
            normals: Some(vec![Vec3::Z; plain.len()]),
            ..plain
        };
        assert_eq!(default_field(&lit), "elevation");
        assert_eq!(default_field(&c), "rgb");
    }

    #[test]
    fn legend_lists_the_classes_present() {
        let c = cloud(
            vec![("classification", vec![6.0, 2.0, 2.0, 40.0, 2.5])],
            false,
        );
        let l = legend(&c);
        let lines: Vec<_> = l
            .iter()
            .map(|e| (e.class, e.name.as_str(), e.color, e.count))
            .collect();
        assert_eq!(
            lines,
            vec![
                (2, "ground", [0xa0, 0x72, 0x4a], 2),
                (6, "building", [0xdc, 0x5a, 0x46], 1),
                (40, "other", [255, 255, 255], 1),
                (256, "other", [255, 255, 255], 1),
            ]
        );
        assert_eq!(return_color(7), return_color(5));
        assert!(legend(&cloud(vec![], false)).is_empty());
    }
}

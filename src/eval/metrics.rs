//! Image metrics comparing a method's [`Frame`] with the ground truth's.
//!
//! Conventions shared by every metric:
//! - Both frames must have the same size and well-formed planes (`color`, `depth` and, when
//!   present, `normal` hold `width * height` entries); otherwise the metric is a
//!   [`MetricError`].
//! - A metric that is undefined for the input (zero-size frames, nothing covered, no normal
//!   map) is `Ok(None)` rather than a panic or a NaN.
//! - Color metrics composite over black: an empty pixel (alpha 0) counts as RGB `(0, 0, 0)`
//!   whatever its stored RGB, so holes cost accuracy against a covered reference.

use image::RgbaImage;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::frame::Frame;

/// The PSNR reported for identical images (whose true PSNR is infinite). Capping keeps the
/// value finite, so it survives JSON (which has no infinity) and plots on a linear axis.
pub const PSNR_CAP_DB: f64 = 100.0;

/// Gain applied to absolute channel differences by [`difference_image`].
pub const DIFF_GAIN: u16 = 4;

/// A hole ratio above this fraction of the reference coverage marks a stressed method as
/// broken (see [`crate::eval::results::stability`]).
pub const BREAK_HOLE_RATIO: f64 = 0.01;

/// Below this mean per-channel change (in 8-bit levels per pixel) a ground-truth sequence is
/// treated as static by [`temporal_flicker`].
pub const FLICKER_STATIC_EPS: f64 = 1e-6;

const SSIM_RADIUS: usize = 5;
const SSIM_WINDOW: usize = 2 * SSIM_RADIUS + 1;
const SSIM_SIGMA: f64 = 1.5;
const SSIM_K1: f64 = 0.01;
const SSIM_K2: f64 = 0.03;
const PEAK_8BIT: f64 = 255.0;

/// Why two frames cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MetricError {
    /// The frames differ in size.
    #[error("frame sizes differ: {a_width}x{a_height} vs {b_width}x{b_height}")]
    SizeMismatch {
        a_width: u32,
        a_height: u32,
        b_width: u32,
        b_height: u32,
    },
    /// A plane's length is not `width * height`.
    #[error("{plane} plane has {len} entries, expected {expected} for a {width}x{height} frame")]
    MalformedPlane {
        plane: &'static str,
        len: usize,
        expected: usize,
        width: u32,
        height: u32,
    },
    /// A frame sequence is too short or the two sequences differ in length.
    #[error("frame sequences need equal lengths of at least 2, got {method} and {truth}")]
    SequenceLength { method: usize, truth: usize },
}

/// Every metric of one method frame against its reference; `None` where a metric is undefined
/// for the input (see the field docs).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Scores {
    /// PSNR of the lit RGB color over all pixels, dB, capped at [`PSNR_CAP_DB`].
    pub psnr: Option<f64>,
    /// Mean SSIM of luma over all 11x11 windows; `None` for frames smaller than 11x11.
    pub ssim: Option<f64>,
    /// PSNR of the normal maps mapped to [0, 1], dB; `None` unless both frames have one.
    pub normal_psnr: Option<f64>,
    /// Fraction of reference-covered pixels the method left empty.
    pub hole_ratio: Option<f64>,
    /// Intersection over union of the two coverage masks.
    pub iou: Option<f64>,
    /// Symmetric mean distance between the masks' boundaries, pixels.
    pub boundary_px: Option<f64>,
    /// Mean of `|d - d_ref| / d_ref` over pixels covered in both.
    pub depth_rel_mean: Option<f64>,
    /// RMS of `(d - d_ref) / d_ref` over pixels covered in both.
    pub depth_rel_rms: Option<f64>,
    /// Temporal flicker ratio ([`temporal_flicker`]); set by the caller that renders the orbit,
    /// never by [`score`].
    pub flicker: Option<f64>,
}

impl Scores {
    /// Number of fields, for [`Scores::fields`].
    pub const FIELD_COUNT: usize = 9;

    /// `(name, value)` of every field in declaration order (the names are the serde keys).
    pub fn fields(&self) -> [(&'static str, Option<f64>); Self::FIELD_COUNT] {
        [
            ("psnr", self.psnr),
            ("ssim", self.ssim),
            ("normal_psnr", self.normal_psnr),
            ("hole_ratio", self.hole_ratio),
            ("iou", self.iou),
            ("boundary_px", self.boundary_px),
            ("depth_rel_mean", self.depth_rel_mean),
            ("depth_rel_rms", self.depth_rel_rms),
            ("flicker", self.flicker),
        ]
    }
}

/// Scores `method` against `reference` with every single-frame metric.
pub fn score(method: &Frame, reference: &Frame) -> Result<Scores, MetricError> {
    check_pair(method, reference)?;
    let depth = depth_error(method, reference)?;
    Ok(Scores {
        psnr: psnr_color(method, reference)?,
        ssim: ssim(method, reference)?,
        normal_psnr: psnr_normal(method, reference)?,
        hole_ratio: hole_ratio(method, reference)?,
        iou: iou(method, reference)?,
        boundary_px: boundary_distance(method, reference)?,
        depth_rel_mean: depth.map(|d| d.mean_rel),
        depth_rel_rms: depth.map(|d| d.rms_rel),
        flicker: None,
    })
}

/// Checks that a frame's planes match its size.
pub fn check_frame(frame: &Frame) -> Result<(), MetricError> {
    let expected = frame.pixels();
    let planes = [
        ("color", Some(frame.color.len())),
        ("depth", Some(frame.depth.len())),
        ("normal", frame.normal.as_ref().map(Vec::len)),
    ];
    for (plane, len) in planes {
        if let Some(len) = len.filter(|&len| len != expected) {
            return Err(MetricError::MalformedPlane {
                plane,
                len,
                expected,
                width: frame.width,
                height: frame.height,
            });
        }
    }
    Ok(())
}

fn check_pair(a: &Frame, b: &Frame) -> Result<(), MetricError> {
    if (a.width, a.height) != (b.width, b.height) {
        return Err(MetricError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    check_frame(a)?;
    check_frame(b)
}

/// RGB of a pixel composited over black.
fn rgb(frame: &Frame, i: usize) -> [u8; 3] {
    let [r, g, b, a] = frame.color[i];
    if a == 0 {
        [0, 0, 0]
    } else {
        [r, g, b]
    }
}

/// PSNR from a mean squared error, capped at [`PSNR_CAP_DB`].
fn psnr_from_mse(mse: f64, peak: f64) -> f64 {
    if mse <= 0.0 {
        return PSNR_CAP_DB;
    }
    (10.0 * (peak * peak / mse).log10()).min(PSNR_CAP_DB)
}

/// PSNR of the lit RGB color (peak 255) over all pixels; `None` for zero-size frames.
pub fn psnr_color(method: &Frame, reference: &Frame) -> Result<Option<f64>, MetricError> {
    check_pair(method, reference)?;
    let n = method.pixels();
    if n == 0 {
        return Ok(None);
    }
    let sse: u64 = (0..n)
        .into_par_iter()
        .map(|i| {
            let (a, b) = (rgb(method, i), rgb(reference, i));
            (0..3)
                .map(|c| {
                    let d = i64::from(a[c]) - i64::from(b[c]);
                    (d * d) as u64
                })
                .sum::<u64>()
        })
        .sum();
    let mse = sse as f64 / (3 * n) as f64;
    Ok(Some(psnr_from_mse(mse, PEAK_8BIT)))
}

/// PSNR of the normal maps, each component mapped from [-1, 1] to [0, 1] (peak 1) over all
/// pixels; an empty pixel (no finite depth) counts as `(0, 0, 0)` after the mapping. `None`
/// unless both frames have a normal map, or for zero-size frames.
pub fn psnr_normal(method: &Frame, reference: &Frame) -> Result<Option<f64>, MetricError> {
    check_pair(method, reference)?;
    let (Some(na), Some(nb)) = (&method.normal, &reference.normal) else {
        return Ok(None);
    };
    let n = method.pixels();
    if n == 0 {
        return Ok(None);
    }
    let mapped = |frame: &Frame, normals: &[[f32; 3]], i: usize, c: usize| -> f64 {
        if frame.covered(i) {
            ((f64::from(normals[i][c]) + 1.0) * 0.5).clamp(0.0, 1.0)
        } else {
            0.0
        }
    };
    let sse: f64 = (0..n)
        .into_par_iter()
        .map(|i| {
            (0..3)
                .map(|c| {
                    let d = mapped(method, na, i, c) - mapped(reference, nb, i, c);
                    d * d
                })
                .sum::<f64>()
        })
        .sum();
    Ok(Some(psnr_from_mse(sse / (3 * n) as f64, 1.0)))
}

/// Luma `Y = 0.299 R + 0.587 G + 0.114 B` of the sRGB values (composited over black).
fn luma(frame: &Frame) -> Vec<f64> {
    (0..frame.pixels())
        .into_par_iter()
        .map(|i| {
            let [r, g, b] = rgb(frame, i);
            0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b)
        })
        .collect()
}

fn gaussian_window() -> [f64; SSIM_WINDOW] {
    let mut w = [0.0; SSIM_WINDOW];
    for (k, v) in w.iter_mut().enumerate() {
        let x = k as f64 - SSIM_RADIUS as f64;
        *v = (-x * x / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp();
    }
    let sum: f64 = w.iter().sum();
    w.iter_mut().for_each(|v| *v /= sum);
    w
}

/// Mean SSIM (Wang et al. 2004) of the luma planes: 11x11 Gaussian window (sigma 1.5),
/// K1 = 0.01, K2 = 0.03, dynamic range 255, averaged over every window that lies entirely
/// inside the image. `None` for frames smaller than 11x11.
pub fn ssim(method: &Frame, reference: &Frame) -> Result<Option<f64>, MetricError> {
    check_pair(method, reference)?;
    let (w, h) = (method.width as usize, method.height as usize);
    if w < SSIM_WINDOW || h < SSIM_WINDOW {
        return Ok(None);
    }
    Ok(Some(ssim_luma(&luma(method), &luma(reference), w, h)))
}

/// Mean SSIM of two `w x h` planes (both at least 11x11).
fn ssim_luma(x: &[f64], y: &[f64], w: usize, h: usize) -> f64 {
    let g = gaussian_window();
    let (ow, oh) = (w - SSIM_WINDOW + 1, h - SSIM_WINDOW + 1);
    // Horizontal pass: per row, the five windowed moments at each valid x.
    let mut horizontal = vec![[0.0f64; 5]; ow * h];
    horizontal
        .par_chunks_mut(ow)
        .enumerate()
        .for_each(|(row, out)| {
            let (xr, yr) = (&x[row * w..(row + 1) * w], &y[row * w..(row + 1) * w]);
            for (col, m) in out.iter_mut().enumerate() {
                let mut acc = [0.0; 5];
                for (k, &gk) in g.iter().enumerate() {
                    let (a, b) = (xr[col + k], yr[col + k]);
                    acc[0] += gk * a;
                    acc[1] += gk * b;
                    acc[2] += gk * a * a;
                    acc[3] += gk * b * b;
                    acc[4] += gk * a * b;
                }
                *m = acc;
            }
        });
    let c1 = (SSIM_K1 * PEAK_8BIT).powi(2);
    let c2 = (SSIM_K2 * PEAK_8BIT).powi(2);
    // Vertical pass and the SSIM map, summed per output row.
    let total: f64 = (0..oh)
        .into_par_iter()
        .map(|row| {
            let mut sum = 0.0;
            for col in 0..ow {
                let mut m = [0.0; 5];
                for (k, &gk) in g.iter().enumerate() {
                    let hm = &horizontal[(row + k) * ow + col];
                    for (mi, hi) in m.iter_mut().zip(hm) {
                        *mi += gk * hi;
                    }
                }
                let [mx, my, xx, yy, xy] = m;
                let (vx, vy, cov) = (xx - mx * mx, yy - my * my, xy - mx * my);
                sum += ((2.0 * mx * my + c1) * (2.0 * cov + c2))
                    / ((mx * mx + my * my + c1) * (vx + vy + c2));
            }
            sum
        })
        .sum();
    total / (ow * oh) as f64
}

/// Coverage mask of a frame (finite depth).
fn mask(frame: &Frame) -> Vec<bool> {
    (0..frame.pixels()).map(|i| frame.covered(i)).collect()
}

/// Fraction of the reference's covered pixels that the method left empty; `None` when the
/// reference covers nothing.
pub fn hole_ratio(method: &Frame, reference: &Frame) -> Result<Option<f64>, MetricError> {
    check_pair(method, reference)?;
    let (covered, holes) = (0..reference.pixels())
        .filter(|&i| reference.covered(i))
        .fold((0usize, 0usize), |(c, h), i| {
            (c + 1, h + usize::from(!method.covered(i)))
        });
    Ok((covered > 0).then(|| holes as f64 / covered as f64))
}

/// Intersection over union of the coverage masks; `None` when neither covers anything.
pub fn iou(method: &Frame, reference: &Frame) -> Result<Option<f64>, MetricError> {
    check_pair(method, reference)?;
    let (inter, union) = (0..reference.pixels()).fold((0usize, 0usize), |(i, u), p| {
        let (a, b) = (method.covered(p), reference.covered(p));
        (i + usize::from(a && b), u + usize::from(a || b))
    });
    Ok((union > 0).then(|| inter as f64 / union as f64))
}

/// Boundary pixels of a `w x h` mask: covered pixels with an uncovered 4-neighbour, where
/// pixels outside the image count as uncovered.
fn boundary(mask: &[bool], w: usize, h: usize) -> Vec<bool> {
    let at = |x: isize, y: isize| {
        x >= 0
            && y >= 0
            && (x as usize) < w
            && (y as usize) < h
            && mask[y as usize * w + x as usize]
    };
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            mask[i] && !(at(x - 1, y) && at(x + 1, y) && at(x, y - 1) && at(x, y + 1))
        })
        .collect()
}

/// Squared distance standing in for "no feature" in [`squared_distance_transform`]:
/// larger than any in-image squared distance.
pub const EDT_FAR: f64 = 1e20;

/// One Felzenszwalb–Huttenlocher pass: the lower envelope of the parabolas
/// `(q - p)^2 + f[p]`, evaluated in place at every `q`.
fn edt_1d(f: &mut [f64], v: &mut [usize], z: &mut [f64], out: &mut [f64]) {
    let n = f.len();
    let mut k = 0usize;
    v[0] = 0;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    for q in 1..n {
        let qf = q as f64;
        let intersection = |p: usize| {
            let pf = p as f64;
            ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf))
        };
        let mut s = intersection(v[k]);
        // z[0] is -inf, so the envelope never pops its first parabola.
        while s <= z[k] {
            k -= 1;
            s = intersection(v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    k = 0;
    for (q, o) in out.iter_mut().enumerate() {
        let qf = q as f64;
        while z[k + 1] < qf {
            k += 1;
        }
        let p = v[k] as f64;
        *o = (qf - p) * (qf - p) + f[v[k]];
    }
    f.copy_from_slice(out);
}

/// Runs [`edt_1d`] on every row of a row-major `w`-wide plane.
fn edt_rows(plane: &mut [f64], w: usize) {
    plane.par_chunks_mut(w).for_each_init(
        || (vec![0usize; w], vec![0.0; w + 1], vec![0.0; w]),
        |(v, z, out), row| edt_1d(row, v, z, out),
    );
}

fn transpose(plane: &[f64], w: usize, h: usize) -> Vec<f64> {
    let mut t = vec![0.0; w * h];
    t.par_chunks_mut(h).enumerate().for_each(|(x, col)| {
        for (y, c) in col.iter_mut().enumerate() {
            *c = plane[y * w + x];
        }
    });
    t
}

/// Exact squared Euclidean distance from every pixel of a `w x h` grid to the nearest
/// feature pixel (Felzenszwalb & Huttenlocher 2012, two separable 1-D passes). Every pixel
/// is at least [`EDT_FAR`] when there is no feature at all; empty for a zero-size grid.
pub fn squared_distance_transform(features: &[bool], w: usize, h: usize) -> Vec<f64> {
    if w == 0 || h == 0 {
        return Vec::new();
    }
    let mut plane: Vec<f64> = features
        .iter()
        .map(|&f| if f { 0.0 } else { EDT_FAR })
        .collect();
    edt_rows(&mut plane, w);
    let mut columns = transpose(&plane, w, h);
    edt_rows(&mut columns, h);
    transpose(&columns, h, w)
}

/// Symmetric mean boundary distance in pixels: over the boundary pixels of both coverage
/// masks, the mean Euclidean distance to the nearest boundary pixel of the other mask
/// (`(sum_A d(a, B) + sum_B d(b, A)) / (|A| + |B|)`). A boundary pixel is a covered pixel
/// with an uncovered 4-neighbour (outside the image counts as uncovered). `None` when
/// either mask is empty.
pub fn boundary_distance(method: &Frame, reference: &Frame) -> Result<Option<f64>, MetricError> {
    check_pair(method, reference)?;
    let (w, h) = (method.width as usize, method.height as usize);
    let ba = boundary(&mask(method), w, h);
    let bb = boundary(&mask(reference), w, h);
    if !ba.contains(&true) || !bb.contains(&true) {
        return Ok(None);
    }
    let (da, db) = rayon::join(
        || squared_distance_transform(&ba, w, h),
        || squared_distance_transform(&bb, w, h),
    );
    let directed = |from: &[bool], to_dist: &[f64]| -> (f64, usize) {
        from.iter()
            .zip(to_dist)
            .filter(|(f, _)| **f)
            .fold((0.0, 0), |(s, n), (_, d)| (s + d.sqrt(), n + 1))
    };
    let (sa, na) = directed(&ba, &db);
    let (sb, nb) = directed(&bb, &da);
    Ok(Some((sa + sb) / (na + nb) as f64))
}

/// Relative depth error over the pixels covered in both frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthError {
    /// Mean of `|d - d_ref| / d_ref`.
    pub mean_rel: f64,
    /// Root mean square of `(d - d_ref) / d_ref`.
    pub rms_rel: f64,
    /// Pixels compared.
    pub pixels: usize,
}

/// Relative depth error over pixels covered in both frames with a positive reference depth;
/// `None` when there are none.
pub fn depth_error(method: &Frame, reference: &Frame) -> Result<Option<DepthError>, MetricError> {
    check_pair(method, reference)?;
    let (sum, sum_sq, pixels) = (0..method.pixels())
        .into_par_iter()
        .filter_map(|i| {
            let (d, r) = (method.depth[i], reference.depth[i]);
            (d.is_finite() && r.is_finite() && r > 0.0)
                .then(|| (f64::from(d) - f64::from(r)) / f64::from(r))
        })
        .map(|e| (e.abs(), e * e, 1usize))
        .reduce(|| (0.0, 0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    Ok((pixels > 0).then(|| DepthError {
        mean_rel: sum / pixels as f64,
        rms_rel: (sum_sq / pixels as f64).sqrt(),
        pixels,
    }))
}

/// Mean absolute per-channel change (8-bit levels) between consecutive frames of a sequence.
fn mean_change(frames: &[Frame]) -> f64 {
    let pairs = frames.windows(2).map(|pair| {
        let (a, b) = (&pair[0], &pair[1]);
        let n = a.pixels();
        if n == 0 {
            return 0.0;
        }
        let total: u64 = (0..n)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (rgb(a, i), rgb(b, i));
                (0..3).map(|c| u64::from(x[c].abs_diff(y[c]))).sum::<u64>()
            })
            .sum();
        total as f64 / (3 * n) as f64
    });
    pairs.sum::<f64>() / (frames.len() - 1) as f64
}

/// Temporal flicker of a method along a slow camera path: the method's mean absolute
/// frame-to-frame color change divided by the ground truth's own mean change over the same
/// poses. 1 means the method changes exactly as much as the scene does; above 1 is flicker.
///
/// When the ground truth is static (mean change below [`FLICKER_STATIC_EPS`]) the ratio is
/// undefined: it is `Some(1.0)` if the method is static too and `None` otherwise.
pub fn temporal_flicker(method: &[Frame], truth: &[Frame]) -> Result<Option<f64>, MetricError> {
    if method.len() != truth.len() || method.len() < 2 {
        return Err(MetricError::SequenceLength {
            method: method.len(),
            truth: truth.len(),
        });
    }
    for (m, t) in method.iter().zip(truth) {
        check_pair(m, t)?;
        check_pair(m, &method[0])?;
    }
    let (m, t) = (mean_change(method), mean_change(truth));
    if t < FLICKER_STATIC_EPS {
        return Ok((m < FLICKER_STATIC_EPS).then_some(1.0));
    }
    Ok(Some(m / t))
}

/// The frame's color as an image (alpha kept), for saving actual/expected pairs.
pub fn color_image(frame: &Frame) -> Result<RgbaImage, MetricError> {
    check_frame(frame)?;
    let bytes = frame.color.iter().flatten().copied().collect();
    RgbaImage::from_raw(frame.width, frame.height, bytes).ok_or(MetricError::MalformedPlane {
        plane: "color",
        len: frame.color.len(),
        expected: frame.pixels(),
        width: frame.width,
        height: frame.height,
    })
}

/// Opaque image of `|a - b|` per RGB channel (colors composited over black), amplified by
/// [`DIFF_GAIN`] and clamped, so small errors are visible.
pub fn difference_image(a: &Frame, b: &Frame) -> Result<RgbaImage, MetricError> {
    check_pair(a, b)?;
    let mut img = RgbaImage::new(a.width, a.height);
    for (i, px) in img.pixels_mut().enumerate() {
        let (x, y) = (rgb(a, i), rgb(b, i));
        let amp = |c: usize| (u16::from(x[c].abs_diff(y[c])) * DIFF_GAIN).min(255) as u8;
        px.0 = [amp(0), amp(1), amp(2), 255];
    }
    Ok(img)
}

/// Non-finite or out-of-contract values found in a frame by [`check_finite`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct FiniteReport {
    /// Depth values that are NaN or negative infinity (positive infinity means "empty").
    pub bad_depth: usize,
    /// Finite depth values that are not positive.
    pub non_positive_depth: usize,
    /// Normals with a NaN or infinite component.
    pub bad_normal: usize,
    /// `(x, y)` of the first offending pixel in row-major order.
    pub first: Option<(u32, u32)>,
}

impl FiniteReport {
    /// True when nothing was found.
    pub fn is_clean(&self) -> bool {
        self.first.is_none()
    }
}

/// Scans a frame for NaN/infinite depth and normal values.
pub fn check_finite(frame: &Frame) -> Result<FiniteReport, MetricError> {
    check_frame(frame)?;
    let mut report = FiniteReport::default();
    for i in 0..frame.pixels() {
        let d = frame.depth[i];
        let bad_depth = d.is_nan() || d == f32::NEG_INFINITY;
        let non_positive = d.is_finite() && d <= 0.0;
        let bad_normal = frame
            .normal
            .as_ref()
            .is_some_and(|n| n[i].iter().any(|c| !c.is_finite()));
        report.bad_depth += usize::from(bad_depth);
        report.non_positive_depth += usize::from(non_positive);
        report.bad_normal += usize::from(bad_normal);
        if (bad_depth || non_positive || bad_normal) && report.first.is_none() {
            let w = frame.width as usize;
            report.first = Some(((i % w) as u32, (i / w) as u32));
        }
    }
    Ok(report)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A `w x h` frame of one color, covered at depth 1 everywhere.
    pub(crate) fn solid(w: u32, h: u32, rgb: [u8; 3]) -> Frame {
        let n = (w * h) as usize;
        Frame {
            width: w,
            height: h,
            color: vec![[rgb[0], rgb[1], rgb[2], 255]; n],
            depth: vec![1.0; n],
            normal: None,
        }
    }

    /// A frame covered (depth 1, white) exactly where `inside(x, y)`.
    pub(crate) fn masked(w: u32, h: u32, inside: impl Fn(u32, u32) -> bool) -> Frame {
        let mut f = solid(w, h, [255, 255, 255]);
        for y in 0..h {
            for x in 0..w {
                if !inside(x, y) {
                    let i = (y * w + x) as usize;
                    f.color[i] = [0, 0, 0, 0];
                    f.depth[i] = f32::INFINITY;
                }
            }
        }
        f
    }

    /// A deterministic textured frame (xorshift noise plus gradients).
    fn textured(w: u32, h: u32, seed: u64) -> Frame {
        let mut f = solid(w, h, [0, 0, 0]);
        let mut s = seed | 1;
        for (i, c) in f.color.iter_mut().enumerate() {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let (x, y) = ((i as u32 % w) as u64, (i as u32 / w) as u64);
            let v = ((s % 64) + x * 3 + y * 2) % 256;
            *c = [v as u8, (255 - v) as u8, ((v * 7) % 256) as u8, 255];
        }
        f
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn psnr_of_a_constant_error_is_known() {
        let a = solid(16, 8, [100, 100, 100]);
        let b = solid(16, 8, [110, 90, 110]);
        let expected = 20.0 * (255.0f64 / 10.0).log10();
        assert!(close(psnr_color(&a, &b).unwrap().unwrap(), expected, 1e-12));
    }

    #[test]
    fn psnr_of_identical_images_is_capped_and_serializable() {
        let a = textured(20, 20, 3);
        assert_eq!(psnr_color(&a, &a).unwrap(), Some(PSNR_CAP_DB));
        let s = score(&a, &a).unwrap();
        let json = serde_json::to_string(&s).unwrap();
        assert_eq!(serde_json::from_str::<Scores>(&json).unwrap(), s);
    }

    #[test]
    fn score_fields_match_the_serde_keys() {
        let s = Scores::default();
        let json = serde_json::to_value(&s).unwrap();
        let keys: Vec<&String> = json.as_object().unwrap().keys().collect();
        assert_eq!(keys.len(), Scores::FIELD_COUNT);
        for (name, _) in s.fields() {
            assert!(keys.iter().any(|k| *k == name), "{name}");
        }
    }

    #[test]
    fn psnr_counts_holes_as_black_whatever_their_rgb() {
        let reference = solid(4, 4, [0, 0, 0]);
        let mut method = solid(4, 4, [0, 0, 0]);
        method.color[0] = [200, 200, 200, 0];
        method.depth[0] = f32::INFINITY;
        assert_eq!(psnr_color(&method, &reference).unwrap(), Some(PSNR_CAP_DB));
    }

    #[test]
    fn zero_size_and_mismatched_frames_do_not_panic() {
        let empty = solid(0, 0, [0, 0, 0]);
        let s = score(&empty, &empty).unwrap();
        assert_eq!(s, Scores::default());
        let err = score(&solid(2, 2, [0; 3]), &solid(3, 2, [0; 3])).unwrap_err();
        assert!(matches!(err, MetricError::SizeMismatch { .. }));
        let mut bad = solid(2, 2, [0; 3]);
        bad.depth.pop();
        let err = score(&bad, &solid(2, 2, [0; 3])).unwrap_err();
        assert!(err.to_string().contains("depth plane has 3 entries"));
    }

    #[test]
    fn ssim_identical_is_one_and_small_frames_are_none() {
        let a = textured(40, 30, 7);
        assert!(close(ssim(&a, &a).unwrap().unwrap(), 1.0, 1e-12));
        let tiny = solid(10, 40, [1, 2, 3]);
        assert_eq!(ssim(&tiny, &tiny).unwrap(), None);
    }

    #[test]
    fn ssim_is_symmetric_and_degrades_with_noise() {
        let a = textured(48, 48, 11);
        let b = textured(48, 48, 12);
        let ab = ssim(&a, &b).unwrap().unwrap();
        let ba = ssim(&b, &a).unwrap().unwrap();
        assert!(close(ab, ba, 1e-12));
        assert!(ab < 0.99);
        // Mild noise scores higher than heavy noise.
        let noisy = |amp: i32| {
            let mut f = a.clone();
            for (i, c) in f.color.iter_mut().enumerate() {
                let d = if i % 2 == 0 { amp } else { -amp };
                for ch in c.iter_mut().take(3) {
                    *ch = (i32::from(*ch) + d).clamp(0, 255) as u8;
                }
            }
            f
        };
        let mild = ssim(&a, &noisy(3)).unwrap().unwrap();
        let heavy = ssim(&a, &noisy(40)).unwrap().unwrap();
        assert!(mild > heavy && mild < 1.0, "mild {mild} heavy {heavy}");
    }

    #[test]
    fn ssim_of_a_luma_shift_on_flat_images_is_the_luminance_term() {
        // Flat images: variances and covariance vanish, so SSIM is the luminance term alone.
        let a = solid(16, 16, [100, 100, 100]);
        let b = solid(16, 16, [120, 120, 120]);
        let c1 = (0.01f64 * 255.0).powi(2);
        let (x, y) = (100.0f64, 120.0f64);
        let expected = (2.0 * x * y + c1) / (x * x + y * y + c1);
        assert!(close(ssim(&a, &b).unwrap().unwrap(), expected, 1e-9));
    }

    #[test]
    fn ssim_matches_a_direct_windowed_evaluation() {
        let (a, b) = (textured(13, 12, 5), textured(13, 12, 9));
        let (la, lb) = (luma(&a), luma(&b));
        let g = gaussian_window();
        let (c1, c2) = ((0.01f64 * 255.0).powi(2), (0.03f64 * 255.0).powi(2));
        let mut total = 0.0;
        for oy in 0..2 {
            for ox in 0..3 {
                let mut m = [0.0; 5];
                for ky in 0..11 {
                    for kx in 0..11 {
                        let wgt = g[ky] * g[kx];
                        let i = (oy + ky) * 13 + ox + kx;
                        let (x, y) = (la[i], lb[i]);
                        m[0] += wgt * x;
                        m[1] += wgt * y;
                        m[2] += wgt * x * x;
                        m[3] += wgt * y * y;
                        m[4] += wgt * x * y;
                    }
                }
                let (vx, vy, cov) = (m[2] - m[0] * m[0], m[3] - m[1] * m[1], m[4] - m[0] * m[1]);
                total += ((2.0 * m[0] * m[1] + c1) * (2.0 * cov + c2))
                    / ((m[0] * m[0] + m[1] * m[1] + c1) * (vx + vy + c2));
            }
        }
        assert!(close(ssim(&a, &b).unwrap().unwrap(), total / 6.0, 1e-12));
    }

    #[test]
    fn normal_psnr_needs_both_maps_and_has_a_known_value() {
        let mut a = solid(4, 4, [0; 3]);
        let mut b = solid(4, 4, [0; 3]);
        assert_eq!(psnr_normal(&a, &b).unwrap(), None);
        a.normal = Some(vec![[0.0, 0.0, 1.0]; 16]);
        assert_eq!(psnr_normal(&a, &b).unwrap(), None);
        // z differs by 0.2 -> mapped difference 0.1 in one of three channels.
        b.normal = Some(vec![[0.0, 0.0, 0.8]; 16]);
        let expected = 10.0 * (1.0 / (0.01f64 / 3.0)).log10();
        let got = psnr_normal(&a, &b).unwrap().unwrap();
        assert!(close(got, expected, 1e-5), "{got} vs {expected}");
    }

    #[test]
    fn hole_ratio_of_a_known_mask() {
        let reference = masked(10, 10, |x, _| x < 5); // 50 covered
        let method = masked(10, 10, |x, y| x < 5 && y >= 2); // misses 10 of them
        assert!(close(
            hole_ratio(&method, &reference).unwrap().unwrap(),
            0.2,
            1e-12
        ));
        let empty = masked(10, 10, |_, _| false);
        assert_eq!(hole_ratio(&method, &empty).unwrap(), None);
    }

    #[test]
    fn iou_of_two_known_rectangles() {
        // [0,6)x[0,4) and [3,9)x[0,4): intersection 12, union 36.
        let a = masked(10, 5, |x, y| x < 6 && y < 4);
        let b = masked(10, 5, |x, y| (3..9).contains(&x) && y < 4);
        assert!(close(iou(&a, &b).unwrap().unwrap(), 12.0 / 36.0, 1e-12));
        let none = masked(10, 5, |_, _| false);
        assert_eq!(iou(&none, &none).unwrap(), None);
    }

    #[test]
    fn boundary_distance_of_concentric_squares() {
        // Outer square [10,30)^2, inner [12,28)^2: offset 2.
        let outer = masked(40, 40, |x, y| {
            (10..30).contains(&x) && (10..30).contains(&y)
        });
        let inner = masked(40, 40, |x, y| {
            (12..28).contains(&x) && (12..28).contains(&y)
        });
        // Every inner boundary pixel is exactly 2 from the outer ring (60 pixels). Of the
        // outer ring's 76 pixels, 64 face an inner edge at 2; each corner has one pixel at
        // sqrt(8) and two at sqrt(5) from the inner corner.
        let outer_sum = 64.0 * 2.0 + 4.0 * (8f64.sqrt() + 2.0 * 5f64.sqrt());
        let expected = (60.0 * 2.0 + outer_sum) / (60.0 + 76.0);
        let got = boundary_distance(&outer, &inner).unwrap().unwrap();
        assert!(close(got, expected, 1e-12), "{got} vs {expected}");
        let same = boundary_distance(&outer, &outer).unwrap().unwrap();
        assert_eq!(same, 0.0);
        let none = masked(40, 40, |_, _| false);
        assert_eq!(boundary_distance(&outer, &none).unwrap(), None);
    }

    #[test]
    fn edt_matches_brute_force_on_random_masks() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for trial in 0..20 {
            let (w, h) = (1 + trial % 7 * 3, 1 + trial % 5 * 4);
            let features: Vec<bool> = (0..w * h)
                .map(|_| {
                    s ^= s << 13;
                    s ^= s >> 7;
                    s ^= s << 17;
                    s.is_multiple_of(5)
                })
                .collect();
            let got = squared_distance_transform(&features, w, h);
            let any = features.contains(&true);
            for (i, &g) in got.iter().enumerate() {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let brute = (0..w * h)
                    .filter(|&j| features[j])
                    .map(|j| {
                        let (fx, fy) = ((j % w) as f64, (j / w) as f64);
                        (x - fx).powi(2) + (y - fy).powi(2)
                    })
                    .fold(f64::INFINITY, f64::min);
                if any {
                    assert_eq!(g, brute, "trial {trial} pixel {i}");
                } else {
                    assert!(g >= EDT_FAR);
                }
            }
        }
        assert!(squared_distance_transform(&[], 0, 3).is_empty());
    }

    #[test]
    fn depth_error_is_known() {
        let reference = masked(4, 1, |x, _| x < 3);
        let mut method = masked(4, 1, |x, _| x > 0);
        // Overlap: pixels 1 and 2 (reference depth 1).
        method.depth[1] = 1.1;
        method.depth[2] = 0.7;
        let d = depth_error(&method, &reference).unwrap().unwrap();
        assert_eq!(d.pixels, 2);
        assert!(close(d.mean_rel, 0.2, 1e-6));
        let rms = ((0.01f64 + 0.09) / 2.0).sqrt();
        assert!(close(d.rms_rel, rms, 1e-6));
        let none = masked(4, 1, |_, _| false);
        assert_eq!(depth_error(&method, &none).unwrap(), None);
    }

    #[test]
    fn flicker_ratio_is_known() {
        let gray = |v: u8| solid(8, 8, [v, v, v]);
        // Truth changes 2 levels per frame, the method alternates by 6.
        let truth = [gray(100), gray(102), gray(104)];
        let method = [gray(100), gray(106), gray(100)];
        let r = temporal_flicker(&method, &truth).unwrap().unwrap();
        assert!(close(r, 3.0, 1e-12));
        let stat = [gray(5), gray(5)];
        assert_eq!(temporal_flicker(&stat, &stat).unwrap(), Some(1.0));
        assert_eq!(temporal_flicker(&[gray(5), gray(9)], &stat).unwrap(), None);
        assert!(temporal_flicker(&stat[..1], &stat[..1]).is_err());
    }

    #[test]
    fn difference_image_amplifies_and_is_opaque() {
        let a = solid(3, 2, [10, 20, 30]);
        let b = solid(3, 2, [12, 20, 200]);
        let img = difference_image(&a, &b).unwrap();
        assert_eq!(img.dimensions(), (3, 2));
        assert_eq!(img.get_pixel(2, 1).0, [8, 0, 255, 255]);
        assert_eq!(
            color_image(&a).unwrap().get_pixel(0, 0).0,
            [10, 20, 30, 255]
        );
    }

    #[test]
    fn check_finite_reports_bad_pixels() {
        let mut f = masked(4, 4, |x, _| x < 2);
        assert!(check_finite(&f).unwrap().is_clean());
        f.depth[6] = f32::NAN;
        f.depth[9] = -1.0;
        f.normal = Some(vec![[0.0, 0.0, 1.0]; 16]);
        f.normal.as_mut().unwrap()[3][1] = f32::INFINITY;
        let r = check_finite(&f).unwrap();
        assert_eq!((r.bad_depth, r.non_positive_depth, r.bad_normal), (1, 1, 1));
        assert_eq!(r.first, Some((3, 0)));
    }

    #[test]
    fn scoring_a_megapixel_frame_is_fast() {
        let a = textured(1024, 1024, 1);
        let b = textured(1024, 1024, 2);
        let start = std::time::Instant::now();
        let s = score(&a, &b).unwrap();
        let elapsed = start.elapsed();
        assert!(s.psnr.is_some() && s.ssim.is_some());
        assert!(elapsed.as_secs_f64() < 1.0, "scoring took {elapsed:?}");
    }
}

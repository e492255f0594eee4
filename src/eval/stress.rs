//! Pure point-cloud transforms for the cloud-side stress sweeps (`subsample`, `noise`,
//! `nonuniform`). The camera-side stresses (`grazing`, `magnification`, `inside`) change the
//! camera, not the cloud.
//!
//! Every transform is deterministic (a fixed seed gives the same cloud on every machine) and
//! keeps the per-point attributes (normals, colors, radii, scalars) aligned with the
//! positions. Transforms that drop points also drop `faces`, whose indices would no longer
//! be valid; the ground truth is rendered from the untransformed mesh.

use glam::Vec3;
use rayon::prelude::*;

use super::config::StressKind;
use crate::rng::SplitMix64;
use crate::scene::cloud::Cloud;

/// Seed used by [`apply`].
pub const DEFAULT_SEED: u64 = 0x5EED_5EED_5EED_5EED;

/// Why a stress transform was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum StressError {
    /// The stress value is outside the kind's range.
    #[error("{kind}: {message}")]
    OutOfRange { kind: StressKind, message: String },
    /// An attribute's length differs from the number of positions.
    #[error("cloud attribute `{attribute}` has {len} entries for {points} points")]
    Misaligned {
        attribute: String,
        len: usize,
        points: usize,
    },
}

/// A generator for point `i` under `seed`: each point's randomness is independent of how
/// the work is split across threads.
fn point_rng(seed: u64, i: usize) -> SplitMix64 {
    let mut mix = SplitMix64::new(seed ^ (i as u64).wrapping_mul(0xD6E8_FEB8_6659_FD93));
    SplitMix64::new(mix.next_u64())
}

fn check_aligned(cloud: &Cloud) -> Result<(), StressError> {
    let points = cloud.len();
    let lens = [
        ("normals", cloud.normals.as_ref().map(Vec::len)),
        ("colors", cloud.colors.as_ref().map(Vec::len)),
        ("radii", cloud.radii.as_ref().map(Vec::len)),
    ];
    let scalars = cloud
        .scalars
        .iter()
        .map(|s| (s.name.as_str(), Some(s.values.len())));
    for (name, len) in lens.into_iter().chain(scalars) {
        if let Some(len) = len.filter(|&l| l != points) {
            return Err(StressError::Misaligned {
                attribute: name.to_string(),
                len,
                points,
            });
        }
    }
    Ok(())
}

/// Keeps `round(fraction * n)` points (at least one of a non-empty cloud), chosen by ranking
/// a per-point hash: deterministic, exact in count and spatially unbiased (unlike a stride,
/// which aliases with the file's scan order). Points keep their original relative order.
///
/// Radii are multiplied by `sqrt(n / kept)`: a splat's area grows by the inverse of the
/// density, so the surface stays covered and the stress measures detail loss, not holes
/// from unchanged splat sizes.
pub fn subsample(cloud: &Cloud, fraction: f64, seed: u64) -> Result<Cloud, StressError> {
    StressKind::Subsample
        .check_value(fraction)
        .map_err(|message| StressError::OutOfRange {
            kind: StressKind::Subsample,
            message,
        })?;
    check_aligned(cloud)?;
    let n = cloud.len();
    let kept = ((fraction * n as f64).round() as usize).clamp(n.min(1), n);
    let mut order: Vec<(u64, usize)> = (0..n)
        .into_par_iter()
        .map(|i| (point_rng(seed, i).next_u64(), i))
        .collect();
    order.par_sort_unstable();
    let mut keep: Vec<usize> = order[..kept].iter().map(|&(_, i)| i).collect();
    keep.par_sort_unstable();
    let scale = if kept > 0 {
        (n as f64 / kept as f64).sqrt() as f32
    } else {
        1.0
    };
    Ok(cloud.select(&keep, |_| scale))
}

/// Adds isotropic Gaussian noise to every position, sigma = `sigma_fraction` x the
/// bounding-box diagonal. Normals, colors, radii and faces are unchanged: the stress isolates
/// positional error from normal estimation.
pub fn noise(cloud: &Cloud, sigma_fraction: f64, seed: u64) -> Result<Cloud, StressError> {
    StressKind::Noise
        .check_value(sigma_fraction)
        .map_err(|message| StressError::OutOfRange {
            kind: StressKind::Noise,
            message,
        })?;
    check_aligned(cloud)?;
    let Some((lo, hi)) = cloud.bounds() else {
        return Ok(cloud.clone());
    };
    let sigma = sigma_fraction * f64::from((hi - lo).length());
    let mut out = cloud.clone();
    out.positions.par_iter_mut().enumerate().for_each(|(i, p)| {
        let mut rng = point_rng(seed, i);
        let mut g = || (rng.next_gaussian() * sigma) as f32;
        *p += Vec3::new(g(), g(), g());
    });
    Ok(out)
}

/// Keep probability of a point at normalised x position `t` in [0, 1] for `contrast`:
/// linear from 1 at `t = 0` to `1 / contrast` at `t = 1`.
pub fn nonuniform_keep_probability(t: f64, contrast: f64) -> f64 {
    1.0 - (1.0 - 1.0 / contrast) * t.clamp(0.0, 1.0)
}

/// Makes the density vary smoothly along x: a point at normalised x position `t` (0 at the
/// bounding box's min x, 1 at its max x) is kept with probability
/// [`nonuniform_keep_probability`], from 100 % down to `1 / contrast`, decided by a per-point
/// hash. Kept radii are multiplied by `sqrt(1 / p)` for the local probability `p`, keeping
/// coverage as [`subsample`] does. A cloud with no x extent, or a contrast of 1, is returned
/// unchanged.
pub fn nonuniform(cloud: &Cloud, contrast: f64, seed: u64) -> Result<Cloud, StressError> {
    StressKind::Nonuniform
        .check_value(contrast)
        .map_err(|message| StressError::OutOfRange {
            kind: StressKind::Nonuniform,
            message,
        })?;
    check_aligned(cloud)?;
    let Some((lo, hi)) = cloud.bounds() else {
        return Ok(cloud.clone());
    };
    let extent = f64::from(hi.x - lo.x);
    if extent <= 0.0 || contrast == 1.0 {
        return Ok(cloud.clone());
    }
    let probability = |i: usize| {
        let t = (f64::from(cloud.positions[i].x) - f64::from(lo.x)) / extent;
        nonuniform_keep_probability(t, contrast)
    };
    let keep: Vec<usize> = (0..cloud.len())
        .into_par_iter()
        .filter(|&i| point_rng(seed, i).next_f64() < probability(i))
        .collect();
    Ok(cloud.select(&keep, |i| (1.0 / probability(i)).sqrt() as f32))
}

/// Applies a cloud-side stress with [`DEFAULT_SEED`]; `Ok(None)` for the camera-side kinds,
/// which leave the cloud alone.
pub fn apply(cloud: &Cloud, kind: StressKind, value: f64) -> Result<Option<Cloud>, StressError> {
    match kind {
        StressKind::Subsample => subsample(cloud, value, DEFAULT_SEED).map(Some),
        StressKind::Noise => noise(cloud, value, DEFAULT_SEED).map(Some),
        StressKind::Nonuniform => nonuniform(cloud, value, DEFAULT_SEED).map(Some),
        StressKind::Grazing | StressKind::Magnification | StressKind::Inside => Ok(None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::cloud::Scalar;

    /// A `side x side` grid in the xy plane over [0, 1]^2 where every attribute encodes the
    /// point index, so alignment can be checked after any selection.
    fn grid(side: usize) -> Cloud {
        let n = side * side;
        let positions: Vec<Vec3> = (0..n)
            .map(|i| {
                let (x, y) = (i % side, i / side);
                Vec3::new(x as f32, y as f32, 0.0) / (side - 1) as f32
            })
            .collect();
        Cloud {
            normals: Some(positions.iter().map(|p| Vec3::new(p.x, p.y, 1.0)).collect()),
            colors: Some((0..n).map(|i| (i as u32).to_le_bytes()).collect()),
            radii: Some((0..n).map(|i| i as f32).collect()),
            scalars: vec![Scalar {
                name: "index".into(),
                values: (0..n).map(|i| i as f32).collect(),
            }],
            faces: Some(vec![[0, 1, 2]]),
            positions,
            ..Cloud::default()
        }
    }

    /// The original index of every point, checked consistent across all attributes.
    fn indices(c: &Cloud, side: usize) -> Vec<usize> {
        (0..c.len())
            .map(|k| {
                let p = c.positions[k] * (side - 1) as f32;
                let i = p.y.round() as usize * side + p.x.round() as usize;
                assert_eq!(c.colors.as_ref().unwrap()[k], (i as u32).to_le_bytes());
                assert_eq!(c.scalars[0].values[k], i as f32);
                let n = c.normals.as_ref().unwrap()[k];
                assert_eq!((n.x, n.y), (c.positions[k].x, c.positions[k].y));
                i
            })
            .collect()
    }

    #[test]
    fn subsample_keeps_the_fraction_aligned_and_scales_radii() {
        let side = 40;
        let c = grid(side);
        let s = subsample(&c, 0.25, 1).unwrap();
        assert_eq!(s.len(), 400);
        assert!(s.faces.is_none());
        let idx = indices(&s, side);
        assert!(idx.windows(2).all(|w| w[0] < w[1]), "order kept");
        for (k, &i) in idx.iter().enumerate() {
            assert_eq!(s.radii.as_ref().unwrap()[k], i as f32 * 2.0);
        }
        // Spread over the cloud, not a block: every quadrant keeps some points.
        for q in 0..4 {
            let count = s
                .positions
                .iter()
                .filter(|p| (p.x >= 0.5) as usize + 2 * ((p.y >= 0.5) as usize) == q)
                .count();
            assert!((70..=130).contains(&count), "quadrant {q}: {count}");
        }
        assert_eq!(subsample(&c, 0.25, 1).unwrap().positions, s.positions);
        assert_ne!(subsample(&c, 0.25, 2).unwrap().positions, s.positions);
        assert_eq!(subsample(&c, 1e-9, 1).unwrap().len(), 1);
        assert_eq!(subsample(&c, 1.0, 1).unwrap().len(), c.len());
        assert!(subsample(&Cloud::default(), 0.5, 1).unwrap().is_empty());
        assert!(subsample(&c, 0.0, 1).is_err());
        assert!(subsample(&c, 1.5, 1).is_err());
    }

    #[test]
    fn noise_has_the_requested_sigma_and_keeps_attributes() {
        let c = grid(100);
        let diag = 2f64.sqrt();
        let s = noise(&c, 0.01, 3).unwrap();
        assert_eq!(s.len(), c.len());
        assert_eq!(s.radii, c.radii);
        assert_eq!(s.colors, c.colors);
        assert_eq!(s.faces, c.faces);
        let d: Vec<f64> = s
            .positions
            .iter()
            .zip(&c.positions)
            .flat_map(|(a, b)| (*a - *b).to_array())
            .map(f64::from)
            .collect();
        let sigma = (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
        assert!((sigma / (0.01 * diag) - 1.0).abs() < 0.03, "sigma {sigma}");
        assert_eq!(noise(&c, 0.0, 3).unwrap().positions, c.positions);
        assert_eq!(noise(&c, 0.01, 3).unwrap().positions, s.positions);
        assert!(noise(&c, -0.1, 3).is_err());
    }

    #[test]
    fn nonuniform_density_falls_along_x() {
        let side = 200;
        let c = grid(side);
        let contrast = 8.0;
        let s = nonuniform(&c, contrast, 5).unwrap();
        let idx = indices(&s, side);
        let band = |lo: f32, hi: f32| {
            let total = c.positions.iter().filter(|p| p.x >= lo && p.x < hi).count();
            let kept = s.positions.iter().filter(|p| p.x >= lo && p.x < hi).count();
            kept as f64 / total as f64
        };
        let (left, right) = (band(0.0, 0.05), band(0.95, 1.01));
        assert!(left > 0.95, "left {left}");
        let p_right = nonuniform_keep_probability(0.975, contrast);
        assert!(
            (right / p_right - 1.0).abs() < 0.15,
            "right {right} vs {p_right}"
        );
        let expected = (1.0 + 1.0 / contrast) / 2.0;
        let fraction = s.len() as f64 / c.len() as f64;
        assert!((fraction - expected).abs() < 0.01, "{fraction}");
        for (k, &i) in idx.iter().enumerate() {
            let t = f64::from(c.positions[i].x);
            let r = (i as f64 / nonuniform_keep_probability(t, contrast).sqrt()) as f32;
            assert!((s.radii.as_ref().unwrap()[k] - r).abs() <= r * 1e-5);
        }
        assert_eq!(nonuniform(&c, 1.0, 5).unwrap().len(), c.len());
        assert!(nonuniform(&c, 0.5, 5).is_err());
    }

    #[test]
    fn misaligned_attributes_are_errors_and_camera_kinds_pass() {
        let mut c = grid(4);
        c.radii.as_mut().unwrap().pop();
        let e = subsample(&c, 0.5, 1).unwrap_err();
        assert_eq!(
            e.to_string(),
            "cloud attribute `radii` has 15 entries for 16 points"
        );
        let c = grid(4);
        assert!(apply(&c, StressKind::Grazing, 45.0).unwrap().is_none());
        assert_eq!(
            apply(&c, StressKind::Subsample, 0.5)
                .unwrap()
                .unwrap()
                .len(),
            8
        );
    }
}

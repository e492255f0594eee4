//! Hybrid scenes (000 §5.2): several inputs merged into one cloud, each kept as triangles or
//! as points. A vertex that a face or a line references is part of the triangles or lines
//! (`pyramid-hybrid` rasterizes them into level 0); every other point is a point. Scene files list the inputs
//! beside the command line's file:
//!
//! ```toml
//! [[inputs]]
//! path = "../shared/data/stanford/happy_buddha_50k.obj"   # relative to the scene file
//! as = "triangles"          # triangles | points (default: triangles when it has faces)
//! translate = [0.3, 0.0, 0.0]
//! scale = 0.2
//! ```

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::{Cloud, Estimator, LoadOptions};

/// How an input joins the scene.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    /// Triangles when the input has faces, else points.
    #[default]
    Auto,
    /// Its faces are dropped: every vertex is a point.
    Points,
    /// Its faces are kept (an input without faces is an error).
    Triangles,
}

/// One extra input of a scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneInput {
    /// The file, relative to the scene file's directory (resolved when the scene file loads).
    pub path: PathBuf,
    #[serde(rename = "as", default)]
    pub role: Role,
    /// Added after scaling, in the first input's frame.
    pub translate: Option<[f32; 3]>,
    /// Uniform scale about the input's own origin.
    pub scale: Option<f32>,
}

/// Applies `role` to `cloud` (named `name` in errors).
pub fn with_role(mut cloud: Cloud, role: Role, name: &str) -> Result<Cloud> {
    match role {
        Role::Auto => {}
        Role::Points => {
            cloud.faces = None;
            cloud.lines = None;
        }
        Role::Triangles => {
            if cloud.faces.as_ref().is_none_or(|f| f.is_empty()) {
                bail!("{name}: 'as = \"triangles\"' needs a mesh, and this input has no faces");
            }
        }
    }
    Ok(cloud)
}

/// Scales `cloud` by `scale` and moves it by `translate` (radii scale too).
pub fn transform(cloud: &mut Cloud, scale: f32, translate: Vec3) {
    for p in &mut cloud.positions {
        *p = *p * scale + translate;
    }
    if let Some(r) = &mut cloud.radii {
        for r in r {
            *r *= scale.abs();
        }
    }
    if scale < 0.0 {
        if let Some(n) = &mut cloud.normals {
            for n in n {
                *n = -*n;
            }
        }
    }
}

/// sRGB color given to the points of an input without colors when another input has them
/// (the renderer's base color, 0.7 linear).
const BASE_SRGB: [u8; 4] = [218, 218, 218, 255];

/// Appends `other` to `base`, moving it into `base`'s frame (their f64 origins differ for
/// re-centred formats). Normals and radii are kept when both have them; colors when either
/// has them (the other's points get the base color); scalar fields present in both (by name).
pub fn append(base: &mut Cloud, mut other: Cloud) -> Result<()> {
    let offset = (other.origin - base.origin).as_vec3();
    for p in &mut other.positions {
        *p += offset;
    }
    if u32::try_from(base.len() + other.len()).is_err() {
        bail!("the merged scene has more than 4G points");
    }
    let first_index = base.len() as u32;
    let (n, m) = (base.len(), other.len());
    base.normals = match (base.normals.take(), other.normals.take()) {
        (Some(mut a), Some(b)) => {
            a.extend(b);
            Some(a)
        }
        _ => None,
    };
    base.radii = match (base.radii.take(), other.radii.take()) {
        (Some(mut a), Some(b)) => {
            a.extend(b);
            Some(a)
        }
        _ => None,
    };
    base.colors = match (base.colors.take(), other.colors.take()) {
        (None, None) => None,
        (a, b) => {
            let mut a = a.unwrap_or_else(|| vec![BASE_SRGB; n]);
            a.extend(b.unwrap_or_else(|| vec![BASE_SRGB; m]));
            Some(a)
        }
    };
    let mut scalars = Vec::new();
    for mut s in std::mem::take(&mut base.scalars) {
        if let Some(o) = other.scalars.iter_mut().find(|o| o.name == s.name) {
            s.values.append(&mut o.values);
            scalars.push(s);
        }
    }
    base.scalars = scalars;
    base.faces = match (base.faces.take(), other.faces.take()) {
        (None, None) => None,
        (a, b) => {
            let mut a = a.unwrap_or_default();
            a.extend(
                b.unwrap_or_default()
                    .into_iter()
                    .map(|t| t.map(|i| i + first_index)),
            );
            Some(a)
        }
    };
    base.lines = match (base.lines.take(), other.lines.take()) {
        (None, None) => None,
        (a, b) => {
            let mut a = a.unwrap_or_default();
            let b = b.unwrap_or_default();
            let shift =
                |pairs: Vec<[u32; 2]>| pairs.into_iter().map(move |p| p.map(|i| i + first_index));
            a.ribbons.extend(shift(b.ribbons));
            a.tubes.extend(shift(b.tubes));
            Some(a)
        }
    };
    base.positions.append(&mut other.positions);
    base.stats.records += other.stats.records;
    base.stats.dropped_non_finite += other.stats.dropped_non_finite;
    base.stats.dropped_invalid += other.stats.dropped_invalid;
    // Each input was completed before the merge: its scanners are spent.
    base.sensors.clear();
    Ok(())
}

/// Loads `file` and merges `inputs` (a scene file's) into it, each completed by
/// `scene::complete_with` and `estimate` before the merge; also the seconds spent estimating
/// normals and radii.
pub fn load(
    file: &Path,
    inputs: &[SceneInput],
    options: &LoadOptions,
    estimate: Estimator,
) -> Result<(Cloud, f64)> {
    let mut estimate_s = 0.0;
    let mut load = |path: &Path| -> Result<Cloud> {
        let mut cloud = super::load_with(path, &options.read())?;
        let start = std::time::Instant::now();
        if super::complete_with(&mut cloud, path, options, estimate)? {
            estimate_s += start.elapsed().as_secs_f64();
        }
        Ok(cloud)
    };
    let mut cloud = load(file)?;
    for input in inputs {
        let name = input.path.display().to_string();
        let mut other = with_role(load(&input.path)?, input.role, &name)?;
        transform(
            &mut other,
            input.scale.unwrap_or(1.0),
            input.translate.map_or(Vec3::ZERO, Vec3::from),
        );
        append(&mut cloud, other).with_context(|| name.clone())?;
    }
    Ok((cloud, estimate_s))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scalar;
    use glam::DVec3;

    fn tri(origin: DVec3, colored: bool) -> Cloud {
        Cloud {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: Some(vec![Vec3::Z; 3]),
            radii: Some(vec![0.5; 3]),
            colors: colored.then(|| vec![[255, 0, 0, 255]; 3]),
            scalars: vec![Scalar {
                name: "intensity".into(),
                values: vec![1.0, 2.0, 3.0],
            }],
            faces: Some(vec![[0, 1, 2]]),
            origin,
            ..Default::default()
        }
    }

    #[test]
    fn append_offsets_indices_and_origins_and_fills_colors() {
        let mut a = tri(DVec3::new(100.0, 0.0, 0.0), true);
        let mut b = with_role(tri(DVec3::new(101.0, 0.0, 0.0), false), Role::Points, "b").unwrap();
        transform(&mut b, 2.0, Vec3::new(0.0, 0.0, 1.0));
        append(&mut a, b).unwrap();
        assert_eq!(a.len(), 6);
        // b's origin is 1 unit further along x; scaled by 2, moved up by 1.
        assert_eq!(a.positions[4], Vec3::new(3.0, 0.0, 1.0));
        assert_eq!(a.radii.as_ref().unwrap()[5], 1.0);
        // b became points: only a's triangle remains.
        assert_eq!(a.faces.as_deref(), Some(&[[0, 1, 2]][..]));
        let colors = a.colors.as_ref().unwrap();
        assert_eq!((colors[0], colors[3]), ([255, 0, 0, 255], BASE_SRGB));
        assert_eq!(a.scalars[0].values, vec![1.0, 2.0, 3.0, 1.0, 2.0, 3.0]);
    }

    #[test]
    fn appended_triangles_index_their_own_vertices() {
        let mut a = with_role(tri(DVec3::ZERO, false), Role::Points, "a").unwrap();
        append(&mut a, tri(DVec3::ZERO, false)).unwrap();
        assert_eq!(a.faces.as_deref(), Some(&[[3, 4, 5]][..]));
        assert!(a.colors.is_none());
    }

    #[test]
    fn triangles_need_faces() {
        let mut points = tri(DVec3::ZERO, false);
        points.faces = None;
        let e = with_role(points, Role::Triangles, "cloud.ply").unwrap_err();
        assert!(
            e.to_string()
                .contains("cloud.ply: 'as = \"triangles\"' needs a mesh"),
            "{e}"
        );
    }
}

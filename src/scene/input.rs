//! Loading a model ready to render: the file, then what the methods to be run need (normals
//! and radii), shared by the command line, the benchmark and anything else that loads input.

use std::path::Path;

use anyhow::{Context as _, Result};

use super::preprocess::{self, PreprocessOptions};
use super::{pack, Cloud};

/// How [`load_prepared`] completes a loaded model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LoadOptions {
    /// Neighbours for k-NN normals and radii; 0 turns the estimation off.
    pub k: usize,
    /// Estimate the normals and radii the file lacks (a method with `needs_surfels` reads
    /// them); without it only a mesh's vertex normals are computed (from its faces, cheap).
    pub estimate: bool,
    /// Reuse and store computed normals and radii in `FILE.surfel-cache`.
    pub cache: bool,
    /// Read at most about this many points from a COPC file: whole octree levels from the root
    /// down while they fit (the root level always). `None` reads everything.
    pub budget: Option<u64>,
    /// Text files: the names of the columns, for a file without a name row.
    pub columns: Option<Vec<String>>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            k: preprocess::DEFAULT_K,
            estimate: true,
            cache: false,
            budget: None,
            columns: None,
        }
    }
}

impl LoadOptions {
    /// The options for [`super::load_with`].
    pub fn read(&self) -> super::ReadOptions {
        super::ReadOptions {
            budget: self.budget,
            columns: self.columns.clone(),
        }
    }
}

/// Loads `path` and completes it ([`complete`]).
pub fn load_prepared(path: &Path, options: &LoadOptions) -> Result<Cloud> {
    let mut cloud = super::load_with(path, &options.read())?;
    complete(&mut cloud, path, options)?;
    Ok(cloud)
}

/// Completes a cloud loaded from `path`: a mesh's vertex normals from its faces; then, when
/// `options.k` > 0, the normals (PCA over k-NN) and radii (k-NN) it lacks: from
/// `FILE.surfel-cache` when `options.cache` and the cache is valid (whether or not
/// `options.estimate`: reading it is cheap), else computed when `options.estimate` (and
/// written to the cache when `options.cache`). Returns whether it estimated or read them.
pub fn complete(cloud: &mut Cloud, path: &Path, options: &LoadOptions) -> Result<bool> {
    complete_with(cloud, path, options, &estimate_on_cpu)
}

/// The CPU's estimate of normals and radii ([`preprocess::preprocess`]) as an [`Estimator`].
pub fn estimate_on_cpu(cloud: &mut Cloud, options: &PreprocessOptions) -> Result<()> {
    preprocess::preprocess(cloud, options);
    Ok(())
}

/// How normals and radii are estimated: [`preprocess::preprocess`], or elsewhere (the GPU).
pub type Estimator<'a> = &'a dyn Fn(&mut Cloud, &PreprocessOptions) -> Result<()>;

/// [`complete`], estimating with `estimate`.
pub fn complete_with(
    cloud: &mut Cloud,
    path: &Path,
    options: &LoadOptions,
    estimate: Estimator,
) -> Result<bool> {
    if let (None, Some(faces)) = (&cloud.normals, &cloud.faces) {
        cloud.normals = Some(pack::vertex_normals(&cloud.positions, faces));
    }
    let preprocess_options = PreprocessOptions {
        k: options.k,
        ..Default::default()
    };
    if options.k == 0 || (cloud.normals.is_some() && cloud.radii.is_some()) {
        return Ok(false);
    }
    if options.cache {
        if let Some((normals, radii)) =
            preprocess::load_cache(path, &preprocess_options, cloud.len())
        {
            cloud.normals.get_or_insert(normals);
            cloud.radii.get_or_insert(radii);
            return Ok(true);
        }
    }
    if !options.estimate {
        return Ok(false);
    }
    estimate(cloud, &preprocess_options)?;
    if options.cache {
        if let (Some(n), Some(r)) = (&cloud.normals, &cloud.radii) {
            preprocess::save_cache(path, &preprocess_options, n, r).with_context(|| {
                format!(
                    "{}: cannot write the cache",
                    preprocess::cache_path(path).display()
                )
            })?;
        }
    }
    Ok(true)
}

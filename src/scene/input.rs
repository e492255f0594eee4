//! Loading a model ready to render: the file, then what every method needs (normals and
//! radii), shared by the command line, the benchmark and anything else that loads input.

use std::path::Path;

use anyhow::{Context as _, Result};

use super::preprocess::{self, PreprocessOptions};
use super::{pack, Cloud};

/// How [`load_prepared`] completes a loaded model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoadOptions {
    /// Neighbours for k-NN normals and radii (at least 1 is used).
    pub k: usize,
    /// Reuse and store computed normals and radii in `FILE.surfel-cache`.
    pub cache: bool,
    /// Read at most about this many points from a COPC file: whole octree levels from the root
    /// down while they fit (the root level always). `None` reads everything.
    pub budget: Option<u64>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            k: preprocess::DEFAULT_K,
            cache: false,
            budget: None,
        }
    }
}

/// Loads `path` and completes what the methods need: normals (from faces for meshes, else PCA
/// over k-NN) and radii (k-NN), optionally cached next to the input.
pub fn load_prepared(path: &Path, options: &LoadOptions) -> Result<Cloud> {
    let mut cloud = super::load_with_budget(path, options.budget)?;
    if let (None, Some(faces)) = (&cloud.normals, &cloud.faces) {
        cloud.normals = Some(pack::vertex_normals(&cloud.positions, faces));
    }
    let preprocess_options = PreprocessOptions {
        k: options.k.max(1),
        ..Default::default()
    };
    if cloud.normals.is_some() && cloud.radii.is_some() {
        return Ok(cloud);
    }
    if options.cache {
        if let Some((normals, radii)) =
            preprocess::load_cache(path, &preprocess_options, cloud.len())
        {
            cloud.normals.get_or_insert(normals);
            cloud.radii.get_or_insert(radii);
            return Ok(cloud);
        }
    }
    preprocess::preprocess(&mut cloud, &preprocess_options);
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
    Ok(cloud)
}

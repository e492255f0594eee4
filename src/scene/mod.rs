//! Scene input: loaders for PLY, OBJ, PCD, LAS/LAZ, COPC, E57 and delimited text, preprocessing (normals and
//! splat radii from k nearest neighbours), mesh sampling, camera, lights and scene files.

pub mod appearance;
pub mod camera;
pub mod clip;
pub mod cloud;
pub mod compose;
pub mod copc;
pub mod e57;
pub mod error;
pub(crate) mod guard;
pub mod input;
pub mod knn;
pub mod las;
pub mod lights;
pub mod lines;
pub mod morton;
pub mod normal_field;
pub mod obj;
pub mod octahedral;
pub mod orient;
pub mod pack;
pub mod path;
pub mod pcd;
pub mod ply;
pub mod preprocess;
pub(crate) mod progress;
mod records;
pub mod sample;
pub mod scene_file;
mod text;
pub mod xyz;

use std::path::Path;

pub use camera::{Camera, Pose, Up};
pub use cloud::{Cloud, Levels, Lines, LoadStats, Scalar, Sensor};
pub use error::{LoadError, Location};
pub use input::{complete, complete_with, load_prepared, Estimator, LoadOptions};
pub use lights::{Light, LightKind};

/// Loads a point cloud or mesh, choosing the format from the file extension (case-insensitive):
/// `ply`, `obj`, `pcd`, `las`, `laz`, `copc.laz`, `e57`, `xyz`, `txt`, `pts`, `csv`. Points with a
/// non-finite coordinate are dropped and counted in `stats.dropped_non_finite`. The cloud's `up`
/// is the format's convention: +z for the survey formats (LAS, LAZ, COPC, E57, PCD), +y for the
/// others; unless the loader reads it from the data (`stats.up_rule`): an organized PCD is in
/// a camera's frame ([`pcd`]), text with survey-sized x and y coordinates is z-up ([`xyz`]).
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    load_with(path, &ReadOptions::default())
}

/// How [`load_with`] reads a file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReadOptions {
    /// COPC only: read the octree down to the deepest level whose points, with those of the
    /// levels above it, fit this many (the root level always).
    pub budget: Option<u64>,
    /// Text only: the names of the columns (see [`xyz`]), for a file without a name row.
    pub columns: Option<Vec<String>>,
}

/// [`load_with`] with a COPC point budget.
pub fn load_with_budget(path: &Path, budget: Option<u64>) -> Result<Cloud, LoadError> {
    load_with(
        path,
        &ReadOptions {
            budget,
            columns: None,
        },
    )
}

/// [`load`] as `options` say. A budget for a format other than COPC is an error (only an
/// octree can be read partially), and so are columns for a format other than text.
pub fn load_with(path: &Path, options: &ReadOptions) -> Result<Cloud, LoadError> {
    let (budget, columns) = (options.budget, options.columns.as_deref());
    let extension = format_extension(path);
    let up = format_up(&extension);
    if budget.is_some() && extension != "copc.laz" {
        return Err(LoadError::whole(
            &path.display().to_string(),
            "a point budget needs a COPC file (.copc.laz); other formats are read whole",
        ));
    }
    if columns.is_some() && !matches!(extension.as_str(), "xyz" | "txt" | "pts" | "csv") {
        return Err(LoadError::whole(
            &path.display().to_string(),
            "column names are for text files (.xyz, .txt, .pts, .csv); this format names its fields",
        ));
    }
    check_regular(path)?;
    let survey = matches!(extension.as_str(), "las" | "laz" | "copc.laz");
    let mut cloud = match extension.as_str() {
        "ply" if crate::scene::lines::is_line_model(path) => {
            crate::scene::lines::load(path).map(|m| m.to_cloud())
        }
        "ply" => ply::load(path),
        "obj" => obj::load(path),
        "pcd" => pcd::load(path),
        "copc.laz" => copc::load(path, budget),
        "las" | "laz" => las::load(path),
        "e57" => e57::load(path),
        "xyz" | "txt" | "pts" | "csv" => xyz::load(path, columns),
        _ => Err(LoadError::UnknownFormat {
            file: path.display().to_string(),
            extension,
        }),
    }?;
    if cloud.stats.up_rule.is_none() {
        cloud.up = up;
    }
    cloud.survey = cloud.survey || survey;
    for warning in &cloud.stats.warnings {
        eprintln!("warning: {warning}");
    }
    Ok(cloud)
}

/// The lower-case format extension of `path`: `copc.laz` for a COPC file, else the last
/// extension (empty when there is none).
pub fn format_extension(path: &Path) -> String {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    if name.ends_with(".copc.laz") {
        return "copc.laz".into();
    }
    path.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default()
}

/// The up axis a file format conventionally uses, from its lower-case extension.
pub fn format_up(extension: &str) -> Up {
    match extension {
        "las" | "laz" | "copc.laz" | "e57" | "pcd" => Up::Z,
        _ => Up::Y,
    }
}

/// Refuses a directory, device, FIFO or socket before a loader opens it: reading a FIFO waits
/// for a writer, and `/dev/zero` or `/dev/urandom` never end.
pub fn check_regular(path: &Path) -> Result<(), LoadError> {
    let file = path.display().to_string();
    let meta = std::fs::metadata(path).map_err(|source| LoadError::Io {
        file: file.clone(),
        source,
    })?;
    if meta.is_dir() {
        Err(LoadError::Directory { file })
    } else if meta.is_file() {
        Ok(())
    } else {
        Err(LoadError::whole(
            &file,
            "is not a regular file (a device, FIFO or socket); expected a point-cloud file",
        ))
    }
}

/// Reads a whole file into memory, naming it in the error.
pub(crate) fn read_file(path: &Path) -> Result<Vec<u8>, LoadError> {
    std::fs::read(path).map_err(|source| LoadError::Io {
        file: path.display().to_string(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn survey_formats_are_z_up_and_the_others_y_up() {
        for ext in ["las", "laz", "copc.laz", "e57", "pcd"] {
            assert_eq!(format_up(ext), Up::Z, "{ext}");
        }
        for ext in ["ply", "obj", "xyz", "txt", "pts"] {
            assert_eq!(format_up(ext), Up::Y, "{ext}");
        }
    }

    #[test]
    fn copc_is_recognised_before_laz() {
        assert_eq!(format_extension(Path::new("a/b.COPC.laz")), "copc.laz");
        assert_eq!(format_extension(Path::new("a/copc.laz")), "laz");
        assert_eq!(format_extension(Path::new("a/b.laz")), "laz");
        assert_eq!(format_extension(Path::new("a/b.E57")), "e57");
        assert_eq!(format_extension(Path::new("a/b")), "");
    }
}

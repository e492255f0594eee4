//! Scene input: loaders for PLY, OBJ, PCD, LAS/LAZ and XYZ text, preprocessing (normals and
//! splat radii from k nearest neighbours), mesh sampling, camera, lights and scene files.

pub mod camera;
pub mod cloud;
pub mod error;
pub mod input;
pub mod las;
pub mod lights;
pub mod obj;
pub mod pack;
pub mod pcd;
pub mod ply;
pub mod preprocess;
mod progress;
mod records;
pub mod sample;
pub mod scene_file;
mod text;
pub mod xyz;

use std::path::Path;

pub use camera::{Camera, Pose, Up};
pub use cloud::{Cloud, LoadStats, Scalar};
pub use error::{LoadError, Location};
pub use input::{load_prepared, LoadOptions};
pub use lights::{Light, LightKind};

/// Loads a point cloud or mesh, choosing the format from the file extension (case-insensitive):
/// `ply`, `obj`, `pcd`, `las`, `laz`, `xyz`, `txt`, `pts`. Points with a non-finite coordinate
/// are dropped and counted in `stats.dropped_non_finite`. The cloud's `up` is the format's
/// convention: +z for the survey formats (LAS, LAZ, PCD), +y for the others.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let up = format_up(&extension);
    let mut cloud = match extension.as_str() {
        "ply" => ply::load(path),
        "obj" => obj::load(path),
        "pcd" => pcd::load(path),
        "las" | "laz" => las::load(path),
        "xyz" | "txt" | "pts" => xyz::load(path),
        _ => Err(LoadError::UnknownFormat {
            file: path.display().to_string(),
            extension,
        }),
    }?;
    cloud.up = up;
    Ok(cloud)
}

/// The up axis a file format conventionally uses, from its lower-case extension.
pub fn format_up(extension: &str) -> Up {
    match extension {
        "las" | "laz" | "pcd" => Up::Z,
        _ => Up::Y,
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
        for ext in ["las", "laz", "pcd"] {
            assert_eq!(format_up(ext), Up::Z, "{ext}");
        }
        for ext in ["ply", "obj", "xyz", "txt", "pts"] {
            assert_eq!(format_up(ext), Up::Y, "{ext}");
        }
    }
}

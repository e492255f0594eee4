//! What the camera, light, post-processing and coloring options of a front end select for a
//! loaded cloud: the command line and the viewer build one `ViewSettings` from their flags and
//! scene file.

use std::path::Path;

use anyhow::Result;

use crate::color::{self, Coloring};
use crate::post::PostOptions;
use crate::scene::camera::{Pose, Up};
use crate::scene::clip::Filter;
use crate::scene::compose::SceneInput;
use crate::scene::scene_file::Bookmark;
use crate::scene::{Camera, Cloud, Light};

/// What the camera options select; unset fields fall back to the loaded cloud's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewSettings {
    /// The pose, `None` for the up axis's default pose.
    pub pose: Option<Pose>,
    /// The up axis, `None` for the input format's.
    pub up: Option<Up>,
    pub lights: Vec<Light>,
    /// Eye-dome lighting and background (flags over the scene file over the defaults).
    pub post: PostOptions,
    /// The field to color by, `None` for the default (`color::default_field`).
    pub color_by: Option<String>,
    /// The scene file's extra inputs (hybrid scenes).
    pub inputs: Vec<SceneInput>,
    /// The scene file's clipping box and hidden classes.
    pub filter: Filter,
    /// The scene file's camera bookmarks.
    pub bookmarks: Vec<Bookmark>,
}

impl ViewSettings {
    /// The up axis for a cloud whose format uses `format_up`.
    pub fn up(&self, format_up: Up) -> Up {
        self.up.unwrap_or(format_up)
    }

    /// The coloring of `cloud` (whose format uses `format_up`) these settings select; an unknown
    /// field is an error naming `file` and listing the cloud's fields.
    pub fn coloring(&self, file: &Path, cloud: &Cloud) -> Result<Coloring> {
        let name = self
            .color_by
            .as_deref()
            .unwrap_or_else(|| color::default_field(cloud));
        color::select(cloud, name, self.up(cloud.up))
            .map_err(|e| anyhow::anyhow!("{}: {e}", file.display()))
    }

    /// The camera for a cloud with this bounding sphere and local origin (in the file's
    /// coordinates) whose format uses `format_up`.
    pub fn camera(
        &self,
        centre: glam::Vec3,
        radius: f32,
        format_up: Up,
        origin: glam::DVec3,
    ) -> Camera {
        let up = self.up(format_up);
        self.pose
            .unwrap_or_else(|| up.default_pose())
            .camera(centre, radius, up, origin)
    }
}

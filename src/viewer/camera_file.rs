//! The viewer's camera file (`K` saves, `L` loads): a scene file holding the camera in the
//! file's coordinates, the up axis, lights, clipping box, hidden classes and bookmarks.

use std::path::Path;

use anyhow::{bail, Context as _, Result};
use glam::{DVec3, Vec3};

use super::Viewer;
use crate::scene::camera::Pose;
use crate::scene::clip::Filter;
use crate::scene::scene_file::{Bookmark, SceneFile};
use crate::scene::{Camera, Light, Up};

/// What the viewer saves in its camera file besides the camera.
pub struct Saved<'a> {
    pub up: Up,
    pub lights: &'a [Light],
    pub filter: &'a Filter,
    pub bookmarks: &'a [Bookmark],
    /// The local frame's origin in file coordinates (`Cloud::origin`).
    pub origin: DVec3,
}

/// Saves `camera` (in the file's coordinates), the up axis, lights, clipping box, hidden
/// classes and bookmarks as a scene file `--scene` reads back; the post-processing and
/// coloring settings are not part of a camera and stay unset.
pub fn save_camera(path: &Path, camera: &Camera, saved: &Saved<'_>) -> Result<()> {
    let file = |p: Vec3| (saved.origin + p.as_dvec3()).to_array();
    SceneFile {
        up: Some(saved.up),
        camera: Some(Pose::LookAt {
            eye: file(camera.eye),
            target: file(camera.target),
        }),
        lights: saved.lights.to_vec(),
        edl: None,
        background: None,
        color_by: None,
        inputs: Vec::new(),
        hidden_classes: saved.filter.hidden.list(),
        clip: saved.filter.clip,
        bookmarks: saved.bookmarks.to_vec(),
    }
    .save(path)
}

/// The camera of the scene file at `path` for a scene with this bounding sphere and local
/// origin, orbiting about `up` unless the file names its own up axis; and the file.
pub fn load_camera(
    path: &Path,
    (centre, radius): (Vec3, f32),
    up: Up,
    origin: DVec3,
) -> Result<(Camera, SceneFile)> {
    let file = SceneFile::load(path)?;
    let pose = file
        .camera
        .with_context(|| format!("{}: the scene file has no camera", path.display()))?;
    Ok((
        pose.camera(centre, radius, file.up.unwrap_or(up), origin),
        file,
    ))
}

impl Viewer {
    /// `K`: saves the camera, lights, filter and bookmarks to the camera file.
    pub(super) fn save_camera_file(&mut self) -> Result<()> {
        let path = self.opts.camera_file.clone();
        let saved = save_camera(
            &path,
            &self.orbit.camera(),
            &Saved {
                up: self.orbit.up,
                lights: &self.opts.lights,
                filter: &self.tools.filter,
                bookmarks: &self.tools.bookmarks,
                origin: self.scene.cloud.origin,
            },
        );
        self.outcome(saved.map(|()| format!("camera saved to {}", path.display())))
    }

    /// `L`: orbits from the camera file's camera (keeping the home pose) and takes its filter
    /// and bookmarks.
    pub(super) fn load_camera_file(&mut self) -> Result<String> {
        let Some((_, info)) = self.scene.drawn() else {
            bail!("scene not uploaded");
        };
        let path = self.opts.camera_file.clone();
        let (camera, file) = load_camera(
            &path,
            (info.centre, info.radius),
            self.orbit.up,
            self.scene.cloud.origin,
        )?;
        self.orbit.look(&camera);
        self.tools.take_file(file);
        self.filter_changed()?;
        Ok(format!("camera loaded from {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::clip::ClipBox;

    #[test]
    fn a_saved_camera_loads_back_unchanged() {
        let dir = std::env::temp_dir().join(format!("surfel-camera-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let (centre, radius) = (Vec3::new(1.0, -2.0, 0.5), 3.0);
        let camera = Camera::orbit_about(Up::Z, centre, radius, 33.3, 21.7, 1.1);
        // A UTM-sized local origin: the file holds the file's coordinates.
        let origin = DVec3::new(512_345.5, 4_123_456.25, 100.0);
        let filter = Filter {
            clip: Some(ClipBox::aligned(origin, origin + DVec3::ONE)),
            hidden: crate::scene::clip::Classes::from_list(&[2, 7]),
        };
        let bookmarks = [Bookmark {
            slot: 3,
            eye: [512_400.0, 4_123_400.0, 300.0],
            target: [512_345.0, 4_123_456.0, 100.0],
        }];
        let saved = Saved {
            up: Up::Z,
            lights: &[Light::headlight()],
            filter: &filter,
            bookmarks: &bookmarks,
            origin,
        };
        for name in ["cam.toml", "cam.json"] {
            let path = dir.join(name);
            save_camera(&path, &camera, &saved).expect("save");
            let file = SceneFile::load(&path).expect("parses");
            assert_eq!(file.up, Some(Up::Z));
            assert_eq!(file.lights, vec![Light::headlight()]);
            assert_eq!(
                file.camera,
                Some(Pose::LookAt {
                    eye: (origin + camera.eye.as_dvec3()).to_array(),
                    target: (origin + camera.target.as_dvec3()).to_array(),
                })
            );
            assert_eq!(file.filter(), filter);
            assert_eq!(file.bookmarks, bookmarks);
            // Loaded about another axis: the file's own up axis wins.
            let (loaded, _) = load_camera(&path, (centre, radius), Up::Y, origin).expect("load");
            assert!((loaded.eye - camera.eye).length() < 1e-5, "{loaded:?}");
            assert!((loaded.target - camera.target).length() < 1e-5);
            assert_eq!(loaded.up, camera.up);
        }
        let bad = dir.join("cam.txt");
        let e = save_camera(&bad, &camera, &saved).unwrap_err();
        assert!(format!("{e:#}").contains("cam.txt"), "{e:#}");
        let at = (centre, radius);
        let e = load_camera(&dir.join("missing.toml"), at, Up::Z, origin).unwrap_err();
        assert!(format!("{e:#}").contains("missing.toml"), "{e:#}");
        std::fs::write(dir.join("nocam.toml"), "up = \"z\"\n").expect("write");
        let e = load_camera(&dir.join("nocam.toml"), at, Up::Z, origin).unwrap_err();
        assert!(format!("{e:#}").contains("has no camera"), "{e:#}");
    }
}

//! Scene input: point clouds, loaders, preprocessing, camera, lights, scene files.

pub mod camera;
pub mod cloud;
pub mod lights;
pub mod pack;
pub mod scene_file;

pub use camera::{Camera, Pose};
pub use cloud::Cloud;
pub use lights::{Light, LightKind};

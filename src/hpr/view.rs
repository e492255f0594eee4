//! The view HPR is measured in: sectors from the viewport, reconstruction edges in pixels,
//! true visibility and PNG output.

use crate::scene::{Camera, Cloud};

/// The view HPR measures pixels in: the camera from the eye to the target and the image size.
pub struct HprView {
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
}

impl HprView {
    pub fn new(
        cloud: &Cloud,
        eye: glam::Vec3,
        target: Option<glam::Vec3>,
        size: (u32, u32),
    ) -> Self {
        let (centre, r) = cloud.bounding_sphere().unwrap_or((glam::Vec3::ZERO, 1.0));
        Self {
            camera: Camera::look_at_up(cloud.up, eye, target.unwrap_or(centre), r),
            width: size.0,
            height: size.1,
        }
    }

    pub fn proj(&self) -> glam::Mat4 {
        self.camera
            .projection(self.width as f32 / self.height as f32)
    }

    pub fn view_proj(&self) -> glam::Mat4 {
        self.proj() * self.camera.view()
    }

    /// The angle of a pixel at the image centre.
    pub fn pixel_angle(&self) -> f64 {
        2.0 / (f64::from(self.proj().y_axis.y.abs()) * f64::from(self.height))
    }

    /// The pixel of `p`, `None` behind the eye.
    pub fn pixel(&self, p: glam::Vec3) -> Option<glam::Vec2> {
        let c = self.view_proj() * p.extend(1.0);
        (c.w > 0.0).then(|| {
            let ndc = c.truncate().truncate() / c.w;
            (ndc + 1.0) * 0.5 * glam::Vec2::new(self.width as f32, self.height as f32)
        })
    }
}

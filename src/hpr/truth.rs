//! True visibility of a mesh's vertices from a viewpoint, from its rendered depth buffer: the
//! reference HPR is scored against when the input has faces (Mehra et al. 2010 score against
//! the same z-buffer test).

use glam::{Mat4, Vec3};

/// The vertices of `positions` that a rendered depth buffer shows: inside the `width` x
/// `height` view of `view_proj` (with `view` giving the linear depth along −z), and either on
/// an empty pixel (the rasterized silhouette passed it) or no more than `tolerance` (scene
/// units) behind the farthest surface of its 3 x 3 pixels (a vertex on a silhouette or a
/// crease may fall on the neighbouring pixel's surface).
/// `depth` is the linear depth per pixel, row-major, infinite or 0 where empty.
pub fn visible_from_depth(
    positions: &[Vec3],
    (view, view_proj): (Mat4, Mat4),
    (width, height): (u32, u32),
    depth: &[f32],
    tolerance: f32,
) -> Vec<u32> {
    let (w, h) = (width as i64, height as i64);
    let at = |x: i64, y: i64| -> f32 {
        if x < 0 || y < 0 || x >= w || y >= h {
            return f32::INFINITY;
        }
        let d = depth[(y * w + x) as usize];
        if d > 0.0 {
            d
        } else {
            f32::INFINITY
        }
    };
    positions
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            let c = view_proj * p.extend(1.0);
            if c.w <= 0.0 {
                return false;
            }
            let ndc = c.truncate() / c.w;
            if ndc.x.abs() > 1.0 || ndc.y.abs() > 1.0 {
                return false;
            }
            // Framebuffer rows run down the image (Vulkan's y).
            let x = ((ndc.x + 1.0) * 0.5 * width as f32).floor() as i64;
            let y = ((ndc.y + 1.0) * 0.5 * height as f32).floor() as i64;
            let z = -(view * p.extend(1.0)).z;
            if !at(x, y).is_finite() {
                return true;
            }
            let nearest = (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
                .map(|(dx, dy)| at(x + dx, y + dy))
                .fold(f32::INFINITY, f32::max_if_finite);
            z <= nearest + tolerance
        })
        .map(|(i, _)| i as u32)
        .collect()
}

/// `f32::max` over finite values (infinite entries are empty pixels).
trait MaxIfFinite {
    fn max_if_finite(self, other: f32) -> f32;
}

impl MaxIfFinite for f32 {
    fn max_if_finite(self, other: f32) -> f32 {
        match (self.is_finite(), other.is_finite()) {
            (true, true) => self.max(other),
            (false, _) => other,
            (true, false) => self,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_the_surface_are_visible_and_points_behind_it_are_not() {
        // A 4 x 4 view looking down −z from the origin onto a surface at depth 5 over the
        // left half of the image; the right half is empty.
        let view = Mat4::IDENTITY;
        let proj = Mat4::perspective_rh(std::f32::consts::FRAC_PI_2, 1.0, 0.1, 100.0);
        let depth: Vec<f32> = (0..16)
            .map(|i| if i % 4 < 2 { 5.0 } else { f32::INFINITY })
            .collect();
        let points = [
            Vec3::new(-2.0, 0.5, -5.0),  // on the surface
            Vec3::new(-2.0, 0.5, -7.0),  // behind it
            Vec3::new(3.5, 0.5, -9.0),   // right half: an empty pixel
            Vec3::new(0.0, 0.0, 5.0),    // behind the eye
            Vec3::new(-40.0, 0.0, -5.0), // outside the view
        ];
        let v = visible_from_depth(&points, (view, proj * view), (4, 4), &depth, 0.1);
        assert_eq!(v, vec![0, 2]);
    }
}

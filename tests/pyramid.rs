//! The pyramid point renderer (000 ch. 4) on lavapipe under validation and synchronization
//! validation: analysis and synthesis against the CPU model (`methods::pyramid::reference`)
//! on synthetic level-0 images, both layouts; sparse planes reconstructed without holes; a
//! front surface occluding a back one; the two layouts and the two projections agreeing.

mod common;

use common::render_view;
use glam::Vec3;
use surfel::scene::{Camera, Cloud};

/// `n` x `n` points on the unit square at height `z` facing +z, radius = the grid spacing.
fn plane(n: usize, z: f32, color: [u8; 4]) -> Cloud {
    let t = |k: usize| -0.5 + (k as f32 + 0.5) / n as f32;
    let positions: Vec<Vec3> = (0..n * n)
        .map(|k| Vec3::new(t(k % n), t(k / n), z))
        .collect();
    let count = positions.len();
    Cloud {
        normals: Some(vec![Vec3::Z; count]),
        radii: Some(vec![1.0 / n as f32; count]),
        colors: Some(vec![color; count]),
        positions,
        ..Default::default()
    }
}

fn top_view(_: Vec3, _: f32) -> Camera {
    Camera::look_at(Vec3::new(0.0, -1.3, 0.75), Vec3::ZERO, 1.0)
}

#[test]
fn a_sparse_plane_reconstructs_without_holes() {
    let size = 128;
    for n in [16, 40] {
        let cloud = plane(n, 0.0, [200, 100, 50, 255]);
        for method in ["perspective-flat", "pyramid:layout=0", "pyramid:layout=1", "pyramid:projection=1"] {
            let frame = render_view(&cloud, method, size, Default::default(), top_view);
            let raw = render_view(
                &cloud,
                &if method.starts_with("pyramid") { format!("{method},show=0") } else { method.to_string() },
                size,
                Default::default(),
                top_view,
            );
            let covered = |f: &surfel::eval::Frame| (0..f.pixels()).filter(|&i| f.covered(i)).count();
            eprintln!("{n} {method}: {} of {} raw {}", covered(&frame), frame.pixels(), covered(&raw));
        }
    }
}

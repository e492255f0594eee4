//! Headless rendering on lavapipe with validation: coverage, depth and normals of known scenes.

use crate::common;

use common::render;

/// Expected fraction of the image covered by the square: its half extent 1 at the framing
/// distance r / sin(fov / 2) with r = sqrt(2) spans 1 / (d tan(fov / 2)) of the NDC half range.
fn square_fraction() -> (f64, f64) {
    let fov = 45f64.to_radians();
    let d = 2f64.sqrt() / (fov / 2.0).sin();
    let ndc = 1.0 / (d * (fov / 2.0).tan());
    (ndc * ndc, d)
}

#[test]
fn mesh_ground_truth_covers_the_projected_square_at_the_right_depth() {
    let frame = render(&common::square(0), "mesh", 64);
    let (fraction, distance) = square_fraction();
    let cov = common::coverage(&frame);
    // One pixel row/column of tolerance around the square's 41.8 px edge.
    assert!(
        (cov - fraction).abs() < 2.0 * 42.0 / (64.0 * 64.0) + 0.005,
        "coverage {cov} vs {fraction}"
    );
    let centre = (32 * 64 + 32) as usize;
    assert!(
        (frame.depth[centre] as f64 - distance).abs() < 1e-3 * distance,
        "depth {}",
        frame.depth[centre]
    );
    let n = frame.normal.as_ref().expect("normals")[centre];
    assert!(n[2] > 0.999, "view-space normal {n:?}");
    assert_eq!(frame.color[centre][3], 255);
    assert_eq!(frame.color[0], [0, 0, 0, 0], "corner is background");
    // Head-on headlight: the lit color is bright and grey.
    let c = frame.color[centre];
    assert!(c[0] > 200 && c[0] == c[1] && c[1] == c[2], "{c:?}");
}

#[test]
fn dense_points_cover_the_square_like_the_mesh() {
    let cloud = common::square(160);
    let points = render(&cloud, "points", 64);
    let mesh = render(&cloud, "mesh", 64);
    let covered_by_mesh: Vec<usize> = (0..mesh.pixels()).filter(|&i| mesh.covered(i)).collect();
    let holes = covered_by_mesh
        .iter()
        .filter(|&&i| !points.covered(i))
        .count();
    assert!(
        holes * 100 < covered_by_mesh.len(),
        "{holes} holes of {}",
        covered_by_mesh.len()
    );
    let outside = (0..points.pixels())
        .filter(|&i| points.covered(i) && !mesh.covered(i))
        .count();
    assert!(
        outside < 2 * 42,
        "{outside} point pixels outside the square's silhouette"
    );
    let centre = 32 * 64 + 32;
    assert!((points.depth[centre] - mesh.depth[centre]).abs() < 1e-3 * mesh.depth[centre]);
}

#[test]
fn large_points_fill_a_sparse_grid() {
    let sparse = common::square(12);
    let one = common::coverage(&render(&sparse, "points:size=1", 64));
    let big = common::coverage(&render(&sparse, "points:size=6", 64));
    // 148 points at 1 px cover at most 148 pixels; 6 px points cover the square.
    assert!(one <= 148.0 / 4096.0 + 1e-9, "{one}");
    let (fraction, _) = square_fraction();
    assert!(big > 0.9 * fraction, "{big} vs {fraction}");
}

#[test]
fn degenerate_clouds_render_without_nan_or_errors() {
    use glam::Vec3;
    use surfel::scene::Cloud;
    let one = |p: Vec3, n: Vec3| Cloud {
        positions: vec![p],
        normals: Some(vec![n]),
        ..Default::default()
    };
    let empty = render(&Cloud::default(), "points:size=1", 32);
    assert_eq!(common::coverage(&empty), 0.0);
    // One point frames itself at the image centre and covers exactly one pixel.
    let single = render(
        &one(Vec3::new(5.0, -2.0, 1.0), Vec3::Z),
        "points:size=1",
        32,
    );
    assert_eq!(
        (0..single.pixels()).filter(|&i| single.covered(i)).count(),
        1
    );
    // Zero normal: rendered (decoded as +z), never NaN.
    let zero = render(&one(Vec3::ZERO, Vec3::ZERO), "points:size=3", 32);
    assert!(common::coverage(&zero) > 0.0);
    // All points identical.
    let dup = Cloud {
        positions: vec![Vec3::ONE; 1000],
        normals: Some(vec![Vec3::Y; 1000]),
        ..Default::default()
    };
    let d = render(&dup, "points:size=1", 32);
    assert_eq!((0..d.pixels()).filter(|&i| d.covered(i)).count(), 1);
    for f in [&empty, &single, &zero, &d] {
        let report = surfel::eval::metrics::check_finite(f).expect("sizes");
        assert!(report.is_clean(), "{report:?}");
    }
}

/// Coverage of a flat z = 0 plane (a LAS-like terrain tile, +z up) seen from the orbit `pose`
/// about the cloud's up axis.
fn plane_coverage(up: surfel::scene::Up, pose: &str) -> f64 {
    let mut cloud = common::square(160);
    cloud.up = up;
    let pose = surfel::scene::Pose::parse_orbit(pose)
        .expect("orbit")
        .expect("not default");
    let frame = common::render_view(&cloud, "points", 64, Default::default(), |c, r| {
        pose.camera(c, r, cloud.up, cloud.origin)
    });
    common::coverage(&frame)
}

#[test]
fn a_z_up_plane_is_seen_from_above_at_high_elevation() {
    use surfel::scene::Up;
    let (fraction, _) = square_fraction();
    // About +z, elevation 84 looks down on the plane (foreshortened by sin 84); elevation 0
    // sees it edge-on.
    let above = plane_coverage(Up::Z, "0,84");
    assert!(above > 0.9 * fraction, "{above} vs {fraction}");
    let edge_on = plane_coverage(Up::Z, "0,0");
    assert!(edge_on < 0.1 * fraction, "{edge_on} vs {fraction}");
    // About +y (before up axes, and still for y-up formats) the same orbit turned the plane
    // edge-on.
    let y_up = plane_coverage(Up::Y, "0,84");
    assert!(y_up < 0.25 * fraction, "{y_up} vs {fraction}");
}

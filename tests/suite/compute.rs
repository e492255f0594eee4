//! The compute rasterizer on lavapipe under validation and synchronization validation:
//! `compute` reproduces the hardware point pipeline's `points:size=1` image, stream segments
//! and quantized positions leave it unchanged, and `compute-hq` blends the front surface.

use crate::common;

use std::path::Path;

use common::{render, render_with};
use glam::Vec3;
use surfel::eval::Frame;
use surfel::gpu_scene::UploadOptions;
use surfel::scene::{pack, Cloud};

fn bunny() -> Cloud {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/stanford/bun_zipper.ply");
    let mut cloud = surfel::scene::load(&path).expect("bunny");
    let faces = cloud.faces.take().expect("faces");
    cloud.normals = Some(pack::vertex_normals(&cloud.positions, &faces));
    cloud
}

/// Pixels whose coverage differs, and the largest relative depth difference where both cover.
fn compare(a: &Frame, b: &Frame) -> (usize, f32) {
    let mut coverage = 0;
    let mut depth = 0f32;
    for i in 0..a.pixels() {
        match (a.covered(i), b.covered(i)) {
            (true, true) => depth = depth.max((a.depth[i] - b.depth[i]).abs() / a.depth[i]),
            (false, false) => {}
            _ => coverage += 1,
        }
    }
    (coverage, depth)
}

#[test]
fn compute_matches_hardware_points_on_the_bunny() {
    let cloud = bunny();
    let points = render(&cloud, "points:size=1", 256);
    let compute = render(&cloud, "compute:quantized=0", 256);
    let covered = (0..points.pixels()).filter(|&i| points.covered(i)).count();
    assert!(covered > 10_000, "bunny covers {covered} px");
    let (coverage, depth) = compare(&points, &compute);
    // Same pixels; ties between points in one pixel go to the lower index in both.
    assert_eq!(
        coverage, 0,
        "coverage differs in {coverage} of {covered} px"
    );
    assert!(depth < 1e-5, "relative depth differs by {depth}");
    let color_diff = (0..points.pixels())
        .filter(|&i| points.covered(i))
        .filter(|&i| (0..3).any(|c| points.color[i][c].abs_diff(compute.color[i][c]) > 1))
        .count();
    assert_eq!(color_diff, 0, "{color_diff} px shaded differently");
}

#[test]
fn culled_and_clipped_batches_match_hardware_points_from_inside_the_cloud() {
    // The eye inside the bounding sphere, looking across the bunny: batches lie behind the
    // camera, beside the frustum and across the near plane.
    let cloud = bunny();
    let inside = |c: Vec3, r: f32| surfel::scene::Camera::orbit_at(c, r, 40.0, 10.0, 0.3);
    let opts = UploadOptions::default;
    let points = common::render_view(&cloud, "points:size=1", 192, opts(), inside);
    let exact = common::render_view(&cloud, "compute:quantized=0", 192, opts(), inside);
    let quantized = common::render_view(&cloud, "compute", 192, opts(), inside);
    let covered = (0..points.pixels()).filter(|&i| points.covered(i)).count();
    assert!(
        covered > 2_000 && covered < points.pixels() * 9 / 10,
        "a partial view: {covered} px"
    );
    let (coverage, depth) = compare(&points, &exact);
    assert_eq!(
        coverage, 0,
        "coverage differs in {coverage} of {covered} px"
    );
    assert!(depth < 1e-5, "relative depth differs by {depth}");
    // Close batches read few enough quantized words that a cell spans up to a pixel: points
    // move by less than a pixel, so every pixel the quantized render covers has a covered
    // neighbour (or itself) in the exact render, and coverage stays within a few percent.
    let w = points.width as i64;
    let near_exact = |i: usize| {
        let (x, y) = (i as i64 % w, i as i64 / w);
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (nx, ny) = (x + dx, y + dy);
                (0..w).contains(&nx)
                    && (0..w).contains(&ny)
                    && exact.covered((ny * w + nx) as usize)
            })
        })
    };
    let moved = (0..quantized.pixels())
        .filter(|&i| quantized.covered(i) && !near_exact(i))
        .count();
    assert_eq!(
        moved, 0,
        "{moved} px farther than a pixel from the exact render"
    );
    let q = (0..quantized.pixels())
        .filter(|&i| quantized.covered(i))
        .count();
    assert!(
        q.abs_diff(covered) * 20 < covered,
        "coverage {q} vs {covered}"
    );
}

#[test]
fn segments_and_quantized_positions_leave_the_image_unchanged() {
    let cloud = bunny();
    let whole = render(&cloud, "compute:quantized=0", 192);
    // One batch per segment, uploaded in tiny chunks: 4 segments, many staging round trips.
    let split = render_with(
        &cloud,
        "compute:quantized=0",
        192,
        UploadOptions {
            segment_points: Some(1),
            chunk_bytes: 64 << 10,
            ..Default::default()
        },
    );
    assert_eq!(whole.color, split.color);
    assert_eq!(whole.depth, split.depth);
    // Quantized positions move a point by at most half a cell, a pixel at most for batches
    // read at 4 bytes per point: nearly every pixel keeps its coverage.
    let quantized = render(&cloud, "compute", 192);
    let covered = (0..whole.pixels()).filter(|&i| whole.covered(i)).count();
    let (coverage, _) = compare(&whole, &quantized);
    assert!(
        coverage * 50 < covered,
        "quantization changed coverage of {coverage} of {covered} px"
    );
}

/// `n` × `n` points of one color on a unit square at height `z`, facing +z.
fn grid(n: usize, color: [u8; 4], z: f32) -> Cloud {
    let t = |k: usize| -0.5 + (k as f32 + 0.5) / n as f32;
    let positions: Vec<Vec3> = (0..n * n)
        .map(|k| Vec3::new(t(k % n), t(k / n), z))
        .collect();
    Cloud {
        normals: Some(vec![Vec3::Z; positions.len()]),
        colors: Some(vec![color; positions.len()]),
        positions,
        ..Default::default()
    }
}

fn merge(a: Cloud, b: Cloud) -> Cloud {
    let cat = |x: Option<Vec<[u8; 4]>>, y: Option<Vec<[u8; 4]>>| Some([x?, y?].concat());
    Cloud {
        normals: Some([a.normals.unwrap(), b.normals.unwrap()].concat()),
        colors: cat(a.colors, b.colors),
        positions: [a.positions, b.positions].concat(),
        ..Default::default()
    }
}

#[test]
fn high_quality_blends_the_front_surface_only() {
    // Two coincident dense layers, red and blue, and a green layer far behind them.
    let red = grid(200, [255, 0, 0, 255], 0.0);
    let blue = grid(200, [0, 0, 255, 255], 0.0);
    let green = grid(200, [0, 255, 0, 255], -0.5);
    let cloud = merge(merge(red, blue), green);
    let nearest = render(&cloud, "compute", 64);
    let blended = render(&cloud, "compute-hq:tolerance=0.01", 64);
    let centre = 32 * 64 + 32;
    let [r, g, b, a] = nearest.color[centre];
    assert_eq!(a, 255);
    // Nearest point: the lowest index wins the tie, a red point (the white specular highlight
    // adds equally to every channel).
    assert!(r > b + 100 && g == b, "nearest {:?}", nearest.color[centre]);
    let [r, g, b, _] = blended.color[centre];
    // Blended: red and blue contribute equally, green (behind the tolerance) not at all.
    assert!(
        r.abs_diff(b) < 24,
        "equal weights: {:?}",
        blended.color[centre]
    );
    assert!(r.min(b) > g + 40, "no green: {:?}", blended.color[centre]);
    assert!((blended.depth[centre] - nearest.depth[centre]).abs() < 1e-4);
    let n = blended.normal.as_ref().unwrap()[centre];
    assert!(n[2] > 0.99, "normal {n:?} faces the camera");
    // Same coverage: blending never adds or removes pixels.
    assert_eq!(compare(&nearest, &blended).0, 0);
}

#[test]
fn methods_state_the_features_they_need() {
    let ctx = common::context();
    let mut caps = ctx.caps.clone();
    let compute = surfel::methods::find("compute").unwrap();
    assert_eq!(compute.unsupported(&caps), None);
    caps.buffer_int64_atomics = false;
    let why = compute.unsupported(&caps).expect("unsupported");
    assert!(
        why.contains("'compute' needs 64-bit buffer atomics") && why.contains(&caps.device_name),
        "{why}"
    );
    assert_eq!(
        surfel::methods::find("points").unwrap().unsupported(&caps),
        None
    );
}

#[test]
fn degenerate_clouds_render_cleanly_through_the_compute_path() {
    let one = |p: Vec3| Cloud {
        positions: vec![p],
        normals: Some(vec![Vec3::ZERO]),
        ..Default::default()
    };
    let covered = |f: &Frame| (0..f.pixels()).filter(|&i| f.covered(i)).count();
    for method in ["compute", "compute-hq"] {
        let empty = render(&Cloud::default(), method, 32);
        assert_eq!(covered(&empty), 0, "{method}: empty cloud");
        // One point frames itself at the image centre: one pixel, zero normal decoded as +z.
        let single = render(&one(Vec3::new(5.0, -2.0, 1.0)), method, 32);
        assert_eq!(covered(&single), 1, "{method}: one point");
        // A batch of identical points has a zero-extent box: quantization must not divide by
        // zero, and all of them land in one pixel.
        let dup = Cloud {
            positions: vec![Vec3::ONE; 1000],
            normals: Some(vec![Vec3::Y; 1000]),
            ..Default::default()
        };
        let d = render(&dup, method, 32);
        assert_eq!(covered(&d), 1, "{method}: duplicates");
        for f in [&empty, &single, &d] {
            let report = surfel::eval::metrics::check_finite(f).expect("sizes");
            assert!(report.is_clean(), "{method}: {report:?}");
        }
    }
}

//! EWA surface splatting (000 ch. 3) on lavapipe under validation and synchronization
//! validation: the ternary depth test on layers of known depth, a hole-free plane close to its
//! mesh, and a cloud without faces or normals (normals and radii estimated from its k nearest
//! neighbours) close to the mesh it was sampled from.

use crate::common;

use std::path::Path;

use common::{layer, masked, render, render_view, sphere};
use glam::Vec3;
use surfel::eval::metrics;
use surfel::scene::{pack, preprocess, Camera, Cloud};

fn merge(layers: Vec<Cloud>) -> Cloud {
    let mut out = Cloud {
        normals: Some(Vec::new()),
        radii: Some(Vec::new()),
        colors: Some(Vec::new()),
        ..Default::default()
    };
    for l in layers {
        out.positions.extend(l.positions);
        out.normals.as_mut().unwrap().extend(l.normals.unwrap());
        out.radii.as_mut().unwrap().extend(l.radii.unwrap());
        out.colors.as_mut().unwrap().extend(l.colors.unwrap());
    }
    out
}

/// A camera 3 units up +z looking at the origin (`render_view`'s camera argument).
fn front_view(_: Vec3, _: f32) -> Camera {
    Camera::look_at(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 1.0)
}

/// Pixels per view unit at depth 3 in a 64² image with the 45° field of view.
fn pixels_per_unit() -> f64 {
    32.0 / (22.5f64.to_radians().tan() * 3.0)
}

#[test]
fn ternary_depth_test_replaces_blends_and_discards() {
    // Seen from z = 3 down -z: yellow at z = 0.3 over the left half (in front of everything:
    // replaces), red at z = 0 and blue at z = -0.004 (within each other's depth interval of
    // ±1 radius = ±0.01: blend), green at z = -0.5 (behind: discarded).
    let n = 100;
    let cloud = merge(vec![
        layer(n, [255, 0, 0, 255], 0.0, |_| true),
        layer(n, [0, 0, 255, 255], -0.004, |_| true),
        layer(n, [0, 255, 0, 255], -0.5, |_| true),
        layer(n, [255, 255, 0, 255], 0.3, |x| x < 0.0),
    ]);
    let size = 128;
    let view = |method: &str| render_view(&cloud, method, size, Default::default(), front_view);
    let frame = view("ewa");
    let at = |x: u32| (size / 2 * size + x) as usize;
    // The left half: the yellow layer alone (no blue or green at all, full red and green).
    let front = at(size / 2 - 12);
    let [r, g, b, a] = frame.color[front];
    assert_eq!(a, 255);
    assert!(r >= 245 && g >= 245 && b == 0, "replaced: {:?}", [r, g, b]);
    assert!(
        (frame.depth[front] - 2.7).abs() < 2e-3,
        "{}",
        frame.depth[front]
    );
    // The right half: red and blue averaged with equal weights (linear 0.5 is sRGB 188), no
    // green.
    let blend = at(size / 2 + 12);
    let [r, g, b, a] = frame.color[blend];
    assert_eq!(a, 255);
    assert_eq!(g, 0, "the layer behind is discarded: {:?}", [r, g, b]);
    assert!(r.abs_diff(b) <= 3, "equal weights: {:?}", [r, g, b]);
    assert!(
        (180..=190).contains(&r),
        "average of red and blue: {:?}",
        [r, g, b]
    );
    // The pixel's depth is the front-most fragment's (red, z = 0).
    assert!(
        (frame.depth[blend] - 3.0).abs() < 2e-3,
        "{}",
        frame.depth[blend]
    );
    let normal = frame.normal.as_ref().unwrap()[blend];
    assert!(normal[2] > 0.99, "normal {normal:?} faces the camera");
    // With a zero interval blue lies behind red's interval and is discarded: pure red.
    let thin = view("ewa:interval=0");
    let [r, g, b, _] = thin.color[blend];
    assert!(r >= 245 && g == 0 && b == 0, "no blending: {:?}", [r, g, b]);
}

#[test]
fn two_splats_blend_with_the_weights_of_their_resampling_gaussians() {
    // A red and a blue splat facing a camera 3 units away, 0.05 left and right of the axis,
    // σ = 0.1. At 64² with a 45° field of view one unit at depth 3 spans
    // 32 / tan(22.5°) / 3 pixels, so both resampling filters are Gaussians of variance
    // s² = (σ · px)² + 1 (prefilter) centred ±0.05 · px from the image centre, and the red
    // share of a pixel at x pixels right of it is 1 / (1 + exp(2 x (0.05 px) / s²)).
    let splat = |x: f32, color: [u8; 4]| Cloud {
        positions: vec![Vec3::new(x, 0.0, 0.0)],
        normals: Some(vec![Vec3::Z]),
        radii: Some(vec![0.1]),
        colors: Some(vec![color]),
        ..Default::default()
    };
    let cloud = merge(vec![
        splat(-0.05, [255, 0, 0, 255]),
        splat(0.05, [0, 0, 255, 255]),
    ]);
    let size = 64;
    let frame = render_view(
        &cloud,
        "ewa:radius=1,cutoff=3,prefilter=1",
        size,
        Default::default(),
        front_view,
    );
    let px = pixels_per_unit();
    let (d, s2) = (0.05 * px, (0.1 * px).powi(2) + 1.0);
    let srgb = |c: f64| (255.0 * (1.055 * c.powf(1.0 / 2.4) - 0.055)).round();
    for column in 29..35u32 {
        let x = f64::from(column) + 0.5 - 32.0;
        let red = 1.0 / (1.0 + (2.0 * x * d / s2).exp());
        let [r, g, b, a] = frame.color[(32 * size + column) as usize];
        assert_eq!((g, a), (0, 255));
        // The headlight lights these pixels within 0.2 % of normal incidence.
        assert!(
            (f64::from(r) - srgb(red)).abs() <= 2.0
                && (f64::from(b) - srgb(1.0 - red)).abs() <= 2.0,
            "column {column}: {:?}, expected red share {red}",
            [r, g, b]
        );
    }
}

#[test]
fn a_splat_larger_than_a_thread_takes_covers_its_whole_ellipse() {
    // One splat of σ = 1 facing a camera 3 units away at 64²: its resampling filter is a
    // circle of s² = (σ · px)² + 1 around the image centre (about 26 pixels, beyond
    // EWA_MAX_RADIUS: a whole workgroup rasterizes it), cut at one standard deviation. The
    // pixels it covers are those of its unfiltered footprint, the circle of radius σ · px; the
    // prefilter's halo (a ring 0.02 pixels wide here) holds less than half an interior pixel's
    // weight.
    let cloud = Cloud {
        positions: vec![Vec3::ZERO],
        normals: Some(vec![Vec3::Z]),
        radii: Some(vec![1.0]),
        ..Default::default()
    };
    let size = 64u32;
    let frame = render_view(
        &cloud,
        "ewa:radius=1,cutoff=1,prefilter=1",
        size,
        Default::default(),
        front_view,
    );
    assert!(f64::from(surfel::layout::EWA_MAX_RADIUS) < 25.0);
    let px = pixels_per_unit();
    let s2 = px * px;
    let mut mismatched = 0;
    for i in 0..frame.pixels() {
        let (x, y) = (
            (i as u32 % size) as f64 + 0.5,
            (i as u32 / size) as f64 + 0.5,
        );
        let d2 = (x - 32.0).powi(2) + (y - 32.0).powi(2);
        // Pixels within a hundredth of a pixel of the contour may go either way.
        if (d2.sqrt() - s2.sqrt()).abs() > 0.01 && frame.covered(i) != (d2 <= s2) {
            mismatched += 1;
        }
    }
    assert_eq!(
        mismatched, 0,
        "pixels outside or inside the ellipse wrongly"
    );
}

#[test]
fn a_densely_sampled_plane_has_no_holes_and_matches_its_mesh() {
    // The square [-1, 1]² as two triangles plus 64 × 64 points whose radius is the grid
    // spacing, about 2.6 pixels at 128².
    let mut cloud = common::square(64);
    cloud.radii = Some(vec![2.0 / 64.0; cloud.positions.len()]);
    let mesh = render(&cloud, "mesh", 128);
    let ewa = render(&cloud, "ewa", 128);
    // Every pixel inside the plane's projection is covered.
    assert_eq!(metrics::hole_ratio(&ewa, &mesh).unwrap(), Some(0.0));
    // At most the splats' reach (one radius, a ring of about 3 pixels) outside it.
    let iou = metrics::iou(&ewa, &mesh).unwrap().unwrap();
    assert!(iou > 0.93, "IoU {iou}");
    let psnr = metrics::psnr_color(&ewa, &mesh).unwrap().unwrap();
    // The ring outside the plane dominates the error.
    assert!(psnr >= 17.0, "PSNR {psnr} dB");
    // Inside, the reconstruction is the mesh's color.
    let inside = metrics::psnr_color(&crop(&ewa, 16), &crop(&mesh, 16))
        .unwrap()
        .unwrap();
    assert!(inside >= 45.0, "PSNR inside {inside} dB");
}

/// The centre `2 r` × `2 r` pixels of a frame.
fn crop(frame: &surfel::eval::Frame, r: u32) -> surfel::eval::Frame {
    let (w, h) = (frame.width, frame.height);
    let keep: Vec<bool> = (0..frame.pixels() as u32)
        .map(|i| (i % w).abs_diff(w / 2) < r && (i / w).abs_diff(h / 2) < r)
        .collect();
    masked(frame, &keep)
}

#[test]
fn a_cloud_without_faces_or_normals_renders_close_to_its_mesh() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/stanford/bun_zipper.ply");
    let mut mesh = surfel::scene::load(&path).expect("bunny");
    let faces = mesh.faces.clone().expect("faces");
    mesh.normals = Some(pack::vertex_normals(&mesh.positions, &faces));
    // The points alone: normals (oriented outward) and radii from the 10 nearest neighbours.
    let mut points = Cloud {
        positions: mesh.positions.clone(),
        ..Default::default()
    };
    preprocess::preprocess(
        &mut points,
        &preprocess::PreprocessOptions {
            progress: false,
            ..Default::default()
        },
    );
    let size = 256;
    let truth = render(&mesh, "mesh", size);
    let ewa = render(&points, "ewa", size);
    let nearest = render(&points, "compute", size);
    let holes = metrics::hole_ratio(&ewa, &truth).unwrap().unwrap();
    assert!(holes < 0.002, "holes {holes}");
    let psnr = metrics::psnr_color(&ewa, &truth).unwrap().unwrap();
    let nearest_psnr = metrics::psnr_color(&nearest, &truth).unwrap().unwrap();
    assert!(psnr >= 20.0, "PSNR {psnr} dB");
    assert!(
        psnr >= nearest_psnr + 3.0,
        "EWA {psnr} dB vs nearest point {nearest_psnr} dB"
    );
}

#[test]
fn ewa_needs_64_bit_atomics_and_renders_degenerate_clouds() {
    let ctx = common::context();
    let mut caps = ctx.caps.clone();
    let ewa = surfel::methods::find("ewa").unwrap();
    assert_eq!(ewa.unsupported(&caps), None);
    caps.buffer_int64_atomics = false;
    assert!(ewa.unsupported(&caps).is_some());
    // No radii, no normals: a point sample, the prefilter's Gaussian (1 pixel here) cut at
    // 2 standard deviations: it covers the pixel centres within 2 pixels of its projection.
    let point = Vec3::new(5.0, -2.0, 1.0);
    let single = Cloud {
        positions: vec![point],
        ..Default::default()
    };
    let frame = render_view(
        &single,
        "ewa:prefilter=1",
        32,
        Default::default(),
        |_, _| Camera::look_at(point + Vec3::Z * 3.0, point, 1.0),
    );
    for i in 0..frame.pixels() {
        let (x, y) = ((i % 32) as f64 + 0.5 - 16.0, (i / 32) as f64 + 0.5 - 16.0);
        let d = (x * x + y * y).sqrt();
        assert_eq!(frame.covered(i), d < 2.0, "pixel ({x}, {y}) at {d}");
    }
    let empty = render(&Cloud::default(), "ewa", 32);
    assert_eq!((0..empty.pixels()).filter(|&i| empty.covered(i)).count(), 0);
    for f in [&frame, &empty] {
        let report = metrics::check_finite(f).expect("sizes");
        assert!(report.is_clean(), "{report:?}");
    }
}

#[test]
fn a_tilted_splat_covers_its_footprint_with_the_resampling_gaussian() {
    // A red splat tilted 60° about the y axis and a blue one facing the camera, both at the
    // origin, 3 units in front of a camera at 64² (px = 32 / tan 22.5° / 3 pixels per unit).
    // Along x (the red splat's minor axis) the red footprint is σ px cos 60° wide: its
    // resampling filter has variance (σ px cos 60°)² + h², the blue one (σ_b px)² + h², and
    // each kernel is scaled by |J| σ² / sqrt|V| (eq. 3.29 with unit peak), so the red share
    // of a pixel x pixels from the centre is w_r / (w_r + w_b). Deferred shading keeps the
    // albedo ratio whatever the lighting. Red alone covers exactly its unfiltered ellipse.
    let tilt = 60f64.to_radians();
    let (sigma, sigma_b, h) = (0.1f64, 0.06f64, 1.0f64);
    let splat = |normal: Vec3, radius: f64, color: [u8; 4]| Cloud {
        positions: vec![Vec3::ZERO],
        normals: Some(vec![normal]),
        radii: Some(vec![radius as f32]),
        colors: Some(vec![color]),
        ..Default::default()
    };
    let red = splat(
        Vec3::new(tilt.sin() as f32, 0.0, tilt.cos() as f32),
        sigma,
        [255, 0, 0, 255],
    );
    let size = 64;
    let method = "ewa:radius=1,cutoff=3,prefilter=1,interval=16,shading=0";
    let px = pixels_per_unit();
    let alone = render_view(&red, method, size, Default::default(), front_view);
    for i in 0..alone.pixels() {
        let x = (i as u32 % size) as f64 + 0.5 - 32.0;
        let y = (i as u32 / size) as f64 + 0.5 - 32.0;
        let d2 = (x / (sigma * px * tilt.cos())).powi(2) + (y / (sigma * px)).powi(2);
        if (d2.sqrt() - 3.0).abs() > 0.05 {
            assert_eq!(
                alone.covered(i),
                d2 <= 9.0,
                "pixel ({x}, {y}) at {}",
                d2.sqrt()
            );
        }
    }
    let both = merge(vec![red, splat(Vec3::Z, sigma_b, [0, 0, 255, 255])]);
    let frame = render_view(&both, method, size, Default::default(), front_view);
    let v_r = (sigma * px * tilt.cos()).powi(2) + h * h;
    let v_r_y = (sigma * px).powi(2) + h * h;
    let scale_r = px * px * tilt.cos() * sigma * sigma / (v_r * v_r_y).sqrt();
    let v_b = (sigma_b * px).powi(2) + h * h;
    let scale_b = (px * sigma_b).powi(2) / v_b;
    let linear = |c: u8| f64::from(pack::linear_component(c));
    let mut checked = 0;
    for column in 28..36u32 {
        let x = f64::from(column) + 0.5 - 32.0;
        let w_r = scale_r * (-0.5 * x * x / v_r).exp();
        let w_b = scale_b * (-0.5 * x * x / v_b).exp();
        let expected = w_r / (w_r + w_b);
        let [r, g, b, a] = frame.color[(32 * size + column) as usize];
        assert_eq!((g, a), (0, 255), "column {column}");
        let (lr, lb) = (linear(r), linear(b));
        let share = lr / (lr + lb);
        // 8-bit colors near either end leave about 2 % of the share uncertain.
        assert!(
            (share - expected).abs() < 0.03,
            "column {column}: red share {share}, Gaussians give {expected}"
        );
        checked += usize::from(expected > 0.1 && expected < 0.9);
    }
    assert!(checked >= 4, "the shares cross over inside the footprint");
}

#[test]
fn ewa_ranks_first_on_a_densely_sampled_curved_surface() {
    // A colored sphere seen at 128² with about 2 points per pixel (160 × 320 quads): EWA
    // against every point and splatting method, the
    // pyramid and the compute rasterizers, scored against the mesh inside its coverage eroded
    // by 2 pixels. On the silhouette the ground truth averages only the pixel's covered
    // samples, a filter no splatting method shares: there EWA's Gaussian prefilter, reaching
    // half a pixel beyond the pixel, costs it 0.6 dB of whole-image PSNR against
    // perspective-gouraud (docs/claims.md).
    let size = 128;
    let mut others = vec!["points", "compute", "compute-hq", "pyramid", "kernel5"];
    let splats: Vec<String> = ["points", "squares", "affine", "perspective"]
        .iter()
        .flat_map(|r| {
            ["flat", "gouraud", "phong", "deferred"]
                .iter()
                .map(move |s| format!("{r}-{s}"))
        })
        .collect();
    others.extend(splats.iter().map(String::as_str));
    let cloud = sphere(160);
    let truth = render(&cloud, "mesh", size);
    let inside = common::eroded(&common::covered(&truth), size as usize, 2);
    let score = |method: &str| {
        let frame = render(&cloud, method, size);
        metrics::psnr_color(&masked(&frame, &inside), &masked(&truth, &inside))
            .unwrap()
            .unwrap()
    };
    let ewa = score("ewa");
    for method in &others {
        let psnr = score(method);
        assert!(psnr < ewa, "{method} {psnr:.2} dB, EWA {ewa:.2} dB");
    }
}

//! The splatting family (002 sections 5.2-5.3) on splats of known position, normal and radius,
//! seen by a camera on the +z axis: coverage and depth as the rasterization equations predict,
//! and the blending of the three-pass shadings. Lavapipe, validation and synchronization
//! validation on.

use crate::common;

use glam::Vec3;
use surfel::eval::{metrics, Frame};
use surfel::scene::{pack, preprocess, Camera, Cloud};

/// One splat: centre, unit normal, radius, sRGB color.
struct Splat {
    centre: Vec3,
    normal: Vec3,
    radius: f32,
    color: [u8; 4],
}

fn cloud(splats: &[Splat]) -> Cloud {
    Cloud {
        positions: splats.iter().map(|s| s.centre).collect(),
        normals: Some(splats.iter().map(|s| s.normal).collect()),
        radii: Some(splats.iter().map(|s| s.radius).collect()),
        colors: Some(splats.iter().map(|s| s.color).collect()),
        ..Default::default()
    }
}

fn grey(centre: Vec3, normal: Vec3, radius: f32) -> Splat {
    Splat {
        centre,
        normal,
        radius,
        color: [180, 180, 180, 255],
    }
}

/// The camera: at (0, 0, `distance`) looking at the origin, +y up, 45° vertical field of view.
fn camera(distance: f32) -> Camera {
    Camera::look_at(Vec3::new(0.0, 0.0, distance), Vec3::ZERO, 1.0)
}

/// Pixels per view-space unit at distance 1 for a `size`-pixel image: h / 2 / tan(fov / 2).
fn pixels_per_unit(size: u32) -> f64 {
    let fov = camera(1.0).fov_y as f64;
    size as f64 / 2.0 / (fov / 2.0).tan()
}

fn render(splats: &[Splat], method: &str, size: u32, distance: f32) -> Frame {
    let frame = common::render_view(&cloud(splats), method, size, Default::default(), |_, _| {
        camera(distance)
    });
    for i in 0..frame.pixels() {
        let alpha = frame.color[i][3];
        assert_eq!(
            frame.covered(i),
            alpha == 255,
            "{method}: pixel {i} depth {} alpha {alpha}",
            frame.depth[i]
        );
    }
    frame
}

fn covered(frame: &Frame) -> Vec<usize> {
    (0..frame.pixels()).filter(|&i| frame.covered(i)).collect()
}

/// The view-space ray through the centre of pixel `i`, scaled to z = -1.
fn pixel_ray(frame: &Frame, i: usize) -> glam::DVec3 {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let k = pixels_per_unit(frame.height);
    let x = (i % w) as f64 + 0.5 - w as f64 / 2.0;
    let y = (i / w) as f64 + 0.5 - h as f64 / 2.0;
    glam::DVec3::new(x / k, -y / k, -1.0)
}

#[test]
fn fixed_size_points_cover_size_squared_pixels_at_the_points_depth() {
    let splats = [grey(Vec3::ZERO, Vec3::Z, 0.1)];
    for (size, method) in [(6, "points-flat:size=6"), (11, "points-flat:size=11")] {
        let frame = render(&splats, method, 64, 3.0);
        let pixels = covered(&frame);
        // A square of 6 px centred on the pixel corner (32, 32) covers 6 x 6 pixels; one of
        // 11 px spans [26.5, 37.5), whose 11 x 11 pixel centres are 27..=37.
        assert_eq!(pixels.len(), size * size, "{method}");
        for &i in &pixels {
            assert!(
                (frame.depth[i] - 3.0).abs() < 1e-5,
                "{method}: depth {}",
                frame.depth[i]
            );
        }
    }
}

#[test]
fn image_aligned_squares_follow_eq_5_1() {
    // Eq. 5.1: the side is 2 r n / p_z * h / (t - b) = 2 r k / d pixels. With r = 0.25 and the
    // camera at d = 2 r k / 20 the side is 20 px: 400 pixels; `radius=1.5` gives 30 px: 900.
    let size = 128;
    let d = (2.0 * 0.25 * pixels_per_unit(size) / 20.0) as f32;
    let splats = [grey(Vec3::ZERO, Vec3::Z, 0.25)];
    for (method, side) in [("squares-flat", 20), ("squares-flat:radius=1.5", 30)] {
        let frame = render(&splats, method, size, d);
        let pixels = covered(&frame);
        assert_eq!(pixels.len(), side * side, "{method}");
        for &i in &pixels {
            assert!(
                (frame.depth[i] - d).abs() < 1e-5 * d,
                "{method}: depth {}",
                frame.depth[i]
            );
            let n = frame.normal.as_ref().unwrap()[i];
            assert!(n[2] > 0.999, "{method}: normal {n:?}");
        }
    }
}

/// A disc of radius 0.25 at the origin whose normal is tilted by 60° about +y from the view
/// axis, and the analytic area of its parallel projection: an ellipse of semi-axes a and a cos 60°.
fn tilted_disc() -> (Splat, Vec3) {
    let t = 60f32.to_radians();
    let n = Vec3::new(t.sin(), 0.0, t.cos());
    (grey(Vec3::ZERO, n, 0.25), n)
}

#[test]
fn affine_sprites_cover_the_ellipse_of_a_disc_at_60_degrees_with_corrected_depth() {
    let size = 256;
    let k = pixels_per_unit(size);
    // Semi-major axis a = 30 px: the camera at d = r k / a.
    let d = 0.25 * k / 30.0;
    let (disc, n) = tilted_disc();
    let frame = render(&[disc], "affine-flat", size, d as f32);
    let pixels = covered(&frame);
    let ellipse = std::f64::consts::PI * 30.0 * 30.0 * 0.5;
    let count = pixels.len() as f64;
    assert!(
        (count - ellipse).abs() < 0.03 * ellipse,
        "{count} px vs {ellipse}"
    );
    // Eq. 5.2 at every covered pixel: the offset (x, y) in the plane z = p_z and the depth
    // correction dz = -(nx / nz) x - (ny / nz) y; linear depth d - dz.
    let (nx, ny, nz) = (n.x as f64, n.y as f64, n.z as f64);
    for &i in &pixels {
        let ray = pixel_ray(&frame, i);
        let (x, y) = (ray.x * d, ray.y * d);
        let dz = -(nx / nz) * x - (ny / nz) * y;
        assert!(
            (x * x + y * y + dz * dz).sqrt() <= 0.25 * 1.02,
            "pixel {i} outside the disc"
        );
        let depth = frame.depth[i] as f64;
        assert!(
            (depth - (d - dz)).abs() < 2e-4 * d,
            "pixel {i}: {depth} vs {}",
            d - dz
        );
    }
}

#[test]
fn perspective_splats_cover_exactly_the_pixels_whose_ray_meets_the_disc() {
    // Close enough for perspective to matter (r / d = 0.26): every pixel ray is intersected
    // with the splat plane (eqs. 5.4-5.5) on the CPU.
    let size = 128;
    let d = 0.25 * pixels_per_unit(size) / 40.0;
    let (disc, n) = tilted_disc();
    let frame = render(&[disc], "perspective-flat", size, d as f32);
    let eye = glam::DVec3::new(0.0, 0.0, d);
    let n = n.as_dvec3();
    let mut expected = 0;
    let mut mismatched = 0;
    for i in 0..frame.pixels() {
        let ray = pixel_ray(&frame, i);
        // View space: the disc's centre is at (0, 0, -d), its normal is n (the view is a
        // translation along z).
        let p = -eye;
        let q = ray * (p.dot(n) / ray.dot(n));
        let inside = (q - p).length() <= 0.25;
        expected += usize::from(inside);
        let near_rim = ((q - p).length() - 0.25).abs() < 2e-3;
        if inside != frame.covered(i) && !near_rim {
            mismatched += 1;
        }
        if inside && frame.covered(i) {
            let depth = frame.depth[i] as f64;
            assert!(
                (depth + q.z).abs() < 1e-4 * d,
                "pixel {i}: {depth} vs {}",
                -q.z
            );
        }
    }
    assert_eq!(mismatched, 0);
    let count = covered(&frame).len();
    assert!(
        count.abs_diff(expected) * 200 < expected,
        "{count} vs {expected}"
    );
    // The near half of the disc is magnified: more pixels than the parallel projection's
    // ellipse of semi-axis 40 px, which the affine sprite approximates.
    let ellipse = std::f64::consts::PI * 40.0 * 40.0 * 0.5;
    assert!(count as f64 > 1.03 * ellipse, "{count} vs {ellipse}");
}

#[test]
fn normal_culling_drops_splats_facing_away() {
    let away = [grey(Vec3::ZERO, -Vec3::Z, 0.25)];
    let towards = [grey(Vec3::ZERO, Vec3::Z, 0.25)];
    for raster in ["points", "squares", "affine", "perspective"] {
        let shown = format!("{raster}-flat");
        let culled = format!("{raster}-flat:cull=1");
        assert!(
            !covered(&render(&away, &shown, 64, 3.0)).is_empty(),
            "{shown}"
        );
        assert!(
            covered(&render(&away, &culled, 64, 3.0)).is_empty(),
            "{culled}"
        );
        assert!(
            !covered(&render(&towards, &culled, 64, 3.0)).is_empty(),
            "{culled}"
        );
    }
}

/// A red and a green splat side by side on the plane z = 0, overlapping around x = 0, and a
/// blue one `behind` below the plane, centred.
fn overlapping(behind: f32) -> Vec<Splat> {
    let splat = |x: f32, z: f32, color| Splat {
        centre: Vec3::new(x, 0.0, z),
        normal: Vec3::Z,
        radius: 0.25,
        color,
    };
    vec![
        splat(-0.15, 0.0, [255, 0, 0, 255]),
        splat(0.15, 0.0, [0, 255, 0, 255]),
        splat(0.0, -behind, [0, 0, 255, 255]),
    ]
}

#[test]
fn blended_shadings_mix_overlapping_splats_of_one_surface_only() {
    // Camera at d = 3; the blue splat is 0.1 (3.3 % of the depth) behind the plane.
    // An odd image size puts the centre pixel's centre on the view axis, equidistant from the
    // red and green splats.
    let scene = overlapping(0.1);
    let size = 127;
    let k = pixels_per_unit(size) / 3.0;
    let centre = 63 * size as usize + 63;
    // Only the red splat covers x = -0.35.
    let red_only = 63 * size as usize + (63.5 - 0.35 * k) as usize;
    for raster in ["points", "squares", "affine", "perspective"] {
        let size_param = if raster == "points" {
            "size=40"
        } else {
            "radius=1"
        };
        for shading in ["gouraud", "phong", "deferred"] {
            let method = format!("{raster}-{shading}:{size_param}");
            let frame = render(&scene, &method, size, 3.0);
            let c = frame.color[centre];
            // Equal weights of red and green at the centre: R = G, and no blue from behind.
            assert!(
                c[0] > 60 && c[0].abs_diff(c[1]) <= 2,
                "{method}: centre {c:?}"
            );
            assert_eq!(c[2], 0, "{method}: the splat behind blended in: {c:?}");
            assert!((frame.depth[centre] - 3.0).abs() < 1e-4, "{method}");
            let r = frame.color[red_only];
            assert!(
                r[0] > 60 && r[1] == 0 && r[2] == 0,
                "{method}: red only {r:?}"
            );
            // With epsilon beyond the 3.3 % gap the splat behind blends in.
            let wide = render(&scene, &format!("{method},epsilon=0.05"), size, 3.0);
            let c = wide.color[centre];
            assert!(c[2] > 40, "{method},epsilon=0.05: centre {c:?}");
        }
        // Flat shading does not blend: the nearest fragment's splat wins the centre.
        let flat = format!("{raster}-flat:{size_param}");
        let c = render(&scene, &flat, size, 3.0).color[centre];
        assert!(c[0].min(c[1]) == 0 && c[2] == 0, "{flat}: centre {c:?}");
    }
}

#[test]
fn off_centre_pixels_take_the_ratio_of_the_two_kernel_weights() {
    // The red and green splats of `overlapping` on the plane z = 0 (centres x = ∓0.15, radius
    // 0.25) seen from d = 3: along the middle row every pixel's ray meets the plane at a known
    // x, so the red share of the blend is w(rho_r) / (w(rho_r) + w(rho_g)) with the Gaussian
    // w(rho) = exp(-2 rho^2) of each splat's normalized distance. Both splats face the eye at
    // the same distance from the headlight's axis, so lighting scales both colors alike.
    let scene = overlapping(0.1);
    let size = 127;
    let k = pixels_per_unit(size) / 3.0;
    let linear = |c: u8| f64::from(pack::linear_component(c));
    let w = |rho: f64| (-2.0 * rho * rho).exp();
    for method in [
        "perspective-gouraud",
        "perspective-phong",
        "perspective-deferred",
    ] {
        let frame = render(&scene, method, size, 3.0);
        let mut checked = 0;
        for column in 0..size as usize {
            let x = (column as f64 + 0.5 - 63.5) / k;
            let (rho_r, rho_g) = ((x + 0.15).abs() / 0.25, (x - 0.15).abs() / 0.25);
            // Away from both rims (the disc edge is a pixel-centre test).
            if rho_r > 0.95 || rho_g > 0.95 {
                continue;
            }
            let expected = w(rho_r) / (w(rho_r) + w(rho_g));
            let [r, g, b, _] = frame.color[63 * size as usize + column];
            assert_eq!(b, 0, "{method}: column {column}");
            let share = linear(r) / (linear(r) + linear(g));
            // 8-bit colors leave about 1 % of the share uncertain.
            assert!(
                (share - expected).abs() < 0.02,
                "{method}: column {column} (x = {x:.3}): red share {share:.3}, kernels give {expected:.3}"
            );
            checked += usize::from((expected - 0.5).abs() > 0.1);
        }
        assert!(
            checked >= 4,
            "{method}: off-centre pixels checked: {checked}"
        );
    }
}

/// PSNR of `method` on `points` against `mesh` rendered by `mesh`, inside the mesh's coverage
/// eroded by 2 pixels, at `size`² from `camera`.
fn interior_psnr(points: &Cloud, mesh: &Cloud, method: &str, size: u32, camera: Camera) -> f64 {
    let view = |_: Vec3, _: f32| camera;
    let truth = common::render_view(mesh, "mesh", size, Default::default(), view);
    let inside = common::eroded(&common::covered(&truth), size as usize, 2);
    let frame = common::render_view(points, method, size, Default::default(), view);
    metrics::psnr_color(
        &common::masked(&frame, &inside),
        &common::masked(&truth, &inside),
    )
    .expect("psnr")
    .expect("pixels")
}

#[test]
fn phong_lights_a_magnified_sphere_closer_to_its_shading_than_gouraud() {
    // 1 200 points with exact normals on a unit sphere seen from 1.2 units away: each splat
    // spans about 30 pixels, so Gouraud's one color per splat blurs the headlight's highlight
    // and Phong's fitted field restores it. The truth: a finely tessellated mesh of the sphere.
    let mut points = common::sphere(24);
    points.colors = None;
    points.faces = None;
    let mut mesh = common::sphere(200);
    mesh.colors = None;
    let camera = Camera::look_at(Vec3::new(0.0, 0.0, 2.2), Vec3::ZERO, 1.0);
    for raster in ["affine", "perspective"] {
        let score = |shading: &str| {
            let method = format!("{raster}-{shading}");
            interior_psnr(&points, &mesh, &method, 256, camera)
        };
        let (phong, gouraud) = (score("phong"), score("gouraud"));
        eprintln!("{raster}: phong {phong:.2} dB, gouraud {gouraud:.2} dB");
        assert!(
            phong > gouraud + 3.0,
            "{raster}: phong {phong:.2} dB, gouraud {gouraud:.2} dB"
        );
    }
}

#[test]
fn phong_shading_does_not_depend_on_the_models_units() {
    // The bunny (coordinates ~0.1) and the same bunny ×1000, framed alike: the normal fields
    // are stored per splat radius, so the two images agree and score alike against the mesh.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/stanford/bun_zipper.ply");
    let mut mesh = surfel::scene::load(&path).expect("bunny");
    let faces = mesh.faces.clone().expect("faces");
    mesh.normals = Some(pack::vertex_normals(&mesh.positions, &faces));
    let neighbours = preprocess::Neighbours::compute(&mesh.positions, preprocess::DEFAULT_K, false);
    mesh.radii = Some(preprocess::estimate_radii(
        &mesh.positions,
        &neighbours,
        preprocess::RadiusMode::DensitySpacing,
    ));
    let scaled = |c: &Cloud, k: f32| Cloud {
        positions: c.positions.iter().map(|&p| p * k).collect(),
        radii: c.radii.as_ref().map(|r| r.iter().map(|&r| r * k).collect()),
        ..c.clone()
    };
    let big = scaled(&mesh, 1000.0);
    let points = |c: &Cloud| Cloud {
        faces: None,
        ..c.clone()
    };
    let size = 256;
    let camera = |c: &Cloud| {
        let (centre, radius) = c.bounding_sphere().expect("bounds");
        // A close view: a third of the bunny fills the frame.
        let eye = centre + Vec3::new(0.3, 0.2, 1.0).normalize() * radius * 1.2;
        Camera::look_at(eye, centre, radius)
    };
    let small_frame = common::render_view(
        &points(&mesh),
        "perspective-phong",
        size,
        Default::default(),
        |_, _| camera(&mesh),
    );
    let big_frame = common::render_view(
        &points(&big),
        "perspective-phong",
        size,
        Default::default(),
        |_, _| camera(&big),
    );
    let same = metrics::psnr_color(&small_frame, &big_frame)
        .expect("psnr")
        .expect("pixels");
    assert!(same > 40.0, "the two scales differ: {same:.2} dB");
    let small = interior_psnr(
        &points(&mesh),
        &mesh,
        "perspective-phong",
        size,
        camera(&mesh),
    );
    let large = interior_psnr(&points(&big), &big, "perspective-phong", size, camera(&big));
    assert!(
        (small - large).abs() < 0.3,
        "×1 {small:.2} dB, ×1000 {large:.2} dB"
    );
    // Against Gouraud on the same view: the field helps, or at least does not hurt.
    let gouraud = interior_psnr(
        &points(&mesh),
        &mesh,
        "perspective-gouraud",
        size,
        camera(&mesh),
    );
    assert!(
        small > gouraud - 0.1,
        "phong {small:.2} dB, gouraud {gouraud:.2} dB"
    );
    eprintln!(
        "bunny close view: x1 {small:.2} dB, x1000 {large:.2} dB, between them {same:.2} dB; \
         gouraud {gouraud:.2} dB"
    );
}

#[test]
fn deferred_lights_per_pixel_and_gouraud_per_splat() {
    // A large splat facing the camera under the headlight: deferred shading lights every pixel
    // at its own point, so the rim (seen at an angle from the light) is darker than the centre.
    let size = 64;
    let splats = [grey(Vec3::ZERO, Vec3::Z, 1.0)];
    let deferred = render(&splats, "affine-deferred", size, 2.0);
    let centre = 32 * size as usize + 32;
    let rim = 32 * size as usize + 5;
    assert!(deferred.covered(rim));
    let (c, r) = (deferred.color[centre], deferred.color[rim]);
    assert!(c[0] > r[0] + 5, "centre {c:?} rim {r:?}");
    let gouraud = render(&splats, "affine-gouraud", size, 2.0);
    assert_eq!(gouraud.color[centre], gouraud.color[rim]);
}

#[test]
fn paraboloids_meet_at_the_bisector_as_round_points_with_raised_centres() {
    // Two 16-pixel points at one depth, 10 pixels apart: red left, blue right, centred on the
    // pixel corners (27, 32) and (37, 32).
    let (size, d) = (64, 3.0);
    let unit = d / pixels_per_unit(size);
    let at = |px: f64, color| Splat {
        color,
        ..grey(Vec3::new((px * unit) as f32, 0.0, 0.0), Vec3::Z, 0.1)
    };
    let splats = [at(-5.0, [255, 0, 0, 255]), at(5.0, [0, 0, 255, 255])];
    let centres = [(27.0, 32.0), (37.0, 32.0)];
    let distance = |i: usize, (cx, cy): (f64, f64)| {
        let (x, y) = ((i % 64) as f64 + 0.5, (i / 64) as f64 + 0.5);
        ((x - cx).powi(2) + (y - cy).powi(2)).sqrt()
    };
    // Which point a covered pixel shows, and whether it is the nearer centre's.
    let wrong_side = |frame: &Frame| {
        covered(frame)
            .into_iter()
            .filter(|&i| {
                let [r, _, b, _] = frame.color[i];
                let left = distance(i, centres[0]) < distance(i, centres[1]);
                (r > b) != left
            })
            .count()
    };
    let frame = render(&splats, "paraboloids:size=16", size, d as f32);
    assert_eq!(wrong_side(&frame), 0, "pixels of the farther centre");
    for i in 0..frame.pixels() {
        let nearest = distance(i, centres[0]).min(distance(i, centres[1]));
        if nearest < 7.5 {
            assert!(frame.covered(i), "pixel {i} inside a disc is empty");
        } else if nearest > 8.5 {
            assert!(!frame.covered(i), "pixel {i} outside both discs is covered");
        }
    }
    // At a centre the depth is raised by the radius, 8 pixels at depth d.
    let centre = 32 * 64 + 27;
    let raised = d - 8.0 * unit * (1.0 - (0.5f64.powi(2) * 2.0) / 64.0);
    assert!(
        (f64::from(frame.depth[centre]) - raised).abs() < 1e-4,
        "depth {} at the centre, {raised} expected",
        frame.depth[centre]
    );
    // Fixed-size squares give the whole overlap to one point.
    let squares = render(&splats, "points:size=16", size, d as f32);
    assert!(wrong_side(&squares) >= 16, "{}", wrong_side(&squares));
}

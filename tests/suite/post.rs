//! The post-processing stage on lavapipe under validation and synchronization validation:
//! eye-dome lighting darkens a depth step by exactly the published formula and leaves flat
//! regions alone, with every method; the background fills exactly the uncovered pixels.

use crate::common;

use glam::Vec3;
use surfel::eval::Frame;
use surfel::gpu_scene::upload;
use surfel::post::{Background, Edl, PostOptions};
use surfel::render::RendererOptions;
use surfel::scene::{Camera, Cloud};

const SIZE: u32 = 64;

/// Two squares without normals, seen head-on: the back one spans [-1, 1]² at z = 0, the front
/// one [0, 1] x [-1, 1] at z = `step`, so a vertical depth step runs down the middle. Each is
/// an `n` x `n` grid of points and two triangles (for `mesh`).
fn depth_step(n: usize, step: f32) -> Cloud {
    let mut positions = Vec::new();
    let mut faces = Vec::new();
    for (x0, z) in [(-1.0, 0.0), (0.0, step)] {
        let first = positions.len() as u32;
        let corner = |x: f32, y: f32| Vec3::new(x, y, z);
        positions.extend([
            corner(x0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(x0, 1.0),
        ]);
        faces.extend([[first, first + 1, first + 2], [first, first + 2, first + 3]]);
        let width = 1.0 - x0;
        for j in 0..n {
            for i in 0..n {
                let t = |k: usize| (k as f32 + 0.5) / n as f32;
                positions.push(corner(x0 + width * t(i), -1.0 + 2.0 * t(j)));
            }
        }
    }
    Cloud {
        positions,
        faces: Some(faces),
        ..Default::default()
    }
}

/// Renders `cloud` with `method` and `post` at SIZE² looking down -z at the back square's
/// centre: a first-frame render, then a read-back frame with the steady-state barriers.
fn render(cloud: &Cloud, method: &str, post: PostOptions) -> Frame {
    let ctx = common::context();
    let config = surfel::methods::MethodConfig::parse(method).expect("method");
    let options = config.method.upload_options(Default::default());
    let (scene, info) = upload(&ctx, cloud, &options).expect("upload");
    let extras = RendererOptions {
        post,
        ..RendererOptions::default()
    };
    let camera = Camera::framing(Vec3::ZERO, 2f32.sqrt());
    common::two_frames(&ctx, &scene, info, method, SIZE, extras, camera)
}

/// The EDL response of pixel `(x, y)` computed on the CPU from the read-back depth (infinite
/// where empty): the mean over the neighbours of max(0, log2 d - log2 d_n), image edges
/// clamped, empty neighbours adding nothing.
fn response(frame: &Frame, edl: &Edl, x: i32, y: i32) -> f64 {
    let (w, h) = (frame.width as i32, frame.height as i32);
    let at = |x: i32, y: i32| f64::from(frame.depth[(y * w + x) as usize]);
    let d = at(x, y).log2();
    let offsets = edl.offsets();
    let sum: f64 = offsets
        .iter()
        .map(|[dx, dy]| at((x + dx).clamp(0, w - 1), (y + dy).clamp(0, h - 1)))
        .filter(|dn| dn.is_finite())
        .map(|dn| (d - dn.log2()).max(0.0))
        .sum();
    sum / offsets.len() as f64
}

/// Checks `lit` (with `edl`, transparent background) against `plain` (no post-processing)
/// pixel by pixel: background unchanged, each covered pixel's color times the shade of the
/// formula (within one step of rounding), flat pixels exactly as they were. Returns (pixels
/// darkened, flat pixels).
fn check_edl(plain: &Frame, lit: &Frame, edl: &Edl, label: &str) -> (usize, usize) {
    assert_eq!(plain.depth, lit.depth, "{label}: EDL changed the depth");
    let (mut darkened, mut flat) = (0, 0);
    for y in 0..SIZE as i32 {
        for x in 0..SIZE as i32 {
            let i = (y * SIZE as i32 + x) as usize;
            let (before, after) = (plain.color[i], lit.color[i]);
            if !plain.covered(i) {
                assert_eq!(
                    after, before,
                    "{label}: background pixel ({x}, {y}) changed"
                );
                continue;
            }
            let shade = (-300.0 * f64::from(edl.strength) * response(plain, edl, x, y)).exp();
            // Flat: the formula moves no channel by a quarter step (zero response, or the
            // rounding noise of quantized positions), so the color must stay exactly.
            if (1.0 - shade) * 255.0 < 0.25 {
                assert_eq!(after, before, "{label}: flat pixel ({x}, {y}) changed");
                flat += 1;
                continue;
            }
            for c in 0..3 {
                let expected = f64::from(before[c]) * shade;
                assert!(
                    (f64::from(after[c]) - expected).abs() <= 1.0,
                    "{label}: ({x}, {y}) channel {c}: {} -> {} but {before:?} x {shade} = {expected}",
                    before[c],
                    after[c]
                );
            }
            assert_eq!(after[3], before[3], "{label}: alpha at ({x}, {y})");
            darkened += 1;
        }
    }
    (darkened, flat)
}

#[test]
fn eye_dome_lighting_darkens_the_far_side_of_a_depth_step_by_the_formula() {
    // At the framing distance (about 3.7) a step of 0.02 is log2 ratio 0.0078: one nearer
    // neighbour of eight shades by exp(-300 x 0.0078 / 8) = 0.75, so the test sees graded
    // values rather than black.
    let cloud = depth_step(200, 0.02);
    let edl = Edl::default();
    let plain = render(&cloud, "points:size=2", PostOptions::NONE);
    let lit = render(
        &cloud,
        "points:size=2",
        PostOptions {
            edl: Some(edl),
            background: Background::Transparent,
        },
    );
    let (darkened, flat) = check_edl(&plain, &lit, &edl, "points");
    // The step is about 42 px tall; the back square's column beside it darkens, the rest of
    // the covered area is flat.
    assert!(darkened >= 40, "{darkened} darkened pixels");
    assert!(flat > 1500, "{flat} flat pixels");
    // The darkened pixels lie on the far side of the step, next to the near square.
    let near = (0..plain.pixels())
        .filter(|&i| plain.covered(i))
        .map(|i| plain.depth[i])
        .fold(f32::INFINITY, f32::min);
    let mut darkest = 1.0f64;
    for i in (0..plain.pixels()).filter(|&i| plain.color[i] != lit.color[i]) {
        assert!(
            plain.depth[i] > near * 1.001,
            "pixel {i} at the near depth darkened"
        );
        darkest = darkest.min(f64::from(lit.color[i][0]) / f64::from(plain.color[i][0]));
    }
    assert!(darkest < 0.5, "darkest shade {darkest}");
}

#[test]
fn eye_dome_lighting_follows_strength_and_radius_with_every_method() {
    let cloud = depth_step(200, 0.02);
    let ctx = common::context();
    let edl = Edl::new(0.5, 3.0).expect("valid");
    for method in ["points:size=2", "compute", "compute-hq", "mesh", "ewa"] {
        let name = method.split(':').next().expect("name");
        if let Some(why) = surfel::methods::find(name)
            .expect("method")
            .unsupported(&ctx.caps)
        {
            eprintln!("skipping {method}: {why}");
            continue;
        }
        let plain = render(&cloud, method, PostOptions::NONE);
        let lit = render(
            &cloud,
            method,
            PostOptions {
                edl: Some(edl),
                background: Background::Transparent,
            },
        );
        let (darkened, flat) = check_edl(&plain, &lit, &edl, method);
        // A radius of 3 reaches 3 px into the back square beside the step.
        assert!(darkened >= 3 * 40, "{method}: {darkened} darkened pixels");
        assert!(flat > 500, "{method}: {flat} flat pixels");
    }
}

#[test]
fn the_background_fills_exactly_the_uncovered_pixels() {
    let cloud = depth_step(200, 0.02);
    let plain = render(&cloud, "points:size=2", PostOptions::NONE);
    assert!(plain.color.iter().any(|c| c[3] == 0), "nothing uncovered");
    let colored = PostOptions {
        edl: None,
        background: Background::Color([10, 200, 30]),
    };
    let edl = Edl::default();
    for (post, method) in [
        (colored, "points:size=2"),
        (colored, "mesh"),
        (
            PostOptions {
                edl: Some(edl),
                ..colored
            },
            "points:size=2",
        ),
    ] {
        let plain = render(&cloud, method, PostOptions::NONE);
        let shown = render(&cloud, method, post);
        if post.edl.is_none() {
            // `render` composites on the host instead of running this pass: same image.
            let mut host = plain.clone();
            surfel::post::composite(&mut host, post.background);
            assert_eq!(host.color, shown.color, "{method}: host composite");
            surfel::post::composite(&mut host, post.background);
            assert_eq!(host.color, shown.color, "{method}: composite twice");
        }
        for i in 0..plain.pixels() {
            if !plain.covered(i) {
                assert_eq!(shown.color[i], [10, 200, 30, 255], "{method}: pixel {i}");
            } else if post.edl.is_none() {
                let [r, g, b, _] = plain.color[i];
                assert_eq!(shown.color[i], [r, g, b, 255], "{method}: pixel {i}");
            } else {
                assert_eq!(shown.color[i][3], 255, "{method}: pixel {i}");
            }
        }
    }
    // With EDL and the background together, covered pixels shade as with a transparent one.
    let both = render(
        &cloud,
        "points:size=2",
        PostOptions {
            edl: Some(edl),
            ..colored
        },
    );
    let lit = render(
        &cloud,
        "points:size=2",
        PostOptions {
            edl: Some(edl),
            background: Background::Transparent,
        },
    );
    for i in (0..plain.pixels()).filter(|&i| plain.covered(i)) {
        assert_eq!(both.color[i], lit.color[i], "pixel {i}");
    }
}

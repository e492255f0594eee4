//! Degenerate clouds through every method, and determinism, on lavapipe with validation and
//! synchronization validation on: each case either renders a frame without NaN (colour, depth,
//! normals) or is refused with a message naming the problem; no validation error, no device
//! loss. Every method renders the same frame twice bit for bit.

use crate::common;

use std::sync::Arc;

use glam::Vec3;
use surfel::eval::Frame;
use surfel::gpu::Context;
use surfel::gpu_scene::upload;
use surfel::gpu_scene::UploadOptions;
use surfel::methods::{MethodConfig, METHODS};
use surfel::render::{Renderer, RendererOptions, View};
use surfel::scene::{Camera, Cloud, Light};

/// Frame size: large enough for the pyramid's levels and the kernels, small for lavapipe.
const SIZE: u32 = 24;

/// A cloud of `positions` with +z normals and radius 0.05.
fn cloud(positions: Vec<Vec3>) -> Cloud {
    let n = positions.len();
    Cloud {
        positions,
        normals: Some(vec![Vec3::Z; n]),
        radii: Some(vec![0.05; n]),
        ..Default::default()
    }
}

/// A `side` × `side` grid on the z = 0 plane over [-1, 1]².
fn grid(side: usize) -> Vec<Vec3> {
    let t = |k: usize| -1.0 + 2.0 * (k as f32 + 0.5) / side as f32;
    (0..side * side)
        .map(|i| Vec3::new(t(i % side), t(i / side), 0.0))
        .collect()
}

/// A named degenerate scene and the camera to see it with (`None`: framing the cloud).
struct Case {
    name: &'static str,
    cloud: Cloud,
    camera: Option<Camera>,
}

fn cases() -> Vec<Case> {
    let case = |name, cloud| Case {
        name,
        cloud,
        camera: None,
    };
    let mut non_finite = cloud(grid(8));
    non_finite.positions[3] = Vec3::NAN;
    non_finite.positions[9] = Vec3::new(f32::INFINITY, 0.0, 0.0);
    non_finite.positions[17] = Vec3::new(0.0, f32::NEG_INFINITY, f32::NAN);
    let mut bad_normals = cloud(grid(8));
    if let Some(n) = bad_normals.normals.as_mut() {
        for (i, n) in n.iter_mut().enumerate() {
            *n = if i % 2 == 0 { Vec3::ZERO } else { Vec3::NAN };
        }
    }
    let with_radius = |r: f32| {
        let mut c = cloud(grid(8));
        c.radii = Some(vec![r; c.len()]);
        c
    };
    let mut far = cloud(grid(8));
    for p in &mut far.positions {
        *p += Vec3::splat(1e7);
    }
    let mut back_facing = cloud(grid(8));
    back_facing.normals = Some(vec![-Vec3::Z; back_facing.len()]);
    let shell = common::shell(400, 1.0);
    let inside = Case {
        name: "camera inside the cloud",
        camera: Some(Camera::look_at(Vec3::ZERO, Vec3::X, 1.0)),
        cloud: Cloud {
            normals: Some(shell.iter().map(|p| -*p).collect()),
            radii: Some(vec![0.1; shell.len()]),
            positions: shell,
            ..Default::default()
        },
    };
    vec![
        case("empty", Cloud::default()),
        case("1 point", cloud(vec![Vec3::new(5.0, -2.0, 1.0)])),
        case(
            "2 points",
            cloud(vec![Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)]),
        ),
        case("all coincident", cloud(vec![Vec3::ONE; 500])),
        case(
            "on a line",
            cloud((0..200).map(|i| Vec3::X * i as f32 * 0.01).collect()),
        ),
        case("on a plane", cloud(grid(16))),
        case("NaN and infinite positions", non_finite),
        case("zero and NaN normals", bad_normals),
        case("radius 0", with_radius(0.0)),
        case("huge radius", with_radius(1e6)),
        case("coordinates at 1e7", far),
        case("all back-facing", back_facing),
        inside,
    ]
}

/// The methods this device runs.
fn methods(ctx: &Context) -> Vec<&'static str> {
    METHODS
        .iter()
        .filter(|m| m.unsupported(&ctx.caps).is_none())
        .map(|m| m.name)
        .collect()
}

/// Renders `method` twice (the first frame with its first-use barriers, the second read back)
/// in a renderer of its own; an error from building or rendering is returned.
fn render(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    method: &str,
    camera: Option<Camera>,
) -> anyhow::Result<Frame> {
    let config = MethodConfig::parse(method)?;
    let options = config.method.upload_options(UploadOptions::default());
    let (scene, info) = upload(ctx, cloud, &options)?;
    let camera = camera.unwrap_or_else(|| Camera::framing(info.centre, info.radius));
    let mut renderer = Renderer::new(
        ctx,
        &scene,
        info,
        &config,
        SIZE,
        SIZE,
        RendererOptions {
            readback: true,
            ..Default::default()
        },
    )?;
    let view = View {
        camera,
        lights: vec![Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    renderer.render(&view, false)?;
    renderer
        .render(&view, true)?
        .ok_or_else(|| anyhow::anyhow!("no read-back frame"))
}

#[test]
fn degenerate_clouds_render_defined_frames_or_are_refused_clearly_by_every_method() {
    let ctx = common::context();
    let methods = methods(&ctx);
    let mut rendered = 0;
    let mut refused = Vec::new();
    let mut failed = Vec::new();
    for case in cases() {
        for &method in &methods {
            match render(&ctx, &case.cloud, method, case.camera) {
                Ok(frame) => {
                    let report = surfel::eval::metrics::check_finite(&frame).expect("sizes");
                    if !report.is_clean() {
                        failed.push(format!("{method}, {}: {report:?}", case.name));
                    }
                    rendered += 1;
                }
                Err(e) => {
                    let message = format!("{e:#}");
                    assert!(
                        !message.contains("DEVICE_LOST") && message.len() > 10,
                        "{method}, {}: {message}",
                        case.name
                    );
                    refused.push(format!("{method}, {}: {message}", case.name));
                }
            }
            common::assert_clean(&ctx);
        }
    }
    println!(
        "{rendered} frames rendered, {} refused:\n{}",
        refused.len(),
        refused.join("\n")
    );
    assert!(failed.is_empty(), "frames with NaN:\n{}", failed.join("\n"));
    assert_eq!(
        rendered + refused.len(),
        cases().len() * methods.len(),
        "every case ran"
    );
}

#[test]
fn every_method_renders_the_same_frame_twice_bit_for_bit() {
    let ctx = common::context();
    // A sphere with faces, normals and radii: every method has what it reads.
    let scene = common::sphere(24);
    let camera = Some(Camera::orbit(Vec3::ZERO, 1.2, 20.0, 25.0));
    for method in methods(&ctx) {
        let a = render(&ctx, &scene, method, camera).expect("first run");
        let b = render(&ctx, &scene, method, camera).expect("second run");
        assert!(a.color == b.color, "{method}: colours differ between runs");
        let bits = |f: &Frame| f.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>();
        assert!(bits(&a) == bits(&b), "{method}: depths differ between runs");
        assert!(
            common::coverage(&a) > 0.05,
            "{method}: the scene is not in the frame"
        );
    }
    common::assert_clean(&ctx);
}

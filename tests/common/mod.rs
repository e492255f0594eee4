//! Shared helpers for GPU tests: a validated lavapipe context and synthetic scenes.

#![allow(dead_code)]

use std::sync::Arc;

use glam::Vec3;
use surfel::gpu::{Context, ContextOptions};
use surfel::scene::Cloud;

/// A context with validation and synchronization validation on. Tests call `assert_clean`.
pub fn context() -> Arc<Context> {
    std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir());
    Arc::new(
        Context::new(&ContextOptions {
            validation: true,
            surface_extensions: Vec::new(),
        })
        .expect("Vulkan context with validation (run ../shared/ci/install-vulkan.sh)"),
    )
}

/// Fails the test if the validation layers reported any error.
pub fn assert_clean(ctx: &Context) {
    assert_eq!(
        ctx.validation_errors(),
        0,
        "validation errors: {:#?}",
        ctx.first_validation_errors()
    );
}

/// A square [-1, 1]^2 in the z = 0 plane as two triangles, normals +z, plus `n x n` extra
/// grid points on it (when `n > 0`), so the same cloud serves the mesh and point methods.
pub fn square(n: usize) -> Cloud {
    let mut positions = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    for j in 0..n {
        for i in 0..n {
            let t = |k: usize| -1.0 + 2.0 * (k as f32 + 0.5) / n as f32;
            positions.push(Vec3::new(t(i), t(j), 0.0));
        }
    }
    let count = positions.len();
    Cloud {
        normals: Some(vec![Vec3::Z; count]),
        radii: Some(vec![1.0 / n.max(1) as f32; count]),
        faces: Some(vec![[0, 1, 2], [0, 2, 3]]),
        positions,
        ..Default::default()
    }
}

/// Fraction of covered pixels.
pub fn coverage(frame: &surfel::eval::Frame) -> f64 {
    (0..frame.pixels()).filter(|&i| frame.covered(i)).count() as f64 / frame.pixels() as f64
}

/// Renders `cloud` with `method` at `size`² in a validated context (streams uploaded with
/// `options` and what the method reads, camera from the bounding sphere's centre and radius): one frame with the
/// first-frame barriers, then a read-back frame with the steady-state ones. Fails on any
/// validation error.
pub fn render_view(
    cloud: &Cloud,
    method: &str,
    size: u32,
    options: surfel::gpu_scene::UploadOptions,
    camera: impl Fn(Vec3, f32) -> surfel::scene::Camera,
) -> surfel::eval::Frame {
    let ctx = context();
    let config = surfel::methods::MethodConfig::parse(method).expect("method");
    let options = config.method.upload_options(options);
    let (scene, info) = surfel::gpu_scene::upload(&ctx, cloud, &options).expect("upload");
    let camera = camera(info.centre, info.radius);
    two_frames(&ctx, &scene, info, method, size, Default::default(), camera)
}

/// Renders `method` at `size`² with the headlight from `camera`, with `extras` plus readback:
/// one frame with the first-frame barriers, then a read-back frame with the steady-state ones.
/// Fails on any validation error.
pub fn two_frames(
    ctx: &Arc<Context>,
    scene: &surfel::gpu_scene::GpuScene,
    info: surfel::gpu_scene::SceneInfo,
    method: &str,
    size: u32,
    extras: surfel::render::RendererOptions,
    camera: surfel::scene::Camera,
) -> surfel::eval::Frame {
    use surfel::render::{Renderer, RendererOptions, View};
    let config = surfel::methods::MethodConfig::parse(method).expect("method");
    let mut r = Renderer::new(
        ctx,
        scene,
        info,
        &config,
        size,
        size,
        RendererOptions {
            readback: true,
            ..extras
        },
    )
    .expect("renderer");
    let view = View {
        camera,
        lights: vec![surfel::scene::Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    r.render(&view, false).expect("frame 1");
    let frame = r.render(&view, true).expect("frame 2").expect("readback");
    drop(r);
    assert_clean(ctx);
    frame
}

/// `render_view` framing the cloud.
pub fn render_with(
    cloud: &Cloud,
    method: &str,
    size: u32,
    options: surfel::gpu_scene::UploadOptions,
) -> surfel::eval::Frame {
    render_view(cloud, method, size, options, surfel::scene::Camera::framing)
}

/// `render_with` the default upload options.
pub fn render(cloud: &Cloud, method: &str, size: u32) -> surfel::eval::Frame {
    render_with(cloud, method, size, Default::default())
}

/// Renders `cloud` colored by `coloring` (`surfel::color::select`) with `method` at `size`²,
/// framing the cloud, in a validated context: one frame, then a read-back one.
pub fn render_colored(
    cloud: &Cloud,
    method: &str,
    size: u32,
    coloring: surfel::color::Coloring,
) -> surfel::eval::Frame {
    let ctx = context();
    let (scene, info) = surfel::gpu_scene::upload(
        &ctx,
        cloud,
        &surfel::gpu_scene::UploadOptions::colored(coloring),
    )
    .expect("upload");
    let camera = surfel::scene::Camera::framing(info.centre, info.radius);
    two_frames(&ctx, &scene, info, method, size, Default::default(), camera)
}

/// `n` × `n` points of one color on the unit square at height `z` facing +z, keeping those whose
/// x passes `keep`; the radius is the grid spacing (what the k-NN estimate gives a grid).
pub fn layer(n: usize, color: [u8; 4], z: f32, keep: impl Fn(f32) -> bool) -> Cloud {
    let t = |k: usize| -0.5 + (k as f32 + 0.5) / n as f32;
    let positions: Vec<Vec3> = (0..n * n)
        .map(|k| Vec3::new(t(k % n), t(k / n), z))
        .filter(|p| keep(p.x))
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

/// Texels of `gpu` and `cpu` agree: same validity, values within half-precision tolerance.
pub fn assert_levels_match(
    gpu: &[surfel::methods::pyramid::reference::Level],
    cpu: &[surfel::methods::pyramid::reference::Level],
    what: &str,
) {
    assert_eq!(gpu.len(), cpu.len(), "{what}: levels");
    for (l, (g, c)) in gpu.iter().zip(cpu).enumerate() {
        assert_eq!(
            (g.width, g.height),
            (c.width, c.height),
            "{what}: level {l} size"
        );
        for (i, (a, b)) in g.texels.iter().zip(&c.texels).enumerate() {
            let at = format!("{what}: level {l} texel {i}");
            assert_eq!(a.is_empty(), b.is_empty(), "{at}: {a:?} vs {b:?}");
            if a.is_empty() {
                continue;
            }
            let near = |x: f32, y: f32, tol: f32| (x - y).abs() <= tol * y.abs().max(1.0);
            assert!((a.n - b.n).length() < 4e-3, "{at}: normal {a:?} vs {b:?}");
            assert!(
                near(a.radius, b.radius, 2e-3),
                "{at}: radius {a:?} vs {b:?}"
            );
            assert!(near(a.depth, b.depth, 1e-5), "{at}: depth {a:?} vs {b:?}");
            assert!(
                near(a.half_range, b.half_range, 1e-5),
                "{at}: range {a:?} vs {b:?}"
            );
            assert!(
                (a.disp - b.disp).length() < 4e-3 * (1 << l) as f32,
                "{at}: disp {a:?} vs {b:?}"
            );
            assert!(
                (a.color - b.color).length() < 4e-3,
                "{at}: color {a:?} vs {b:?}"
            );
        }
    }
}

/// Adds to `g` the readback of the pyramid images `images(l)` (A: RGBA16F normal and radius,
/// B: RGBA32F depth, half range and displacement, C: RGBA16F color) at every level of
/// `extents`, runs the graph once, checks that validation stayed clean and decodes the levels.
pub fn run_and_read_levels(
    ctx: &Arc<Context>,
    mut g: surfel::graph::GraphBuilder,
    extents: &[(u32, u32)],
    images: impl Fn(u32) -> [surfel::graph::ImageId; 3],
) -> Vec<surfel::methods::pyramid::reference::Level> {
    use surfel::graph::Access;
    use surfel::methods::pyramid::reference::{Level, Texel};
    let host: Vec<[Arc<surfel::gpu::Buffer>; 3]> = extents
        .iter()
        .map(|&(lw, lh)| {
            let px = u64::from(lw * lh);
            [8, 16, 8].map(|bytes| {
                Arc::new(surfel::gpu::Buffer::readback(ctx, "rb", px * bytes).expect("rb"))
            })
        })
        .collect();
    let mut copies = Vec::new();
    for (l, bufs) in host.iter().enumerate() {
        for (image, buffer) in images(l as u32).into_iter().zip(bufs) {
            copies.push((image, l as u32, g.import_buffer("rb", buffer.clone())));
        }
    }
    let mut pass = g.pass("readback");
    for &(image, level, id) in &copies {
        pass = pass
            .image_mips(image, level, 1, Access::TransferSrc)
            .buffer(id, Access::TransferDst);
    }
    let list = copies.clone();
    pass.record(move |ctx| {
        for &(image, level, id) in &list {
            ctx.copy_image_to_buffer(image, level, id);
        }
    });
    let mut done = g.pass("readback.host");
    for &(_, _, id) in &copies {
        done = done.buffer(id, Access::HostRead);
    }
    done.record(|_| {});
    let mut graph = g.compile(ctx).expect("compile");
    graph.run_once(ctx).expect("run");
    let halves = |b: &surfel::gpu::Buffer| -> Vec<f32> {
        b.mapped()
            .expect("mapped")
            .chunks_exact(2)
            .map(|h| half::f16::from_le_bytes([h[0], h[1]]).to_f32())
            .collect()
    };
    let out = extents
        .iter()
        .zip(&host)
        .map(|(&(lw, lh), bufs)| {
            let (a, c) = (halves(&bufs[0]), halves(&bufs[2]));
            let b: Vec<f32> = bytemuck::cast_slice(bufs[1].mapped().expect("mapped")).to_vec();
            Level {
                width: lw,
                height: lh,
                texels: (0..(lw * lh) as usize)
                    .map(|i| Texel {
                        n: Vec3::new(a[4 * i], a[4 * i + 1], a[4 * i + 2]),
                        radius: a[4 * i + 3],
                        depth: b[4 * i],
                        half_range: b[4 * i + 1],
                        disp: glam::Vec2::new(b[4 * i + 2], b[4 * i + 3]),
                        color: glam::Vec4::new(c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]),
                    })
                    .collect(),
            }
        })
        .collect();
    drop(graph);
    assert_clean(ctx);
    out
}

/// A camera 1.5 above the origin looking down -z (the synthetic planes' top view; the
/// signature of `render_view`'s framing).
pub fn top_view(_: Vec3, _: f32) -> surfel::scene::Camera {
    surfel::scene::Camera::look_at(Vec3::new(0.0, 0.0, 1.5), Vec3::ZERO, 1.0)
}

/// Pixels covered by `frame`.
pub fn covered(frame: &surfel::eval::Frame) -> Vec<bool> {
    (0..frame.pixels()).map(|i| frame.covered(i)).collect()
}

/// `mask` shrunk by `r` pixels (a pixel stays when its whole (2r+1)² window is set).
pub fn eroded(mask: &[bool], size: usize, r: usize) -> Vec<bool> {
    (0..mask.len())
        .map(|i| {
            let (x, y) = (i % size, i / size);
            x >= r
                && y >= r
                && x + r < size
                && y + r < size
                && (y - r..=y + r).all(|v| (x - r..=x + r).all(|u| mask[v * size + u]))
        })
        .collect()
}

/// A UV sphere of radius 1 (`rings` × `2 rings` quads) as a mesh and its vertices as points
/// with their exact normals and radii from the density of their 10 nearest neighbours.
pub fn sphere(rings: usize) -> Cloud {
    let segments = 2 * rings;
    let mut positions = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            positions.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ));
        }
    }
    let at = |i: usize, j: usize| (i * segments + j % segments) as u32;
    let mut faces = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            faces.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
            faces.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
        }
    }
    let neighbours = surfel::scene::preprocess::Neighbours::compute(
        &positions,
        surfel::scene::preprocess::DEFAULT_K,
        false,
    );
    let radii = surfel::scene::preprocess::estimate_radii(
        &positions,
        &neighbours,
        surfel::scene::preprocess::RadiusMode::DensitySpacing,
    );
    let colors = positions
        .iter()
        .map(|p| {
            let c = |v: f32| (127.5 + 127.0 * v) as u8;
            [c(p.x), c(p.y), c(p.z), 255]
        })
        .collect();
    Cloud {
        normals: Some(positions.clone()),
        radii: Some(radii),
        colors: Some(colors),
        faces: Some(faces),
        positions,
        ..Default::default()
    }
}

/// `frame` with the pixels outside `mask` emptied.
pub fn masked(frame: &surfel::eval::Frame, mask: &[bool]) -> surfel::eval::Frame {
    let mut out = frame.clone();
    for (i, keep) in mask.iter().enumerate() {
        if !keep {
            out.color[i] = [0; 4];
            out.depth[i] = f32::INFINITY;
        }
    }
    out
}

/// Points on a unit sphere (Fibonacci lattice), scaled.
pub fn shell(n: usize, scale: f32) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let a = golden * i as f32;
            Vec3::new(r * a.cos(), y, r * a.sin()) * scale
        })
        .collect()
}

/// Angles in degrees between two sets of unit normals, pairwise, sorted.
pub fn angles(a: &[Vec3], b: &[Vec3]) -> Vec<f32> {
    let mut d: Vec<f32> = a
        .iter()
        .zip(b)
        .map(|(x, y)| x.dot(*y).clamp(-1.0, 1.0).acos().to_degrees())
        .collect();
    d.sort_by(f32::total_cmp);
    d
}

/// `../shared/data/e57/bunnyFloat.e57` with its scan's recordCount (30,571) replaced by
/// `count`, at most 13 digits: the XML keeps its length (the next line's indentation shrinks)
/// and the changed pages get their CRC-32C checksums again.
pub fn bunny_e57_claiming(count: u64) -> Vec<u8> {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/e57/bunnyFloat.e57");
    let mut bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let old = b"recordCount=\"30571\">\n        <prototype";
    let digits = count.to_string();
    let indent = " ".repeat(13 - digits.len());
    let new = format!("recordCount=\"{digits}\">\n{indent}<prototype");
    assert_eq!(old.len(), new.len(), "at most 13 digits");
    let at = bytes
        .windows(old.len())
        .position(|w| w == old)
        .expect("recordCount in the XML");
    bytes[at..at + new.len()].copy_from_slice(new.as_bytes());
    for page in [at / 1024, (at + new.len()) / 1024] {
        let start = page * 1024;
        let crc = crc32c(&bytes[start..start + 1020]);
        bytes[start + 1020..start + 1024].copy_from_slice(&crc.to_be_bytes());
    }
    bytes
}

/// CRC-32C (Castagnoli), the checksum of every 1,020-byte E57 page (stored big-endian after it).
fn crc32c(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in bytes {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = (crc >> 1) ^ if crc & 1 == 1 { 0x82F6_3B78 } else { 0 };
        }
    }
    !crc
}

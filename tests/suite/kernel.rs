//! The pyramid with search kernels (000 ch. 6) on lavapipe under validation and
//! synchronization validation: the GPU analysis and interpolation against the CPU model
//! (`methods::kernel::reference`) on random synthetic level-0 images for each kernel
//! size, and a sparse plane reconstructed without holes by `kernel3`, `kernel5` and `kernel7`.

use crate::common;

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, Vec2, Vec3, Vec4};
use surfel::gpu::Buffer;
use surfel::graph::{Access, Bind, GraphBuilder, Stages};
use surfel::layout::{
    FrameBlock, BINDING_INPUT0, BINDING_PYRAMID_OUT, PYRAMID_GROUP, PYRAMID_SPEC_COLOR,
};
use surfel::methods::kernel::reference::{self, searched_levels};
use surfel::methods::kernel::KernelPyramid;
use surfel::methods::pyramid::reference::{Level, Texel};
use surfel::scene::Cloud;

use common::{assert_levels_match, covered, eroded, render_view, top_view};

/// (proj[0][0] width, proj[1][1] height) of the synthetic frames (see tests/suite/pyramid.rs).
const SCALE: Vec2 = Vec2::new(40.0, -40.0);

fn buffer_with(ctx: &Arc<surfel::gpu::Context>, name: &str, bytes: &[u8]) -> Arc<Buffer> {
    Arc::new(
        Buffer::with_data(ctx, name, bytes, vk::BufferUsageFlags::STORAGE_BUFFER).expect("buffer"),
    )
}

/// Runs `level0` through the GPU analysis and interpolation of a `kernel` × `kernel` pyramid
/// and reads every level back: level 0 as resolved, the others as analysed.
fn gpu_levels(level0: &Level, kernel: u32) -> Vec<Level> {
    let ctx = common::context();
    let (w, h) = (level0.width, level0.height);
    let mut block: FrameBlock = bytemuck::Zeroable::zeroed();
    block.u.proj = Mat4::from_cols(
        Vec4::new(SCALE.x / w as f32, 0.0, 0.0, 0.0),
        Vec4::new(0.0, SCALE.y / h as f32, 0.0, 0.0),
        Vec4::new(0.0, 0.0, 0.0, -1.0),
        Vec4::new(0.0, 0.0, 1.0, 0.0),
    );
    block.u.viewport = Vec4::new(w as f32, h as f32, 1.0 / w as f32, 1.0 / h as f32);
    let frame_buffer = buffer_with(&ctx, "frame", bytemuck::bytes_of(&block));
    let texels: Vec<Vec4> = level0
        .texels
        .iter()
        .flat_map(|t| {
            [
                t.n.extend(t.radius),
                Vec4::new(t.depth, t.half_range, t.disp.x, t.disp.y),
                t.color,
            ]
        })
        .collect();
    let texel_buffer = buffer_with(&ctx, "texels", bytemuck::cast_slice(&texels));

    let mut g = GraphBuilder::new();
    let frame = g.import_buffer("frame", frame_buffer);
    let input = g.import_buffer("texels", texel_buffer);
    let kp = KernelPyramid::new(&mut g, "kernel", (w, h), kernel, true);
    let levels = kp.pyramid.levels;
    assert_eq!(levels, searched_levels(w, h, kernel));
    let params = kp.params(1.0);
    let first = kp.level0();
    let c = first.c.expect("colors");
    let mut binds = vec![Bind::reads(BINDING_INPUT0, input)];
    binds.extend(first.binds(
        BINDING_PYRAMID_OUT,
        0,
        Access::StorageWrite(Stages::Compute),
    ));
    g.compute("test.level0", "test/pyramid_level0.comp", &binds)
        .spec(&[(PYRAMID_SPEC_COLOR, 1)])
        .push(&params)
        .dispatch_grid((w.div_ceil(PYRAMID_GROUP), h.div_ceil(PYRAMID_GROUP)));
    kp.add_analysis(&mut g, frame, params, levels - 1);
    let result = kp.add_interpolation(&mut g, frame, params);
    assert_eq!(result.a, first.a);

    let extents: Vec<(u32, u32)> = (0..levels)
        .map(|l| ((w >> l).max(1), (h >> l).max(1)))
        .collect();
    common::run_and_read_levels(&ctx, g, &extents, |_| [first.a, first.b, c])
}

/// A `w` x `h` level 0: about a quarter of the pixels hold texels of a front surface (depth
/// around 2, tilted normals, radii 0.5..10 px: stored from level 0 up to level 3), a few a
/// back surface (depth 5); all in half precision like the images.
fn random_level(w: u32, h: u32, seed: u64) -> Level {
    let mut rng = surfel::rng::SplitMix64::new(seed);
    let mut unit = move || rng.next_f64() as f32;
    let mut level = Level::empty(w, h);
    for t in &mut level.texels {
        let roll = unit();
        if roll > 0.3 {
            continue;
        }
        let back = roll < 0.04;
        let n = Vec3::new(unit() - 0.5, unit() - 0.5, 1.0).normalize();
        *t = Texel {
            n,
            radius: 0.5 + 9.5 * unit() * unit(),
            depth: if back { 5.0 } else { 2.0 + 0.02 * unit() },
            half_range: 0.05,
            disp: Vec2::ZERO,
            color: Vec4::new(unit(), unit(), unit(), 0.0),
        }
        .stored();
    }
    level
}

#[test]
fn analysis_and_interpolation_match_the_cpu_model() {
    let level0 = random_level(37, 29, 21);
    let projected = level0.texels.iter().filter(|t| !t.is_empty()).count();
    for kernel in [3, 5, 7] {
        let mut cpu = reference::analysis(level0.clone(), kernel);
        let result = reference::interpolate(&cpu, kernel, SCALE);
        let filled = result.texels.iter().filter(|t| !t.is_empty()).count();
        assert!(
            filled > 2 * projected,
            "{kernel}: {filled} of {projected}: holes filled"
        );
        cpu[0] = result;
        let gpu = gpu_levels(&level0, kernel);
        assert_levels_match(&gpu, &cpu, &format!("kernel {kernel}"));
    }
}

/// `n` x `n` points on the unit square at height `z` facing +z, radius = the grid spacing.
fn plane(n: usize, z: f32, color: [u8; 4]) -> Cloud {
    common::layer(n, color, z, |_| true)
}

#[test]
fn a_sparse_plane_reconstructs_without_holes() {
    // 16 x 16 points about 5 pixels apart, projected radius about 9 pixels: stored in level 3
    // with 3 x 3 (several to a texel, merged), level 2 with 5 x 5 and 7 x 7.
    let size = 128;
    let cloud = plane(16, 0.0, [200, 100, 50, 255]);
    let view = |method: &str| render_view(&cloud, method, size, Default::default(), top_view);
    let inside = eroded(&covered(&view("perspective-flat")), size as usize, 2);
    assert!(inside.iter().filter(|&&c| c).count() > 10_000);
    // Ellipses as large as the pyramid's (the default radius scale) bound what it may cover.
    let large = view(&format!(
        "perspective-flat:radius={}",
        surfel::methods::pyramid::RADIUS_SCALE
    ));
    let outside = eroded(
        &covered(&large).iter().map(|c| !c).collect::<Vec<_>>(),
        size as usize,
        1,
    );
    for method in ["kernel3", "kernel5", "kernel7"] {
        let raw = view(&format!("{method}:show=0"));
        assert_eq!(
            covered(&raw).iter().filter(|&&c| c).count(),
            256,
            "{method}: level 0"
        );
        let frame = view(method);
        let got = covered(&frame);
        let holes = inside.iter().zip(&got).filter(|(&i, &g)| i && !g).count();
        assert_eq!(holes, 0, "{method}: holes inside the plane");
        let beyond = got
            .iter()
            .zip(&outside)
            .filter(|(&g, &far)| g && far)
            .count();
        assert_eq!(beyond, 0, "{method}: pixels beyond the splats' outline");
        // The plane's color under the headlight, and its depth.
        let centre = (size / 2 * size + size / 2) as usize;
        let [r, g, b, _] = frame.color[centre];
        assert!(
            (r as i32 - 200).abs() <= 3
                && (g as i32 - 100).abs() <= 3
                && (b as i32 - 50).abs() <= 3,
            "{method}: {:?}",
            frame.color[centre]
        );
        assert!(
            (frame.depth[centre] - 1.5).abs() < 1e-3,
            "{method}: {}",
            frame.depth[centre]
        );
    }
}

#[test]
fn a_front_surface_occludes_the_surface_behind_it() {
    // A sparse red plane over a dense green one 0.5 behind: the green splats are small and
    // stored in the lowest levels, found first by the search; the red ones, stored higher,
    // lie in front of them and replace them wherever they cover a pixel.
    let size = 128;
    let mut cloud = plane(16, 0.0, [255, 0, 0, 255]);
    let back = plane(64, -0.5, [0, 255, 0, 255]);
    cloud.positions.extend(back.positions);
    cloud
        .normals
        .as_mut()
        .unwrap()
        .extend(back.normals.unwrap());
    cloud.radii.as_mut().unwrap().extend(back.radii.unwrap());
    cloud.colors.as_mut().unwrap().extend(back.colors.unwrap());
    let front_only = plane(16, 0.0, [255, 0, 0, 255]);
    let view = |cloud: &Cloud, method: &str| {
        render_view(cloud, method, size, Default::default(), top_view)
    };
    let inside = eroded(
        &covered(&view(&front_only, "perspective-flat")),
        size as usize,
        2,
    );
    let green = |f: &surfel::eval::Frame, i: usize| f.color[i][1] > f.color[i][0];
    for method in ["kernel3", "kernel5", "kernel7"] {
        let frame = view(&cloud, method);
        for i in (0..frame.pixels()).filter(|&i| inside[i]) {
            assert!(
                !green(&frame, i),
                "{method}: pixel {i} shows the back plane"
            );
            assert!(
                (frame.depth[i] - 1.5).abs() < 0.01,
                "{method}: pixel {i} depth {}",
                frame.depth[i]
            );
        }
    }
}

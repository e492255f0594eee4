//! The pyramid point renderer (000 ch. 4) on lavapipe under validation and synchronization
//! validation: analysis and synthesis against the CPU model (`methods::pyramid::reference`)
//! on synthetic level-0 images in both layouts; sparse planes reconstructed without holes; a
//! front surface occluding a back one; the layouts and projections agreeing.

use crate::common;

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, Vec2, Vec3, Vec4};
use surfel::gpu::{Buffer, Context};
use surfel::graph::{Access, Bind, GraphBuilder, Stages};
use surfel::layout::{
    FrameBlock, PyramidParams, BINDING_INPUT0, BINDING_PYRAMID_OUT, PYRAMID_GROUP,
};
use surfel::methods::pyramid::reference::{self, Level, Texel};
use surfel::methods::pyramid::{specialization, Pyramid};
use surfel::scene::{pack, Camera, Cloud};

use common::{assert_levels_match, covered, eroded, render_view, top_view};

/// (proj[0][0] width, proj[1][1] height) of the synthetic frames: the pixel-space scale of
/// view directions (the sign of y flips the image rows, as the renderer's projection does).
const SCALE: Vec2 = Vec2::new(40.0, -40.0);
const FALLOFF: f32 = 2.0;

fn buffer_with(ctx: &Arc<Context>, name: &str, bytes: &[u8]) -> Arc<Buffer> {
    Arc::new(
        Buffer::with_data(ctx, name, bytes, vk::BufferUsageFlags::STORAGE_BUFFER).expect("buffer"),
    )
}

/// Runs level 0 through the GPU analysis (and synthesis) and reads every level back: the
/// analysed levels, or the synthesized ones (the top level as analysed).
fn gpu_levels(level0: &Level, single: bool, synthesize: bool, falloff: f32) -> Vec<Level> {
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
    let pyramid = Pyramid::new(&mut g, "pyramid", (w, h), true, single);
    let levels = pyramid.levels;
    let params = PyramidParams {
        level: 0,
        level_count: levels,
        radius_scale: 1.0,
        falloff,
    };
    let first = pyramid.holder(0);
    let mut binds = vec![Bind::reads(BINDING_INPUT0, input)];
    binds.extend(first.binds(
        BINDING_PYRAMID_OUT,
        0,
        Access::StorageWrite(Stages::Compute),
    ));
    g.compute("test.level0", "test/pyramid_level0.comp", &binds)
        .spec(&specialization(true, false, false))
        .push(&params)
        .dispatch_grid((w.div_ceil(PYRAMID_GROUP), h.div_ceil(PYRAMID_GROUP)));
    pyramid.add_analysis(&mut g, frame, params, levels - 1);
    // Where each level ends up: analysed level l in holder(l); synthesized level l in the
    // image synthesis of l wrote (holder(l + 1) for the pair, holder(l) for one image).
    let place = |l: u32| {
        if synthesize && l + 1 < levels && !single {
            pyramid.holder(l + 1)
        } else {
            pyramid.holder(l)
        }
    };
    if synthesize {
        let result = pyramid.add_synthesis(&mut g, frame, params);
        assert_eq!(result.a, place(0).a);
    }
    let extents: Vec<(u32, u32)> = (0..levels)
        .map(|l| ((w >> l).max(1), (h >> l).max(1)))
        .collect();
    common::run_and_read_levels(&ctx, g, &extents, |l| {
        let group = place(l);
        [group.a, group.b, group.c.expect("colors")]
    })
}

/// A `w` x `h` level 0: about a third of the pixels hold texels of a front surface (depth
/// around 2, tilted normals, radii 0.5..3.5 px), a few a back surface (depth 5) that the front
/// ellipses should cover; all in half precision like the images.
fn random_level(w: u32, h: u32, seed: u64) -> Level {
    let mut rng = surfel::rng::SplitMix64::new(seed);
    let mut unit = move || rng.next_f64() as f32;
    let mut level = Level::empty(w, h);
    for t in &mut level.texels {
        let roll = unit();
        if roll > 0.4 {
            continue;
        }
        let back = roll < 0.05;
        let n = Vec3::new(unit() - 0.5, unit() - 0.5, 1.0).normalize();
        *t = Texel {
            n,
            radius: 0.5 + 3.0 * unit(),
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
fn analysis_matches_the_cpu_model_in_both_layouts() {
    let level0 = random_level(37, 29, 11);
    let cpu = reference::analysis(level0.clone());
    assert_eq!(cpu.len(), 6);
    for single in [false, true] {
        let gpu = gpu_levels(&level0, single, false, FALLOFF);
        assert_levels_match(&gpu, &cpu, &format!("analysis, single image {single}"));
    }
}

#[test]
fn synthesis_matches_the_cpu_model_in_both_layouts() {
    let level0 = random_level(37, 29, 12);
    let cpu = reference::synthesis(reference::analysis(level0.clone()), SCALE, FALLOFF);
    let filled = cpu[0].texels.iter().filter(|t| !t.is_empty()).count();
    let projected = level0.texels.iter().filter(|t| !t.is_empty()).count();
    assert!(
        filled > projected + projected / 2,
        "{filled} of {projected}: holes filled"
    );
    for single in [false, true] {
        let gpu = gpu_levels(&level0, single, true, FALLOFF);
        assert_levels_match(&gpu, &cpu, &format!("synthesis, single image {single}"));
    }
}

/// A `w` x `h` level 0 full of one surface (depth 2, facing the camera) whose ellipses are
/// smaller than a pixel (radius 0.6), with empty texels: isolated ones, 2 x 2 and 4 x 4
/// blocks at every alignment, and the pixels outside a disc of radius `w` / 2 - 2 around the
/// centre (the background beyond a silhouette). Returns the level and the empty texels inside
/// the disc (the holes).
fn pinholed_level(w: u32, seed: u64) -> (Level, Vec<usize>) {
    let mut rng = surfel::rng::SplitMix64::new(seed);
    let mut unit = move || rng.next_f64() as f32;
    let mut level = Level::empty(w, w);
    let centre = w as f32 / 2.0;
    let inside = |x: u32, y: u32| {
        let d = Vec2::new(x as f32 + 0.5 - centre, y as f32 + 0.5 - centre);
        d.length() < centre - 2.0
    };
    for y in 0..w {
        for x in 0..w {
            if inside(x, y) {
                level.texels[(y * w + x) as usize] = Texel {
                    n: Vec3::new(0.1 * (unit() - 0.5), 0.1 * (unit() - 0.5), 1.0).normalize(),
                    radius: 0.6,
                    depth: 2.0 + 0.001 * unit(),
                    half_range: 0.05,
                    disp: Vec2::ZERO,
                    color: Vec4::new(unit(), unit(), unit(), 0.0),
                }
                .stored();
            }
        }
    }
    let mut holes = Vec::new();
    let mut punch = |x0: u32, y0: u32, n: u32, level: &mut Level| {
        for y in y0..y0 + n {
            for x in x0..x0 + n {
                let i = (y * w + x) as usize;
                if !level.texels[i].is_empty() {
                    level.texels[i] = Texel::default();
                    holes.push(i);
                }
            }
        }
    };
    // Isolated texels on a 7-pixel lattice, then blocks at even and odd offsets.
    for y in (6..w - 6).step_by(7) {
        for x in (6..w - 6).step_by(7) {
            if inside(x, y) {
                punch(x, y, 1, &mut level);
            }
        }
    }
    let c = w / 2;
    for (x, y, n) in [
        (c - 8, c - 8, 2),
        (c + 5, c - 9, 2),
        (c - 9, c + 4, 4),
        (c + 4, c + 5, 4),
        (c - 1, c + 12, 4),
    ] {
        punch(x, y, n, &mut level);
    }
    (level, holes)
}

#[test]
fn synthesis_fills_isolated_empty_texels_and_small_blocks() {
    // Ellipses of radius 0.6 px reach no neighbouring pixel centre, so only the enclosed-gap
    // rule fills the holes; the background outside the disc stays empty (its texels have at
    // most two valid parents), and the GPU equals the CPU model in both layouts.
    let (level0, holes) = pinholed_level(48, 21);
    assert!(holes.len() > 40, "{} holes", holes.len());
    let cpu = reference::synthesis(reference::analysis(level0.clone()), SCALE, FALLOFF);
    for &i in &holes {
        let t = cpu[0].texels[i];
        assert!(!t.is_empty(), "hole {i} stays empty");
        assert!((t.depth - 2.0).abs() < 0.01, "hole {i}: {t:?}");
    }
    let outside = level0
        .texels
        .iter()
        .zip(&cpu[0].texels)
        .enumerate()
        .filter(|(i, (before, after))| before.is_empty() && !after.is_empty() && !holes.contains(i))
        .count();
    // The disc's rim: a pixel just outside it may be enclosed where the rim is concave on the
    // pixel grid, never more than a ring's worth.
    assert!(outside < 48, "{outside} background texels filled");
    for single in [false, true] {
        let gpu = gpu_levels(&level0, single, true, FALLOFF);
        assert_levels_match(&gpu, &cpu, &format!("pinholes, single image {single}"));
    }
}

#[test]
fn a_hole_takes_the_gaussian_weighted_mean_of_the_parents_covering_it() {
    // Level 0 (4 x 2): a red texel at (0, 0) and a blue one at (3, 0), both facing the camera
    // (circles of radius 2.5) at the same depth; everything else empty. Their level-1 parents
    // hold them alone, centred on them, so the hole (1, 0) is covered by the red ellipse at
    // distance 1 and the blue one at distance 2: its albedo is the mean weighted by
    // exp(-falloff d^2) with d the distance over the radius, computed here from the geometry.
    let texel = |color: Vec4| {
        Texel {
            n: Vec3::Z,
            radius: 2.5,
            depth: 2.0,
            half_range: 0.05,
            disp: Vec2::ZERO,
            color,
        }
        .stored()
    };
    let mut level0 = Level::empty(4, 2);
    level0.texels[0] = texel(Vec4::new(1.0, 0.0, 0.0, 0.0));
    level0.texels[3] = texel(Vec4::new(0.0, 0.0, 1.0, 0.0));
    for falloff in [0.5, 4.0] {
        let cpu = reference::synthesis(reference::analysis(level0.clone()), SCALE, falloff);
        for (q, near, far) in [(1usize, 1.0f32, 2.0f32), (2, 2.0, 1.0)] {
            let weight = |d: f32| (-falloff * (d / 2.5).powi(2)).exp();
            let red = weight(near) / (weight(near) + weight(far));
            let t = cpu[0].texels[q];
            assert!(
                (t.color.x - red).abs() < 1e-3 && (t.color.z - (1.0 - red)).abs() < 1e-3,
                "falloff {falloff}, texel {q}: {:?}, expected red share {red}",
                t.color
            );
        }
        for single in [false, true] {
            let gpu = gpu_levels(&level0, single, true, falloff);
            assert_levels_match(&gpu, &cpu, &format!("two parents, falloff {falloff}"));
        }
    }
}

/// `n` x `n` points on the unit square at height `z` facing +z, radius = the grid spacing.
fn plane(n: usize, z: f32, color: [u8; 4]) -> Cloud {
    common::layer(n, color, z, |_| true)
}

/// `method` with one more `key=value` parameter.
fn with_param(method: &str, param: &str) -> String {
    let sep = if method.contains(':') { ',' } else { ':' };
    format!("{method}{sep}{param}")
}

#[test]
fn a_sparse_plane_reconstructs_without_holes() {
    // 16 x 16 points about 5 pixels apart: level 0 holds 256 pixels of the ~12,000 the plane
    // covers; the reconstruction fills every pixel of the disc-covered area.
    let size = 128;
    let cloud = plane(16, 0.0, [200, 100, 50, 255]);
    let splats = covered(&render_view(
        &cloud,
        "perspective-flat",
        size,
        Default::default(),
        top_view,
    ));
    let inside = eroded(&splats, size as usize, 2);
    assert!(inside.iter().filter(|&&c| c).count() > 10_000);
    // Ellipses as large as the pyramid's (the default radius scale) bound what it may cover.
    let large = render_view(
        &cloud,
        &format!(
            "perspective-flat:radius={}",
            surfel::methods::pyramid::RADIUS_SCALE
        ),
        size,
        Default::default(),
        top_view,
    );
    let outside = eroded(
        &covered(&large).iter().map(|c| !c).collect::<Vec<_>>(),
        size as usize,
        1,
    );
    for method in ["pyramid", "pyramid:layout=1", "pyramid:projection=1"] {
        let raw = render_view(
            &cloud,
            &with_param(method, "show=0"),
            size,
            Default::default(),
            top_view,
        );
        assert_eq!(
            covered(&raw).iter().filter(|&&c| c).count(),
            256,
            "{method}: level 0"
        );
        let frame = render_view(&cloud, method, size, Default::default(), top_view);
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
                && (b as i32 - 50).abs() <= 3
        );
        assert!(
            (frame.depth[centre] - 1.5).abs() < 1e-3,
            "{}",
            frame.depth[centre]
        );
    }
}

#[test]
fn a_plane_with_a_color_gradient_is_reconstructed_within_three_levels() {
    // 24 × 24 points about 3.5 pixels apart, grey with a linear albedo ramp along x (linear
    // values 0.2 → 0.8 across the plane): most pixels are built by the synthesis. Lit by the
    // headlight, a pixel's linear color is its albedo times the light's factor there, which a
    // white plane through the same pyramid measures.
    let size = 128;
    let n = 24;
    let ramp = |x: f32| 0.2 + 0.6 * (x + 0.5);
    let mut cloud = plane(n, 0.0, [255; 4]);
    let white = render_view(&cloud, "pyramid", size, Default::default(), top_view);
    cloud.colors = Some(
        cloud
            .positions
            .iter()
            .map(|p| {
                let c = pack::srgb_byte(ramp(p.x));
                [c, c, c, 255]
            })
            .collect(),
    );
    let camera = top_view(Vec3::ZERO, 1.0);
    let pixels_per_unit = size as f32 / 2.0 / (camera.fov_y / 2.0).tan() / 1.5;
    for method in ["pyramid", "pyramid:layout=1", "pyramid:projection=1"] {
        let frame = render_view(&cloud, method, size, Default::default(), top_view);
        // Inside the points' hull (the outermost points are at ±0.48; beyond them the colors
        // are the edge's, not the ramp's).
        let inside = eroded(&covered(&frame), size as usize, 3);
        let mut checked = 0;
        for (i, _) in inside.iter().enumerate().filter(|(_, &c)| c) {
            let at = |k: usize| (k as f32 + 0.5 - size as f32 / 2.0) / pixels_per_unit;
            let (x, y) = (at(i % size as usize), at(i / size as usize));
            if x.abs() > 0.45 || y.abs() > 0.45 {
                continue;
            }
            let light = pack::linear_component(white.color[i][0]);
            let expected = pack::srgb_byte(ramp(x) * light);
            let got = frame.color[i];
            assert!(
                got[..3].iter().all(|&c| c.abs_diff(expected) <= 3),
                "{method}: pixel {i} (x = {x:.3}) {got:?}, the ramp gives {expected}"
            );
            checked += 1;
        }
        assert!(checked > 8_000, "{method}: {checked} pixels checked");
    }
}

#[test]
fn a_front_surface_occludes_the_surface_behind_it() {
    // A sparse red plane over a dense green one 0.5 behind: at level 0 green points show
    // through the red plane's gaps; the reconstruction replaces them by red (their depth
    // intervals lie behind the red parents') and keeps the front depth.
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
    let inside = eroded(
        &covered(&render_view(
            &front_only,
            "perspective-flat",
            size,
            Default::default(),
            top_view,
        )),
        size as usize,
        2,
    );
    let green = |f: &surfel::eval::Frame, i: usize| f.color[i][1] > f.color[i][0];
    let raw = render_view(&cloud, "pyramid:show=0", size, Default::default(), top_view);
    let through = (0..raw.pixels())
        .filter(|&i| inside[i] && green(&raw, i))
        .count();
    assert!(
        through > 3_000,
        "level 0 shows the back plane through the gaps: {through}"
    );
    for method in ["pyramid", "pyramid:layout=1"] {
        let frame = render_view(&cloud, method, size, Default::default(), top_view);
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

#[test]
fn layouts_and_projections_render_the_same_image() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/stanford/bun_zipper.ply");
    let cloud = surfel::scene::input::load_prepared(&path, &Default::default()).expect("bunny");
    let view = |method: &str| render_view(&cloud, method, 160, Default::default(), Camera::framing);
    let reference = view("pyramid");
    assert!(common::coverage(&reference) > 0.2);
    for method in [
        "pyramid:layout=1",
        "pyramid:projection=1",
        "pyramid:projection=1,layout=1",
    ] {
        let frame = view(method);
        assert!(frame.color == reference.color, "{method}: colors differ");
        // The hardware path interpolates its attributes: depths agree to float rounding.
        let worst = frame
            .depth
            .iter()
            .zip(&reference.depth)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1e-6))
            .fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{method}: depths differ by {worst}");
    }
}

#[test]
fn hybrid_triangles_and_points_resolve_by_depth() {
    // Red triangles on z = 0 over [-1, 1]², green points on the plane z = 0.5 x crossing them
    // at x = 0: seen from above, the triangles win left of the crossing and the points right
    // of it, each at its own depth; `pyramid` (no triangles) shows the points everywhere.
    let n = 48;
    let mut positions = vec![
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(1.0, -1.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(-1.0, 1.0, 0.0),
    ];
    let t = |k: usize| -1.0 + 2.0 * (k as f32 + 0.5) / n as f32;
    positions.extend((0..n * n).map(|k| Vec3::new(t(k % n), t(k / n), 0.5 * t(k % n))));
    let mut normals = vec![Vec3::Z; 4];
    normals.extend(vec![Vec3::new(-0.5, 0.0, 1.0).normalize(); n * n]);
    let mut colors = vec![[255, 0, 0, 255]; 4];
    colors.extend(vec![[0, 255, 0, 255]; n * n]);
    let cloud = Cloud {
        radii: Some(vec![2.0 / n as f32; positions.len()]),
        normals: Some(normals),
        colors: Some(colors),
        faces: Some(vec![[0, 1, 2], [0, 2, 3]]),
        positions,
        ..Default::default()
    };
    let size = 96u32;
    let camera = |_: Vec3, _: f32| Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 1.0);
    let pixel = |x: u32, y: u32| (y * size + x) as usize;
    for method in ["pyramid-hybrid", "pyramid-hybrid:projection=1"] {
        let frame = render_view(&cloud, method, size, Default::default(), camera);
        for y in [30, 48, 66] {
            // Left: the triangle, red, at depth 4 exactly.
            for x in [20, 30, 40] {
                let [r, g, _, _] = frame.color[pixel(x, y)];
                assert!(
                    r > 100 && g < 20,
                    "{method} ({x}, {y}): {:?}",
                    frame.color[pixel(x, y)]
                );
                assert!(
                    (frame.depth[pixel(x, y)] - 4.0).abs() < 1e-4,
                    "{method} ({x}, {y})"
                );
            }
            // Right: the points, green, nearer than the triangle.
            for x in [56, 66, 76] {
                let [r, g, _, _] = frame.color[pixel(x, y)];
                assert!(
                    g > 100 && r < 20,
                    "{method} ({x}, {y}): {:?}",
                    frame.color[pixel(x, y)]
                );
                assert!(frame.depth[pixel(x, y)] < 3.99, "{method} ({x}, {y})");
            }
        }
    }
    let points_only = render_view(&cloud, "pyramid", size, Default::default(), camera);
    let [r, g, _, _] = points_only.color[pixel(30, 48)];
    assert!(
        g > 100 && r < 20,
        "pyramid draws the face vertices as points too"
    );
}

#[test]
fn ribbons_and_tubes_rasterize_into_the_pyramid() {
    // Seen from z = 4 down -z: a ribbon along x at y = 0.5 (normal -z: no back-face culling,
    // lit two-sided) and a tube along x at y = -0.5 (tangent +x), both of radius 0.1 over
    // x in [-1, 1], as polylines of 9 vertices. The reconstruction covers a band of the
    // projected width around each centre line, in their colors under the headlight.
    let ribbon_y = 0.5;
    let tube_y = -0.5;
    let r = 0.1;
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut colors = Vec::new();
    let mut ribbons = Vec::new();
    let mut tubes = Vec::new();
    for (y, dir, color, list) in [
        (ribbon_y, -Vec3::Z, [200u8, 100, 50, 255], &mut ribbons),
        (tube_y, Vec3::X, [50, 100, 200, 255], &mut tubes),
    ] {
        let first = positions.len() as u32;
        for k in 0..9 {
            positions.push(Vec3::new(-1.0 + 0.25 * k as f32, y, 0.0));
            normals.push(dir);
            colors.push(color);
        }
        list.extend((0..8).map(|k| [first + k, first + k + 1]));
    }
    let count = positions.len();
    let cloud = Cloud {
        positions,
        normals: Some(normals),
        radii: Some(vec![r; count]),
        colors: Some(colors),
        lines: Some(surfel::scene::Lines { ribbons, tubes }),
        ..Default::default()
    };
    let size = 128u32;
    let camera = |_: Vec3, _: f32| Camera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 1.0);
    let rows = |f: &surfel::eval::Frame, x: u32| -> Vec<u32> {
        (0..size)
            .filter(|&y| f.covered((y * size + x) as usize))
            .collect()
    };
    for method in [
        "pyramid-hybrid",
        "pyramid-hybrid:projection=1",
        "pyramid-hybrid:layout=1",
    ] {
        let frame = render_view(&cloud, method, size, Default::default(), camera);
        // Two bands, each 2 r wide: 0.2 units at depth 4 with a 45° field of view is about
        // 0.2 / (2 * 4 * tan 22.5°) * 128 = 7.7 pixels.
        let column = rows(&frame, size / 2);
        let mut runs: Vec<(u32, u32)> = Vec::new();
        for &y in &column {
            match runs.last_mut() {
                Some((_, end)) if *end + 1 == y => *end = y,
                _ => runs.push((y, y)),
            }
        }
        assert_eq!(runs.len(), 2, "{method}: two bands, got {runs:?}");
        for (start, end) in &runs {
            let width = end - start + 1;
            assert!((6..=10).contains(&width), "{method}: band {start}..{end}");
        }
        let at = |y: u32| frame.color[(y * size + size / 2) as usize];
        let centre = |(s, e): (u32, u32)| (s + e) / 2;
        // Image rows grow downwards: the ribbon (y = 0.5) is the upper band.
        let [r0, g0, b0, _] = at(centre(runs[0]));
        let [r1, g1, b1, _] = at(centre(runs[1]));
        assert!(r0 > b0 && g0 > b0, "{method}: ribbon {:?}", [r0, g0, b0]);
        assert!(b1 > r1 && b1 > g1, "{method}: tube {:?}", [r1, g1, b1]);
        // Both face the headlight: their own colors (the tube through its projected light
        // vector, the ribbon two-sided).
        assert!(
            (r0 as i32 - 200).abs() <= 8 && (b1 as i32 - 200).abs() <= 8,
            "{method}"
        );
    }
}

/// Grey level of a pixel (the mean of its channels).
fn grey(frame: &surfel::eval::Frame, i: usize) -> i32 {
    let [r, g, b, _] = frame.color[i];
    (i32::from(r) + i32::from(g) + i32::from(b)) / 3
}

/// Pixels of `frame` whose 8 neighbours are covered, that differ by more than 64 grey levels
/// from every neighbour, where `truth` is smooth: covered with its 8 neighbours, each within
/// 16 grey levels of it.
fn speckles(frame: &surfel::eval::Frame, truth: &surfel::eval::Frame) -> Vec<usize> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut found = Vec::new();
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let i = y * w + x;
            let around: Vec<usize> = (0..9)
                .filter(|&k| k != 4)
                .map(|k| (y + k / 3 - 1) * w + x + k % 3 - 1)
                .collect();
            let all_covered =
                |f: &surfel::eval::Frame| f.covered(i) && around.iter().all(|&j| f.covered(j));
            if !all_covered(frame) || !all_covered(truth) {
                continue;
            }
            let smooth = around
                .iter()
                .all(|&j| (grey(truth, j) - grey(truth, i)).abs() < 16);
            let isolated = around
                .iter()
                .all(|&j| (grey(frame, j) - grey(frame, i)).abs() > 64);
            if smooth && isolated {
                found.push(i);
            }
        }
    }
    found
}

#[test]
fn hybrid_triangles_render_a_mesh_without_speckles() {
    // The bunny: 34,834 of its 35,947 vertices in faces (drawn as triangles), 1,113 on the
    // surface in none (drawn as points). No pixel stands out alone where the mesh is smooth,
    // and against the `mesh` ground truth the hybrid scores 5 dB above the points-only
    // pyramid (30.3 dB against 25.0 at 256²; 28.2 when the surface points win the pixels
    // where they lie in front of the triangles by less than their radius).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/stanford/bun_zipper.ply");
    let cloud = surfel::scene::input::load_prepared(&path, &Default::default()).expect("bunny");
    let size = 256;
    let truth = common::render(&cloud, "mesh", size);
    let score = |method: &str| {
        let frame = common::render(&cloud, method, size);
        let psnr = surfel::eval::metrics::psnr_color(&frame, &truth)
            .expect("sizes")
            .expect("psnr");
        (psnr, speckles(&frame, &truth).len())
    };
    let (pyramid, _) = score("pyramid");
    for method in ["pyramid-hybrid", "pyramid-hybrid:projection=1"] {
        let (hybrid, speckled) = score(method);
        assert!(
            hybrid >= pyramid + 5.0,
            "{method}: {hybrid:.2} dB, pyramid {pyramid:.2}"
        );
        assert_eq!(speckled, 0, "{method}: isolated pixels");
    }
}

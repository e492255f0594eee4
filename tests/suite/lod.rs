//! Level of detail from object textures (000 ch. 7) on lavapipe under validation: every
//! expansion path (compute, mesh, geometry) emits, for fixed cameras, exactly the vertices the
//! CPU reference (`ObjectTexture::select`) chooses and counts them per level; the methods
//! render, and the renderer reads their counts per level back.

use crate::common;

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, Vec3, Vec4};
use surfel::eval::metrics;
use surfel::gpu::{Buffer, Context, ImageDesc};
use surfel::gpu_scene::GpuLod;
use surfel::gpu_scene::UploadOptions;
use surfel::graph::{Access, BufferId, GraphBuilder};
use surfel::layout::FrameBlock;
use surfel::lod::{Hierarchy, LodView, ObjectTexture, DEFAULT_LEVELS};
use surfel::methods::lod::gpu::{
    add_draw, DrawOptions, DrawTargets, LodInputs, Path, COUNTER_BYTES, GEOMETRY_VERTEX_COMPONENTS,
    PER_LEVEL_OFFSET, THRESHOLD_OFFSET,
};
use surfel::methods::{COLOR_FORMAT, DEPTH_FORMAT, NORMAL_FORMAT, ZBUFFER_FORMAT};
use surfel::scene::Cloud;

const SIZE: f32 = 512.0;

/// A unit sphere of `n` points (Fibonacci spiral) with outward normals.
fn sphere(n: usize) -> (Vec<Vec3>, Vec<f32>) {
    let p = surfel::scene::sample::fibonacci_sphere(n);
    (p, vec![(4.0 / n as f32).sqrt(); n])
}

/// Copies the first `size` bytes of `src` into a new host-visible buffer `name` after the
/// passes declared so far.
fn readback(
    ctx: &Arc<Context>,
    g: &mut GraphBuilder,
    name: &str,
    src: BufferId,
    size: u64,
) -> Arc<Buffer> {
    let host = Arc::new(Buffer::readback(ctx, name, size).expect("readback"));
    let id = g.import_buffer(name, host.clone());
    let region = [vk::BufferCopy {
        src_offset: 0,
        dst_offset: 0,
        size,
    }];
    g.copy_buffer(&format!("{name}.download"), src, id, &region);
    g.pass(&format!("{name}.host"))
        .buffer(id, Access::HostRead)
        .record(|_| {});
    host
}

fn words(buffer: &Buffer) -> Vec<u32> {
    bytemuck::cast_slice(buffer.mapped().expect("mapped")).to_vec()
}

/// What one path emitted for a view.
struct Emitted {
    /// The emitted vertex indices, sorted.
    list: Vec<u32>,
    /// Vertices per level.
    per_level: Vec<u32>,
    /// The threshold the levels were chosen with.
    threshold: f32,
}

/// Draws the object texture once with `path` for the camera `view`, `proj` into a small
/// target with `options` (recording on); returns what it emitted.
fn emitted(
    ctx: &Arc<Context>,
    lod: &GpuLod,
    path: Path,
    (view, proj): (Mat4, Mat4),
    options: DrawOptions,
) -> anyhow::Result<Emitted> {
    let mut block: FrameBlock = bytemuck::Zeroable::zeroed();
    block.u.view = view;
    block.u.proj = proj;
    block.u.view_proj = proj * view;
    block.u.viewport = Vec4::new(SIZE, SIZE, 1.0 / SIZE, 1.0 / SIZE);
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let frame_buffer = Arc::new(
        Buffer::with_data(ctx, "frame", bytemuck::bytes_of(&block), usage).expect("frame"),
    );
    let mut g = GraphBuilder::new();
    let frame = g.import_buffer_with("frame", frame_buffer, Access::TransferDst);
    let inputs = LodInputs::import(&mut g, frame, lod);
    let image = |g: &mut GraphBuilder, name: &str, format, usage| {
        g.image(
            name,
            ImageDesc {
                format,
                width: 64,
                height: 64,
                mip_levels: 1,
                usage,
            },
        )
    };
    let color = vk::ImageUsageFlags::COLOR_ATTACHMENT;
    let targets = DrawTargets {
        color: image(&mut g, "color", COLOR_FORMAT, color),
        depth: image(&mut g, "depth", DEPTH_FORMAT, color),
        normal: image(&mut g, "normal", NORMAL_FORMAT, color),
        zbuffer: image(
            &mut g,
            "zbuffer",
            ZBUFFER_FORMAT,
            vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
        ),
    };
    let options = DrawOptions {
        path,
        max_point_size: 4.0,
        record: true,
        ..options
    };
    let selection = add_draw(ctx, &mut g, "lod", lod, inputs, options, targets)?;
    let list_bytes = u64::from(lod.max_selected) * 4;
    let list = readback(ctx, &mut g, "list", selection.list, list_bytes);
    let counters = readback(ctx, &mut g, "counts", selection.counters, COUNTER_BYTES);
    g.compile(ctx).expect("compile").run_once(ctx).expect("run");
    let counters = words(&counters);
    let mut list = words(&list);
    list.truncate(counters[0] as usize);
    list.sort_unstable();
    let at = |offset: u64| offset as usize / 4;
    Ok(Emitted {
        list,
        per_level: counters[at(PER_LEVEL_OFFSET)..at(THRESHOLD_OFFSET)].to_vec(),
        threshold: f32::from_bits(counters[at(THRESHOLD_OFFSET)]),
    })
}

/// The paths the device can run (lavapipe has mesh and geometry shaders).
fn paths(ctx: &Context) -> Vec<Path> {
    let mut paths = vec![Path::Compute];
    if ctx.caps.mesh_shader && ctx.caps.task_shader {
        paths.push(Path::Mesh);
    } else {
        eprintln!("skipping the mesh path: the device has no mesh shaders");
    }
    if ctx.caps.geometry_points {
        paths.push(Path::Geometry);
    } else {
        eprintln!("skipping the geometry path: the device cannot emit sized points");
    }
    paths
}

#[test]
fn every_path_emits_the_cpu_reference_sample_set() {
    let ctx = common::context();
    let (p, r) = sphere(30_000);
    let texture = ObjectTexture::new(&Hierarchy::build(&p, &p, &r, DEFAULT_LEVELS), None);
    let lod = GpuLod::upload(&ctx, &texture).expect("upload");
    let proj = Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 1.0, 0.01);
    let mut totals = Vec::new();
    for (eye, epsilon) in [
        (1.5, 0.5),
        (3.0, 0.5),
        (3.0, 2.0),
        (30.0, 0.5),
        (300.0, 0.5),
    ] {
        let view = Mat4::look_at_rh(Vec3::new(0.3, 0.2, eye), Vec3::ZERO, Vec3::Y);
        let reference = LodView::from_camera(view, proj, SIZE, epsilon);
        // From 1.5 radii the sphere overfills the 60° frustum: patches are culled.
        let culled = texture
            .patches
            .iter()
            .filter(|p| !texture.in_view(p, &reference))
            .count();
        assert_eq!(culled > 0, eye < 2.0, "eye at {eye}: {culled} culled");
        let mut expected: Vec<u32> = texture.select(&reference).into_iter().flatten().collect();
        expected.sort_unstable();
        let per_level: Vec<u32> = texture
            .histogram(&reference)
            .iter()
            .map(|&c| c as u32)
            .collect();
        for path in paths(&ctx) {
            let e =
                emitted(&ctx, &lod, path, (view, proj), DrawOptions::new(epsilon)).expect("path");
            assert_eq!(
                e.per_level, per_level,
                "{path:?}: eye at {eye}, ε {epsilon}"
            );
            assert_eq!(e.threshold, epsilon);
            assert!(
                e.list == expected,
                "{path:?}: eye at {eye}, ε {epsilon}: lists differ"
            );
        }
        totals.push(expected.len());
    }
    // Nearer and stricter views select more.
    assert!(totals[0] > totals[1] && totals[1] > totals[2], "{totals:?}");
    assert!(
        totals[1] > totals[3] && totals[3] >= totals[4],
        "{totals:?}"
    );
    assert_eq!(
        totals[4],
        texture.patches.len(),
        "far: only representatives"
    );
    drop(lod);
    common::assert_clean(&ctx);
}

#[test]
fn every_path_fills_the_point_budget_as_the_cpu_reference() {
    let ctx = common::context();
    let (p, r) = sphere(30_000);
    let texture = ObjectTexture::new(&Hierarchy::build(&p, &p, &r, DEFAULT_LEVELS), None);
    let lod = GpuLod::upload(&ctx, &texture).expect("upload");
    let patches = texture.patches.len() as u32;
    let proj = Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 1.0, 0.01);
    // Near (patches culled) and framed; budgets from the patch count (every patch at its
    // coarsest level) to above what ε demands (the budget does not bind).
    for (eye, epsilon, budget) in [
        (1.5, 0.05, 12_000),
        (3.0, 0.05, 5_000),
        (3.0, 0.5, patches),
        (3.0, 0.0, 29_999),
        (3.0, 2.0, 20_000),
    ] {
        let view = Mat4::look_at_rh(Vec3::new(0.3, 0.2, eye), Vec3::ZERO, Vec3::Y);
        let unbounded = LodView::from_camera(view, proj, SIZE, epsilon);
        let threshold = texture.budget_threshold(&unbounded, budget);
        let reference = LodView {
            epsilon: threshold,
            ..unbounded
        };
        let mut expected: Vec<u32> = texture.select(&reference).into_iter().flatten().collect();
        expected.sort_unstable();
        let demanded: u64 = texture.histogram(&unbounded).iter().sum();
        let what = format!("eye at {eye}, ε {epsilon}, budget {budget}");
        assert!(expected.len() as u64 <= u64::from(budget), "{what}");
        assert_eq!(
            threshold == epsilon,
            demanded <= u64::from(budget),
            "{what}"
        );
        for path in paths(&ctx) {
            let options = DrawOptions {
                budget,
                geometry_chunk: 16,
                ..DrawOptions::new(epsilon)
            };
            let e = emitted(&ctx, &lod, path, (view, proj), options).expect("path");
            assert_eq!(e.threshold, threshold, "{path:?}: {what}");
            assert!(e.list == expected, "{path:?}: {what}: lists differ");
        }
    }
    // Below the patch count no threshold can fit: refused, with the figures.
    let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, Vec3::Y);
    let options = DrawOptions {
        budget: patches - 1,
        ..DrawOptions::new(0.5)
    };
    let err = emitted(&ctx, &lod, Path::Compute, (view, proj), options)
        .err()
        .expect("refused");
    let message = err.to_string();
    assert!(
        message.contains(&format!("budget of {}", patches - 1))
            && message.contains(&format!("{patches} patches")),
        "{message}"
    );
    drop(lod);
    common::assert_clean(&ctx);
}

#[test]
fn geometry_invocations_split_a_patch_without_changing_the_samples() {
    let ctx = common::context();
    if !ctx.caps.geometry_points {
        eprintln!("skipping: the device cannot emit sized points from geometry shaders");
        return;
    }
    let (p, r) = sphere(20_000);
    let texture = ObjectTexture::new(&Hierarchy::build(&p, &p, &r, DEFAULT_LEVELS), None);
    let lod = GpuLod::upload(&ctx, &texture).expect("upload");
    let proj = Mat4::perspective_infinite_reverse_rh(60f32.to_radians(), 1.0, 0.01);
    let view = Mat4::look_at_rh(Vec3::new(0.3, 0.2, 2.5), Vec3::ZERO, Vec3::Y);
    // ε 0: patches at their finest level (up to 64 vertices) need every invocation.
    let reference = LodView::from_camera(view, proj, SIZE, 0.0);
    let mut expected: Vec<u32> = texture.select(&reference).into_iter().flatten().collect();
    expected.sort_unstable();
    for chunk in [2, 8, 32] {
        let options = DrawOptions {
            geometry_chunk: chunk,
            ..DrawOptions::new(0.0)
        };
        let e = emitted(&ctx, &lod, Path::Geometry, (view, proj), options).expect("path");
        assert!(e.list == expected, "chunk {chunk}: lists differ");
    }
    let options = DrawOptions {
        geometry_chunk: 24,
        ..DrawOptions::new(0.0)
    };
    let err = emitted(&ctx, &lod, Path::Geometry, (view, proj), options)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("power of two"), "{err}");
    // All 64 in one invocation exceed the total output components most devices allow.
    if 64 * GEOMETRY_VERTEX_COMPONENTS > ctx.caps.max_geometry_total_output_components {
        let options = DrawOptions {
            geometry_chunk: 64,
            ..DrawOptions::new(0.0)
        };
        let err = emitted(&ctx, &lod, Path::Geometry, (view, proj), options)
            .err()
            .expect("refused");
        assert!(err.to_string().contains("1152 output components"), "{err}");
    }
    drop(lod);
    common::assert_clean(&ctx);
}

fn sphere_cloud(n: usize) -> Cloud {
    let (positions, radii) = sphere(n);
    Cloud {
        normals: Some(positions.clone()),
        radii: Some(radii),
        positions,
        ..Default::default()
    }
}

fn with_lod() -> UploadOptions {
    UploadOptions {
        lod: true,
        ..Default::default()
    }
}

#[test]
fn lod_methods_cover_the_sphere_at_every_threshold_and_agree() {
    let cloud = sphere_cloud(20_000);
    let others: Vec<&str> = {
        let ctx = common::context();
        let mut others = Vec::new();
        if ctx.caps.mesh_shader && ctx.caps.task_shader {
            others.push("lod-mesh");
        }
        if ctx.caps.geometry_points {
            others.push("lod-geometry");
        }
        others
    };
    let compute = common::render_with(&cloud, "lod-compute:epsilon=0", 128, with_lod());
    let coarse = common::render_with(&cloud, "lod-compute:epsilon=8", 128, with_lod());
    let (a, b) = (common::coverage(&compute), common::coverage(&coarse));
    // The framed sphere's disc covers about a quarter of the image.
    assert!(a > 0.2, "coverage {a}");
    // Coarser levels draw fewer, larger splats (their radii cover the children's discs, drawn
    // as squares): no holes open, the silhouette grows.
    assert!(b >= 0.95 * a, "coverage {a} vs {b}");
    for epsilon in [0, 8] {
        let method = |m: &str| format!("{m}:epsilon={epsilon}");
        let c = common::render_with(&cloud, &method("lod-compute"), 128, with_lod());
        for other in &others {
            let m = common::render_with(&cloud, &method(other), 128, with_lod());
            // The same points in another order: only depth ties may differ.
            let same = c.color.iter().zip(&m.color).filter(|(x, y)| x == y).count();
            assert!(
                same * 100 >= 99 * c.color.len(),
                "{other}, ε {epsilon}: {same} pixels agree"
            );
        }
    }
}

#[test]
fn lod_discs_keep_the_silhouette_where_squares_grow_it() {
    let cloud = sphere_cloud(20_000);
    let coverage =
        |method: &str| common::coverage(&common::render_with(&cloud, method, 128, with_lod()));
    let fine = coverage("lod-compute:epsilon=0,shape=1");
    let discs = coverage("lod-compute:epsilon=8,shape=1");
    let squares = coverage("lod-compute:epsilon=8,shape=0");
    // Coarse parents as squares of their diameter spill past the sphere's outline; as discs
    // in the parents' planes they stay within a few pixels of the finest level's.
    assert!(
        (discs - fine).abs() * 4.0 < squares - fine,
        "fine {fine}, discs {discs}, squares {squares}"
    );
}

#[test]
fn lod_compute_colors_coarse_levels_when_asked() {
    let cloud = sphere_cloud(20_000);
    let frame = common::render_with(&cloud, "lod-compute:epsilon=64,levels=1", 128, with_lod());
    // Level 3 (red, 0xe63c3c) dominates a framed sphere at a loose threshold: red over green.
    let pixels: Vec<&[u8; 4]> = frame.color.iter().filter(|p| p[3] > 0).collect();
    let red = pixels.iter().filter(|p| p[0] > 2 * p[1].max(p[2])).count();
    assert!(red * 2 > pixels.len(), "{red} of {}", pixels.len());
}

#[test]
fn pyramid_lod_projects_the_selection_with_its_points_colors() {
    // The sphere red for x < 0, blue for x >= 0.
    let mut cloud = sphere_cloud(20_000);
    cloud.colors = Some(
        cloud
            .positions
            .iter()
            .map(|p| {
                if p.x < 0.0 {
                    [230, 20, 20, 255]
                } else {
                    [20, 20, 230, 255]
                }
            })
            .collect(),
    );
    let size = 128;
    let render = |method: &str| common::render_with(&cloud, method, size, with_lod());
    // ε = 0 selects every input point: level 0 is the hardware projection of all points, the
    // image `pyramid:projection=1`'s (the radii differ by the f16 rounding of the streams).
    let all = render("pyramid:projection=1");
    let fine = render("pyramid-lod:epsilon=0");
    let same = metrics::psnr_color(&fine, &all)
        .expect("psnr")
        .expect("pixels");
    assert!(
        same > 40.0,
        "pyramid-lod at epsilon 0 against every point: {same:.1} dB"
    );
    // ε = 64: the representatives, each the mean color of its 64 points. Away from x = 0 the
    // patches are one color, so each side keeps its own; the outline moves by at most 1.5
    // pixels (the silhouette's representatives are discs seen edge-on).
    let coarse = render("pyramid-lod:epsilon=64");
    let pixels = f64::from(size * size);
    let (fine_px, coarse_px) = (
        common::coverage(&fine) * pixels,
        common::coverage(&coarse) * pixels,
    );
    let perimeter = 2.0 * (std::f64::consts::PI * fine_px).sqrt();
    assert!(
        (coarse_px - fine_px).abs() < 1.5 * perimeter,
        "{coarse_px} px covered against {fine_px} (outline {perimeter:.0} px)"
    );
    for (i, c) in coarse.color.iter().enumerate().filter(|(_, c)| c[3] > 0) {
        let column = i % size as usize;
        if column < 40 {
            assert!(c[0] > 2 * c[2], "pixel {i}: {c:?} on the red side");
        } else if column >= 88 {
            assert!(c[2] > 2 * c[0], "pixel {i}: {c:?} on the blue side");
        }
    }
}

#[test]
fn lod_methods_need_the_object_texture() {
    let ctx = common::context();
    let (scene, info) =
        surfel::gpu_scene::upload(&ctx, &sphere_cloud(100), &Default::default()).expect("upload");
    let config = surfel::methods::MethodConfig::parse("lod-compute").expect("method");
    let err =
        surfel::render::Renderer::new(&ctx, &scene, info, &config, 16, 16, Default::default())
            .err()
            .expect("refused");
    assert!(err.to_string().contains("object texture"), "{err}");
    drop(scene);
    common::assert_clean(&ctx);
}

/// The renderer reads every LOD method's samples per level back each frame: from a near
/// camera (which culls patches) and a far one, the newest finished frame's counts are the CPU
/// reference's histogram, also with two frames in flight (`begin_frame` reads the frame it
/// waited for, `finish` the newest); a method that counts no samples reports none.
#[test]
fn the_renderer_reads_back_each_lod_methods_samples_per_level() {
    use surfel::render::{Renderer, RendererOptions, View};
    use surfel::scene::{Camera, Light};

    const EDGE: u32 = 128;
    const EPSILON: f32 = 0.5;
    let ctx = common::context();
    let cloud = sphere_cloud(8_000);
    let (scene, info) = surfel::gpu_scene::upload(&ctx, &cloud, &with_lod()).expect("upload");
    let (Some(normals), Some(radii)) = (&cloud.normals, &cloud.radii) else {
        unreachable!("sphere_cloud has normals and radii");
    };
    // The object texture the upload built, on the host.
    let texture = ObjectTexture::new(
        &Hierarchy::build(&cloud.positions, normals, radii, DEFAULT_LEVELS),
        cloud.colors.as_deref(),
    );
    let view_from = |distance: f32| View {
        camera: Camera {
            eye: Vec3::new(0.3, 0.2, distance),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y: 60f32.to_radians(),
            near: 0.01,
        },
        lights: vec![Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    let (near, far) = (view_from(1.5), view_from(30.0));
    let histogram = |v: &View| {
        let (view, proj) = (v.camera.view(), v.camera.projection(1.0));
        let reference = LodView::from_camera(view, proj, EDGE as f32, EPSILON);
        let culled = texture
            .patches
            .iter()
            .any(|p| !texture.in_view(p, &reference));
        (texture.histogram(&reference), culled)
    };
    let ((near_counts, near_culls), (far_counts, far_culls)) = (histogram(&near), histogram(&far));
    assert!(
        near_culls && !far_culls,
        "the near view culls, the far one does not"
    );
    let total = |c: &[u64]| c.iter().sum::<u64>();
    assert!(
        total(&far_counts) > 0 && total(&near_counts) > total(&far_counts),
        "near {near_counts:?}, far {far_counts:?}"
    );
    let mut methods = vec!["lod-compute", "pyramid-lod"];
    if ctx.caps.mesh_shader && ctx.caps.task_shader {
        methods.push("lod-mesh");
    }
    if ctx.caps.geometry_points {
        methods.push("lod-geometry");
    }
    let renderer = |method: &str| {
        let config = surfel::methods::MethodConfig::parse(method).expect("method");
        Renderer::new(
            &ctx,
            &scene,
            info,
            &config,
            EDGE,
            EDGE,
            RendererOptions::default(),
        )
        .expect("renderer")
    };
    for method in methods {
        let mut r = renderer(&format!("{method}:epsilon={EPSILON}"));
        assert_eq!(r.frames_in_flight(), 2);
        assert_eq!(r.samples_per_level(), None, "{method}: no frame finished");
        for (v, expected) in [
            (&near, &near_counts),
            (&far, &far_counts),
            (&near, &near_counts),
        ] {
            r.render(v, false).expect("frame");
            assert_eq!(r.samples_per_level(), Some(&expected[..]), "{method}");
        }
        // Two frames in flight: starting a third waits for (and reads) the first only.
        for v in [&far, &near] {
            r.begin_frame().expect("begin");
            r.update(v).expect("update");
            r.record(false).expect("record");
            r.submit(None, None).expect("submit");
        }
        r.begin_frame().expect("begin");
        assert_eq!(r.samples_per_level(), Some(&far_counts[..]), "{method}");
        r.update(&far).expect("update");
        r.record(false).expect("record");
        r.submit(None, None).expect("submit");
        r.finish().expect("finish");
        assert_eq!(r.samples_per_level(), Some(&far_counts[..]), "{method}");
        assert!(r.schedule().contains("samples.copy"), "{method}");
    }
    let mut points = renderer("points");
    points.render(&near, false).expect("frame");
    assert_eq!(points.samples_per_level(), None);
    assert!(!points.schedule().contains("samples"));
    drop(points);
    drop(scene);
    common::assert_clean(&ctx);
}

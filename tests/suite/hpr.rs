//! GPU hidden point removal (003 ch. 4, `methods::hpr`) against its CPU reference
//! (`hpr::approx`), the complete visible set on the GPU against exact HPR and its CPU
//! reference (`hpr::complete`), and the `hpr` and `hpr-mesh` methods.

use crate::common;

use std::sync::Arc;

use glam::{DVec3, Mat4, Vec3};
use surfel::gpu::Context;
use surfel::hpr::approx::{self, Params, Propagation, Sectors};
use surfel::methods::hpr::{self as gpu_hpr, Evaluation, Settings};
use surfel::scene::Cloud;

/// Where `p` falls in the sector grid, in fractional sectors along phi and theta.
fn grid_position(s: &Sectors, eye: DVec3, p: DVec3) -> (f64, f64) {
    let v = p - eye;
    let l = DVec3::new(s.axes[0].dot(v), s.axes[1].dot(v), s.axes[2].dot(v));
    let phi = l.y.atan2(l.x);
    let theta = (l.z / l.length()).clamp(-1.0, 1.0).acos();
    (
        (phi - s.start[0]) / s.step[0],
        (theta - s.start[1]) / s.step[1],
    )
}

/// `points` and their mirror images -p, without the pairs where either lies within 3 % of a
/// sector boundary (the GPU's f32 angles must put every point in the sector the f64
/// reference does). Mirrored pairs keep the centroid at the origin and the radius at the
/// largest |p|, so dropping points does not move the grid. In stream (Morton) order, so GPU
/// and CPU indices agree.
fn away_from_boundaries(half: Vec<Vec3>, eye: Vec3, sqrt_k: u32) -> Vec<Vec3> {
    let r = half
        .iter()
        .map(|p| f64::from(p.length()))
        .fold(0.0, f64::max);
    let s = Sectors::new(DVec3::ZERO, r, eye.as_dvec3(), sqrt_k);
    let clear = |p: Vec3| {
        let (a, b) = grid_position(&s, eye.as_dvec3(), p.as_dvec3());
        let inside = |x: f64| (0.03..0.97).contains(&(x - x.floor()));
        inside(a) && inside(b)
    };
    let points: Vec<Vec3> = half
        .iter()
        .filter(|&&p| clear(p) && clear(-p))
        .flat_map(|&p| [p, -p])
        .collect();
    let order = surfel::point_streams::morton_order(&points);
    let sorted: Vec<Vec3> = order.iter().map(|&i| points[i as usize]).collect();
    let again = surfel::point_streams::morton_order(&sorted);
    assert!(again.iter().enumerate().all(|(i, &j)| i as u32 == j));
    sorted
}

fn cloud_of(points: &[Vec3]) -> Cloud {
    Cloud {
        normals: Some(points.iter().map(|p| p.normalize_or_zero()).collect()),
        radii: Some(vec![0.02; points.len()]),
        positions: points.to_vec(),
        ..Default::default()
    }
}

/// Runs the GPU passes once on `points` (in stream order) from `eye`.
fn run_gpu(
    ctx: &Arc<Context>,
    points: &[Vec3],
    eye: Vec3,
    sqrt_k: u32,
    radius: f32,
    propagation: Propagation,
    sort: bool,
) -> Evaluation {
    let (scene, _) =
        surfel::gpu_scene::upload(ctx, &cloud_of(points), &Default::default()).expect("upload");
    let mut settings = Settings::grid(sqrt_k, f64::from(radius), propagation, sort);
    settings.params.max_edge = 4.0;
    let view = Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
    let proj = Mat4::perspective_rh(0.8, 1.0, 0.1, 100.0);
    gpu_hpr::evaluate(ctx, &scene, (view, proj), (64, 64), &settings, true).expect("evaluate")
}

/// The CPU reference with the GPU's bounding sphere.
fn run_cpu(
    points: &[Vec3],
    eye: Vec3,
    gpu: &Evaluation,
    sqrt_k: u32,
    radius: f32,
    propagation: Propagation,
) -> approx::Approx {
    let d: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).collect();
    approx::approximate_in(
        &d,
        eye.as_dvec3(),
        (gpu.centre.as_dvec3(), f64::from(gpu.radius)),
        Params {
            sqrt_k,
            radius: f64::from(radius),
            propagation,
        },
    )
    .expect("approximation")
}

/// Runs the GPU passes (sorted by sector or with the sort-free atomic maximum) and the CPU
/// reference and checks they agree exactly.
fn assert_same(
    points: &[Vec3],
    eye: Vec3,
    sqrt_k: u32,
    propagation: Propagation,
    sort: bool,
) -> Evaluation {
    let ctx = common::context();
    let radius = 400.0;
    let gpu = run_gpu(&ctx, points, eye, sqrt_k, radius, propagation, sort);
    let cpu = run_cpu(points, eye, &gpu, sqrt_k, radius, propagation);
    let what = format!("{propagation:?} at sqrt(k) = {sqrt_k}, sorted: {sort}");
    assert_eq!(gpu.state.sqrt_k, sqrt_k, "{what}");
    assert_eq!(gpu.state.coarse, cpu.coarse, "{what}: EMPTY grid");
    assert_eq!(gpu.state.full, u32::from(cpu.full), "{what}: partition");
    let differ = gpu
        .extremes
        .iter()
        .zip(&cpu.max)
        .filter(|(a, b)| a != b)
        .count();
    assert_eq!(differ, 0, "{what}: sectors whose extreme differs");
    if let Propagation::Adaptive { .. } = propagation {
        assert_eq!(gpu.state.rounds, cpu.rounds, "{what}: rounds");
    }
    assert_eq!(gpu.visible, cpu.visible, "{what}: visible points");
    assert_eq!(gpu.state.visible as usize, cpu.visible.len(), "{what}");
    common::assert_clean(&ctx);
    gpu
}

/// A sphere seen from outside with a smaller shell inside it (hidden points propagation must
/// remove).
fn two_shells(eye: Vec3, sqrt_k: u32) -> Vec<Vec3> {
    let mut half = common::shell(3000, 1.0);
    half.extend(common::shell(1000, 0.6));
    let points = away_from_boundaries(half, eye, sqrt_k);
    assert!(points.len() > 6000, "{}", points.len());
    points
}

#[test]
fn the_bounding_sphere_reduction_matches_the_cpu() {
    let ctx = common::context();
    let mut points = common::shell(50_000, 2.0);
    points
        .iter_mut()
        .for_each(|p| *p += Vec3::new(3.0, -1.0, 0.5));
    points.push(Vec3::new(3.0, -1.0, 9.0));
    let d: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).collect();
    let (c, r) = approx::bounding_sphere(&d).unwrap();
    let gpu = run_gpu(
        &ctx,
        &points,
        Vec3::new(30.0, 0.0, 0.0),
        8,
        1000.0,
        Propagation::Fixed(1),
        false,
    );
    assert!(
        gpu.centre.as_dvec3().distance(c) < 1e-4,
        "{} {c}",
        gpu.centre
    );
    assert!(
        (f64::from(gpu.radius) - r).abs() < 1e-4 * r,
        "{} {r}",
        gpu.radius
    );
    common::assert_clean(&ctx);
}

#[test]
fn gpu_extremes_equal_the_cpu_reference_with_fixed_propagation() {
    let eye = Vec3::new(0.3, 0.2, 3.0);
    let points = two_shells(eye, 48);
    let one = assert_same(&points, eye, 48, Propagation::Fixed(1), false);
    let three = assert_same(&points, eye, 48, Propagation::Fixed(3), false);
    // The partial reconstruction: the GPU's triangles are the CPU filter's over the same
    // extremes (two per 2 x 2 block, minus gaps, repeats and edges over 4 pixels).
    let view_proj =
        Mat4::perspective_rh(0.8, 1.0, 0.1, 100.0) * Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
    let pixel = |i: u32| {
        let c = view_proj * points[i as usize].extend(1.0);
        (c.w > 0.0).then(|| (c.truncate().truncate() / c.w + 1.0) * 0.5 * 64.0)
    };
    let mut cpu = approx::triangulate(&one.extremes, 48, pixel, 4.0);
    let mut gpu = one.triangles.clone();
    cpu.sort_unstable();
    gpu.sort_unstable();
    assert!(cpu.len() > 500, "{}", cpu.len());
    assert_eq!(gpu, cpu);
    // Gathering over 3 x 3 replaces extremes (the comparison is then non-trivial).
    let replaced = one
        .extremes
        .iter()
        .zip(&three.extremes)
        .filter(|(a, b)| a != b)
        .count();
    assert!(replaced > 100, "{replaced}");
    assert_same(&points, eye, 48, Propagation::Fixed(5), false);
    // The thesis' pipeline, radix sort by sector and segmented maximum, finds the same
    // extremes as the sort-free atomic maximum.
    let sorted = assert_same(&points, eye, 48, Propagation::Fixed(3), true);
    assert_eq!(sorted.extremes, three.extremes);
}

#[test]
fn gpu_adaptive_propagation_equals_the_cpu_reference_and_reports_its_cap() {
    let eye = Vec3::new(0.3, 0.2, 3.0);
    let points = two_shells(eye, 64);
    let stable = assert_same(
        &points,
        eye,
        64,
        Propagation::Adaptive { max_rounds: 64 },
        true,
    );
    assert!(stable.state.rounds > 1 && stable.state.rounds < 64);
    // A cap below the rounds needed stops there, on the GPU as on the CPU.
    let capped = assert_same(
        &points,
        eye,
        64,
        Propagation::Adaptive { max_rounds: 2 },
        false,
    );
    assert_eq!(capped.state.rounds, 2);
}

#[test]
fn a_viewpoint_inside_the_cloud_uses_the_full_sphere_partition() {
    // From inside the outer shell (off centre), the full-sphere grid: phi wraps around.
    let eye = Vec3::new(0.1, 0.75, 0.2);
    let points = two_shells(eye, 32);
    let gpu = assert_same(
        &points,
        eye,
        32,
        Propagation::Adaptive { max_rounds: 64 },
        false,
    );
    assert_eq!(gpu.state.full, 1);
    assert!(!gpu.visible.is_empty());
}

#[test]
fn the_gpu_complete_set_holds_every_exactly_visible_point() {
    let ctx = common::context();
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../shared/data/stanford/bun_zipper.ply");
    let bunny = surfel::scene::load(&path).expect("bunny");
    let eye = Vec3::new(0.25, 0.3, 0.35);
    let side = surfel::hpr::complete_side(bunny.len());
    let (scene, _) = surfel::gpu_scene::upload(&ctx, &bunny, &Default::default()).expect("upload");
    let order = surfel::point_streams::morton_order(&bunny.positions);
    let spacing = surfel::hpr::spacing(&bunny);
    let density = surfel::hpr::Radius::Density { spacing };
    let radius = surfel::hpr::flip_radius(&bunny.positions, eye, density).expect("R");
    let mut settings = Settings::grid(128, radius, Propagation::Fixed(3), false);
    settings.params.complete_side = side;
    let view = Mat4::look_at_rh(eye, Vec3::new(-0.017, 0.11, 0.0), Vec3::Y);
    let proj = Mat4::perspective_rh(0.8, 1.0, 0.01, 10.0);
    let found = gpu_hpr::evaluate(&ctx, &scene, (view, proj), (64, 64), &settings, false)
        .expect("evaluate");
    common::assert_clean(&ctx);
    let mut gpu: Vec<u32> = found.visible.iter().map(|&i| order[i as usize]).collect();
    gpu.sort_unstable();
    assert_eq!(found.state.visible as usize, gpu.len());
    // The flip the GPU used: its eye and R, both f32.
    let r = surfel::hpr::Radius::Absolute(f64::from(found.state.eye_radius.w));
    let exact = surfel::hpr::exact(&bunny.positions, eye, r).expect("exact");
    let cpu = surfel::hpr::complete(&bunny.positions, eye, r, Some(side)).expect("complete");
    let (_, recall, f1) = surfel::hpr::agreement(&gpu, &exact.visible);
    let (_, _, cpu_f1) = surfel::hpr::agreement(&cpu.visible, &exact.visible);
    assert_eq!(recall, 1.0, "no exactly visible point is dropped");
    assert!(f1 >= 0.95, "F1 {f1}");
    // The CPU reference decides on its own (f64) sector frame: nearly the same set.
    assert!((f1 - cpu_f1).abs() < 0.01, "GPU F1 {f1}, CPU {cpu_f1}");
}

/// The names of the passes `method` records rendering `cloud` (one frame, then one timed).
fn pass_names(cloud: &Cloud, method: &str) -> Vec<String> {
    use surfel::render::{Renderer, RendererOptions, View};
    let ctx = common::context();
    let config = surfel::methods::MethodConfig::parse(method).expect("method");
    let options = config.method.upload_options(Default::default());
    let (scene, info) = surfel::gpu_scene::upload(&ctx, cloud, &options).expect("upload");
    let extras = RendererOptions {
        readback: true,
        ..RendererOptions::default()
    };
    let mut r = Renderer::new(&ctx, &scene, info, &config, 64, 64, extras).expect("renderer");
    let view = View {
        camera: surfel::scene::Camera::framing(info.centre, info.radius),
        lights: vec![surfel::scene::Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    r.render(&view, false).expect("frame");
    r.clear_timings();
    r.render(&view, false).expect("timed frame");
    r.finish().expect("finish");
    let names = r.timings().0.iter().map(|p| p.name.clone()).collect();
    drop(r);
    common::assert_clean(&ctx);
    names
}

#[test]
fn the_complete_set_alone_skips_the_sector_passes_and_the_reconstruction_keeps_them() {
    let sphere = cloud_of(&common::shell(2_000, 1.0));
    let points = pass_names(&sphere, "hpr");
    assert!(
        points.iter().any(|p| p == "hpr.complete.classify"),
        "{points:?}"
    );
    assert!(
        !points
            .iter()
            .any(|p| p == "hpr.sector" || p.starts_with("hpr.round.")),
        "{points:?}"
    );
    let mesh = pass_names(&sphere, "hpr-mesh:pyramid=1");
    for pass in ["hpr.sector", "hpr.complete.classify", "hpr.triangulate"] {
        assert!(mesh.iter().any(|p| p == pass), "{pass}: {mesh:?}");
    }
}

#[test]
fn the_methods_render_a_sphere_s_facing_side_and_degenerate_clouds_cleanly() {
    // A sphere seen from outside: `hpr` with the sector extremes alone (003) shows about the
    // facing cap's points, the complete set (the default) at least those, `hpr-mesh` the
    // reconstruction, which covers the disc much like the points' splats would.
    let sphere = cloud_of(&common::shell(20_000, 1.0));
    let points = common::render(&sphere, "hpr:complete=0", 128);
    let complete = common::render(&sphere, "hpr", 128);
    let mesh = common::render(&sphere, "hpr-mesh:max_edge=4", 128);
    let covered = |f: &surfel::eval::Frame| (0..f.pixels()).filter(|&i| f.covered(i)).count();
    // Measured: the points cover 2,964 pixels, the reconstruction 3,757 (its triangles span
    // the gaps between the visible points); through the pyramid (the triangles and the
    // visible points, holes filled by the synthesis) at least as much.
    assert!(
        (2_500..3_500).contains(&covered(&points)),
        "{}",
        covered(&points)
    );
    assert!(
        (3_300..4_300).contains(&covered(&mesh)),
        "{}",
        covered(&mesh)
    );
    assert!(
        covered(&complete) >= covered(&points),
        "{} < {}",
        covered(&complete),
        covered(&points)
    );
    let pyramid = common::render(&sphere, "hpr-mesh:max_edge=4,pyramid=1", 128);
    assert!(covered(&pyramid) >= covered(&mesh), "{}", covered(&pyramid));
    // One point, and a thousand copies of it: one visible extreme, one pixel, no triangles.
    let one = Cloud {
        positions: vec![Vec3::new(5.0, -2.0, 1.0)],
        normals: Some(vec![Vec3::Z]),
        ..Default::default()
    };
    let dup = Cloud {
        positions: vec![Vec3::ONE; 1000],
        normals: Some(vec![Vec3::Y; 1000]),
        ..Default::default()
    };
    for cloud in [&one, &dup] {
        assert_eq!(covered(&common::render(cloud, "hpr", 32)), 1);
        assert_eq!(covered(&common::render(cloud, "hpr-mesh", 32)), 0);
    }
    // No points: a clear error, not a panic or an empty GPU dispatch.
    let ctx = common::context();
    let config = surfel::methods::MethodConfig::parse("hpr").expect("method");
    let options = config.method.upload_options(Default::default());
    let (scene, info) =
        surfel::gpu_scene::upload(&ctx, &Cloud::default(), &options).expect("upload");
    let e = surfel::render::Renderer::new(&ctx, &scene, info, &config, 32, 32, Default::default())
        .err()
        .expect("an empty cloud is rejected");
    assert!(e.to_string().contains("at least one point"), "{e}");
    common::assert_clean(&ctx);
}

#[test]
fn the_bounding_sphere_is_reduced_once_per_scene_and_hpr_data_is_required() {
    use surfel::render::Renderer;
    let ctx = common::context();
    let cloud = cloud_of(&two_shells(Vec3::new(0.0, 0.0, 5.0), 8));
    let config = surfel::methods::MethodConfig::parse("hpr").expect("method");
    // Uploaded for another method: the HPR method names what the scene lacks.
    let (bare, info) =
        surfel::gpu_scene::upload(&ctx, &cloud, &Default::default()).expect("upload");
    let e = Renderer::new(&ctx, &bare, info, &config, 32, 32, Default::default())
        .err()
        .expect("a scene without HPR data is rejected");
    assert!(e.to_string().contains("needs the scene's HPR data"), "{e}");
    // Uploaded for HPR: two renderers (a rebuild) share one sphere buffer.
    let options = config.method.upload_options(Default::default());
    let (scene, info) = surfel::gpu_scene::upload(&ctx, &cloud, &options).expect("upload");
    let first = surfel::methods::hpr::bounding_sphere(&ctx, &scene).expect("sphere");
    for _ in 0..2 {
        Renderer::new(&ctx, &scene, info, &config, 32, 32, Default::default()).expect("renderer");
    }
    let again = surfel::methods::hpr::bounding_sphere(&ctx, &scene).expect("sphere");
    assert!(std::sync::Arc::ptr_eq(&first, &again));
    // Completing the bare scene adds the same data the upload would have built.
    let mut completed = bare;
    completed
        .complete(&ctx, &cloud, &options)
        .expect("complete");
    let (a, b) = (completed.hpr.as_ref().unwrap(), scene.hpr.as_ref().unwrap());
    assert_eq!((a.density, a.diagonal), (b.density, b.diagonal));
    common::assert_clean(&ctx);
}

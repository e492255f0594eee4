//! GPU hidden point removal (003 ch. 4, `methods::hpr`) against its CPU reference
//! (`hpr::approx`), and the `hpr` and `hpr-mesh` methods.

mod common;

use std::sync::Arc;

use ash::vk;
use glam::{DVec3, Mat4, Vec3, Vec4};
use surfel::gpu::layout::{FrameBlock, HprFrame, HprParams};
use surfel::gpu::{Buffer, Context};
use surfel::graph::{Access, BufferId, GraphBuilder};
use surfel::hpr::approx::{self, Params, Propagation, Sectors};
use surfel::methods::hpr::{self as gpu_hpr, Inputs, Settings};
use surfel::scene::Cloud;

/// Points on a unit sphere (Fibonacci lattice), scaled.
fn shell(n: usize, scale: f32) -> Vec<Vec3> {
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

/// `points` without those within 3 % of a sector boundary (the GPU's f32 angles must put
/// every point in the sector the f64 reference does), repeated until the bounding sphere (and
/// so the grid) no longer moves; then in stream (Morton) order, so GPU and CPU indices agree.
fn away_from_boundaries(mut points: Vec<Vec3>, eye: Vec3, sqrt_k: u32) -> Vec<Vec3> {
    loop {
        let d: Vec<DVec3> = points.iter().map(|p| p.as_dvec3()).collect();
        let (c, r) = approx::bounding_sphere(&d).unwrap();
        let s = Sectors::new(c, r, eye.as_dvec3(), sqrt_k);
        let inside = |x: f64| {
            let f = x - x.floor();
            (0.03..0.97).contains(&f)
        };
        let kept: Vec<Vec3> = points
            .iter()
            .copied()
            .filter(|p| {
                let (a, b) = grid_position(&s, eye.as_dvec3(), p.as_dvec3());
                inside(a) && inside(b)
            })
            .collect();
        if kept.len() == points.len() {
            break;
        }
        points = kept;
    }
    let order = surfel::streams::morton_order(&points);
    let sorted: Vec<Vec3> = order.iter().map(|&i| points[i as usize]).collect();
    let again = surfel::streams::morton_order(&sorted);
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

struct GpuResult {
    centre: Vec3,
    radius: f32,
    state: HprFrame,
    extremes: Vec<u32>,
    visible: Vec<u32>,
}

fn host(ctx: &Arc<Context>, bytes: u64) -> Arc<Buffer> {
    Arc::new(Buffer::readback(ctx, "readback", bytes).expect("readback buffer"))
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
) -> GpuResult {
    let (scene, _) = surfel::render::upload(ctx, &cloud_of(points)).expect("upload");
    let sphere = gpu_hpr::bounding_sphere(ctx, &scene).expect("bounding sphere");
    let mut block: FrameBlock = bytemuck::Zeroable::zeroed();
    block.u.view = Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
    block.u.proj = Mat4::perspective_rh(0.8, 1.0, 0.1, 100.0);
    block.u.view_proj = block.u.proj * block.u.view;
    block.u.viewport = Vec4::new(64.0, 64.0, 1.0 / 64.0, 1.0 / 64.0);
    block.u.point_count = scene.point_count;
    block.u.segment_points = scene.streams.segment_points;
    let frame_buffer = Arc::new(
        Buffer::with_data(
            ctx,
            "frame",
            bytemuck::bytes_of(&block),
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )
        .expect("frame"),
    );
    let settings = Settings {
        sqrt_k_max: sqrt_k,
        params: HprParams {
            sqrt_k,
            radius,
            max_rounds: match propagation {
                Propagation::Adaptive { max_rounds } => max_rounds,
                Propagation::Fixed(_) => 0,
            },
            ..Default::default()
        },
        propagation,
        sort,
    };
    let mut g = GraphBuilder::new();
    let inputs = Inputs {
        frame: g.import_buffer("frame", frame_buffer),
        segments: g.import_buffer("stream.segments", scene.streams.table.clone()),
        sphere: g.import_buffer_with(
            "hpr.sphere",
            sphere.clone(),
            Access::StorageWrite(surfel::graph::Stages::Compute),
        ),
    };
    let hpr = gpu_hpr::add(&mut g, ctx, scene.point_count, inputs, &settings).expect("passes");
    let k = u64::from(sqrt_k * sqrt_k);
    let words = u64::from(scene.point_count.div_ceil(32));
    let outputs: [(BufferId, u64); 4] = [
        (inputs.sphere, 16),
        (hpr.state, std::mem::size_of::<HprFrame>() as u64),
        (hpr.extremes, k * 4),
        (hpr.hidden, words * 4),
    ];
    let hosts: Vec<Arc<Buffer>> = outputs.iter().map(|&(_, n)| host(ctx, n)).collect();
    let mut ids = Vec::new();
    for (i, (&(src, n), buffer)) in outputs.iter().zip(&hosts).enumerate() {
        let id = g.import_buffer("readback", buffer.clone());
        g.copy_buffer(
            &format!("readback.{i}"),
            src,
            id,
            &[vk::BufferCopy {
                src_offset: 0,
                dst_offset: 0,
                size: n,
            }],
        );
        ids.push(id);
    }
    let mut done = g.pass("readback.host");
    for &id in &ids {
        done = done.buffer(id, Access::HostRead);
    }
    done.record(|_| {});
    let mut graph = g.compile(ctx).expect("compile");
    graph.run_once(ctx).expect("run");
    let words_of = |b: &Buffer| -> Vec<u32> {
        bytemuck::cast_slice(b.mapped().expect("mapped")).to_vec()
    };
    let s = words_of(&hosts[0]);
    let hidden = words_of(&hosts[3]);
    let result = GpuResult {
        centre: Vec3::new(
            f32::from_bits(s[0]),
            f32::from_bits(s[1]),
            f32::from_bits(s[2]),
        ),
        radius: f32::from_bits(s[3]),
        state: *bytemuck::from_bytes(hosts[1].mapped().expect("mapped")),
        extremes: words_of(&hosts[2]),
        visible: (0..scene.point_count)
            .filter(|&i| hidden[(i / 32) as usize] & (1 << (i % 32)) == 0)
            .collect(),
    };
    drop(graph);
    result
}

/// The CPU reference with the GPU's bounding sphere.
fn run_cpu(
    points: &[Vec3],
    eye: Vec3,
    gpu: &GpuResult,
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
) -> GpuResult {
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
    let mut points = shell(6000, 1.0);
    points.extend(shell(2000, 0.6));
    away_from_boundaries(points, eye, sqrt_k)
}

#[test]
fn the_bounding_sphere_reduction_matches_the_cpu() {
    let ctx = common::context();
    let mut points = shell(50_000, 2.0);
    points.iter_mut().for_each(|p| *p += Vec3::new(3.0, -1.0, 0.5));
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
    assert!(gpu.centre.as_dvec3().distance(c) < 1e-4, "{} {c}", gpu.centre);
    assert!((f64::from(gpu.radius) - r).abs() < 1e-4 * r, "{} {r}", gpu.radius);
    common::assert_clean(&ctx);
}

#[test]
fn gpu_extremes_equal_the_cpu_reference_with_fixed_propagation() {
    let eye = Vec3::new(0.3, 0.2, 3.0);
    let points = two_shells(eye, 48);
    let one = assert_same(&points, eye, 48, Propagation::Fixed(1), false);
    let three = assert_same(&points, eye, 48, Propagation::Fixed(3), false);
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

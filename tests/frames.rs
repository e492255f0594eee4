//! Frames in flight on lavapipe: frames submitted back to back without waiting render the
//! same image as one frame alone (synchronization validation on), with and without the post
//! stage, and a warmed-up frame (`begin_frame` + `update` + record + submit + wait) performs
//! no heap allocation.

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use surfel::eval::Frame;
use surfel::gpu_scene::upload;
use surfel::methods::{MethodConfig, METHODS};
use surfel::post::{Background, Edl, PostOptions};
use surfel::render::{Renderer, RendererOptions, View};
use surfel::scene::{Camera, Cloud, Light};

/// Counts the allocations (`alloc`, `alloc_zeroed`, `realloc`) made by threads that opted in.
struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Whether this thread's allocations are counted (the test harness and the other tests
    /// of this binary run on other threads).
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

fn count() {
    if COUNTED.with(Cell::get) {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
    }
}

// SAFETY: every call is forwarded unchanged to the system allocator; counting touches only an
// atomic and a const-initialized thread-local, neither of which allocates.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: forwarded with the caller's layout.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` (through this allocator) with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Allocations `f` makes on this thread.
fn allocations_of(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.load(Ordering::SeqCst);
    COUNTED.with(|c| c.set(true));
    f();
    COUNTED.with(|c| c.set(false));
    ALLOCATIONS.load(Ordering::SeqCst) - before
}

/// Every method this device can run on `cloud` (it has faces).
fn methods(ctx: &surfel::gpu::Context) -> Vec<MethodConfig> {
    METHODS
        .iter()
        .filter(|m| m.unsupported(&ctx.caps).is_none())
        .map(|m| MethodConfig::parse(m.name).expect("method"))
        .collect()
}

/// Each method alone, then followed by the post stage (eye-dome lighting and a background).
const POST: [PostOptions; 2] = [
    PostOptions::NONE,
    PostOptions {
        edl: Some(Edl {
            strength: 1.0,
            radius: 2.0,
        }),
        background: Background::Color([30, 60, 90]),
    },
];

fn renderer(
    ctx: &std::sync::Arc<surfel::gpu::Context>,
    cloud: &Cloud,
    config: &MethodConfig,
    frames_in_flight: usize,
    post: PostOptions,
) -> (Renderer, View) {
    renderer_sized(ctx, cloud, config, frames_in_flight, post, 48)
}

fn renderer_sized(
    ctx: &std::sync::Arc<surfel::gpu::Context>,
    cloud: &Cloud,
    config: &MethodConfig,
    frames_in_flight: usize,
    post: PostOptions,
    size: u32,
) -> (Renderer, View) {
    let options = config.method.upload_options(Default::default());
    let (scene, info) = upload(ctx, cloud, &options).expect("upload");
    let r = Renderer::new(
        ctx,
        &scene,
        info,
        config,
        size,
        size,
        RendererOptions {
            readback: true,
            frames_in_flight,
            post,
            ..RendererOptions::default()
        },
    )
    .expect("renderer");
    let view = View {
        camera: Camera::orbit(info.centre, info.radius, 15.0, 10.0),
        lights: vec![Light::headlight()],
        use_color: true,
        time: 0.0,
    };
    (r, view)
}

fn assert_same(a: &Frame, b: &Frame, method: &str) {
    assert_eq!(a.color, b.color, "{method}: color");
    assert_eq!(
        a.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>(),
        b.depth.iter().map(|d| d.to_bits()).collect::<Vec<_>>(),
        "{method}: depth"
    );
    assert_eq!(a.normal, b.normal, "{method}: normal");
}

/// `common::square(n)` bent into a shallow bowl (z = 0.1 (x² + y²), normals to match): no two
/// splats share a plane, so no pixel's nearest depth is an exact tie whose winner depends on
/// the order the splats are drawn in (`lod-compute` appends its list with atomics, in no fixed
/// order, and coplanar discs tie).
fn bowl(n: usize) -> Cloud {
    let mut cloud = common::square(n);
    for p in &mut cloud.positions {
        p.z = 0.1 * (p.x * p.x + p.y * p.y);
    }
    cloud.normals = Some(
        cloud
            .positions
            .iter()
            .map(|p| glam::Vec3::new(-0.2 * p.x, -0.2 * p.y, 1.0).normalize())
            .collect(),
    );
    cloud
}

#[test]
fn frames_in_flight_render_the_single_frame_image() {
    let ctx = common::context();
    let cloud = bowl(96);
    for (config, post) in methods(&ctx)
        .into_iter()
        .flat_map(|c| POST.map(|p| (c.clone(), p)))
    {
        let name = &format!("{} {post:?}", config.method.name);
        let (mut single, view) = renderer(&ctx, &cloud, &config, 1, post);
        assert_eq!(single.frames_in_flight(), 1);
        let expected = single
            .render(&view, true)
            .expect("frame")
            .expect("readback");
        drop(single);
        assert!(
            common::coverage(&expected) > 0.1,
            "{name}: renders the square"
        );

        let (mut r, view) = renderer(&ctx, &cloud, &config, 2, post);
        assert_eq!(r.frames_in_flight(), 2);
        // Eight frames from other viewpoints, submitted back to back: each waits only for
        // the frame that used its slot two frames earlier. A frame reading another slot's
        // uniforms would render one of these viewpoints instead of the final one.
        for i in 0..8 {
            let moved = View {
                camera: Camera::orbit(
                    r.info.centre,
                    r.info.radius,
                    40.0 * i as f32,
                    -20.0 + 5.0 * i as f32,
                ),
                ..view.clone()
            };
            r.begin_frame().expect("begin");
            r.update(&moved).expect("update");
            r.record(false).expect("record");
            r.submit(None, None).expect("submit");
        }
        let got = r.render(&view, true).expect("frame").expect("readback");
        assert_same(&got, &expected, name);
        let (_, frame) = r.timings();
        assert_eq!(
            frame.samples, 9,
            "{name}: every frame's timestamps collected"
        );
        drop(r);
    }
    common::assert_clean(&ctx);
}

#[test]
fn warmed_up_frames_allocate_nothing() {
    // Validation stays on: the counter sees only Rust allocations (the global allocator),
    // while the Vulkan loader, the layers and the driver allocate through their own C
    // allocators, which are not ours to remove.
    let ctx = common::context();
    let cloud = common::square(32);
    for (config, post) in methods(&ctx)
        .into_iter()
        .flat_map(|c| POST.map(|p| (c.clone(), p)))
    {
        let name = &format!("{} {post:?}", config.method.name);
        let (mut r, view) = renderer(&ctx, &cloud, &config, 2, post);
        for _ in 0..3 {
            r.render(&view, false).expect("warm-up frame");
        }
        let mut result = Ok(None);
        let allocations = allocations_of(|| {
            for _ in 0..10 {
                result = r.render(&view, false);
                if result.is_err() {
                    break;
                }
            }
        });
        result.expect("frame");
        assert_eq!(allocations, 0, "{name}: allocations in 10 frames");
    }
    common::assert_clean(&ctx);
}

#[test]
fn pass_times_add_up_to_the_frame_time() {
    // Scopes are written back to back, so the time the GPU takes to finish a pass's work
    // (lavapipe completes deferred rasterization inside the next pass's barriers: a 4x MSAA
    // mesh raster left 13 % of the frame to no pass before) belongs to a named pass.
    let ctx = common::context();
    let cloud = common::square(96);
    for config in methods(&ctx) {
        let name = config.method.name;
        let (mut r, view) = renderer_sized(&ctx, &cloud, &config, 1, POST[1], 512);
        r.render(&view, false).expect("warm-up frame");
        r.clear_timings();
        r.render(&view, false).expect("timed frame");
        let (passes, frame) = r.timings();
        assert_eq!(frame.samples, 1, "{name}");
        let sum: f64 = passes.iter().map(|p| p.median_ms).sum();
        assert!(
            sum <= frame.median_ms + 1e-6
                && sum >= frame.median_ms * 0.99 - 0.02 * passes.len() as f64,
            "{name}: passes {passes:?} sum to {sum} ms of a {} ms frame",
            frame.median_ms
        );
    }
    common::assert_clean(&ctx);
}

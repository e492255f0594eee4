//! The render graph executed on lavapipe under synchronization validation: a ping-pong
//! pyramid (per-mip barriers, copy pass filling missing levels), a history image carried
//! across frames, an on-demand readback, an indirect dispatch whose arguments a compute pass
//! writes, fill/copy/update buffer passes, a mesh-shader draw, imported initial states, the
//! usage check of imported resources and the declared-access check of `PassContext`.

use crate::common;

use std::cell::Cell;
use std::rc::Rc;
use std::sync::Arc;

use ash::vk;
use surfel::gpu::{Binding, Buffer, Context, FrameRing, GraphicsDesc, Image, ImageDesc, Pipeline};
use surfel::graph::{
    Access, BarrierTarget, BufferId, BufferRange, CompiledGraph, Descriptor, GraphBuilder, ImageId,
    Load, Sampler, Stages,
};

/// Records and submits `graph` once per entry of `readback` (whether on-demand passes run),
/// calling `check(frame)` after each frame completed.
fn run_frames(
    ctx: &Arc<Context>,
    graph: &mut CompiledGraph,
    readback: &[bool],
    mut check: impl FnMut(usize),
) {
    let mut frames = FrameRing::new(ctx, 1, false).expect("frame ring");
    for (frame, on_demand) in readback.iter().enumerate() {
        let slot = frames.advance().expect("wait");
        let cmd = frames.begin().expect("begin");
        graph.record(cmd, slot, *on_demand);
        frames.end().expect("end");
        frames.submit(None, None).expect("submit");
        frames.wait(slot).expect("wait");
        graph.profiler().collect(slot).expect("timestamps");
        check(frame);
    }
}

fn host_buffer(ctx: &Arc<Context>, name: &str, bytes: u64) -> Arc<Buffer> {
    Arc::new(Buffer::readback(ctx, name, bytes).expect("buffer"))
}

fn words(buffer: &Buffer) -> Vec<u32> {
    buffer
        .mapped()
        .expect("mapped")
        .chunks_exact(4)
        .map(|w| u32::from_ne_bytes([w[0], w[1], w[2], w[3]]))
        .collect()
}

/// The clear color of `frame` and its RGBA8 encoding (exact: multiples of 17).
fn frame_color(frame: u32) -> ([f32; 4], [u8; 4]) {
    let level = (frame + 1) * 17;
    (
        [level as f32 / 255.0, 0.0, 0.0, 1.0],
        [level as u8, 0, 0, 255],
    )
}

fn u32_bytes(words: &[u32]) -> Vec<u8> {
    words.iter().flat_map(|w| w.to_ne_bytes()).collect()
}

fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_ne_bytes()).collect()
}

/// A compute pipeline whose binding `i` has descriptor type `types[i]`.
fn compute_pipeline(
    ctx: &Arc<Context>,
    shader: &str,
    types: &[vk::DescriptorType],
) -> Arc<Pipeline> {
    Arc::new(Pipeline::compute(ctx, shader, &compute_bindings(types)).expect("pipeline"))
}

fn compute_bindings(types: &[vk::DescriptorType]) -> Vec<Binding> {
    (0..)
        .zip(types)
        .map(|(i, ty)| Binding::new(i, *ty, vk::ShaderStageFlags::COMPUTE))
        .collect()
}

/// One region copying the first `size` bytes.
fn whole(size: u64) -> [vk::BufferCopy; 1] {
    [vk::BufferCopy {
        src_offset: 0,
        dst_offset: 0,
        size,
    }]
}

/// An 8x8 single-level render target whose usage the graph derives.
fn target_8x8(g: &mut GraphBuilder, format: vk::Format) -> ImageId {
    g.image(
        "target",
        ImageDesc {
            format,
            width: 8,
            height: 8,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::empty(),
        },
    )
}

/// The pass "host", reading `host` after the frame's fence.
fn host_pass(g: &mut GraphBuilder, host: BufferId) {
    g.pass("host").buffer(host, Access::HostRead).record(|_| {});
}

/// The passes "download" (mip 0 of `image` into `host`) and "host".
fn download(g: &mut GraphBuilder, image: ImageId, host: BufferId) {
    g.pass("download")
        .image(image, Access::TransferSrc)
        .buffer(host, Access::TransferDst)
        .record(move |ctx| ctx.copy_image_to_buffer(image, 0, host));
    host_pass(g, host);
}

/// Every pixel of the 8x8 RGBA8 `pixels` is red in the left half and blue in the right.
fn assert_halves(pixels: &[u8], frame: usize) {
    for (i, px) in pixels.chunks(4).enumerate() {
        let expected: [u8; 4] = if i % 8 < 4 {
            [255, 0, 0, 255]
        } else {
            [0, 0, 255, 255]
        };
        assert_eq!(px, expected, "frame {frame}, pixel ({}, {})", i % 8, i / 8);
    }
}

/// Whether the device lacks `feature` (`has` false), noting the skipped test.
fn skipped(ctx: &Context, has: bool, feature: &str) -> bool {
    if !has {
        eprintln!("note: {} {feature}; test skipped", ctx.caps.device_name);
    }
    !has
}

#[test]
fn ping_pong_pyramid_history_and_readback_run_hazard_free() {
    let ctx = common::context();
    let desc = ImageDesc {
        format: vk::Format::R8G8B8A8_UNORM,
        width: 16,
        height: 16,
        mip_levels: 3,
        usage: vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST,
    };
    // Levels 0..3 of A, then B's level 0 (last frame's history).
    let readback: Vec<Arc<Buffer>> = [0, 1, 2, 0]
        .into_iter()
        .map(|l| {
            let (w, h) = desc.level_extent(l);
            host_buffer(&ctx, "rb", u64::from(w * h * 4))
        })
        .collect();
    let mut g = GraphBuilder::new();
    let pp = g.ping_pong("pyramid", desc);
    let history = g.history_image(
        "history",
        ImageDesc {
            mip_levels: 1,
            ..desc
        },
    );
    let rb: Vec<_> = readback
        .iter()
        .map(|b| g.import_buffer("rb", b.clone()))
        .collect();
    let level0 = pp.holder(0);
    // A different color every frame, so a history that was lost or not carried shows.
    let frame = Rc::new(Cell::new(0u32));
    let counter = frame.clone();
    g.pass("project")
        .image_mips(level0, 0, 1, Access::TransferDst)
        .record(move |ctx| ctx.clear(level0, 0, frame_color(counter.get()).0));
    for l in 1..3 {
        let (src, dst) = (pp.holder(l - 1), pp.holder(l));
        g.pass(&format!("analysis {l}"))
            .image_mips(src, l - 1, 1, Access::TransferSrc)
            .image_mips(dst, l, 1, Access::TransferDst)
            .record(move |ctx| ctx.blit(src, l - 1, dst, l));
    }
    // Image A lacks level 1 (it lives in B): the copy pass fills it.
    let (a, b) = (pp.a, pp.b);
    g.pass("copy")
        .image_mips(b, 1, 1, Access::TransferSrc)
        .image_mips(a, 1, 1, Access::TransferDst)
        .record(move |ctx| ctx.copy_mip(b, a, 1));
    // History: read last frame's value (into B's unused level 0), then overwrite it with this
    // frame's level 0. The read waits on the previous frame's write across submissions.
    let previous = pp.b;
    g.pass("history.read")
        .image(history, Access::TransferSrc)
        .image_mips(previous, 0, 1, Access::TransferDst)
        .record(move |ctx| ctx.blit(history, 0, previous, 0));
    g.pass("history.write")
        .image_mips(a, 0, 1, Access::TransferSrc)
        .image(history, Access::TransferDst)
        .record(move |ctx| ctx.blit(a, 0, history, 0));
    let sources = [(a, 0), (a, 1), (a, 2), (previous, 0)];
    let mut readback_pass = g.pass("readback").on_demand();
    for ((image, level), id) in sources.iter().zip(&rb) {
        readback_pass = readback_pass
            .image_mips(*image, *level, 1, Access::TransferSrc)
            .buffer(*id, Access::TransferDst);
    }
    let ids = rb.clone();
    readback_pass.record(move |ctx| {
        for ((image, level), id) in sources.iter().zip(&ids) {
            ctx.copy_image_to_buffer(*image, *level, *id);
        }
    });
    let mut host = g.pass("readback.host").on_demand();
    for id in &rb {
        host = host.buffer(*id, Access::HostRead);
    }
    host.record(|_| {});
    let mut graph = g.compile(&ctx).expect("compile");
    assert_eq!(
        graph.pass_names(),
        [
            "project",
            "analysis 1",
            "analysis 2",
            "copy",
            "history.read",
            "history.write"
        ]
    );

    // Readback in frames 1, 3 and 4: frame 3 follows a frame without the on-demand passes.
    let readback_frames = [false, true, false, true, true];
    let mut checked = 0;
    run_frames(&ctx, &mut graph, &readback_frames, |f| {
        let current = frame_color(f as u32).1;
        if readback_frames[f] {
            for buffer in &readback[..3] {
                let bytes = buffer.mapped().expect("mapped");
                assert!(
                    bytes.chunks(4).all(|t| t == current),
                    "frame {f}: every level of A has this frame's color"
                );
            }
            let previous = frame_color(f as u32 - 1).1;
            let bytes = readback[3].mapped().expect("mapped");
            assert!(
                bytes.chunks(4).all(|t| t == previous),
                "frame {f}: the history holds the previous frame's color, got {:?}",
                &bytes[..4]
            );
            checked += 1;
        }
        frame.set(f as u32 + 1);
    });
    assert_eq!(checked, 3);
    let scopes = graph.profiler().scopes();
    assert_eq!(scopes.len(), 6);
    assert!(scopes.iter().all(|s| s.samples == 5));
    drop(graph);
    common::assert_clean(&ctx);
}

#[test]
fn indirect_dispatch_reads_group_counts_a_compute_pass_wrote() {
    let ctx = common::context();
    let write_args = compute_pipeline(
        &ctx,
        "test/indirect_args.comp",
        &[
            vk::DescriptorType::UNIFORM_BUFFER,
            vk::DescriptorType::STORAGE_BUFFER,
        ],
    );
    let fill = Arc::new(
        Pipeline::compute_specialized(
            &ctx,
            "test/indirect_fill.comp",
            &compute_bindings(&[vk::DescriptorType::STORAGE_BUFFER]),
            &[(0, 3)],
        )
        .expect("specialized pipeline"),
    );
    let host = host_buffer(&ctx, "host", 128);
    let mut g = GraphBuilder::new();
    // Usage flags left empty: the graph derives them from the accesses.
    let params = g.buffer("params", 16, vk::BufferUsageFlags::empty());
    let args = g.buffer("args", 32, vk::BufferUsageFlags::empty());
    let values = g.buffer("values", 128, vk::BufferUsageFlags::empty());
    let host_id = g.import_buffer("host", host.clone());
    const GROUPS: u32 = 5;
    g.update_buffer("params", params, 0, &GROUPS.to_ne_bytes());
    g.fill_buffer("clear", values, BufferRange::WHOLE, 0xdead_beef);
    g.pass("args")
        .buffer(params, Access::UniformRead(Stages::Compute))
        .buffer(args, Access::StorageWrite(Stages::Compute))
        .record(move |ctx| {
            ctx.bind(
                &write_args,
                &[Descriptor::Uniform(0, params), Descriptor::Buffer(1, args)],
            );
            ctx.dispatch(1, 1, 1);
        });
    g.pass("indirect")
        .buffer_range(args, BufferRange::new(16, 12), Access::IndirectRead)
        .buffer(values, Access::StorageReadWrite(Stages::Compute))
        .record(move |ctx| {
            ctx.bind(&fill, &[Descriptor::Buffer(0, values)]);
            ctx.dispatch_indirect(args, 16);
        });
    let halves = [0u64, 64].map(|offset| vk::BufferCopy {
        src_offset: offset,
        dst_offset: offset,
        size: 64,
    });
    g.copy_buffer("download", values, host_id, &halves);
    host_pass(&mut g, host_id);
    let steady = g.barriers().expect("valid");
    let indirect = steady[3]
        .iter()
        .find(|b| matches!(b.target, BarrierTarget::Buffer { id, .. } if id == args))
        .expect("indirect barrier");
    assert_eq!(
        indirect.target,
        BarrierTarget::Buffer {
            id: args,
            range: BufferRange::new(16, 12)
        }
    );
    assert_eq!(
        indirect.transition.dst_stages,
        vk::PipelineStageFlags2::DRAW_INDIRECT
    );
    let mut graph = g.compile(&ctx).expect("compile");
    let expected: Vec<u32> = (0..32)
        .map(|i| {
            if i < GROUPS * 4 {
                i * 3 + 1
            } else {
                0xdead_beef
            }
        })
        .collect();
    run_frames(&ctx, &mut graph, &[false; 3], |f| {
        assert_eq!(words(&host), expected, "frame {f}");
        host.write(&[0; 128]).expect("reset host copy");
    });
    drop(graph);
    common::assert_clean(&ctx);
}

#[test]
fn mesh_shader_quads_cover_exactly_their_half_of_the_target() {
    let ctx = common::context();
    if skipped(&ctx, ctx.caps.mesh_shader, "has no mesh shaders") {
        return;
    }
    let format = vk::Format::R8G8B8A8_UNORM;
    let pipeline = |shift: u32| {
        Arc::new(
            Pipeline::graphics(
                &ctx,
                &GraphicsDesc {
                    shaders: vec!["test/quad.mesh", "test/flat.frag"],
                    color_formats: vec![format],
                    specialization: vec![(0, shift)],
                    ..Default::default()
                },
                &[],
            )
            .expect("mesh pipeline"),
        )
    };
    let (left, right) = (pipeline(0), pipeline(1));
    let host = host_buffer(&ctx, "pixels", 8 * 8 * 4);
    let mut g = GraphBuilder::new();
    let target = target_8x8(&mut g, format);
    let args = g.buffer("args", 12, vk::BufferUsageFlags::empty());
    let host_id = g.import_buffer("pixels", host.clone());
    g.update_buffer("args", args, 0, &u32_bytes(&[1, 1, 1]));
    let red = f32_bytes(&[1.0, 0.0, 0.0, 1.0]);
    let blue = f32_bytes(&[0.0, 0.0, 1.0, 1.0]);
    g.pass("left")
        .color(target, Load::Clear([0.0; 4]))
        .record(move |ctx| {
            ctx.bind(&left, &[]);
            ctx.push(&left, &red);
            ctx.draw_mesh_tasks(1, 1, 1);
        });
    g.pass("right")
        .buffer(args, Access::IndirectRead)
        .color(target, Load::Load)
        .record(move |ctx| {
            ctx.bind(&right, &[]);
            ctx.push(&right, &blue);
            ctx.draw_mesh_tasks_indirect(args, 0, 1, 12);
        });
    download(&mut g, target, host_id);
    let mut graph = g.compile(&ctx).expect("compile");
    run_frames(&ctx, &mut graph, &[false; 2], |f| {
        assert_halves(host.mapped().expect("mapped"), f);
    });
    drop(graph);
    common::assert_clean(&ctx);
}

#[test]
fn imported_images_keep_their_contents_from_the_declared_initial_state() {
    let ctx = common::context();
    let desc = ImageDesc {
        format: vk::Format::R8G8B8A8_UNORM,
        width: 4,
        height: 4,
        mip_levels: 1,
        usage: vk::ImageUsageFlags::SAMPLED
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::TRANSFER_DST,
    };
    let image = Arc::new(Image::new(&ctx, "texture", desc).expect("image"));
    let (clear, encoded) = frame_color(4);
    // A first graph fills the texture and leaves it ready for sampling.
    let mut g = GraphBuilder::new();
    let tex = g.import_image("texture", image.clone());
    g.pass("fill")
        .image(tex, Access::TransferDst)
        .record(move |ctx| ctx.clear(tex, 0, clear));
    g.pass("to sampled")
        .image(tex, Access::Sampled(Stages::Fragment))
        .record(|_| {});
    let mut upload = g.compile(&ctx).expect("compile");
    run_frames(&ctx, &mut upload, &[false], |_| {});
    drop(upload);

    // The second graph starts from SHADER_READ_ONLY_OPTIMAL instead of UNDEFINED.
    let host = host_buffer(&ctx, "texels", 64);
    let mut g = GraphBuilder::new();
    let tex = g.import_image_with("texture", image.clone(), Access::Sampled(Stages::Fragment));
    let host_id = g.import_buffer("texels", host.clone());
    download(&mut g, tex, host_id);
    let first = g.first_frame_barriers().expect("valid");
    let t = first[0]
        .iter()
        .find(|b| matches!(b.target, BarrierTarget::Image { id, .. } if id == tex))
        .expect("transition")
        .transition;
    assert_eq!(
        (t.old_layout, t.new_layout),
        (
            vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
            vk::ImageLayout::TRANSFER_SRC_OPTIMAL
        )
    );
    assert_eq!(t.src_stages, vk::PipelineStageFlags2::FRAGMENT_SHADER);
    let mut graph = g.compile(&ctx).expect("compile");
    run_frames(&ctx, &mut graph, &[false], |_| {
        let texels = host.mapped().expect("mapped");
        assert!(texels.chunks(4).all(|t| t == encoded), "{:?}", &texels[..4]);
    });
    drop(graph);
    common::assert_clean(&ctx);
}

#[test]
fn imported_resources_lacking_a_declared_usage_are_rejected_at_compile() {
    let ctx = common::context();
    let readback = host_buffer(&ctx, "readback", 64);
    let mut g = GraphBuilder::new();
    let id = g.import_buffer("readback", readback);
    g.pass("misuse")
        .buffer(id, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    let e = g.compile(&ctx).err().expect("rejected").to_string();
    assert!(
        e.contains("misuse") && e.contains("'readback'") && e.contains("STORAGE_BUFFER"),
        "{e}"
    );
    common::assert_clean(&ctx);
}

#[test]
fn resources_only_culled_passes_used_are_not_allocated() {
    // Usage flags follow from the accesses: a transient buffer or image whose passes were all
    // culled has none, and allocating it would be invalid (usage 0).
    let ctx = common::context();
    let mut g = GraphBuilder::new();
    let scratch = g.buffer("scratch", 64, vk::BufferUsageFlags::empty());
    let image = g.image(
        "unseen",
        ImageDesc {
            format: vk::Format::R8G8B8A8_UNORM,
            width: 8,
            height: 8,
            mip_levels: 1,
            usage: vk::ImageUsageFlags::empty(),
        },
    );
    g.pass("dead")
        .buffer(scratch, Access::StorageWrite(Stages::Compute))
        .image(image, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    drop(g.compile(&ctx).expect("compile"));
    common::assert_clean(&ctx);
}

#[test]
fn binding_an_undeclared_resource_panics_with_pass_and_resource() {
    let ctx = common::context();
    let fill = compute_pipeline(
        &ctx,
        "test/indirect_fill.comp",
        &[vk::DescriptorType::STORAGE_BUFFER],
    );
    let mut g = GraphBuilder::new();
    let declared = g.buffer("declared", 64, vk::BufferUsageFlags::STORAGE_BUFFER);
    let forgotten = g.buffer("forgotten", 64, vk::BufferUsageFlags::STORAGE_BUFFER);
    let keep = g.import_buffer("keep", host_buffer(&ctx, "keep", 64));
    g.pass("sloppy")
        .buffer(declared, Access::StorageWrite(Stages::Compute))
        .record(move |ctx| {
            ctx.bind(&fill, &[Descriptor::Buffer(0, forgotten)]);
            ctx.dispatch(1, 1, 1);
        });
    g.copy_buffer("keep", declared, keep, &whole(64));
    let mut graph = g.compile(&ctx).expect("compile");
    let cmd = ctx.allocate_command_buffer().expect("cmd");
    // SAFETY: a fresh command buffer; it is freed without being submitted.
    unsafe {
        ctx.device
            .begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
            .expect("begin")
    };
    let panic = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        graph.record(cmd, 0, false);
    }))
    .expect_err("binding an undeclared buffer must panic");
    let message = panic.downcast_ref::<String>().cloned().unwrap_or_default();
    assert!(
        message.contains("pass 'sloppy'")
            && message.contains("buffer 'forgotten'")
            && message.contains("binding 0"),
        "{message}"
    );
    ctx.free_command_buffer(cmd);
    drop(graph);
    common::assert_clean(&ctx);
}

#[test]
fn mip_range_views_with_a_linear_sampler_see_only_their_levels() {
    let ctx = common::context();
    let sample = compute_pipeline(
        &ctx,
        "test/sample_mips.comp",
        &[
            vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
            vk::DescriptorType::STORAGE_BUFFER,
        ],
    );
    let host = host_buffer(&ctx, "texels", 48);
    let mut g = GraphBuilder::new();
    let image = g.image(
        "levels",
        ImageDesc {
            format: vk::Format::R8G8B8A8_UNORM,
            width: 8,
            height: 8,
            mip_levels: 4,
            usage: vk::ImageUsageFlags::empty(),
        },
    );
    let texels = g.buffer("texels", 48, vk::BufferUsageFlags::empty());
    let host_id = g.import_buffer("texels.host", host.clone());
    g.pass("clear levels")
        .image(image, Access::TransferDst)
        .record(move |ctx| {
            for level in 0..4 {
                ctx.clear(image, level, frame_color(level).0);
            }
        });
    g.pass("sample")
        .image_mips(image, 1, 2, Access::Sampled(Stages::Compute))
        .buffer(texels, Access::StorageWrite(Stages::Compute))
        .record(move |ctx| {
            ctx.bind(
                &sample,
                &[
                    Descriptor::SampledMips {
                        binding: 0,
                        image,
                        base: 1,
                        count: 2,
                        sampler: Sampler::Linear,
                    },
                    Descriptor::Buffer(1, texels),
                ],
            );
            ctx.dispatch(1, 1, 1);
        });
    g.copy_buffer("download", texels, host_id, &whole(48));
    host_pass(&mut g, host_id);
    let mut graph = g.compile(&ctx).expect("compile");
    run_frames(&ctx, &mut graph, &[false; 2], |f| {
        let red: Vec<f32> = host
            .mapped()
            .expect("mapped")
            .chunks_exact(16)
            .map(|t| f32::from_ne_bytes([t[0], t[1], t[2], t[3]]))
            .collect();
        let level = |l: u32| frame_color(l).0[0];
        assert!(
            (red[0] - level(1)).abs() < 1e-4,
            "frame {f}: lod 0 is mip 1, got {red:?}"
        );
        assert!(
            (red[1] - level(2)).abs() < 1e-4,
            "frame {f}: lod 1 is mip 2, got {red:?}"
        );
        let between = (level(1) + level(2)) / 2.0;
        assert!(
            (red[2] - between).abs() < 1.5 / 255.0,
            "frame {f}: linear filtering between mips 1 and 2, got {red:?}"
        );
    });
    drop(graph);
    common::assert_clean(&ctx);
}

#[test]
fn indirect_draws_read_their_arguments_and_count_from_buffers() {
    let ctx = common::context();
    if skipped(
        &ctx,
        ctx.caps.draw_indirect_count,
        "lacks drawIndirectCount",
    ) {
        return;
    }
    let format = vk::Format::R8G8B8A8_UNORM;
    let pipeline = Arc::new(
        Pipeline::graphics(
            &ctx,
            &GraphicsDesc {
                shaders: vec!["test/quad.vert", "test/flat.frag"],
                color_formats: vec![format],
                ..Default::default()
            },
            &[],
        )
        .expect("pipeline"),
    );
    let host = host_buffer(&ctx, "pixels", 8 * 8 * 4);
    let mut g = GraphBuilder::new();
    let target = target_8x8(&mut g, format);
    let args = g.buffer("args", 32, vk::BufferUsageFlags::empty());
    let count = g.buffer("count", 4, vk::BufferUsageFlags::empty());
    let host_id = g.import_buffer("pixels", host.clone());
    // Draw 0: the right half (first vertex 6); draw 1: the left half (first vertex 0).
    g.update_buffer("args", args, 0, &u32_bytes(&[6, 1, 6, 0, 6, 1, 0, 0]));
    g.update_buffer("count", count, 0, &1u32.to_ne_bytes());
    let red = f32_bytes(&[1.0, 0.0, 0.0, 1.0]);
    let blue = f32_bytes(&[0.0, 0.0, 1.0, 1.0]);
    let p = pipeline.clone();
    g.pass("left")
        .buffer_range(args, BufferRange::new(16, 16), Access::IndirectRead)
        .color(target, Load::Clear([0.0; 4]))
        .record(move |ctx| {
            ctx.bind(&p, &[]);
            ctx.push(&p, &red);
            ctx.draw_indirect(args, 16, 1, 16);
        });
    // Up to two draws, but the count buffer says one: the left half stays red.
    g.pass("counted")
        .buffer(args, Access::IndirectRead)
        .buffer(count, Access::IndirectRead)
        .color(target, Load::Load)
        .record(move |ctx| {
            ctx.bind(&pipeline, &[]);
            ctx.push(&pipeline, &blue);
            ctx.draw_indirect_count(args, 0, count, 0, 2, 16);
        });
    download(&mut g, target, host_id);
    let mut graph = g.compile(&ctx).expect("compile");
    run_frames(&ctx, &mut graph, &[false; 2], |f| {
        assert_halves(host.mapped().expect("mapped"), f);
    });
    drop(graph);
    common::assert_clean(&ctx);
}

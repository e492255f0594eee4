//! The render graph executed on lavapipe under synchronization validation: a ping-pong
//! pyramid (per-mip barriers, copy pass filling missing levels), a history image carried
//! across frames, and an on-demand readback.

mod common;

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;
use surfel::gpu::{Buffer, ImageDesc};
use surfel::graph::{Access, GraphBuilder};

const RED: [f32; 4] = [1.0, 0.0, 0.0, 1.0];

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
            Arc::new(
                Buffer::new(
                    &ctx,
                    "rb",
                    u64::from(w * h * 4),
                    vk::BufferUsageFlags::TRANSFER_DST,
                    MemoryLocation::GpuToCpu,
                )
                .expect("buffer"),
            )
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
    g.pass("project")
        .image_mips(level0, 0, 1, Access::TransferDst)
        .record(move |ctx| ctx.clear(level0, 0, RED));
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

    let cmd = ctx.allocate_command_buffer().expect("cmd");
    for frame in 0..3 {
        // SAFETY: the previous submission was waited on.
        unsafe {
            ctx.device
                .reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())
                .expect("reset");
            ctx.device
                .begin_command_buffer(cmd, &vk::CommandBufferBeginInfo::default())
                .expect("begin");
        }
        graph.record(cmd, frame == 2);
        // SAFETY: recording began above.
        unsafe { ctx.device.end_command_buffer(cmd).expect("end") };
        ctx.submit_and_wait(cmd).expect("submit");
        graph.profiler().collect().expect("timestamps");
    }
    ctx.free_command_buffer(cmd);
    for buffer in &readback {
        let bytes = buffer.mapped().expect("mapped");
        assert!(
            bytes.chunks(4).all(|t| t == [255, 0, 0, 255]),
            "every level of A is red"
        );
    }
    let scopes = graph.profiler().scopes();
    assert_eq!(scopes.len(), 6);
    assert!(scopes.iter().all(|s| s.samples == 3));
    drop(graph);
    common::assert_clean(&ctx);
}

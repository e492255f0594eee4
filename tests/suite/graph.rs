//! The render graph derives the right barriers: MRT, ping-pong pyramids, compute -> graphics
//! hand-offs, history and swapchain images, merged accesses, buffer ranges, transfer
//! operations, device stage support, on-demand passes, and rejects invalid declarations. No
//! device needed.

use ash::vk;
use surfel::gpu::ImageDesc;
use surfel::graph::{
    Access, Barrier, BarrierTarget, BufferId, BufferRange, GraphBuilder, ImageId, Load,
    StageSupport, Stages,
};

use vk::AccessFlags2 as A;
use vk::ImageLayout as L;
use vk::PipelineStageFlags2 as S;

fn desc(format: vk::Format, mips: u32) -> ImageDesc {
    ImageDesc {
        format,
        width: 64,
        height: 64,
        mip_levels: mips,
        usage: vk::ImageUsageFlags::COLOR_ATTACHMENT | vk::ImageUsageFlags::SAMPLED,
    }
}

fn on_image(barriers: &[Barrier], id: ImageId) -> Vec<(u32, Barrier)> {
    barriers
        .iter()
        .filter_map(|b| match b.target {
            BarrierTarget::Image { id: i, mip } if i == id => Some((mip, *b)),
            _ => None,
        })
        .collect()
}

#[test]
fn mrt_attachments_transition_then_become_visible_to_the_sampling_pass() {
    let mut g = GraphBuilder::new();
    let a = g.image("albedo", desc(vk::Format::R8G8B8A8_UNORM, 1));
    let n = g.image("normals", desc(vk::Format::R16G16B16A16_SFLOAT, 1));
    let z = g.image("z", desc(vk::Format::D32_SFLOAT, 1));
    let out = g.image("out", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("gbuffer")
        .color(a, Load::Clear([0.0; 4]))
        .color(n, Load::Clear([0.0; 4]))
        .depth(z, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("shade")
        .image(a, Access::Sampled(Stages::Fragment))
        .image(n, Access::Sampled(Stages::Fragment))
        .color(out, Load::DontCare)
        .record(|_| {});
    let first = g.first_frame_barriers().expect("valid");
    assert_eq!(
        first[0].len(),
        3,
        "albedo, normals and depth leave UNDEFINED"
    );
    let depth = on_image(&first[0], z)[0].1.transition;
    assert_eq!(
        (depth.old_layout, depth.new_layout),
        (L::UNDEFINED, L::DEPTH_ATTACHMENT_OPTIMAL)
    );
    assert_eq!(
        depth.dst_stages,
        S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS
    );

    let steady = g.barriers().expect("valid");
    for id in [a, n] {
        let t = on_image(&steady[1], id)[0].1.transition;
        assert_eq!(
            (t.src_stages, t.dst_stages),
            (S::COLOR_ATTACHMENT_OUTPUT, S::FRAGMENT_SHADER)
        );
        assert!(t.src_access.contains(A::COLOR_ATTACHMENT_WRITE));
        assert_eq!(t.dst_access, A::SHADER_SAMPLED_READ);
        assert_eq!(
            (t.old_layout, t.new_layout),
            (L::COLOR_ATTACHMENT_OPTIMAL, L::SHADER_READ_ONLY_OPTIMAL)
        );
        // Next frame the G-buffer pass waits for this frame's sampling before overwriting.
        let w = on_image(&steady[0], id)[0].1.transition;
        assert!(w.src_stages.contains(S::FRAGMENT_SHADER));
        assert_eq!(
            w.old_layout,
            L::UNDEFINED,
            "transient contents are discarded"
        );
    }
    assert_eq!(on_image(&steady[1], out).len(), 1);
}

#[test]
fn ping_pong_levels_alternate_images_and_only_touched_mips_get_barriers() {
    let mut g = GraphBuilder::new();
    let pp = g.ping_pong("pyramid", desc(vk::Format::R16G16B16A16_SFLOAT, 3));
    assert_eq!(
        (pp.holder(0), pp.holder(1), pp.holder(2)),
        (pp.a, pp.b, pp.a)
    );
    g.pass("project")
        .color_mip(pp.holder(0), 0, Load::Clear([0.0; 4]))
        .record(|_| {});
    for level in 1..3 {
        g.pass(&format!("analysis {level}"))
            .image_mips(
                pp.holder(level - 1),
                level - 1,
                1,
                Access::Sampled(Stages::Fragment),
            )
            .color_mip(pp.holder(level), level, Load::DontCare)
            .record(|_| {});
    }
    // Copy pass: give image A the level it is missing (level 1) for the synthesis phase.
    g.pass("copy")
        .image_mips(pp.b, 1, 1, Access::TransferSrc)
        .image_mips(pp.a, 1, 1, Access::TransferDst)
        .record(|_| {});
    let b = g.barriers().expect("valid");
    let analysis1_reads = on_image(&b[1], pp.a);
    assert_eq!(analysis1_reads.len(), 1);
    assert_eq!(analysis1_reads[0].0, 0, "reads A level 0 only");
    assert_eq!(
        analysis1_reads[0].1.transition.new_layout,
        L::SHADER_READ_ONLY_OPTIMAL
    );
    let analysis1_writes = on_image(&b[1], pp.b);
    assert_eq!(analysis1_writes.len(), 1);
    assert_eq!(analysis1_writes[0].0, 1, "writes B level 1 only");
    let analysis2 = on_image(&b[2], pp.b);
    assert_eq!(analysis2[0].0, 1);
    assert_eq!(
        analysis2[0].1.transition.src_stages,
        S::COLOR_ATTACHMENT_OUTPUT
    );
    let copy_src = on_image(&b[3], pp.b)[0].1.transition;
    assert_eq!(
        (copy_src.old_layout, copy_src.new_layout),
        (L::SHADER_READ_ONLY_OPTIMAL, L::TRANSFER_SRC_OPTIMAL)
    );
    let copy_dst = on_image(&b[3], pp.a);
    assert_eq!(copy_dst.len(), 1);
    assert_eq!(copy_dst[0].0, 1);
    assert_eq!(copy_dst[0].1.transition.new_layout, L::TRANSFER_DST_OPTIMAL);
}

#[test]
fn compute_results_are_handed_to_indirect_draws_and_vertex_shaders() {
    let mut g = GraphBuilder::new();
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER;
    let args = g.buffer("args", 64, usage);
    let verts = g.buffer("visible", 4096, usage);
    let color = g.image("color", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("cull")
        .buffer(args, Access::StorageWrite(Stages::Compute))
        .buffer(verts, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.pass("draw")
        .buffer(args, Access::IndirectRead)
        .buffer(verts, Access::StorageRead(Stages::Vertex))
        .color(color, Load::Clear([0.0; 4]))
        .record(|_| {});
    let b = g.barriers().expect("valid");
    let find = |pass: usize, name: surfel::graph::BufferId| {
        b[pass]
            .iter()
            .find(|x| matches!(x.target, BarrierTarget::Buffer { id, .. } if id == name))
            .map(|x| x.transition)
    };
    let t = find(1, args).expect("indirect barrier");
    assert_eq!(
        (t.src_stages, t.src_access),
        (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE)
    );
    assert_eq!(
        (t.dst_stages, t.dst_access),
        (S::DRAW_INDIRECT, A::INDIRECT_COMMAND_READ)
    );
    let v = find(1, verts).expect("vertex barrier");
    assert_eq!(
        (v.dst_stages, v.dst_access),
        (S::VERTEX_SHADER, A::SHADER_STORAGE_READ)
    );
    // Next frame the compute pass must wait for the draw's reads (write-after-read).
    let war = find(0, args).expect("WAR barrier");
    assert_eq!(war.src_stages, S::DRAW_INDIRECT);
}

#[test]
fn history_keeps_its_layout_and_swapchain_images_chain_to_the_acquire() {
    let mut g = GraphBuilder::new();
    let history = g.history_image("previous", desc(vk::Format::R8G8B8A8_UNORM, 1));
    let swap = g.external_image("swapchain", desc(vk::Format::B8G8R8A8_UNORM, 1));
    g.pass("read previous")
        .image(history, Access::Sampled(Stages::Fragment))
        .color(swap, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("write history")
        .image(history, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.pass("present")
        .image(swap, Access::Present)
        .record(|_| {});
    let first = g.first_frame_barriers().expect("valid");
    let steady = g.barriers().expect("valid");
    assert_eq!(
        on_image(&first[0], history)[0].1.transition.old_layout,
        L::UNDEFINED
    );
    let kept = on_image(&steady[0], history)[0].1.transition;
    assert_eq!(
        kept.old_layout,
        L::GENERAL,
        "history keeps last frame's layout and contents"
    );
    assert_eq!(kept.src_access, A::SHADER_STORAGE_WRITE);
    let acquire = on_image(&steady[0], swap)[0].1.transition;
    assert_eq!(acquire.src_stages, S::COLOR_ATTACHMENT_OUTPUT);
    assert_eq!(acquire.old_layout, L::UNDEFINED);
    let present = on_image(&steady[2], swap)[0].1.transition;
    assert_eq!(present.new_layout, L::PRESENT_SRC_KHR);
}

#[test]
fn invalid_declarations_are_rejected_with_the_pass_name() {
    let mut g = GraphBuilder::new();
    let img = g.image("img", desc(vk::Format::R8G8B8A8_UNORM, 2));
    g.pass("too deep")
        .image_mips(img, 1, 2, Access::Sampled(Stages::Compute))
        .record(|_| {});
    let e = g.barriers().unwrap_err().to_string();
    assert!(e.contains("too deep") && e.contains("img"), "{e}");

    let mut g = GraphBuilder::new();
    let img = g.image("img", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("readback")
        .image(img, Access::TransferSrc)
        .on_demand()
        .record(|_| {});
    g.pass("late")
        .image(img, Access::Sampled(Stages::Compute))
        .record(|_| {});
    assert!(g.barriers().unwrap_err().to_string().contains("late"));

    let mut g = GraphBuilder::new();
    let kept = g.history_image("kept", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("peek")
        .image(kept, Access::TransferSrc)
        .on_demand()
        .record(|_| {});
    assert!(g
        .barriers()
        .unwrap_err()
        .to_string()
        .contains("not transient"));

    let mut g = GraphBuilder::new();
    let big = g.image("big", desc(vk::Format::R8G8B8A8_UNORM, 2));
    let small = g.image("small", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("mixed")
        .color_mip(big, 1, Load::DontCare)
        .color(small, Load::DontCare)
        .record(|_| {});
    assert!(g
        .barriers()
        .unwrap_err()
        .to_string()
        .contains("differ in size"));

    let mut g = GraphBuilder::new();
    let img = g.image("img", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("twice")
        .image(img, Access::Sampled(Stages::Compute))
        .image(img, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    assert!(g.barriers().unwrap_err().to_string().contains("twice"));

    let mut g = GraphBuilder::new();
    let img = g.image("img", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("confused")
        .image(img, Access::IndirectRead)
        .record(|_| {});
    let e = g.barriers().unwrap_err().to_string();
    assert!(
        e.contains("confused") && e.contains("applies to buffers"),
        "{e}"
    );

    let mut g = GraphBuilder::new();
    let buf = g.buffer("small", 64, vk::BufferUsageFlags::empty());
    g.pass("overrun")
        .buffer_range(buf, BufferRange::new(60, 8), Access::TransferDst)
        .record(|_| {});
    let e = g.barriers().unwrap_err().to_string();
    assert!(
        e.contains("overrun") && e.contains("60..68") && e.contains("small"),
        "{e}"
    );
}

fn on_buffer(barriers: &[Barrier], id: BufferId) -> Vec<(BufferRange, Barrier)> {
    barriers
        .iter()
        .filter_map(|b| match b.target {
            BarrierTarget::Buffer { id: i, range } if i == id => Some((range, *b)),
            _ => None,
        })
        .collect()
}

#[test]
fn several_accesses_of_one_pass_merge_into_one_barrier() {
    let mut g = GraphBuilder::new();
    let args = g.buffer("args", 64, vk::BufferUsageFlags::empty());
    let img = g.image("img", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("cull")
        .buffer(args, Access::StorageWrite(Stages::Compute))
        .image(img, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.pass("consume")
        .buffer(args, Access::IndirectRead)
        .buffer(args, Access::StorageRead(Stages::Compute))
        .image(img, Access::StorageRead(Stages::Compute))
        .image(img, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    let b = g.barriers().expect("merged");
    let args_barriers = on_buffer(&b[1], args);
    assert_eq!(args_barriers.len(), 1, "one barrier for both reads");
    let t = args_barriers[0].1.transition;
    assert_eq!(args_barriers[0].0, BufferRange::WHOLE);
    assert_eq!(
        (t.src_stages, t.src_access),
        (S::COMPUTE_SHADER, A::SHADER_STORAGE_WRITE)
    );
    assert_eq!(t.dst_stages, S::DRAW_INDIRECT | S::COMPUTE_SHADER);
    assert_eq!(
        t.dst_access,
        A::INDIRECT_COMMAND_READ | A::SHADER_STORAGE_READ
    );
    let img_barriers = on_image(&b[1], img);
    assert_eq!(img_barriers.len(), 1);
    let t = img_barriers[0].1.transition;
    assert_eq!(
        t.dst_access,
        A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE,
        "a read and a write in one layout act as a read-write"
    );
    assert_eq!((t.old_layout, t.new_layout), (L::GENERAL, L::GENERAL));
}

#[test]
fn overlapping_mips_in_conflicting_layouts_are_rejected_but_disjoint_levels_are_not() {
    let mut g = GraphBuilder::new();
    let img = g.image("pyramid", desc(vk::Format::R16G16B16A16_SFLOAT, 4));
    g.pass("reduce")
        .image_mips(img, 0, 3, Access::Sampled(Stages::Fragment))
        .color_mip(img, 2, Load::DontCare)
        .record(|_| {});
    let e = g.barriers().unwrap_err().to_string();
    assert!(
        e.contains("'reduce'") && e.contains("'pyramid'") && e.contains("mip 2"),
        "{e}"
    );

    let mut g = GraphBuilder::new();
    let img = g.image("pyramid", desc(vk::Format::R16G16B16A16_SFLOAT, 4));
    g.pass("level 0")
        .color_mip(img, 0, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("level 1")
        .image_mips(img, 0, 1, Access::Sampled(Stages::Fragment))
        .color_mip(img, 1, Load::DontCare)
        .record(|_| {});
    let b = g
        .barriers()
        .expect("disjoint levels of one image are legal");
    let levels: Vec<u32> = on_image(&b[1], img).iter().map(|(m, _)| *m).collect();
    assert_eq!(levels, [0, 1]);
}

#[test]
fn buffer_ranges_are_tracked_separately_and_barriers_carry_them() {
    let mut g = GraphBuilder::new();
    let buf = g.buffer("args", 64, vk::BufferUsageFlags::empty());
    g.pass("first half")
        .buffer_range(
            buf,
            BufferRange::new(0, 16),
            Access::StorageWrite(Stages::Compute),
        )
        .record(|_| {});
    g.fill_buffer("second half", buf, BufferRange::new(16, 16), 7);
    g.pass("read")
        .buffer(buf, Access::IndirectRead)
        .record(|_| {});
    let first = g.first_frame_barriers().expect("valid");
    assert!(
        on_buffer(&first[1], buf).is_empty(),
        "disjoint writes need no barrier between them"
    );
    let reads = on_buffer(&first[2], buf);
    assert_eq!(reads.len(), 2, "{reads:?}");
    assert_eq!(reads[0].0, BufferRange::new(0, 16));
    assert_eq!(reads[0].1.transition.src_stages, S::COMPUTE_SHADER);
    assert_eq!(reads[1].0, BufferRange::new(16, 16));
    assert_eq!(
        (
            reads[1].1.transition.src_stages,
            reads[1].1.transition.src_access
        ),
        (S::ALL_TRANSFER, A::TRANSFER_WRITE)
    );
    // Next frame each writer waits only for the read of its own range.
    let steady = g.barriers().expect("valid");
    let war = on_buffer(&steady[1], buf);
    assert_eq!(war.len(), 1);
    assert_eq!(war[0].0, BufferRange::new(16, 16));
    assert_eq!(war[0].1.transition.src_stages, S::DRAW_INDIRECT);
    assert_eq!(war[0].1.transition.dst_stages, S::ALL_TRANSFER);
    let s = g.schedule().expect("valid");
    assert!(s.contains("barrier args[16..32]"), "{s}");
}

#[test]
fn adjacent_ranges_with_the_same_transition_share_one_barrier() {
    let mut g = GraphBuilder::new();
    let buf = g.buffer("values", 64, vk::BufferUsageFlags::empty());
    g.pass("write")
        .buffer(buf, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.pass("read parts")
        .buffer_range(
            buf,
            BufferRange::new(0, 16),
            Access::StorageRead(Stages::Vertex),
        )
        .buffer_range(
            buf,
            BufferRange::new(16, 16),
            Access::StorageRead(Stages::Vertex),
        )
        .record(|_| {});
    let b = g.barriers().expect("valid");
    let reads = on_buffer(&b[1], buf);
    assert_eq!(reads.len(), 1);
    assert_eq!(reads[0].0, BufferRange::new(0, 32));
}

#[test]
fn fill_and_copy_buffer_passes_declare_their_transfers() {
    let mut g = GraphBuilder::new();
    let src = g.buffer("src", 64, vk::BufferUsageFlags::empty());
    let dst = g.buffer("dst", 64, vk::BufferUsageFlags::empty());
    g.fill_buffer("fill", src, BufferRange::WHOLE, 0xdead_beef);
    g.copy_buffer(
        "copy",
        src,
        dst,
        &[vk::BufferCopy {
            src_offset: 0,
            dst_offset: 8,
            size: 8,
        }],
    );
    g.pass("use")
        .buffer(dst, Access::StorageRead(Stages::Compute))
        .record(|_| {});
    let first = g.first_frame_barriers().expect("valid");
    assert!(first[0].is_empty(), "nothing to wait for in the first fill");
    let copy_src = on_buffer(&first[1], src);
    assert_eq!(copy_src.len(), 1);
    assert_eq!(copy_src[0].0, BufferRange::new(0, 8));
    let t = copy_src[0].1.transition;
    assert_eq!(
        (t.src_stages, t.src_access, t.dst_stages, t.dst_access),
        (
            S::ALL_TRANSFER,
            A::TRANSFER_WRITE,
            S::ALL_TRANSFER,
            A::TRANSFER_READ
        )
    );
    assert!(on_buffer(&first[1], dst).is_empty());
    let used = on_buffer(&first[2], dst);
    assert_eq!(used.len(), 1, "only the copied bytes were written");
    assert_eq!(used[0].0, BufferRange::new(8, 8));
    assert_eq!(used[0].1.transition.dst_stages, S::COMPUTE_SHADER);
    // Steady state: the fill waits for last frame's copy to have read the source.
    let steady = g.barriers().expect("valid");
    let fill = on_buffer(&steady[0], src);
    assert_eq!(fill[0].0, BufferRange::new(0, 8));
    assert_eq!(fill[0].1.transition.src_stages, S::ALL_TRANSFER);
    assert_eq!(fill[0].1.transition.src_access, A::NONE);
}

#[test]
fn stage_masks_only_name_stages_the_device_supports() {
    let build = || {
        let mut g = GraphBuilder::new();
        let buf = g.buffer("frame", 64, vk::BufferUsageFlags::empty());
        let color = g.image("color", desc(vk::Format::R8G8B8A8_UNORM, 1));
        g.update_buffer("upload", buf, 0, &[0; 16]);
        g.pass("draw")
            .buffer(buf, Access::UniformRead(Stages::Graphics))
            .color(color, Load::Clear([0.0; 4]))
            .record(|_| {});
        (g, buf)
    };
    let (g, buf) = build();
    let optional = S::GEOMETRY_SHADER | S::TASK_SHADER_EXT | S::MESH_SHADER_EXT;
    let all = g.barriers().expect("valid");
    let t = on_buffer(&all[1], buf)[0].1.transition;
    assert_eq!(
        t.dst_stages,
        S::VERTEX_SHADER | S::FRAGMENT_SHADER | optional
    );
    let bare = StageSupport {
        geometry: false,
        task: false,
        mesh: false,
    };
    let barriers = build().0.barriers_with(bare).expect("valid");
    for b in barriers.iter().flatten() {
        let t = b.transition;
        assert!(
            !(t.src_stages | t.dst_stages).intersects(optional),
            "{b:?} names an unsupported stage"
        );
    }
    let t = on_buffer(&barriers[1], buf)[0].1.transition;
    assert_eq!(t.dst_stages, S::VERTEX_SHADER | S::FRAGMENT_SHADER);
    let no_mesh = StageSupport {
        geometry: true,
        task: false,
        mesh: false,
    };
    let t = on_buffer(&build().0.barriers_with(no_mesh).expect("valid")[1], buf)[0]
        .1
        .transition;
    assert_eq!(
        t.dst_stages,
        S::VERTEX_SHADER | S::GEOMETRY_SHADER | S::FRAGMENT_SHADER
    );
}

#[test]
fn steady_state_waits_on_both_variants_of_an_on_demand_frame() {
    let mut g = GraphBuilder::new();
    let stats = g.buffer("stats", 64, vk::BufferUsageFlags::empty());
    g.pass("accumulate")
        .buffer(stats, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.fill_buffer("clear", stats, BufferRange::WHOLE, 0);
    let mut readback = g.pass("readback").on_demand();
    readback = readback.buffer(stats, Access::TransferDst);
    readback.record(|_| {});
    g.pass("readback.host")
        .on_demand()
        .buffer(stats, Access::HostRead)
        .record(|_| {});
    let steady = g.barriers().expect("valid");
    let t = on_buffer(&steady[0], stats)[0].1.transition;
    // Without readback last frame the clear (a transfer) wrote last; with it, the readback
    // wrote (transfer) and the host read. Either way the compute write must wait.
    assert!(
        t.src_stages.contains(S::ALL_TRANSFER | S::HOST),
        "{:?}",
        t.src_stages
    );
    assert!(
        t.src_access.contains(A::TRANSFER_WRITE),
        "{:?}",
        t.src_access
    );

    // A readback that writes a buffer a regular pass also writes last: the next frame's
    // first write waits on the regular writer and on the readback's transfer.
    let mut g = GraphBuilder::new();
    let buf = g.buffer("shared", 64, vk::BufferUsageFlags::empty());
    g.pass("produce")
        .buffer(buf, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.pass("readback")
        .on_demand()
        .buffer(buf, Access::TransferDst)
        .record(|_| {});
    let steady = g.barriers().expect("valid");
    let t = on_buffer(&steady[0], buf)[0].1.transition;
    assert_eq!(t.src_stages, S::COMPUTE_SHADER | S::ALL_TRANSFER);
    assert_eq!(t.src_access, A::SHADER_STORAGE_WRITE | A::TRANSFER_WRITE);
    // The readback itself waits for this frame's regular write.
    let t = on_buffer(&steady[1], buf)[0].1.transition;
    assert_eq!(
        (t.src_stages, t.dst_stages),
        (S::COMPUTE_SHADER, S::ALL_TRANSFER)
    );
}

#[test]
fn schedule_lists_passes_accesses_and_barriers() {
    let mut g = GraphBuilder::new();
    let img = g.image("img", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("draw")
        .color(img, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("readback")
        .image(img, Access::TransferSrc)
        .on_demand()
        .record(|_| {});
    let s = g.schedule().expect("valid");
    assert!(
        s.contains("0: draw") && s.contains("1: readback (on demand)"),
        "{s}"
    );
    assert!(
        s.contains("barrier img[mip 0]") && s.contains("TRANSFER_SRC_OPTIMAL"),
        "{s}"
    );
}

#[test]
fn passes_whose_results_nothing_uses_are_culled() {
    let mut g = GraphBuilder::new();
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let scratch = g.image("scratch", desc(vk::Format::R8G8B8A8_UNORM, 1));
    let feed = g.image("feed", desc(vk::Format::R8G8B8A8_UNORM, 1));
    let accumulated = g.image("accumulated", desc(vk::Format::R8G8B8A8_UNORM, 1));
    let swap = g.external_image("swapchain", desc(vk::Format::B8G8R8A8_UNORM, 1));
    let stats = g.buffer("stats", 64, usage);
    g.pass("debug view")
        .color(scratch, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("unused stats")
        .buffer(stats, Access::StorageWrite(Stages::Compute))
        .record(|_| {});
    g.pass("feed")
        .color(feed, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("first layer")
        .color(accumulated, Load::Clear([0.0; 4]))
        .record(|_| {});
    // Loads the first layer's result: that pass stays.
    g.pass("second layer")
        .image(feed, Access::Sampled(Stages::Fragment))
        .color(accumulated, Load::Load)
        .record(|_| {});
    // Overwrites `scratch` without reading it: "debug view" stays dead.
    g.pass("overwrite")
        .color(scratch, Load::Clear([1.0; 4]))
        .record(|_| {});
    g.pass("blit")
        .image(accumulated, Access::TransferSrc)
        .image(swap, Access::TransferDst)
        .record(|_| {});
    g.pass("present")
        .image(swap, Access::Present)
        .record(|_| {});
    let culled = g.cull();
    assert_eq!(culled, ["debug view", "unused stats", "overwrite"]);
    let s = g.schedule().expect("valid");
    for kept in ["feed", "first layer", "second layer", "blit", "present"] {
        assert!(s.contains(kept), "{kept} missing from\n{s}");
    }
    assert!(!s.contains("debug view"));
    assert!(g.cull().is_empty(), "culling is idempotent");
}

#[test]
fn external_buffers_are_checked_against_their_usage_and_outlive_the_frame() {
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let mut g = GraphBuilder::new();
    let frame = g.external_buffer("frame", 256, storage);
    let out = g.image("out", desc(vk::Format::R8G8B8A8_UNORM, 1));
    g.pass("draw")
        .buffer(frame, Access::UniformRead(Stages::Graphics))
        .color(out, Load::Clear([0.0; 4]))
        .record(|_| {});
    g.pass("sample")
        .image(out, Access::Sampled(Stages::Fragment))
        .buffer(frame, Access::StorageWrite(Stages::Fragment))
        .record(|_| {});
    assert!(
        g.cull().is_empty(),
        "writing an external buffer is an effect"
    );
    let steady = g.barriers().expect("valid");
    let on_frame = |pass: usize| on_buffer(&steady[pass], frame);
    assert_eq!(
        on_frame(0)[0].1.transition.src_stages,
        S::FRAGMENT_SHADER,
        "the read waits for the previous frame's write"
    );
    assert!(
        on_frame(1)[0]
            .1
            .transition
            .src_stages
            .contains(S::VERTEX_SHADER | S::FRAGMENT_SHADER),
        "the write waits for the uniform reads"
    );

    let mut g = GraphBuilder::new();
    let frame = g.external_buffer("frame", 256, storage);
    g.pass("indirect")
        .buffer(frame, Access::IndirectRead)
        .record(|_| {});
    let e = g.barriers().unwrap_err().to_string();
    assert!(
        e.contains("'indirect'") && e.contains("'frame'") && e.contains("lacks usage"),
        "{e}"
    );

    let mut g = GraphBuilder::new();
    let frame = g.external_buffer("frame", 256, storage);
    g.pass("past")
        .buffer_range(
            frame,
            BufferRange::new(128, 256),
            Access::StorageRead(Stages::Compute),
        )
        .record(|_| {});
    let e = g.barriers().unwrap_err().to_string();
    assert!(e.contains("256 bytes"), "{e}");
}

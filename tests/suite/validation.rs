//! The validation layers are really on in GPU tests: a deliberate misuse is counted.

use crate::common;

use ash::vk;

#[test]
fn validation_layer_reports_a_deliberate_error() {
    let ctx = common::context();
    assert!(ctx.validation);
    assert_eq!(ctx.validation_errors(), 0);
    // VUID-VkBufferCreateInfo-size-00912: size must be greater than 0.
    let info = vk::BufferCreateInfo::default()
        .size(0)
        .usage(vk::BufferUsageFlags::STORAGE_BUFFER);
    // SAFETY: deliberately invalid create info; the buffer (if any) is destroyed right away.
    unsafe {
        if let Ok(b) = ctx.device.create_buffer(&info, None) {
            ctx.device.destroy_buffer(b, None);
        }
    }
    assert!(
        ctx.validation_errors() >= 1,
        "the validation layer did not report the misuse"
    );
    assert!(ctx.first_validation_errors()[0].contains("size"));
}

#[test]
fn synchronization_validation_reports_a_missing_barrier() {
    let ctx = common::context();
    let buffer = surfel::gpu::Buffer::new(
        &ctx,
        "hazard",
        256,
        vk::BufferUsageFlags::TRANSFER_DST,
        gpu_allocator::MemoryLocation::GpuOnly,
    )
    .expect("buffer");
    ctx.one_shot(|cmd| {
        // SAFETY: valid commands; the missing barrier between the writes is the point.
        unsafe {
            ctx.device.cmd_fill_buffer(cmd, buffer.raw, 0, 256, 1);
            ctx.device.cmd_fill_buffer(cmd, buffer.raw, 0, 256, 2);
        }
    })
    .expect("submit");
    assert!(
        ctx.first_validation_errors()
            .iter()
            .any(|m| m.contains("SYNC-HAZARD-WRITE-AFTER-WRITE")),
        "synchronization validation is off: {:?}",
        ctx.first_validation_errors()
    );
}

//! Chunked uploads into device-local buffers through two staging buffers used alternately:
//! the host fills one while the GPU copies the other, so host memory stays bounded by two
//! chunks whatever the size of the data.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;
use gpu_allocator::MemoryLocation;

use super::frames::{begin_one_time, wait_and_reset};
use super::{Buffer, Context};

/// One copy from the current staging chunk into a destination buffer.
#[derive(Clone, Copy, Debug)]
pub struct CopyRegion {
    pub dst: vk::Buffer,
    pub dst_offset: u64,
    pub src_offset: u64,
    pub size: u64,
}

struct Slot {
    staging: Buffer,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    pending: bool,
}

/// Double-buffered staging uploader.
pub struct Uploader {
    ctx: Arc<Context>,
    slots: Vec<Slot>,
    next: usize,
}

impl Uploader {
    /// Two staging buffers of `chunk` bytes each.
    pub fn new(ctx: &Arc<Context>, chunk: u64) -> Result<Self> {
        let slots = (0..2)
            .map(|_| {
                let staging = Buffer::new(
                    ctx,
                    "upload.staging",
                    chunk,
                    vk::BufferUsageFlags::TRANSFER_SRC,
                    MemoryLocation::CpuToGpu,
                )?;
                let cmd = ctx.allocate_command_buffer()?;
                // SAFETY: plain fence creation; destroyed in Drop after waiting on it.
                let fence = unsafe {
                    ctx.device
                        .create_fence(&vk::FenceCreateInfo::default(), None)?
                };
                Ok(Slot {
                    staging,
                    cmd,
                    fence,
                    pending: false,
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            ctx: ctx.clone(),
            slots,
            next: 0,
        })
    }

    fn wait(&mut self, slot: usize) -> Result<()> {
        let s = &mut self.slots[slot];
        wait_and_reset(&self.ctx.device, s.fence, &mut s.pending)
            .context("waiting for an upload (device lost?)")
    }

    /// Lets `fill` write the next chunk (at most the chunk size given to `new`), then submits `copies` out
    /// of it without waiting; the chunk is reused two calls later.
    pub fn upload(
        &mut self,
        fill: impl FnOnce(&mut [u8]) -> Result<()>,
        copies: &[CopyRegion],
    ) -> Result<()> {
        let slot = self.next;
        self.next = (self.next + 1) % self.slots.len();
        self.wait(slot)?;
        let s = &mut self.slots[slot];
        fill(s.staging.mapped_mut()?)?;
        let d = &self.ctx.device;
        let regions: Vec<_> = copies
            .iter()
            .filter(|c| c.size > 0)
            .map(|c| {
                (
                    c.dst,
                    vk::BufferCopy::default()
                        .src_offset(c.src_offset)
                        .dst_offset(c.dst_offset)
                        .size(c.size),
                )
            })
            .collect();
        // Later submissions read the uploaded data in any shader stage.
        let barrier = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::ALL_TRANSFER)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
            .dst_access_mask(vk::AccessFlags2::MEMORY_READ)];
        // SAFETY: the slot's previous submission completed (waited above), so its command
        // buffer and staging memory may be reused; copies stay within both buffers (callers
        // size them from the same layout) and the fence is unsignalled.
        unsafe {
            begin_one_time(d, s.cmd)?;
            for (dst, region) in &regions {
                d.cmd_copy_buffer(s.cmd, s.staging.raw, *dst, std::slice::from_ref(region));
            }
            d.cmd_pipeline_barrier2(
                s.cmd,
                &vk::DependencyInfo::default().memory_barriers(&barrier),
            );
            d.end_command_buffer(s.cmd)?;
            let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(s.cmd)];
            let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
            d.queue_submit2(self.ctx.queue, &submit, s.fence)
                .context("submitting an upload")?;
        }
        s.pending = true;
        Ok(())
    }

    /// Waits for every submitted chunk.
    pub fn finish(&mut self) -> Result<()> {
        (0..self.slots.len()).try_for_each(|i| self.wait(i))
    }
}

impl Drop for Uploader {
    fn drop(&mut self) {
        let _ = self.finish();
        for s in &self.slots {
            self.ctx.free_command_buffer(s.cmd);
            // SAFETY: the fence is not pending (finish waited on it).
            unsafe { self.ctx.device.destroy_fence(s.fence, None) };
        }
    }
}

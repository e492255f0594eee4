//! Frames in flight: the submission policy of the frame loop. A `FrameRing` owns one command
//! buffer, one fence and (for a presenting renderer) one image-available semaphore per slot.
//! The host records slot `k` only after waiting on slot `k`'s fence, i.e. for the frame that
//! used the slot `len()` frames ago, never for the frame it just submitted.
//!
//! Every slot submits to the context's one queue. The present-wait ("rendered") semaphores
//! stay per swapchain image in `Swapchain`: a slot's fence says when its submission finished,
//! not when the presentation engine finished waiting on a semaphore, so one is reused only
//! once its image is acquired again.

use std::sync::Arc;

use anyhow::{Context as _, Result};
use ash::vk;

use super::Context;

struct Slot {
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    /// Signalled by the swapchain acquire of the frame recorded into this slot; null when the
    /// ring was made without semaphores.
    acquire: vk::Semaphore,
    /// Submitted and not waited on yet.
    pending: bool,
}

/// `len()` frame slots used round-robin (see the module documentation).
pub struct FrameRing {
    ctx: Arc<Context>,
    slots: Vec<Slot>,
    current: usize,
}

impl FrameRing {
    /// A ring of `count` slots (at least one); `acquire_semaphores` adds a swapchain
    /// image-available semaphore to each.
    pub fn new(ctx: &Arc<Context>, count: usize, acquire_semaphores: bool) -> Result<Self> {
        let mut ring = Self {
            ctx: ctx.clone(),
            slots: Vec::with_capacity(count.max(1)),
            current: 0,
        };
        for _ in 0..count.max(1) {
            ring.slots.push(Slot {
                cmd: ctx.allocate_command_buffer()?,
                fence: vk::Fence::null(),
                acquire: vk::Semaphore::null(),
                pending: false,
            });
            let slot = ring.slots.last_mut().expect("slot pushed above");
            // SAFETY: plain object creation; the handles are stored in the ring at once and
            // destroyed by its Drop (null handles are ignored), also on an early return.
            unsafe {
                slot.fence = ctx
                    .device
                    .create_fence(&vk::FenceCreateInfo::default(), None)?;
                if acquire_semaphores {
                    slot.acquire = ctx
                        .device
                        .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)?;
                }
            }
        }
        Ok(ring)
    }

    /// Number of slots (frames in flight).
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Always false: a ring has at least one slot.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// The slot being recorded.
    pub fn current(&self) -> usize {
        self.current
    }

    /// The current slot's image-available semaphore (null without semaphores). It is
    /// unsignalled: the submission that waited on it last has finished (`advance` waited).
    pub fn acquire_semaphore(&self) -> vk::Semaphore {
        self.slots[self.current].acquire
    }

    /// Moves to the next slot and blocks until the frame it held last has finished (only
    /// that frame: later submissions keep running). Returns the slot.
    pub fn advance(&mut self) -> Result<usize> {
        self.current = (self.current + 1) % self.slots.len();
        self.wait(self.current)?;
        Ok(self.current)
    }

    /// Blocks until `slot`'s submitted frame (if any) has finished.
    pub fn wait(&mut self, slot: usize) -> Result<()> {
        let s = &mut self.slots[slot];
        wait_and_reset(&self.ctx.device, s.fence, &mut s.pending)
            .context("waiting for a frame failed (device lost?)")
    }

    /// Blocks until every submitted frame has finished.
    pub fn wait_all(&mut self) -> Result<()> {
        (0..self.slots.len()).try_for_each(|slot| self.wait(slot))
    }

    /// Resets the current slot's command buffer and begins recording it.
    pub fn begin(&mut self) -> Result<vk::CommandBuffer> {
        let s = &self.slots[self.current];
        debug_assert!(!s.pending, "recording a slot whose frame is in flight");
        // SAFETY: the slot's previous submission has completed (`advance` waited on its
        // fence), so its command buffer may be reset and re-recorded.
        unsafe { begin_one_time(&self.ctx.device, s.cmd)? };
        Ok(s.cmd)
    }

    /// Ends recording the current slot's command buffer.
    pub fn end(&mut self) -> Result<()> {
        // SAFETY: `begin` started recording this command buffer.
        unsafe {
            self.ctx
                .device
                .end_command_buffer(self.slots[self.current].cmd)?
        };
        Ok(())
    }

    /// Submits the current slot's command buffer and returns without waiting. `wait` (a
    /// swapchain acquire) is waited on at color-attachment output; `signal` is signalled when
    /// the frame's commands finish.
    pub fn submit(
        &mut self,
        wait: Option<vk::Semaphore>,
        signal: Option<vk::Semaphore>,
    ) -> Result<()> {
        let s = &mut self.slots[self.current];
        let waits = wait.map(|w| {
            vk::SemaphoreSubmitInfo::default()
                .semaphore(w)
                .stage_mask(vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT)
        });
        let signals = signal.map(|w| {
            vk::SemaphoreSubmitInfo::default()
                .semaphore(w)
                .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
        });
        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(s.cmd)];
        let submit = [vk::SubmitInfo2::default()
            .command_buffer_infos(&cmds)
            .wait_semaphore_infos(waits.as_slice())
            .signal_semaphore_infos(signals.as_slice())];
        // SAFETY: the command buffer is fully recorded; the fence is unsignalled (created so,
        // and reset when the slot's previous frame was waited on); the renderer submits from
        // one thread, which keeps the queue externally synchronized.
        unsafe {
            self.ctx
                .device
                .queue_submit2(self.ctx.queue, &submit, s.fence)
                .context("queue submission failed (device lost?)")?;
        }
        s.pending = true;
        Ok(())
    }
}

/// When `pending` (a submission signals `fence`), blocks until `fence` signals, resets it
/// for the next submission and clears `pending`.
pub(super) fn wait_and_reset(
    device: &ash::Device,
    fence: vk::Fence,
    pending: &mut bool,
) -> Result<()> {
    if *pending {
        // SAFETY: waiting has no precondition beyond a valid fence; once it has signalled, no
        // pending submission uses it, so it may be reset.
        unsafe {
            device.wait_for_fences(&[fence], true, u64::MAX)?;
            device.reset_fences(&[fence])?;
        }
        *pending = false;
    }
    Ok(())
}

/// Resets `cmd` and begins recording it for one submission.
///
/// # Safety
/// No pending submission may use `cmd`, and its pool must allow resetting single buffers.
pub(super) unsafe fn begin_one_time(device: &ash::Device, cmd: vk::CommandBuffer) -> Result<()> {
    device.reset_command_buffer(cmd, vk::CommandBufferResetFlags::empty())?;
    device.begin_command_buffer(
        cmd,
        &vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
    )?;
    Ok(())
}

impl Drop for FrameRing {
    fn drop(&mut self) {
        let _ = self.wait_all();
        for s in &self.slots {
            // SAFETY: no submission of the slot is pending (waited above); null semaphores
            // are ignored.
            unsafe {
                self.ctx.device.destroy_fence(s.fence, None);
                self.ctx.device.destroy_semaphore(s.acquire, None);
            }
            self.ctx.free_command_buffer(s.cmd);
        }
    }
}

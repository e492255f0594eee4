//! Buffers and images backed by gpu-allocator, per-mip image views, staged upload and readback.

use std::sync::Arc;

use anyhow::{anyhow, Result};
use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::Context;

/// A buffer and its memory. Freed on drop.
pub struct Buffer {
    ctx: Arc<Context>,
    pub raw: vk::Buffer,
    pub size: u64,
    pub usage: vk::BufferUsageFlags,
    allocation: Option<Allocation>,
}

impl Buffer {
    /// Creates a buffer of `size` bytes (at least 4) in `location`.
    pub fn new(
        ctx: &Arc<Context>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Self> {
        let size = size.max(4);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid create info; the buffer is bound to memory before use and destroyed in Drop.
        unsafe {
            let raw = ctx.device.create_buffer(&info, None)?;
            let requirements = ctx.device.get_buffer_memory_requirements(raw);
            let allocation = ctx.with_allocator(|a| {
                a.allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location,
                    linear: true,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
                .map_err(|e| anyhow!("allocating {size} bytes for buffer '{name}': {e}"))
            });
            let allocation = match allocation {
                Ok(a) => a,
                Err(e) => {
                    ctx.device.destroy_buffer(raw, None);
                    return Err(e);
                }
            };
            ctx.device
                .bind_buffer_memory(raw, allocation.memory(), allocation.offset())?;
            ctx.name_object(raw, name);
            Ok(Self {
                ctx: ctx.clone(),
                raw,
                size,
                usage,
                allocation: Some(allocation),
            })
        }
    }

    /// A host-visible buffer the GPU copies results into (readback).
    pub fn readback(ctx: &Arc<Context>, name: &str, size: u64) -> Result<Self> {
        Self::new(
            ctx,
            name,
            size,
            vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuToCpu,
        )
    }

    /// Host-visible bytes of a CpuToGpu/GpuToCpu buffer.
    pub fn mapped(&self) -> Result<&[u8]> {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .ok_or_else(|| anyhow!("buffer is not host visible"))
    }

    /// Mutable host-visible bytes of a CpuToGpu buffer the GPU is not using.
    pub fn mapped_mut(&mut self) -> Result<&mut [u8]> {
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .ok_or_else(|| anyhow!("buffer is not host visible"))
    }

    /// The buffer's device address (created with `SHADER_DEVICE_ADDRESS` usage).
    pub fn device_address(&self) -> u64 {
        let info = vk::BufferDeviceAddressInfo::default().buffer(self.raw);
        // SAFETY: the buffer is live and bound to memory allocated with the device-address flag.
        unsafe { self.ctx.device.get_buffer_device_address(&info) }
    }

    /// Writes `data` at the start of a host-visible buffer. The caller guarantees the GPU is
    /// not using the buffer (its last frame's fence was waited on).
    pub fn write(&self, data: &[u8]) -> Result<()> {
        let allocation = self
            .allocation
            .as_ref()
            .ok_or_else(|| anyhow!("buffer has no memory"))?;
        let ptr = allocation
            .mapped_ptr()
            .ok_or_else(|| anyhow!("buffer is not host visible"))?;
        if data.len() as u64 > allocation.size() {
            return Err(anyhow!(
                "write of {} bytes into a {} byte buffer",
                data.len(),
                allocation.size()
            ));
        }
        // SAFETY: the mapping covers `allocation.size()` bytes, checked above; no GPU access
        // overlaps (see the method's contract) and no Rust reference aliases the mapping.
        unsafe {
            std::ptr::copy_nonoverlapping(data.as_ptr(), ptr.as_ptr().cast::<u8>(), data.len())
        };
        Ok(())
    }

    /// A device-local buffer filled with `data` through a staging buffer.
    pub fn with_data(
        ctx: &Arc<Context>,
        name: &str,
        data: &[u8],
        usage: vk::BufferUsageFlags,
    ) -> Result<Self> {
        let buffer = Self::new(
            ctx,
            name,
            data.len() as u64,
            usage | vk::BufferUsageFlags::TRANSFER_DST,
            MemoryLocation::GpuOnly,
        )?;
        if data.is_empty() {
            return Ok(buffer);
        }
        let staging = Self::new(
            ctx,
            "staging",
            data.len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        staging.write(data)?;
        ctx.one_shot(|cmd| {
            let region = [vk::BufferCopy::default().size(data.len() as u64)];
            // SAFETY: both buffers are live and large enough; the submission is waited on
            // before the staging buffer drops, and queue submission orders it before later use.
            unsafe {
                ctx.device
                    .cmd_copy_buffer(cmd, staging.raw, buffer.raw, &region)
            };
        })?;
        Ok(buffer)
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: the owner guarantees the GPU no longer uses the buffer (frames are waited on).
        unsafe { self.ctx.device.destroy_buffer(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self
                .ctx
                .with_allocator(|al| al.free(a).map_err(|e| anyhow!("{e}")));
        }
    }
}

/// What an image is created for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageDesc {
    pub format: vk::Format,
    pub width: u32,
    pub height: u32,
    pub mip_levels: u32,
    pub usage: vk::ImageUsageFlags,
}

impl ImageDesc {
    /// Extent of `level`.
    pub fn level_extent(&self, level: u32) -> (u32, u32) {
        ((self.width >> level).max(1), (self.height >> level).max(1))
    }

    pub fn aspect(&self) -> vk::ImageAspectFlags {
        aspect_of(self.format)
    }
}

/// The aspect a format's views and barriers use.
pub fn aspect_of(format: vk::Format) -> vk::ImageAspectFlags {
    match format {
        vk::Format::D32_SFLOAT | vk::Format::D16_UNORM | vk::Format::X8_D24_UNORM_PACK32 => {
            vk::ImageAspectFlags::DEPTH
        }
        vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT => {
            vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
        }
        _ => vk::ImageAspectFlags::COLOR,
    }
}

/// Creates a 2D view of mips `base..base + count` of `raw` (described by `desc`).
///
/// # Safety
/// `raw` must be a live image created from `desc` with a usage that allows views, and the
/// range must lie within its mip chain. The caller destroys the view before the image.
pub unsafe fn create_view(
    device: &ash::Device,
    raw: vk::Image,
    desc: &ImageDesc,
    base: u32,
    count: u32,
) -> ash::prelude::VkResult<vk::ImageView> {
    let info = vk::ImageViewCreateInfo::default()
        .image(raw)
        .view_type(vk::ImageViewType::TYPE_2D)
        .format(desc.format)
        .subresource_range(vk::ImageSubresourceRange {
            aspect_mask: desc.aspect(),
            base_mip_level: base,
            level_count: count,
            base_array_layer: 0,
            layer_count: 1,
        });
    device.create_image_view(&info, None)
}

/// A 2D image with a view of the whole mip chain and one view per mip level (no views for
/// transfer-only images).
pub struct Image {
    ctx: Arc<Context>,
    pub raw: vk::Image,
    pub desc: ImageDesc,
    pub view: vk::ImageView,
    pub mip_views: Vec<vk::ImageView>,
    allocation: Option<Allocation>,
}

impl Image {
    pub fn new(ctx: &Arc<Context>, name: &str, desc: ImageDesc) -> Result<Self> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(desc.format)
            .extent(vk::Extent3D {
                width: desc.width,
                height: desc.height,
                depth: 1,
            })
            .mip_levels(desc.mip_levels)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(desc.usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: valid create info; views/memory are destroyed in Drop.
        unsafe {
            let raw = ctx.device.create_image(&info, None)?;
            ctx.name_object(raw, name);
            let requirements = ctx.device.get_image_memory_requirements(raw);
            let allocation = ctx.with_allocator(|a| {
                a.allocate(&AllocationCreateDesc {
                    name,
                    requirements,
                    location: MemoryLocation::GpuOnly,
                    linear: false,
                    allocation_scheme: AllocationScheme::GpuAllocatorManaged,
                })
                .map_err(|e| anyhow!("allocating image '{name}': {e}"))
            });
            let allocation = match allocation {
                Ok(a) => a,
                Err(e) => {
                    ctx.device.destroy_image(raw, None);
                    return Err(e);
                }
            };
            ctx.device
                .bind_image_memory(raw, allocation.memory(), allocation.offset())?;
            let make_view =
                |base: u32, count: u32| create_view(&ctx.device, raw, &desc, base, count);
            // Transfer-only images cannot have views.
            let viewable = desc.usage.intersects(
                vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::STORAGE
                    | vk::ImageUsageFlags::COLOR_ATTACHMENT
                    | vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
            );
            let (view, mip_views) = if viewable {
                let mips = (0..desc.mip_levels)
                    .map(|l| make_view(l, 1))
                    .collect::<Result<Vec<_>, _>>()?;
                (make_view(0, desc.mip_levels)?, mips)
            } else {
                (vk::ImageView::null(), Vec::new())
            };
            Ok(Self {
                ctx: ctx.clone(),
                raw,
                desc,
                view,
                mip_views,
                allocation: Some(allocation),
            })
        }
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        // SAFETY: the GPU no longer uses the image (owners wait for their frames).
        unsafe {
            for v in self.mip_views.drain(..) {
                self.ctx.device.destroy_image_view(v, None);
            }
            if self.view != vk::ImageView::null() {
                self.ctx.device.destroy_image_view(self.view, None);
            }
            self.ctx.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            let _ = self
                .ctx
                .with_allocator(|al| al.free(a).map_err(|e| anyhow!("{e}")));
        }
    }
}

//! Window surface and swapchain (viewer only).

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use ash::{khr, vk};
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};

use super::Context;

/// A surface with its swapchain and per-image present-wait semaphores (the image-available
/// semaphores belong to the frame slots: `FrameRing`).
pub struct Swapchain {
    ctx: Arc<Context>,
    surface_ext: khr::surface::Instance,
    pub surface: vk::SurfaceKHR,
    pub raw: vk::SwapchainKHR,
    pub images: Vec<vk::Image>,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    /// Signalled when rendering to image i finished (waited by present). One per image: it is
    /// signalled again only after image i was acquired again, when present no longer uses it.
    pub rendered: Vec<vk::Semaphore>,
}

impl Swapchain {
    /// Creates a surface for `window` and a swapchain of `width` x `height`.
    pub fn new(
        ctx: &Arc<Context>,
        window: &(impl HasWindowHandle + HasDisplayHandle),
        width: u32,
        height: u32,
    ) -> Result<Self> {
        let surface_ext = khr::surface::Instance::new(&ctx.entry, &ctx.instance);
        // SAFETY: the window outlives the swapchain (the viewer drops the swapchain first).
        let surface = unsafe {
            ash_window::create_surface(
                &ctx.entry,
                &ctx.instance,
                window.display_handle()?.as_raw(),
                window.window_handle()?.as_raw(),
                None,
            )?
        };
        // SAFETY: valid handles.
        let supported = unsafe {
            surface_ext.get_physical_device_surface_support(
                ctx.physical_device,
                ctx.queue_family,
                surface,
            )?
        };
        if !supported {
            bail!("the selected queue cannot present to this window");
        }
        let mut s = Self {
            ctx: ctx.clone(),
            surface_ext,
            surface,
            raw: vk::SwapchainKHR::null(),
            images: Vec::new(),
            format: vk::Format::UNDEFINED,
            extent: vk::Extent2D::default(),
            rendered: Vec::new(),
        };
        s.recreate(width, height)?;
        Ok(s)
    }

    fn loader(&self) -> Result<&khr::swapchain::Device> {
        self.ctx
            .swapchain_ext
            .as_ref()
            .context("context was created without VK_KHR_swapchain")
    }

    /// (Re)creates the swapchain for a new window size.
    pub fn recreate(&mut self, width: u32, height: u32) -> Result<()> {
        // SAFETY: the device is idle before the old swapchain and semaphores are replaced.
        unsafe {
            self.ctx.device.device_wait_idle()?;
            let caps = self
                .surface_ext
                .get_physical_device_surface_capabilities(self.ctx.physical_device, self.surface)?;
            let formats = self
                .surface_ext
                .get_physical_device_surface_formats(self.ctx.physical_device, self.surface)?;
            let format = formats
                .iter()
                .find(|f| {
                    f.format == vk::Format::B8G8R8A8_UNORM || f.format == vk::Format::R8G8B8A8_UNORM
                })
                .or(formats.first())
                .context("surface has no formats")?;
            let extent = if caps.current_extent.width != u32::MAX {
                caps.current_extent
            } else {
                vk::Extent2D {
                    width: width.clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                    height: height
                        .clamp(caps.min_image_extent.height, caps.max_image_extent.height),
                }
            };
            if !caps
                .supported_usage_flags
                .contains(vk::ImageUsageFlags::TRANSFER_DST)
            {
                bail!("the surface does not support transfer destinations (blit)");
            }
            let mut count = caps.min_image_count + 1;
            if caps.max_image_count > 0 {
                count = count.min(caps.max_image_count);
            }
            let info = vk::SwapchainCreateInfoKHR::default()
                .surface(self.surface)
                .min_image_count(count)
                .image_format(format.format)
                .image_color_space(format.color_space)
                .image_extent(extent)
                .image_array_layers(1)
                .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
                .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
                .pre_transform(caps.current_transform)
                .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
                .present_mode(vk::PresentModeKHR::FIFO)
                .clipped(true)
                .old_swapchain(self.raw);
            let loader = self.loader()?.clone();
            let raw = loader.create_swapchain(&info, None)?;
            if self.raw != vk::SwapchainKHR::null() {
                loader.destroy_swapchain(self.raw, None);
            }
            self.raw = raw;
            self.images = loader.get_swapchain_images(raw)?;
            self.format = format.format;
            self.extent = extent;
            self.destroy_semaphores();
            for _ in 0..self.images.len() {
                let info = vk::SemaphoreCreateInfo::default();
                self.rendered
                    .push(self.ctx.device.create_semaphore(&info, None)?);
            }
        }
        Ok(())
    }

    /// Acquires the next image, signalling `available` (unsignalled, with no pending wait)
    /// when it is ready: its index, or `None` when the swapchain is out of date (then
    /// `available` stays unsignalled). A suboptimal image is still returned; `present` then
    /// reports that the swapchain must be recreated.
    pub fn acquire(&mut self, available: vk::Semaphore) -> Result<Option<u32>> {
        // SAFETY: the caller's semaphore is unsignalled with no pending operation (its frame
        // slot's previous submission completed).
        match unsafe {
            self.loader()?
                .acquire_next_image(self.raw, u64::MAX, available, vk::Fence::null())
        } {
            Ok((index, _)) => Ok(Some(index)),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Presents image `index` after its rendering; false when the swapchain must be recreated.
    pub fn present(&self, index: u32) -> Result<bool> {
        let waits = [self.rendered[index as usize]];
        let swapchains = [self.raw];
        let indices = [index];
        let info = vk::PresentInfoKHR::default()
            .wait_semaphores(&waits)
            .swapchains(&swapchains)
            .image_indices(&indices);
        // SAFETY: the image was acquired and rendered; the semaphore is signalled by that submit.
        match unsafe { self.loader()?.queue_present(self.ctx.queue, &info) } {
            Ok(false) => Ok(true),
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(false),
            Err(e) => Err(e.into()),
        }
    }

    fn destroy_semaphores(&mut self) {
        for s in self.rendered.drain(..) {
            // SAFETY: the device is idle (callers wait before recreating or dropping).
            unsafe { self.ctx.device.destroy_semaphore(s, None) };
        }
    }
}

impl Drop for Swapchain {
    fn drop(&mut self) {
        // SAFETY: wait for the queue, then destroy in reverse creation order.
        unsafe {
            let _ = self.ctx.device.device_wait_idle();
            self.destroy_semaphores();
            if let Ok(loader) = self.loader() {
                loader.destroy_swapchain(self.raw, None);
            }
            self.surface_ext.destroy_surface(self.surface, None);
        }
    }
}

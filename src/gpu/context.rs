//! Instance (with optional validation + synchronization validation), physical-device selection
//! with a capability report, logical device, queue and the gpu-allocator memory allocator.

use std::ffi::{c_void, CStr};
use std::fmt;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Mutex;

use anyhow::{anyhow, bail, Context as _, Result};
use ash::{ext, khr, vk};
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::pipeline_cache;

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// How to create the context.
#[derive(Clone, Debug, Default)]
pub struct ContextOptions {
    /// Enable `VK_LAYER_KHRONOS_validation` with synchronization validation.
    pub validation: bool,
    /// Instance extensions a window surface needs (from ash-window); empty for headless.
    pub surface_extensions: Vec<&'static CStr>,
}

impl ContextOptions {
    /// Headless; validation on when `SURFEL_VALIDATION=1` is set.
    pub fn from_env() -> Self {
        Self {
            validation: validation_requested(),
            surface_extensions: Vec::new(),
        }
    }
}

/// `SURFEL_VALIDATION=1` (or `true`) turns the validation layers on.
pub fn validation_requested() -> bool {
    std::env::var("SURFEL_VALIDATION").is_ok_and(|v| v == "1" || v.eq_ignore_ascii_case("true"))
}

/// What the selected device can do (printed by `surfel info`).
#[derive(Clone, Debug)]
pub struct Capabilities {
    pub device_name: String,
    pub driver: String,
    pub api_version: String,
    pub device_type: String,
    pub geometry_shader: bool,
    /// `shaderTessellationAndGeometryPointSize` and `vertexPipelineStoresAndAtomics`:
    /// geometry shaders that emit sized points and write storage buffers.
    pub geometry_points: bool,
    pub mesh_shader: bool,
    pub task_shader: bool,
    /// shaderInt64 and shaderBufferInt64Atomics.
    pub buffer_int64_atomics: bool,
    /// `shaderFloat64`: double precision in shaders.
    pub float64: bool,
    /// `multiDrawIndirect`: indirect draws with a draw count above 1.
    pub multi_draw_indirect: bool,
    /// `pipelineStatisticsQuery`: shader invocation counts per pass (`--pipeline-stats`).
    pub pipeline_statistics: bool,
    /// `drawIndirectCount`: `PassContext::draw_indirect_count`.
    pub draw_indirect_count: bool,
    /// `shaderDrawParameters`: `gl_DrawID`/`gl_BaseInstance` in vertex shaders.
    pub shader_draw_parameters: bool,
    pub large_points: bool,
    pub point_size_range: [f32; 2],
    pub timestamps: bool,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period: f32,
    pub max_image_dimension_2d: u32,
    pub max_color_attachments: u32,
    pub max_compute_workgroup_invocations: u32,
    /// `maxComputeSharedMemorySize`: bytes of shared memory per workgroup.
    pub max_compute_shared_memory: u32,
    pub max_storage_buffer_range: u32,
    /// `VkPhysicalDeviceSubgroupProperties::subgroupSize`: invocations per subgroup (the
    /// size compute shaders see, as shaders target SPIR-V 1.5).
    pub subgroup_size: u32,
    /// Subgroup ballot operations (`GL_KHR_shader_subgroup_ballot`) in compute shaders.
    pub subgroup_ballot_compute: bool,
    pub max_mesh_output_vertices: u32,
    pub max_geometry_output_vertices: u32,
    /// `maxGeometryTotalOutputComponents`: components all vertices one geometry invocation
    /// emits may have.
    pub max_geometry_total_output_components: u32,
    /// `maxGeometryShaderInvocations`: instances of a geometry shader per primitive.
    pub max_geometry_shader_invocations: u32,
}

impl fmt::Display for Capabilities {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let yes = |b: bool| if b { "yes" } else { "no" };
        writeln!(
            f,
            "device            {} ({})",
            self.device_name, self.device_type
        )?;
        writeln!(f, "driver            {}", self.driver)?;
        writeln!(f, "vulkan            {}", self.api_version)?;
        writeln!(f, "geometry shader   {}", yes(self.geometry_shader))?;
        writeln!(f, "geometry points   {}", yes(self.geometry_points))?;
        writeln!(
            f,
            "mesh/task shader  {}/{}",
            yes(self.mesh_shader),
            yes(self.task_shader)
        )?;
        writeln!(f, "int64 atomics     {}", yes(self.buffer_int64_atomics))?;
        writeln!(f, "float64           {}", yes(self.float64))?;
        writeln!(
            f,
            "subgroups         {} invocations, compute ballot {}",
            self.subgroup_size,
            yes(self.subgroup_ballot_compute)
        )?;
        writeln!(
            f,
            "indirect draws    multi {}, count {}, draw parameters {}",
            yes(self.multi_draw_indirect),
            yes(self.draw_indirect_count),
            yes(self.shader_draw_parameters)
        )?;
        writeln!(
            f,
            "large points      {} (size {}..{} px)",
            yes(self.large_points),
            self.point_size_range[0],
            self.point_size_range[1]
        )?;
        writeln!(
            f,
            "timestamps        {} ({} ns/tick)",
            yes(self.timestamps),
            self.timestamp_period
        )?;
        writeln!(
            f,
            "limits            image2D {} px, {} color attachments, {} invocations/group, storage buffer {} MiB",
            self.max_image_dimension_2d,
            self.max_color_attachments,
            self.max_compute_workgroup_invocations,
            self.max_storage_buffer_range >> 20
        )?;
        write!(
            f,
            "primitive output  mesh {} vertices, geometry {} vertices",
            self.max_mesh_output_vertices, self.max_geometry_output_vertices
        )
    }
}

/// Validation messages seen by the debug messenger.
#[derive(Default)]
pub struct DebugCounters {
    pub errors: AtomicU32,
    /// The first error messages, kept for test failure reports.
    pub first_errors: Mutex<Vec<String>>,
}

/// The host's monotonic clock (`CLOCK_MONOTONIC`, the calibration's host domain), in
/// milliseconds.
pub fn monotonic_ms() -> f64 {
    let mut t = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `t` is a valid timespec to write; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut t) };
    t.tv_sec as f64 * 1e3 + t.tv_nsec as f64 / 1e6
}

/// The Vulkan context: everything a frame needs that lives as long as the program.
pub struct Context {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub physical_device: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub caps: Capabilities,
    pub allocator: Mutex<Option<Allocator>>,
    pub push_descriptor: khr::push_descriptor::Device,
    pub debug_utils: Option<ext::debug_utils::Device>,
    pub mesh_shader: Option<ext::mesh_shader::Device>,
    pub swapchain_ext: Option<khr::swapchain::Device>,
    /// Reads the device's timestamp clock and the host's monotonic clock together, where the
    /// device can (`VK_EXT_calibrated_timestamps` with both domains; see [`Context::calibrate`]).
    pub calibrated_timestamps: Option<ext::calibrated_timestamps::Device>,
    /// Used by every pipeline creation; saved to `pipeline_cache_path` on drop.
    pub pipeline_cache: vk::PipelineCache,
    pipeline_cache_path: Option<PathBuf>,
    messenger: Option<(ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    counters: Box<DebugCounters>,
    pub validation: bool,
    command_pool: vk::CommandPool,
}

unsafe extern "system" fn debug_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    // SAFETY: `user` is the `DebugCounters` box owned by the Context, which destroys the
    // messenger before dropping the box; `data` is valid for the duration of the call.
    let counters = unsafe { &*(user as *const DebugCounters) };
    let message = unsafe { data.as_ref() }
        .and_then(|d| unsafe { d.message_as_c_str() })
        .map(|m| m.to_string_lossy().into_owned())
        .unwrap_or_default();
    if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        counters.errors.fetch_add(1, Ordering::SeqCst);
        if let Ok(mut first) = counters.first_errors.lock() {
            if first.len() < 8 {
                first.push(message.clone());
            }
        }
        eprintln!("[vulkan error] {message}");
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        eprintln!("[vulkan warning] {message}");
    }
    vk::FALSE
}

fn has_extension(list: &[vk::ExtensionProperties], name: &CStr) -> bool {
    list.iter()
        .any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name))
}

impl Context {
    /// Creates a headless context (or one able to present when `surface_extensions` is set).
    pub fn new(options: &ContextOptions) -> Result<Self> {
        // SAFETY: loading the system Vulkan loader; all later calls follow the spec's valid usage.
        unsafe { Self::create(options) }
    }

    unsafe fn create(options: &ContextOptions) -> Result<Self> {
        let entry = ash::Entry::load()
            .context("cannot load the Vulkan loader (is libvulkan1 installed?)")?;
        let app = vk::ApplicationInfo::default()
            .application_name(c"surfel")
            .engine_name(c"surfel")
            .api_version(vk::API_VERSION_1_3);

        let available_layers = entry.enumerate_instance_layer_properties()?;
        let has_validation = available_layers
            .iter()
            .any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
        if options.validation && !has_validation {
            bail!("validation requested but VK_LAYER_KHRONOS_validation is not installed");
        }
        let instance_exts = entry.enumerate_instance_extension_properties(None)?;
        let debug_available = has_extension(&instance_exts, ext::debug_utils::NAME);

        let mut extensions: Vec<*const i8> = options
            .surface_extensions
            .iter()
            .map(|e| e.as_ptr())
            .collect();
        if debug_available {
            extensions.push(ext::debug_utils::NAME.as_ptr());
        }
        let mut layers = Vec::new();
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        if options.validation {
            layers.push(VALIDATION_LAYER.as_ptr());
            extensions.push(ext::validation_features::NAME.as_ptr());
        }
        let mut create = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&extensions);
        if options.validation {
            create = create.push_next(&mut features);
        }
        let instance = entry
            .create_instance(&create, None)
            .context("vkCreateInstance failed")?;

        let counters = Box::<DebugCounters>::default();
        let messenger = if debug_available && options.validation {
            let loader = ext::debug_utils::Instance::new(&entry, &instance);
            let info = vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                        | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(debug_callback))
                .user_data(&*counters as *const DebugCounters as *mut c_void);
            let m = loader.create_debug_utils_messenger(&info, None)?;
            Some((loader, m))
        } else {
            None
        };

        let (physical_device, queue_family) = pick_device(&instance)?;
        let device_exts = instance.enumerate_device_extension_properties(physical_device)?;
        if !has_extension(&device_exts, khr::push_descriptor::NAME) {
            bail!("the device lacks VK_KHR_push_descriptor");
        }
        let has_mesh = has_extension(&device_exts, ext::mesh_shader::NAME);
        let has_swapchain = !options.surface_extensions.is_empty()
            && has_extension(&device_exts, khr::swapchain::NAME);
        let has_calibration = has_extension(&device_exts, ext::calibrated_timestamps::NAME) && {
            let domains = ext::calibrated_timestamps::Instance::new(&entry, &instance)
                .get_physical_device_calibrateable_time_domains(physical_device)
                .unwrap_or_default();
            [
                vk::TimeDomainEXT::DEVICE,
                vk::TimeDomainEXT::CLOCK_MONOTONIC,
            ]
            .iter()
            .all(|d| domains.contains(d))
        };

        // Query what is supported, then enable what we use.
        let mut mesh_q = vk::PhysicalDeviceMeshShaderFeaturesEXT::default();
        let mut v11_q = vk::PhysicalDeviceVulkan11Features::default();
        let mut v12_q = vk::PhysicalDeviceVulkan12Features::default();
        let mut v13_q = vk::PhysicalDeviceVulkan13Features::default();
        let mut q = vk::PhysicalDeviceFeatures2::default()
            .push_next(&mut v11_q)
            .push_next(&mut v12_q)
            .push_next(&mut v13_q);
        if has_mesh {
            q = q.push_next(&mut mesh_q);
        }
        instance.get_physical_device_features2(physical_device, &mut q);
        let core_q = q.features;
        if v12_q.buffer_device_address == 0 {
            bail!("the device lacks bufferDeviceAddress (Vulkan 1.2): point streams need it");
        }
        if v13_q.dynamic_rendering == 0 || v13_q.synchronization2 == 0 {
            bail!("the device lacks dynamic rendering or synchronization2 (Vulkan 1.3)");
        }

        let core = vk::PhysicalDeviceFeatures::default()
            .geometry_shader(core_q.geometry_shader != 0)
            .shader_tessellation_and_geometry_point_size(
                core_q.shader_tessellation_and_geometry_point_size != 0,
            )
            .large_points(core_q.large_points != 0)
            .shader_int64(core_q.shader_int64 != 0)
            .shader_float64(core_q.shader_float64 != 0)
            .fragment_stores_and_atomics(core_q.fragment_stores_and_atomics != 0)
            .vertex_pipeline_stores_and_atomics(core_q.vertex_pipeline_stores_and_atomics != 0)
            .independent_blend(core_q.independent_blend != 0)
            .multi_draw_indirect(core_q.multi_draw_indirect != 0)
            .pipeline_statistics_query(core_q.pipeline_statistics_query != 0);
        let mut v11 = vk::PhysicalDeviceVulkan11Features::default()
            .shader_draw_parameters(v11_q.shader_draw_parameters != 0);
        let mut v12 = vk::PhysicalDeviceVulkan12Features::default()
            .draw_indirect_count(v12_q.draw_indirect_count != 0)
            .host_query_reset(v12_q.host_query_reset != 0)
            .shader_buffer_int64_atomics(v12_q.shader_buffer_int64_atomics != 0)
            .scalar_block_layout(v12_q.scalar_block_layout != 0)
            .buffer_device_address(true);
        let mut v13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true)
            .maintenance4(v13_q.maintenance4 != 0);
        let mut mesh = vk::PhysicalDeviceMeshShaderFeaturesEXT::default()
            .mesh_shader(mesh_q.mesh_shader != 0)
            .task_shader(mesh_q.task_shader != 0);
        let mut features = vk::PhysicalDeviceFeatures2::default()
            .features(core)
            .push_next(&mut v11)
            .push_next(&mut v12)
            .push_next(&mut v13);
        let mut dev_exts = vec![khr::push_descriptor::NAME.as_ptr()];
        if has_mesh && mesh_q.mesh_shader != 0 {
            dev_exts.push(ext::mesh_shader::NAME.as_ptr());
            features = features.push_next(&mut mesh);
        }
        if has_swapchain {
            dev_exts.push(khr::swapchain::NAME.as_ptr());
        }
        if has_calibration {
            dev_exts.push(ext::calibrated_timestamps::NAME.as_ptr());
        }
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&dev_exts)
            .push_next(&mut features);
        let device = instance
            .create_device(physical_device, &device_info, None)
            .context("vkCreateDevice failed")?;
        let queue = device.get_device_queue(queue_family, 0);

        let caps = capabilities(
            &instance,
            physical_device,
            queue_family,
            &core_q,
            &v11_q,
            &v12_q,
            has_mesh.then_some(&mesh_q),
        );

        let props = instance.get_physical_device_properties(physical_device);
        let pipeline_cache_path = pipeline_cache::path(&props);
        let initial = pipeline_cache::load(pipeline_cache_path.as_ref(), &props);
        let create_cache = |data: &[u8]| {
            device.create_pipeline_cache(
                &vk::PipelineCacheCreateInfo::default().initial_data(data),
                None,
            )
        };
        // A payload the driver rejects despite a matching header is dropped, not fatal.
        let pipeline_cache = create_cache(&initial).or_else(|_| create_cache(&[]))?;

        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device,
            debug_settings: Default::default(),
            buffer_device_address: true,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| anyhow!("gpu-allocator: {e}"))?;

        let command_pool = device.create_command_pool(
            &vk::CommandPoolCreateInfo::default()
                .queue_family_index(queue_family)
                .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
            None,
        )?;

        Ok(Self {
            push_descriptor: khr::push_descriptor::Device::new(&instance, &device),
            debug_utils: debug_available.then(|| ext::debug_utils::Device::new(&instance, &device)),
            mesh_shader: (has_mesh && mesh_q.mesh_shader != 0)
                .then(|| ext::mesh_shader::Device::new(&instance, &device)),
            swapchain_ext: has_swapchain.then(|| khr::swapchain::Device::new(&instance, &device)),
            calibrated_timestamps: has_calibration
                .then(|| ext::calibrated_timestamps::Device::new(&instance, &device)),
            pipeline_cache,
            pipeline_cache_path,
            entry,
            instance,
            physical_device,
            device,
            queue,
            queue_family,
            caps,
            allocator: Mutex::new(Some(allocator)),
            messenger,
            counters,
            validation: options.validation,
            command_pool,
        })
    }

    /// Number of validation errors reported so far.
    pub fn validation_errors(&self) -> u32 {
        self.counters.errors.load(Ordering::SeqCst)
    }

    /// The first validation error messages (at most 8).
    pub fn first_validation_errors(&self) -> Vec<String> {
        self.counters
            .first_errors
            .lock()
            .map(|v| v.clone())
            .unwrap_or_default()
    }

    /// Allocates a primary command buffer from the context's pool.
    pub fn allocate_command_buffer(&self) -> Result<vk::CommandBuffer> {
        let info = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: the pool belongs to this device and is externally synchronized by &self use
        // from one thread (the renderer is single-threaded).
        Ok(unsafe { self.device.allocate_command_buffers(&info)? }[0])
    }

    /// Frees a command buffer allocated by `allocate_command_buffer`.
    pub fn free_command_buffer(&self, cmd: vk::CommandBuffer) {
        // SAFETY: `cmd` came from this pool and is not pending (callers wait on its fence).
        unsafe { self.device.free_command_buffers(self.command_pool, &[cmd]) };
    }

    /// Records `record` into a one-shot command buffer, submits it and waits (setup work such
    /// as uploads; frames go through `FrameRing`).
    pub fn one_shot(&self, record: impl FnOnce(vk::CommandBuffer)) -> Result<()> {
        let cmd = self.allocate_command_buffer()?;
        // SAFETY: plain fence creation; destroyed below.
        let fence = unsafe {
            self.device
                .create_fence(&vk::FenceCreateInfo::default(), None)
        };
        let result = fence.map_err(anyhow::Error::from).and_then(|fence| {
            // SAFETY: a fresh command buffer, recorded and submitted once, waited on before the
            // fence is destroyed and the buffer freed; one-shot work runs on the thread that
            // renders, which keeps the queue externally synchronized.
            let done = unsafe {
                self.device
                    .begin_command_buffer(
                        cmd,
                        &vk::CommandBufferBeginInfo::default()
                            .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
                    )
                    .and_then(|_| {
                        record(cmd);
                        self.device.end_command_buffer(cmd)
                    })
                    .and_then(|_| {
                        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(cmd)];
                        let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
                        self.device.queue_submit2(self.queue, &submit, fence)
                    })
                    .and_then(|_| self.device.wait_for_fences(&[fence], true, u64::MAX))
                    .context("one-shot submission failed (device lost?)")
            };
            // SAFETY: the submission (if any) has completed.
            unsafe { self.device.destroy_fence(fence, None) };
            done
        });
        self.free_command_buffer(cmd);
        result
    }

    /// Opens a debug label region on `cmd` (visible in RenderDoc/Nsight) when debug utils exist.
    pub fn begin_label(&self, cmd: vk::CommandBuffer, name: &CStr) {
        if let Some(du) = &self.debug_utils {
            let label = vk::DebugUtilsLabelEXT::default().label_name(name);
            // SAFETY: cmd is in the recording state.
            unsafe { du.cmd_begin_debug_utils_label(cmd, &label) };
        }
    }

    /// Names `object` in captures and validation messages (RenderDoc, Nsight) when debug
    /// utils exist; a name with a NUL byte is cut there.
    /// The device's timestamp clock and the host's monotonic clock ([`monotonic_ms`]) read at
    /// one moment, both in milliseconds (the device's as the profiler converts its ticks);
    /// `None` where the device cannot calibrate them.
    pub fn calibrate(&self) -> Option<(f64, f64)> {
        let loader = self.calibrated_timestamps.as_ref()?;
        let info = [
            vk::CalibratedTimestampInfoEXT::default().time_domain(vk::TimeDomainEXT::DEVICE),
            vk::CalibratedTimestampInfoEXT::default()
                .time_domain(vk::TimeDomainEXT::CLOCK_MONOTONIC),
        ];
        // SAFETY: both domains were reported calibrateable when the extension was enabled.
        let (stamps, _) = unsafe { loader.get_calibrated_timestamps(&info) }.ok()?;
        let period = f64::from(self.caps.timestamp_period);
        Some((stamps[0] as f64 * period / 1.0e6, stamps[1] as f64 / 1.0e6))
    }

    pub fn name_object<H: vk::Handle>(&self, object: H, name: &str) {
        let Some(du) = &self.debug_utils else {
            return;
        };
        let name = name.split('\0').next().unwrap_or_default();
        let Ok(name) = std::ffi::CString::new(name) else {
            return;
        };
        let info = vk::DebugUtilsObjectNameInfoEXT::default()
            .object_handle(object)
            .object_name(&name);
        // SAFETY: `object` is a live handle of this device; naming has no other effect.
        // A failure to name is not an error of the program: the object stays unnamed.
        let _ = unsafe { du.set_debug_utils_object_name(&info) };
    }

    /// Closes the region opened by `begin_label`.
    pub fn end_label(&self, cmd: vk::CommandBuffer) {
        if let Some(du) = &self.debug_utils {
            // SAFETY: matches a begin_label on the same command buffer.
            unsafe { du.cmd_end_debug_utils_label(cmd) };
        }
    }

    /// Runs `f` with the allocator.
    pub fn with_allocator<T>(&self, f: impl FnOnce(&mut Allocator) -> Result<T>) -> Result<T> {
        let mut guard = self
            .allocator
            .lock()
            .map_err(|_| anyhow!("allocator lock poisoned"))?;
        let allocator = guard
            .as_mut()
            .ok_or_else(|| anyhow!("allocator destroyed"))?;
        f(allocator)
    }
}

impl Drop for Context {
    fn drop(&mut self) {
        // SAFETY: the owner dropped every resource made from this context before it (resources
        // hold an Arc<Context>), so destroying the device and instance here is valid.
        unsafe {
            let _ = self.device.device_wait_idle();
            if let Some(path) = &self.pipeline_cache_path {
                if let Ok(data) = self.device.get_pipeline_cache_data(self.pipeline_cache) {
                    if let Err(e) = pipeline_cache::save(path, &data) {
                        eprintln!(
                            "warning: cannot save the pipeline cache {}: {e}",
                            path.display()
                        );
                    }
                }
            }
            self.device
                .destroy_pipeline_cache(self.pipeline_cache, None);
            self.device.destroy_command_pool(self.command_pool, None);
            if let Ok(mut guard) = self.allocator.lock() {
                guard.take();
            }
            self.device.destroy_device(None);
            if let Some((loader, messenger)) = self.messenger.take() {
                loader.destroy_debug_utils_messenger(messenger, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

/// Picks the best physical device: discrete > integrated > virtual > CPU; `SURFEL_DEVICE`
/// (a substring of the device name) overrides.
unsafe fn pick_device(instance: &ash::Instance) -> Result<(vk::PhysicalDevice, u32)> {
    let wanted = std::env::var("SURFEL_DEVICE").ok();
    let mut best: Option<(u32, vk::PhysicalDevice, u32)> = None;
    for pd in instance.enumerate_physical_devices()? {
        let props = instance.get_physical_device_properties(pd);
        if props.api_version < vk::API_VERSION_1_3 {
            continue;
        }
        let name = props
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        if let Some(w) = &wanted {
            if !name.contains(w.as_str()) {
                continue;
            }
        }
        let families = instance.get_physical_device_queue_family_properties(pd);
        let Some(family) = families.iter().position(|f| {
            f.queue_flags
                .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
                && f.timestamp_valid_bits > 0
        }) else {
            continue;
        };
        let score = match props.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => 4,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 3,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            _ => 1,
        };
        if best.is_none_or(|(s, _, _)| score > s) {
            best = Some((score, pd, family as u32));
        }
    }
    best.map(|(_, pd, fam)| (pd, fam)).ok_or_else(|| {
        anyhow!("no Vulkan 1.3 device with a graphics+compute queue and timestamps was found")
    })
}

unsafe fn capabilities(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
    family: u32,
    core: &vk::PhysicalDeviceFeatures,
    v11: &vk::PhysicalDeviceVulkan11Features<'_>,
    v12: &vk::PhysicalDeviceVulkan12Features<'_>,
    mesh: Option<&vk::PhysicalDeviceMeshShaderFeaturesEXT<'_>>,
) -> Capabilities {
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut mesh_props = vk::PhysicalDeviceMeshShaderPropertiesEXT::default();
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default()
        .push_next(&mut driver)
        .push_next(&mut subgroup);
    if mesh.is_some() {
        props2 = props2.push_next(&mut mesh_props);
    }
    instance.get_physical_device_properties2(pd, &mut props2);
    let props = props2.properties;
    let families = instance.get_physical_device_queue_family_properties(pd);
    let limits = props.limits;
    let v = props.api_version;
    Capabilities {
        device_name: props
            .device_name_as_c_str()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        driver: format!(
            "{} {}",
            driver
                .driver_name_as_c_str()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
            driver
                .driver_info_as_c_str()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default()
        ),
        api_version: format!(
            "{}.{}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v),
            vk::api_version_patch(v)
        ),
        device_type: format!("{:?}", props.device_type),
        geometry_shader: core.geometry_shader != 0,
        geometry_points: core.geometry_shader != 0
            && core.shader_tessellation_and_geometry_point_size != 0
            && core.vertex_pipeline_stores_and_atomics != 0,
        mesh_shader: mesh.is_some_and(|m| m.mesh_shader != 0),
        task_shader: mesh.is_some_and(|m| m.task_shader != 0),
        buffer_int64_atomics: v12.shader_buffer_int64_atomics != 0 && core.shader_int64 != 0,
        float64: core.shader_float64 != 0,
        multi_draw_indirect: core.multi_draw_indirect != 0,
        pipeline_statistics: core.pipeline_statistics_query != 0,
        draw_indirect_count: v12.draw_indirect_count != 0,
        shader_draw_parameters: v11.shader_draw_parameters != 0,
        large_points: core.large_points != 0,
        point_size_range: limits.point_size_range,
        timestamps: families[family as usize].timestamp_valid_bits > 0,
        timestamp_period: limits.timestamp_period,
        max_image_dimension_2d: limits.max_image_dimension2_d,
        max_color_attachments: limits.max_color_attachments,
        max_compute_workgroup_invocations: limits.max_compute_work_group_invocations,
        max_compute_shared_memory: limits.max_compute_shared_memory_size,
        max_storage_buffer_range: limits.max_storage_buffer_range,
        subgroup_size: subgroup.subgroup_size,
        subgroup_ballot_compute: subgroup
            .supported_stages
            .contains(vk::ShaderStageFlags::COMPUTE)
            && subgroup
                .supported_operations
                .contains(vk::SubgroupFeatureFlags::BALLOT),
        max_mesh_output_vertices: if mesh.is_some() {
            mesh_props.max_mesh_output_vertices
        } else {
            0
        },
        max_geometry_output_vertices: limits.max_geometry_output_vertices,
        max_geometry_shader_invocations: limits.max_geometry_shader_invocations,
        max_geometry_total_output_components: limits.max_geometry_total_output_components,
    }
}

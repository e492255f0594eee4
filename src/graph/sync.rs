//! Barrier derivation: from the accesses passes declare to synchronization2 barriers and image
//! layout transitions. Pure CPU logic, unit-tested without a device.

use ash::vk;

/// How a pass uses a resource.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Color attachment (written; read too when loaded).
    ColorAttachment,
    /// Depth attachment, tested and written.
    DepthAttachment,
    /// Sampled image read in `stages`.
    Sampled(Stages),
    /// Storage image/buffer read.
    StorageRead(Stages),
    /// Storage image/buffer written without being read. Earlier contents count as dead (the
    /// producer may be culled): declare `StorageReadWrite` for partial updates.
    StorageWrite(Stages),
    /// Storage image/buffer read and written (atomics, in-place updates).
    StorageReadWrite(Stages),
    /// Uniform/storage buffer read by shaders as per-frame constants.
    UniformRead(Stages),
    /// Index buffer of an indexed draw.
    IndexRead,
    /// Indirect draw/dispatch arguments.
    IndirectRead,
    TransferSrc,
    TransferDst,
    /// Host reads after the frame's fence (readback buffers).
    HostRead,
    /// Handed to the presentation engine.
    Present,
}

/// Shader stages a shader access happens in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stages {
    Vertex,
    Fragment,
    Compute,
    /// Task and mesh shaders.
    Mesh,
    /// Vertex, task, mesh, geometry and fragment (a whole graphics pipeline), limited to the
    /// stages the device supports.
    Graphics,
}

/// Optional shader stages the device has enabled; stage masks only name supported stages
/// (the validation layers reject e.g. `MESH_SHADER_EXT` without the mesh-shader feature).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct StageSupport {
    pub geometry: bool,
    pub task: bool,
    pub mesh: bool,
}

impl StageSupport {
    /// Every optional stage (the default for device-free derivation).
    pub const ALL: StageSupport = StageSupport {
        geometry: true,
        task: true,
        mesh: true,
    };
}

impl Default for StageSupport {
    fn default() -> Self {
        Self::ALL
    }
}

impl Stages {
    fn flags(self, support: StageSupport) -> vk::PipelineStageFlags2 {
        use vk::PipelineStageFlags2 as S;
        let optional = |on: bool, stage: S| if on { stage } else { S::NONE };
        let mesh =
            optional(support.task, S::TASK_SHADER_EXT) | optional(support.mesh, S::MESH_SHADER_EXT);
        match self {
            Stages::Vertex => S::VERTEX_SHADER,
            Stages::Fragment => S::FRAGMENT_SHADER,
            Stages::Compute => S::COMPUTE_SHADER,
            Stages::Mesh => mesh,
            Stages::Graphics => {
                S::VERTEX_SHADER
                    | optional(support.geometry, S::GEOMETRY_SHADER)
                    | mesh
                    | S::FRAGMENT_SHADER
            }
        }
    }
}

/// Stage, access and layout of an access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AccessInfo {
    pub stages: vk::PipelineStageFlags2,
    pub access: vk::AccessFlags2,
    /// Image layout (ignored for buffers).
    pub layout: vk::ImageLayout,
    pub writes: bool,
}

impl AccessInfo {
    /// One state for several accesses of a pass to the same subresource: the union of stages
    /// and accesses, writing if any writes. `None` when two image accesses need different
    /// layouts (`is_image`); buffers ignore layouts.
    pub fn merge(self, other: AccessInfo, is_image: bool) -> Option<AccessInfo> {
        if is_image && self.layout != other.layout {
            return None;
        }
        Some(AccessInfo {
            stages: self.stages | other.stages,
            access: self.access | other.access,
            layout: self.layout,
            writes: self.writes || other.writes,
        })
    }
}

impl Access {
    /// Stage/access/layout of this access with every optional stage supported.
    pub fn info(self) -> AccessInfo {
        self.info_for(StageSupport::ALL)
    }

    /// Stage/access/layout of this access on a device with `support`.
    pub fn info_for(self, support: StageSupport) -> AccessInfo {
        use vk::AccessFlags2 as A;
        use vk::ImageLayout as L;
        use vk::PipelineStageFlags2 as S;
        let (stages, access, layout, writes) = match self {
            Access::ColorAttachment => (
                S::COLOR_ATTACHMENT_OUTPUT,
                A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE,
                L::COLOR_ATTACHMENT_OPTIMAL,
                true,
            ),
            Access::DepthAttachment => (
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
                L::DEPTH_ATTACHMENT_OPTIMAL,
                true,
            ),
            Access::Sampled(s) => (
                s.flags(support),
                A::SHADER_SAMPLED_READ,
                L::SHADER_READ_ONLY_OPTIMAL,
                false,
            ),
            Access::StorageRead(s) => (s.flags(support), A::SHADER_STORAGE_READ, L::GENERAL, false),
            Access::StorageWrite(s) => {
                (s.flags(support), A::SHADER_STORAGE_WRITE, L::GENERAL, true)
            }
            Access::StorageReadWrite(s) => (
                s.flags(support),
                A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE,
                L::GENERAL,
                true,
            ),
            Access::UniformRead(s) => (
                s.flags(support),
                A::SHADER_STORAGE_READ | A::UNIFORM_READ,
                L::UNDEFINED,
                false,
            ),
            Access::IndexRead => (S::INDEX_INPUT, A::INDEX_READ, L::UNDEFINED, false),
            Access::IndirectRead => (
                S::DRAW_INDIRECT,
                A::INDIRECT_COMMAND_READ,
                L::UNDEFINED,
                false,
            ),
            Access::TransferSrc => (
                S::ALL_TRANSFER,
                A::TRANSFER_READ,
                L::TRANSFER_SRC_OPTIMAL,
                false,
            ),
            Access::TransferDst => (
                S::ALL_TRANSFER,
                A::TRANSFER_WRITE,
                L::TRANSFER_DST_OPTIMAL,
                true,
            ),
            Access::HostRead => (S::HOST, A::HOST_READ, L::GENERAL, false),
            Access::Present => (S::NONE, A::NONE, L::PRESENT_SRC_KHR, false),
        };
        AccessInfo {
            stages,
            access,
            layout,
            writes,
        }
    }

    /// Whether this access can apply to images (`Some(true)`), buffers (`Some(false)`) or both
    /// (`None`).
    pub fn on_image(self) -> Option<bool> {
        match self {
            Access::ColorAttachment
            | Access::DepthAttachment
            | Access::Sampled(_)
            | Access::Present => Some(true),
            Access::UniformRead(_)
            | Access::IndexRead
            | Access::IndirectRead
            | Access::HostRead => Some(false),
            Access::StorageRead(_)
            | Access::StorageWrite(_)
            | Access::StorageReadWrite(_)
            | Access::TransferSrc
            | Access::TransferDst => None,
        }
    }

    /// The image usage this access needs.
    pub fn image_usage(self) -> vk::ImageUsageFlags {
        use vk::ImageUsageFlags as U;
        match self {
            Access::ColorAttachment => U::COLOR_ATTACHMENT,
            Access::DepthAttachment => U::DEPTH_STENCIL_ATTACHMENT,
            Access::Sampled(_) => U::SAMPLED,
            Access::StorageRead(_) | Access::StorageWrite(_) | Access::StorageReadWrite(_) => {
                U::STORAGE
            }
            Access::TransferSrc => U::TRANSFER_SRC,
            Access::TransferDst => U::TRANSFER_DST,
            _ => U::empty(),
        }
    }

    /// The buffer usages this access can work with (any one of them suffices; a buffer the
    /// graph allocates gets all of them).
    pub fn buffer_usage(self) -> vk::BufferUsageFlags {
        use vk::BufferUsageFlags as U;
        match self {
            Access::StorageRead(_) | Access::StorageWrite(_) | Access::StorageReadWrite(_) => {
                U::STORAGE_BUFFER
            }
            Access::UniformRead(_) => U::UNIFORM_BUFFER | U::STORAGE_BUFFER,
            Access::IndexRead => U::INDEX_BUFFER,
            Access::IndirectRead => U::INDIRECT_BUFFER,
            Access::TransferSrc => U::TRANSFER_SRC,
            Access::TransferDst => U::TRANSFER_DST,
            _ => U::empty(),
        }
    }
}

/// What happened to one subresource (an image mip level or a buffer range) so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SubState {
    pub layout: vk::ImageLayout,
    /// Stages and accesses of the last write (empty if none yet).
    pub write_stages: vk::PipelineStageFlags2,
    pub write_access: vk::AccessFlags2,
    /// The last write may not have been read yet: a later write waits on it too.
    pub unread: bool,
    /// Stages that read since the last write (for write-after-read hazards).
    pub read_stages: vk::PipelineStageFlags2,
    /// Stages/accesses the last write has already been made visible to.
    pub visible_stages: vk::PipelineStageFlags2,
    pub visible_access: vk::AccessFlags2,
}

impl SubState {
    /// Nothing known: contents undefined.
    pub const UNDEFINED: SubState = SubState {
        layout: vk::ImageLayout::UNDEFINED,
        write_stages: vk::PipelineStageFlags2::NONE,
        write_access: vk::AccessFlags2::NONE,
        unread: false,
        read_stages: vk::PipelineStageFlags2::NONE,
        visible_stages: vk::PipelineStageFlags2::NONE,
        visible_access: vk::AccessFlags2::NONE,
    };

    /// The state after a use by `access` whose completion nothing has waited on yet (an
    /// imported resource's initial state).
    pub fn after(access: AccessInfo, is_image: bool) -> SubState {
        let mut state = SubState::UNDEFINED;
        apply_info(&mut state, access, is_image);
        state
    }

    /// A state that covers both `self` and `other` (a frame that may or may not have run
    /// its on-demand passes): waits on every stage either waits on, counts as visible only
    /// what both made visible. Layouts must agree or the result is UNDEFINED (contents lost).
    pub fn merge(self, other: SubState) -> SubState {
        SubState {
            layout: if self.layout == other.layout {
                self.layout
            } else {
                vk::ImageLayout::UNDEFINED
            },
            write_stages: self.write_stages | other.write_stages,
            write_access: self.write_access | other.write_access,
            unread: self.unread || other.unread,
            read_stages: self.read_stages | other.read_stages,
            visible_stages: self.visible_stages & other.visible_stages,
            visible_access: self.visible_access & other.visible_access,
        }
    }
}

/// One derived barrier for a subresource.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition {
    pub src_stages: vk::PipelineStageFlags2,
    pub src_access: vk::AccessFlags2,
    pub dst_stages: vk::PipelineStageFlags2,
    pub dst_access: vk::AccessFlags2,
    pub old_layout: vk::ImageLayout,
    pub new_layout: vk::ImageLayout,
}

/// Applies `access` to a subresource in `state`; returns the barrier needed before it, if any.
/// `is_image` decides whether layouts matter.
pub fn apply(state: &mut SubState, access: Access, is_image: bool) -> Option<Transition> {
    apply_info(state, access.info(), is_image)
}

/// `apply` for a resolved (possibly merged) access.
pub fn apply_info(state: &mut SubState, info: AccessInfo, is_image: bool) -> Option<Transition> {
    let new_layout = if is_image {
        info.layout
    } else {
        vk::ImageLayout::UNDEFINED
    };
    let layout_change = is_image && state.layout != new_layout;
    let mut barrier = None;
    if info.writes || layout_change {
        // Write-after-read / layout transition: wait for the reads since the last write; they
        // were themselves ordered after that write (and it was made available then), so the
        // execution dependency chains. A write nothing read yet is waited on itself (WAW).
        let (src_stages, src_access) = if state.unread || state.read_stages.is_empty() {
            (state.read_stages | state.write_stages, state.write_access)
        } else {
            (state.read_stages, vk::AccessFlags2::NONE)
        };
        if layout_change || !src_stages.is_empty() {
            barrier = Some(Transition {
                src_stages,
                src_access,
                dst_stages: info.stages,
                dst_access: info.access,
                old_layout: state.layout,
                new_layout: if is_image {
                    new_layout
                } else {
                    vk::ImageLayout::UNDEFINED
                },
            });
        }
        if info.writes {
            state.write_stages = info.stages;
            state.write_access = info.access;
            state.unread = true;
            state.read_stages = vk::PipelineStageFlags2::NONE;
            state.visible_stages = vk::PipelineStageFlags2::NONE;
            state.visible_access = vk::AccessFlags2::NONE;
        } else {
            // A transition to a read layout makes the earlier write visible to this read.
            state.unread = false;
            state.read_stages = info.stages;
            state.visible_stages = info.stages;
            state.visible_access = info.access;
        }
        state.layout = new_layout;
        return barrier;
    }
    // Read after write in the same layout: make the write visible unless already done.
    let missing_stages = info.stages & !state.visible_stages;
    let missing_access = info.access & !state.visible_access;
    if !state.write_stages.is_empty() && (!missing_stages.is_empty() || !missing_access.is_empty())
    {
        barrier = Some(Transition {
            src_stages: state.write_stages,
            src_access: state.write_access,
            dst_stages: info.stages,
            dst_access: info.access,
            old_layout: state.layout,
            new_layout: state.layout,
        });
        state.visible_stages |= info.stages;
        state.visible_access |= info.access;
    }
    state.read_stages |= info.stages;
    state.unread = false;
    barrier
}

#[cfg(test)]
mod tests {
    use super::*;
    use vk::PipelineStageFlags2 as S;

    #[test]
    fn first_color_write_transitions_from_undefined_without_waiting() {
        let mut s = SubState::UNDEFINED;
        let t = apply(&mut s, Access::ColorAttachment, true).expect("layout transition");
        assert_eq!(t.old_layout, vk::ImageLayout::UNDEFINED);
        assert_eq!(t.new_layout, vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL);
        assert_eq!(t.src_stages, S::NONE);
    }

    #[test]
    fn sampling_after_color_write_waits_for_attachment_output() {
        let mut s = SubState::UNDEFINED;
        apply(&mut s, Access::ColorAttachment, true);
        let t = apply(&mut s, Access::Sampled(Stages::Fragment), true).expect("barrier");
        assert_eq!(t.src_stages, S::COLOR_ATTACHMENT_OUTPUT);
        assert_eq!(t.dst_stages, S::FRAGMENT_SHADER);
        assert_eq!(t.new_layout, vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL);
        // A second read by the same stage needs nothing more.
        assert_eq!(apply(&mut s, Access::Sampled(Stages::Fragment), true), None);
        // A later write must wait for the readers (write-after-read).
        let w = apply(&mut s, Access::StorageWrite(Stages::Compute), true).expect("WAR");
        assert_eq!(w.src_stages, S::FRAGMENT_SHADER);
        assert_eq!(w.src_access, vk::AccessFlags2::NONE);
    }

    #[test]
    fn stage_masks_follow_the_supported_stages() {
        let none = StageSupport {
            geometry: false,
            task: false,
            mesh: false,
        };
        let mesh_read = Access::StorageRead(Stages::Mesh);
        assert_eq!(
            mesh_read.info().stages,
            S::TASK_SHADER_EXT | S::MESH_SHADER_EXT
        );
        assert_eq!(
            mesh_read
                .info_for(StageSupport {
                    task: false,
                    ..StageSupport::ALL
                })
                .stages,
            S::MESH_SHADER_EXT
        );
        assert_eq!(
            Access::Sampled(Stages::Graphics).info_for(none).stages,
            S::VERTEX_SHADER | S::FRAGMENT_SHADER
        );
    }

    #[test]
    fn merged_accesses_union_stages_and_reject_two_layouts() {
        let indirect = Access::IndirectRead.info();
        let storage = Access::StorageWrite(Stages::Compute).info();
        let both = indirect
            .merge(storage, false)
            .expect("buffers ignore layouts");
        assert_eq!(both.stages, S::DRAW_INDIRECT | S::COMPUTE_SHADER);
        assert!(both.writes);
        let sampled = Access::Sampled(Stages::Fragment).info();
        assert_eq!(sampled.merge(storage, true), None);
        assert_eq!(
            storage
                .merge(Access::StorageRead(Stages::Fragment).info(), true)
                .map(|m| m.layout),
            Some(vk::ImageLayout::GENERAL)
        );
    }

    #[test]
    fn a_merged_frame_end_waits_on_both_variants() {
        // Variant A: a compute write nothing read. Variant B: a transfer write the host read.
        let mut a = SubState::UNDEFINED;
        apply(&mut a, Access::StorageWrite(Stages::Compute), false);
        let mut b = a;
        apply(&mut b, Access::TransferDst, false);
        apply(&mut b, Access::HostRead, false);
        let mut merged = a.merge(b);
        let t = apply(&mut merged, Access::StorageWrite(Stages::Compute), false).expect("WAW");
        assert_eq!(t.src_stages, S::COMPUTE_SHADER | S::ALL_TRANSFER | S::HOST);
        assert_eq!(
            t.src_access,
            vk::AccessFlags2::SHADER_STORAGE_WRITE | vk::AccessFlags2::TRANSFER_WRITE
        );
    }

    #[test]
    fn buffer_read_after_read_needs_no_barrier_and_ignores_layouts() {
        let mut s = SubState::UNDEFINED;
        assert_eq!(
            apply(&mut s, Access::StorageRead(Stages::Vertex), false),
            None
        );
        assert_eq!(
            apply(&mut s, Access::StorageRead(Stages::Compute), false),
            None
        );
        let t = apply(&mut s, Access::StorageWrite(Stages::Compute), false).expect("WAR");
        assert_eq!(t.src_stages, S::VERTEX_SHADER | S::COMPUTE_SHADER);
        assert_eq!(t.src_access, vk::AccessFlags2::NONE);
        assert_eq!(t.old_layout, vk::ImageLayout::UNDEFINED);
        let r = apply(&mut s, Access::IndirectRead, false).expect("RAW");
        assert_eq!(r.src_access, vk::AccessFlags2::SHADER_STORAGE_WRITE);
        assert_eq!(r.dst_access, vk::AccessFlags2::INDIRECT_COMMAND_READ);
    }
}

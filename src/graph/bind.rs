//! Shader bindings declared once. A [`Bind`] names the binding number, the graph resource and
//! the pass's access to it; from one list of them come the pipeline layout entries
//! ([`layout`]), the pass's accesses ([`PassBuilder::binds`](super::PassBuilder::binds)) and
//! the descriptors pushed when it records ([`PassContext::bind_all`](super::PassContext::bind_all)).
//! [`GraphBuilder::compute`](super::GraphBuilder::compute) and
//! [`GraphBuilder::draw`](super::GraphBuilder::draw) do all three from one expression
//! (`graph::pass`).

use ash::vk;

use super::{Access, BufferId, BufferRange, Descriptor, ImageId, Sampler, Stages};
use crate::gpu::Binding;

/// Bytes of the placeholder buffer a pass binds where a shader variant statically references a
/// binding it never uses.
pub const UNUSED_BYTES: u64 = 256;

pub use crate::layout::MAX_GROUPS;

/// The `(x, y)` group counts covering `groups` workgroups: one row up to `MAX_GROUPS`, then
/// rows of `MAX_GROUPS`. Shaders recover the flat index as `x + y * gl_NumWorkGroups.x` and
/// skip indices past their count; at least one group is dispatched.
pub fn fold_groups(groups: u64) -> (u32, u32) {
    let groups = groups.max(1);
    let max = u64::from(MAX_GROUPS);
    let rows = groups.div_ceil(max);
    assert!(
        rows <= max,
        "{groups} workgroups exceed {MAX_GROUPS}² (fold them in the shader)"
    );
    (groups.min(max) as u32, rows as u32)
}

/// The `(x, y)` group counts covering `threads` invocations in groups of `group_size`.
pub fn fold_threads(threads: u64, group_size: u32) -> (u32, u32) {
    fold_groups(threads.div_ceil(u64::from(group_size)))
}

/// What a binding binds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resource {
    /// A storage buffer, or bytes of it.
    Buffer(BufferId, BufferRange),
    /// A uniform buffer (`UNIFORM_BUFFER`).
    Uniform(BufferId),
    /// A storage image at one mip level.
    StorageImage(ImageId, u32),
    /// A combined image sampler over mip levels `base..base + count`.
    Sampled {
        image: ImageId,
        base: u32,
        count: u32,
        sampler: Sampler,
    },
    /// A storage buffer the shader variant never reaches (dead code under its specialization,
    /// but statically present): the pass's graph-owned placeholder.
    Unused,
}

/// One binding of a pass: number, resource, access.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Bind {
    pub binding: u32,
    pub resource: Resource,
    pub access: Access,
}

impl Bind {
    /// A whole storage buffer with `access`.
    pub fn buffer(binding: u32, buffer: BufferId, access: Access) -> Self {
        Self::range(binding, buffer, BufferRange::WHOLE, access)
    }

    /// Bytes `range` of a storage buffer with `access`.
    pub fn range(binding: u32, buffer: BufferId, range: BufferRange, access: Access) -> Self {
        Self {
            binding,
            resource: Resource::Buffer(buffer, range),
            access,
        }
    }

    /// A storage buffer compute shaders read.
    pub fn reads(binding: u32, buffer: BufferId) -> Self {
        Self::buffer(binding, buffer, Access::StorageRead(Stages::Compute))
    }

    /// A storage buffer compute shaders write without reading.
    pub fn writes(binding: u32, buffer: BufferId) -> Self {
        Self::buffer(binding, buffer, Access::StorageWrite(Stages::Compute))
    }

    /// A storage buffer compute shaders read and write (atomics, in-place updates).
    pub fn updates(binding: u32, buffer: BufferId) -> Self {
        Self::buffer(binding, buffer, Access::StorageReadWrite(Stages::Compute))
    }

    /// Per-frame constants compute shaders read from a storage buffer (the frame block).
    pub fn constants(binding: u32, buffer: BufferId) -> Self {
        Self::buffer(binding, buffer, Access::UniformRead(Stages::Compute))
    }

    /// A uniform buffer read in `stages`.
    pub fn uniform(binding: u32, buffer: BufferId, stages: Stages) -> Self {
        Self {
            binding,
            resource: Resource::Uniform(buffer),
            access: Access::UniformRead(stages),
        }
    }

    /// A storage image at `mip` with `access`.
    pub fn image(binding: u32, image: ImageId, mip: u32, access: Access) -> Self {
        Self {
            binding,
            resource: Resource::StorageImage(image, mip),
            access,
        }
    }

    /// A combined image sampler of one mip level, nearest filtering, sampled in `stages`.
    pub fn sampled(binding: u32, image: ImageId, mip: u32, stages: Stages) -> Self {
        Self::sampled_mips(binding, image, (mip, 1), Sampler::Nearest, stages)
    }

    /// A combined image sampler of mip levels `base..base + count` with `sampler`.
    pub fn sampled_mips(
        binding: u32,
        image: ImageId,
        (base, count): (u32, u32),
        sampler: Sampler,
        stages: Stages,
    ) -> Self {
        Self {
            binding,
            resource: Resource::Sampled {
                image,
                base,
                count,
                sampler,
            },
            access: Access::Sampled(stages),
        }
    }

    /// A storage-buffer binding the shader variant never reaches, in compute.
    pub fn unused(binding: u32) -> Self {
        Self::unused_in(binding, Stages::Compute)
    }

    /// A storage-buffer binding the shader variant never reaches, in `stages`. Validation
    /// counts the stores a shader holds even where they are dead, so the placeholder is
    /// declared read and written; each pass has its own.
    pub fn unused_in(binding: u32, stages: Stages) -> Self {
        Self {
            binding,
            resource: Resource::Unused,
            access: Access::StorageReadWrite(stages),
        }
    }

    /// The descriptor type of the binding.
    pub fn descriptor_type(&self) -> vk::DescriptorType {
        match self.resource {
            Resource::Buffer(..) | Resource::Unused => vk::DescriptorType::STORAGE_BUFFER,
            Resource::Uniform(_) => vk::DescriptorType::UNIFORM_BUFFER,
            Resource::StorageImage(..) => vk::DescriptorType::STORAGE_IMAGE,
            Resource::Sampled { .. } => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
        }
    }

    /// The descriptor pushed for this binding; `unused` is the pass's placeholder buffer.
    pub fn descriptor(&self, unused: BufferId) -> Descriptor {
        let binding = self.binding;
        match self.resource {
            Resource::Buffer(id, range) if range == BufferRange::WHOLE => {
                Descriptor::Buffer(binding, id)
            }
            Resource::Buffer(id, range) => Descriptor::BufferRange(binding, id, range),
            Resource::Uniform(id) => Descriptor::Uniform(binding, id),
            Resource::StorageImage(id, mip) => Descriptor::StorageImage(binding, id, mip),
            Resource::Sampled {
                image,
                base,
                count,
                sampler,
            } => Descriptor::SampledMips {
                binding,
                image,
                base,
                count,
                sampler,
            },
            Resource::Unused => Descriptor::Buffer(binding, unused),
        }
    }
}

/// The pipeline layout entries of `binds`, every one visible to `stages`; a binding listed
/// twice (passes of one pipeline differing in resources) appears once.
pub fn layout(binds: &[Bind], stages: vk::ShaderStageFlags) -> Vec<Binding> {
    let mut entries: Vec<Binding> = Vec::with_capacity(binds.len());
    for b in binds {
        let entry = Binding::new(b.binding, b.descriptor_type(), stages);
        match entries.iter().find(|e| e.binding == b.binding) {
            Some(e) => assert_eq!(
                e.ty, entry.ty,
                "binding {} declared with two descriptor types",
                b.binding
            ),
            None => entries.push(entry),
        }
    }
    entries
}

/// `layout` for a compute pipeline.
pub fn compute_layout(binds: &[Bind]) -> Vec<Binding> {
    layout(binds, vk::ShaderStageFlags::COMPUTE)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn large_dispatches_fold_into_rows_of_the_device_minimum() {
        assert_eq!(fold_groups(0), (1, 1));
        assert_eq!(fold_groups(65_535), (65_535, 1));
        assert_eq!(fold_groups(65_536), (65_535, 2));
        assert_eq!(fold_threads(256 * 70_000 + 1, 256), (65_535, 2));
        let (x, y) = fold_groups(10_000_000);
        assert!(u64::from(x) * u64::from(y) >= 10_000_000 && y == 153);
    }

    #[test]
    fn one_declaration_gives_the_layout_the_access_and_the_descriptor() {
        let (a, b) = (BufferId(0), BufferId(1));
        let image = ImageId(0);
        let binds = [
            Bind::constants(0, a),
            Bind::updates(1, b),
            Bind::image(2, image, 3, Access::StorageWrite(Stages::Compute)),
            Bind::unused(4),
            Bind::range(
                1,
                b,
                BufferRange::new(16, 32),
                Access::StorageRead(Stages::Compute),
            ),
        ];
        let entries = compute_layout(&binds);
        let types: Vec<_> = entries.iter().map(|e| (e.binding, e.ty)).collect();
        assert_eq!(
            types,
            [
                (0, vk::DescriptorType::STORAGE_BUFFER),
                (1, vk::DescriptorType::STORAGE_BUFFER),
                (2, vk::DescriptorType::STORAGE_IMAGE),
                (4, vk::DescriptorType::STORAGE_BUFFER),
            ]
        );
        let placeholder = BufferId(9);
        assert!(matches!(
            binds[3].descriptor(placeholder),
            Descriptor::Buffer(4, id) if id == placeholder
        ));
        assert!(matches!(
            binds[4].descriptor(placeholder),
            Descriptor::BufferRange(1, id, r) if id == b && r == BufferRange::new(16, 32)
        ));
        assert!(matches!(
            binds[2].descriptor(placeholder),
            Descriptor::StorageImage(2, id, 3) if id == image
        ));
    }

    #[test]
    #[should_panic(expected = "binding 1 declared with two descriptor types")]
    fn a_binding_with_two_types_is_a_programming_error() {
        compute_layout(&[
            Bind::reads(1, BufferId(0)),
            Bind::uniform(1, BufferId(0), Stages::Compute),
        ]);
    }
}

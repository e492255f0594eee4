//! Checking a `GraphBuilder`'s declarations and culling passes whose results nothing uses.
//! Pure CPU (no device needed).

use std::collections::HashSet;

use anyhow::{anyhow, bail, Result};

use super::sync::Access;
use super::{
    BufferId, BufferSource, GraphBuilder, ImageId, ImageSource, Load, Subresource,
    MAX_COLOR_ATTACHMENTS,
};

pub(crate) fn validate(builder: &GraphBuilder) -> Result<()> {
    let mut seen_on_demand = false;
    for pass in &builder.passes {
        if pass.on_demand {
            seen_on_demand = true;
        } else if seen_on_demand {
            bail!(
                "pass '{}' follows an on-demand pass; on-demand passes must come last",
                pass.name
            );
        }
        if pass.on_demand {
            // Their state must not leak into frames that skip them: only transient images
            // (discarded each frame) and buffers (no layouts) may be touched.
            for (sub, _) in &pass.uses {
                if let Subresource::Image { id, .. } = sub {
                    let res = &builder.images[id.0 as usize];
                    if !matches!(res.source, ImageSource::Transient(_)) {
                        bail!(
                            "on-demand pass '{}' uses '{}', which is not transient",
                            pass.name,
                            res.name
                        );
                    }
                }
            }
        }
        for (sub, access) in &pass.uses {
            match *sub {
                Subresource::Image { id, base, count } => {
                    let res = builder
                        .images
                        .get(id.0 as usize)
                        .ok_or_else(|| anyhow!("pass '{}': unknown image {id:?}", pass.name))?;
                    let levels = res.desc().mip_levels;
                    if count == 0 || base + count > levels {
                        bail!(
                            "pass '{}': mips {base}..{} of '{}' (has {levels})",
                            pass.name,
                            base + count,
                            res.name
                        );
                    }
                    if access.on_image() == Some(false) {
                        bail!(
                            "pass '{}': {access:?} applies to buffers, not image '{}'",
                            pass.name,
                            res.name
                        );
                    }
                    let needs = access.image_usage();
                    if let ImageSource::Imported(image) = &res.source {
                        if !image.desc.usage.contains(needs) {
                            bail!(
                                "pass '{}': imported image '{}' lacks usage {needs:?} for {access:?}",
                                pass.name,
                                res.name
                            );
                        }
                    }
                }
                Subresource::Buffer(id, range) => {
                    let res = builder
                        .buffers
                        .get(id.0 as usize)
                        .ok_or_else(|| anyhow!("pass '{}': unknown buffer {id:?}", pass.name))?;
                    if access.on_image() == Some(true) {
                        bail!(
                            "pass '{}': {access:?} applies to images, not buffer '{}'",
                            pass.name,
                            res.name
                        );
                    }
                    let size = res.size();
                    if range.size == 0 || (range.end() != u64::MAX && range.end() > size) {
                        bail!(
                            "pass '{}': range {range} of buffer '{}' (has {size} bytes)",
                            pass.name,
                            res.name
                        );
                    }
                    let needs = access.buffer_usage();
                    let owned = match &res.source {
                        BufferSource::Imported(b) => Some(b.usage),
                        BufferSource::External { usage, .. } => Some(*usage),
                        BufferSource::Transient { .. } => None,
                    };
                    if let Some(usage) = owned {
                        if !needs.is_empty() && !usage.intersects(needs) {
                            bail!(
                                "pass '{}': imported buffer '{}' lacks usage {needs:?} for {access:?}",
                                pass.name,
                                res.name
                            );
                        }
                    }
                }
            }
        }
        if pass.colors.len() > MAX_COLOR_ATTACHMENTS {
            bail!(
                "pass '{}': {} color attachments (at most {MAX_COLOR_ATTACHMENTS})",
                pass.name,
                pass.colors.len()
            );
        }
        let extents: Vec<(u32, u32)> = pass
            .colors
            .iter()
            .chain(&pass.depth)
            .map(|a| builder.desc(a.image).level_extent(a.mip))
            .collect();
        if extents.windows(2).any(|w| w[0] != w[1]) {
            bail!(
                "pass '{}': attachments differ in size {extents:?}",
                pass.name
            );
        }
    }
    Ok(())
}

impl GraphBuilder {
    /// Removes passes whose results nothing uses and returns their names. A pass is kept when
    /// it is on demand, presents or hands data to the host, writes a resource that outlives
    /// the frame (imported, history, external), is the last to use an imported image (its
    /// access sets the layout the image's owner finds), or writes something a kept pass reads
    /// (an attachment loaded with `Load::Load` is read too).
    pub fn cull(&mut self) -> Vec<String> {
        let mut last_import_use = vec![None; self.images.len()];
        for (i, pass) in self.passes.iter().enumerate() {
            for (sub, _) in &pass.uses {
                if let Subresource::Image { id, .. } = *sub {
                    if matches!(self.images[id.0 as usize].source, ImageSource::Imported(_)) {
                        last_import_use[id.0 as usize] = Some(i);
                    }
                }
            }
        }
        let persistent_image =
            |id: ImageId| !matches!(self.images[id.0 as usize].source, ImageSource::Transient(_));
        let persistent_buffer = |id: BufferId| {
            !matches!(
                self.buffers[id.0 as usize].source,
                BufferSource::Transient { .. }
            )
        };
        let mut needed: HashSet<(bool, u32, u32)> = HashSet::new();
        let key = |sub: &Subresource| -> Vec<(bool, u32, u32)> {
            match *sub {
                Subresource::Image { id, base, count } => {
                    (base..base + count).map(|m| (true, id.0, m)).collect()
                }
                Subresource::Buffer(id, _) => vec![(false, id.0, 0)],
            }
        };
        let mut live = vec![false; self.passes.len()];
        for (i, pass) in self.passes.iter().enumerate().rev() {
            let effect = pass.on_demand
                || pass.uses.is_empty()
                || last_import_use.contains(&Some(i))
                || pass.uses.iter().any(|(sub, access)| {
                    let writes = access.info().writes;
                    matches!(access, Access::Present | Access::HostRead)
                        || (writes
                            && match *sub {
                                Subresource::Image { id, .. } => persistent_image(id),
                                Subresource::Buffer(id, _) => persistent_buffer(id),
                            })
                        || (writes && key(sub).iter().any(|k| needed.contains(k)))
                });
            if !effect {
                continue;
            }
            live[i] = true;
            let loaded: Vec<(ImageId, u32)> = pass
                .colors
                .iter()
                .chain(&pass.depth)
                .filter(|a| a.load == Load::Load)
                .map(|a| (a.image, a.mip))
                .collect();
            for (sub, access) in &pass.uses {
                let attachment =
                    matches!(access, Access::ColorAttachment | Access::DepthAttachment);
                let reads = !access.info().writes
                    || matches!(access, Access::StorageReadWrite(_))
                    || (attachment
                        && matches!(*sub, Subresource::Image { id, base, .. } if loaded.contains(&(id, base))));
                if reads {
                    needed.extend(key(sub));
                }
            }
        }
        let mut culled = Vec::new();
        let mut index = 0;
        self.passes.retain(|p| {
            index += 1;
            if !live[index - 1] {
                culled.push(p.name.clone());
            }
            live[index - 1]
        });
        culled
    }
}

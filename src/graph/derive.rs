//! Barrier derivation over the whole graph: merges each pass's accesses per subresource, runs
//! the per-subresource state machine of `sync.rs` through the passes for the first frame and
//! for the steady state, and prints the schedule. Pure CPU (no device needed).
//!
//! Images are tracked per mip level. Buffers are tracked per disjoint range: the offsets at
//! which any declared range of a buffer starts or ends cut it into segments, each segment
//! has its own state, and the barriers of neighbouring segments with the same transition are
//! emitted as one barrier over their union.

use std::fmt::Write as _;

use anyhow::{bail, Result};
use ash::vk;

use super::sync::{apply_info, Access, AccessInfo, StageSupport, SubState, Transition};
use super::validate::validate;
use super::{BufferId, BufferRange, GraphBuilder, ImageId, ImageSource, Subresource};

/// A barrier on one subresource (one image mip or one buffer range), resolved to handles at
/// record time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Barrier {
    pub target: BarrierTarget,
    pub transition: Transition,
}

/// What a barrier applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BarrierTarget {
    Image { id: ImageId, mip: u32 },
    Buffer { id: BufferId, range: BufferRange },
}

/// One tracked unit: an image mip or a buffer segment (index into the buffer's segments).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Unit {
    Image(ImageId, u32),
    Buffer(BufferId, usize),
}

/// The per-frame state of every subresource: images per mip, buffers per segment.
#[derive(Clone, PartialEq)]
struct States {
    images: Vec<Vec<SubState>>,
    buffers: Vec<Vec<SubState>>,
}

impl States {
    fn get(&mut self, unit: Unit) -> &mut SubState {
        match unit {
            Unit::Image(id, mip) => &mut self.images[id.0 as usize][mip as usize],
            Unit::Buffer(id, seg) => &mut self.buffers[id.0 as usize][seg],
        }
    }

    fn merge(&self, other: &States) -> States {
        let zip = |a: &Vec<Vec<SubState>>, b: &Vec<Vec<SubState>>| {
            a.iter()
                .zip(b)
                .map(|(x, y)| x.iter().zip(y).map(|(s, t)| s.merge(*t)).collect())
                .collect()
        };
        States {
            images: zip(&self.images, &other.images),
            buffers: zip(&self.buffers, &other.buffers),
        }
    }
}

/// Resource kinds that carry their state into the next frame.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Carry {
    /// Contents discarded: the next frame starts from UNDEFINED but waits on this frame's use.
    Discard,
    /// Contents and layout kept.
    Keep,
    /// Re-acquired every frame (swapchain): UNDEFINED, ordered after the acquire semaphore.
    Acquired,
}

fn image_carry(source: &ImageSource) -> Carry {
    match source {
        ImageSource::Transient(_) => Carry::Discard,
        ImageSource::History(_) | ImageSource::Imported(_) => Carry::Keep,
        ImageSource::External(_) => Carry::Acquired,
    }
}

fn next_frame_state(s: SubState, carry: Carry) -> SubState {
    match carry {
        Carry::Keep => s,
        Carry::Discard => SubState {
            layout: vk::ImageLayout::UNDEFINED,
            ..s
        },
        Carry::Acquired => SubState {
            write_stages: vk::PipelineStageFlags2::COLOR_ATTACHMENT_OUTPUT,
            unread: true,
            ..SubState::UNDEFINED
        },
    }
}

/// Segment boundaries of every buffer: segment `i` is `cuts[i]..cuts[i + 1]` (the last one
/// ends at `u64::MAX`, i.e. the end of the buffer). Cuts lie inside the buffer.
fn buffer_cuts(builder: &GraphBuilder) -> Vec<Vec<u64>> {
    let mut cuts = vec![vec![0u64]; builder.buffers.len()];
    for pass in &builder.passes {
        for (sub, _) in &pass.uses {
            if let Subresource::Buffer(id, range) = *sub {
                let c = &mut cuts[id.0 as usize];
                c.push(range.offset);
                c.push(range.end());
            }
        }
    }
    for (c, res) in cuts.iter_mut().zip(&builder.buffers) {
        let size = res.size();
        c.retain(|&x| x < size);
        c.sort_unstable();
        c.dedup();
    }
    cuts
}

fn segments(cuts: &[u64], range: BufferRange) -> impl Iterator<Item = usize> + '_ {
    let end = range.end();
    (0..cuts.len()).filter(move |&i| cuts[i] >= range.offset && cuts[i] < end)
}

fn segment_range(cuts: &[u64], first: usize, last: usize) -> BufferRange {
    let end = cuts.get(last + 1).copied().unwrap_or(u64::MAX);
    BufferRange::span(cuts[first], end)
}

/// A pass's accesses merged per unit, in order of first appearance.
type PassUnits = Vec<(Unit, AccessInfo)>;

fn merge_pass_units(
    builder: &GraphBuilder,
    cuts: &[Vec<u64>],
    support: StageSupport,
) -> Result<Vec<PassUnits>> {
    builder
        .passes
        .iter()
        .map(|pass| {
            let mut units: PassUnits = Vec::new();
            let mut first: Vec<Access> = Vec::new();
            for (sub, access) in &pass.uses {
                let info = access.info_for(support);
                let touched: Vec<Unit> = match *sub {
                    Subresource::Image { id, base, count } => {
                        (base..base + count).map(|m| Unit::Image(id, m)).collect()
                    }
                    Subresource::Buffer(id, range) => segments(&cuts[id.0 as usize], range)
                        .map(|s| Unit::Buffer(id, s))
                        .collect(),
                };
                for unit in touched {
                    let is_image = matches!(unit, Unit::Image(..));
                    match units.iter().position(|(u, _)| *u == unit) {
                        Some(i) => match units[i].1.merge(info, is_image) {
                            Some(merged) => units[i].1 = merged,
                            None => {
                                let Unit::Image(id, mip) = unit else {
                                    unreachable!("buffers ignore layouts")
                                };
                                bail!(
                                    "pass '{}' uses mip {mip} of '{}' as {:?} ({:?}) and as {:?} \
                                     ({:?}); one pass cannot need two layouts of one subresource",
                                    pass.name,
                                    builder.images[id.0 as usize].name,
                                    first[i],
                                    units[i].1.layout,
                                    access,
                                    info.layout
                                );
                            }
                        },
                        None => {
                            units.push((unit, info));
                            first.push(*access);
                        }
                    }
                }
            }
            Ok(units)
        })
        .collect()
}

/// Barriers of `passes` from `states`, advancing `states`.
fn simulate(
    passes: &[PassUnits],
    cuts: &[Vec<u64>],
    states: &mut States,
    out: &mut Vec<Vec<Barrier>>,
) {
    for units in passes {
        let mut barriers: Vec<Barrier> = Vec::new();
        // Last emitted buffer barrier: (position in `barriers`, buffer, first and last segment).
        let mut open: Option<(usize, BufferId, usize, usize)> = None;
        for &(unit, info) in units {
            let is_image = matches!(unit, Unit::Image(..));
            let Some(transition) = apply_info(states.get(unit), info, is_image) else {
                continue;
            };
            match unit {
                Unit::Image(id, mip) => barriers.push(Barrier {
                    target: BarrierTarget::Image { id, mip },
                    transition,
                }),
                Unit::Buffer(id, seg) => {
                    let c = &cuts[id.0 as usize];
                    if let Some((at, bid, first, last)) = open {
                        if bid == id && last + 1 == seg && barriers[at].transition == transition {
                            barriers[at].target = BarrierTarget::Buffer {
                                id,
                                range: segment_range(c, first, seg),
                            };
                            open = Some((at, id, first, seg));
                            continue;
                        }
                    }
                    open = Some((barriers.len(), id, seg, seg));
                    barriers.push(Barrier {
                        target: BarrierTarget::Buffer {
                            id,
                            range: segment_range(c, seg, seg),
                        },
                        transition,
                    });
                }
            }
        }
        out.push(barriers);
    }
}

/// Per pass: barriers of the first frame and of every later frame.
pub(crate) type DerivedBarriers = Vec<(Vec<Barrier>, Vec<Barrier>)>;

/// Validates the declarations and derives barriers for a device with `support`.
pub(crate) fn derive(builder: &GraphBuilder, support: StageSupport) -> Result<DerivedBarriers> {
    validate(builder)?;
    let cuts = buffer_cuts(builder);
    let units = merge_pass_units(builder, &cuts, support)?;
    let regular = builder.passes.iter().filter(|p| !p.on_demand).count();
    let (regular_units, on_demand_units) = units.split_at(regular);
    let initial = States {
        images: builder
            .images
            .iter()
            .map(|r| {
                let init = match (image_carry(&r.source), r.initial) {
                    (Carry::Acquired, _) => next_frame_state(SubState::UNDEFINED, Carry::Acquired),
                    (_, Some(access)) => SubState::after(access.info_for(support), true),
                    _ => SubState::UNDEFINED,
                };
                vec![init; r.desc().mip_levels as usize]
            })
            .collect(),
        buffers: builder
            .buffers
            .iter()
            .zip(&cuts)
            .map(|(r, c)| {
                let init = r.initial.map_or(SubState::UNDEFINED, |a| {
                    SubState::after(a.info_for(support), false)
                });
                vec![init; c.len()]
            })
            .collect(),
    };
    // One frame: the regular passes, then the on-demand ones. The next frame starts from
    // either end (on-demand passes run only in some frames), so from their merge.
    let frame = |mut states: States| {
        let mut barriers = Vec::with_capacity(units.len());
        simulate(regular_units, &cuts, &mut states, &mut barriers);
        let without = states.clone();
        simulate(on_demand_units, &cuts, &mut states, &mut barriers);
        (barriers, without.merge(&states))
    };
    let carries: Vec<Carry> = builder
        .images
        .iter()
        .map(|r| image_carry(&r.source))
        .collect();
    let next_start = |end: &States| States {
        images: end
            .images
            .iter()
            .zip(&carries)
            .map(|(mips, c)| mips.iter().map(|s| next_frame_state(*s, *c)).collect())
            .collect(),
        buffers: end.buffers.clone(),
    };
    let (first, mut end) = frame(initial);
    let mut steady = Vec::new();
    // Iterate to the steady state (stage sets only grow, so this converges quickly).
    for _ in 0..8 {
        let (barriers, next_end) = frame(next_start(&end));
        steady = barriers;
        if next_end == end {
            break;
        }
        end = next_end;
    }
    Ok(first.into_iter().zip(steady).collect())
}

impl GraphBuilder {
    /// The derived schedule (passes, accesses, barriers) without a device, for tests and
    /// `--dump-graph`.
    pub fn schedule(&self) -> Result<String> {
        let barriers = derive(self, StageSupport::ALL)?;
        let buffer_name = |id: BufferId, range: BufferRange| {
            let name = &self.buffers[id.0 as usize].name;
            if range == BufferRange::WHOLE {
                name.clone()
            } else {
                format!("{name}[{range}]")
            }
        };
        let names = |t: &BarrierTarget| match *t {
            BarrierTarget::Image { id, mip } => {
                format!("{}[mip {mip}]", self.images[id.0 as usize].name)
            }
            BarrierTarget::Buffer { id, range } => buffer_name(id, range),
        };
        let mut s = String::new();
        for (i, (pass, (_, steady))) in self.passes.iter().zip(&barriers).enumerate() {
            let kind = if pass.on_demand { " (on demand)" } else { "" };
            writeln!(s, "{i}: {}{kind}", pass.name).expect("fmt");
            for (sub, access) in &pass.uses {
                let what = match *sub {
                    Subresource::Image { id, base, count } => format!(
                        "{} mips {base}..{}",
                        self.images[id.0 as usize].name,
                        base + count
                    ),
                    Subresource::Buffer(id, range) => buffer_name(id, range),
                };
                writeln!(s, "    {access:?} {what}").expect("fmt");
            }
            for b in steady {
                let t = b.transition;
                writeln!(
                    s,
                    "    barrier {}: {:?}/{:?} -> {:?}/{:?}, {:?} -> {:?}",
                    names(&b.target),
                    t.src_stages,
                    t.src_access,
                    t.dst_stages,
                    t.dst_access,
                    t.old_layout,
                    t.new_layout
                )
                .expect("fmt");
            }
        }
        Ok(s)
    }

    /// Derived barriers per pass (steady state), for tests.
    pub fn barriers(&self) -> Result<Vec<Vec<Barrier>>> {
        self.barriers_with(StageSupport::ALL)
    }

    /// Derived barriers per pass (steady state) on a device with `support`.
    pub fn barriers_with(&self, support: StageSupport) -> Result<Vec<Vec<Barrier>>> {
        Ok(derive(self, support)?.into_iter().map(|(_, s)| s).collect())
    }

    /// Derived barriers per pass in the first frame, for tests.
    pub fn first_frame_barriers(&self) -> Result<Vec<Vec<Barrier>>> {
        Ok(derive(self, StageSupport::ALL)?
            .into_iter()
            .map(|(f, _)| f)
            .collect())
    }
}

//! A stable GPU radix sort of (u32 key, u64 value) pairs and a segmented maximum over sorted
//! keys, declared as render-graph passes.
//!
//! The sort is least-significant-digit first with 8-bit digits. Each digit pass is
//! reduce-then-scan, five compute passes:
//!
//! * `count`: one workgroup per tile of `SORT_GROUP * SORT_ITEMS` keys writes the tile's digit
//!   histogram digit-major (`hist[digit * tiles + tile]`).
//! * `reduce`, `scan`, `downsweep`: the exclusive prefix sum over that whole array. `reduce`
//!   sums each block of `SCAN_GROUP * SCAN_ITEMS` entries, `scan` (one workgroup) scans the
//!   block sums serially in chunks, and `downsweep` scans each block and adds its offset, so
//!   `hist[digit * tiles + tile]` becomes the first output position of that digit's elements
//!   of that tile.
//! * `scatter`: each tile ranks its elements among the tile's earlier elements of the same
//!   digit (subgroup ballots, then per-subgroup counts combined in order) and writes each pair
//!   to its position: stable.
//!
//! Why not a single-pass scan with decoupled look-back: it makes a workgroup spin on a flag
//! that an earlier workgroup publishes, which needs forward progress between workgroups, and
//! lavapipe (and the Vulkan specification) gives none, so it can hang. Reduce-then-scan only
//! ever waits at pass boundaries, where the graph places the barriers.
//!
//! The segmented maximum (`segmax.comp`) reduces each tile in shared memory and combines the
//! segments that cross tile boundaries with 64-bit atomics.

use anyhow::{bail, Result};
use ash::vk;

use crate::gpu::Context;
use crate::graph::{Access, Bind, BufferId, GraphBuilder, Stages};
use crate::layout::{
    BINDING_SORT_HIST, BINDING_SORT_KEYS, BINDING_SORT_KEYS_OUT, BINDING_SORT_SUMS,
    BINDING_SORT_VALUES, BINDING_SORT_VALUES_OUT, SCAN_GROUP, SCAN_ITEMS, SEGMAX_GROUP,
    SORT_DIGIT_BITS, SORT_GROUP, SORT_ITEMS, SORT_RADIX, SORT_SPEC_SUBGROUPS,
};

/// Elements per tile of the count and scatter passes.
const TILE: u32 = SORT_GROUP * SORT_ITEMS;
/// Histogram entries per block of the reduce and downsweep passes.
const SCAN_BLOCK: u32 = SCAN_GROUP * SCAN_ITEMS;

/// What the device gives `add_sort` and `add_segmented_max`: the scatter's subgroups per
/// workgroup.
#[derive(Clone, Copy, Debug)]
pub struct RadixSort {
    subgroups: u32,
}

impl RadixSort {
    /// Fails when the device lacks what the passes need: subgroup ballots in compute shaders
    /// with subgroups of at most `SORT_GROUP` invocations, enough shared memory for the
    /// scatter's per-subgroup digit counts, and 64-bit buffer atomics.
    pub fn new(ctx: &Context) -> Result<Self> {
        let caps = &ctx.caps;
        if !caps.subgroup_ballot_compute {
            bail!(
                "{} lacks subgroup ballot operations in compute shaders \
                 (GL_KHR_shader_subgroup_ballot): the GPU radix sort needs them",
                caps.device_name
            );
        }
        let size = caps.subgroup_size;
        if size == 0 || size > SORT_GROUP || !size.is_power_of_two() {
            bail!(
                "{} has subgroups of {size} invocations: the GPU radix sort needs a power of \
                 two of at most {SORT_GROUP}",
                caps.device_name
            );
        }
        let subgroups = SORT_GROUP / size;
        let shared = (subgroups + 1) * SORT_RADIX * 4;
        if shared > caps.max_compute_shared_memory {
            bail!(
                "{}: the radix sort's scatter needs {shared} bytes of shared memory with \
                 subgroups of {size} (the device allows {})",
                caps.device_name,
                caps.max_compute_shared_memory
            );
        }
        if !caps.buffer_int64_atomics {
            bail!(
                "{} lacks 64-bit buffer atomics (shaderBufferInt64Atomics): the segmented \
                 maximum needs them",
                caps.device_name
            );
        }
        Ok(Self { subgroups })
    }
}

/// Push constants of every sort shader (`Push` in `glsl/hpr/sort.glsl`).
#[derive(Clone, Copy, bytemuck::NoUninit)]
#[repr(C)]
struct Push {
    count: u32,
    shift: u32,
    mask: u32,
    tiles: u32,
    blocks: u32,
}

/// Declares a stable LSD radix sort of the first `count` (key, value) pairs of `keys` (`u32`
/// each) and `values` (`u64` each) by the low `key_bits` bits of the key (1..=32): one digit
/// pass per 8 bits, each five compute passes (`sort.count.N`, `sort.reduce.N`, `sort.scan.N`,
/// `sort.downsweep.N`, `sort.scatter.N`). The passes ping-pong between the input buffers
/// (which they overwrite) and two transient buffers; returns the buffers that hold the sorted
/// keys and values (the inputs after an even number of digit passes). Fewer than two pairs
/// are already sorted: no passes, the inputs are returned.
pub fn add_sort(
    g: &mut GraphBuilder,
    sort: &RadixSort,
    keys: BufferId,
    values: BufferId,
    count: u32,
    key_bits: u32,
) -> (BufferId, BufferId) {
    assert!(
        (1..=32).contains(&key_bits),
        "sort keys have 1 to 32 bits, not {key_bits}"
    );
    if count < 2 {
        return (keys, values);
    }
    let tiles = count.div_ceil(TILE);
    let entries = tiles * SORT_RADIX;
    let blocks = entries.div_ceil(SCAN_BLOCK);
    // Usage flags follow from the declared accesses.
    let usage = vk::BufferUsageFlags::empty();
    let alt = (
        g.buffer("sort.keys", u64::from(count) * 4, usage),
        g.buffer("sort.values", u64::from(count) * 8, usage),
    );
    let hist = g.buffer("sort.hist", u64::from(entries) * 4, usage);
    let sums = g.buffer("sort.sums", u64::from(blocks) * 4, usage);
    let read = Access::StorageRead(Stages::Compute);
    let write = Access::StorageWrite(Stages::Compute);
    let read_write = Access::StorageReadWrite(Stages::Compute);
    let (mut src, mut dst) = ((keys, values), alt);
    for digit in 0..key_bits.div_ceil(SORT_DIGIT_BITS) {
        let shift = digit * SORT_DIGIT_BITS;
        let bits = (key_bits - shift).min(SORT_DIGIT_BITS);
        let push = Push {
            count,
            shift,
            mask: (1 << bits) - 1,
            tiles,
            blocks,
        };
        g.compute(
            &format!("sort.count.{digit}"),
            "common/sort_count.comp",
            &[
                Bind::buffer(BINDING_SORT_KEYS, src.0, read),
                Bind::buffer(BINDING_SORT_HIST, hist, write),
            ],
        )
        .push(&push)
        .dispatch(u64::from(tiles));
        g.compute(
            &format!("sort.reduce.{digit}"),
            "common/sort_reduce.comp",
            &[
                Bind::buffer(BINDING_SORT_HIST, hist, read),
                Bind::buffer(BINDING_SORT_SUMS, sums, write),
            ],
        )
        .push(&push)
        .dispatch(u64::from(blocks));
        g.compute(
            &format!("sort.scan.{digit}"),
            "common/sort_scan.comp",
            &[Bind::buffer(BINDING_SORT_SUMS, sums, read_write)],
        )
        .push(&push)
        .dispatch(1);
        g.compute(
            &format!("sort.downsweep.{digit}"),
            "common/sort_downsweep.comp",
            &[
                Bind::buffer(BINDING_SORT_HIST, hist, read_write),
                Bind::buffer(BINDING_SORT_SUMS, sums, read),
            ],
        )
        .push(&push)
        .dispatch(u64::from(blocks));
        g.compute(
            &format!("sort.scatter.{digit}"),
            "common/sort_scatter.comp",
            &[
                Bind::buffer(BINDING_SORT_KEYS, src.0, read),
                Bind::buffer(BINDING_SORT_VALUES, src.1, read),
                Bind::buffer(BINDING_SORT_KEYS_OUT, dst.0, write),
                Bind::buffer(BINDING_SORT_VALUES_OUT, dst.1, write),
                Bind::buffer(BINDING_SORT_HIST, hist, read),
            ],
        )
        .spec(&[(SORT_SPEC_SUBGROUPS, sort.subgroups)])
        .push(&push)
        .dispatch(u64::from(tiles));
        std::mem::swap(&mut src, &mut dst);
    }
    src
}

/// Declares the pass `sort.segmax`: for the first `count` pairs of `keys` (`u32`, sorted
/// ascending) and `values` (`u64`), writes `out[s] = max(values[i] for keys[i] == s)` (`u64`
/// per possible key) for every key `s` present. The caller clears `out` to 0 before (the
/// segments crossing tile boundaries combine with `atomicMax`); keys without elements keep
/// their value. Needs 64-bit buffer atomics (`RadixSort::new` checks them).
pub fn add_segmented_max(
    g: &mut GraphBuilder,
    keys: BufferId,
    values: BufferId,
    count: u32,
    out: BufferId,
) {
    if count == 0 {
        return;
    }
    let push = Push {
        count,
        shift: 0,
        mask: 0,
        tiles: 0,
        blocks: 0,
    };
    let read = Access::StorageRead(Stages::Compute);
    g.compute(
        "sort.segmax",
        "hpr/segmax.comp",
        &[
            Bind::buffer(BINDING_SORT_KEYS, keys, read),
            Bind::buffer(BINDING_SORT_VALUES, values, read),
            Bind::updates(BINDING_SORT_VALUES_OUT, out),
        ],
    )
    .push(&push)
    .dispatch(u64::from(count.div_ceil(SEGMAX_GROUP)));
}

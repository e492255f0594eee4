//! k-NN normals and radii on the GPU: the same estimate as `scene::preprocess` (exact k nearest
//! neighbours, PCA normals with the same orientation rule, the same radius rule) as five steps
//! of one render graph:
//!
//! * `estimate.key`: each point's cell of the CPU's grid (`scene::knn::GridFrame`, sized from a
//!   sample on the CPU) hashed into one of 2^b buckets (2^b ≥ points) as a sort key;
//! * the radix sort of `methods::common::sort` groups the points by bucket;
//! * `estimate.cells`: each bucket's range in the sorted order (a cleared table) and the
//!   points in that order;
//! * `estimate.query`: one thread per sorted point, the k nearest in the 3×3×3 block of cells
//!   (candidates of colliding cells only add work: every distance is measured), verified
//!   against the block's inner bound, else the 5×5×5 block; the PCA normal by Jacobi
//!   rotations in single precision; the k-th neighbour's squared distance;
//! * the result (16 bytes per point) and the 6 nearest neighbours (24 bytes per point, the
//!   orientation's graph) are read back and `scene::preprocess::complete_from` turns distances
//!   into radii, with the same floor, after searching the points the GPU left unresolved
//!   (outliers whose 5×5×5 block holds fewer than k verified neighbours) on the CPU; then it
//!   signs the normals by the same walk as the CPU path (`scene::orient`).
//!
//! Deviations from the CPU path, measured by `tests/suite/estimate.rs`: single precision (the CPU
//! accumulates the covariance in double), a neighbourhood counts as flat only with spread in
//! a second direction above 1e-6 of the first (1e-12 on the CPU), and ties in distance go to
//! the lower GPU-sorted index (the CPU's sort differs), so equidistant k-th neighbours can
//! differ.

use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context as _, Result};
use ash::vk;
use glam::{Vec3, Vec4};

use crate::gpu::{Buffer, Context};
use crate::graph::{Access, Bind, BufferRange, GraphBuilder, Stages};
use crate::layout::{
    KnnParams, BINDING_KNN_GRAPH, BINDING_KNN_OUT, BINDING_KNN_POSITIONS, BINDING_KNN_SORTED,
    BINDING_KNN_TABLE, BINDING_SORT_KEYS, BINDING_SORT_VALUES, KNN_GRAPH_K, KNN_GROUP, KNN_MAX_K,
    KNN_SPEC_K,
};
use crate::methods::common::sort::{add_sort, RadixSort};
use crate::scene::knn::{finite_indices, GridFrame};
use crate::scene::orient::{Graph, GRAPH_K};
use crate::scene::preprocess::{self, PreprocessOptions};
use crate::scene::Cloud;

// The graph rows the GPU writes are those the orientation reads.
const _: () = assert!(KNN_GRAPH_K as usize == GRAPH_K);

/// Clouds below this size are estimated on the CPU: a GPU submission costs more than it saves.
pub const MIN_POINTS: usize = 4096;

/// Points the GPU path takes at most: 16 bytes per point of its largest buffers within the
/// 4 GiB one storage binding may span.
pub const MAX_POINTS: usize = (1 << 28) - 1;

/// Where normals and radii are estimated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum EstimateOn {
    /// The GPU when the device is one (not a CPU implementation such as lavapipe), else the
    /// CPU.
    #[default]
    Auto,
    Cpu,
    Gpu,
}

impl EstimateOn {
    /// Whether this choice runs on the GPU of `ctx`.
    pub fn uses_gpu(self, ctx: &Context) -> bool {
        match self {
            EstimateOn::Auto => ctx.caps.device_type != "CPU",
            EstimateOn::Cpu => false,
            EstimateOn::Gpu => true,
        }
    }
}

/// The GPU estimate for one neighbourhood size, checked against the device.
pub struct GpuKnn {
    k: usize,
    sort: RadixSort,
}

impl GpuKnn {
    /// For `k` neighbours (1..=`KNN_MAX_K`); fails where the device lacks what the radix sort
    /// needs.
    pub fn new(ctx: &Context, k: usize) -> Result<Self> {
        anyhow::ensure!(
            (1..=KNN_MAX_K as usize).contains(&k),
            "the GPU estimate keeps 1 to {KNN_MAX_K} neighbours per point, not {k}"
        );
        Ok(GpuKnn {
            k,
            sort: RadixSort::new(ctx)?,
        })
    }
}

/// Seconds of each step of [`estimate`], and how many points the CPU finished.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuTimes {
    /// The grid's frame, the upload, the graph's compilation (its pipelines included),
    /// submission and read-back.
    pub gpu_s: f64,
    /// Radii, their floor and the unresolved points on the CPU.
    pub finish_s: f64,
    /// Points the GPU left to the CPU's exact search.
    pub unresolved: usize,
}

/// Per point in input order: `xyz` the unit normal (facing the sensor, else away from the
/// centroid, before [`crate::scene::orient`]), `w` the squared distance of the k-th neighbour,
/// or `w < 0` where the GPU could not verify one (non-finite points, outliers); and the nearest
/// neighbours of every resolved point, the orientation's graph.
pub fn nearest_on_gpu(
    ctx: &Arc<Context>,
    knn: &GpuKnn,
    positions: &[Vec3],
    sensor: Option<Vec3>,
) -> Result<(Vec<Vec4>, Graph)> {
    let n = positions.len();
    anyhow::ensure!(
        n <= MAX_POINTS,
        "the GPU estimate takes at most {MAX_POINTS} points, not {n}"
    );
    if n == 0 {
        return Ok((Vec::new(), Graph::default()));
    }
    let count = n as u32;
    let finite = finite_indices(positions);
    let frame = GridFrame::new(positions, &finite, knn.k);
    let mean = preprocess::centroid(positions);
    let hash_bits = count.next_power_of_two().trailing_zeros().clamp(1, 31);
    let params = KnnParams {
        origin_cell: frame.origin.extend(frame.cell),
        dims_count: [frame.dims[0], frame.dims[1], frame.dims[2], count],
        sensor: sensor.map_or(Vec4::ZERO, |s| s.extend(1.0)),
        mean: mean.extend(0.0),
        hash_bits,
        ..Default::default()
    };
    let mut g = GraphBuilder::new();
    let upload = Buffer::with_data(
        ctx,
        "estimate.positions",
        bytemuck::cast_slice(positions),
        vk::BufferUsageFlags::STORAGE_BUFFER,
    )?;
    let input = g.import_buffer_with("estimate.positions", Arc::new(upload), Access::TransferDst);
    let usage = vk::BufferUsageFlags::empty();
    let n64 = u64::from(count);
    let keys = g.buffer("estimate.keys", n64 * 4, usage);
    let values = g.buffer("estimate.values", n64 * 8, usage);
    let table = g.buffer("estimate.table", 8 << hash_bits, usage);
    let sorted = g.buffer("estimate.sorted", n64 * 16, usage);
    let out = g.buffer("estimate.out", n64 * 16, usage);
    let graph_bytes = n64 * 4 * u64::from(KNN_GRAPH_K);
    let graph = g.buffer("estimate.graph", graph_bytes, usage);
    let read = Access::StorageRead(Stages::Compute);
    let write = Access::StorageWrite(Stages::Compute);
    let groups = count.div_ceil(KNN_GROUP);
    g.compute(
        "estimate.key",
        "knn_gpu/key.comp",
        &[
            Bind::buffer(BINDING_KNN_POSITIONS, input, read),
            Bind::buffer(BINDING_SORT_KEYS, keys, write),
            Bind::buffer(BINDING_SORT_VALUES, values, write),
        ],
    )
    .push(&params)
    .dispatch(u64::from(groups));
    let (keys, values) = add_sort(&mut g, &knn.sort, keys, values, count, hash_bits);
    g.fill_buffer("estimate.clear", table, BufferRange::WHOLE, 0);
    g.compute(
        "estimate.cells",
        "knn_gpu/cells.comp",
        &[
            Bind::buffer(BINDING_KNN_POSITIONS, input, read),
            Bind::buffer(BINDING_SORT_KEYS, keys, read),
            Bind::buffer(BINDING_SORT_VALUES, values, read),
            Bind::buffer(BINDING_KNN_TABLE, table, write),
            Bind::buffer(BINDING_KNN_SORTED, sorted, write),
        ],
    )
    .push(&params)
    .dispatch(u64::from(groups));
    g.compute(
        "estimate.query",
        "knn_gpu/query.comp",
        &[
            Bind::buffer(BINDING_KNN_TABLE, table, read),
            Bind::buffer(BINDING_KNN_SORTED, sorted, read),
            Bind::buffer(BINDING_KNN_OUT, out, write),
            Bind::buffer(BINDING_KNN_GRAPH, graph, write),
        ],
    )
    .spec(&[(KNN_SPEC_K, knn.k as u32)])
    .push(&params)
    .dispatch(u64::from(groups));
    let host = Arc::new(Buffer::readback(ctx, "estimate.readback", n64 * 16)?);
    let host_id = g.import_buffer("estimate.readback", host.clone());
    let region = [vk::BufferCopy {
        src_offset: 0,
        dst_offset: 0,
        size: n64 * 16,
    }];
    g.copy_buffer("estimate.download", out, host_id, &region);
    let host_graph = Arc::new(Buffer::readback(
        ctx,
        "estimate.graph.readback",
        graph_bytes,
    )?);
    let host_graph_id = g.import_buffer("estimate.graph.readback", host_graph.clone());
    let graph_region = [vk::BufferCopy {
        src_offset: 0,
        dst_offset: 0,
        size: graph_bytes,
    }];
    g.copy_buffer(
        "estimate.graph.download",
        graph,
        host_graph_id,
        &graph_region,
    );
    g.pass("estimate.host")
        .buffer(host_id, Access::HostRead)
        .buffer(host_graph_id, Access::HostRead)
        .record(|_| {});
    g.compile(ctx)?.run_once(ctx)?;
    let result = bytemuck::pod_collect_to_vec::<u8, Vec4>(host.mapped()?);
    let rows = bytemuck::pod_collect_to_vec::<u8, u32>(host_graph.mapped()?);
    Ok((result, Graph { rows }))
}

/// Computes the normals and radii `cloud` lacks on the GPU (see the module documentation);
/// `None` when nothing was missing. Clouds outside [`MIN_POINTS`]..=[`MAX_POINTS`] and
/// neighbourhoods above `KNN_MAX_K` go to the CPU (`scene::preprocess`), which returns
/// `Some` with every time zero but `finish_s`.
pub fn estimate(
    ctx: &Arc<Context>,
    cloud: &mut Cloud,
    options: &PreprocessOptions,
) -> Result<Option<GpuTimes>> {
    if cloud.normals.is_some() && cloud.radii.is_some() {
        return Ok(None);
    }
    let n = cloud.len();
    let k = options.k.max(1);
    if !(MIN_POINTS..=MAX_POINTS).contains(&n) || k > KNN_MAX_K as usize {
        let start = Instant::now();
        preprocess::preprocess(cloud, options);
        return Ok(Some(GpuTimes {
            finish_s: start.elapsed().as_secs_f64(),
            ..Default::default()
        }));
    }
    let start = Instant::now();
    let knn = GpuKnn::new(ctx, k)?;
    let sensor = cloud
        .sensors
        .first()
        .map(|s| s.position)
        .filter(|s| s.is_finite());
    let (result, graph) = nearest_on_gpu(ctx, &knn, &cloud.positions, sensor)
        .context("estimating normals and radii on the GPU")?;
    let ran = Instant::now();
    let unresolved = preprocess::complete_from(cloud, options, &result, graph);
    Ok(Some(GpuTimes {
        gpu_s: (ran - start).as_secs_f64(),
        finish_s: ran.elapsed().as_secs_f64(),
        unresolved,
    }))
}

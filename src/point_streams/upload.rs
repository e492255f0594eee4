//! Uploading a cloud's streams: one device-local buffer per stream and segment, filled in
//! chunks through a double-buffered staging pair (encoding the next chunk overlaps the copy of
//! the previous one), plus the segment table of device addresses and the batch table.

use std::sync::Arc;

use anyhow::{bail, Context as _, Result};
use ash::vk;

use super::{Stream, StreamLayout};
use crate::gpu::staging::{CopyRegion, Uploader};
use crate::gpu::{Buffer, Context};
use crate::layout::{GpuBatch, GpuSegment, BATCH_POINTS};
use crate::scene::progress::Progress;
use crate::scene::Cloud;

/// Bytes per staging chunk by default.
pub const DEFAULT_CHUNK_BYTES: u64 = 32 << 20;

/// A cloud's streams on the GPU.
pub struct GpuStreams {
    /// Per segment, the buffer of each stream (kept alive; shaders reach them by address).
    pub segments: Vec<Vec<(Stream, Buffer)>>,
    /// `GpuSegment` per segment.
    pub table: Arc<Buffer>,
    /// The segment table's host copy (rewritten when the scalar stream changes).
    entries: Vec<GpuSegment>,
    /// The scalar field uploaded, if any.
    pub scalar: Option<usize>,
    /// `GpuBatch` per batch.
    pub batches: Arc<Buffer>,
    /// The batches' host copy (32 bytes per `BATCH_POINTS` points), for counting the points
    /// a culling method projects (`super::projected_points`).
    pub host_batches: Vec<GpuBatch>,
    pub point_count: u32,
    pub batch_count: u32,
    pub segment_points: u32,
    /// Whether the `NormalField` stream was uploaded.
    pub normal_field: bool,
    /// The scalar field uploaded as the `Classes` stream, if any.
    pub classes: Option<usize>,
}

/// The segment size fitting every stream into one storage-buffer range of `ctx`'s device.
pub fn default_segment_points(ctx: &Context) -> u64 {
    u64::from(ctx.caps.max_storage_buffer_range) / Stream::Position.bytes_per_point()
}

fn address_pair(a: u64) -> [u32; 2] {
    [a as u32, (a >> 32) as u32]
}

/// The device-local buffer of `stream` for the `points` points of segment `segment`.
fn stream_buffer(
    ctx: &Arc<Context>,
    segment: usize,
    stream: Stream,
    points: u64,
) -> Result<Buffer> {
    Buffer::new(
        ctx,
        &format!("stream.{segment}.{}", stream.name()),
        StreamLayout::stream_bytes(stream, points),
        vk::BufferUsageFlags::STORAGE_BUFFER
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
            | vk::BufferUsageFlags::TRANSFER_DST,
        gpu_allocator::MemoryLocation::GpuOnly,
    )
}

/// A `GpuSegment` entry holding the address of `stream` among `buffers` in xy (zeros without
/// it).
fn address_entry(buffers: &[(Stream, Buffer)], stream: Stream) -> [u32; 4] {
    buffers
        .iter()
        .find(|(s, _)| *s == stream)
        .map_or([0; 4], |(_, b)| {
            let [lo, hi] = address_pair(b.device_address());
            [lo, hi, 0, 0]
        })
}

/// The `GpuSegment` entry of the stream of a cloud field among `buffers` that `field` picks
/// (its field index): the address in xy, the index in z, `present` in w; zeros without one.
fn field_entry(
    buffers: &[(Stream, Buffer)],
    field: impl Fn(&Stream) -> Option<usize>,
    present: u32,
) -> [u32; 4] {
    buffers
        .iter()
        .find_map(|(s, b)| {
            let k = field(s)?;
            let [lo, hi] = address_pair(b.device_address());
            Some([lo, hi, k as u32, present])
        })
        .unwrap_or([0; 4])
}

/// `GpuSegment.scalar`: the scalar stream's entry (w unused).
fn scalar_entry(buffers: &[(Stream, Buffer)]) -> [u32; 4] {
    let scalar = |s: &Stream| match s {
        Stream::Scalar(k) => Some(*k),
        _ => None,
    };
    field_entry(buffers, scalar, 0)
}

/// `GpuSegment.classes`: the classes stream's entry (w 1 when present).
fn classes_entry(buffers: &[(Stream, Buffer)]) -> [u32; 4] {
    let classes = |s: &Stream| match s {
        Stream::Classes(k) => Some(*k),
        _ => None,
    };
    field_entry(buffers, classes, 1)
}

fn table_buffer(ctx: &Arc<Context>, entries: &[GpuSegment]) -> Result<Arc<Buffer>> {
    Ok(Arc::new(Buffer::with_data(
        ctx,
        "stream.segments",
        bytemuck::cast_slice(entries),
        vk::BufferUsageFlags::STORAGE_BUFFER,
    )?))
}

impl GpuStreams {
    /// Replaces the uploaded scalar stream by field `scalar` of `cloud` (the cloud these
    /// streams were uploaded from), or drops it (`None`): an event (the viewer cycling color
    /// fields), not per frame. Waits for the device to be idle, since frames in flight read
    /// the old buffers, and writes a new segment table: renderers built on the old `table`
    /// must be rebuilt. The Morton order is recomputed (it is deterministic) rather than kept.
    pub fn select_scalar(
        &mut self,
        ctx: &Arc<Context>,
        cloud: &Cloud,
        scalar: Option<usize>,
        chunk_bytes: u64,
    ) -> Result<()> {
        if scalar == self.scalar {
            return Ok(());
        }
        if scalar.is_some_and(|k| k >= cloud.scalars.len()) {
            bail!("scalar field {scalar:?} is not in the cloud");
        }
        // SAFETY: waits for every submitted use of the buffers replaced below.
        unsafe { ctx.device.device_wait_idle()? };
        for buffers in &mut self.segments {
            buffers.retain(|(s, _)| !matches!(s, Stream::Scalar(_)));
        }
        if let Some(k) = scalar {
            let layout = StreamLayout::new(cloud, u64::from(self.segment_points), None)
                .map_err(anyhow::Error::msg)?;
            self.upload_stream(ctx, cloud, &layout, Stream::Scalar(k), chunk_bytes)?;
        }
        for (entry, buffers) in self.entries.iter_mut().zip(&self.segments) {
            entry.color_first[3] = u32::from(scalar.is_some());
            entry.scalar = scalar_entry(buffers);
        }
        self.table = table_buffer(ctx, &self.entries)?;
        self.scalar = scalar;
        Ok(())
    }

    /// Adds the `NormalField` stream with the packed fields `field` of `cloud`'s points (cloud
    /// order), when these streams were uploaded without it: an event (the viewer switching to a
    /// method that reads it), not per frame. Waits for the device to be idle and writes a new
    /// segment table, as `select_scalar` does.
    pub fn add_normal_field(
        &mut self,
        ctx: &Arc<Context>,
        cloud: &Cloud,
        field: Vec<[u32; 2]>,
        chunk_bytes: u64,
    ) -> Result<()> {
        if self.normal_field {
            return Ok(());
        }
        // SAFETY: waits for every submitted use of the segment table replaced below.
        unsafe { ctx.device.device_wait_idle()? };
        let layout = StreamLayout::new(cloud, u64::from(self.segment_points), None)
            .map_err(anyhow::Error::msg)?
            .with_normal_field(field);
        self.upload_stream(ctx, cloud, &layout, Stream::NormalField, chunk_bytes)?;
        for (entry, buffers) in self.entries.iter_mut().zip(&self.segments) {
            entry.normal_field = address_entry(buffers, Stream::NormalField);
        }
        self.table = table_buffer(ctx, &self.entries)?;
        self.normal_field = true;
        Ok(())
    }

    /// Adds the `Classes` stream of scalar field `field` (the classification), when these
    /// streams were uploaded without it: an event (the viewer hiding a class the first time),
    /// not per frame. Waits for the device to be idle and writes a new segment table, as
    /// `select_scalar` does.
    pub fn add_classes(
        &mut self,
        ctx: &Arc<Context>,
        cloud: &Cloud,
        field: usize,
        chunk_bytes: u64,
    ) -> Result<()> {
        if self.classes.is_some() {
            return Ok(());
        }
        if field >= cloud.scalars.len() {
            bail!("scalar field {field} is not in the cloud");
        }
        // SAFETY: waits for every submitted use of the segment table replaced below.
        unsafe { ctx.device.device_wait_idle()? };
        let layout = StreamLayout::new(cloud, u64::from(self.segment_points), None)
            .map_err(anyhow::Error::msg)?;
        self.upload_stream(ctx, cloud, &layout, Stream::Classes(field), chunk_bytes)?;
        for (entry, buffers) in self.entries.iter_mut().zip(&self.segments) {
            entry.classes = classes_entry(buffers);
        }
        self.table = table_buffer(ctx, &self.entries)?;
        self.classes = Some(field);
        Ok(())
    }

    /// Uploads `stream` of `cloud` as `layout` orders it into one new buffer per segment,
    /// added to `segments`.
    fn upload_stream(
        &mut self,
        ctx: &Arc<Context>,
        cloud: &Cloud,
        layout: &StreamLayout,
        stream: Stream,
        chunk_bytes: u64,
    ) -> Result<()> {
        let chunk_points = (chunk_bytes / stream.bytes_per_point()).max(4) & !3;
        let mut uploader = Uploader::new(ctx, chunk_points * stream.bytes_per_point())?;
        for (s, range) in layout.segments().into_iter().enumerate() {
            let buffer = stream_buffer(ctx, s, stream, range.end - range.start)?;
            let mut start = range.start;
            while start < range.end {
                let end = (start + chunk_points).min(range.end);
                let size = StreamLayout::stream_bytes(stream, end - start);
                uploader.upload(
                    |staging| {
                        layout.encode(cloud, stream, start..end, &mut staging[..size as usize]);
                        Ok(())
                    },
                    &[CopyRegion {
                        dst: buffer.raw,
                        dst_offset: StreamLayout::stream_bytes(stream, start - range.start),
                        src_offset: 0,
                        size,
                    }],
                )?;
                start = end;
            }
            self.segments[s].push((stream, buffer));
        }
        uploader.finish()
    }
}

/// An empty pool of `slots` batch slots for a streamed cloud: one segment holding
/// `slots * BATCH_POINTS` points of each of `streams`, every batch empty (`first` at its slot,
/// `count` 0). The streamer copies nodes into slots and draws from a per-frame batch table.
pub fn pool(ctx: &Arc<Context>, streams: &[Stream], slots: u32) -> Result<GpuStreams> {
    let capacity = u64::from(slots) * u64::from(BATCH_POINTS);
    let segment_points = u32::try_from(capacity)
        .ok()
        .filter(|&c| c > 0)
        .with_context(|| format!("a pool of {slots} batches does not fit 32-bit point indices"))?;
    let buffers = streams
        .iter()
        .map(|&stream| stream_buffer(ctx, 0, stream, capacity).map(|b| (stream, b)))
        .collect::<Result<Vec<_>>>()?;
    let table = vec![segment_entry(&buffers, 0)];
    let batches: Vec<GpuBatch> = (0..slots)
        .map(|slot| GpuBatch {
            first: slot * BATCH_POINTS,
            ..GpuBatch::default()
        })
        .collect();
    Ok(GpuStreams {
        segments: vec![buffers],
        table: table_buffer(ctx, &table)?,
        entries: table,
        scalar: streams.iter().find_map(|s| match s {
            Stream::Scalar(k) => Some(*k),
            _ => None,
        }),
        batches: Arc::new(Buffer::with_data(
            ctx,
            "stream.batches",
            bytemuck::cast_slice(&batches),
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )?),
        host_batches: batches,
        point_count: segment_points,
        batch_count: slots,
        segment_points,
        normal_field: streams.contains(&Stream::NormalField),
        classes: streams.iter().find_map(|s| match s {
            Stream::Classes(k) => Some(*k),
            _ => None,
        }),
    })
}

/// The segment-table entry of the streams in `buffers`, whose first point is stream index
/// `first`.
fn segment_entry(buffers: &[(Stream, Buffer)], first: u64) -> GpuSegment {
    let address = |stream: Stream| {
        buffers
            .iter()
            .find(|(s, _)| *s == stream)
            .map_or([0, 0], |(_, b)| address_pair(b.device_address()))
    };
    let pair = |a: Stream, b: Stream| {
        let (a, b) = (address(a), address(b));
        [a[0], a[1], b[0], b[1]]
    };
    let color = address(Stream::Color);
    let has_scalar = buffers.iter().any(|(s, _)| matches!(s, Stream::Scalar(_)));
    GpuSegment {
        position_coarse: pair(Stream::Position, Stream::Coarse),
        medium_fine: pair(Stream::Medium, Stream::Fine),
        normal_radius: pair(Stream::Normal, Stream::Radius),
        color_first: [color[0], color[1], first as u32, u32::from(has_scalar)],
        scalar: scalar_entry(buffers),
        normal_field: address_entry(buffers, Stream::NormalField),
        classes: classes_entry(buffers),
    }
}

/// Uploads `cloud`'s streams as laid out by `layout`.
pub fn upload(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    layout: &StreamLayout,
    chunk_bytes: u64,
) -> Result<GpuStreams> {
    let per_point: u64 = layout.streams.iter().map(|&s| s.bytes_per_point()).sum();
    // Whole radius pairs and class quadruples per chunk: a multiple of 4 points.
    let chunk_points = (chunk_bytes / per_point.max(1)) & !3;
    if chunk_points == 0 {
        bail!(
            "upload chunk of {} bytes is smaller than two points ({per_point} bytes each)",
            chunk_bytes
        );
    }
    let mut uploader = Uploader::new(ctx, chunk_points * per_point + 8)?;
    let mut segments = Vec::new();
    let mut table = Vec::new();
    let points = usize::try_from(layout.len()).unwrap_or(usize::MAX);
    let progress = Progress::new(
        "uploading",
        points,
        points >= crate::scene::preprocess::PROGRESS_MIN_POINTS * 10,
    );
    for (s, range) in layout.segments().into_iter().enumerate() {
        let points = range.end - range.start;
        let buffers = layout
            .streams
            .iter()
            .map(|&stream| stream_buffer(ctx, s, stream, points).map(|b| (stream, b)))
            .collect::<Result<Vec<_>>>()?;
        let mut start = range.start;
        while start < range.end {
            let end = (start + chunk_points).min(range.end);
            let mut copies = Vec::with_capacity(buffers.len());
            let mut offset = 0;
            for (stream, buffer) in &buffers {
                let size = StreamLayout::stream_bytes(*stream, end - start);
                copies.push(CopyRegion {
                    dst: buffer.raw,
                    dst_offset: StreamLayout::stream_bytes(*stream, start - range.start),
                    src_offset: offset,
                    size,
                });
                offset += size;
            }
            uploader.upload(
                |staging| {
                    layout.encode_chunk(cloud, start..end, &mut staging[..offset as usize]);
                    Ok(())
                },
                &copies,
            )?;
            progress.advance((end - start) as usize);
            start = end;
        }
        table.push(segment_entry(&buffers, range.start));
        segments.push(buffers);
    }
    uploader.finish()?;
    progress.finish();
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    Ok(GpuStreams {
        segments,
        table: table_buffer(ctx, &table)?,
        entries: table,
        scalar: layout.streams.iter().find_map(|s| match s {
            Stream::Scalar(k) => Some(*k),
            _ => None,
        }),
        batches: Arc::new(Buffer::with_data(
            ctx,
            "stream.batches",
            bytemuck::cast_slice(&layout.batches),
            storage,
        )?),
        host_batches: layout.batches.clone(),
        point_count: layout.len() as u32,
        batch_count: layout.batches.len() as u32,
        segment_points: layout.segment_points,
        normal_field: layout.normal_field.is_some(),
        classes: layout.streams.iter().find_map(|s| match s {
            Stream::Classes(k) => Some(*k),
            _ => None,
        }),
    })
}

//! Uploading a cloud's streams: one device-local buffer per stream and segment, filled in
//! chunks through a double-buffered staging pair (encoding the next chunk overlaps the copy of
//! the previous one), plus the segment table of device addresses and the batch table.

use std::sync::Arc;

use anyhow::{bail, Result};
use ash::vk;

use super::{Stream, StreamLayout};
use crate::gpu::layout::{GpuSegment, MAX_SCALAR_STREAMS};
use crate::gpu::upload::{CopyRegion, Uploader};
use crate::gpu::{Buffer, Context};
use crate::scene::Cloud;

/// Upload settings.
#[derive(Clone, Copy, Debug)]
pub struct UploadOptions {
    /// Points per segment; `None` fits segments to the device's `maxStorageBufferRange`.
    pub segment_points: Option<u64>,
    /// Bytes per staging chunk.
    pub chunk_bytes: u64,
}

impl Default for UploadOptions {
    fn default() -> Self {
        Self {
            segment_points: None,
            chunk_bytes: 32 << 20,
        }
    }
}

/// A cloud's streams on the GPU.
pub struct GpuStreams {
    /// Per segment, the buffer of each stream (kept alive; shaders reach them by address).
    pub segments: Vec<Vec<(Stream, Buffer)>>,
    /// `GpuSegment` per segment.
    pub table: Arc<Buffer>,
    /// `GpuBatch` per batch.
    pub batches: Arc<Buffer>,
    pub point_count: u32,
    pub batch_count: u32,
    pub segment_points: u32,
}

/// The segment size fitting every stream into one storage-buffer range of `ctx`'s device.
pub fn default_segment_points(ctx: &Context) -> u64 {
    u64::from(ctx.caps.max_storage_buffer_range) / Stream::Position.bytes_per_point()
}

fn address_pair(a: u64) -> [u32; 2] {
    [a as u32, (a >> 32) as u32]
}

/// Uploads `cloud`'s streams as laid out by `layout`.
pub fn upload(
    ctx: &Arc<Context>,
    cloud: &Cloud,
    layout: &StreamLayout,
    options: UploadOptions,
) -> Result<GpuStreams> {
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER
        | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
        | vk::BufferUsageFlags::TRANSFER_DST;
    let per_point: u64 = layout.streams.iter().map(|&s| s.bytes_per_point()).sum();
    // Whole radius pairs per chunk: an even number of points.
    let chunk_points = (options.chunk_bytes / per_point.max(1)) & !1;
    if chunk_points == 0 {
        bail!(
            "upload chunk of {} bytes is smaller than two points ({per_point} bytes each)",
            options.chunk_bytes
        );
    }
    let mut uploader = Uploader::new(ctx, chunk_points * per_point + 8)?;
    let mut segments = Vec::new();
    let mut table = Vec::new();
    for (s, range) in layout.segments().into_iter().enumerate() {
        let points = range.end - range.start;
        let buffers = layout
            .streams
            .iter()
            .map(|&stream| {
                let bytes = StreamLayout::stream_bytes(stream, points);
                Buffer::new(
                    ctx,
                    &format!("stream.{s}.{}", stream.name()),
                    bytes,
                    usage,
                    gpu_allocator::MemoryLocation::GpuOnly,
                )
                .map(|b| (stream, b))
            })
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
            start = end;
        }
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
        let scalars = |k: usize| pair(Stream::Scalar(k), Stream::Scalar(k + 1));
        let color = address(Stream::Color);
        let scalar_count = layout
            .streams
            .iter()
            .filter(|s| matches!(s, Stream::Scalar(_)))
            .count() as u32;
        debug_assert!(scalar_count <= MAX_SCALAR_STREAMS);
        table.push(GpuSegment {
            position_coarse: pair(Stream::Position, Stream::Coarse),
            medium_fine: pair(Stream::Medium, Stream::Fine),
            normal_radius: pair(Stream::Normal, Stream::Radius),
            color_first: [color[0], color[1], range.start as u32, scalar_count],
            scalars01: scalars(0),
            scalars23: scalars(2),
        });
        segments.push(buffers);
    }
    uploader.finish()?;
    let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
    Ok(GpuStreams {
        segments,
        table: Arc::new(Buffer::with_data(
            ctx,
            "stream.segments",
            bytemuck::cast_slice(&table),
            storage,
        )?),
        batches: Arc::new(Buffer::with_data(
            ctx,
            "stream.batches",
            bytemuck::cast_slice(&layout.batches),
            storage,
        )?),
        point_count: layout.len() as u32,
        batch_count: layout.batches.len() as u32,
        segment_points: layout.segment_points,
    })
}

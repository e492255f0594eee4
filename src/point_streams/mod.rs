//! Point streams: the layout every method reads points from.
//!
//! A cloud is sorted into Morton order and cut into batches of `BATCH_POINTS` points, each with
//! its bounding box. Every attribute lives in its own stream so a pass reads only what it needs
//! (Schütz, Kerbl, Wimmer 2021): f32 positions (12 B), three quantized position words
//! (Schütz et al. 2022: 10 bits per axis each, relative to the batch's box, so a distant batch
//! reads 4 bytes per point, a nearer one 8 and a close one 12), octahedral normals (4 B), f16
//! radii (2 B), RGBA8 colors (4 B, only when the cloud has colors) and the one f32 scalar
//! attribute the frame is colored by (4 B, only when the color mode reads one), and the linear
//! normal fields of Phong splatting (8 B, only for the methods that read them). Streams are split into segments of whole batches
//! that each fit the device's buffer limits; shaders reach them through buffer device addresses
//! kept in a segment table (`upload.rs`).
//!
//! This module is pure CPU: ordering, batching and encoding, unit-tested without a device.

pub mod upload;

use std::ops::Range;

use glam::{Mat4, Vec3};
use rayon::prelude::*;

use crate::layout::{GpuBatch, BATCH_POINTS, QUANT_BITS};
pub use crate::scene::morton::{morton, morton_order};
use crate::scene::pack::oct_encode;
use crate::scene::Cloud;

pub use upload::GpuStreams;

/// Bits of a full quantized coordinate (three words of `QUANT_BITS`).
pub const QUANT_FULL_BITS: u32 = 3 * QUANT_BITS;

/// The position streams every layout starts with, encoded together.
const POSITION_STREAMS: [Stream; 4] = [
    Stream::Position,
    Stream::Coarse,
    Stream::Medium,
    Stream::Fine,
];

/// One per-point stream and its element size in bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Stream {
    /// f32 x, y, z.
    Position,
    /// Top `QUANT_BITS` of each axis, relative to the batch box.
    Coarse,
    /// The next `QUANT_BITS`.
    Medium,
    /// The last `QUANT_BITS`.
    Fine,
    /// Octahedral normal, 2 × snorm16.
    Normal,
    /// f16 splat radius (two per 32-bit word).
    Radius,
    /// RGBA8 sRGB color.
    Color,
    /// The k-th scalar attribute of the cloud as f32.
    Scalar(usize),
    /// Linear normal field (`crate::scene::normal_field`): three f16 and a zero.
    NormalField,
    /// The k-th scalar attribute as a classification class (`scene::clip::class_of`), one
    /// byte per point, four per 32-bit word: read by the projection passes while the viewer
    /// hides classes.
    Classes(usize),
}

impl Stream {
    /// Bytes per point.
    pub fn bytes_per_point(self) -> u64 {
        match self {
            Stream::Position => 12,
            Stream::Radius => 2,
            Stream::NormalField => 8,
            Stream::Classes(_) => 1,
            _ => 4,
        }
    }

    /// Name used in reports (`surfel info`).
    pub fn name(self) -> String {
        match self {
            Stream::Position => "position f32".into(),
            Stream::Coarse => "position q10 (coarse)".into(),
            Stream::Medium => "position q10 (medium)".into(),
            Stream::Fine => "position q10 (fine)".into(),
            Stream::Normal => "normal oct16".into(),
            Stream::Radius => "radius f16".into(),
            Stream::Color => "color rgba8".into(),
            Stream::Scalar(k) => format!("scalar {k} f32"),
            Stream::NormalField => "normal field 3×f16".into(),
            Stream::Classes(k) => format!("classes {k} u8"),
        }
    }
}

/// How a cloud maps onto streams: Morton order, batches and segments.
#[derive(Clone, Debug)]
pub struct StreamLayout {
    /// Stream position → index in the cloud.
    pub order: Vec<u32>,
    /// Batch bounds in stream order (`first` is the global stream index of its first point).
    pub batches: Vec<GpuBatch>,
    /// Points per segment (a multiple of `BATCH_POINTS`); the last segment may hold fewer.
    pub segment_points: u32,
    /// Streams present, in upload order.
    pub streams: Vec<Stream>,
    /// The packed linear normal fields in cloud order (`normal_field::pack`), when the
    /// layout has the `NormalField` stream.
    pub normal_field: Option<Vec<[u32; 2]>>,
}

impl StreamLayout {
    /// Orders `cloud` along a Morton curve over its bounding box (ties by index) and cuts it
    /// into batches; `segment_points` is rounded down to whole batches (at least one).
    /// `scalar` is the scalar field to upload (the one the frame is colored by), if any.
    pub fn new(cloud: &Cloud, segment_points: u64, scalar: Option<usize>) -> Result<Self, String> {
        let n = cloud.len();
        if n as u64 > u64::from(u32::MAX) {
            return Err(format!(
                "{n} points: at most {} fit 32-bit point indices",
                u32::MAX
            ));
        }
        let batch = u64::from(BATCH_POINTS);
        let segment_points = ((segment_points / batch).max(1) * batch).min(1 << 31) as u32;
        let order = morton_order(&cloud.positions);
        let batches = order
            .par_chunks(BATCH_POINTS as usize)
            .enumerate()
            .map(|(b, idx)| {
                let first = cloud.positions[idx[0] as usize];
                let (lo, hi) = idx.iter().fold((first, first), |(lo, hi), &i| {
                    let p = cloud.positions[i as usize];
                    (lo.min(p), hi.max(p))
                });
                GpuBatch {
                    min_x: lo.x,
                    min_y: lo.y,
                    min_z: lo.z,
                    first: (b as u64 * batch) as u32,
                    max_x: hi.x,
                    max_y: hi.y,
                    max_z: hi.z,
                    count: idx.len() as u32,
                }
            })
            .collect();
        let streams = Self::streams_for(cloud, scalar);
        Ok(Self {
            order,
            batches,
            segment_points,
            streams,
            normal_field: None,
        })
    }

    /// Adds the `NormalField` stream with the packed fields of every point, in cloud order.
    pub fn with_normal_field(mut self, field: Vec<[u32; 2]>) -> Self {
        debug_assert_eq!(field.len(), self.order.len());
        self.streams.push(Stream::NormalField);
        self.normal_field = Some(field);
        self
    }

    /// The streams a cloud needs: positions (f32 and quantized), normals, radii, colors when
    /// it has them, and scalar field `scalar` when one is colored by.
    pub fn streams_for(cloud: &Cloud, scalar: Option<usize>) -> Vec<Stream> {
        let mut streams = POSITION_STREAMS.to_vec();
        streams.extend([Stream::Normal, Stream::Radius]);
        if cloud.colors.is_some() {
            streams.push(Stream::Color);
        }
        streams.extend(
            scalar
                .filter(|&k| k < cloud.scalars.len())
                .map(Stream::Scalar),
        );
        streams
    }

    pub fn len(&self) -> u64 {
        self.order.len() as u64
    }

    pub fn is_empty(&self) -> bool {
        self.order.is_empty()
    }

    /// Stream index ranges of the segments.
    pub fn segments(&self) -> Vec<Range<u64>> {
        let step = u64::from(self.segment_points);
        (0..self.len().div_ceil(step))
            .map(|s| s * step..((s + 1) * step).min(self.len()))
            .collect()
    }

    /// Bytes of one stream over `points` points.
    pub fn stream_bytes(stream: Stream, points: u64) -> u64 {
        match stream {
            // Radii are packed in pairs: round up to whole words.
            Stream::Radius => points.div_ceil(2) * 4,
            // Classes are packed four to a word.
            Stream::Classes(_) => points.div_ceil(4) * 4,
            s => points * s.bytes_per_point(),
        }
    }

    /// Cloud index → stream index (for remapping triangle indices).
    pub fn inverse(&self) -> Vec<u32> {
        let mut inv = vec![0u32; self.order.len()];
        for (s, &c) in self.order.iter().enumerate() {
            inv[c as usize] = s as u32;
        }
        inv
    }

    /// Encodes every stream for stream indices `range` (an even start) into `out`, stream
    /// after stream in `self.streams` order, each `stream_bytes(stream, range.len())` long.
    /// The f32 and quantized positions are written in one pass (one gather and one
    /// quantization per point).
    pub fn encode_chunk(&self, cloud: &Cloud, range: Range<u64>, out: &mut [u8]) {
        let n = range.end - range.start;
        let mut rest = out;
        let mut slices = Vec::with_capacity(self.streams.len());
        for &stream in &self.streams {
            let (head, tail) = rest.split_at_mut(Self::stream_bytes(stream, n) as usize);
            slices.push((stream, head));
            rest = tail;
        }
        // Every layout starts with the four position streams (`streams_for`).
        let (positions, others) = slices.split_at_mut(POSITION_STREAMS.len());
        debug_assert!(positions.iter().map(|(s, _)| *s).eq(POSITION_STREAMS));
        let [(_, exact), (_, coarse), (_, medium), (_, fine)] = positions else {
            unreachable!("four position streams");
        };
        self.encode_positions(cloud, range.clone(), exact, [coarse, medium, fine]);
        for (stream, slice) in others {
            self.encode(cloud, *stream, range.clone(), slice);
        }
    }

    /// f32 positions and the three quantized words of stream indices `range`.
    fn encode_positions(
        &self,
        cloud: &Cloud,
        range: Range<u64>,
        exact: &mut [u8],
        words: [&mut [u8]; 3],
    ) {
        let ids = &self.order[range.start as usize..range.end as usize];
        let chunk = 4096;
        let [coarse, medium, fine] = words;
        exact
            .par_chunks_mut(chunk * 12)
            .zip(coarse.par_chunks_mut(chunk * 4))
            .zip(medium.par_chunks_mut(chunk * 4))
            .zip(fine.par_chunks_mut(chunk * 4))
            .zip(ids.par_chunks(chunk))
            .enumerate()
            .for_each(|(c, ((((e, w0), w1), w2), ids))| {
                let start = range.start + (c * chunk) as u64;
                let mut batch = u64::MAX;
                let mut scale = Quantizer::default();
                for (k, &i) in ids.iter().enumerate() {
                    let b = (start + k as u64) / u64::from(BATCH_POINTS);
                    if b != batch {
                        batch = b;
                        scale = Quantizer::new(&self.batches[b as usize]);
                    }
                    let p = cloud.positions[i as usize];
                    e[12 * k..12 * k + 12].copy_from_slice(bytemuck::bytes_of(&p.to_array()));
                    let q = scale.quantize(p);
                    for (w, out) in [&mut *w0, &mut *w1, &mut *w2].into_iter().enumerate() {
                        out[4 * k..4 * k + 4]
                            .copy_from_slice(&quant_word(q, w as u32).to_le_bytes());
                    }
                }
            });
    }

    /// Encodes stream `stream` for stream indices `range` (a start that is a multiple of 4, so
    /// radius pairs and class quadruples stay aligned) into `out`, which must be `stream_bytes(stream, range.len())` long.
    pub fn encode(&self, cloud: &Cloud, stream: Stream, range: Range<u64>, out: &mut [u8]) {
        debug_assert_eq!(
            out.len() as u64,
            Self::stream_bytes(stream, range.end - range.start)
        );
        let ids = &self.order[range.start as usize..range.end as usize];
        let chunk = 4096;
        match stream {
            Stream::Position => {
                out.par_chunks_mut(chunk * 12)
                    .zip(ids.par_chunks(chunk))
                    .for_each(|(o, ids)| {
                        for (o, &i) in o.chunks_exact_mut(12).zip(ids) {
                            let p = cloud.positions[i as usize];
                            o.copy_from_slice(bytemuck::bytes_of(&p.to_array()));
                        }
                    });
            }
            Stream::Coarse | Stream::Medium | Stream::Fine => {
                let word = match stream {
                    Stream::Coarse => 0,
                    Stream::Medium => 1,
                    _ => 2,
                };
                out.par_chunks_mut(chunk * 4)
                    .zip(ids.par_chunks(chunk))
                    .enumerate()
                    .for_each(|(c, (o, ids))| {
                        let start = range.start + (c * chunk) as u64;
                        for (k, (o, &i)) in o.chunks_exact_mut(4).zip(ids).enumerate() {
                            let b = &self.batches
                                [((start + k as u64) / u64::from(BATCH_POINTS)) as usize];
                            let q = quantize(cloud.positions[i as usize], b);
                            o.copy_from_slice(&quant_word(q, word).to_le_bytes());
                        }
                    });
            }
            Stream::Normal => {
                let normals = cloud.normals.as_deref();
                encode_words(out, ids, chunk, |i| {
                    oct_encode(normals.map_or(Vec3::Z, |n| n[i]))
                });
            }
            Stream::Color => {
                let colors = cloud.colors.as_deref();
                encode_words(out, ids, chunk, |i| {
                    u32::from_le_bytes(colors.map_or([255; 4], |c| c[i]))
                });
            }
            Stream::Scalar(k) => {
                let values = &cloud.scalars[k].values;
                encode_words(out, ids, chunk, |i| values[i].to_bits());
            }
            Stream::NormalField => {
                let field = self.normal_field.as_deref().unwrap_or_default();
                out.par_chunks_mut(chunk * 8)
                    .zip(ids.par_chunks(chunk))
                    .for_each(|(o, ids)| {
                        for (o, &i) in o.chunks_exact_mut(8).zip(ids) {
                            let w = field.get(i as usize).copied().unwrap_or_default();
                            o[..4].copy_from_slice(&w[0].to_le_bytes());
                            o[4..].copy_from_slice(&w[1].to_le_bytes());
                        }
                    });
            }
            Stream::Classes(k) => {
                let values = &cloud.scalars[k].values;
                let class = |i: Option<&u32>| {
                    i.map_or(0, |&i| {
                        u32::from(crate::scene::clip::class_of(values[i as usize]))
                    })
                };
                out.par_chunks_mut(chunk * 4)
                    .zip(ids.par_chunks(chunk * 4))
                    .for_each(|(o, ids)| {
                        for (k, o) in o.chunks_exact_mut(4).enumerate() {
                            let w = (0..4).fold(0, |w, b| w | class(ids.get(4 * k + b)) << (8 * b));
                            o.copy_from_slice(&u32::to_le_bytes(w));
                        }
                    });
            }
            Stream::Radius => {
                let radii = cloud.radii.as_deref();
                let half = |i: Option<&u32>| {
                    i.map_or(0, |&i| {
                        half::f16::from_f32(radii.map_or(0.0, |r| r[i as usize])).to_bits() as u32
                    })
                };
                out.par_chunks_mut(chunk * 4)
                    .zip(ids.par_chunks(chunk * 2))
                    .for_each(|(o, ids)| {
                        for (k, o) in o.chunks_exact_mut(4).enumerate() {
                            let w = half(ids.get(2 * k)) | (half(ids.get(2 * k + 1)) << 16);
                            o.copy_from_slice(&w.to_le_bytes());
                        }
                    });
            }
        }
    }
}

fn encode_words(out: &mut [u8], ids: &[u32], chunk: usize, f: impl Fn(usize) -> u32 + Sync) {
    out.par_chunks_mut(chunk * 4)
        .zip(ids.par_chunks(chunk))
        .for_each(|(o, ids)| {
            for (o, &i) in o.chunks_exact_mut(4).zip(ids) {
                o.copy_from_slice(&f(i as usize).to_le_bytes());
            }
        });
}

/// Maps positions to `QUANT_FULL_BITS` cells per axis of one batch box.
#[derive(Clone, Copy, Debug, Default)]
struct Quantizer {
    lo: [f64; 3],
    /// Cells per unit length (0 for a flat axis).
    scale: [f64; 3],
}

impl Quantizer {
    fn new(b: &GpuBatch) -> Self {
        let lo = [b.min_x, b.min_y, b.min_z].map(f64::from);
        let hi = [b.max_x, b.max_y, b.max_z].map(f64::from);
        let cells = (1u64 << QUANT_FULL_BITS) as f64;
        Self {
            lo,
            scale: std::array::from_fn(|a| {
                let extent = hi[a] - lo[a];
                if extent > 0.0 {
                    cells / extent
                } else {
                    0.0
                }
            }),
        }
    }

    fn quantize(&self, p: Vec3) -> [u32; 3] {
        let max = ((1u64 << QUANT_FULL_BITS) - 1) as f64;
        let p = p.to_array();
        std::array::from_fn(|a| {
            ((f64::from(p[a]) - self.lo[a]) * self.scale[a]).clamp(0.0, max) as u32
        })
    }
}

/// Whether the compute rasterizer projects batch `b` under `view_proj`: the same test as
/// `glsl/compute/raster.comp`, which skips a batch when all eight corners of its box lie
/// outside one of the left, right, bottom, top and near clip planes (reversed infinite Z has
/// no far plane).
pub fn batch_visible(view_proj: Mat4, b: &GpuBatch) -> bool {
    let (lo, hi) = (
        Vec3::new(b.min_x, b.min_y, b.min_z),
        Vec3::new(b.max_x, b.max_y, b.max_z),
    );
    let mut out = [true; 5];
    for k in 0..8 {
        let p = Vec3::new(
            if k & 1 != 0 { hi.x } else { lo.x },
            if k & 2 != 0 { hi.y } else { lo.y },
            if k & 4 != 0 { hi.z } else { lo.z },
        );
        let c = view_proj * p.extend(1.0);
        let inside = [c.x >= -c.w, c.x <= c.w, c.y >= -c.w, c.y <= c.w, c.z <= c.w];
        for (o, i) in out.iter_mut().zip(inside) {
            *o &= !i;
        }
    }
    !out.iter().any(|&o| o)
}

/// Points in the batches [`batch_visible`] keeps: what a batch-culling method projects in a
/// frame (O(batches), one per `BATCH_POINTS` points).
pub fn projected_points(view_proj: Mat4, batches: &[GpuBatch]) -> u64 {
    batches
        .iter()
        .filter(|b| batch_visible(view_proj, b))
        .map(|b| u64::from(b.count))
        .sum()
}

/// `p` quantized to `QUANT_FULL_BITS` per axis relative to the batch box.
pub fn quantize(p: Vec3, b: &GpuBatch) -> [u32; 3] {
    Quantizer::new(b).quantize(p)
}

/// Word `word` (0 coarse, 1 medium, 2 fine) of a quantized position: `QUANT_BITS` of each
/// axis, x in the low bits.
pub fn quant_word(q: [u32; 3], word: u32) -> u32 {
    let shift = QUANT_BITS * (2 - word);
    let mask = (1 << QUANT_BITS) - 1;
    q.iter().enumerate().fold(0, |w, (a, &v)| {
        w | (((v >> shift) & mask) << (QUANT_BITS * a as u32))
    })
}

/// Decodes the first `words` words (1..=3) of a quantized position to the centre of its
/// cell (mirrors `dequantize` in glsl/common/streams.glsl).
pub fn dequantize(w: [u32; 3], words: u32, b: &GpuBatch) -> Vec3 {
    let mask = (1 << QUANT_BITS) - 1;
    let lo = Vec3::new(b.min_x, b.min_y, b.min_z);
    let extent = Vec3::new(b.max_x, b.max_y, b.max_z) - lo;
    let bits = QUANT_BITS * words;
    let q = Vec3::from_array(std::array::from_fn(|a| {
        let v = (0..words).fold(0u32, |v, k| {
            (v << QUANT_BITS) | ((w[k as usize] >> (QUANT_BITS * a as u32)) & mask)
        });
        v as f32 + 0.5
    }));
    lo + extent * q / (1u64 << bits) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::SplitMix64;

    fn random_cloud(n: usize, seed: u64) -> Cloud {
        let mut rng = SplitMix64::new(seed);
        Cloud {
            positions: (0..n)
                .map(|_| {
                    let mut f = || rng.next_f64() as f32;
                    Vec3::new(f(), f() * 3.0, f() - 7.0)
                })
                .collect(),
            radii: Some((0..n).map(|i| i as f32 * 1e-3).collect()),
            ..Default::default()
        }
    }

    #[test]
    fn order_is_a_permutation_and_batches_bound_their_points() {
        let cloud = random_cloud(25_000, 7);
        let layout = StreamLayout::new(&cloud, 20_480, None).unwrap();
        let mut seen = layout.order.clone();
        seen.sort_unstable();
        assert!(seen.iter().enumerate().all(|(i, &v)| i as u32 == v));
        assert_eq!(layout.batches.len(), 3);
        assert_eq!(
            layout.batches.iter().map(|b| b.count).collect::<Vec<_>>(),
            [10_240, 10_240, 4_520]
        );
        for (k, b) in layout.batches.iter().enumerate() {
            assert_eq!(b.first, k as u32 * BATCH_POINTS);
            for &i in &layout.order[b.first as usize..(b.first + b.count) as usize] {
                let p = cloud.positions[i as usize];
                assert!(p.x >= b.min_x && p.y >= b.min_y && p.z >= b.min_z);
                assert!(p.x <= b.max_x && p.y <= b.max_y && p.z <= b.max_z);
            }
        }
        // Morton batches are compact: far smaller than the whole cloud's box.
        let volume = |b: &GpuBatch| (b.max_x - b.min_x) * (b.max_y - b.min_y) * (b.max_z - b.min_z);
        assert!(volume(&layout.batches[0]) < 0.6 * 3.0);
        assert_eq!(layout.segments(), vec![0..20_480, 20_480..25_000]);
        let inv = layout.inverse();
        assert!(layout
            .order
            .iter()
            .enumerate()
            .all(|(s, &c)| inv[c as usize] == s as u32));
    }

    #[test]
    fn batches_outside_the_frustum_are_not_projected() {
        let camera = crate::scene::Camera::look_at(Vec3::new(0.0, 0.0, 10.0), Vec3::ZERO, 1.0);
        let vp = camera.projection(1.0) * camera.view();
        let batch = |lo: Vec3, hi: Vec3, count: u32| GpuBatch {
            min_x: lo.x,
            min_y: lo.y,
            min_z: lo.z,
            first: 0,
            max_x: hi.x,
            max_y: hi.y,
            max_z: hi.z,
            count,
        };
        let centre = batch(Vec3::splat(-0.5), Vec3::splat(0.5), 100);
        let left = batch(
            Vec3::new(-200.0, -0.5, -0.5),
            Vec3::new(-100.0, 0.5, 0.5),
            10,
        );
        let behind = batch(Vec3::new(-0.5, -0.5, 20.0), Vec3::new(0.5, 0.5, 30.0), 20);
        // Straddles the left plane: partly inside, so projected.
        let edge = batch(Vec3::new(-100.0, -0.5, -0.5), Vec3::new(0.0, 0.5, 0.5), 30);
        // Surrounds the camera: corners on both sides of every plane.
        let around = batch(Vec3::splat(-50.0), Vec3::splat(50.0), 40);
        assert!(batch_visible(vp, &centre));
        assert!(!batch_visible(vp, &left));
        assert!(!batch_visible(vp, &behind));
        assert!(batch_visible(vp, &edge));
        assert!(batch_visible(vp, &around));
        assert_eq!(
            projected_points(vp, &[centre, left, behind, edge, around]),
            170
        );
    }

    #[test]
    fn segments_are_whole_batches() {
        let cloud = random_cloud(100, 1);
        let layout = StreamLayout::new(&cloud, 5, None).unwrap();
        assert_eq!(layout.segment_points, BATCH_POINTS);
        assert_eq!(layout.segments(), vec![0..100]);
        let empty = StreamLayout::new(&Cloud::default(), 1 << 30, None).unwrap();
        assert!(empty.is_empty() && empty.batches.is_empty() && empty.segments().is_empty());
    }

    #[test]
    fn quantized_words_refine_to_the_cell_size() {
        let cloud = random_cloud(5_000, 3);
        let layout = StreamLayout::new(&cloud, 1 << 30, None).unwrap();
        let b = layout.batches[0];
        let extent = Vec3::new(b.max_x - b.min_x, b.max_y - b.min_y, b.max_z - b.min_z);
        let mut words = vec![[0u32; 3]; 5_000];
        for (w, stream) in [Stream::Coarse, Stream::Medium, Stream::Fine]
            .into_iter()
            .enumerate()
        {
            let mut out = vec![0u8; 20_000];
            layout.encode(&cloud, stream, 0..5_000, &mut out);
            for (k, c) in out.chunks_exact(4).enumerate() {
                words[k][w] = u32::from_le_bytes(c.try_into().unwrap());
            }
        }
        for (k, w) in words.iter().enumerate() {
            let p = cloud.positions[layout.order[k] as usize];
            for level in 1..=3u32 {
                let cell = extent / (1u64 << (QUANT_BITS * level)) as f32;
                let err = (dequantize(*w, level, &b) - p).abs();
                // Half a cell, plus f32 rounding of the reconstruction.
                let bound = cell * 0.5 + extent * 1e-6;
                assert!(err.cmple(bound).all(), "level {level}: {err} > {bound}");
            }
        }
    }

    #[test]
    fn streams_encode_attributes_in_stream_order() {
        let mut cloud = random_cloud(7, 9);
        cloud.colors = Some((0..7).map(|i| [i as u8, 0, 0, 255]).collect());
        let layout = StreamLayout::new(&cloud, 1 << 30, None).unwrap();
        assert!(layout.streams.contains(&Stream::Color));
        let mut pos = vec![0u8; 7 * 12];
        layout.encode(&cloud, Stream::Position, 0..7, &mut pos);
        let floats: &[f32] = bytemuck::cast_slice(&pos);
        let mut colors = vec![0u8; 28];
        layout.encode(&cloud, Stream::Color, 0..7, &mut colors);
        let mut radii = vec![0u8; StreamLayout::stream_bytes(Stream::Radius, 7) as usize];
        assert_eq!(radii.len(), 16);
        layout.encode(&cloud, Stream::Radius, 0..7, &mut radii);
        let halves: &[u16] = bytemuck::cast_slice(&radii);
        for (s, &c) in layout.order.iter().enumerate() {
            let p = cloud.positions[c as usize];
            assert_eq!(&floats[3 * s..3 * s + 3], &p.to_array());
            assert_eq!(colors[4 * s], c as u8);
            let r = half::f16::from_bits(halves[s]).to_f32();
            assert!((r - c as f32 * 1e-3).abs() < 1e-5);
        }
        assert_eq!(halves[7], 0, "the padding half is zero");
    }

    #[test]
    fn a_fused_chunk_equals_the_streams_encoded_one_by_one() {
        let mut cloud = random_cloud(30_000, 5);
        cloud.colors = Some((0..30_000).map(|i| [i as u8, 1, 2, 3]).collect());
        for name in ["a", "b"] {
            cloud.scalars.push(crate::scene::Scalar {
                name: name.into(),
                values: (0..30_000).map(|i| i as f32 * 0.5).collect(),
            });
        }
        // Only the selected scalar field becomes a stream.
        assert!(!StreamLayout::streams_for(&cloud, None).contains(&Stream::Scalar(0)));
        let layout = StreamLayout::new(&cloud, 1 << 30, Some(1)).unwrap();
        assert_eq!(layout.streams.last(), Some(&Stream::Scalar(1)));
        assert!(!layout.streams.contains(&Stream::Scalar(0)));
        let range = 10_240..25_002;
        let n = range.end - range.start;
        let mut separate = Vec::new();
        for &s in &layout.streams {
            let mut out = vec![0u8; StreamLayout::stream_bytes(s, n) as usize];
            layout.encode(&cloud, s, range.clone(), &mut out);
            separate.extend(out);
        }
        let mut fused = vec![0u8; separate.len()];
        layout.encode_chunk(&cloud, range, &mut fused);
        assert!(fused == separate, "fused chunk differs");
    }
}

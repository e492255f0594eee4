//! LAS/LAZ reader. Headers and LAZ (compressed) points are read by the `las` crate;
//! uncompressed point records have a fixed size and are decoded here, in parallel, streamed from
//! the file in blocks.
//!
//! Coordinates are scaled and offset in f64 (`scale * X + offset`, as the crate does); the f64
//! bounding-box centre becomes [`Cloud::origin`] and is subtracted in f64 before the conversion
//! to f32, so large projected coordinates keep their centimetre grid. RGB is kept (8-bit values
//! stored in the 16-bit fields, as many writers do, are detected and used as is; true 16-bit
//! values are shifted down). Intensity, classification (12, "overlap", reads as 1,
//! "unclassified", as in the crate), return number, number of returns, point source id, GPS
//! time (in seconds after the file's earliest, which is `stats.gps_time_origin`: f32 cannot
//! hold absolute GPS times; the times are kept in f64 until the earliest is known) and, in
//! formats 8 and 10, NIR become scalars, and so does every field an extra-bytes VLR (LASF_Spec
//! record 4, LAS 1.4 R15 §2.5.8) describes, by its name, with its scale and offset.

use std::fs::File;
use std::io::{BufReader, Cursor, ErrorKind, Read, Seek};
use std::path::Path;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::cloud::{Bounds, Cloud, LasSummary, LoadStats, Scalar};
use super::error::{show, LoadError};
use super::guard;
use super::progress::Progress;
use super::records::{self, Span};

/// The LAS classification code for overlap points, which the `las` crate reads as unclassified.
const OVERLAP: u8 = 12;

/// Reads the header and VLRs of a file of `size` bytes, leaving `read` at the first point record.
pub(crate) fn read_header<R: Read + Seek>(
    file: &str,
    read: &mut R,
    size: usize,
) -> Result<las::Header, LoadError> {
    check_header(file, read, size as u64)?;
    read.rewind().map_err(|source| io_error(file, source))?;
    guard::third_party(|| las::Header::new(read))
        .map_err(|e| LoadError::whole(file, format!("invalid LAS header: {e}")))?
        .map_err(|e| header_error(file, e, size))
}

/// The `len` bytes at byte `at` of `read`.
fn bytes_at<R: Read + Seek>(read: &mut R, at: u64, len: usize) -> std::io::Result<Vec<u8>> {
    read.seek(std::io::SeekFrom::Start(at))?;
    let mut bytes = vec![0; len];
    read.read_exact(&mut bytes)?;
    Ok(bytes)
}

/// Checks what the `las` crate would trust in the header of a file of `size` bytes before it
/// reads it: the signature, version, header size, point format and the offset to the points,
/// and that every VLR ends before the points and every EVLR inside the file (the crate
/// allocates what their lengths say, and walks as many as the header counts).
fn check_header<R: Read + Seek>(file: &str, read: &mut R, size: u64) -> Result<(), LoadError> {
    let io = |source| io_error(file, source);
    let at = |offset: u64, message: String| LoadError::at_byte(file, offset as usize, message);
    if size < 227 {
        let head = bytes_at(read, 0, size.min(4) as usize).map_err(io)?;
        if head.len() == 4 && head != b"LASF" {
            return Err(at(
                0,
                format!(
                    "expected the LAS signature \"LASF\", found \"{}\"",
                    show(&head)
                ),
            ));
        }
        return Err(LoadError::whole(
            file,
            format!("invalid LAS header: the file ends at byte {size}, inside the 227-byte header (truncated file?)"),
        ));
    }
    let h = bytes_at(read, 0, 227).map_err(io)?;
    let u16_at = |o: usize| u64::from(u16::from_le_bytes([h[o], h[o + 1]]));
    let u32_at = |o: usize| u64::from(u32::from_le_bytes([h[o], h[o + 1], h[o + 2], h[o + 3]]));
    if &h[..4] != b"LASF" {
        return Err(at(
            0,
            format!(
                "expected the LAS signature \"LASF\", found \"{}\"",
                show(&h[..4])
            ),
        ));
    }
    let (major, minor) = (h[24], h[25]);
    if major != 1 || minor > 4 {
        return Err(at(
            24,
            format!("expected LAS version 1.0 to 1.4, found {major}.{minor}"),
        ));
    }
    let header_size = u16_at(94);
    let minimum = match minor {
        0..=2 => 227,
        3 => 235,
        _ => 375,
    };
    if header_size < minimum {
        return Err(at(94, format!("header size {header_size} is smaller than the {minimum} bytes of a LAS 1.{minor} header")));
    }
    if header_size > size {
        return Err(at(94, format!("header size {header_size} is past the end of the file at byte {size} (truncated file?)")));
    }
    let format = h[104] & 0x3f;
    if format > 10 {
        return Err(at(
            104,
            format!("expected a point data format 0 to 10, found {format}"),
        ));
    }
    let points_at = u32_at(96);
    if points_at > size {
        return Err(at(96, format!("the point data starts at byte {points_at}, past the end of the file at byte {size} (truncated file?)")));
    }
    if points_at < header_size {
        return Err(at(
            96,
            format!("the point data offset {points_at} is inside the {header_size}-byte header"),
        ));
    }
    let record = u16_at(105);
    let legacy = u32_at(107);
    let points = if minor >= 4 {
        let b = bytes_at(read, 247, 8).map_err(io)?;
        legacy.max(u64::from_le_bytes(b.try_into().unwrap_or_default()))
    } else {
        legacy
    };
    if points.checked_mul(record).is_none() {
        return Err(at(
            if minor >= 4 { 247 } else { 107 },
            format!("the header declares {points} points of {record} bytes, more than 2^64 bytes"),
        ));
    }
    let vlrs = u32_at(100);
    let mut vlr = header_size;
    for i in 0..vlrs {
        let length = if vlr + 54 <= points_at {
            let head = bytes_at(read, vlr, 54).map_err(io)?;
            u64::from(u16::from_le_bytes([head[20], head[21]]))
        } else {
            0
        };
        if vlr + 54 + length > points_at {
            return Err(at(vlr, format!("the header declares {vlrs} VLRs, but VLR {i} ends past the start of the point data at byte {points_at}")));
        }
        vlr += 54 + length;
    }
    if minor < 4 {
        return Ok(());
    }
    let h = bytes_at(read, 235, 12).map_err(io)?;
    let mut evlr = u64::from_le_bytes(h[..8].try_into().unwrap_or_default());
    let evlrs = u64::from(u32::from_le_bytes(h[8..].try_into().unwrap_or_default()));
    for i in 0..evlrs {
        let length = if evlr.checked_add(60).is_some_and(|end| end <= size) {
            let head = bytes_at(read, evlr, 60).map_err(io)?;
            u64::from_le_bytes(head[20..28].try_into().unwrap_or_default())
        } else {
            u64::MAX
        };
        let end = evlr.checked_add(60).and_then(|e| e.checked_add(length));
        if evlr < points_at || end.is_none_or(|end| end > size) {
            return Err(at(evlr, format!("the header declares {evlrs} EVLRs, but EVLR {i} at byte {evlr} is not inside the file of {size} bytes after the points")));
        }
        evlr = end.unwrap_or(size);
    }
    Ok(())
}

/// The error for a header the `las` crate rejects: an operating-system failure is
/// [`LoadError::Io`], an early end of the file says where the file ends.
fn header_error(file: &str, err: las::Error, size: usize) -> LoadError {
    match err {
        las::Error::Io(e) if e.kind() == ErrorKind::UnexpectedEof => LoadError::whole(
            file,
            format!("invalid LAS header: the file ends at byte {size}, inside the header (truncated file?)"),
        ),
        las::Error::Io(source) => io_error(file, source),
        e => LoadError::whole(file, format!("invalid LAS header: {e}")),
    }
}

/// Records the `las` crate decodes per call (an error names the first of them).
const CRATE_BLOCK_POINTS: u64 = 1024;

/// The message for point record `index` of `declared` that a file of `size` bytes cuts short.
fn truncated(index: u64, declared: u64, size: usize) -> String {
    format!(
        "point record {index} of {declared} ends past the end of the file at byte {size} (truncated file?)"
    )
}

/// The storage type of an extra-bytes field (data types 1-10 of LAS 1.4 R15 table 24).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
}

impl Kind {
    const ALL: [Kind; 10] = [
        Kind::U8,
        Kind::I8,
        Kind::U16,
        Kind::I16,
        Kind::U32,
        Kind::I32,
        Kind::U64,
        Kind::I64,
        Kind::F32,
        Kind::F64,
    ];

    fn size(self) -> usize {
        match self {
            Kind::U8 | Kind::I8 => 1,
            Kind::U16 | Kind::I16 => 2,
            Kind::U32 | Kind::I32 | Kind::F32 => 4,
            Kind::U64 | Kind::I64 | Kind::F64 => 8,
        }
    }

    /// The value at the start of `b` (at least `size` bytes).
    fn read(self, b: &[u8]) -> f64 {
        let a = |n: usize| -> [u8; 8] {
            let mut w = [0; 8];
            w[..n].copy_from_slice(&b[..n]);
            w
        };
        match self {
            Kind::U8 => f64::from(b[0]),
            Kind::I8 => f64::from(b[0] as i8),
            Kind::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Kind::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Kind::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Kind::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Kind::U64 => u64::from_le_bytes(a(8)) as f64,
            Kind::I64 => i64::from_le_bytes(a(8)) as f64,
            Kind::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Kind::F64 => f64::from_le_bytes(a(8)),
        }
    }
}

/// How one scalar field is read from a point record.
#[derive(Clone, Copy, Debug)]
enum Decode {
    /// `kind` at byte `at`, then `* scale + offset`.
    Value {
        at: usize,
        kind: Kind,
        scale: f64,
        offset: f64,
    },
    /// `(byte >> shift) & mask` of byte `at`.
    Bits { at: usize, shift: u8, mask: u8 },
    /// The classification code at byte `at` under `mask`; overlap reads as unclassified.
    Class { at: usize, mask: u8 },
    /// The GPS time's column (the f64 time is at `Layout::time_at`): decoded as 0, then
    /// filled by [`finish`] from the f64 times once the earliest is known.
    Time,
}

impl Decode {
    /// Decodes the field of every record of `stride` bytes in `records` into `out`, one field
    /// at a time over a block that stays in cache (the common fields without a per-record
    /// dispatch).
    fn fill(self, records: &[u8], stride: usize, out: &mut [f32]) {
        let rows = records.chunks_exact(stride).zip(out);
        match self {
            Decode::Value {
                at,
                kind: Kind::U16,
                scale,
                offset,
            } if scale == 1.0 && offset == 0.0 => {
                rows.for_each(|(r, o)| *o = f32::from(u16_at(r, at)));
            }
            Decode::Bits { at, shift, mask } => {
                rows.for_each(|(r, o)| *o = f32::from((r[at] >> shift) & mask));
            }
            d => rows.for_each(|(r, o)| *o = d.read(r)),
        }
    }

    fn read(self, r: &[u8]) -> f32 {
        match self {
            Decode::Value {
                at,
                kind,
                scale,
                offset,
            } => (kind.read(&r[at..]) * scale + offset) as f32,
            Decode::Bits { at, shift, mask } => f32::from((r[at] >> shift) & mask),
            Decode::Class { at, mask } => {
                let code = r[at] & mask;
                f32::from(if code == OVERLAP { 1 } else { code })
            }
            Decode::Time => 0.0,
        }
    }
}

/// A field described by the extra-bytes VLR: its name and where it is in the bytes that follow
/// a record's standard fields.
#[derive(Clone, Debug)]
pub(crate) struct ExtraField {
    pub(crate) name: String,
    decode: Decode,
}

impl ExtraField {
    /// The field's value in `extra`, the bytes after a record's standard fields.
    pub(crate) fn read(&self, extra: &[u8]) -> f32 {
        self.decode.read(extra)
    }
}

/// Size of one extra-bytes descriptor.
const DESCRIPTOR_BYTES: usize = 192;

/// The fields the extra-bytes VLRs of `header` describe. Fails on a VLR that is not a whole
/// number of descriptors, an unknown data type, or fields that need more bytes than the point
/// records have after their standard fields.
pub(crate) fn extra_fields(file: &str, header: &las::Header) -> Result<Vec<ExtraField>, LoadError> {
    let format = header.point_format();
    let available = usize::from(format.extra_bytes);
    let mut fields = Vec::new();
    let mut at = 0;
    let descriptors = header
        .all_vlrs()
        .filter(|v| v.user_id.trim_end_matches('\0') == "LASF_Spec" && v.record_id == 4);
    for vlr in descriptors {
        if vlr.data.len() % DESCRIPTOR_BYTES != 0 {
            return Err(LoadError::whole(
                file,
                format!(
                    "extra-bytes VLR (LASF_Spec record 4) holds {} bytes, not a whole number of \
                     {DESCRIPTOR_BYTES}-byte descriptors (truncated?)",
                    vlr.data.len()
                ),
            ));
        }
        for d in vlr.data.chunks_exact(DESCRIPTOR_BYTES) {
            let index = fields.len();
            let raw_name = String::from_utf8_lossy(&d[4..36]);
            let name = raw_name.trim_end_matches('\0').trim();
            let name = if name.is_empty() {
                format!("extra_{index}")
            } else {
                name.to_owned()
            };
            let (data_type, options) = (d[2], d[3]);
            let f64_at = |o: usize| f64::from_le_bytes(d[o..o + 8].try_into().expect("8 bytes"));
            let scale = if options & 8 != 0 { f64_at(112) } else { 1.0 };
            let offset = if options & 16 != 0 { f64_at(136) } else { 0.0 };
            // 0: undocumented bytes (the options byte holds their count); 1-10: one value;
            // 11-30: the deprecated arrays of 2 or 3 values.
            let (kind, count) = match data_type {
                0 => {
                    at += usize::from(options);
                    continue;
                }
                1..=30 => (
                    Kind::ALL[usize::from((data_type - 1) % 10)],
                    usize::from((data_type - 1) / 10 + 1),
                ),
                t => {
                    return Err(LoadError::whole(
                        file,
                        format!(
                            "extra-bytes descriptor {index} ('{name}'): unknown data type {t} \
                             (expected 0..=30)"
                        ),
                    ))
                }
            };
            for k in 0..count {
                fields.push(ExtraField {
                    name: if count == 1 {
                        name.clone()
                    } else {
                        format!("{name}_{k}")
                    },
                    decode: Decode::Value {
                        at,
                        kind,
                        scale,
                        offset,
                    },
                });
                at += kind.size();
            }
        }
    }
    if at > available {
        return Err(LoadError::whole(
            file,
            format!(
                "the extra-bytes descriptors describe {at} bytes per point, but the records of \
                 point format {} have {available} bytes after their standard fields",
                format.to_u8().unwrap_or(0)
            ),
        ));
    }
    Ok(fields)
}

/// The scalar fields of every record of `format`: the standard ones, then the extra bytes'.
/// The scalar fields every point record has, as `surfel info` names them (the COPC reader's
/// too).
pub(crate) const STANDARD_NAMES: [&str; 5] = [
    "intensity",
    "classification",
    "return_number",
    "number_of_returns",
    "point_source_id",
];

/// `point`'s values of [`STANDARD_NAMES`].
pub(crate) fn standard_values(point: &las::Point) -> [f32; 5] {
    [
        f32::from(point.intensity),
        f32::from(u8::from(point.classification)),
        f32::from(point.return_number),
        f32::from(point.number_of_returns),
        f32::from(point.point_source_id),
    ]
}

fn standard_names(format: &las::point::Format) -> Vec<&'static str> {
    let mut names = STANDARD_NAMES.to_vec();
    if format.has_gps_time {
        names.push("gps_time");
    }
    if format.has_nir {
        names.push("nir");
    }
    names
}

/// Where the fields of an uncompressed point record are, and how coordinates are scaled.
struct Layout {
    span: Span,
    transforms: las::Vector<las::Transform>,
    /// Byte offset of red, green and blue (u16 each) when the format has colors.
    color_at: Option<usize>,
    /// Names and decoders of the scalar fields, standard fields first.
    fields: Vec<(String, Decode)>,
    /// Byte offset of the GPS time when the format has one.
    time_at: Option<usize>,
}

impl Layout {
    /// The layout of `header`'s records, which start at byte `at` of a file of `size` bytes.
    /// Fails before anything is allocated when the declared points cannot fit in the file.
    fn new(file: &str, header: &las::Header, at: usize, size: usize) -> Result<Self, LoadError> {
        let stride = usize::from(header.point_format().len()).max(1);
        let declared = header.number_of_points();
        let needed = u128::from(declared) * stride as u128 + at as u128;
        if needed > size as u128 {
            let whole = (size.saturating_sub(at) / stride) as u64;
            return Err(LoadError::whole(file, truncated(whole, declared, size)));
        }
        Self::at(file, header, at)
    }

    /// The layout of `header`'s records starting at byte `at` of a buffer that holds them all.
    fn at(file: &str, header: &las::Header, at: usize) -> Result<Self, LoadError> {
        let format = header.point_format();
        let extra = extra_fields(file, header)?;
        let stride = usize::from(format.len()).max(1);
        let declared = header.number_of_points();
        // Fixed part: X, Y, Z, intensity, flags (2 bytes, or 3 in formats 6-10), then scan
        // angle, user data and point source id; GPS time and colors follow.
        let base = if format.is_extended { 22 } else { 20 };
        let gps = if format.has_gps_time { 8 } else { 0 };
        let ext = format.is_extended;
        let return_bits = if ext { 4 } else { 3 };
        let mut decoders = vec![
            Decode::Value {
                at: 12,
                kind: Kind::U16,
                scale: 1.0,
                offset: 0.0,
            },
            Decode::Class {
                at: if ext { 16 } else { 15 },
                mask: if ext { 0xff } else { 0x1f },
            },
            Decode::Bits {
                at: 14,
                shift: 0,
                mask: (1 << return_bits) - 1,
            },
            Decode::Bits {
                at: 14,
                shift: return_bits,
                mask: (1 << return_bits) - 1,
            },
            Decode::Value {
                at: if ext { 20 } else { 18 },
                kind: Kind::U16,
                scale: 1.0,
                offset: 0.0,
            },
        ];
        if format.has_gps_time {
            decoders.push(Decode::Time);
        }
        if format.has_nir {
            decoders.push(Decode::Value {
                at: base + gps + 6,
                kind: Kind::U16,
                scale: 1.0,
                offset: 0.0,
            });
        }
        let standard_len = stride - usize::from(format.extra_bytes);
        let mut fields: Vec<(String, Decode)> = standard_names(format)
            .into_iter()
            .map(str::to_owned)
            .zip(decoders)
            .collect();
        fields.extend(extra.into_iter().map(|f| {
            let decode = match f.decode {
                Decode::Value {
                    at,
                    kind,
                    scale,
                    offset,
                } => Decode::Value {
                    at: standard_len + at,
                    kind,
                    scale,
                    offset,
                },
                other => other,
            };
            (f.name, decode)
        }));
        Ok(Layout {
            span: Span {
                at,
                count: declared as usize,
                stride,
            },
            transforms: *header.transforms(),
            color_at: format.has_color.then_some(base + gps),
            fields,
            time_at: format.has_gps_time.then_some(base),
        })
    }

    /// The decoded columns for every record, before any is decoded.
    fn columns(&self) -> Columns {
        let n = self.span.count;
        Columns {
            raw: records::filled([0; 3], n),
            colors: self.color_at.map(|_| records::filled([0, 0, 0, 255], n)),
            scalars: self
                .fields
                .iter()
                .map(|_| records::filled(0.0, n))
                .collect(),
            times: match self.time_at {
                Some(_) => records::filled(0.0, n),
                None => Vec::new(),
            },
            bounds: Bounds::EMPTY,
            sixteen_bit: false,
        }
    }

    fn world(&self, raw: [i32; 3]) -> DVec3 {
        let t = &self.transforms;
        DVec3::new(t.x.direct(raw[0]), t.y.direct(raw[1]), t.z.direct(raw[2]))
    }
}

/// Point columns while decoding: coordinates stay raw until the origin is known.
struct Columns {
    raw: Vec<[i32; 3]>,
    colors: Option<Vec<[u8; 4]>>,
    /// One column per field of `Layout::fields`.
    scalars: Vec<Vec<f32>>,
    /// The GPS time of every record when the format has one.
    times: Vec<f64>,
    /// Bounds of the (scaled) points decoded so far.
    bounds: Bounds,
    /// Whether a color channel above 255 was seen (true 16-bit colors).
    sixteen_bit: bool,
}

/// The little-endian u16 at byte `at` of a record.
fn u16_at(r: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([r[at], r[at + 1]])
}

/// The little-endian i32 at byte `at` of a record.
fn i32_at(r: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([r[at], r[at + 1], r[at + 2], r[at + 3]])
}

impl Columns {
    /// Decodes the whole records in `bytes`, which are points `first..`, in parallel.
    fn decode_block(&mut self, layout: &Layout, first: usize, bytes: &[u8]) {
        let stride = layout.span.stride;
        let per_task = records::task_records(stride);
        let rows = first..first + bytes.len() / stride;
        let shift = self.sixteen_bit;
        if let Some(at) = layout.time_at {
            self.times[rows.clone()]
                .par_chunks_mut(per_task)
                .zip(bytes.par_chunks(per_task * stride))
                .for_each(|(times, b)| {
                    for (t, r) in times.iter_mut().zip(b.chunks_exact(stride)) {
                        *t = Kind::F64.read(&r[at..]);
                    }
                });
        }
        // Per task, its slice of every scalar column.
        let mut columns: Vec<Vec<&mut [f32]>> = Vec::new();
        for column in &mut self.scalars {
            for (t, chunk) in column[rows.clone()].chunks_mut(per_task).enumerate() {
                if columns.len() <= t {
                    columns.push(Vec::with_capacity(layout.fields.len()));
                }
                columns[t].push(chunk);
            }
        }
        let (bounds, max_channel) = self.raw[rows.clone()]
            .par_chunks_mut(per_task)
            .zip(columns.into_par_iter())
            .zip(bytes.par_chunks(per_task * stride))
            .map(|((raw, mut columns), b)| {
                let mut bounds = Bounds::EMPTY;
                for (r, xyz) in b.chunks_exact(stride).zip(raw) {
                    *xyz = [i32_at(r, 0), i32_at(r, 4), i32_at(r, 8)];
                    bounds.add(layout.world(*xyz));
                }
                for ((_, decode), column) in layout.fields.iter().zip(columns.iter_mut()) {
                    decode.fill(b, stride, column);
                }
                let max_channel = layout.color_at.map_or(0, |at| {
                    b.chunks_exact(stride)
                        .flat_map(|r| [0, 2, 4].map(|k| u16_at(r, at + k)))
                        .max()
                        .unwrap_or(0)
                });
                (bounds, max_channel)
            })
            .reduce(
                || (Bounds::EMPTY, 0),
                |(a, m), (b, n)| (a.union(b), m.max(n)),
            );
        self.bounds = self.bounds.union(bounds);
        if let (Some(colors), Some(at)) = (self.colors.as_mut(), layout.color_at) {
            let sixteen_bit = shift || max_channel > 255;
            if sixteen_bit && !shift {
                // Every channel before this block was at most 255, so shifted down it is 0.
                colors[..first]
                    .par_iter_mut()
                    .for_each(|c| *c = [0, 0, 0, 255]);
                self.sixteen_bit = true;
            }
            colors[rows]
                .par_chunks_mut(per_task)
                .zip(bytes.par_chunks(per_task * stride))
                .for_each(|(colors, b)| {
                    for (c, r) in colors.iter_mut().zip(b.chunks_exact(stride)) {
                        let channel = |k| {
                            let v = u16_at(r, at + k);
                            if sixteen_bit {
                                (v >> 8) as u8
                            } else {
                                v as u8
                            }
                        };
                        *c = [channel(0), channel(2), channel(4), 255];
                    }
                });
        }
    }

    /// Scales the coordinates relative to the bounding-box centre and builds the cloud.
    fn finish(self, layout: &Layout, declared: u64) -> Cloud {
        let origin = self.bounds.centre().unwrap_or(DVec3::ZERO);
        // The raw coordinates become the positions in place (both are three 4-byte values).
        let mut positions: Vec<Vec3> = bytemuck::cast_vec(self.raw);
        positions.par_iter_mut().for_each(|p| {
            let raw: [i32; 3] = bytemuck::cast(*p);
            *p = (layout.world(raw) - origin).as_vec3();
        });
        let scalars = layout
            .fields
            .iter()
            .map(|(name, _)| name.clone())
            .zip(self.scalars)
            .collect();
        finish(
            positions,
            self.colors.filter(|c| !c.is_empty()),
            scalars,
            (origin, self.bounds),
            declared,
            layout.time_at.map(|_| self.times),
        )
    }
}

/// The cloud of a decoded LAS/LAZ file (both decoders): the named scalar columns, `declared`
/// header records, non-finite points dropped. A name used twice (an extra-bytes field named
/// like a standard one) gets its column index appended. The `gps_time` column becomes
/// `times` in seconds after the earliest (`stats.gps_time_origin`).
fn finish(
    positions: Vec<Vec3>,
    colors: Option<Vec<[u8; 4]>>,
    mut columns: Vec<(String, Vec<f32>)>,
    (origin, bounds): (DVec3, Bounds),
    declared: u64,
    times: Option<Vec<f64>>,
) -> Cloud {
    let earliest = times.as_ref().map(|times| {
        let earliest = times.par_iter().copied().reduce(|| f64::INFINITY, f64::min);
        if earliest.is_finite() {
            earliest
        } else {
            0.0
        }
    });
    if let (Some(times), Some(earliest)) = (times, earliest) {
        if let Some((_, column)) = columns.iter_mut().find(|(name, _)| name == "gps_time") {
            *column = times.par_iter().map(|t| (t - earliest) as f32).collect();
        }
    }
    let mut scalars: Vec<Scalar> = Vec::with_capacity(columns.len());
    for (k, (name, values)) in columns.into_iter().enumerate() {
        let name = if scalars.iter().any(|s| s.name == name) {
            format!("{name}_{k}")
        } else {
            name
        };
        scalars.push(Scalar { name, values });
    }
    let mut cloud = Cloud {
        positions,
        colors,
        scalars,
        origin,
        stats: LoadStats {
            records: usize::try_from(declared).unwrap_or(usize::MAX),
            file_bounds: bounds.centre().map(|_| [bounds.lo, bounds.hi]),
            gps_time_origin: earliest,
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    cloud.adopt_geometry_fields();
    cloud.retain_finite();
    cloud
}

/// Parses a LAS or LAZ file held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: Vec<u8>) -> Result<Cloud, LoadError> {
    let size = data.len();
    let mut cursor = Cursor::new(data);
    let header = read_header(file, &mut cursor, size)?;
    let mut cloud = if header.point_format().is_compressed {
        guard::deep_stack(|| read_compressed(file, cursor, &header, size))?
    } else {
        let at = cursor.position() as usize;
        let layout = Layout::new(file, &header, at, size)?;
        let data = cursor.into_inner();
        let mut columns = layout.columns();
        let end = at + layout.span.count * layout.span.stride;
        columns.decode_block(&layout, 0, &data[at..end]);
        columns.finish(&layout, header.number_of_points())
    };
    cloud.stats.las = Some(summary(&header));
    Ok(cloud)
}

/// Opens `path` and reads its checked header: the file's name, the reader (at the first point
/// record), its size and the header.
fn open_file(path: &Path) -> Result<(String, BufReader<File>, usize, las::Header), LoadError> {
    let file = path.display().to_string();
    let open = File::open(path).map_err(|source| io_error(&file, source))?;
    let size = open
        .metadata()
        .map_err(|source| io_error(&file, source))?
        .len();
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    let mut read = BufReader::new(open);
    let header = read_header(&file, &mut read, size)?;
    Ok((file, read, size, header))
}

/// A LAS or LAZ file opened for reading in blocks with the `las` crate (`surfel convert`),
/// after the checks [`load`] makes of its header and laszip VLR; `None` for a point-wise
/// compressed LAZ (LASzip 1.2), which only [`load`] reads. Decode under
/// [`super::guard::deep_stack`] and [`super::guard::third_party`], as [`load`] does.
pub(crate) fn open_blocks(path: &Path) -> Result<Option<las::Reader>, LoadError> {
    let (file, mut read, size, header) = open_file(path)?;
    if header.point_format().is_compressed {
        let laszip = header
            .vlrs()
            .iter()
            .find(|v| v.user_id.trim_end_matches('\0') == "laszip encoded" && v.record_id == 22204);
        if laszip.is_some_and(|v| {
            v.data.len() >= 2 && u16::from_le_bytes([v.data[0], v.data[1]]) == POINT_WISE
        }) {
            return Ok(None);
        }
        let vlr = header
            .laz_vlr()
            .map_err(|e| LoadError::whole(&file, format!("invalid or missing laszip VLR: {e}")))?;
        let items: u64 = vlr.items().iter().map(|i| u64::from(i.size())).sum();
        let record = u64::from(header.point_format().len());
        if vlr.items().is_empty() || items != record {
            return Err(LoadError::whole(
                &file,
                format!(
                    "the laszip VLR's items make {items}-byte points, but the header's point records have {record} bytes"
                ),
            ));
        }
    }
    read.rewind().map_err(|source| io_error(&file, source))?;
    let reader = guard::third_party(|| las::Reader::new(read))
        .map_err(|e| LoadError::whole(&file, format!("invalid LAS header: {e}")))?
        .map_err(|e| header_error(&file, e, size))?;
    Ok(Some(reader))
}

/// Loads a LAS or LAZ file. LAS point records are streamed from the file and decoded in
/// parallel while the next block is read.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    load_in_blocks(path, records::BLOCK_BYTES)
}

/// What `surfel info` reports of a LAS, LAZ or COPC file's `header`.
pub(crate) fn summary(header: &las::Header) -> LasSummary {
    let t = header.transforms();
    LasSummary {
        version: header.version().to_string(),
        point_format: header.point_format().to_u8().unwrap_or_default(),
        scale: DVec3::new(t.x.scale, t.y.scale, t.z.scale),
        offset: DVec3::new(t.x.offset, t.y.offset, t.z.offset),
        crs: crs(header.vlrs().iter().chain(header.evlrs())),
        note: None,
    }
}

/// The coordinate reference system among `vlrs`: the OGC WKT's name and authority code
/// (`LASF_Projection` record 2112), else the EPSG codes of the GeoTIFF keys (record 34735:
/// projected 3072, geographic 2048, vertical 4096); `None` without either.
pub(crate) fn crs<'a>(vlrs: impl Iterator<Item = &'a las::Vlr> + Clone) -> Option<String> {
    let projection = |id: u16| {
        vlrs.clone()
            .find(|v| v.user_id.trim_end_matches('\0') == "LASF_Projection" && v.record_id == id)
    };
    if let Some(wkt) = projection(2112) {
        let text = String::from_utf8_lossy(&wkt.data);
        return Some(wkt_summary(text.trim_end_matches('\0').trim()));
    }
    let keys: Vec<u16> = projection(34735)?
        .data
        .chunks_exact(2)
        .map(|b| u16::from_le_bytes([b[0], b[1]]))
        .collect();
    let count = usize::from(*keys.get(3)?);
    let codes: Vec<String> = keys[4..]
        .chunks_exact(4)
        .take(count)
        .filter(|k| k[1] == 0)
        .filter_map(|k| {
            let what = match k[0] {
                3072 => "projected",
                2048 => "geographic",
                4096 => "vertical",
                _ => return None,
            };
            Some(match k[3] {
                32767 => format!("{what} user-defined"),
                code => format!("{what} EPSG:{code}"),
            })
        })
        .collect();
    Some(if codes.is_empty() {
        "GeoTIFF keys without an EPSG code".to_owned()
    } else {
        format!("{} (GeoTIFF keys)", codes.join(", "))
    })
}

/// A WKT's name (its first quoted text) and top-level authority code (`AUTHORITY["EPSG","32633"]`
/// in WKT 1, `ID["EPSG",32633]` in WKT 2), e.g. `WGS 84 / UTM zone 33N (EPSG:32633)`.
fn wkt_summary(wkt: &str) -> String {
    let Some(name) = wkt.split('"').nth(1) else {
        return format!("WKT without a name: \"{}\"", show(wkt));
    };
    let mut depth = 0usize;
    let mut quoted = false;
    let mut code = None;
    for (i, c) in wkt.char_indices() {
        match c {
            '"' => quoted = !quoted,
            '[' | '(' if !quoted => {
                depth += 1;
                let keyword = wkt[..i]
                    .rsplit(|c: char| c == ',' || c == '[' || c == '(' || c.is_whitespace())
                    .next()
                    .unwrap_or_default();
                if depth == 2 && matches!(keyword, "AUTHORITY" | "ID") {
                    let args = &wkt[i + 1..];
                    let args = &args[..args.find([']', ')']).unwrap_or(args.len())];
                    let mut parts = args.split(',').map(|p| p.trim().trim_matches('"'));
                    if let (Some(authority), Some(number)) = (parts.next(), parts.next()) {
                        code = Some(format!("{authority}:{number}"));
                    }
                }
            }
            ']' | ')' if !quoted => depth = depth.saturating_sub(1),
            _ => {}
        }
    }
    match code {
        Some(code) => format!("{name} ({code})"),
        None => name.to_owned(),
    }
}

/// [`load`], reading records in blocks of about `block_bytes`.
fn load_in_blocks(path: &Path, block_bytes: usize) -> Result<Cloud, LoadError> {
    let (file, mut read, size, header) = open_file(path)?;
    let mut cloud = if header.point_format().is_compressed {
        guard::deep_stack(|| read_compressed(&file, read, &header, size))?
    } else {
        read_blocks(&file, &mut read, size, &header, block_bytes)?
    };
    cloud.stats.las = Some(summary(&header));
    Ok(cloud)
}

/// The uncompressed records of `header`'s file of `size` bytes, `read` at the first of
/// them, decoded in blocks of about `block_bytes`.
fn read_blocks(
    file: &str,
    read: &mut BufReader<File>,
    size: usize,
    header: &las::Header,
    block_bytes: usize,
) -> Result<Cloud, LoadError> {
    let at = read
        .stream_position()
        .map_err(|source| io_error(file, source))?;
    let layout = Layout::new(file, header, at as usize, size)?;
    let mut columns = layout.columns();
    let bytes = layout.span.count * layout.span.stride;
    let progress = Progress::new("loading", bytes, bytes >= records::PROGRESS_MIN_BYTES);
    records::for_each_block(
        file,
        read,
        layout.span,
        block_bytes,
        &progress,
        |first, block| columns.decode_block(&layout, first, block),
    )?;
    Ok(columns.finish(&layout, header.number_of_points()))
}

fn io_error(file: &str, source: std::io::Error) -> LoadError {
    LoadError::Io {
        file: file.to_owned(),
        source,
    }
}

/// Decompressed records larger than this multiple of the file are not allocated at once: such a
/// file is read point by point, its vectors growing as points decode.
const MAX_EXPANSION: u128 = 64;

/// Reads a LAZ file of `size` bytes with `header`, from the first point record: into memory,
/// then its chunks decompressed in parallel ([`read_chunks`]); a file whose chunk table is
/// missing, inconsistent or past the end (a truncated file), or whose chunks do not decode,
/// is read point by point instead. A chunk table past the end is replaced by an empty one
/// appended to the data, so the points that are there decode and the error names the first
/// that is not.
fn read_compressed<R: Read + Seek + Send + Sync + 'static>(
    file: &str,
    mut read: R,
    header: &las::Header,
    size: usize,
) -> Result<Cloud, LoadError> {
    let at = read
        .stream_position()
        .map_err(|source| io_error(file, source))? as usize;
    read.rewind().map_err(|source| io_error(file, source))?;
    let mut data = Vec::with_capacity(size + 16);
    read.read_to_end(&mut data)
        .map_err(|source| io_error(file, source))?;
    let (vlr_at, vlr) = laszip_vlr(file, &data, header)?;
    if vlr.items().is_empty() {
        return Err(LoadError::at_byte(
            file,
            vlr_at + 32,
            "the laszip VLR lists no point items",
        ));
    }
    // The decoder writes each item into the record the reader sizes from the header.
    let items: u64 = vlr.items().iter().map(|i| u64::from(i.size())).sum();
    let record = u64::from(header.point_format().len());
    if items != record {
        return Err(LoadError::at_byte(
            file,
            vlr_at + 32,
            format!(
                "the laszip VLR's items make {items}-byte points, but the header's point records have {record} bytes"
            ),
        ));
    }
    if u16::from_le_bytes([data[vlr_at], data[vlr_at + 1]]) == POINT_WISE {
        // The point-wise compressor has no chunks, no chunk table and no offset to one; the
        // `laz` crate reads it as one chunk unless its chunk size says variable (0 or 2^32-1,
        // which LASzip 1.2 wrote), then panics for the table it did not read.
        data[vlr_at + 12..vlr_at + 16].copy_from_slice(&(u32::MAX - 1).to_le_bytes());
        return read_with_crate(file, Cursor::new(data), size, false);
    }
    let Some(offset) = data.get(at..at + 8) else {
        return Err(LoadError::whole(
            file,
            truncated(0, header.number_of_points(), size),
        ));
    };
    let table = i64::from_le_bytes(offset.try_into().unwrap_or_default());
    let table_past_end = table > at as i64 && table.saturating_add(8) > size as i64;
    if !table_past_end {
        if let Some(cloud) = read_chunks(file, &data, header, at)? {
            return Ok(cloud);
        }
        return read_with_crate(file, Cursor::new(data), size, false);
    }
    if vlr.uses_variable_size_chunks() {
        return Err(LoadError::at_byte(
            file,
            at,
            format!(
                "the chunk table at byte {table} is past the end of the file at byte {size} (truncated file?), and variable-size chunks cannot be read without it"
            ),
        ));
    }
    let end = data.len() as i64;
    data[at..at + 8].copy_from_slice(&end.to_le_bytes());
    // Chunk table version 0 with no chunks.
    data.extend_from_slice(&[0; 8]);
    read_with_crate(file, Cursor::new(data), size, true)
}

/// The laszip VLR's compressor code for the point-wise compressor (LASzip's first, unchunked).
const POINT_WISE: u16 = 1;

/// The byte offset of the laszip VLR's data in `data` (a file whose header and VLRs
/// [`check_header`] accepted), and the VLR.
fn laszip_vlr(
    file: &str,
    data: &[u8],
    header: &las::Header,
) -> Result<(usize, laz::LazVlr), LoadError> {
    let missing = || {
        LoadError::whole(file, "a compressed point format without a laszip VLR (user \"laszip encoded\", record 22204)")
    };
    let vlr = header.laz_vlr().map_err(|e| match e {
        las::Error::LasZipVlrNotFound => missing(),
        e => LoadError::whole(file, format!("invalid laszip VLR: {e}")),
    })?;
    let word = |at: usize| usize::from(u16::from_le_bytes([data[at], data[at + 1]]));
    let count = u32::from_le_bytes([data[100], data[101], data[102], data[103]]);
    let mut at = word(94);
    for _ in 0..count {
        let user = &data[at + 2..at + 18];
        let record = word(at + 18);
        if user.starts_with(b"laszip encoded") && record == 22204 && word(at + 20) >= 34 {
            return Ok((at + 54, vlr));
        }
        at += 54 + word(at + 20);
    }
    Err(missing())
}

/// The chunks of a LAZ file held in `data` (point data from byte `at`) decompressed in
/// parallel by the `laz` crate into uncompressed records, decoded as a LAS file's are. An
/// error when the chunk table does not describe the declared points within the file; `None`
/// when the chunks cannot be read this way: no LAZ VLR or chunk table, a record size of 0,
/// more than [`MAX_EXPANSION`] times the file in records, or a chunk that fails to decode.
/// [`read_compressed`] has checked that the laszip items make the record size.
fn read_chunks(
    file: &str,
    data: &[u8],
    header: &las::Header,
    at: usize,
) -> Result<Option<Cloud>, LoadError> {
    let Ok(vlr) = header.laz_vlr() else {
        return Ok(None);
    };
    let stride = usize::from(header.point_format().len());
    let declared = header.number_of_points();
    let bytes = u128::from(declared) * stride as u128;
    // The table is checked whichever reader goes on: the crate's would trust it.
    let Some(table) =
        chunk_table(data, at, &vlr, declared).map_err(|e| LoadError::whole(file, e))?
    else {
        return Ok(None);
    };
    if stride == 0 || bytes > MAX_EXPANSION * data.len() as u128 {
        return Ok(None);
    }
    let mut records = vec![0u8; bytes as usize];
    let progress = Progress::new(
        "loading",
        records.len(),
        records.len() >= records::PROGRESS_MIN_BYTES,
    );
    // Groups of chunks, each decompressed in parallel, between progress updates.
    let group = 4 * rayon::current_num_threads().max(1);
    let (mut input, mut output) = (&data[at + 8..], records.as_mut_slice());
    for entries in table.chunks(group) {
        let compressed: u64 = entries.iter().map(|e| e.byte_count).sum();
        let points: u64 = entries.iter().map(|e| e.point_count).sum();
        let (chunk_in, rest_in) = input.split_at(compressed as usize);
        let (chunk_out, rest_out) = output.split_at_mut(points as usize * stride);
        let decoded =
            guard::third_party(|| laz::par_decompress(chunk_in, chunk_out, &vlr, entries))
                .map_err(|e| LoadError::at_byte(file, at, format!("LAZ chunks: {e}")))?;
        if decoded.is_err() {
            progress.finish();
            return Ok(None);
        }
        progress.advance(chunk_out.len());
        (input, output) = (rest_in, rest_out);
    }
    progress.finish();
    let layout = Layout::at(file, header, 0)?;
    let mut columns = layout.columns();
    columns.decode_block(&layout, 0, &records);
    Ok(Some(columns.finish(&layout, declared)))
}

/// The chunk table of the LAZ data at byte `at` of `data`, checked before the `laz` crate
/// trusts it (it allocates what the table's chunk count says): the table lies after the
/// points and inside the file, it holds at least one and at most as many chunks as the file
/// has points and bytes, the chunks' bytes fit between the points' start and the table, and
/// their points add up to `declared` (for fixed-size chunks, every chunk but the last holds
/// the VLR's chunk size). `Ok(None)` when the file has no chunk table (a writer that could
/// not seek back leaves its offset unset); an error says what is inconsistent.
fn chunk_table(
    data: &[u8],
    at: usize,
    vlr: &laz::LazVlr,
    declared: u64,
) -> Result<Option<Vec<laz::laszip::ChunkTableEntry>>, String> {
    let word = |from: usize| -> Option<i64> {
        Some(i64::from_le_bytes(
            data.get(from..from.checked_add(8)?)?.try_into().ok()?,
        ))
    };
    let start = at + 8;
    // As the crate looks for it: after the points, else in the file's last 8 bytes.
    let offset = match word(at) {
        Some(o) if o > at as i64 => o,
        _ => match data.len().checked_sub(8).and_then(word) {
            Some(o) if o > at as i64 => o,
            _ => return Ok(None),
        },
    };
    let invalid = |what: String| Err(format!("invalid LAZ chunk table at byte {offset}: {what}"));
    let table_at = usize::try_from(offset).unwrap_or(usize::MAX);
    let Some(head) = data.get(table_at..table_at.saturating_add(8)) else {
        return invalid(format!("the file ends at byte {}", data.len()));
    };
    let chunks = u64::from(u32::from_le_bytes([head[4], head[5], head[6], head[7]]));
    if table_at < start || chunks == 0 || chunks > declared || chunks > data.len() as u64 {
        return invalid(format!(
            "{chunks} chunks for {declared} points in a file of {} bytes",
            data.len()
        ));
    }
    let mut cursor = Cursor::new(data);
    cursor.set_position(at as u64);
    let read = guard::third_party(|| laz::laszip::ChunkTable::read_from(&mut cursor, vlr));
    let mut entries = match read {
        Ok(Ok(table)) if table.as_ref().len() as u64 == chunks => table.as_ref().to_vec(),
        Ok(Ok(_)) => return invalid(format!("fewer than the {chunks} chunks it declares")),
        Ok(Err(e)) => return invalid(e.to_string()),
        Err(e) => return invalid(e),
    };
    let bytes = entries
        .iter()
        .try_fold(0u64, |sum, e| sum.checked_add(e.byte_count));
    if bytes.is_none_or(|b| b > (table_at - start) as u64) {
        return invalid(format!(
            "its chunks hold more than the {} bytes before it",
            table_at - start
        ));
    }
    if !vlr.uses_variable_size_chunks() {
        let size = u64::from(vlr.chunk_size());
        let last = (chunks - 1)
            .checked_mul(size)
            .and_then(|before| declared.checked_sub(before))
            .filter(|&last| last > 0 && last <= size);
        match (last, entries.last_mut()) {
            (Some(last), Some(entry)) => entry.point_count = last,
            _ => {
                return invalid(format!(
                    "{chunks} chunks of {size} points cannot hold the {declared} points declared"
                ))
            }
        }
    }
    let points = entries
        .iter()
        .try_fold(0u64, |sum, e| sum.checked_add(e.point_count));
    if points != Some(declared) {
        return invalid(format!(
            "its chunks hold {} points, the header declares {declared}",
            points.map_or_else(|| "more than 2^64".to_owned(), |p| p.to_string())
        ));
    }
    Ok(Some(entries))
}

/// Reads the points with the `las` crate (used for LAZ), from the start of a file of `size`
/// bytes; `truncated_file` says the file is known to be cut short.
fn read_with_crate<R: Read + Seek + Send + Sync + 'static>(
    file: &str,
    read: R,
    size: usize,
    truncated_file: bool,
) -> Result<Cloud, LoadError> {
    let mut reader = guard::third_party(|| las::Reader::new(read))
        .map_err(|e| LoadError::whole(file, format!("invalid LAS header: {e}")))?
        .map_err(|e| header_error(file, e, size))?;
    let declared = reader.header().number_of_points();
    let extra = extra_fields(file, reader.header())?;
    let format = *reader.header().point_format();
    let names = standard_names(&format);
    // Compressed records bound the count only loosely: reserve at most one point per two
    // bytes and let honest files that compress better grow the vectors.
    let capacity = usize::try_from(declared)
        .unwrap_or(usize::MAX)
        .min(size / 2);
    let mut world = Vec::with_capacity(capacity);
    let mut rgb16 = Vec::new();
    let mut columns: Vec<Vec<f32>> = (0..names.len() + extra.len())
        .map(|_| Vec::with_capacity(capacity))
        .collect();
    let mut index = 0u64;
    let mut times = Vec::new();
    let mut data = las::PointDataBuilder::new()
        .for_header(reader.header())
        .build();
    loop {
        // Records are decoded a block at a time; an error names the block's first record.
        let read = guard::third_party(|| reader.fill_points(CRATE_BLOCK_POINTS, &mut data))
            .map_err(|e| {
                LoadError::whole(file, format!("point record {index} of {declared}: {e}"))
            })?
            .map_err(|e| {
                let message = match e {
                    _ if truncated_file => truncated(index, declared, size),
                    las::Error::Io(e) if e.kind() == ErrorKind::UnexpectedEof => {
                        truncated(index, declared, size)
                    }
                    e => format!("point record {index} of {declared}: {e}"),
                };
                LoadError::whole(file, message)
            })?;
        if read == 0 {
            break;
        }
        for point in data.points() {
            let point = point.map_err(|e| {
                LoadError::whole(file, format!("point record {index} of {declared}: {e}"))
            })?;
            world.push(DVec3::new(point.x, point.y, point.z));
            if let Some(c) = point.color {
                rgb16.push([c.red, c.green, c.blue]);
            }
            if let Some(time) = point.gps_time {
                times.push(time);
            }
            let standard = standard_values(&point);
            let optional = [format.has_gps_time.then_some(0.0), point.nir.map(f32::from)];
            let extras = extra.iter().map(|f| f.decode.read(&point.extra_bytes));
            let values = standard
                .into_iter()
                .chain(optional.into_iter().flatten())
                .chain(extras);
            for (column, value) in columns.iter_mut().zip(values) {
                column.push(value);
            }
            index += 1;
        }
    }
    let bounds = world.iter().fold(Bounds::EMPTY, |mut b, p| {
        b.add(*p);
        b
    });
    let origin = bounds.centre().unwrap_or(DVec3::ZERO);
    let colors = (rgb16.len() == world.len() && !world.is_empty()).then(|| {
        let eight_bit = rgb16.iter().flatten().all(|&c| c <= 255);
        rgb16
            .iter()
            .map(|c| {
                let [r, g, b] = c.map(|v| if eight_bit { v as u8 } else { (v >> 8) as u8 });
                [r, g, b, 255]
            })
            .collect()
    });
    let positions = world.iter().map(|p| (*p - origin).as_vec3()).collect();
    let named = names
        .iter()
        .map(|n| (*n).to_owned())
        .chain(extra.into_iter().map(|f| f.name))
        .zip(columns)
        .collect();
    let times = format.has_gps_time.then_some(times);
    Ok(finish(
        positions,
        colors,
        named,
        (origin, bounds),
        declared,
        times,
    ))
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use las::point::{Classification, Format};
    use las::{Builder, Color, Point, Transform, Vector, Writer};

    use super::*;

    /// A LAS 1.4 file of point `format` with 3 extra bytes per record and `n` points whose
    /// color channels exceed 255 only from point `wide_from` on. Every fifth point has the
    /// overlap class (with flag bits set in formats 0-5).
    fn las_file(format: u8, n: usize, wide_from: usize) -> Vec<u8> {
        written(format, n, wide_from, false)
    }

    /// [`las_file`], LAZ-compressed when `compressed` (then without overlap classes: those
    /// are set in the written records; and with coordinates jittered, so the points do not
    /// compress beyond [`MAX_EXPANSION`]).
    fn written(format: u8, n: usize, wide_from: usize, compressed: bool) -> Vec<u8> {
        let mut builder = Builder::from((1, 4));
        builder.point_format = Format::new(format).unwrap();
        builder.point_format.extra_bytes = 3;
        builder.point_format.is_compressed = compressed;
        builder.transforms = Vector {
            x: Transform {
                scale: 0.01,
                offset: 636_000.0,
            },
            y: Transform {
                scale: 0.001,
                offset: -55_989.0,
            },
            z: Transform {
                scale: 0.1,
                offset: 0.0,
            },
        };
        let point_format = builder.point_format;
        let mut writer =
            Writer::new(Cursor::new(Vec::new()), builder.into_header().unwrap()).unwrap();
        let mut rng = crate::rng::SplitMix64::new(3);
        for i in 0..n {
            let f = i as f64
                + if compressed {
                    rng.next_f64() * 100.0
                } else {
                    0.0
                };
            let channel = if i >= wide_from {
                (i * 997 % 65_536) as u16
            } else {
                (i % 256) as u16
            };
            let point = Point {
                x: 636_000.0 + f * 0.37,
                y: -55_989.0 - f * 0.011,
                z: (f * 0.7) % 50.0,
                intensity: (i * 31 % 65_536) as u16,
                classification: Classification::new((i % 12) as u8).unwrap(),
                gps_time: point_format.has_gps_time.then_some(f),
                color: point_format
                    .has_color
                    .then(|| Color::new(channel, channel / 2, 255 - (i % 256) as u16)),
                nir: point_format.has_nir.then_some(7),
                extra_bytes: vec![1, 2, 3],
                ..Default::default()
            };
            writer.write_point(point).unwrap();
        }
        let mut bytes = writer.into_inner().unwrap().into_inner();
        if compressed {
            return bytes;
        }
        let at = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
        let stride = usize::from(u16::from_le_bytes([bytes[105], bytes[106]]));
        for record in bytes[at..].chunks_exact_mut(stride).step_by(5) {
            if point_format.is_extended {
                record[16] = OVERLAP;
            } else {
                record[15] = 0b1110_0000 | OVERLAP;
            }
        }
        bytes
    }

    fn temp_file(name: &str, bytes: &[u8]) -> PathBuf {
        let path = std::env::temp_dir().join(format!("surfel-{}-{name}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        path
    }

    /// The parallel decoder, in memory and streamed in blocks of several sizes, against the
    /// `las` crate's point reader.
    fn assert_matches_crate(name: &str, bytes: Vec<u8>) {
        let mut reference =
            read_with_crate(name, Cursor::new(bytes.clone()), bytes.len(), false).unwrap();
        let mut read = Cursor::new(&bytes);
        reference.stats.las = Some(summary(&read_header(name, &mut read, bytes.len()).unwrap()));
        assert_eq!(
            parse(name, bytes.clone()).unwrap(),
            reference,
            "{name} in memory"
        );
        let path = temp_file(name, &bytes);
        for block in [1, 4096, records::BLOCK_BYTES] {
            let streamed = load_in_blocks(&path, block).unwrap();
            assert_eq!(streamed, reference, "{name} in blocks of {block} bytes");
        }
        std::fs::remove_file(path).unwrap();
    }

    #[test]
    fn point_formats_match_the_las_crate() {
        for format in [0, 1, 2, 3, 6, 7, 8] {
            // 16-bit colors from the first point, from a later block on, and never.
            for wide_from in [0, 700, usize::MAX] {
                let bytes = las_file(format, 1000, wide_from);
                assert_matches_crate(&format!("f{format}-{wide_from}.las"), bytes);
            }
        }
    }

    /// An extra-bytes descriptor: `name`, data type, options, scale and offset.
    fn descriptor(name: &str, data_type: u8, options: u8, scale: f64, offset: f64) -> Vec<u8> {
        let mut d = vec![0u8; DESCRIPTOR_BYTES];
        d[2] = data_type;
        d[3] = options;
        d[4..4 + name.len()].copy_from_slice(name.as_bytes());
        d[112..120].copy_from_slice(&scale.to_le_bytes());
        d[136..144].copy_from_slice(&offset.to_le_bytes());
        d
    }

    /// A LAS 1.4 file of point `format` whose records carry `extra` extra bytes (the bytes of
    /// point `i` from `bytes(i)`) described by the `descriptors` VLR data.
    fn las_with_extra(
        format: u8,
        descriptors: Vec<u8>,
        extra: u16,
        n: usize,
        bytes: impl Fn(usize) -> Vec<u8>,
    ) -> Vec<u8> {
        let mut builder = Builder::from((1, 4));
        builder.point_format = Format::new(format).unwrap();
        builder.point_format.extra_bytes = extra;
        builder.vlrs.push(las::Vlr {
            user_id: "LASF_Spec".into(),
            record_id: 4,
            description: "extra bytes".into(),
            data: descriptors,
        });
        let point_format = builder.point_format;
        let mut writer =
            Writer::new(Cursor::new(Vec::new()), builder.into_header().unwrap()).unwrap();
        for i in 0..n {
            writer
                .write_point(Point {
                    x: i as f64,
                    y: 2.0 * i as f64,
                    z: 0.5,
                    intensity: 100 + i as u16,
                    return_number: 1 + (i % 3) as u8,
                    number_of_returns: 3,
                    point_source_id: 40 + i as u16,
                    classification: Classification::new(2 + (i % 2) as u8 * 4).unwrap(),
                    gps_time: point_format.has_gps_time.then_some(3.0e8 + i as f64 * 0.25),
                    color: point_format.has_color.then(|| Color::new(1, 2, 3)),
                    nir: point_format.has_nir.then_some(700 + i as u16),
                    extra_bytes: bytes(i),
                    ..Default::default()
                })
                .unwrap();
        }
        writer.into_inner().unwrap().into_inner()
    }

    /// f32 `Deviation`, u16 `amplitude` scaled by 0.5 and offset by 10, two undocumented bytes,
    /// then the deprecated 2 x i8 array `tilt`: 10 extra bytes.
    fn deviation_file(format: u8, n: usize) -> Vec<u8> {
        let descriptors = [
            descriptor("Deviation", 9, 0, 0.0, 0.0),
            descriptor("amplitude", 3, 8 | 16, 0.5, 10.0),
            descriptor("", 0, 2, 0.0, 0.0),
            descriptor("tilt", 12, 0, 0.0, 0.0),
        ]
        .concat();
        las_with_extra(format, descriptors, 10, n, |i| {
            let mut b = (i as f32 * 0.25 - 1.0).to_le_bytes().to_vec();
            b.extend((i as u16 * 3).to_le_bytes());
            b.extend([0xee, 0xee, i as u8, (-(i as i8)) as u8]);
            b
        })
    }

    #[test]
    fn gps_times_are_seconds_after_the_earliest() {
        let times = [
            1_234_567_890.5,
            1_234_567_884.25,
            1_234_567_891.125,
            1_234_567_886.0,
        ];
        for compressed in [false, true] {
            let mut builder = Builder::from((1, 2));
            builder.point_format = Format::new(1).unwrap();
            builder.point_format.is_compressed = compressed;
            let mut writer =
                Writer::new(Cursor::new(Vec::new()), builder.into_header().unwrap()).unwrap();
            for (i, &t) in times.iter().enumerate() {
                let point = Point {
                    x: i as f64,
                    gps_time: Some(t),
                    ..Default::default()
                };
                writer.write_point(point).unwrap();
            }
            let bytes = writer.into_inner().unwrap().into_inner();
            let c = parse("t.las", bytes).unwrap();
            assert_eq!(c.stats.gps_time_origin, Some(1_234_567_884.25));
            let column = &c.scalars.iter().find(|s| s.name == "gps_time").unwrap();
            assert_eq!(
                column.values,
                [6.25, 0.0, 6.875, 1.75],
                "compressed: {compressed}"
            );
        }
    }

    #[test]
    fn crs_from_wkt_or_geotiff_keys() {
        let vlr = |record_id: u16, data: Vec<u8>| las::Vlr {
            user_id: "LASF_Projection".into(),
            record_id,
            description: String::new(),
            data,
        };
        let wkt2 = br#"PROJCRS["WGS 84 / UTM zone 33N",BASEGEOGCRS["WGS 84",ID["EPSG",4326]],CONVERSION["UTM zone 33N",ID["EPSG",16033]],ID["EPSG",32633]]"#;
        let wkt1 = br#"PROJCS["NAD83 / Conus Albers",GEOGCS["NAD83",AUTHORITY["EPSG","4269"]],UNIT["metre",1,AUTHORITY["EPSG","9001"]],AUTHORITY["EPSG","5070"]]"#;
        let keys: Vec<u8> = [
            1u16, 1, 0, 3, 1024, 0, 1, 1, 3072, 0, 1, 32633, 4096, 0, 1, 5703,
        ]
        .iter()
        .flat_map(|k| k.to_le_bytes())
        .collect();
        let mut with_nul = wkt2.to_vec();
        with_nul.push(0);
        for (vlrs, expected) in [
            (
                vec![vlr(34735, keys.clone()), vlr(2112, with_nul)],
                Some("WGS 84 / UTM zone 33N (EPSG:32633)"),
            ),
            (
                vec![vlr(2112, wkt1.to_vec())],
                Some("NAD83 / Conus Albers (EPSG:5070)"),
            ),
            (
                vec![vlr(34735, keys)],
                Some("projected EPSG:32633, vertical EPSG:5703 (GeoTIFF keys)"),
            ),
            (
                vec![vlr(2112, b"LOCAL_CS[\"site\"]".to_vec())],
                Some("site"),
            ),
            (vec![], None),
        ] {
            assert_eq!(crs(vlrs.iter()).as_deref(), expected);
        }
    }

    #[test]
    fn extra_bytes_nir_and_returns_become_named_scalars() {
        for format in [0, 1, 6, 8] {
            let bytes = deviation_file(format, 1500);
            let cloud = parse("x.las", bytes.clone()).unwrap();
            let names: Vec<_> = cloud.scalars.iter().map(|s| s.name.as_str()).collect();
            let mut expected = vec![
                "intensity",
                "classification",
                "return_number",
                "number_of_returns",
                "point_source_id",
            ];
            if format != 0 {
                expected.push("gps_time");
            }
            if format == 8 {
                expected.push("nir");
            }
            expected.extend(["Deviation", "amplitude", "tilt_0", "tilt_1"]);
            assert_eq!(names, expected, "format {format}");
            let column = |name: &str| {
                &cloud
                    .scalars
                    .iter()
                    .find(|s| s.name == name)
                    .unwrap()
                    .values
            };
            for i in [0, 1, 2, 999, 1499] {
                let f = i as f32;
                assert_eq!(column("Deviation")[i], f * 0.25 - 1.0);
                assert_eq!(column("amplitude")[i], (i * 3) as f32 * 0.5 + 10.0);
                assert_eq!(column("tilt_0")[i], f32::from(i as u8 as i8));
                assert_eq!(column("tilt_1")[i], f32::from(-(i as i8)));
                assert_eq!(column("return_number")[i], (1 + i % 3) as f32);
                assert_eq!(column("number_of_returns")[i], 3.0);
                assert_eq!(column("point_source_id")[i], 40.0 + f);
                assert_eq!(
                    column("classification")[i],
                    if i % 2 == 0 { 2.0 } else { 6.0 }
                );
                if format == 8 {
                    assert_eq!(column("nir")[i], 700.0 + f);
                }
                if format != 0 {
                    // Seconds after the first record, exact although 3e8 + 0.25 is not an f32.
                    assert_eq!(column("gps_time")[i], f * 0.25);
                }
            }
            assert_matches_crate(&format!("extra-f{format}.las"), bytes);
        }
    }

    #[test]
    fn bad_extra_bytes_descriptors_are_clear_errors() {
        let message = |bytes: Vec<u8>| parse("bad.las", bytes).unwrap_err().to_string();
        let short = descriptor("Deviation", 9, 0, 0.0, 0.0)[..191].to_vec();
        assert_eq!(
            message(las_with_extra(6, short, 4, 3, |_| vec![0; 4])),
            "bad.las: extra-bytes VLR (LASF_Spec record 4) holds 191 bytes, not a whole number \
             of 192-byte descriptors (truncated?)"
        );
        let wide = descriptor("Deviation", 10, 0, 0.0, 0.0);
        assert_eq!(
            message(las_with_extra(6, wide, 4, 3, |_| vec![0; 4])),
            "bad.las: the extra-bytes descriptors describe 8 bytes per point, but the records \
             of point format 6 have 4 bytes after their standard fields"
        );
        let unknown = descriptor("odd", 31, 0, 0.0, 0.0);
        assert_eq!(
            message(las_with_extra(6, unknown, 4, 3, |_| vec![0; 4])),
            "bad.las: extra-bytes descriptor 0 ('odd'): unknown data type 31 (expected 0..=30)"
        );
    }

    #[test]
    fn compressed_chunks_decode_as_the_las_crate_reads_them() {
        for format in [0, 1, 3, 6, 7, 8] {
            let bytes = written(format, 120_000, 70_000, true);
            let name = format!("f{format}.laz");
            let size = bytes.len();
            let mut cursor = Cursor::new(&bytes);
            let header = read_header(&name, &mut cursor, size).unwrap();
            let at = cursor.position() as usize;
            let chunks = read_chunks(&name, &bytes, &header, at).unwrap();
            let reference = read_with_crate(&name, Cursor::new(bytes), size, false).unwrap();
            let chunks = chunks.expect("chunked");
            assert_eq!(chunks.len(), reference.len(), "{name}");
            assert_eq!(chunks.positions, reference.positions, "{name}");
            assert_eq!(chunks.origin, reference.origin, "{name}");
            assert_eq!(chunks.colors, reference.colors, "{name}");
            for (a, b) in chunks.scalars.iter().zip(&reference.scalars) {
                let first = a.values.iter().zip(&b.values).position(|(x, y)| x != y);
                assert!(
                    first.is_none(),
                    "{name} {} at {first:?}: {} vs {}",
                    a.name,
                    a.values[first.unwrap_or(0)],
                    b.values[first.unwrap_or(0)]
                );
            }
            assert_eq!(chunks.stats, reference.stats, "{name}");
        }
    }

    /// `laz` (one chunk) rewritten as LASzip 1.2's point-wise compressor writes: no offset to a
    /// chunk table before the points, no table after them, compressor 1 and chunk size 0.
    fn point_wise(laz: &[u8]) -> Vec<u8> {
        let word = |at: usize| usize::from(u16::from_le_bytes([laz[at], laz[at + 1]]));
        let at = u32::from_le_bytes(laz[96..100].try_into().unwrap()) as usize;
        let table = i64::from_le_bytes(laz[at..at + 8].try_into().unwrap()) as usize;
        let mut out = [&laz[..at], &laz[at + 8..table]].concat();
        let mut vlr = word(94);
        while &out[vlr + 2..vlr + 16] != b"laszip encoded" {
            vlr += 54 + word(vlr + 20);
        }
        out[vlr + 54..vlr + 56].copy_from_slice(&1u16.to_le_bytes());
        out[vlr + 66..vlr + 70].copy_from_slice(&0u32.to_le_bytes());
        out
    }

    #[test]
    fn point_wise_laz_reads_as_its_chunked_twin() {
        for format in [1, 3] {
            let chunked = written(format, 2_000, 2_000, true);
            let name = format!("pw{format}.laz");
            let expected = parse(&name, chunked.clone()).unwrap();
            let cloud = parse(&name, point_wise(&chunked)).unwrap();
            assert_eq!(cloud.len(), 2_000);
            assert_eq!(cloud.positions, expected.positions, "{name}");
            assert_eq!(cloud.scalars, expected.scalars, "{name}");
            assert_eq!(cloud.colors, expected.colors, "{name}");
        }
    }

    #[test]
    fn laszip_vlrs_the_crate_would_panic_on_are_errors() {
        let laz = written(3, 100, 100, true);
        let word = |at: usize| usize::from(u16::from_le_bytes([laz[at], laz[at + 1]]));
        let mut vlr = word(94);
        while &laz[vlr + 2..vlr + 16] != b"laszip encoded" {
            vlr += 54 + word(vlr + 20);
        }
        let mut no_items = laz.clone();
        no_items[vlr + 54 + 32..vlr + 54 + 34].copy_from_slice(&0u16.to_le_bytes());
        assert_eq!(
            parse("items.laz", no_items).unwrap_err().to_string(),
            format!(
                "items.laz: byte offset {}: the laszip VLR lists no point items",
                vlr + 86
            )
        );
        // Variable-size chunks in a file cut before its chunk table.
        let mut variable = laz.clone();
        variable[vlr + 66..vlr + 70].copy_from_slice(&u32::MAX.to_le_bytes());
        let cut = variable[..variable.len() - 40].to_vec();
        let message = parse("cut.laz", cut).unwrap_err().to_string();
        assert!(
            message.contains("variable-size chunks cannot be read without it"),
            "{message}"
        );
    }

    #[test]
    fn inconsistent_chunk_tables_are_errors_before_anything_is_allocated() {
        let root = std::env::var_os("SURFEL_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
        let good = std::fs::read(root.join("lidar/autzen_trim.laz")).unwrap();
        let at = u32::from_le_bytes(good[96..100].try_into().unwrap()) as usize;
        let table = i64::from_le_bytes(good[at..at + 8].try_into().unwrap()) as usize;
        let changed = |edit: &dyn Fn(&mut Vec<u8>)| {
            let mut bytes = good.clone();
            edit(&mut bytes);
            parse("bad.laz", bytes)
                .err()
                .map_or_else(String::new, |e| e.to_string())
        };
        // A chunk count the file cannot hold (the crate would reserve 64 GiB for it).
        let m = changed(&|b| b[table + 4..table + 8].copy_from_slice(&u32::MAX.to_le_bytes()));
        assert_eq!(
            m,
            format!(
                "bad.laz: invalid LAZ chunk table at byte {table}: 4294967295 chunks for 110000 \
                 points in a file of {} bytes",
                good.len()
            )
        );
        // Fixed-size chunks of 50,000 points: 3 hold 110,000, 2 do not.
        let m = changed(&|b| b[table + 4..table + 8].copy_from_slice(&2u32.to_le_bytes()));
        assert!(
            m.ends_with("2 chunks of 50000 points cannot hold the 110000 points declared"),
            "{m}"
        );
        // A damaged chunk: the crate's reader names the record it stops at.
        let m = changed(&|b| {
            for x in &mut b[at + 30_000..at + 30_100] {
                *x ^= 0x5a;
            }
        });
        assert!(m.starts_with("bad.laz: point record "), "{m}");
    }

    #[test]
    fn shared_files_match_the_las_crate() {
        let root = std::env::var_os("SURFEL_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
        for file in ["autzen_trim.las", "autzen_trim.laz", "vegetation_1_3.las"] {
            let bytes = std::fs::read(root.join("lidar").join(file)).unwrap();
            assert_matches_crate(file, bytes);
        }
    }
}

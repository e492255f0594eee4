//! LAS/LAZ reader. Headers and LAZ (compressed) points are read by the `las` crate;
//! uncompressed point records have a fixed size and are decoded here, in parallel, streamed from
//! the file in blocks.
//!
//! Coordinates are scaled and offset in f64 (`scale * X + offset`, as the crate does); the f64
//! bounding-box centre becomes [`Cloud::origin`] and is subtracted in f64 before the conversion
//! to f32, so large projected coordinates keep their centimetre grid. RGB is kept (8-bit values
//! stored in the 16-bit fields, as many writers do, are detected and used as is; true 16-bit
//! values are shifted down), and intensity and classification become scalars (classification
//! 12, "overlap", reads as 1, "unclassified", as in the crate).

use std::fs::File;
use std::io::{BufReader, Cursor, ErrorKind, Read, Seek};
use std::path::Path;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::cloud::{Bounds, Cloud, LoadStats, Scalar};
use super::error::LoadError;
use super::progress::Progress;
use super::records::{self, Span};

/// The LAS classification code for overlap points, which the `las` crate reads as unclassified.
const OVERLAP: u8 = 12;

/// Reads the header and VLRs of a file of `size` bytes, leaving `read` at the first point record.
fn read_header<R: Read + Seek>(
    file: &str,
    read: &mut R,
    size: usize,
) -> Result<las::Header, LoadError> {
    las::Header::new(read).map_err(|e| header_error(file, e, size))
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

/// The message for point record `index` of `declared` that a file of `size` bytes cuts short.
fn truncated(index: u64, declared: u64, size: usize) -> String {
    format!(
        "point record {index} of {declared} ends past the end of the file at byte {size} (truncated file?)"
    )
}

/// Where the fields of an uncompressed point record are, and how coordinates are scaled.
struct Layout {
    span: Span,
    transforms: las::Vector<las::Transform>,
    /// Byte offset of the classification byte.
    class_at: usize,
    /// Formats 0-5 keep flags in the classification byte's top three bits.
    class_mask: u8,
    /// Byte offset of red, green and blue (u16 each) when the format has colors.
    color_at: Option<usize>,
}

impl Layout {
    /// The layout of `header`'s records, which start at byte `at` of a file of `size` bytes.
    /// Fails before anything is allocated when the declared points cannot fit in the file.
    fn new(file: &str, header: &las::Header, at: usize, size: usize) -> Result<Self, LoadError> {
        let format = header.point_format();
        let stride = usize::from(format.len()).max(1);
        let declared = header.number_of_points();
        let needed = u128::from(declared) * stride as u128 + at as u128;
        if needed > size as u128 {
            let whole = (size.saturating_sub(at) / stride) as u64;
            return Err(LoadError::whole(file, truncated(whole, declared, size)));
        }
        // Fixed part: X, Y, Z, intensity, flags (2 bytes, or 3 in formats 6-10), then scan
        // angle, user data and point source id; GPS time and colors follow.
        let base = if format.is_extended { 22 } else { 20 };
        let gps = if format.has_gps_time { 8 } else { 0 };
        Ok(Layout {
            span: Span {
                at,
                count: declared as usize,
                stride,
            },
            transforms: *header.transforms(),
            class_at: if format.is_extended { 16 } else { 15 },
            class_mask: if format.is_extended { 0xff } else { 0x1f },
            color_at: format.has_color.then_some(base + gps),
        })
    }

    /// The decoded columns for every record, before any is decoded.
    fn columns(&self) -> Columns {
        let n = self.span.count;
        Columns {
            raw: records::filled([0; 3], n),
            colors: self.color_at.map(|_| records::filled([0, 0, 0, 255], n)),
            intensity: records::filled(0.0, n),
            class: records::filled(0.0, n),
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
    intensity: Vec<f32>,
    class: Vec<f32>,
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
        let (bounds, max_channel) = self.raw[rows.clone()]
            .par_chunks_mut(per_task)
            .zip(self.intensity[rows.clone()].par_chunks_mut(per_task))
            .zip(self.class[rows.clone()].par_chunks_mut(per_task))
            .zip(bytes.par_chunks(per_task * stride))
            .map(|(((raw, intensity), class), b)| {
                let mut bounds = Bounds::EMPTY;
                for (((r, xyz), i), c) in b.chunks_exact(stride).zip(raw).zip(intensity).zip(class)
                {
                    *xyz = [i32_at(r, 0), i32_at(r, 4), i32_at(r, 8)];
                    bounds.add(layout.world(*xyz));
                    *i = f32::from(u16_at(r, 12));
                    let code = r[layout.class_at] & layout.class_mask;
                    *c = f32::from(if code == OVERLAP { 1 } else { code });
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
        finish(
            positions,
            self.colors.filter(|c| !c.is_empty()),
            self.intensity,
            self.class,
            origin,
            declared,
        )
    }
}

/// The cloud of a decoded LAS/LAZ file (both decoders): intensity and classification as
/// scalars, `declared` header records, non-finite points dropped.
fn finish(
    positions: Vec<Vec3>,
    colors: Option<Vec<[u8; 4]>>,
    intensity: Vec<f32>,
    class: Vec<f32>,
    origin: DVec3,
    declared: u64,
) -> Cloud {
    let mut cloud = Cloud {
        positions,
        colors,
        scalars: vec![
            Scalar {
                name: "intensity".into(),
                values: intensity,
            },
            Scalar {
                name: "classification".into(),
                values: class,
            },
        ],
        origin,
        stats: LoadStats {
            records: usize::try_from(declared).unwrap_or(usize::MAX),
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    cloud.retain_finite();
    cloud
}

/// Parses a LAS or LAZ file held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: Vec<u8>) -> Result<Cloud, LoadError> {
    let size = data.len();
    let mut cursor = Cursor::new(data);
    let header = read_header(file, &mut cursor, size)?;
    if header.point_format().is_compressed {
        return read_compressed(file, cursor, &header, size);
    }
    let at = cursor.position() as usize;
    let layout = Layout::new(file, &header, at, size)?;
    let data = cursor.into_inner();
    let mut columns = layout.columns();
    let end = at + layout.span.count * layout.span.stride;
    columns.decode_block(&layout, 0, &data[at..end]);
    Ok(columns.finish(&layout, header.number_of_points()))
}

/// Loads a LAS or LAZ file. LAS point records are streamed from the file and decoded in
/// parallel while the next block is read.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    load_in_blocks(path, records::BLOCK_BYTES)
}

/// [`load`], reading records in blocks of about `block_bytes`.
fn load_in_blocks(path: &Path, block_bytes: usize) -> Result<Cloud, LoadError> {
    let file = path.display().to_string();
    let open = File::open(path).map_err(|source| io_error(&file, source))?;
    let size = open
        .metadata()
        .map_err(|source| io_error(&file, source))?
        .len();
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    let mut read = BufReader::new(open);
    let header = read_header(&file, &mut read, size)?;
    if header.point_format().is_compressed {
        return read_compressed(&file, read, &header, size);
    }
    let at = read
        .stream_position()
        .map_err(|source| io_error(&file, source))?;
    let layout = Layout::new(&file, &header, at as usize, size)?;
    let mut columns = layout.columns();
    let bytes = layout.span.count * layout.span.stride;
    let progress = Progress::new("loading", bytes, bytes >= records::PROGRESS_MIN_BYTES);
    records::for_each_block(
        &file,
        &mut read,
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

/// Reads a LAZ file of `size` bytes with `header`, from the first point record. The chunk table
/// is written after the points; when it lies past the end (a truncated file), the file is read
/// into memory with an empty chunk table appended, so the points that are there decode and the
/// error names the first that is not.
fn read_compressed<R: Read + Seek + Send + Sync + 'static>(
    file: &str,
    mut read: R,
    header: &las::Header,
    size: usize,
) -> Result<Cloud, LoadError> {
    let at = read
        .stream_position()
        .map_err(|source| io_error(file, source))? as usize;
    let mut offset = [0; 8];
    read.read_exact(&mut offset).map_err(|source| {
        if source.kind() == ErrorKind::UnexpectedEof {
            LoadError::whole(file, truncated(0, header.number_of_points(), size))
        } else {
            io_error(file, source)
        }
    })?;
    let table = i64::from_le_bytes(offset);
    let table_past_end = table > at as i64 && table.saturating_add(8) > size as i64;
    read.rewind().map_err(|source| io_error(file, source))?;
    if !table_past_end {
        return read_with_crate(file, read, size, false);
    }
    let mut data = Vec::with_capacity(size + 8);
    read.read_to_end(&mut data)
        .map_err(|source| io_error(file, source))?;
    let end = data.len() as i64;
    data[at..at + 8].copy_from_slice(&end.to_le_bytes());
    // Chunk table version 0 with no chunks.
    data.extend_from_slice(&[0; 8]);
    read_with_crate(file, Cursor::new(data), size, true)
}

/// Reads the points with the `las` crate (used for LAZ), from the start of a file of `size`
/// bytes; `truncated_file` says the file is known to be cut short.
fn read_with_crate<R: Read + Seek + Send + Sync + 'static>(
    file: &str,
    read: R,
    size: usize,
    truncated_file: bool,
) -> Result<Cloud, LoadError> {
    let mut reader = las::Reader::new(read).map_err(|e| header_error(file, e, size))?;
    let declared = reader.header().number_of_points();
    // Compressed records bound the count only loosely: reserve at most one point per two
    // bytes and let honest files that compress better grow the vectors.
    let capacity = usize::try_from(declared)
        .unwrap_or(usize::MAX)
        .min(size / 2);
    let mut world = Vec::with_capacity(capacity);
    let mut rgb16 = Vec::new();
    let mut intensity = Vec::with_capacity(capacity);
    let mut class = Vec::with_capacity(capacity);
    let mut index = 0u64;
    while let Some(point) = reader.read_point().map_err(|e| {
        let message = match e {
            _ if truncated_file => truncated(index, declared, size),
            las::Error::Io(e) if e.kind() == ErrorKind::UnexpectedEof => {
                truncated(index, declared, size)
            }
            e => format!("point record {index} of {declared}: {e}"),
        };
        LoadError::whole(file, message)
    })? {
        world.push(DVec3::new(point.x, point.y, point.z));
        if let Some(c) = point.color {
            rgb16.push([c.red, c.green, c.blue]);
        }
        intensity.push(f32::from(point.intensity));
        class.push(f32::from(u8::from(point.classification)));
        index += 1;
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
    Ok(finish(
        positions, colors, intensity, class, origin, declared,
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
        let mut builder = Builder::from((1, 4));
        builder.point_format = Format::new(format).unwrap();
        builder.point_format.extra_bytes = 3;
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
        for i in 0..n {
            let f = i as f64;
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
        let reference =
            read_with_crate(name, Cursor::new(bytes.clone()), bytes.len(), false).unwrap();
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

    #[test]
    fn shared_files_match_the_las_crate() {
        let root = std::env::var_os("SURFEL_DATA")
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
        for file in ["autzen_trim.las", "vegetation_1_3.las"] {
            let bytes = std::fs::read(root.join("lidar").join(file)).unwrap();
            assert_matches_crate(file, bytes);
        }
    }
}

//! PCD v0.7 reader (Point Cloud Library): `DATA ascii`, `binary` and `binary_compressed`.
//!
//! Fields `x y z` give positions, `normal_x normal_y normal_z` normals, a packed `rgb`/`rgba`
//! field (F4 or U4, bytes b, g, r, a in little-endian order) colors; every other numeric field is
//! kept as a named scalar (`name_i` for element `i` of a field with `COUNT` > 1; `_` padding
//! fields are skipped). Points with a non-finite coordinate are dropped and counted. The
//! `VIEWPOINT` translation becomes the cloud's one scan position ([`Cloud::sensors`]).
//!
//! **Up axis.** An organized cloud (`HEIGHT` > 1: a depth or RGB-D camera's image) is in the
//! camera's frame, x right, y down, z forward, so its up axis is -y. The `VIEWPOINT` rotation
//! is not applied to it: PCL's own sample scans record a rotation (180° about x) their points,
//! all in front of the camera (z > 0), do not follow. An unorganized cloud (`HEIGHT` 1) keeps
//! the survey formats' +z.
//!
//! Coordinates are kept in f64 while reading. When the finite points reach a magnitude of
//! [`RECENTRE_MAGNITUDE`] (projected coordinates such as UTM, ~5 × 10⁶ m), the f64 centre of
//! their bounding box becomes [`Cloud::origin`] and is subtracted before the conversion to f32,
//! as for LAS, so the local coordinates keep the precision the file's values had.

use std::path::Path;

use glam::{DVec3, Vec3};

use super::camera::Up;
use super::cloud::{Bounds, Cloud, LoadStats, Scalar, Sensor};
use super::error::{show, LoadError};
use super::text::{self, Lines};

/// Clouds with a finite coordinate at least this large (in absolute value) are re-centred.
pub const RECENTRE_MAGNITUDE: f64 = 1e5;

/// Largest output an LZF stream can produce per input byte (a 3-byte back-reference copies
/// at most 264 bytes), used to reject absurd uncompressed sizes before allocating.
const LZF_MAX_RATIO: u64 = 88;

/// Decompresses an LZF block (the format PCL uses for `binary_compressed`) into exactly
/// `expected_len` bytes. Errors describe the offset into `input` where decoding failed.
pub fn lzf_decompress(input: &[u8], expected_len: usize) -> Result<Vec<u8>, String> {
    if expected_len as u64 > (input.len() as u64).saturating_mul(LZF_MAX_RATIO) {
        return Err(format!(
            "uncompressed size {expected_len} is impossible for {} compressed bytes",
            input.len()
        ));
    }
    let mut out = Vec::with_capacity(expected_len);
    let mut i = 0;
    while i < input.len() {
        let ctrl = usize::from(input[i]);
        let at = i;
        i += 1;
        if ctrl < 32 {
            let len = ctrl + 1;
            let literal = input.get(i..i + len).ok_or_else(|| {
                format!("literal run of {len} bytes at compressed offset {at} runs past the end of the block")
            })?;
            if out.len() + len > expected_len {
                return Err(format!(
                    "literal run at compressed offset {at} overflows the declared size {expected_len}"
                ));
            }
            out.extend_from_slice(literal);
            i += len;
        } else {
            let mut len = ctrl >> 5;
            if len == 7 {
                len += usize::from(*input.get(i).ok_or_else(|| {
                    format!("back-reference at compressed offset {at} is truncated")
                })?);
                i += 1;
            }
            len += 2;
            let low =
                usize::from(*input.get(i).ok_or_else(|| {
                    format!("back-reference at compressed offset {at} is truncated")
                })?);
            i += 1;
            let distance = ((ctrl & 0x1f) << 8) + low + 1;
            if distance > out.len() {
                return Err(format!(
                    "back-reference at compressed offset {at} points {distance} bytes back, but only {} bytes were decoded",
                    out.len()
                ));
            }
            if out.len() + len > expected_len {
                return Err(format!(
                    "back-reference at compressed offset {at} overflows the declared size {expected_len}"
                ));
            }
            let start = out.len() - distance;
            if distance >= len {
                out.extend_from_within(start..start + len);
            } else {
                // The source overlaps the bytes being written (run-length copies): byte by byte.
                for k in 0..len {
                    let b = out[start + k];
                    out.push(b);
                }
            }
        }
    }
    if out.len() != expected_len {
        return Err(format!(
            "block decodes to {} bytes, but the header declares {expected_len}",
            out.len()
        ));
    }
    Ok(out)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum FieldType {
    Int,
    Uint,
    Float,
}

#[derive(Clone, Debug)]
struct Field {
    name: String,
    size: usize,
    ty: FieldType,
    count: usize,
}

impl Field {
    fn bytes(&self) -> usize {
        self.size.saturating_mul(self.count)
    }

    /// Decodes one little-endian element of this field.
    #[inline]
    fn decode(&self, b: &[u8]) -> f64 {
        match (self.ty, self.size) {
            (FieldType::Int, 1) => f64::from(b[0] as i8),
            (FieldType::Int, 2) => f64::from(i16::from_le_bytes([b[0], b[1]])),
            (FieldType::Int, 4) => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            (FieldType::Int, _) => i64::from_le_bytes(eight(b)) as f64,
            (FieldType::Uint, 1) => f64::from(b[0]),
            (FieldType::Uint, 2) => f64::from(u16::from_le_bytes([b[0], b[1]])),
            (FieldType::Uint, 4) => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            (FieldType::Uint, _) => u64::from_le_bytes(eight(b)) as f64,
            (FieldType::Float, 4) => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            (FieldType::Float, _) => f64::from_le_bytes(eight(b)),
        }
    }
}

fn eight(b: &[u8]) -> [u8; 8] {
    let mut raw = [0u8; 8];
    raw.copy_from_slice(&b[..8]);
    raw
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Data {
    Ascii,
    Binary,
    Compressed,
}

struct Header {
    fields: Vec<Field>,
    points: usize,
    viewpoint: Option<DVec3>,
    /// `WIDTH` and `HEIGHT` when the header gives both.
    image: Option<(usize, usize)>,
    data: Data,
    body: usize,
    lines: usize,
}

fn parse_header(file: &str, bytes: &[u8]) -> Result<Header, LoadError> {
    let mut lines = Lines::new(bytes);
    let mut names: Option<Vec<String>> = None;
    let mut sizes: Option<Vec<usize>> = None;
    let mut types: Option<Vec<FieldType>> = None;
    let mut counts: Option<Vec<usize>> = None;
    let (mut width, mut height, mut points) = (None, None, None);
    let mut viewpoint = None;
    let data = loop {
        let Some(line) = lines.next_line() else {
            return Err(if lines.line() == 0 {
                LoadError::whole(file, "empty file; expected a PCD header")
            } else {
                LoadError::at_line(
                    file,
                    lines.line(),
                    "unexpected end of file; expected a DATA line ending the header",
                )
            });
        };
        let n = lines.line();
        let words: Vec<&[u8]> = text::tokens(line, false).collect();
        let Some(&keyword) = words.first() else {
            continue;
        };
        if keyword.starts_with(b"#") {
            continue;
        }
        let args = &words[1..];
        let err = |what: &str| {
            LoadError::at_line(
                file,
                n,
                format!("expected {what}, found \"{}\"", show(line.trim_ascii())),
            )
        };
        let uints = |what: &str| -> Result<Vec<usize>, LoadError> {
            args.iter()
                .map(|a| text::parse_i64(a).and_then(|v| usize::try_from(v).ok()))
                .collect::<Option<Vec<_>>>()
                .filter(|v| !v.is_empty())
                .ok_or_else(|| err(what))
        };
        match keyword.to_ascii_uppercase().as_slice() {
            b"VERSION" => {}
            b"FIELDS" => {
                names = Some(args.iter().map(|a| String::from_utf8_lossy(a).into_owned()).collect())
            }
            b"SIZE" => {
                let s = uints("field sizes 1, 2, 4 or 8")?;
                if s.iter().any(|s| ![1, 2, 4, 8].contains(s)) {
                    return Err(err("field sizes 1, 2, 4 or 8"));
                }
                sizes = Some(s);
            }
            b"TYPE" => {
                types = Some(
                    args.iter()
                        .map(|a| match a.to_ascii_uppercase().as_slice() {
                            b"I" => Some(FieldType::Int),
                            b"U" => Some(FieldType::Uint),
                            b"F" => Some(FieldType::Float),
                            _ => None,
                        })
                        .collect::<Option<Vec<_>>>()
                        .ok_or_else(|| err("field types I, U or F"))?,
                )
            }
            b"COUNT" => counts = Some(uints("field counts")?),
            b"WIDTH" => width = Some(uints("a width")?[0]),
            b"HEIGHT" => height = Some(uints("a height")?[0]),
            b"POINTS" => points = Some(uints("a point count")?[0]),
            b"VIEWPOINT" => {
                let v: Option<Vec<f64>> = args.iter().map(|a| text::parse_f64(a)).collect();
                match v {
                    Some(v) if v.len() == 7 => {
                        viewpoint = Some(DVec3::new(v[0], v[1], v[2]))
                    }
                    _ => return Err(err("VIEWPOINT tx ty tz qw qx qy qz (7 numbers)")),
                }
            }
            b"DATA" => {
                break match args.first().map(|a| a.to_ascii_lowercase()).as_deref() {
                    Some(b"ascii") => Data::Ascii,
                    Some(b"binary") => Data::Binary,
                    Some(b"binary_compressed") => Data::Compressed,
                    _ => return Err(err("DATA ascii, binary or binary_compressed")),
                }
            }
            _ => return Err(err("a PCD header keyword (VERSION, FIELDS, SIZE, TYPE, COUNT, WIDTH, HEIGHT, VIEWPOINT, POINTS, DATA)")),
        }
    };
    let n_line = lines.line();
    let names = names.ok_or_else(|| LoadError::whole(file, "header has no FIELDS line"))?;
    let sizes = sizes.ok_or_else(|| LoadError::whole(file, "header has no SIZE line"))?;
    let types = types.ok_or_else(|| LoadError::whole(file, "header has no TYPE line"))?;
    let counts = counts.unwrap_or_else(|| vec![1; names.len()]);
    if sizes.len() != names.len() || types.len() != names.len() || counts.len() != names.len() {
        return Err(LoadError::at_line(
            file,
            n_line,
            format!(
                "expected SIZE, TYPE and COUNT to list one entry per field ({} fields), found {}, {} and {}",
                names.len(),
                sizes.len(),
                types.len(),
                counts.len()
            ),
        ));
    }
    let fields: Vec<Field> = names
        .into_iter()
        .zip(sizes)
        .zip(types.into_iter().zip(counts))
        .map(|((name, size), (ty, count))| Field {
            name,
            size,
            ty,
            count,
        })
        .collect();
    if let Some(f) = fields
        .iter()
        .find(|f| f.ty == FieldType::Float && f.size < 4)
    {
        return Err(LoadError::whole(
            file,
            format!(
                "field {} is a float of size {}; expected size 4 or 8",
                show(&f.name),
                f.size
            ),
        ));
    }
    let points = match (points, width, height) {
        (Some(p), _, _) => p,
        (None, Some(w), Some(h)) => w.saturating_mul(h),
        _ => {
            return Err(LoadError::whole(
                file,
                "header has neither POINTS nor WIDTH and HEIGHT",
            ))
        }
    };
    Ok(Header {
        fields,
        points,
        viewpoint,
        image: width.zip(height),
        data,
        body: lines.offset(),
        lines: lines.line(),
    })
}

/// Per-field destination of decoded values.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    Position(usize),
    Normal(usize),
    Color { alpha: bool },
    Scalar(usize),
    Skip,
}

/// Collects decoded values into a cloud.
struct Builder {
    roles: Vec<Role>,
    positions: Vec<[f64; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    colors: Option<Vec<[u8; 4]>>,
    scalars: Vec<Scalar>,
}

impl Builder {
    fn new(file: &str, fields: &[Field], points: usize) -> Result<Self, LoadError> {
        let mut scalars = Vec::new();
        let mut roles = Vec::new();
        for f in fields {
            // Names match in any case, as PDAL's reader matches them; scalars keep the file's.
            let lower = f.name.to_ascii_lowercase();
            let role = match lower.as_str() {
                "x" | "y" | "z" if f.count == 1 => {
                    Role::Position(usize::from(lower.as_bytes()[0] - b'x'))
                }
                "normal_x" | "normal_y" | "normal_z" if f.count == 1 => {
                    Role::Normal(usize::from(lower.as_bytes()[7] - b'x'))
                }
                "rgb" | "rgba" if f.count == 1 && f.size == 4 => Role::Color {
                    alpha: lower == "rgba",
                },
                "_" => Role::Skip,
                _ => {
                    for i in 0..f.count {
                        let name = if f.count == 1 {
                            f.name.clone()
                        } else {
                            format!("{}_{i}", f.name)
                        };
                        scalars.push(Scalar {
                            name,
                            values: Vec::with_capacity(points),
                        });
                    }
                    Role::Scalar(scalars.len() - f.count)
                }
            };
            roles.push(role);
        }
        for axis in 0..3 {
            if !roles.contains(&Role::Position(axis)) {
                return Err(LoadError::whole(file, "the FIELDS line needs x, y and z"));
            }
        }
        let has_normals = (0..3).all(|a| roles.contains(&Role::Normal(a)));
        let has_colors = roles.iter().any(|r| matches!(r, Role::Color { .. }));
        if !has_normals {
            for r in roles.iter_mut().filter(|r| matches!(r, Role::Normal(_))) {
                *r = Role::Skip;
            }
        }
        Ok(Builder {
            roles,
            positions: vec![[0.0; 3]; points],
            normals: has_normals.then(|| vec![[0.0; 3]; points]),
            colors: has_colors.then(|| vec![[0, 0, 0, 255]; points]),
            scalars,
        })
    }

    /// Stores element `element` of field `field` for point `point`, given its raw bytes (binary)
    /// and decoded value.
    #[inline]
    fn set(&mut self, field: usize, element: usize, point: usize, raw: [u8; 4], value: f64) {
        match self.roles[field] {
            Role::Position(a) => self.positions[point][a] = value,
            Role::Normal(a) => {
                if let Some(n) = self.normals.as_mut() {
                    n[point][a] = value as f32;
                }
            }
            Role::Color { alpha } => {
                if let Some(c) = self.colors.as_mut() {
                    c[point] = [raw[2], raw[1], raw[0], if alpha { raw[3] } else { 255 }];
                }
            }
            Role::Scalar(s) => self.scalars[s + element].values.push(value as f32),
            Role::Skip => {}
        }
    }

    fn finish(self, header: &Header) -> Cloud {
        let bounds = self.positions.iter().fold(Bounds::EMPTY, |mut b, p| {
            b.add(DVec3::from(*p));
            b
        });
        let origin = bounds
            .centre()
            .filter(|_| bounds.lo.abs().max(bounds.hi.abs()).max_element() >= RECENTRE_MAGNITUDE)
            .unwrap_or(DVec3::ZERO);
        let mut cloud = Cloud {
            positions: self
                .positions
                .into_iter()
                .map(|p| (DVec3::from(p) - origin).as_vec3())
                .collect(),
            normals: self
                .normals
                .map(|n| n.into_iter().map(Vec3::from).collect()),
            colors: self.colors,
            scalars: self.scalars,
            sensors: header
                .viewpoint
                .map(|v| Sensor {
                    first: 0,
                    position: (v - origin).as_vec3(),
                })
                .into_iter()
                .collect(),
            origin,
            stats: LoadStats {
                records: header.points,
                ..LoadStats::default()
            },
            ..Cloud::default()
        };
        if let Some((width, height)) = header.image.filter(|&(_, h)| h > 1) {
            cloud.up = Up::NegY;
            cloud.stats.up_rule = Some(format!(
                "organized PCD {width}x{height}: a camera's frame, y down"
            ));
        }
        cloud.retain_finite();
        cloud
    }
}

/// The four raw bytes of a 4-byte field element (colors are bit-packed, not numeric).
fn raw4(b: &[u8]) -> [u8; 4] {
    let mut raw = [0u8; 4];
    if b.len() == 4 {
        raw.copy_from_slice(b);
    }
    raw
}

fn parse_ascii(
    file: &str,
    bytes: &[u8],
    header: &Header,
    mut out: Builder,
) -> Result<Cloud, LoadError> {
    let mut lines = Lines::new(&bytes[header.body..]);
    let values_per_point: usize = header.fields.iter().map(|f| f.count).sum();
    let mut point = 0;
    while point < header.points {
        let Some(line) = lines.next_line() else {
            return Err(LoadError::at_line(
                file,
                header.lines + lines.line() + 1,
                format!(
                    "unexpected end of file after {point} points; header declares {} points",
                    header.points
                ),
            ));
        };
        if line.trim_ascii().is_empty() {
            continue;
        }
        let line_no = header.lines + lines.line();
        let mut tokens = text::tokens(line, true);
        let mismatch = || {
            LoadError::at_line(
                file,
                line_no,
                format!(
                    "expected {values_per_point} numbers for point {point}, found \"{}\"",
                    show(line.trim_ascii())
                ),
            )
        };
        for (fi, field) in header.fields.iter().enumerate() {
            for e in 0..field.count {
                let token = tokens.next().ok_or_else(mismatch)?;
                let value = text::parse_f64(token).ok_or_else(mismatch)?;
                let raw = if matches!(out.roles[fi], Role::Color { .. }) {
                    match field.ty {
                        FieldType::Float => (value as f32).to_le_bytes(),
                        _ => (value as u32).to_le_bytes(),
                    }
                } else {
                    [0; 4]
                };
                out.set(fi, e, point, raw, value);
            }
        }
        if tokens.next().is_some() {
            return Err(mismatch());
        }
        point += 1;
    }
    Ok(out.finish(header))
}

fn parse_binary(
    file: &str,
    bytes: &[u8],
    header: &Header,
    mut out: Builder,
) -> Result<Cloud, LoadError> {
    let point_size: usize = header.fields.iter().map(Field::bytes).sum();
    let body = &bytes[header.body..];
    let needed = (header.points as u128) * (point_size as u128);
    if needed > body.len() as u128 {
        return Err(LoadError::at_byte(
            file,
            header.body,
            format!(
                "DATA size mismatch: {} points of {point_size} bytes need {needed} bytes, but only {} bytes follow the header",
                header.points,
                body.len()
            ),
        ));
    }
    for (point, record) in body
        .chunks_exact(point_size.max(1))
        .take(header.points)
        .enumerate()
    {
        let mut offset = 0;
        for (fi, field) in header.fields.iter().enumerate() {
            for e in 0..field.count {
                let b = &record[offset..offset + field.size];
                out.set(fi, e, point, raw4(b), field.decode(b));
                offset += field.size;
            }
        }
    }
    Ok(out.finish(header))
}

fn parse_compressed(
    file: &str,
    bytes: &[u8],
    header: &Header,
    mut out: Builder,
) -> Result<Cloud, LoadError> {
    let body = &bytes[header.body..];
    let word = |at: usize| -> Result<usize, LoadError> {
        body.get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
            .ok_or_else(|| {
                LoadError::at_byte(
                    file,
                    header.body + at,
                    "unexpected end of file; expected the compressed and uncompressed block sizes (2 x u32)",
                )
            })
    };
    let compressed = word(0)?;
    let uncompressed = word(4)?;
    let point_size: usize = header.fields.iter().map(Field::bytes).sum();
    let expected = (header.points as u128) * (point_size as u128);
    if uncompressed as u128 != expected {
        return Err(LoadError::at_byte(
            file,
            header.body + 4,
            format!(
                "DATA size mismatch: {} points of {point_size} bytes need {expected} bytes, but the compressed block declares {uncompressed}",
                header.points
            ),
        ));
    }
    let block = body.get(8..8 + compressed).ok_or_else(|| {
        LoadError::at_byte(
            file,
            header.body + 8,
            format!(
                "truncated compressed block: expected {compressed} bytes, found {}",
                body.len().saturating_sub(8)
            ),
        )
    })?;
    let raw = lzf_decompress(block, uncompressed)
        .map_err(|e| LoadError::at_byte(file, header.body + 8, format!("corrupt LZF data: {e}")))?;
    // Field-major layout: all points' values of field 0, then field 1, ...
    let mut start = 0;
    for (fi, field) in header.fields.iter().enumerate() {
        let len = field.bytes() * header.points;
        let column = &raw[start..start + len];
        for (point, chunk) in column.chunks_exact(field.bytes().max(1)).enumerate() {
            for (e, b) in chunk.chunks_exact(field.size).enumerate() {
                out.set(fi, e, point, raw4(b), field.decode(b));
            }
        }
        start += len;
    }
    Ok(out.finish(header))
}

/// Parses a PCD file held in memory. `file` names it in error messages.
pub fn parse(file: &str, bytes: &[u8]) -> Result<Cloud, LoadError> {
    let header = parse_header(file, bytes)?;
    let remaining = bytes.len() - header.body;
    // Every value of every point takes at least a byte of ASCII (a digit),
    // its size in binary, and its size over the LZF ratio compressed: counts that claim more
    // than the file holds are refused before anything is allocated for them.
    let values: u128 = header.fields.iter().map(|f| f.count as u128).sum();
    let point_bytes: u128 = header.fields.iter().map(|f| f.bytes() as u128).sum();
    let points = header.points as u128;
    let (need, have, unit) = match header.data {
        Data::Ascii => (
            values * points,
            remaining as u128 + 1,
            "bytes of text at least",
        ),
        Data::Binary => (point_bytes * points, remaining as u128, "bytes"),
        Data::Compressed => (
            point_bytes * points,
            remaining as u128 * u128::from(LZF_MAX_RATIO),
            "bytes, more than LZF packs into them",
        ),
    };
    if values > bytes.len() as u128 {
        return Err(LoadError::at_byte(
            file,
            header.body,
            format!(
                "DATA size mismatch: {values} values per point in a file of {} bytes",
                bytes.len()
            ),
        ));
    }
    if need > have {
        return Err(LoadError::at_byte(
            file,
            header.body,
            format!(
                "DATA size mismatch: {points} points of {point_bytes} bytes ({values} values) need {need} {unit}, but only {remaining} bytes follow the header"
            ),
        ));
    }
    let out = Builder::new(file, &header.fields, header.points)?;
    match header.data {
        Data::Ascii => parse_ascii(file, bytes, &header, out),
        Data::Binary => parse_binary(file, bytes, &header, out),
        Data::Compressed => parse_compressed(file, bytes, &header, out),
    }
}

/// Loads a PCD file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let data = super::read_file(path)?;
    parse(&path.display().to_string(), &data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lzf_literals_and_overlapping_backref() {
        // "abc" literal, then a back-reference of length 7 at distance 3 (overlapping copy).
        let block = [2, b'a', b'b', b'c', (5 << 5), 2];
        assert_eq!(lzf_decompress(&block, 10).unwrap(), b"abcabcabca");
        // Long back-reference: len code 7 plus extra byte 1 -> 10 bytes, distance 1.
        let block = [0, b'z', (7 << 5), 1, 0];
        assert_eq!(lzf_decompress(&block, 11).unwrap(), vec![b'z'; 11]);
    }

    #[test]
    fn lzf_rejects_corruption() {
        assert!(lzf_decompress(&[2, b'a'], 3)
            .unwrap_err()
            .contains("past the end"));
        assert!(lzf_decompress(&[0, b'a', (1 << 5), 5], 4)
            .unwrap_err()
            .contains("points 6 bytes back"));
        assert!(lzf_decompress(&[0, b'a'], 2)
            .unwrap_err()
            .contains("declares 2"));
        assert!(lzf_decompress(&[0, b'a'], 1_000)
            .unwrap_err()
            .contains("impossible"));
        assert!(lzf_decompress(&[0, b'a', (7 << 5)], 20)
            .unwrap_err()
            .contains("truncated"));
    }

    #[test]
    fn ascii_with_nan_and_viewpoint() {
        let data = b"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb intensity\nSIZE 4 4 4 4 4\nTYPE F F F U F\nCOUNT 1 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 1 2 3 1 0 0 0\nPOINTS 3\nDATA ascii\n0 0 1 16711680 0.5\nnan nan nan 0 0\n1 1 1 255 2\n";
        let c = parse("a.pcd", data).unwrap();
        assert_eq!(c.len(), 2);
        assert_eq!(c.stats.dropped_non_finite, 1);
        assert_eq!(c.stats.records, 3);
        assert_eq!(c.colors.as_ref().unwrap()[0], [255, 0, 0, 255]);
        assert_eq!(c.colors.as_ref().unwrap()[1], [0, 0, 255, 255]);
        assert_eq!(c.scalars[0].values, vec![0.5, 2.0]);
        assert_eq!(
            c.sensors,
            vec![Sensor {
                first: 0,
                position: Vec3::new(1.0, 2.0, 3.0)
            }]
        );
    }

    #[test]
    fn organized_clouds_are_in_a_camera_frame_with_y_down() {
        let header = |w: usize, h: usize, viewpoint: &str| {
            format!("VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {w}\nHEIGHT {h}\n{viewpoint}POINTS 4\nDATA ascii\n0 0 1\n1 0 1\n0 1 1\n1 1 2\n")
        };
        for viewpoint in ["", "VIEWPOINT 0 0 0 0 1 0 0\n"] {
            let c = parse("o.pcd", header(2, 2, viewpoint).as_bytes()).unwrap();
            assert_eq!(c.up, Up::NegY);
            assert_eq!(
                c.stats.up_rule.as_deref(),
                Some("organized PCD 2x2: a camera's frame, y down")
            );
        }
        let c = parse("u.pcd", header(4, 1, "").as_bytes()).unwrap();
        assert_eq!(c.stats.up_rule, None);
    }
}

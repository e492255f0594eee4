//! PLY reader (ascii, binary_little_endian, binary_big_endian) and a binary PLY writer.
//!
//! The `vertex` element supplies positions (`x y z`), normals (`nx ny nz`), colors
//! (`red green blue [alpha]`, 8-bit, 16-bit or float 0..1), `radius`, and every other scalar
//! property as a named [`Scalar`]. The `face` element's `vertex_indices` (or `vertex_index`)
//! list is fan-triangulated. Any other element is skipped.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::path::Path;
use std::slice::{ChunksExact, ChunksMut};

use glam::{DVec3, Vec3};

use rayon::prelude::*;

use super::cloud::{Bounds, Cloud, LoadStats, Scalar};
use super::error::{show, LoadError};
use super::progress::Progress;
use super::records;
use super::text::{self, Lines};

/// A Rust number type that a PLY scalar type decodes to.
trait Raw {
    /// Reads the value at the start of `b` in big-endian (`big`) or little-endian order.
    fn read(b: &[u8], big: bool) -> f64;
}

macro_rules! impl_raw {
    ($($t:ty),*) => {$(
        impl Raw for $t {
            #[inline(always)]
            fn read(b: &[u8], big: bool) -> f64 {
                let mut raw = [0u8; std::mem::size_of::<$t>()];
                raw.copy_from_slice(&b[..std::mem::size_of::<$t>()]);
                let value = if big {
                    <$t>::from_be_bytes(raw)
                } else {
                    <$t>::from_le_bytes(raw)
                };
                value as f64
            }
        }
    )*};
}

impl_raw!(i8, u8, i16, u16, i32, u32, f32, f64);

/// Evaluates `$body` with `$T` naming the Rust type of the [`ScalarType`] `$t`, so that a loop
/// in the body is compiled once per type instead of matching the type for every value.
macro_rules! with_type {
    ($t:expr, $T:ident => $body:expr) => {
        match $t {
            ScalarType::I8 => {
                type $T = i8;
                $body
            }
            ScalarType::U8 => {
                type $T = u8;
                $body
            }
            ScalarType::I16 => {
                type $T = i16;
                $body
            }
            ScalarType::U16 => {
                type $T = u16;
                $body
            }
            ScalarType::I32 => {
                type $T = i32;
                $body
            }
            ScalarType::U32 => {
                type $T = u32;
                $body
            }
            ScalarType::F32 => {
                type $T = f32;
                $body
            }
            ScalarType::F64 => {
                type $T = f64;
                $body
            }
        }
    };
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ScalarType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl ScalarType {
    fn parse(name: &[u8]) -> Option<Self> {
        Some(match name {
            b"char" | b"int8" => Self::I8,
            b"uchar" | b"uint8" => Self::U8,
            b"short" | b"int16" => Self::I16,
            b"ushort" | b"uint16" => Self::U16,
            b"int" | b"int32" => Self::I32,
            b"uint" | b"uint32" => Self::U32,
            b"float" | b"float32" => Self::F32,
            b"double" | b"float64" => Self::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::F64 => 8,
        }
    }

    /// Decodes one value from the first `self.size()` bytes of `b`.
    #[inline]
    fn decode(self, b: &[u8], big: bool) -> f64 {
        with_type!(self, T => T::read(b, big))
    }

    /// Calls `f(row, value)` with the value of this type at byte `offset` of every record;
    /// the type is matched once, not per value.
    #[inline]
    fn each_value(
        self,
        records: ChunksExact<'_, u8>,
        offset: usize,
        big: bool,
        mut f: impl FnMut(usize, f64),
    ) {
        with_type!(self, T => {
            for (row, r) in records.enumerate() {
                f(row, T::read(&r[offset..], big));
            }
        })
    }

    /// Converts a color channel of this type to 8 bits.
    fn to_u8_channel(self, v: f64) -> u8 {
        let scaled = match self {
            // Exact for in-range bytes; the common case needs no rounding.
            Self::U8 => return v as u8,
            Self::F32 | Self::F64 => v * 255.0,
            Self::U16 | Self::I16 => v / 257.0,
            _ => v,
        };
        if scaled.is_nan() {
            0
        } else {
            scaled.round().clamp(0.0, 255.0) as u8
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Scalar(ScalarType),
    List { count: ScalarType, item: ScalarType },
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    kind: Kind,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

impl Element {
    /// Smallest possible size of one binary record (lists count as empty).
    fn min_record_size(&self) -> usize {
        self.props
            .iter()
            .map(|p| match p.kind {
                Kind::Scalar(t) => t.size(),
                Kind::List { count, .. } => count.size(),
            })
            .sum()
    }

    /// Size of a binary record when the element has no list property.
    fn fixed_record_size(&self) -> Option<usize> {
        self.props
            .iter()
            .all(|p| matches!(p.kind, Kind::Scalar(_)))
            .then(|| self.min_record_size())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { big: bool },
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the first data byte.
    body: usize,
    /// Number of header lines (the body starts on the next line).
    lines: usize,
}

/// Parses the header at the start of `data`; `file_len` is the size of the whole file (`data`
/// may hold only its beginning).
fn parse_header(file: &str, data: &[u8], file_len: usize) -> Result<Header, LoadError> {
    let mut lines = Lines::new(data);
    match lines.next_line() {
        Some(l) if l.trim_ascii() == b"ply" => {}
        Some(l) => {
            return Err(LoadError::at_line(
                file,
                1,
                format!("expected the magic line \"ply\", found \"{}\"", show(l)),
            ))
        }
        None => return Err(LoadError::whole(file, "empty file; expected a PLY header")),
    }
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        let Some(line) = lines.next_line() else {
            return Err(LoadError::at_line(
                file,
                lines.line(),
                "unexpected end of file; expected \"end_header\"",
            ));
        };
        let n = lines.line();
        let words: Vec<&[u8]> = text::tokens(line, false).collect();
        let err = |msg: String| LoadError::at_line(file, n, msg);
        match words.first().copied() {
            None | Some(b"comment") | Some(b"obj_info") => {}
            Some(b"end_header") => break,
            Some(b"format") => {
                encoding = Some(match words.get(1).copied() {
                    Some(b"ascii") => Encoding::Ascii,
                    Some(b"binary_little_endian") => Encoding::Binary { big: false },
                    Some(b"binary_big_endian") => Encoding::Binary { big: true },
                    other => {
                        return Err(err(format!(
                            "expected format ascii, binary_little_endian or binary_big_endian, found \"{}\"",
                            show(other.unwrap_or_default())
                        )))
                    }
                });
            }
            Some(b"element") => {
                let (Some(name), Some(count)) = (words.get(1), words.get(2)) else {
                    return Err(err(format!(
                        "expected \"element <name> <count>\", found \"{}\"",
                        show(line)
                    )));
                };
                let count = text::parse_i64(count)
                    .and_then(|c| usize::try_from(c).ok())
                    .ok_or_else(|| {
                        err(format!(
                            "expected a non-negative element count, found \"{}\"",
                            show(count)
                        ))
                    })?;
                elements.push(Element {
                    name: String::from_utf8_lossy(name).into_owned(),
                    count,
                    props: Vec::new(),
                });
            }
            Some(b"property") => {
                let Some(element) = elements.last_mut() else {
                    return Err(err("property declared before any element".into()));
                };
                let bad = || {
                    err(format!(
                        "expected \"property <type> <name>\" or \"property list <count type> <item type> <name>\", found \"{}\"",
                        show(line)
                    ))
                };
                let (kind, name) = if words.get(1).copied() == Some(b"list") {
                    let count = words.get(2).and_then(|w| ScalarType::parse(w));
                    let item = words.get(3).and_then(|w| ScalarType::parse(w));
                    match (count, item, words.get(4)) {
                        (Some(count), Some(item), Some(name)) => (Kind::List { count, item }, name),
                        _ => return Err(bad()),
                    }
                } else {
                    match (words.get(1).and_then(|w| ScalarType::parse(w)), words.get(2)) {
                        (Some(t), Some(name)) => (Kind::Scalar(t), name),
                        _ => return Err(bad()),
                    }
                };
                element.props.push(Property {
                    name: String::from_utf8_lossy(name).into_owned(),
                    kind,
                });
            }
            Some(other) => {
                return Err(err(format!(
                    "expected a header keyword (format, element, property, comment, end_header), found \"{}\"",
                    show(other)
                )))
            }
        }
    }
    let encoding =
        encoding.ok_or_else(|| LoadError::whole(file, "header has no \"format\" line"))?;
    let header = Header {
        encoding,
        elements,
        body: lines.offset(),
        lines: lines.line(),
    };
    check_counts(file, &header, file_len.saturating_sub(header.body))?;
    Ok(header)
}

/// Rejects header counts that cannot fit in the file, before anything is allocated.
fn check_counts(file: &str, header: &Header, body_len: usize) -> Result<(), LoadError> {
    let mut needed: u128 = 0;
    for e in &header.elements {
        let per_record = match header.encoding {
            Encoding::Binary { .. } => e.min_record_size(),
            // The shortest ascii record is one digit and a line break.
            Encoding::Ascii if e.props.is_empty() => 0,
            Encoding::Ascii => 2,
        } as u128;
        needed += per_record * e.count as u128;
        // The last ascii line may lack its line break.
        let available = body_len as u128 + u128::from(header.encoding == Encoding::Ascii);
        if needed > available {
            return Err(LoadError::at_byte(
                file,
                header.body,
                format!(
                    "header declares {} {} records, which need at least {} bytes, but only {} bytes follow the header",
                    e.count, show(&e.name), needed, body_len
                ),
            ));
        }
    }
    Ok(())
}

/// Reads records of one element in either encoding.
struct Body<'a> {
    file: &'a str,
    data: &'a [u8],
    pos: usize,
    /// File offset of `data[0]` (for error messages).
    base: usize,
    lines: Lines<'a>,
    line_base: usize,
    encoding: Encoding,
}

impl<'a> Body<'a> {
    /// A reader of `data` from `pos` on; `data[0]` is at byte `base` of the file.
    fn new(file: &'a str, data: &'a [u8], pos: usize, base: usize, header: &Header) -> Self {
        Body {
            file,
            data,
            pos,
            base,
            lines: Lines::new(&data[pos.min(data.len())..]),
            line_base: header.lines,
            encoding: header.encoding,
        }
    }

    /// Reads one record. Scalar properties go to `scalars` (by property index); the items of
    /// the list property `keep_list` go to `list`; other lists are skipped.
    fn record(
        &mut self,
        element: &Element,
        index: usize,
        keep_list: Option<usize>,
        scalars: &mut [f64],
        list: &mut Vec<f64>,
    ) -> Result<(), LoadError> {
        list.clear();
        match self.encoding {
            Encoding::Binary { big } => {
                self.binary_record(element, index, big, keep_list, scalars, list)
            }
            Encoding::Ascii => self.ascii_record(element, index, keep_list, scalars, list),
        }
    }

    fn take(&mut self, n: usize, element: &Element, index: usize) -> Result<&'a [u8], LoadError> {
        match self.data.get(self.pos..self.pos.saturating_add(n)) {
            Some(bytes) => {
                self.pos += n;
                Ok(bytes)
            }
            None => Err(LoadError::at_byte(
                self.file,
                self.base + self.pos,
                format!(
                    "unexpected end of file; expected {n} more bytes for {} {index} of {}",
                    show(&element.name),
                    element.count
                ),
            )),
        }
    }

    fn binary_record(
        &mut self,
        element: &Element,
        index: usize,
        big: bool,
        keep_list: Option<usize>,
        scalars: &mut [f64],
        list: &mut Vec<f64>,
    ) -> Result<(), LoadError> {
        if let Some(size) = element.fixed_record_size() {
            let record = self.take(size, element, index)?;
            let mut offset = 0;
            for (value, prop) in scalars.iter_mut().zip(&element.props) {
                if let Kind::Scalar(t) = prop.kind {
                    *value = t.decode(&record[offset..offset + t.size()], big);
                    offset += t.size();
                }
            }
            return Ok(());
        }
        for (p, prop) in element.props.iter().enumerate() {
            match prop.kind {
                Kind::Scalar(t) => scalars[p] = t.decode(self.take(t.size(), element, index)?, big),
                Kind::List { count, item } => {
                    let at = self.base + self.pos;
                    let n = count.decode(self.take(count.size(), element, index)?, big);
                    if !(n >= 0.0 && n.fract() == 0.0) {
                        return Err(LoadError::at_byte(
                            self.file,
                            at,
                            format!(
                                "expected a non-negative list length for {} of {} {index}, found {n}",
                                show(&prop.name), show(&element.name)
                            ),
                        ));
                    }
                    let bytes =
                        self.take((n as usize).saturating_mul(item.size()), element, index)?;
                    if keep_list == Some(p) {
                        list.extend(bytes.chunks_exact(item.size()).map(|b| item.decode(b, big)));
                    }
                }
            }
        }
        Ok(())
    }

    fn ascii_record(
        &mut self,
        element: &Element,
        index: usize,
        keep_list: Option<usize>,
        scalars: &mut [f64],
        list: &mut Vec<f64>,
    ) -> Result<(), LoadError> {
        let line = loop {
            match self.lines.next_line() {
                Some(l) if l.trim_ascii().is_empty() => continue,
                Some(l) => break l,
                None => {
                    return Err(LoadError::at_line(
                        self.file,
                        self.line_base + self.lines.line() + 1,
                        format!(
                            "unexpected end of file; expected {} {index} of {}",
                            show(&element.name),
                            element.count
                        ),
                    ))
                }
            }
        };
        let line_no = self.line_base + self.lines.line();
        let mut expected = 0usize;
        let mut tokens = text::tokens(line, false);
        let file = self.file;
        let mismatch = |expected: usize, what: &str| {
            LoadError::at_line(
                file,
                line_no,
                format!(
                    "expected {expected} {what} for {} {index}, found \"{}\"",
                    show(&element.name),
                    show(line.trim_ascii())
                ),
            )
        };
        for (p, prop) in element.props.iter().enumerate() {
            match prop.kind {
                Kind::Scalar(_) => {
                    expected += 1;
                    scalars[p] = tokens
                        .next()
                        .and_then(text::parse_f64)
                        .ok_or_else(|| mismatch(expected, "numbers"))?;
                }
                Kind::List { .. } => {
                    expected += 1;
                    let n = tokens
                        .next()
                        .and_then(text::parse_i64)
                        .and_then(|n| usize::try_from(n).ok())
                        .ok_or_else(|| mismatch(expected, "numbers (a list length)"))?;
                    expected += n;
                    for _ in 0..n {
                        let v = tokens
                            .next()
                            .and_then(text::parse_f64)
                            .ok_or_else(|| mismatch(expected, "numbers"))?;
                        if keep_list == Some(p) {
                            list.push(v);
                        }
                    }
                }
            }
        }
        if tokens.next().is_some() {
            return Err(mismatch(expected, "numbers only"));
        }
        Ok(())
    }

    /// Skips all records of an element.
    fn skip(&mut self, element: &Element) -> Result<(), LoadError> {
        if let (Encoding::Binary { .. }, Some(size)) = (self.encoding, element.fixed_record_size())
        {
            self.take(size.saturating_mul(element.count), element, 0)?;
            return Ok(());
        }
        let mut scalars = vec![0.0; element.props.len()];
        let mut list = Vec::new();
        for i in 0..element.count {
            self.record(element, i, None, &mut scalars, &mut list)?;
        }
        Ok(())
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Role {
    X,
    Y,
    Z,
    Nx,
    Ny,
    Nz,
    Red,
    Green,
    Blue,
    Alpha,
    Radius,
    Scalar(usize),
    Ignore,
}

fn vertex_role(name: &str, next_scalar: &mut usize) -> Role {
    match name {
        "x" => Role::X,
        "y" => Role::Y,
        "z" => Role::Z,
        "nx" | "normal_x" => Role::Nx,
        "ny" | "normal_y" => Role::Ny,
        "nz" | "normal_z" => Role::Nz,
        "red" | "r" | "diffuse_red" => Role::Red,
        "green" | "g" | "diffuse_green" => Role::Green,
        "blue" | "b" | "diffuse_blue" => Role::Blue,
        "alpha" | "a" | "diffuse_alpha" => Role::Alpha,
        "radius" => Role::Radius,
        _ => {
            *next_scalar += 1;
            Role::Scalar(*next_scalar - 1)
        }
    }
}

/// What the vertex element's properties mean, decided once from the header.
#[derive(Clone)]
struct VertexSpec {
    /// Role of every property, by property index (lists are ignored).
    roles: Vec<Role>,
    scalar_names: Vec<String>,
    has_normals: bool,
    has_colors: bool,
    has_alpha: bool,
    has_radius: bool,
    /// Types of red, green, blue and alpha (for the conversion to 8 bits).
    color_types: [ScalarType; 4],
}

impl VertexSpec {
    fn new(file: &str, element: &Element) -> Result<Self, LoadError> {
        let mut scalar_names = Vec::new();
        let mut next_scalar = 0;
        let roles: Vec<Role> = element
            .props
            .iter()
            .map(|p| match p.kind {
                Kind::List { .. } => Role::Ignore,
                Kind::Scalar(_) => {
                    let role = vertex_role(&p.name, &mut next_scalar);
                    if let Role::Scalar(_) = role {
                        scalar_names.push(p.name.clone());
                    }
                    role
                }
            })
            .collect();
        let has = |r: Role| roles.contains(&r);
        let type_of = |r: Role| {
            roles
                .iter()
                .position(|x| *x == r)
                .and_then(|i| match element.props[i].kind {
                    Kind::Scalar(t) => Some(t),
                    Kind::List { .. } => None,
                })
                .unwrap_or(ScalarType::U8)
        };
        if !(has(Role::X) && has(Role::Y) && has(Role::Z)) {
            return Err(LoadError::whole(
                file,
                "the vertex element needs properties x, y and z",
            ));
        }
        Ok(VertexSpec {
            has_normals: has(Role::Nx) && has(Role::Ny) && has(Role::Nz),
            has_colors: has(Role::Red) && has(Role::Green) && has(Role::Blue),
            has_alpha: has(Role::Alpha),
            has_radius: has(Role::Radius),
            color_types: [
                type_of(Role::Red),
                type_of(Role::Green),
                type_of(Role::Blue),
                type_of(Role::Alpha),
            ],
            roles,
            scalar_names,
        })
    }
}

/// The origin for a local frame: zero for small coordinates (so round trips are exact), else
/// the f64 centre of the finite points' bounding box.
fn local_origin(bounds: &Bounds) -> DVec3 {
    match bounds.centre() {
        Some(c) if bounds.lo.abs().max(bounds.hi.abs()).max_element() >= 1.0e4 => c,
        _ => DVec3::ZERO,
    }
}

/// The vertex attribute columns, sized for every record before decoding starts.
struct Columns {
    positions: Vec<Vec3>,
    normals: Option<Vec<Vec3>>,
    colors: Option<Vec<[u8; 4]>>,
    radii: Option<Vec<f32>>,
    scalars: Vec<Vec<f32>>,
}

/// The rows of [`Columns`] that one parallel task writes.
struct ColumnsMut<'a> {
    positions: &'a mut [Vec3],
    normals: Option<&'a mut [Vec3]>,
    colors: Option<&'a mut [[u8; 4]]>,
    radii: Option<&'a mut [f32]>,
    scalars: Vec<&'a mut [f32]>,
}

impl Columns {
    fn new(spec: &VertexSpec, n: usize) -> Self {
        Columns {
            positions: records::filled(Vec3::ZERO, n),
            normals: spec.has_normals.then(|| records::filled(Vec3::ZERO, n)),
            colors: spec.has_colors.then(|| records::filled([0, 0, 0, 255], n)),
            radii: spec.has_radius.then(|| records::filled(0.0, n)),
            scalars: (spec.scalar_names.iter())
                .map(|_| records::filled(0.0, n))
                .collect(),
        }
    }

    /// Splits rows `rows` of every column into consecutive pieces of `per_task` rows.
    fn tasks(&mut self, rows: Range<usize>, per_task: usize) -> Vec<ColumnsMut<'_>> {
        fn split<'c, T>(
            column: &'c mut [T],
            rows: &Range<usize>,
            per_task: usize,
        ) -> ChunksMut<'c, T> {
            column[rows.clone()].chunks_mut(per_task)
        }
        let mut normals = self
            .normals
            .as_deref_mut()
            .map(|c| split(c, &rows, per_task));
        let mut colors = self
            .colors
            .as_deref_mut()
            .map(|c| split(c, &rows, per_task));
        let mut radii = self.radii.as_deref_mut().map(|c| split(c, &rows, per_task));
        let mut scalars: Vec<_> = self
            .scalars
            .iter_mut()
            .map(|c| split(c, &rows, per_task))
            .collect();
        split(&mut self.positions, &rows, per_task)
            .map(|positions| ColumnsMut {
                positions,
                normals: normals.as_mut().and_then(Iterator::next),
                colors: colors.as_mut().and_then(Iterator::next),
                radii: radii.as_mut().and_then(Iterator::next),
                scalars: scalars.iter_mut().filter_map(Iterator::next).collect(),
            })
            .collect()
    }

    /// Moves the columns into `cloud`.
    fn store(self, spec: VertexSpec, origin: DVec3, cloud: &mut Cloud) {
        cloud.positions = self.positions;
        cloud.normals = self.normals;
        cloud.colors = self.colors;
        cloud.radii = self.radii;
        cloud.scalars = spec
            .scalar_names
            .into_iter()
            .zip(self.scalars)
            .map(|(name, values)| Scalar { name, values })
            .collect();
        cloud.origin = origin;
    }
}

/// Byte offsets and roles of the properties of a list-free vertex element's binary records.
struct VertexLayout {
    stride: usize,
    big: bool,
    xyz: [(usize, ScalarType); 3],
    /// Every other property that has a destination: offset, type and role.
    others: Vec<(usize, ScalarType, Role)>,
}

impl VertexLayout {
    /// The layout of `element`'s records, which have no list property and `stride` bytes
    /// ([`Element::fixed_record_size`]).
    fn new(element: &Element, spec: &VertexSpec, big: bool, stride: usize) -> Self {
        let mut xyz = [(0, ScalarType::F32); 3];
        let mut others = Vec::new();
        let mut offset = 0;
        for (prop, &role) in element.props.iter().zip(&spec.roles) {
            let Kind::Scalar(t) = prop.kind else {
                continue;
            };
            match role {
                Role::X => xyz[0] = (offset, t),
                Role::Y => xyz[1] = (offset, t),
                Role::Z => xyz[2] = (offset, t),
                Role::Nx | Role::Ny | Role::Nz if !spec.has_normals => {}
                Role::Red | Role::Green | Role::Blue | Role::Alpha if !spec.has_colors => {}
                Role::Ignore => {}
                _ => others.push((offset, t, role)),
            }
            offset += t.size();
        }
        VertexLayout {
            stride,
            big,
            xyz,
            others,
        }
    }

    /// Decodes the whole records in `bytes` into `out` (one row per record). Positions are
    /// stored relative to `origin`; with `positions_only` the other columns are left alone.
    /// Returns the bounds of the finite positions.
    fn decode(
        &self,
        bytes: &[u8],
        out: ColumnsMut<'_>,
        origin: DVec3,
        positions_only: bool,
    ) -> Bounds {
        let records = bytes.chunks_exact(self.stride);
        let big = self.big;
        let [(ox, tx), (oy, ty), (oz, tz)] = self.xyz;
        let positions = &mut *out.positions;
        let bounds = if tx == ty && tx == tz {
            with_type!(tx, T => decode_positions(records.clone(), positions, origin, |r| {
                DVec3::new(
                    T::read(&r[ox..], big),
                    T::read(&r[oy..], big),
                    T::read(&r[oz..], big),
                )
            }))
        } else {
            decode_positions(records.clone(), positions, origin, |r| {
                DVec3::new(
                    tx.decode(&r[ox..], big),
                    ty.decode(&r[oy..], big),
                    tz.decode(&r[oz..], big),
                )
            })
        };
        if positions_only {
            return bounds;
        }
        let ColumnsMut {
            mut normals,
            mut colors,
            mut radii,
            mut scalars,
            ..
        } = out;
        for &(offset, t, role) in &self.others {
            let records = records.clone();
            let axis = match role {
                Role::Nx | Role::Red => 0,
                Role::Ny | Role::Green => 1,
                Role::Nz | Role::Blue => 2,
                _ => 3,
            };
            match (role, normals.as_deref_mut(), colors.as_deref_mut()) {
                (Role::Nx | Role::Ny | Role::Nz, Some(ns), _) => {
                    t.each_value(records, offset, big, |row, v| ns[row][axis] = v as f32)
                }
                (Role::Red | Role::Green | Role::Blue | Role::Alpha, _, Some(cs)) => {
                    t.each_value(records, offset, big, |row, v| {
                        cs[row][axis] = t.to_u8_channel(v)
                    })
                }
                (Role::Radius, ..) => {
                    if let Some(rs) = radii.as_deref_mut() {
                        t.each_value(records, offset, big, |row, v| rs[row] = v as f32);
                    }
                }
                (Role::Scalar(s), ..) => {
                    let values = &mut *scalars[s];
                    t.each_value(records, offset, big, |row, v| values[row] = v as f32);
                }
                _ => {}
            }
        }
        bounds
    }

    /// Decodes the records in `bytes`, which are rows `first..` of `columns`, in parallel.
    fn decode_block(
        &self,
        columns: &mut Columns,
        first: usize,
        bytes: &[u8],
        origin: DVec3,
        positions_only: bool,
    ) -> Bounds {
        let per_task = records::task_records(self.stride);
        let rows = first..first + bytes.len() / self.stride;
        columns
            .tasks(rows, per_task)
            .into_par_iter()
            .zip(bytes.par_chunks(per_task * self.stride))
            .map(|(out, b)| self.decode(b, out, origin, positions_only))
            .reduce(|| Bounds::EMPTY, Bounds::union)
    }
}

/// Stores the position `world(record)` of every record relative to `origin` and returns the
/// bounds of the finite ones.
#[inline]
fn decode_positions(
    records: ChunksExact<'_, u8>,
    positions: &mut [Vec3],
    origin: DVec3,
    world: impl Fn(&[u8]) -> DVec3,
) -> Bounds {
    let mut bounds = Bounds::EMPTY;
    for (r, p) in records.zip(positions) {
        let w = world(r);
        bounds.add(w);
        *p = (w - origin).as_vec3();
    }
    bounds
}

/// Reads the vertex element from memory: list-free binary records in parallel, anything else
/// (ascii, records with lists) record by record.
fn read_vertices(
    body: &mut Body<'_>,
    element: &Element,
    cloud: &mut Cloud,
) -> Result<(), LoadError> {
    let spec = VertexSpec::new(body.file, element)?;
    let n = element.count;
    if let (Encoding::Binary { big }, Some(stride)) = (body.encoding, element.fixed_record_size()) {
        let layout = VertexLayout::new(element, &spec, big, stride);
        let bytes = body.take(n.saturating_mul(stride), element, 0)?;
        let mut columns = Columns::new(&spec, n);
        let bounds = layout.decode_block(&mut columns, 0, bytes, DVec3::ZERO, false);
        let origin = local_origin(&bounds);
        if origin != DVec3::ZERO {
            layout.decode_block(&mut columns, 0, bytes, origin, true);
        }
        columns.store(spec, origin, cloud);
        return Ok(());
    }
    let mut positions = Vec::with_capacity(n);
    let mut columns = Columns {
        positions: Vec::new(),
        normals: spec.has_normals.then(|| Vec::with_capacity(n)),
        colors: spec.has_colors.then(|| Vec::with_capacity(n)),
        radii: spec.has_radius.then(|| Vec::with_capacity(n)),
        scalars: spec
            .scalar_names
            .iter()
            .map(|_| Vec::with_capacity(n))
            .collect(),
    };
    let mut values = vec![0.0f64; element.props.len()];
    let mut list = Vec::new();
    let mut bounds = Bounds::EMPTY;
    for i in 0..n {
        body.record(element, i, None, &mut values, &mut list)?;
        let p = push_vertex(&spec, &values, &mut columns);
        bounds.add(p);
        positions.push(p);
    }
    let origin = local_origin(&bounds);
    columns.positions = positions.iter().map(|p| (*p - origin).as_vec3()).collect();
    columns.store(spec, origin, cloud);
    Ok(())
}

/// Appends one decoded vertex record (`values` by property index) to the attribute columns
/// other than positions, and returns its position.
fn push_vertex(spec: &VertexSpec, values: &[f64], columns: &mut Columns) -> DVec3 {
    let mut p = [0.0f64; 3];
    let mut nrm = [0.0f32; 3];
    let mut rgba = [0.0f64, 0.0, 0.0, 255.0];
    for (role, &v) in spec.roles.iter().zip(values) {
        match *role {
            Role::X => p[0] = v,
            Role::Y => p[1] = v,
            Role::Z => p[2] = v,
            Role::Nx => nrm[0] = v as f32,
            Role::Ny => nrm[1] = v as f32,
            Role::Nz => nrm[2] = v as f32,
            Role::Red => rgba[0] = v,
            Role::Green => rgba[1] = v,
            Role::Blue => rgba[2] = v,
            Role::Alpha => rgba[3] = v,
            Role::Radius => {
                if let Some(r) = columns.radii.as_mut() {
                    r.push(v as f32);
                }
            }
            Role::Scalar(s) => columns.scalars[s].push(v as f32),
            Role::Ignore => {}
        }
    }
    if let Some(normals) = columns.normals.as_mut() {
        normals.push(Vec3::from(nrm));
    }
    if let Some(colors) = columns.colors.as_mut() {
        let types = &spec.color_types;
        let alpha = if spec.has_alpha {
            types[3].to_u8_channel(rgba[3])
        } else {
            255
        };
        colors.push([
            types[0].to_u8_channel(rgba[0]),
            types[1].to_u8_channel(rgba[1]),
            types[2].to_u8_channel(rgba[2]),
            alpha,
        ]);
    }
    DVec3::from(p)
}

fn read_faces(
    body: &mut Body<'_>,
    element: &Element,
    list_prop: usize,
    vertex_count: usize,
) -> Result<Vec<[u32; 3]>, LoadError> {
    let mut faces = Vec::with_capacity(element.count);
    let mut values = vec![0.0f64; element.props.len()];
    let mut list = Vec::new();
    let mut indices = Vec::new();
    for i in 0..element.count {
        let at_byte = body.base + body.pos;
        body.record(element, i, Some(list_prop), &mut values, &mut list)?;
        indices.clear();
        for &v in &list {
            if !(v >= 0.0 && v < vertex_count as f64 && v.fract() == 0.0) {
                let message = format!(
                    "face {i}: vertex index {v} is out of range; expected 0..{vertex_count}"
                );
                return Err(match body.encoding {
                    Encoding::Ascii => {
                        LoadError::at_line(body.file, body.line_base + body.lines.line(), message)
                    }
                    Encoding::Binary { .. } => LoadError::at_byte(body.file, at_byte, message),
                });
            }
            indices.push(v as u32);
        }
        for k in 2..indices.len() {
            faces.push([indices[0], indices[k - 1], indices[k]]);
        }
    }
    Ok(faces)
}

/// Reads `elements` from `body`: the first vertex element (unless `seen_vertex`), faces, and
/// skips everything else.
fn read_elements(
    body: &mut Body<'_>,
    elements: &[Element],
    vertex_count: usize,
    mut seen_vertex: bool,
    cloud: &mut Cloud,
) -> Result<(), LoadError> {
    for element in elements {
        let face_list = element.props.iter().position(|p| {
            matches!(p.kind, Kind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        });
        match (element.name.as_str(), face_list) {
            ("vertex", _) if !seen_vertex => {
                read_vertices(body, element, cloud)?;
                seen_vertex = true;
            }
            ("face", Some(list_prop)) => {
                let mut faces = read_faces(body, element, list_prop, vertex_count)?;
                if let Some(existing) = cloud.faces.as_mut() {
                    existing.append(&mut faces);
                } else {
                    cloud.faces = Some(faces);
                }
            }
            _ => body.skip(element)?,
        }
    }
    Ok(())
}

/// Index of the first vertex element.
fn vertex_element(file: &str, header: &Header) -> Result<usize, LoadError> {
    header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| LoadError::whole(file, "the header declares no vertex element"))
}

/// Records the header's vertex count and drops non-finite points.
fn finish(mut cloud: Cloud, vertex_count: usize) -> Cloud {
    cloud.stats = LoadStats {
        records: vertex_count,
        ..LoadStats::default()
    };
    cloud.retain_finite();
    cloud
}

/// Parses a PLY file held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: &[u8]) -> Result<Cloud, LoadError> {
    let header = parse_header(file, data, data.len())?;
    let vertex_count = header.elements[vertex_element(file, &header)?].count;
    let mut body = Body::new(file, data, header.body, 0, &header);
    let mut cloud = Cloud::default();
    read_elements(&mut body, &header.elements, vertex_count, false, &mut cloud)?;
    Ok(finish(cloud, vertex_count))
}

/// Reads from the start of `read` until the buffer holds the header's `end_header` line or
/// the input ends.
fn read_header_bytes(read: &mut impl Read) -> io::Result<Vec<u8>> {
    let mut data = Vec::new();
    let mut scanned = 0;
    loop {
        let got = read.by_ref().take(64 << 10).read_to_end(&mut data)?;
        while let Some(end) = data[scanned..].iter().position(|&b| b == b'\n') {
            let line = &data[scanned..scanned + end];
            scanned += end + 1;
            if text::tokens(line, false).next() == Some(b"end_header") {
                return Ok(data);
            }
        }
        if got == 0 {
            return Ok(data);
        }
    }
}

/// Loads a PLY file. A binary vertex element without list properties (after only list-free
/// elements) is streamed from the file and decoded in parallel while it is read, so the file
/// is never held in memory; the elements after it (faces) are read into memory. Other files
/// are read whole and parsed by [`parse`].
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    load_in_blocks(path, records::BLOCK_BYTES)
}

/// [`load`], reading records in blocks of about `block_bytes`.
fn load_in_blocks(path: &Path, block_bytes: usize) -> Result<Cloud, LoadError> {
    let file = path.display().to_string();
    let io_error = |source| LoadError::Io {
        file: file.clone(),
        source,
    };
    let mut f = File::open(path).map_err(io_error)?;
    let len = f.metadata().map_err(io_error)?.len();
    let mut data = read_header_bytes(&mut f).map_err(io_error)?;
    let header = parse_header(&file, &data, usize::try_from(len).unwrap_or(usize::MAX))?;
    let v = vertex_element(&file, &header)?;
    let element = &header.elements[v];
    let before: Option<usize> = header.elements[..v]
        .iter()
        .map(|e| Some(e.fixed_record_size()? * e.count))
        .sum();
    let (Encoding::Binary { big }, Some(before), Some(stride)) =
        (header.encoding, before, element.fixed_record_size())
    else {
        f.read_to_end(&mut data).map_err(io_error)?;
        return parse(&file, &data);
    };
    drop(data);
    let spec = VertexSpec::new(&file, element)?;
    let layout = VertexLayout::new(element, &spec, big, stride);
    let span = records::Span {
        at: header.body + before,
        count: element.count,
        stride: layout.stride,
    };
    let bytes = span.count * span.stride;
    let start = SeekFrom::Start(span.at as u64);
    let mut columns = Columns::new(&spec, span.count);
    let progress = Progress::new("loading", bytes, bytes >= records::PROGRESS_MIN_BYTES);
    let mut bounds = Bounds::EMPTY;
    f.seek(start).map_err(io_error)?;
    records::for_each_block(
        &file,
        &mut f,
        span,
        block_bytes,
        &progress,
        |first, block| {
            let b = layout.decode_block(&mut columns, first, block, DVec3::ZERO, false);
            bounds = bounds.union(b);
        },
    )?;
    let origin = local_origin(&bounds);
    if origin != DVec3::ZERO {
        // Large coordinates: decode the positions again, relative to the origin.
        f.seek(start).map_err(io_error)?;
        let progress = Progress::new("centring", bytes, bytes >= records::PROGRESS_MIN_BYTES);
        records::for_each_block(
            &file,
            &mut f,
            span,
            block_bytes,
            &progress,
            |first, block| {
                layout.decode_block(&mut columns, first, block, origin, true);
            },
        )?;
    }
    let mut cloud = Cloud::default();
    columns.store(spec, origin, &mut cloud);
    let rest = &header.elements[v + 1..];
    if !rest.is_empty() {
        let at = span.at + bytes;
        f.seek(SeekFrom::Start(at as u64)).map_err(io_error)?;
        let mut tail = Vec::new();
        f.read_to_end(&mut tail).map_err(io_error)?;
        let mut body = Body::new(&file, &tail, 0, at, &header);
        read_elements(&mut body, rest, element.count, true, &mut cloud)?;
    }
    Ok(finish(cloud, element.count))
}

/// Writes `cloud` as binary little-endian PLY: positions (float, or double when the cloud has
/// a non-zero origin, so large coordinates survive), and normals, colors (with alpha) and
/// radii when present, and the faces. Scalars are not written.
pub fn write_binary<W: Write>(cloud: &Cloud, out: W) -> io::Result<()> {
    let mut out = io::BufWriter::new(out);
    let wide = cloud.origin != DVec3::ZERO;
    let n = cloud.len();
    let normals = cloud.normals.as_ref().filter(|v| v.len() == n);
    let colors = cloud.colors.as_ref().filter(|v| v.len() == n);
    let radii = cloud.radii.as_ref().filter(|v| v.len() == n);
    let coord = if wide { "double" } else { "float" };
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment written by surfel\nelement vertex {n}\n"
    )?;
    for axis in ["x", "y", "z"] {
        writeln!(out, "property {coord} {axis}")?;
    }
    if normals.is_some() {
        out.write_all(b"property float nx\nproperty float ny\nproperty float nz\n")?;
    }
    if colors.is_some() {
        out.write_all(
            b"property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n",
        )?;
    }
    if radii.is_some() {
        out.write_all(b"property float radius\n")?;
    }
    let faces = cloud.faces.as_deref().unwrap_or_default();
    if !faces.is_empty() {
        writeln!(out, "element face {}", faces.len())?;
        out.write_all(b"property list uchar int vertex_indices\n")?;
    }
    out.write_all(b"end_header\n")?;
    let stride = if wide { 24 } else { 12 }
        + normals.map_or(0, |_| 12)
        + colors.map_or(0, |_| 4)
        + radii.map_or(0, |_| 4);
    let encode = |i: usize, record: &mut [u8]| {
        let mut at = 0;
        let mut put = |bytes: &[u8]| {
            record[at..at + bytes.len()].copy_from_slice(bytes);
            at += bytes.len();
        };
        let p = cloud.positions[i];
        if wide {
            for c in (p.as_dvec3() + cloud.origin).to_array() {
                put(&c.to_le_bytes());
            }
        } else {
            for c in p.to_array() {
                put(&c.to_le_bytes());
            }
        }
        if let Some(normals) = normals {
            for c in normals[i].to_array() {
                put(&c.to_le_bytes());
            }
        }
        if let Some(colors) = colors {
            put(&colors[i]);
        }
        if let Some(radii) = radii {
            put(&radii[i].to_le_bytes());
        }
    };
    // Records are encoded in parallel, a block at a time, and each block written at once.
    let per_task = records::task_records(stride);
    let per_block = (records::BLOCK_BYTES / stride)
        .max(1)
        .next_multiple_of(per_task);
    let mut block = Vec::new();
    for start in (0..n).step_by(per_block) {
        block.resize((n - start).min(per_block) * stride, 0);
        block
            .par_chunks_mut(per_task * stride)
            .enumerate()
            .for_each(|(task, bytes)| {
                let first = start + task * per_task;
                for (i, record) in bytes.chunks_exact_mut(stride).enumerate() {
                    encode(first + i, record);
                }
            });
        out.write_all(&block)?;
    }
    for face in faces {
        out.write_all(&[3])?;
        for i in face {
            out.write_all(&(*i as i32).to_le_bytes())?;
        }
    }
    out.flush()
}

/// Writes `cloud` to `path` as binary little-endian PLY (see [`write_binary`]).
pub fn save(path: &Path, cloud: &Cloud) -> io::Result<()> {
    write_binary(cloud, std::fs::File::create(path)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_cloud() -> Cloud {
        Cloud {
            positions: vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.5, 0.25, 8.0)],
            normals: Some(vec![Vec3::Z, Vec3::X]),
            colors: Some(vec![[1, 2, 3, 255], [200, 100, 50, 7]]),
            radii: Some(vec![0.5, 0.25]),
            ..Cloud::default()
        }
    }

    #[test]
    fn binary_round_trip() {
        let cloud = sample_cloud();
        let mut bytes = Vec::new();
        write_binary(&cloud, &mut bytes).unwrap();
        let back = parse("mem.ply", &bytes).unwrap();
        assert_eq!(back.positions, cloud.positions);
        assert_eq!(back.normals, cloud.normals);
        assert_eq!(back.colors, cloud.colors);
        assert_eq!(back.radii, cloud.radii);
        assert_eq!(back.faces, None);
        let mesh = Cloud {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            faces: Some(vec![[0, 1, 2]]),
            ..Cloud::default()
        };
        let mut bytes = Vec::new();
        write_binary(&mesh, &mut bytes).unwrap();
        let back = parse("mesh.ply", &bytes).unwrap();
        assert_eq!((back.positions, back.faces), (mesh.positions, mesh.faces));
    }

    #[test]
    fn wide_round_trip_keeps_origin() {
        let mut cloud = sample_cloud();
        cloud.origin = DVec3::new(636_000.0, 849_000.0, 400.0);
        let mut bytes = Vec::new();
        write_binary(&cloud, &mut bytes).unwrap();
        let back = parse("mem.ply", &bytes).unwrap();
        for (a, b) in back.positions.iter().zip(&cloud.positions) {
            let wa = a.as_dvec3() + back.origin;
            let wb = b.as_dvec3() + cloud.origin;
            assert!((wa - wb).length() < 1e-6);
        }
    }

    #[test]
    fn big_endian_and_ascii_agree() {
        let mut be = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty ushort red\nproperty ushort green\nproperty ushort blue\nend_header\n".to_vec();
        for v in [1.0f32, 2.0, 3.0] {
            be.extend_from_slice(&v.to_be_bytes());
        }
        for c in [65535u16, 0, 257] {
            be.extend_from_slice(&c.to_be_bytes());
        }
        let a = parse("be.ply", &be).unwrap();
        let ascii = b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nproperty float red\nproperty float green\nproperty float blue\nend_header\n1 2 3 1.0 0.0 0.00392157\n";
        let b = parse("a.ply", ascii).unwrap();
        assert_eq!(a.positions, b.positions);
        assert_eq!(a.colors, Some(vec![[255, 0, 1, 255]]));
        assert_eq!(b.colors, a.colors);
    }

    #[test]
    fn skips_unknown_elements_with_lists() {
        for enc in ["ascii", "binary_little_endian", "binary_big_endian"] {
            let big = enc == "binary_big_endian";
            let mut data = format!(
                "ply\nformat {enc} 1.0\nelement grid 2\nproperty list uchar int idx\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float confidence\nend_header\n"
            )
            .into_bytes();
            if enc == "ascii" {
                data.extend_from_slice(b"0\n2 5 6\n1 2 3 0.5\n4 5 6 0.25\n");
            } else {
                data.push(0);
                data.push(2);
                for i in [5i32, 6] {
                    data.extend_from_slice(&if big {
                        i.to_be_bytes()
                    } else {
                        i.to_le_bytes()
                    });
                }
                for v in [1.0f32, 2.0, 3.0, 0.5, 4.0, 5.0, 6.0, 0.25] {
                    data.extend_from_slice(&if big {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    });
                }
            }
            let cloud = parse("skip.ply", &data).unwrap();
            assert_eq!(
                cloud.positions,
                vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)]
            );
            assert_eq!(cloud.scalars[0].name, "confidence");
            assert_eq!(cloud.scalars[0].values, vec![0.5, 0.25]);
        }
    }

    /// A binary PLY of `n` points with normals, colors and radii (double coordinates far
    /// from zero when `wide`), one NaN position, and two faces after the vertices.
    fn binary_with_faces(n: usize, wide: bool) -> Vec<u8> {
        let mut cloud = Cloud {
            positions: (0..n)
                .map(|i| {
                    let f = i as f32;
                    Vec3::new(f * 0.5, (i % 7) as f32, -f.sqrt())
                })
                .collect(),
            normals: Some((0..n).map(|i| Vec3::new(0.0, 1.0, i as f32)).collect()),
            colors: Some((0..n).map(|i| [i as u8, 2, 3, (i / 3) as u8]).collect()),
            radii: Some((0..n).map(|i| i as f32 * 0.25).collect()),
            ..Cloud::default()
        };
        if wide {
            cloud.origin = DVec3::new(636_000.0, 849_000.0, 400.0);
        }
        cloud.positions[17].x = f32::NAN;
        let mut bytes = Vec::new();
        write_binary(&cloud, &mut bytes).unwrap();
        let end = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap();
        bytes.splice(
            end..end,
            b"element face 2\nproperty list uchar int vertex_indices\n"
                .iter()
                .copied(),
        );
        for face in [[0i32, 1, 2], [3, 17, 4]] {
            bytes.push(3);
            for i in face {
                bytes.extend_from_slice(&i.to_le_bytes());
            }
        }
        bytes
    }

    #[test]
    fn streamed_blocks_match_in_memory_parse() {
        for wide in [false, true] {
            let bytes = binary_with_faces(5000, wide);
            let expected = parse("mem.ply", &bytes).unwrap();
            assert_eq!(expected.len(), 4999);
            assert_eq!(expected.faces, Some(vec![[0, 1, 2]]));
            assert_eq!(expected.origin != DVec3::ZERO, wide);
            let path = std::env::temp_dir()
                .join(format!("surfel-{}-blocks-{wide}.ply", std::process::id()));
            std::fs::write(&path, &bytes).unwrap();
            for block in [1, 1000, records::BLOCK_BYTES] {
                let streamed = load_in_blocks(&path, block).unwrap();
                assert_eq!(streamed, expected, "blocks of {block} bytes");
            }
            std::fs::remove_file(path).unwrap();
        }
    }
}

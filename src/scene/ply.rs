//! PLY reader (ascii, binary_little_endian, binary_big_endian) and a binary PLY writer.
//!
//! The `vertex` element supplies positions (`x y z`), normals (`nx ny nz`), colors
//! (`red green blue [alpha]`, 8-bit, 16-bit or float 0..1), `radius`, and every other scalar
//! property as a named [`Scalar`]. The `face` element's `vertex_indices` (or `vertex_index`)
//! list is fan-triangulated. Any other element is skipped.

use std::io::{self, Write};
use std::path::Path;

use glam::{DVec3, Vec3};

use super::cloud::{Cloud, LoadStats, Scalar};
use super::error::LoadError;
use super::text::{self, Lines};

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

    /// Decodes one value from exactly `self.size()` bytes.
    #[inline]
    fn decode(self, b: &[u8], big: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:literal) => {{
                let mut raw = [0u8; $n];
                raw.copy_from_slice(&b[..$n]);
                if big {
                    <$t>::from_be_bytes(raw) as f64
                } else {
                    <$t>::from_le_bytes(raw) as f64
                }
            }};
        }
        match self {
            Self::I8 => f64::from(b[0] as i8),
            Self::U8 => f64::from(b[0]),
            Self::I16 => num!(i16, 2),
            Self::U16 => num!(u16, 2),
            Self::I32 => num!(i32, 4),
            Self::U32 => num!(u32, 4),
            Self::F32 => num!(f32, 4),
            Self::F64 => num!(f64, 8),
        }
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

fn parse_header(file: &str, data: &[u8]) -> Result<Header, LoadError> {
    let mut lines = Lines::new(data);
    match lines.next_line() {
        Some(l) if l.trim_ascii() == b"ply" => {}
        Some(l) => {
            return Err(LoadError::at_line(
                file,
                1,
                format!(
                    "expected the magic line \"ply\", found \"{}\"",
                    text::show(l)
                ),
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
                            text::show(other.unwrap_or_default())
                        )))
                    }
                });
            }
            Some(b"element") => {
                let (Some(name), Some(count)) = (words.get(1), words.get(2)) else {
                    return Err(err(format!(
                        "expected \"element <name> <count>\", found \"{}\"",
                        text::show(line)
                    )));
                };
                let count = text::parse_i64(count)
                    .and_then(|c| usize::try_from(c).ok())
                    .ok_or_else(|| {
                        err(format!(
                            "expected a non-negative element count, found \"{}\"",
                            text::show(count)
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
                        text::show(line)
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
                    text::show(other)
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
    check_counts(file, &header, data.len() - header.body)?;
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
                    e.count, e.name, needed, body_len
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
    lines: Lines<'a>,
    line_base: usize,
    encoding: Encoding,
}

impl<'a> Body<'a> {
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
                self.pos,
                format!(
                    "unexpected end of file; expected {n} more bytes for {} {index} of {}",
                    element.name, element.count
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
                    let at = self.pos;
                    let n = count.decode(self.take(count.size(), element, index)?, big);
                    if !(n >= 0.0 && n.fract() == 0.0) {
                        return Err(LoadError::at_byte(
                            self.file,
                            at,
                            format!(
                                "expected a non-negative list length for {} of {} {index}, found {n}",
                                prop.name, element.name
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
                            element.name, element.count
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
                    element.name,
                    text::show(line.trim_ascii())
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

fn read_vertices(
    body: &mut Body<'_>,
    element: &Element,
    cloud: &mut Cloud,
) -> Result<(), LoadError> {
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
            body.file,
            "the vertex element needs properties x, y and z",
        ));
    }
    let n = element.count;
    let has_normals = has(Role::Nx) && has(Role::Ny) && has(Role::Nz);
    let has_colors = has(Role::Red) && has(Role::Green) && has(Role::Blue);
    let has_alpha = has(Role::Alpha);
    let color_types = [
        type_of(Role::Red),
        type_of(Role::Green),
        type_of(Role::Blue),
        type_of(Role::Alpha),
    ];
    let mut positions = Vec::with_capacity(n);
    let mut normals = has_normals.then(|| Vec::with_capacity(n));
    let mut colors = has_colors.then(|| Vec::with_capacity(n));
    let mut radii = has(Role::Radius).then(|| Vec::with_capacity(n));
    let mut scalars: Vec<Scalar> = scalar_names
        .into_iter()
        .map(|name| Scalar {
            name,
            values: Vec::with_capacity(n),
        })
        .collect();
    let mut values = vec![0.0f64; element.props.len()];
    let mut list = Vec::new();
    // Binary records without lists: take the whole element at once (one bounds check) and
    // decode it column by column, one tight loop per property.
    if let (Encoding::Binary { big }, Some(size)) = (body.encoding, element.fixed_record_size()) {
        let bytes = body.take(n.saturating_mul(size), element, 0)?;
        positions.resize(n, DVec3::ZERO);
        if let Some(v) = normals.as_mut() {
            v.resize(n, Vec3::ZERO);
        }
        if let Some(v) = colors.as_mut() {
            v.resize(n, [0, 0, 0, 255]);
        }
        if let Some(v) = radii.as_mut() {
            v.resize(n, 0.0);
        }
        for s in &mut scalars {
            s.values.resize(n, 0.0);
        }
        for ((offset, t), role) in binary_layout(element).into_iter().zip(&roles) {
            let column = bytes
                .chunks_exact(size.max(1))
                .map(|r| t.decode(&r[offset..offset + t.size()], big));
            let set_f32 = |dst: Option<&mut Vec<f32>>| {
                if let Some(dst) = dst {
                    dst.iter_mut()
                        .zip(column.clone())
                        .for_each(|(d, v)| *d = v as f32);
                }
            };
            match *role {
                Role::X => positions.iter_mut().zip(column).for_each(|(d, v)| d.x = v),
                Role::Y => positions.iter_mut().zip(column).for_each(|(d, v)| d.y = v),
                Role::Z => positions.iter_mut().zip(column).for_each(|(d, v)| d.z = v),
                Role::Nx | Role::Ny | Role::Nz => {
                    let axis = match *role {
                        Role::Nx => 0,
                        Role::Ny => 1,
                        _ => 2,
                    };
                    if let Some(ns) = normals.as_mut() {
                        ns.iter_mut()
                            .zip(column)
                            .for_each(|(d, v)| d[axis] = v as f32);
                    }
                }
                Role::Red | Role::Green | Role::Blue | Role::Alpha => {
                    let channel = match *role {
                        Role::Red => 0,
                        Role::Green => 1,
                        Role::Blue => 2,
                        _ => 3,
                    };
                    if let Some(cs) = colors.as_mut() {
                        cs.iter_mut()
                            .zip(column)
                            .for_each(|(d, v)| d[channel] = t.to_u8_channel(v));
                    }
                }
                Role::Radius => set_f32(radii.as_mut()),
                Role::Scalar(s) => set_f32(Some(&mut scalars[s].values)),
                Role::Ignore => {}
            }
        }
    } else {
        for i in 0..n {
            body.record(element, i, None, &mut values, &mut list)?;
            push_vertex(
                &roles,
                &values,
                &color_types,
                has_alpha,
                &mut positions,
                &mut normals,
                &mut colors,
                &mut radii,
                &mut scalars,
            );
        }
    }
    let origin = local_origin(&positions);
    cloud.positions = positions.iter().map(|p| (*p - origin).as_vec3()).collect();
    cloud.origin = origin;
    cloud.normals = normals;
    cloud.colors = colors;
    cloud.radii = radii;
    cloud.scalars = scalars;
    Ok(())
}

/// Appends one decoded vertex record (`values` by property index) to the attribute arrays.
#[allow(clippy::too_many_arguments)]
fn push_vertex(
    roles: &[Role],
    values: &[f64],
    color_types: &[ScalarType; 4],
    has_alpha: bool,
    positions: &mut Vec<DVec3>,
    normals: &mut Option<Vec<Vec3>>,
    colors: &mut Option<Vec<[u8; 4]>>,
    radii: &mut Option<Vec<f32>>,
    scalars: &mut [Scalar],
) {
    let mut p = [0.0f64; 3];
    let mut nrm = [0.0f32; 3];
    let mut rgba = [0.0f64, 0.0, 0.0, 255.0];
    for (role, &v) in roles.iter().zip(values) {
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
                if let Some(r) = radii.as_mut() {
                    r.push(v as f32);
                }
            }
            Role::Scalar(s) => scalars[s].values.push(v as f32),
            Role::Ignore => {}
        }
    }
    positions.push(DVec3::from(p));
    if let Some(normals) = normals.as_mut() {
        normals.push(Vec3::from(nrm));
    }
    if let Some(colors) = colors.as_mut() {
        let alpha = if has_alpha {
            color_types[3].to_u8_channel(rgba[3])
        } else {
            255
        };
        colors.push([
            color_types[0].to_u8_channel(rgba[0]),
            color_types[1].to_u8_channel(rgba[1]),
            color_types[2].to_u8_channel(rgba[2]),
            alpha,
        ]);
    }
}

/// Offset and type of every (scalar) property of a list-free element's binary record.
fn binary_layout(element: &Element) -> Vec<(usize, ScalarType)> {
    let mut offset = 0;
    element
        .props
        .iter()
        .filter_map(|p| match p.kind {
            Kind::Scalar(t) => {
                offset += t.size();
                Some((offset - t.size(), t))
            }
            Kind::List { .. } => None,
        })
        .collect()
}

/// The origin for a local frame: zero for small coordinates (so round trips are exact), else
/// the f64 bounding-box centre of the finite points.
fn local_origin(points: &[DVec3]) -> DVec3 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in points.iter().filter(|p| p.is_finite()) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if lo.x > hi.x || lo.abs().max(hi.abs()).max_element() < 1.0e4 {
        DVec3::ZERO
    } else {
        (lo + hi) * 0.5
    }
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
        let at_byte = body.pos;
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

/// Parses a PLY file held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: &[u8]) -> Result<Cloud, LoadError> {
    let header = parse_header(file, data)?;
    let vertex_count = header
        .elements
        .iter()
        .find(|e| e.name == "vertex")
        .map(|e| e.count)
        .ok_or_else(|| LoadError::whole(file, "the header declares no vertex element"))?;
    let body_bytes = &data[header.body..];
    let mut body = Body {
        file,
        data,
        pos: header.body,
        lines: Lines::new(body_bytes),
        line_base: header.lines,
        encoding: header.encoding,
    };
    let mut cloud = Cloud::default();
    let mut seen_vertex = false;
    for element in &header.elements {
        let face_list = element.props.iter().position(|p| {
            matches!(p.kind, Kind::List { .. })
                && (p.name == "vertex_indices" || p.name == "vertex_index")
        });
        match (element.name.as_str(), face_list) {
            ("vertex", _) if !seen_vertex => {
                read_vertices(&mut body, element, &mut cloud)?;
                seen_vertex = true;
            }
            ("face", Some(list_prop)) => {
                let mut faces = read_faces(&mut body, element, list_prop, vertex_count)?;
                if let Some(existing) = cloud.faces.as_mut() {
                    existing.append(&mut faces);
                } else {
                    cloud.faces = Some(faces);
                }
            }
            _ => body.skip(element)?,
        }
    }
    cloud.stats = LoadStats {
        records: vertex_count,
        dropped_non_finite: 0,
    };
    cloud.retain_finite();
    Ok(cloud)
}

/// Loads a PLY file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let data = super::read_file(path)?;
    parse(&path.display().to_string(), &data)
}

/// Writes `cloud` as binary little-endian PLY: positions (float, or double when the cloud has
/// a non-zero origin, so large coordinates survive), and normals, colors (with alpha) and
/// radii when present. Faces and scalars are not written.
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
    out.write_all(b"end_header\n")?;
    for i in 0..n {
        let p = cloud.positions[i];
        if wide {
            for c in (p.as_dvec3() + cloud.origin).to_array() {
                out.write_all(&c.to_le_bytes())?;
            }
        } else {
            for c in p.to_array() {
                out.write_all(&c.to_le_bytes())?;
            }
        }
        if let Some(normals) = normals {
            for c in normals[i].to_array() {
                out.write_all(&c.to_le_bytes())?;
            }
        }
        if let Some(colors) = colors {
            out.write_all(&colors[i])?;
        }
        if let Some(radii) = radii {
            out.write_all(&radii[i].to_le_bytes())?;
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
}

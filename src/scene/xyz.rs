//! Plain-text point lists (`.xyz`, `.txt`, `.pts`, `.csv`): one point per line, values separated by
//! commas, semicolons, tabs or spaces (CRLF line ends too); blank lines are ignored.
//!
//! **Named columns** follow PDAL's text reader: a first line of column names (`X,Y,Z,Intensity`,
//! quoted or not, in any order and any case, also CloudCompare's `//X,Y,Z,R,G,B`; a quoted
//! name keeps its spaces, and so does every name of a row separated by commas, semicolons or
//! tabs, such as `M3C2 distance`) names every
//! column, or `--columns x,y,z,intensity` names them for a file without that line. Names are
//! matched case-insensitively, ignoring `_`, `-` and spaces:
//!
//! | names | becomes |
//! |---|---|
//! | `x`, `y`, `z` | the position (required) |
//! | `nx`, `ny`, `nz`, `normalx`, ... | the normal (all three) |
//! | `r`, `g`, `b`, `red`, `green`, `blue` | the colour (0..255, 0..1 floats, or 16-bit as LAS) |
//! | `i`, `intensity`; `class`, `classification`; `gpstime`, `time`; `returnnumber`; `numberofreturns`; `pointsourceid` | the scalars LAS files give (`intensity`, `classification`, `gps_time`, ...) |
//! | `_`, `skip` | ignored |
//! | anything else | a scalar with the file's name |
//!
//! A row with another number of values than there are names is skipped and counted (`surfel
//! info`: dropped as invalid), as PDAL skips it.
//!
//! **Unnamed columns** (no name line and no `--columns`): lines starting with `#` or `//` are
//! comments, a first line holding a single integer (the `.pts` point count) is skipped, rows
//! of different lengths are read for the columns every row has (as CGAL reads `.xyz`), and that
//! column count selects the layout (`surfel info` prints it as `columns guessed`):
//!
//! | columns | layout |
//! |---|---|
//! | 3 | x y z |
//! | 4 | x y z intensity |
//! | 6 | x y z nx ny nz when every row's last three values form a unit vector, x y z r g b when they are all colour values, else x y z and scalars |
//! | 7 | x y z intensity r g b (Leica PTS) when the last three are colour values, else x y z and scalars |
//! | 9 | x y z nx ny nz r g b |
//! | other (≥ 3) | x y z, the rest kept as scalars `column4`, `column5`, ... |
//!
//! Values are read as f64; the position's f64 centre is subtracted when the coordinates are
//! large (UTM, ~5 × 10⁶ m), as for the binary formats, so centimetres survive the f32 cloud.
//!
//! **Up axis.** Text clouds are +y up (the convention of the mesh formats) unless their
//! coordinates are survey-sized: x and y both reach [`SURVEY_MAGNITUDE`] (10⁴) in absolute
//! value, or either reaches [`RECENTRE_MAGNITUDE`] (10⁵, which also re-centres the cloud), as
//! projected coordinates such as UTM eastings and northings do. Those are +z up, and survey
//! data ([`Cloud::survey`]: estimated normals face up where no scanner position is known).

use std::path::Path;

use glam::{DVec3, Vec3};

use super::camera::Up;
use super::cloud::{Bounds, Cloud, LoadStats, Scalar};
use super::error::{show, LoadError};
use super::pcd::RECENTRE_MAGNITUDE;
use super::text::{self, Lines};

/// Coordinates this large in both x and y make a text cloud z-up (see the module docs).
pub const SURVEY_MAGNITUDE: f64 = 1e4;

/// More columns than this on a line is refused (a 10 MB line of one-byte values would
/// otherwise make millions of scalar attributes).
pub const MAX_COLUMNS: usize = 256;

/// What a named column holds.
#[derive(Clone, Debug, PartialEq)]
enum Role {
    Position(usize),
    Normal(usize),
    Color(usize),
    /// A scalar attribute by this name.
    Scalar(String),
    Skip,
}

impl Role {
    /// How `surfel info` names the column.
    fn name(&self) -> String {
        match self {
            Role::Position(a) => ["x", "y", "z"][*a].into(),
            Role::Normal(a) => ["nx", "ny", "nz"][*a].into(),
            Role::Color(a) => ["red", "green", "blue"][*a].into(),
            Role::Scalar(name) => name.clone(),
            Role::Skip => "_".into(),
        }
    }
}

/// The role of a column named `name` (quotes already removed).
fn role(name: &str) -> Role {
    let key: String = name
        .chars()
        .filter(|c| !matches!(c, '_' | '-' | ' '))
        .flat_map(char::to_lowercase)
        .collect();
    let scalar = |s: &str| Role::Scalar(s.to_owned());
    match key.as_str() {
        "x" => Role::Position(0),
        "y" => Role::Position(1),
        "z" => Role::Position(2),
        "nx" | "normalx" => Role::Normal(0),
        "ny" | "normaly" => Role::Normal(1),
        "nz" | "normalz" => Role::Normal(2),
        "r" | "red" => Role::Color(0),
        "g" | "green" => Role::Color(1),
        "b" | "blue" => Role::Color(2),
        "i" | "intensity" => scalar("intensity"),
        "class" | "classification" => scalar("classification"),
        "gpstime" | "time" => scalar("gps_time"),
        "returnnumber" => scalar("return_number"),
        "numberofreturns" => scalar("number_of_returns"),
        "pointsourceid" => scalar("point_source_id"),
        "" | "skip" => Role::Skip,
        _ => Role::Scalar(name.to_owned()),
    }
}

/// Whether `b` separates the values of a row: a comma, semicolon or white space.
fn value_separator(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | 0x0c | b',' | b';')
}

/// Whether `b` separates the names of a name row that has commas, semicolons or tabs, where
/// a space belongs to a name (`M3C2 distance`, as CloudCompare writes it).
fn name_separator(b: u8) -> bool {
    matches!(b, b'\t' | b',' | b';')
}

/// The non-empty tokens of `line` between `separator`s, white space around them trimmed. A
/// token opening with a quote (`"` or `'`, as spreadsheets write names and values) runs to the
/// matching quote, separators included, and is returned without its quotes.
fn split_fields(line: &[u8], separator: fn(u8) -> bool) -> impl Iterator<Item = &[u8]> {
    let mut rest = line;
    std::iter::from_fn(move || loop {
        let start = rest
            .iter()
            .position(|&b| !separator(b) && !b.is_ascii_whitespace())?;
        rest = &rest[start..];
        let quote = rest[0];
        let token = if quote == b'"' || quote == b'\'' {
            let end = rest[1..].iter().position(|&b| b == quote);
            let token = &rest[1..end.map_or(rest.len(), |e| e + 1)];
            rest = &rest[end.map_or(rest.len(), |e| e + 2)..];
            token
        } else {
            let end = rest
                .iter()
                .position(|&b| separator(b))
                .unwrap_or(rest.len());
            let token = rest[..end].trim_ascii_end();
            rest = &rest[end..];
            token
        };
        if !token.is_empty() {
            return Some(token);
        }
    })
}

/// The values of a row: split at commas, semicolons and white space (quotes as
/// [`split_fields`] reads them).
fn fields(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    split_fields(line, value_separator)
}

/// The names of a name row: split at commas, semicolons and tabs when it has any (a name may
/// hold spaces), else at white space; quoted names keep what their quotes hold.
fn name_fields(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    let separator = if line.iter().any(|&b| name_separator(b)) {
        name_separator
    } else {
        value_separator
    };
    split_fields(line, separator)
}

/// The roles of the named columns `names`, checked: x, y and z present, each role at most once.
fn named(names: &[String]) -> Result<Vec<Role>, String> {
    if names.len() > MAX_COLUMNS {
        return Err(format!(
            "{} column names; at most {MAX_COLUMNS} are read",
            names.len()
        ));
    }
    let roles: Vec<Role> = names.iter().map(|n| role(n)).collect();
    for (i, r) in roles.iter().enumerate() {
        if *r != Role::Skip && roles[..i].contains(r) {
            return Err(format!("column {} repeats \"{}\"", i + 1, show(&names[i])));
        }
    }
    if !(0..3).all(|a| roles.contains(&Role::Position(a))) {
        return Err(format!(
            "the column names must include x, y and z, found \"{}\"",
            show(names.join(","))
        ));
    }
    for (make, what) in [
        (Role::Normal as fn(usize) -> Role, "nx, ny and nz"),
        (Role::Color, "r, g and b"),
    ] {
        let present = (0..3).filter(|&a| roles.contains(&make(a))).count();
        if present != 0 && present != 3 {
            return Err(format!(
                "the column names must include all of {what} or none, found \"{}\"",
                show(names.join(","))
            ));
        }
    }
    Ok(roles)
}

/// Whether `line` is a row of column names: text without control characters (binary data is
/// not), with a token that is not a number, each such token starting with a letter or `_`.
fn is_name_row(line: &[u8]) -> bool {
    let words: Vec<&[u8]> = name_fields(line)
        .filter(|t| text::parse_f64(t).is_none())
        .collect();
    std::str::from_utf8(line).is_ok_and(|s| !s.chars().any(|c| c.is_control() && c != '\t'))
        && !words.is_empty()
        && words.iter().all(|w| {
            w.first()
                .is_some_and(|&c| c.is_ascii_alphabetic() || c == b'_' || c >= 0x80)
        })
}

/// Parses point-list text held in memory; `columns` names the columns of a file without a name
/// row (it replaces the name row of a file with one). `file` names it in error messages.
pub fn parse(file: &str, data: &[u8], columns: Option<&[String]>) -> Result<Cloud, LoadError> {
    let mut lines = Lines::new(data);
    let mut roles: Option<Vec<Role>> = columns
        .map(named)
        .transpose()
        .map_err(|e| LoadError::whole(file, format!("--columns: {e}")))?;
    let mut width = roles.as_ref().map_or(0, Vec::len);
    let mut values: Vec<f64> = Vec::new();
    // Values per row of a file without names (at most MAX_COLUMNS).
    let mut lengths: Vec<u16> = Vec::new();
    // Rows skipped for not matching the named columns.
    let mut skipped = 0usize;
    let mut first = true;
    while let Some(line) = lines.next_line() {
        let trimmed = line.trim_ascii();
        let n = lines.line();
        let comment = trimmed
            .strip_prefix(b"//")
            .or_else(|| trimmed.strip_prefix(b"#"));
        if trimmed.is_empty() {
            continue;
        }
        // A first line with a word names the columns; commented out (`//X,Y,Z`, `# x y z`),
        // it does when it names x, y and z, else it is a comment.
        let names_text = comment.unwrap_or(trimmed);
        if first && is_name_row(names_text) {
            let names: Vec<String> = name_fields(names_text)
                .map(|t| String::from_utf8_lossy(t).into_owned())
                .collect();
            match named(&names) {
                Ok(named) => {
                    first = false;
                    if columns.is_none() {
                        width = named.len();
                        roles = Some(named);
                    }
                }
                Err(e) if comment.is_none() => return Err(LoadError::at_line(file, n, e)),
                Err(_) => {}
            }
            continue;
        }
        if comment.is_some() {
            continue;
        }
        let first_line = std::mem::take(&mut first);
        let start = values.len();
        // Named columns: a row with another number of values is skipped and counted, as
        // PDAL skips it.
        if roles.is_some() && fields(trimmed).take(width + 1).count() != width {
            skipped += 1;
            continue;
        }
        for token in fields(trimmed) {
            let count = values.len() - start;
            if count == MAX_COLUMNS {
                return Err(LoadError::at_line(
                    file,
                    n,
                    format!("more than {MAX_COLUMNS} columns"),
                ));
            }
            let v = text::parse_f64(token).ok_or_else(|| {
                LoadError::at_line(
                    file,
                    n,
                    format!(
                        "expected a number in column {}, found \"{}\"",
                        count + 1,
                        show(token)
                    ),
                )
            })?;
            values.push(v);
        }
        let count = values.len() - start;
        if roles.is_some() {
            continue;
        }
        if first_line && count == 1 && text::parse_i64(trimmed).is_some() {
            values.truncate(start);
            continue;
        }
        if count < 3 {
            return Err(LoadError::at_line(
                file,
                n,
                format!(
                    "expected at least 3 numbers (x y z), found {count}: \"{}\"",
                    show(trimmed)
                ),
            ));
        }
        lengths.push(count as u16);
        width = if width == 0 { count } else { width.min(count) };
    }
    if values.is_empty() {
        let message = if skipped > 0 {
            format!("no points; the {skipped} rows do not have the {width} values the columns name")
        } else {
            "no points; expected lines of x y z values".to_owned()
        };
        return Err(LoadError::whole(file, message));
    }
    let (roles, guessed) = match roles {
        Some(roles) => (roles, None),
        None => {
            // Rows of different lengths: the columns every row has.
            if lengths.iter().any(|&l| usize::from(l) != width) {
                let mut at = 0;
                let mut kept = Vec::with_capacity(lengths.len() * width);
                for &l in &lengths {
                    kept.extend_from_slice(&values[at..at + width]);
                    at += usize::from(l);
                }
                values = kept;
            }
            let roles = guess(&values, width);
            let names: Vec<String> = roles.iter().map(Role::name).collect();
            (roles, Some(names.join(", ")))
        }
    };
    let mut cloud = build(&values, &roles);
    cloud.stats.guessed_columns = guessed;
    cloud.stats.records += skipped;
    cloud.stats.dropped_invalid = skipped;
    Ok(cloud)
}

/// The roles of unnamed columns, from their count and values (see the module table).
fn guess(values: &[f64], width: usize) -> Vec<Role> {
    let rows = || values.chunks_exact(width);
    let color_values = |c: usize| {
        rows().all(|r| {
            let rgb = &r[c..c + 3];
            rgb.iter()
                .all(|v| (0.0..=255.0).contains(v) && v.fract() == 0.0)
                || rgb.iter().all(|v| (0.0..=1.0).contains(v))
        })
    };
    let unit_vectors = |c: usize| {
        rows().all(|r| {
            let len2 = r[c] * r[c] + r[c + 1] * r[c + 1] + r[c + 2] * r[c + 2];
            (len2 - 1.0).abs() < 0.02
        })
    };
    let xyz = [Role::Position(0), Role::Position(1), Role::Position(2)];
    let normal = [Role::Normal(0), Role::Normal(1), Role::Normal(2)];
    let color = [Role::Color(0), Role::Color(1), Role::Color(2)];
    let intensity = Role::Scalar("intensity".into());
    let mut roles: Vec<Role> = xyz.to_vec();
    match width {
        3 => {}
        4 => roles.push(intensity),
        6 if unit_vectors(3) => roles.extend(normal),
        6 if color_values(3) => roles.extend(color),
        7 if color_values(4) => {
            roles.push(intensity);
            roles.extend(color);
        }
        9 => {
            roles.extend(normal);
            roles.extend(color);
        }
        _ => {}
    }
    for c in roles.len()..width {
        roles.push(Role::Scalar(format!("column{}", c + 1)));
    }
    roles
}

fn build(values: &[f64], roles: &[Role]) -> Cloud {
    let rows: Vec<&[f64]> = values.chunks_exact(roles.len()).collect();
    let find = |want: Role| roles.iter().position(|r| *r == want);
    let triple = |make: fn(usize) -> Role| -> Option<[usize; 3]> {
        Some([find(make(0))?, find(make(1))?, find(make(2))?])
    };
    let position = triple(Role::Position).unwrap_or([0, 1, 2]);
    let world = |r: &[f64]| DVec3::new(r[position[0]], r[position[1]], r[position[2]]);
    let bounds = rows.iter().fold(Bounds::EMPTY, |mut b, r| {
        b.add(world(r));
        b
    });
    let origin = bounds
        .centre()
        .filter(|_| bounds.lo.abs().max(bounds.hi.abs()).max_element() >= RECENTRE_MAGNITUDE)
        .unwrap_or(DVec3::ZERO);
    let normals = triple(Role::Normal).map(|[a, b, c]| {
        rows.iter()
            .map(|r| Vec3::new(r[a] as f32, r[b] as f32, r[c] as f32))
            .collect()
    });
    let colors = triple(Role::Color).map(|channels| {
        let all = || rows.iter().flat_map(|r| channels.map(|c| r[c]));
        let scale = if all().all(|v| v <= 1.0) {
            255.0
        } else if all().any(|v| v > 255.0) {
            1.0 / 257.0
        } else {
            1.0
        };
        rows.iter()
            .map(|r| {
                let [red, green, blue] = channels.map(|c| {
                    let v = (r[c] * scale).round();
                    if v.is_nan() {
                        0
                    } else {
                        v.clamp(0.0, 255.0) as u8
                    }
                });
                [red, green, blue, 255]
            })
            .collect()
    });
    let time_origin = roles
        .iter()
        .position(|r| *r == Role::Scalar("gps_time".into()))
        .map(|c| {
            let earliest = rows.iter().map(|r| r[c]).fold(f64::INFINITY, f64::min);
            if earliest.is_finite() {
                earliest
            } else {
                0.0
            }
        });
    let scalars = roles
        .iter()
        .enumerate()
        .filter_map(|(c, r)| match r {
            Role::Scalar(name) => {
                // GPS times (~10⁹ s) keep their sub-millisecond steps relative to the
                // earliest (`stats.gps_time_origin`).
                let base = if name == "gps_time" {
                    time_origin.unwrap_or(0.0)
                } else {
                    0.0
                };
                Some(Scalar {
                    name: name.clone(),
                    values: rows.iter().map(|r| (r[c] - base) as f32).collect(),
                })
            }
            _ => None,
        })
        .collect();
    let magnitude = bounds.lo.abs().max(bounds.hi.abs());
    let survey = bounds.centre().is_some()
        && ((magnitude.x >= SURVEY_MAGNITUDE && magnitude.y >= SURVEY_MAGNITUDE)
            || magnitude.x.max(magnitude.y) >= RECENTRE_MAGNITUDE);
    let mut cloud = Cloud {
        positions: rows.iter().map(|r| (world(r) - origin).as_vec3()).collect(),
        normals,
        colors,
        scalars,
        origin,
        stats: LoadStats {
            records: rows.len(),
            gps_time_origin: time_origin,
            up_rule: survey
                .then(|| "survey-sized x, y coordinates (projected, such as UTM): z up".to_owned()),
            ..LoadStats::default()
        },
        up: if survey { Up::Z } else { Up::Y },
        survey,
        ..Cloud::default()
    };
    cloud.retain_finite();
    cloud
}

/// Loads a point-list text file; `columns` as for [`parse`].
pub fn load(path: &Path, columns: Option<&[String]>) -> Result<Cloud, LoadError> {
    let data = super::read_file(path)?;
    parse(&path.display().to_string(), &data, columns)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(file: &str, data: &[u8]) -> Result<Cloud, LoadError> {
        super::parse(file, data, None)
    }

    fn scalar<'a>(c: &'a Cloud, name: &str) -> &'a [f32] {
        &c.scalars.iter().find(|s| s.name == name).unwrap().values
    }

    #[test]
    fn layouts() {
        let c = parse(
            "a.xyz",
            b"# header\n3\n0,0,0,255,0,0\n1 1 1 0 128 0\n\n2 2 2 0 0 1\n",
        )
        .unwrap();
        assert_eq!(c.len(), 3);
        assert_eq!(c.colors.unwrap()[1], [0, 128, 0, 255]);
        let c = parse("n.xyz", b"0 0 0 0 0 1\n1 1 1 1 0 0\n").unwrap();
        assert_eq!(c.normals.unwrap()[1], Vec3::X);
        let c = parse("f.xyz", b"0 0 0 1 0 0 0 0.5 1\n").unwrap();
        assert_eq!(c.colors.unwrap()[0], [0, 128, 255, 255]);
        let c = parse("p.pts", b"1\n0 0 0 -5 10 20 30\n").unwrap();
        assert_eq!(c.scalars[0].values, vec![-5.0]);
        assert_eq!(c.colors.unwrap()[0], [10, 20, 30, 255]);
    }

    #[test]
    fn six_columns_that_are_neither_colours_nor_normals_stay_scalars() {
        let c = parse(
            "t.xyz",
            b"0 0 0 1653000000.5 2 300\n1 1 1 1653000001.5 1 7\n",
        )
        .unwrap();
        assert!(c.colors.is_none() && c.normals.is_none());
        assert_eq!(scalar(&c, "column6"), [300.0, 7.0]);
    }

    #[test]
    fn a_name_row_in_any_case_order_and_separator() {
        for text in [
            &b"X,Y,Z,Intensity\n1,2,3,4\n5,6,7,8\n"[..],
            b"\"x\";\"y\";\"z\";\"intensity\"\r\n1;2;3;4\r\n5;6;7;8\r\n",
            b"Intensity\tZ\tY\tX\n4\t3\t2\t1\n8\t7\t6\t5\n",
            b"//X,Y,Z,I\n1 2 3 4\n5 6 7 8\n",
        ] {
            let c = parse("h.txt", text).unwrap();
            assert_eq!(c.positions, [Vec3::new(1., 2., 3.), Vec3::new(5., 6., 7.)]);
            assert_eq!(scalar(&c, "intensity"), [4.0, 8.0]);
        }
        let c = parse(
            "c.csv",
            b"Red,X,Green,Y,Blue,Z,GpsTime,Reflectance\n255,1,0,2,65535,3,1e9,0.5\n0,0,0,0,0,0,1000000000.25,1\n",
        )
        .unwrap();
        assert_eq!(c.colors.as_ref().unwrap()[0], [1, 0, 255, 255]);
        assert_eq!(scalar(&c, "gps_time"), [0.0, 0.25]);
        assert_eq!(c.stats.gps_time_origin, Some(1e9));
        assert_eq!(scalar(&c, "Reflectance"), [0.5, 1.0]);
        let c = parse(
            "t.csv",
            b"x,y,z,time\n0,0,0,1000000003.5\n1,1,1,1000000001.25\n",
        )
        .unwrap();
        assert_eq!(scalar(&c, "gps_time"), [2.25, 0.0]);
        assert_eq!(c.stats.gps_time_origin, Some(1_000_000_001.25));
    }

    #[test]
    fn names_keep_their_spaces_inside_quotes_or_between_commas() {
        for text in [
            &b"X Y Z \"M3C2 distance\" 'point id'\n1 2 3 0.5 7\n"[..],
            b"//X,Y,Z,M3C2 distance,point id\n1,2,3,0.5,7\n",
            b"x;y;z;\"M3C2 distance\";\"point id\"\r\n1;2;3;0.5;7\r\n",
            b"x\ty\tz\t M3C2 distance \tpoint id\n1\t2\t3\t0.5\t7\n",
        ] {
            let c = parse("m3c2.txt", text).unwrap();
            assert_eq!(c.positions, [Vec3::new(1., 2., 3.)]);
            assert_eq!(scalar(&c, "M3C2 distance"), [0.5]);
            assert_eq!(scalar(&c, "point id"), [7.0]);
        }
        let fields: Vec<&[u8]> = fields(b"\"a,b\" 'c d' \"\" 'open").collect();
        assert_eq!(fields, [&b"a,b"[..], b"c d", b"open"]);
    }

    #[test]
    fn columns_name_a_file_without_a_name_row() {
        let names: Vec<String> = ["red", "x", "y", "z"].map(String::from).into();
        let e = super::parse("n.txt", b"10 1 2 3\n", Some(&names)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "n.txt: --columns: the column names must include all of r, g and b or none, found \"red,x,y,z\""
        );
        let names: Vec<String> = ["i", "x", "y", "z"].map(String::from).into();
        let c = super::parse("n.txt", b"10 1 2 3\n", Some(&names)).unwrap();
        assert_eq!(c.positions, [Vec3::new(1., 2., 3.)]);
        assert_eq!(scalar(&c, "intensity"), [10.0]);
    }

    #[test]
    fn large_coordinates_keep_centimetres() {
        let c = parse(
            "utm.xyz",
            b"500000.01 4320000.01 100.01\n500004.36 4320004.36 104.36\n",
        )
        .unwrap();
        let far = c.origin + c.positions[1].as_dvec3();
        assert!(
            (far - DVec3::new(500004.36, 4320004.36, 104.36))
                .abs()
                .max_element()
                < 1e-3
        );
    }

    #[test]
    fn survey_sized_coordinates_are_z_up() {
        let rule = "survey-sized x, y coordinates (projected, such as UTM): z up";
        for text in [
            &b"500000.01 4320000.01 100.01\n500004.36 4320004.36 104.36\n"[..],
            b"-10000 10000 0\n0 0 5\n",
            b"100000 5 0\n0 0 5\n",
        ] {
            let c = parse("utm.xyz", text).unwrap();
            assert_eq!((c.up, c.stats.up_rule.as_deref()), (Up::Z, Some(rule)));
            assert!(c.survey);
        }
        for text in [&b"9999 9999 0\n0 0 1\n"[..], b"10000 5 1000000\n0 0 1\n"] {
            let c = parse("local.xyz", text).unwrap();
            assert_eq!((c.up, c.stats.up_rule.as_deref()), (Up::Y, None));
            assert!(!c.survey);
        }
    }

    #[test]
    fn ragged_rows_keep_the_columns_every_row_has() {
        let c = parse(
            "r.xyz",
            b"2 3 4   4  4 2 7 4\n3 4 6\n1 2 3 4 5 6\n0 0 0 9 9 9",
        )
        .unwrap();
        assert_eq!(c.len(), 4);
        assert!(c.scalars.is_empty() && c.colors.is_none());
        assert_eq!(c.positions[2], Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(c.stats.guessed_columns.as_deref(), Some("x, y, z"));
        let c = parse("named.txt", b"X, Y, Z\n\n1 , 2 , 3,27\n4,5,6\n7 8\n").unwrap();
        assert_eq!(c.positions, [Vec3::new(4., 5., 6.)]);
        assert_eq!((c.stats.records, c.stats.dropped_invalid), (3, 2));
        assert_eq!(c.stats.guessed_columns, None);
    }

    #[test]
    fn bad_rows_name_their_line() {
        let err = parse("m.xyz", b"0 0 0\n1 1\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "m.xyz: line 2: expected at least 3 numbers (x y z), found 2: \"1 1\""
        );
        // An empty quoted field is no column (and no name row).
        let c = parse("q.xyz", b"\"\" 1 2 3\n").unwrap();
        assert_eq!(c.positions, [Vec3::new(1.0, 2.0, 3.0)]);
        let err = parse("n.xyz", b"-+e093e\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "n.xyz: line 1: expected a number in column 1, found \"-+e093e\""
        );
        let err = parse("h.txt", b"X,Y,Intensity\n1,2,3\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            "h.txt: line 1: the column names must include x, y and z, found \"X,Y,Intensity\""
        );
        let err = parse("h.txt", b"x,y,z,i\n1,2,3\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "h.txt: no points; the 1 rows do not have the 4 values the columns name"
        );
        let err = parse("h.txt", b"x,y,z\n1,2,q\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "h.txt: line 2: expected a number in column 3, found \"q\""
        );
        let wide = "1 ".repeat(MAX_COLUMNS + 1);
        let err = parse("w.xyz", wide.as_bytes()).unwrap_err().to_string();
        assert_eq!(
            err,
            format!("w.xyz: line 1: more than {MAX_COLUMNS} columns")
        );
    }
}

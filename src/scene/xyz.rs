//! Plain-text point lists (`.xyz`, `.txt`, `.pts`): one point per line, values separated by
//! whitespace or commas; blank lines and lines starting with `#` or `//` are ignored. A first
//! data line holding a single integer (the `.pts` point count) is skipped.
//!
//! The column count of the first data line selects the layout, and every line must match it:
//!
//! | columns | layout |
//! |---|---|
//! | 3 | x y z |
//! | 4 | x y z intensity |
//! | 6 | x y z r g b, or x y z nx ny nz when every row's last three values form a unit vector |
//! | 7 | x y z intensity r g b (Leica PTS) |
//! | 9 | x y z nx ny nz r g b |
//! | other (≥ 3) | x y z, the rest kept as scalars `column4`, `column5`, ... |
//!
//! Colors are 0..255, or 0..1 floats when no color value in the file exceeds 1.

use std::path::Path;

use glam::Vec3;

use super::cloud::{Cloud, LoadStats, Scalar};
use super::error::{show, LoadError};
use super::text::{self, Lines};

/// Parses point-list text held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: &[u8]) -> Result<Cloud, LoadError> {
    let mut lines = Lines::new(data);
    let mut columns = 0usize;
    let mut values: Vec<f64> = Vec::new();
    let mut first = true;
    while let Some(line) = lines.next_line() {
        let trimmed = line.trim_ascii();
        if trimmed.is_empty() || trimmed.starts_with(b"#") || trimmed.starts_with(b"//") {
            continue;
        }
        let n = lines.line();
        let start = values.len();
        let mut count = 0;
        for token in text::tokens(trimmed, true) {
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
            count += 1;
        }
        let first_line = std::mem::take(&mut first);
        if columns == 0 {
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
            columns = count;
        } else if count != columns {
            return Err(LoadError::at_line(
                file,
                n,
                format!(
                    "expected {columns} numbers like the first data line, found {count}: \"{}\"",
                    show(trimmed)
                ),
            ));
        }
    }
    if columns == 0 {
        return Err(LoadError::whole(
            file,
            "no points; expected lines of x y z values",
        ));
    }
    Ok(build(&values, columns))
}

fn build(values: &[f64], columns: usize) -> Cloud {
    let rows: Vec<&[f64]> = values.chunks_exact(columns).collect();
    let column = |c: usize| rows.iter().map(move |r| r[c]);
    let vec3 = |c: usize| -> Vec<Vec3> {
        rows.iter()
            .map(|r| Vec3::new(r[c] as f32, r[c + 1] as f32, r[c + 2] as f32))
            .collect()
    };
    let colors_at = |c: usize| -> Vec<[u8; 4]> {
        let unit = column(c)
            .chain(column(c + 1))
            .chain(column(c + 2))
            .all(|v| v <= 1.0);
        let scale = if unit { 255.0 } else { 1.0 };
        rows.iter()
            .map(|r| {
                let ch = |v: f64| {
                    let v = (v * scale).round();
                    if v.is_nan() {
                        0
                    } else {
                        v.clamp(0.0, 255.0) as u8
                    }
                };
                [ch(r[c]), ch(r[c + 1]), ch(r[c + 2]), 255]
            })
            .collect()
    };
    let scalar = |name: String, c: usize| Scalar {
        name,
        values: column(c).map(|v| v as f32).collect(),
    };
    let mut cloud = Cloud {
        positions: vec3(0),
        stats: LoadStats {
            records: rows.len(),
            ..LoadStats::default()
        },
        ..Cloud::default()
    };
    match columns {
        3 => {}
        4 => cloud.scalars.push(scalar("intensity".into(), 3)),
        6 => {
            let unit_vectors = rows.iter().all(|r| {
                let len2 = r[3] * r[3] + r[4] * r[4] + r[5] * r[5];
                (len2 - 1.0).abs() < 0.02
            });
            if unit_vectors {
                cloud.normals = Some(vec3(3));
            } else {
                cloud.colors = Some(colors_at(3));
            }
        }
        7 => {
            cloud.scalars.push(scalar("intensity".into(), 3));
            cloud.colors = Some(colors_at(4));
        }
        9 => {
            cloud.normals = Some(vec3(3));
            cloud.colors = Some(colors_at(6));
        }
        _ => {
            for c in 3..columns {
                cloud.scalars.push(scalar(format!("column{}", c + 1), c));
            }
        }
    }
    cloud.retain_finite();
    cloud
}

/// Loads a point-list text file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let data = super::read_file(path)?;
    parse(&path.display().to_string(), &data)
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn column_mismatch_names_line() {
        let err = parse("m.xyz", b"0 0 0\n1 1\n").unwrap_err().to_string();
        assert_eq!(
            err,
            "m.xyz: line 2: expected 3 numbers like the first data line, found 2: \"1 1\""
        );
    }
}

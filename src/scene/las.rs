//! LAS/LAZ reader, built on the `las` crate.
//!
//! Coordinates are scaled and offset in f64 by the crate; the f64 bounding-box centre becomes
//! [`Cloud::origin`] and is subtracted in f64 before the conversion to f32, so large projected
//! coordinates keep their centimetre grid. RGB is kept (8-bit values stored in the 16-bit
//! fields, as many writers do, are detected and used as is; true 16-bit values are shifted down),
//! and intensity and classification become scalars.

use std::io::Cursor;
use std::path::Path;

use glam::DVec3;

use super::cloud::{Cloud, LoadStats, Scalar};
use super::error::LoadError;

/// Parses a LAS or LAZ file held in memory. `file` names it in error messages.
pub fn parse(file: &str, data: Vec<u8>) -> Result<Cloud, LoadError> {
    let size = data.len();
    let mut reader = las::Reader::new(Cursor::new(data))
        .map_err(|e| LoadError::whole(file, format!("invalid LAS header: {e}")))?;
    let header = reader.header();
    let declared = header.number_of_points();
    let record_len = usize::from(header.point_format().len()).max(1);
    let compressed = header.point_format().is_compressed;
    // LAZ records are compressed, so the file size bounds the count only loosely: reserve at
    // most one point per two bytes and let honest files that compress better grow the vectors.
    let bound = if compressed {
        size / 2
    } else {
        size / record_len
    };
    if !compressed && declared > bound as u64 {
        return Err(LoadError::whole(
            file,
            format!(
                "header declares {declared} points of {record_len} bytes, but the file has only {size} bytes"
            ),
        ));
    }
    let capacity = usize::try_from(declared).unwrap_or(usize::MAX).min(bound);
    let mut world = Vec::with_capacity(capacity);
    let mut rgb16 = Vec::new();
    let mut intensity = Vec::with_capacity(capacity);
    let mut class = Vec::with_capacity(capacity);
    let mut index = 0u64;
    while let Some(point) = reader
        .read_point()
        .map_err(|e| LoadError::whole(file, format!("point {index} of {declared}: {e}")))?
    {
        world.push(DVec3::new(point.x, point.y, point.z));
        if let Some(c) = point.color {
            rgb16.push([c.red, c.green, c.blue]);
        }
        intensity.push(f32::from(point.intensity));
        class.push(f32::from(u8::from(point.classification)));
        index += 1;
    }
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for p in world.iter().filter(|p| p.is_finite()) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let origin = if lo.x <= hi.x {
        (lo + hi) * 0.5
    } else {
        DVec3::ZERO
    };
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
    let mut cloud = Cloud {
        positions: world.iter().map(|p| (*p - origin).as_vec3()).collect(),
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
            dropped_non_finite: 0,
        },
        ..Cloud::default()
    };
    cloud.retain_finite();
    Ok(cloud)
}

/// Loads a LAS or LAZ file.
pub fn load(path: &Path) -> Result<Cloud, LoadError> {
    let data = super::read_file(path)?;
    parse(&path.display().to_string(), data)
}
